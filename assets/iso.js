// truecut dashboard: ISO 230-2 positioning accuracy and repeatability (deviation against
// position per approach direction, mean ± 2s) and ISO 230-4 circular test (polar plot of the
// radial deviation, magnified). Both post to the stateless routes; example data built in.
"use strict";

(() => {
  const { api, h, table, figures, um, view, runner, csvRows } = App;

  // Seeded noise so the examples are the same everywhere.
  function rng(seed) {
    let s = seed >>> 0;
    return () => { s = (s * 1664525 + 1013904223) >>> 0; return s / 4294967296 - 0.5; };
  }

  /** Example: an 800 mm axis, 11 targets, 5 cycles each way: pitch error, 6 µm reversal, 1 µm scatter. */
  function iso2302Example() {
    const r = rng(7), lines = ["target,fwd1,fwd2,fwd3,fwd4,fwd5,bwd1,bwd2,bwd3,bwd4,bwd5"];
    for (let i = 0; i <= 10; i++) {
      const t = i * 80 + (i % 2 ? 1.3 : 0); // ISO 230-2 asks for uneven target spacing
      const dev = 0.006 * Math.sin(t / 800 * 5.0) + 0.000012 * t;
      const fwd = [...Array(5)].map(() => t + dev + 0.0015 * r());
      const bwd = [...Array(5)].map(() => t + dev - 0.006 + 0.0015 * r());
      lines.push([t, ...fwd, ...bwd].map((v) => v.toFixed(4)).join(","));
    }
    return lines.join("\n");
  }

  view(/^\/iso230-2$/, async (main) => {
    main.append(h("h2", {}, "ISO 230-2: positioning accuracy and repeatability of an axis"),
      h("p", { class: "note" }, "One row per target: the target position, then the measured positions approached in the positive direction (one column per cycle), then as many approached in the negative direction; mm. An example axis is filled in. Deviation = measured − target."));
    const data = h("textarea", { spellcheck: "false", "aria-label": "ISO 230-2 readings" });
    data.value = iso2302Example();
    const button = h("button", {}, "Evaluate");
    const compMode = h("select", { "aria-label": "compensation table" },
      h("option", { value: "mode=mean" }, "mean deviation per target"),
      h("option", { value: "mode=model&fit_cyclic=true" }, "model: scale + backlash + fitted cyclic term"),
      h("option", { value: "mode=model" }, "model: scale + backlash"));
    const spacing = h("input", { type: "number", step: "any", min: "0.001", placeholder: "default", "aria-label": "table spacing (mm)" });
    main.append(h("form", { class: "inputs" }, h("div", {}, h("label", {}, "target, forward cycles…, backward cycles… (mm)"), data, App.fileInto(data)),
      h("div", {}, h("label", {}, "compensation table"), compMode, h("label", {}, "spacing of a model table (mm)"), spacing, h("div", {}, button))));
    const out = h("div");
    main.append(out);
    await runner(button, out, async (out) => {
      const rows = csvRows(data.value);
      if (!rows.length || (rows[0].length - 1) % 2) throw new Error("each row needs a target and the same number of forward and backward readings");
      const c = (rows[0].length - 1) / 2;
      const body = { targets: rows.map((r) => r[0]), forward: rows.map((r) => r.slice(1, 1 + c)), backward: rows.map((r) => r.slice(1 + c)) };
      const d = await api("POST", "/v1/iso230-2", body);
      out.append(figures([[um(d.A), "A: bidirectional accuracy"], [um(d.E), "E: systematic deviation"], [um(d.M), "M: mean bidirectional deviation"],
        [um(d.R), "R: bidirectional repeatability"], [um(d.B), "B: reversal value"], [um(d.B_avg), "mean reversal value"]]));
      const plots = h("div", { class: "plots" });
      out.append(plots);
      const x = d.targets.map((t) => t.target);
      const U = (v) => v * 1000;
      const fwdDots = [], bwdDots = [];
      body.targets.forEach((t, i) => {
        body.forward[i].forEach((p) => fwdDots.push([t, U(p - t)]));
        body.backward[i].forEach((p) => bwdDots.push([t, U(p - t)]));
      });
      Plot.lines(plots, {
        title: "Positional deviation against target, per approach direction",
        xlabel: "target position (mm)", ylabel: "deviation measured − target (µm)", hline: 0,
        bands: [
          { x, lo: d.targets.map((t) => U(t.mean_fwd - 2 * t.s_fwd)), hi: d.targets.map((t) => U(t.mean_fwd + 2 * t.s_fwd)), colour: "#1f5f99", label: "↑ mean ± 2s" },
          { x, lo: d.targets.map((t) => U(t.mean_bwd - 2 * t.s_bwd)), hi: d.targets.map((t) => U(t.mean_bwd + 2 * t.s_bwd)), colour: "#c0392b", label: "↓ mean ± 2s" },
        ],
        series: [
          { x, y: d.targets.map((t) => U(t.mean_fwd)), label: "↑ mean (+ approach)", colour: "#1f5f99", width: 2 },
          { x, y: d.targets.map((t) => U(t.mean_bwd)), label: "↓ mean (− approach)", colour: "#c0392b", width: 2 },
          { x: fwdDots.map((p) => p[0]), y: fwdDots.map((p) => p[1]), colour: "#1f5f99", dotsOnly: true },
          { x: bwdDots.map((p) => p[0]), y: bwdDots.map((p) => p[1]), colour: "#c0392b", dotsOnly: true },
        ],
      });
      Plot.lines(plots, {
        title: "Reversal value B and repeatability R per target",
        xlabel: "target position (mm)", ylabel: "value (µm)", hline: 0,
        series: [{ x, y: d.targets.map((t) => U(t.B)), label: "B_i (reversal)", colour: "#8e44ad", dots: true, width: 2 },
          { x, y: d.targets.map((t) => U(t.R)), label: "R_i (repeatability)", colour: "#2e8b57", dots: true, width: 2 }],
      });
      out.append(h("h3", {}, "Per target (µm)"), table(["target (mm)", "mean ↑", "mean ↓", "s ↑", "s ↓", "B", "R"],
        d.targets.map((t) => [t.target, ...[t.mean_fwd, t.mean_bwd, t.s_fwd, t.s_bwd, t.B, t.R].map((v) => Number((v * 1000).toFixed(2)))])));
      await compensationTable(out, body, compMode.value + (spacing.value && compMode.value !== "mode=mean" ? `&spacing_mm=${encodeURIComponent(spacing.value)}` : ""));
    });
  });

  /**
   * The axis's pitch-error compensation table of the evaluated readings: the predicted E and M
   * with it, the corrections per direction, and the LinuxCNC file and CSV to download (the
   * route's own text, as data: links so nothing is fetched again).
   */
  async function compensationTable(out, body, query) {
    const c = await api("POST", `/v1/iso230-2/compensation?${query}`, body);
    out.append(h("h3", {}, "Compensation table for the controller"),
      h("p", { class: "note" }, `Correction = what the controller adds to the commanded position = −(mean deviation), per approach direction, counted from the reference ${c.reference_mm} mm (${c.reference_rule === "named" ? "the target named" : "the first target approached forward"}; its forward correction is 0, so the measuring device's zero does not enter); interpolated between positions as LinuxCNC does. E and M after are predicted on these readings (each plus its correction).`),
      figures([[`${um(c.before.E)} → ${um(c.after.E)}`, "E with the table"], [`${um(c.before.M)} → ${um(c.after.M)}`, "M with the table"],
        [String(c.positions.length), c.mode === "model" ? `positions every ${c.spacing_mm} mm (model)` : "positions (the targets)"]]));
    const plots = h("div", { class: "plots" });
    out.append(plots);
    Plot.lines(plots, {
      title: "Compensation table: correction added to the command",
      xlabel: "position (mm)", ylabel: "correction (µm)", hline: 0,
      series: [{ x: c.positions, y: c.forward_correction.map((v) => v * 1000), label: "↑ forward", colour: "#1f5f99", width: 2, dots: c.mode === "mean" },
        { x: c.positions, y: c.backward_correction.map((v) => v * 1000), label: "↓ backward", colour: "#c0392b", width: 2, dots: c.mode === "mean" }],
    });
    const mode = c.mode;
    const links = await Promise.all([["linuxcnc", "txt", "LinuxCNC compensation file (COMP_FILE_TYPE = 1)"], ["csv", "csv", "CSV"]].map(async ([format, ext, label]) => {
      const text = await api("POST", `/v1/iso230-2/compensation?format=${format}&${query}`, body);
      return h("a", { class: "download", "data-format": format, download: `iso230-2-${mode}-comp.${ext}`,
        href: `data:text/plain;charset=utf-8,${encodeURIComponent(text)}` }, `Download ${label}`);
    }));
    out.append(h("p", { class: "links" }, ...links));
  }

  /** Example: a 50 mm circle, 720 points: 3 µm two-lobe ellipse, quadrant reversal spikes, 0.3 µm noise. */
  function iso2304Example() {
    const r = rng(11), lines = ["x,y"], R = 50, n = 720;
    for (let i = 0; i < n; i++) {
      const a = 2 * Math.PI * i / n;
      let dev = 0.003 * Math.cos(2 * (a - Math.PI / 4)) + 0.0003 * r();
      for (let q = 0; q < 4; q++) {
        const since = a - q * Math.PI / 2;
        const s = since < 0 ? since + 2 * Math.PI : since;
        dev += 0.005 * Math.exp(-s / 0.05);
      }
      lines.push(`${((R + dev) * Math.cos(a) + 0.002).toFixed(5)},${((R + dev) * Math.sin(a) - 0.001).toFixed(5)}`);
    }
    return lines.join("\n");
  }

  view(/^\/iso230-4$/, async (main) => {
    main.append(h("h2", {}, "ISO 230-4: circular test"),
      h("p", { class: "note" }, "Measured tool positions x,y (mm) around a programmed circle of the nominal radius, one per line, for example from a ballbar or the scales. An example run is filled in."));
    const data = h("textarea", { spellcheck: "false", "aria-label": "ISO 230-4 points" });
    data.value = iso2304Example();
    const radius = h("input", { type: "number", value: "50", step: "any", min: "0" });
    const button = h("button", {}, "Evaluate");
    main.append(h("form", { class: "inputs" }, h("div", {}, h("label", {}, "points x,y (mm)"), data, App.fileInto(data)),
      h("div", {}, h("label", {}, "nominal radius (mm)"), radius, h("p", {}, button))));
    const out = h("div");
    main.append(out);
    await runner(button, out, async (out) => {
      const points = csvRows(data.value).map((r) => r.slice(0, 2));
      const d = await api("POST", "/v1/iso230-4", { points, radius: Number(radius.value) });
      out.append(figures([[um(d.G), "G: circular deviation"], [um(d.F_max), "F max: radius deviation"], [um(d.F_min), "F min: radius deviation"],
        [`${d.radius_fit.toFixed(4)} mm`, "least-squares radius"], [`(${d.centre.map((v) => v.toFixed(4)).join(", ")}) mm`, "least-squares centre"]]));
      const [cx, cy] = d.centre;
      const angles = points.map((p) => Math.atan2(p[1] - cy, p[0] - cx));
      const dev = points.map((p) => (Math.hypot(p[0] - cx, p[1] - cy) - d.radius_fit) * 1000);
      const top = Math.max(...dev.map(Math.abs));
      // The dashed rings sit at ± a round value at least the largest deviation.
      const step = Plot.niceTicks(0, top || 1, 2).step;
      const ring = step * Math.max(1, Math.ceil(top / step - 1e-9));
      const plots = h("div", { class: "plots" });
      out.append(plots);
      Plot.polar(plots, {
        title: "Radial deviation about the least-squares circle (magnified)",
        ringUm: ring, ringStep: step,
        series: [{ angles, dev, colour: "#1f5f99", label: "measured path" }],
        notes: [`dashed rings: ±${Plot.fmt(ring, step)} µm`, `G = ${(d.G * 1000).toFixed(2)} µm`, `radius ${d.radius_fit.toFixed(3)} mm`],
      });
      Plot.lines(plots, { title: "Radial deviation against angle", xlabel: "angle (°)", ylabel: "radial deviation (µm)", hline: 0,
        xr: [0, 360], xticks: Object.assign([0, 45, 90, 135, 180, 225, 270, 315, 360], { step: 1 }),
        series: [{ x: angles.map((a) => ((a * 180 / Math.PI) + 360) % 360), y: dev, colour: "#1f5f99", dotsOnly: true }] });
      const extra = Object.keys(d).filter((k) => !["G", "F_max", "F_min", "centre", "radius_fit"].includes(k));
      if (extra.length) out.append(h("h3", {}, "Further figures"), table(["name", "value"], extra.map((k) => [k, JSON.stringify(d[k]).slice(0, 200)])));
    });
  });
})();
