// truecut dashboard views: machines → surfaces → measurements (deviation maps before and
// after compensation, decomposition, offsets), part gap diagnosis, contour error and the
// volumetric map's ISO 230-1 component curves.
"use strict";

(() => {
  const { api, h, link, enc, table, figures, mm, um, view, runner } = App;
  const COLOURS = ["#1f5f99", "#c0392b", "#2e8b57", "#8e44ad", "#d35400", "#16a085"];
  const rms = (a) => Math.sqrt(a.reduce((s, v) => s + v * v, 0) / Math.max(1, a.length));
  const maxAbs = (a) => a.reduce((m, v) => Math.max(m, Math.abs(v)), 0);

  /** Whether machine `m` has a volumetric map, from the machine list (which says what each
   *  machine has), so that no view asks for a map that does not exist. */
  async function hasVolumetricMap(m) {
    return (await machineRecord(m)).volumetric_map;
  }
  /** What machine `m` has ({volumetric_map, effects}), from the machine list. */
  async function machineRecord(m) {
    const { machines } = await api("GET", "/v1/machines");
    const rec = machines.find((x) => x.id === m) || {};
    return { volumetric_map: !!rec.volumetric_map, effects: !!rec.effects };
  }
  const paramText = (p) => Object.entries(p || {}).map(([k, x]) => `${k} = ${Number(x).toPrecision(4)}`).join(", ");

  /** The effects stored with machine `m` (what every simulation of it adds), their versions
   *  and a button per kept version to serve it again. */
  async function storedEffects(m, box) {
    box.textContent = "";
    box.append(h("h3", {}, "Stored effects (added to every simulation of this machine)"));
    if (!(await machineRecord(m)).effects) {
      box.append(h("p", { class: "none" }, "Stored effects: none yet. Accept them from a gap diagnosis (motion): contour error, compensated programs and the next diagnosis then include them."));
      return;
    }
    const base = `/v1/machines/${enc(m)}/effects`;
    const [cur, v] = await Promise.all([api("GET", base), api("GET", `${base}/versions`)]);
    box.append(h("p", { class: "note" }, `Stored effects, version ${cur.version}${cur.source ? " (from " + cur.source + ")" : ""}.`),
      table(["effect", "parameters"], cur.effects.map((e) => [e.effect, paramText(e.params)])));
    box.append(h("h3", {}, "Versions"), table(["version", "saved", "served"], v.versions.map((x) => {
      const b = h("button", { class: "rollback" }, "serve this version");
      b.addEventListener("click", async (e) => {
        e.preventDefault();
        document.body.dataset.state = "loading";
        await api("POST", `${base}/rollback`, { version: x.version });
        await storedEffects(m, box);
        document.body.dataset.state = "ready";
      });
      return [x.version, (x.created_at || "").replace("T", " ").slice(0, 19), x.version === v.current ? "served now" : b];
    })));
  }

  // ── machines ───────────────────────────────────────────────────────────────────────
  view(/^\/$/, async (main) => {
    const { machines } = await api("GET", "/v1/machines");
    main.append(h("h2", {}, "Machines"));
    if (!machines.length) {
      main.append(h("p", { class: "note" }, "No machine is defined yet: PUT /v1/machines/{id} (or start the server with --demo)."));
    }
    main.append(table(["machine", "name", "kinematics", "views"], machines.map((m) => [
      link(`#/m/${enc(m.id)}`, m.id), m.name || "", m.kinematics,
      h("span", { class: "links" }, link(`#/m/${enc(m.id)}/cam`, "CAM: compensate a program"), link(`#/m/${enc(m.id)}/contour`, "contour error"),
        link(`#/m/${enc(m.id)}/gap`, "gap diagnosis (motion)"),
        m.volumetric_map ? link(`#/m/${enc(m.id)}/volumetric`, "volumetric map") : h("span", { class: "none" }, "volumetric map: none yet")),
    ])));
    main.append(h("h3", {}, "Metrology (no machine needed)"),
      h("p", { class: "links" }, link("#/iso230-2", "ISO 230-2 positioning accuracy"), link("#/iso230-4", "ISO 230-4 circular test")));
  });

  // ── one machine ────────────────────────────────────────────────────────────────────
  view(/^\/m\/([^/]+)$/, async (main, [, m]) => {
    const [def, { surfaces }, hasMap] = await Promise.all([
      api("GET", `/v1/machines/${enc(m)}`), api("GET", `/v1/machines/${enc(m)}/surfaces`), hasVolumetricMap(m)]);
    main.append(h("h2", {}, `Machine ${m}${def.name ? ": " + def.name : ""}`));
    main.append(h("p", { class: "links" }, link(`#/m/${enc(m)}/cam`, "CAM: compensate a program"), link(`#/m/${enc(m)}/contour`, "Contour error of a program"),
      link(`#/m/${enc(m)}/gap`, "Sim-to-real gap diagnosis (motion)"),
      hasMap ? link(`#/m/${enc(m)}/volumetric`, "Volumetric map (ISO 230-1 components)") : h("span", { class: "none" }, "Volumetric map: none yet")));
    const axes = def.axes || {};
    main.append(h("h3", {}, `Servo models (kinematics ${def.kinematics})`),
      table(["axis", "kv (1/s)", "kff", "kp_v (1/s)", "ti_v (s)", "tc (s)"], Object.keys(axes).map((a) => [
        a, ...["kv", "kff", "kp_v", "ti_v", "tc"].map((k) => (axes[a][k] === undefined ? "–" : axes[a][k]))])));
    const effectsBox = h("div");
    main.append(effectsBox);
    await storedEffects(m, effectsBox);
    main.append(h("h3", {}, "Surfaces"));
    if (!surfaces.length) main.append(h("p", { class: "note" }, "No surface on this machine."));
    else main.append(table(["surface", "grid (nu × nv)", "tool radius", "measurements"], surfaces.map((s) => [
      link(`#/m/${enc(m)}/s/${enc(s.id)}`, s.id), `${s.nu} × ${s.nv}`, s.tool_radius ? mm(s.tool_radius, 2) : "–", s.measurements])));
  });

  // ── one surface ────────────────────────────────────────────────────────────────────
  view(/^\/m\/([^/]+)\/s\/([^/]+)$/, async (main, [, m, s]) => {
    const base = `/v1/machines/${enc(m)}/surfaces/${enc(s)}`;
    const [surf, { measurements }] = await Promise.all([api("GET", base), api("GET", `${base}/measurements`)]);
    const g = surf.nominal.grid;
    main.append(h("h2", {}, `Surface ${s}${surf.name ? ": " + surf.name : ""}`),
      h("p", { class: "note" }, `${g.nu} × ${g.nv} grid points; tool radius ${surf.tool_radius ? mm(surf.tool_radius, 2) : "not given"}.`));
    main.append(h("h3", {}, "Probe measurements"));
    main.append(table(["measurement", "points", "max |deviation|", "mean |deviation|", "measured at", "views"], measurements.map((x) => [
      link(`#/m/${enc(m)}/s/${enc(s)}/meas/${enc(x.id)}`, x.id), x.n, mm(x.max_abs), mm(x.mean_abs),
      x.created_at_ms ? new Date(x.created_at_ms).toISOString().replace("T", " ").slice(0, 19) + " UTC" : "–",
      h("span", { class: "links" }, link(`#/m/${enc(m)}/s/${enc(s)}/meas/${enc(x.id)}`, "deviation map"),
        link(`#/m/${enc(m)}/s/${enc(s)}/meas/${enc(x.id)}/gap`, "gap diagnosis (part)"))])));
  });

  // ── one measurement: deviation map, decomposition, compensation ─────────────────────
  view(/^\/m\/([^/]+)\/s\/([^/]+)\/meas\/([^/]+)$/, async (main, [, m, s, id]) => {
    const base = `/v1/machines/${enc(m)}/surfaces/${enc(s)}`;
    const [surf, meas] = await Promise.all([api("GET", base), api("GET", `${base}/measurements/${enc(id)}`)]);
    const dec = await api("POST", `${base}/measurements/${enc(id)}/decomposition`, {});
    const comp = await api("GET", `${base}/compensation?measurement=${enc(id)}`);
    const g = surf.nominal.grid, dev = meas.deviations;
    const after = dev.map((d, k) => d - comp.offsets[k]);
    const outliers = new Set(dec.outliers || []);
    const afterKept = after.filter((_, k) => !outliers.has(k));
    main.append(h("h2", {}, `Measurement ${id} on ${s}`));
    main.append(h("p", { class: "note" },
      `Deviation along the outward normal, measured − nominal (positive: material left). Decomposition ${dec.method}: ` +
      `systematic + random = measured. The compensation moves each point by its offset against the normal, so the ` +
      `deviation expected after compensation is measured − offset, the random part` +
      (outliers.size ? `; ${outliers.size} probe flyer(s) were left out of the systematic part.` : ".")));
    main.append(figures([
      [mm(rms(dev)), "RMS deviation before"], [mm(maxAbs(dev)), "max |deviation| before"],
      [mm(rms(afterKept)), "RMS after compensation (predicted)"], [mm(maxAbs(afterKept)), "max |deviation| after (predicted)"],
      [mm(maxAbs(comp.offsets)), "largest compensation offset"], [String(outliers.size), "probe flyers"]]));
    const plots = h("div", { class: "plots" });
    main.append(plots);
    const vmax = maxAbs(dev);
    const hm = (title, values, v) => Plot.heatmap(plots, { title, nu: g.nu, nv: g.nv, points: g.points, values, unit: "mm", vmax: v });
    hm("Deviation before compensation (mm)", dev, vmax);
    hm("Deviation after compensation, predicted (mm, same scale)", after, vmax);
    hm(`Systematic part (${dec.method}, mm)`, dec.systematic);
    hm("Random part (mm)", dec.random);
    hm("Compensation offsets (mm, point moved against the normal)", comp.offsets);
    // A profile along u through the middle row shows the parts as lines.
    const iv = Math.floor(g.nv / 2), ks = [...Array(g.nu).keys()].map((iu) => iv * g.nu + iu);
    const [a] = [0, 1, 2].filter((k) => Math.abs(g.points[ks[ks.length - 1]][k] - g.points[ks[0]][k]) > 0).slice(0, 1);
    const xs = ks.map((k) => g.points[k][a === undefined ? 0 : a]);
    Plot.lines(plots, {
      title: `Profile at v index ${iv}: measured = systematic + random (random = after compensation)`,
      xlabel: `${"xyz"[a || 0]} (mm)`, ylabel: "deviation (mm)", hline: 0,
      series: [
        { x: xs, y: ks.map((k) => dev[k]), label: "measured", colour: "#555", dots: true, width: 1 },
        { x: xs, y: ks.map((k) => dec.systematic[k]), label: "systematic", colour: COLOURS[0], width: 2.2 },
        { x: xs, y: ks.map((k) => dec.random[k]), label: "random", colour: COLOURS[1], width: 1.2 },
      ],
    });
  });

  // ── part gap diagnosis ──────────────────────────────────────────────────────────────
  view(/^\/m\/([^/]+)\/s\/([^/]+)\/meas\/([^/]+)\/gap$/, async (main, [, m, s, id]) => {
    const base = `/v1/machines/${enc(m)}/surfaces/${enc(s)}`;
    const [surf, meas, { measurements }] = await Promise.all([api("GET", base), api("GET", `${base}/measurements/${enc(id)}`), api("GET", `${base}/measurements`)]);
    const g = surf.nominal.grid;
    main.append(h("h2", {}, `Sim-to-real gap of part ${id} on ${s}`),
      h("p", { class: "note" }, "The gap is the measured deviation minus the service's prediction for this machine and surface. " +
        "The diagnosis says where on the part it lies (outlined regions), which effect explains it (scores: held-out share of the gap removed), and, with a second part as validation, how far the effect fitted on this part shrinks the gap on the other."));
    const select = h("select", {}, h("option", { value: "" }, "none"),
      ...measurements.filter((x) => x.id !== id).map((x) => h("option", { value: x.id }, x.id)));
    // Validate on another part by default when the surface has one.
    if (select.options.length > 1) select.selectedIndex = 1;
    const button = h("button", {}, "Diagnose");
    main.append(h("form", { class: "inputs" }, h("div", {}, h("label", {}, "Validation part (another measurement of this surface)"), select), h("div", {}, button)));
    const out = h("div");
    main.append(out);
    await runner(button, out, async (out) => {
      const body = { domain: "part", surface: s, measurement: id };
      if (select.value) body.validation = { measurement: select.value };
      const d = await api("POST", `/v1/machines/${enc(m)}/gap-diagnosis`, body);
      out.append(figures([[d.verdict, "verdict: the effect found"], [mm(d.gap_before.rms), "gap RMS before"], [mm(d.gap_after.rms), "gap RMS with the effect"],
        [mm(d.gap_before.max), "gap max before"], [mm(d.gap_after.max), "gap max with the effect"], [d.predicted_source, "prediction subtracted"]]));
      const plots = h("div", { class: "plots" });
      out.append(plots);
      Plot.heatmap(plots, {
        title: d.predicted_source === "zero" ? "Gap = measured deviation (no prediction stored), mm" : "Measured deviation (mm); regions where the gap lies",
        nu: g.nu, nv: g.nv, points: g.points, values: meas.deviations, unit: "mm",
        rects: d.where.slice(0, 4).map((w, i) => ({ u: w.u, v: w.v, label: `${i + 1}: ${(w.share * 100).toFixed(0)} %` })),
      });
      const eff = d.effects || [];
      Plot.bars(plots, { title: "Effects: held-out score (share of the gap removed)", labels: eff.map((e) => e.effect), values: eff.map((e) => e.score || 0), ylabel: "score (0–1)", valueFmt: (v) => v.toFixed(2) });
      if (d.validation) {
        Plot.bars(plots, { title: `Validation on part ${select.value}: gap RMS (µm)`, labels: ["before", `with ${d.verdict}`], values: [d.validation.rms_before * 1000, d.validation.rms_after * 1000], ylabel: "RMS gap (µm)", colours: ["#c0392b", "#2e8b57"], valueFmt: (v) => v.toFixed(2) });
      } else {
        out.append(h("p", { class: "note" }, "Validation: choose a second measurement of this surface above to see the gap before and after on a part the effect was not fitted on."));
      }
      out.append(h("h3", {}, "Where the gap lies (largest share first)"),
        App.table(["#", "region", "u index", "v index", "share of the squared gap"], d.where.map((w, i) => [i + 1, w.label, `${w.u[0]}–${w.u[1]}`, `${w.v[0]}–${w.v[1]}`, `${(w.share * 100).toFixed(1)} %`])));
      out.append(h("h3", {}, "Effects"), App.table(["effect", "score", "parameters"], eff.map((e) => [e.effect, e.score === null ? "–" : Number(e.score).toFixed(3),
        Object.entries(e.params || {}).map(([k, v]) => `${k} = ${Number(v).toPrecision(4)}`).join(", ")])));
    });
  });

  // ── contour error of a program ──────────────────────────────────────────────────────
  const DEMO_PROGRAM = [
    "(demo: a 40 mm circle at F3000, then a 60 x 40 mm pocket outline with sharp corners at F4000)",
    "G21 G90 G17", "G0 X20 Y0 Z0", "G2 X20 Y0 I-20 J0 F3000",
    "G1 X30 Y0 F4000", "G1 X30 Y-20", "G1 X-30 Y-20", "G1 X-30 Y20", "G1 X30 Y20", "G1 X30 Y0", "M30"].join("\n");
  view(/^\/m\/([^/]+)\/contour$/, async (main, [, m]) => {
    main.append(h("h2", {}, `Contour error on machine ${m}`),
      h("p", { class: "note" }, "The program is interpolated on this machine and run through its servo models; the contour error is the distance from the simulated tool tip to the programmed path. The demo program is filled in; paste or load your own."));
    const code = h("textarea", { spellcheck: "false", "aria-label": "G-code program" });
    code.value = DEMO_PROGRAM;
    const period = h("input", { type: "number", value: "0.001", step: "0.0005", min: "0.0001" });
    const button = h("button", {}, "Simulate");
    main.append(h("form", { class: "inputs" }, h("div", {}, h("label", {}, "G-code program"), code, App.fileInto(code)),
      h("div", {}, h("label", {}, "Interpolation period (s)"), period, h("p", {}, button))));
    const out = h("div");
    main.append(out);
    await runner(button, out, async (out) => {
      const d = await api("POST", `/v1/machines/${enc(m)}/contour-error`, { gcode: code.value, period_s: Number(period.value) });
      const lines = code.value.split(/\r?\n/);
      const runTime = d.settle ? d.settle.command_end_s : (d.t[d.t.length - 1] || 0);
      out.append(figures([[mm(d.max), "max contour error"], [mm(d.rms), "RMS contour error"], [`${d.t.length}`, "interpolation periods"],
        [`${runTime.toFixed(2)} s`, "run time"], [d.settle ? `${d.settle.settle_s.toFixed(3)} s` : "–", "servo run-out after the last command"]]));
      if (d.settle) out.append(h("p", { class: "note" }, `run-out: ${d.settle.note}`));
      for (const w of d.warnings || []) out.append(h("p", { class: "note" }, `reader: ${w}`));
      const plots = h("div", { class: "plots" });
      out.append(plots);
      // Worst blocks: the largest contour error while each program line executes.
      const worst = new Map();
      (d.line || []).forEach((ln, i) => { const e = d.contour_error[i]; const w = worst.get(ln); if (!w || e > w.e) worst.set(ln, { e, t: d.t[i], i }); });
      const rows = [...worst.entries()].sort((a, b) => b[1].e - a[1].e).slice(0, 8);
      Plot.colouredPath(plots, {
        title: "Tool path coloured by contour error; circled: the 3 worst blocks",
        x: d.actual.map((p) => p[0]), y: d.actual.map((p) => p[1]), values: d.contour_error, unit: "mm",
        refX: d.commanded.map((p) => p[0]), refY: d.commanded.map((p) => p[1]), xlabel: "X (mm)", ylabel: "Y (mm)",
        marks: rows.slice(0, 3).map(([ln, w], k) => ({ x: d.actual[w.i][0], y: d.actual[w.i][1], label: `${k + 1}: line ${ln}` })),
      });
      Plot.lines(plots, { title: "Contour error over time", xlabel: "time (s)", ylabel: "contour error (mm)", series: [{ x: d.t, y: d.contour_error, colour: COLOURS[0] }] });
      out.append(h("h3", {}, "Worst blocks"), table(["#", "program line", "block", "max contour error", "at time"], rows.map(([ln, w], k) => [
        k + 1, ln, h("code", {}, (lines[ln - 1] || "").trim()), mm(w.e), `${w.t.toFixed(3)} s`])));
    });
  });

  // ── volumetric map: ISO 230-1 components ────────────────────────────────────────────
  view(/^\/m\/([^/]+)\/volumetric$/, async (main, [, m]) => {
    main.append(h("h2", {}, `Volumetric error map of machine ${m}`));
    if (!(await hasVolumetricMap(m))) {
      main.append(h("p", { class: "note" }, "Volumetric map: none yet. Measure the machine's positioning errors at grid nodes and PUT them to " +
        `/v1/machines/${m}/volumetric-map (body {"nodes": [[x, y, z]], "errors": [[dx, dy, dz]]}); this view then shows the map's ISO 230-1 components.`));
      return;
    }
    const d = await api("GET", `/v1/machines/${enc(m)}/volumetric-map?samples=41`);
    main.append(h("p", { class: "note" }, "The 21 ISO 230-1 error parameters of the X-Y-Z chain identified from the measured grid: per axis three translational error motions (positioning along the axis, two straightness) in µm and three rotational (roll, pitch, yaw) in µrad, relative to the axis start; and three squareness errors."));
    const figs = [[d.model || "–", "model"]];
    if (d.fit_rms_mm !== undefined) figs.push([mm(d.fit_rms_mm), "fit RMS at the nodes"]);
    if (d.n_nodes !== undefined) figs.push([String(d.n_nodes), "measured nodes"]);
    main.append(figures(figs));
    const comp = d.components;
    if (!comp) {
      main.append(App.problemBox("this map has no ISO 230-1 components (fit it with model kinematic or hybrid)"));
      return;
    }
    const plots = h("div", { class: "plots" });
    main.append(plots);
    const absent = [];
    for (const ax of comp.axes) {
      for (const [lo, unit, what] of [[0, "µm", "translational"], [3, "µrad", "rotational"]]) {
        const cs = ax.curves.slice(lo, lo + 3);
        const series = cs.filter((c) => c.values).map((c, i) => ({ x: ax.position_mm, y: c.values, label: `${c.name} (${c.kind})`, colour: COLOURS[i + lo] }));
        const missing = cs.filter((c) => !c.values).map((c) => c.name);
        if (!series.length) {
          absent.push(`${ax.axis} axis ${what} error motions (${missing.join(", ")})`);
          continue;
        }
        Plot.lines(plots, {
          title: `${ax.axis} axis: ${what} error motions${missing.length ? " (not identifiable: " + missing.join(", ") + ")" : ""}`,
          xlabel: `${ax.axis} position (mm)`, ylabel: `error (${unit})`, hline: 0, series,
        });
      }
    }
    Plot.bars(plots, { title: "Squareness errors (µrad)", labels: comp.squareness.map((q) => q.name), values: comp.squareness.map((q) => q.value_urad), ylabel: "squareness (µrad)", valueFmt: (v) => v.toFixed(1) });
    if (absent.length) main.append(h("p", { class: "note" }, `Not drawn, none of them identifiable from these nodes: ${absent.join("; ")}.`));
    if ((comp.notes || []).length) main.append(h("h3", {}, "Notes"), h("ul", {}, ...comp.notes.map((n) => h("li", {}, n))));
  });
})();

