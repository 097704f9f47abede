// truecut dashboard: the API client, the hash router and small page helpers.
// Views register themselves in App.views (views.js, motion.js, iso.js). When a view has
// finished drawing, <body data-state> becomes "ready" (or "error" with the problem shown);
// the headless-browser test in .ci/ waits for that.
"use strict";

const App = (() => {
  /** An API answer that is not 2xx: its problem+json sentence. */
  class Problem extends Error {
    constructor(status, body) {
      const detail = body && typeof body === "object"
        ? `${body.title || "error"}: ${body.detail || ""}`
        : `HTTP ${status}: ${String(body).slice(0, 300)}`;
      super(detail);
      this.status = status;
    }
  }

  /**
   * Calls the API. With a token configured the browser sends the Basic credentials the
   * operator typed at the log-in prompt; the extra header lets the server accept them for
   * POSTs (it refuses Basic-authenticated POSTs without it, so other sites cannot use them).
   * A 202 job is followed until it is done.
   */
  async function api(method, path, body) {
    const headers = { Accept: "application/json", "X-Truecut-Dashboard": "1" };
    if (body !== undefined) headers["Content-Type"] = "application/json";
    const r = await fetch(path, { method, headers, body: body === undefined ? undefined : JSON.stringify(body) });
    const type = r.headers.get("content-type") || "";
    const data = type.includes("json") ? await r.json() : await r.text();
    if (!r.ok) throw new Problem(r.status, data);
    if (r.status === 202 && data && data.job) return await waitJob(data.job);
    return data;
  }
  async function waitJob(id) {
    for (;;) {
      await new Promise((res) => setTimeout(res, 400));
      const j = await api("GET", `/v1/jobs/${encodeURIComponent(id)}`);
      if (j.state === "done") return j.result;
      if (j.state === "failed" || j.state === "cancelled") throw new Error(`job ${id} ${j.state}: ${j.error || ""}`);
    }
  }

  /** Element helper: h("div", {class: "x"}, child, "text", ...). */
  function h(tag, attrs, ...children) {
    const e = document.createElement(tag);
    for (const k in attrs || {}) {
      if (k === "onclick" || k === "onchange" || k === "onsubmit") e.addEventListener(k.slice(2), attrs[k]);
      else e.setAttribute(k, attrs[k]);
    }
    for (const c of children) if (c !== null && c !== undefined) e.append(c instanceof Node ? c : String(c));
    return e;
  }
  const link = (href, label) => h("a", { href }, label);
  const enc = encodeURIComponent;

  /** A table from a header row and data rows; numbers right-aligned. */
  function table(head, rows) {
    return h("table", {}, h("tr", {}, ...head.map((x) => h("th", {}, x))),
      ...rows.map((r) => h("tr", {}, ...r.map((x) => (typeof x === "number" ? h("td", { class: "num" }, x) : h("td", {}, x))))));
  }
  /** Headline figures: [[value, caption], ...]. */
  function figures(items) {
    return h("div", { class: "figures" }, ...items.map(([v, c]) => h("div", { class: "figure" }, h("b", {}, v), h("span", {}, c))));
  }
  const mm = (v, d) => (v === null || v === undefined ? "–" : `${Number(v).toFixed(d === undefined ? 4 : d)} mm`);
  const um = (v, d) => (v === null || v === undefined ? "–" : `${(Number(v) * 1000).toFixed(d === undefined ? 2 : d)} µm`);
  function problemBox(err) {
    return h("div", { class: "problem", role: "alert" }, err && err.message ? err.message : String(err));
  }
  /** Parses CSV text into rows of numbers; lines that are not all numbers (headers) are skipped. */
  function csvRows(text) {
    const rows = [];
    for (const line of text.split(/\r?\n/)) {
      const cells = line.split(/[,;\t ]+/).filter((c) => c !== "");
      if (!cells.length) continue;
      const nums = cells.map(Number);
      if (nums.every(isFinite)) rows.push(nums);
    }
    return rows;
  }
  /** A file input that loads a local file's text into `textarea` (read in the browser). */
  function fileInto(textarea) {
    const input = h("input", { type: "file", accept: ".csv,.txt,.nc,.tap,.gcode,text/*" });
    input.addEventListener("change", () => {
      const f = input.files[0];
      if (f) f.text().then((t) => { textarea.value = t; });
    });
    return input;
  }

  const views = [];
  /** Registers a view: `pattern` a RegExp over the hash path, `render(main, match)` async. */
  function view(pattern, render) { views.push({ pattern, render }); }

  function crumbs(path) {
    const nav = document.getElementById("crumbs");
    nav.textContent = "";
    const parts = path.split("/").filter(Boolean);
    const items = [["#/", "machines"]];
    if (parts[0] === "m" && parts[1]) {
      items.push([`#/m/${parts[1]}`, decodeURIComponent(parts[1])]);
      if (parts[2] === "s" && parts[3]) items.push([`#/m/${parts[1]}/s/${parts[3]}`, decodeURIComponent(parts[3])]);
      if (parts[4] === "meas" && parts[5]) items.push([`#/m/${parts[1]}/s/${parts[3]}/meas/${parts[5]}`, decodeURIComponent(parts[5])]);
    }
    items.forEach(([href, label], i) => {
      if (i) nav.append(h("span", { class: "sep" }, "›"));
      nav.append(link(href, label));
    });
  }

  let generation = 0;
  async function route() {
    const path = (location.hash || "#/").slice(1) || "/";
    const main = document.getElementById("main");
    const mine = ++generation;
    document.body.dataset.state = "loading";
    main.textContent = "";
    crumbs(path);
    const found = views.map((v) => [v, path.match(v.pattern)]).find(([, m]) => m);
    if (!found) {
      main.append(problemBox(`no such page: ${path}`));
      document.body.dataset.state = "error";
      return;
    }
    try {
      await found[0].render(main, found[1].map((x) => (x === undefined ? x : decodeURIComponent(x))));
      if (mine === generation) document.body.dataset.state = main.querySelector(".problem") ? "error" : "ready";
    } catch (err) {
      if (mine !== generation) return;
      main.append(problemBox(err));
      document.body.dataset.state = "error";
    }
  }
  window.addEventListener("hashchange", route);
  window.addEventListener("DOMContentLoaded", route);

  /**
   * Runs `work` (async, drawing into `out`) now and again on each click of `button`,
   * showing an API problem in `out` instead of throwing.
   */
  async function runner(button, out, work) {
    const go = async () => {
      out.textContent = "";
      document.body.dataset.state = "loading";
      try {
        await work(out);
        document.body.dataset.state = out.querySelector(".problem") ? "error" : "ready";
      } catch (err) {
        out.append(problemBox(err));
        document.body.dataset.state = "error";
      }
    };
    button.addEventListener("click", (e) => { e.preventDefault(); go(); });
    await go();
  }

  return { api, h, link, enc, table, figures, mm, um, problemBox, csvRows, fileInto, view, runner, Problem };
})();