// ── the API reference: every route of openapi.yaml with its summary ─────────────────────
(() => {
  const { h, table, view } = App;
  view(/^\/api$/, async (main) => {
    const r = await fetch("/openapi.yaml");
    if (!r.ok) throw new App.Problem(r.status, await r.text());
    const text = await r.text();
    // The spec's layout: paths at two spaces, methods at four, their summary at six.
    const rows = [];
    let path = null, method = null, inPaths = false;
    for (const line of text.split("\n")) {
      if (/^\S/.test(line)) inPaths = line.startsWith("paths:");
      if (!inPaths) continue;
      let m;
      if ((m = line.match(/^  (\/\S*):\s*$/))) { path = m[1]; method = null; }
      else if ((m = line.match(/^    (get|put|post|delete|patch):\s*$/))) { method = m[1].toUpperCase(); rows.push([method, path, ""]); }
      else if (method && (m = line.match(/^      summary:\s*(.*)$/))) rows[rows.length - 1][2] = m[1].replace(/^'(.*)'$/, "$1");
    }
    main.append(h("h2", {}, "API reference"),
      h("p", { class: "note" }, "Every route this server answers, from its openapi.yaml (request and answer schemas are in the file itself). Send Authorization: Bearer TOKEN when tokens are configured."),
      h("p", {}, h("a", { href: "/openapi.yaml" }, "openapi.yaml (raw)")),
      table(["method", "path", "what it does"], rows.map(([me, p, s]) => [me, h("code", {}, p), s])));
  });
})();
