// truecut dashboard: the CAM loop. A program (pasted or loaded) is compensated by the service
// (volumetric and/or contour, POST .../compensated-program); both the original and the
// compensated program are run through this machine's servo simulation (POST .../contour-error)
// and, when the machine has a volumetric map, its geometric error (POST .../compensated-points),
// and the predicted tool tip is drawn against the original programmed path, coloured by its
// distance from it in µm. The compensated program can be downloaded.
"use strict";

(() => {
  const { api, h, enc, table, figures, view, runner } = App;

  // Inside the demo machining centre's 800 x 500 x 400 mm box with G54 at its middle.
  const DEMO_PROGRAM = [
    "%", "O2001 (DEMO BRACKET - 120 X 80 MM OUTLINE R10 CORNERS, 30 MM BORE, D10 END MILL)",
    "N10 G21 G90 G17 G40 G80 G54", "N20 T1 M6", "N30 S9000 M3",
    "N40 G0 X-60. Y-30. Z5.", "N50 G1 Z-2. F300", "N60 G3 X-50. Y-40. I10. J0 F3000",
    "N70 G1 X50.", "N80 G3 X60. Y-30. R10.", "N90 G1 Y30.", "N100 G3 X50. Y40. R10.",
    "N110 G1 X-50.", "N120 G3 X-60. Y30. R10.", "N130 G1 Y-30.", "N140 G0 Z5.",
    "N150 X15. Y0", "N160 G1 Z-2. F300", "N170 G3 X15. Y0 I-15. J0 F2000", "N180 G0 Z5.",
    "N190 M5", "N200 M30", "%"].join("\n");
  const DEMO_OFFSET = "400, 250, 200";
  const BEFORE = "#c0392b", AFTER = "#1e8449", ORIGINAL = "#7f8c99", COMPENSATED = "#1f5f99";

  /** The polyline without consecutive repeats (stops), as [x, y, z] mm, with each point's line. */
  function distinct(points, lines) {
    const pts = [], at = [];
    points.forEach((p, i) => {
      const q = [p[0], p[1], p[2] || 0], r = pts[pts.length - 1];
      if (!r || Math.hypot(q[0] - r[0], q[1] - r[1], q[2] - r[2]) > 1e-9) { pts.push(q); at.push(lines[i]); }
    });
    return { pts, lines: at };
  }

  /**
   * Which lines of a program move at rapid (G0, modal): their samples are left out of the
   * errors and the drawings (the drawing asks nothing of a rapid). Canned cycles count as
   * cutting.
   */
  function rapidLines(text) {
    let mode = 1;
    return [false].concat(text.split(/\r?\n/).map((raw) => {
      const line = raw.replace(/\([^)]*\)/g, "").replace(/;.*$/, "").toUpperCase();
      for (const m of line.matchAll(/G0*(\d+)(?![\d.])/g)) {
        const g = Number(m[1]);
        if (g <= 3 || (g >= 73 && g <= 89 && g !== 80)) mode = g;
      }
      return mode === 0;
    }));
  }

  /**
   * For each point of a run (in time order), its distance to the polyline `path` (mm), the
   * nearest point on it and how far along it that is (mm from the start). The nearest segment
   * is searched in a window that moves with the run (20 back, 600 ahead), so where the path
   * passes a place twice the run is matched to the pass it is on. Rapid segments
   * (`rapidSeg[j]`) add nothing to the length along the path.
   */
  function alongPath(run, path, rapidSeg) {
    const cum = [0];
    for (let j = 1; j < path.length; j++) {
      const a = path[j - 1], b = path[j];
      cum.push(cum[j - 1] + (rapidSeg[j - 1] ? 0 : Math.hypot(b[0] - a[0], b[1] - a[1], b[2] - a[2])));
    }
    const dist = [], foot = [], at = [];
    let k = 0;
    for (const p of run) {
      let best = Infinity, bf = path[0], ba = 0;
      const j1 = Math.min(path.length - 2, k + 600);
      for (let j = Math.max(0, k - 20); j <= j1; j++) {
        const a = path[j], b = path[j + 1];
        const dx = b[0] - a[0], dy = b[1] - a[1], dz = b[2] - a[2];
        const l2 = dx * dx + dy * dy + dz * dz;
        let t = l2 > 0 ? ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy + (p[2] - a[2]) * dz) / l2 : 0;
        t = Math.max(0, Math.min(1, t));
        const f = [a[0] + t * dx, a[1] + t * dy, a[2] + t * dz];
        const d2 = (f[0] - p[0]) ** 2 + (f[1] - p[1]) ** 2 + (f[2] - p[2]) ** 2;
        if (d2 < best) { best = d2; bf = f; ba = cum[j] + t * (cum[j + 1] - cum[j]); k = j; }
      }
      if (path.length < 2) best = (p[0] - bf[0]) ** 2 + (p[1] - bf[1]) ** 2 + (p[2] - bf[2]) ** 2;
      dist.push(Math.sqrt(best)); foot.push(bf); at.push(ba);
    }
    return { dist, foot, at };
  }

  /**
   * The predicted tool tip of a simulated run: the servo-simulated axis positions q plus the
   * machine's volumetric error e(q) when it has a map (compensated-points answers q − e(q)).
   */
  async function tips(m, actual, hasMap) {
    const q = actual.map((p) => [p[0], p[1], p[2] || 0]);
    if (!hasMap) return q;
    const out = [];
    for (let i = 0; i < q.length; i += 50000) {
      const chunk = q.slice(i, i + 50000);
      const r = await api("POST", `/v1/machines/${enc(m)}/compensated-points`, { points: chunk });
      r.points.forEach((c, k) => out.push([0, 1, 2].map((a) => 2 * chunk[k][a] - c[a])));
    }
    return out;
  }

  /** A round factor (1, 2 or 5 × 10^n, at least 1) that makes `dev` mm about `target` mm. */
  function magnification(dev, target) {
    if (!(dev > 0)) return 1;
    const raw = target / dev;
    const mag = Math.pow(10, Math.floor(Math.log10(raw)));
    const k = [5, 2, 1].map((f) => f * mag).find((f) => f <= raw) || mag;
    return Math.max(1, k);
  }
  const rms = (a) => { const f = a.filter(isFinite); return Math.sqrt(f.reduce((s, v) => s + v * v, 0) / Math.max(1, f.length)); };
  const max = (a) => a.reduce((s, v) => (isFinite(v) ? Math.max(s, v) : s), 0);
  const um = (mm, d) => `${(mm * 1000).toFixed(d === undefined ? 1 : d)} µm`;

  function offsets(text) {
    const v = text.split(/[,;\s]+/).filter((x) => x !== "").map(Number);
    if (!v.length) return undefined;
    if (v.length !== 3 || !v.every(isFinite)) throw new Error(`G54 work offset "${text}": give three numbers in mm (x, y, z in machine coordinates), or leave it empty`);
    return { G54: v };
  }

  view(/^\/m\/([^/]+)\/cam$/, async (main, [, m]) => {
    main.append(h("h2", {}, `CAM: compensate a program for machine ${m}`),
      h("p", { class: "note" }, "Paste or load the program your post wrote. The service compensates it (volumetric: each programmed point moved against the machine's volumetric error; contour: the motion rewritten as G1 points that the servo model follows along the original path). " +
        "Both programs are then run through this machine's simulation, and the predicted tool tip is drawn against the original programmed path, coloured by its distance from that path in µm. " +
        "A demo program and its G54 offset are filled in."));
    const code = h("textarea", { spellcheck: "false", "aria-label": "G-code program" });
    code.value = DEMO_PROGRAM;
    let fileName = "demo.nc";
    const file = App.fileInto(code);
    file.addEventListener("change", () => { if (file.files[0]) fileName = file.files[0].name; });
    const vol = h("input", { type: "checkbox", id: "cam-volumetric" });
    vol.checked = true;
    const volNote = h("span", { class: "note" }, " (on when the machine has a map)");
    const con = h("input", { type: "checkbox", id: "cam-contour" });
    con.checked = true;
    const g54 = h("input", { type: "text", value: DEMO_OFFSET, size: "18", "aria-label": "G54 work offset" });
    const period = h("input", { type: "number", value: "0.001", step: "0.0005", min: "0.0001" });
    const ratio = h("input", { type: "number", value: "1.15", step: "0.05", min: "1", max: "2", "aria-label": "longest duration, times the original's" });
    const button = h("button", {}, "Compensate");
    main.append(h("form", { class: "inputs" },
      h("div", {}, h("label", {}, "G-code program (work coordinates, mm or inch)"), code, file),
      h("div", {},
        h("p", {}, vol, h("label", { for: "cam-volumetric", class: "inline" }, " Volumetric pre-compensation"), volNote),
        h("p", {}, con, h("label", { for: "cam-contour", class: "inline" }, " Contour pre-distortion (servo model)")),
        h("label", {}, "G54 work offset: x, y, z (mm, machine coordinates)"), g54,
        h("label", {}, "Interpolation period (s)"), period,
        h("label", {}, "With contour: longest duration (× the original's; more lets close corners slow further)"), ratio,
        h("p", {}, button))));
    const out = h("div");
    main.append(out);
    let hasMap = null; // learnt from the first answer (volumetric left to the service)
    let downloadUrl = null;

    await runner(button, out, async (out) => {
      const period_s = Number(period.value);
      const work_offsets = offsets(g54.value);
      const common = { period_s };
      if (work_offsets) common.work_offsets = work_offsets;
      const body = Object.assign({ gcode: code.value, contour: con.checked }, common);
      if (con.checked) body.max_duration_ratio = Number(ratio.value);
      if (hasMap !== null) body.volumetric = vol.checked;
      const c = await api("POST", `/v1/machines/${enc(m)}/compensated-program`, body);
      if (hasMap === null) {
        hasMap = !!c.volumetric;
        if (!hasMap) { vol.checked = false; vol.disabled = true; volNote.textContent = " (this machine has no volumetric map)"; }
      }
      const [s0, s1] = await Promise.all([
        api("POST", `/v1/machines/${enc(m)}/contour-error`, Object.assign({ gcode: code.value }, common)),
        api("POST", `/v1/machines/${enc(m)}/contour-error`, Object.assign({ gcode: c.gcode }, common))]);
      const [t0, t1] = await Promise.all([tips(m, s0.actual, hasMap), tips(m, s1.actual, hasMap)]);
      // Rapid moves are left out: samples on G0 lines of the original (the compensated
      // program's lines map back to it through source_lines).
      const rapid = rapidLines(code.value);
      const srcLine = (l) => (c.source_lines || [])[l - 1] || 0;
      const lines0 = s0.line || [], lines1 = (s1.line || []).map(srcLine);
      const { pts: path, lines: pathLines } = distinct(s0.commanded, lines0);
      const rapidSeg = pathLines.slice(1).map((l) => rapid[l]);
      const cmd1 = distinct(s1.commanded, lines1);
      const before = alongPath(t0, path, rapidSeg), after = alongPath(t1, path, rapidSeg);
      const program = alongPath(cmd1.pts, path, rapidSeg);
      const cut = (near, lines) => near.dist.map((d, i) => (rapid[lines[i]] ? NaN : d));
      const e0 = cut(before, lines0), e1 = cut(after, lines1), ep = cut(program, cmd1.lines);

      const done = [c.volumetric ? "volumetric" : null, c.contour ? "contour" : null].filter(Boolean).join(" + ");
      out.append(figures([
        [um(rms(e0)), "RMS error before"], [um(rms(e1)), "RMS error after"],
        [um(max(e0)), "max error before"], [um(max(e1)), "max error after"],
        [c.volumetric ? um(c.max_shift_mm) : "–", "largest volumetric shift"], [done || "–", "compensation applied"],
        [String(c.blocks), "blocks in the compensated program"], [String(c.warnings.length), "warnings"]]));

      const xyz = ["X", "Y", "Z"];
      const cutPts = path.filter((_, j) => !rapid[pathLines[j]]);
      const spread = [0, 1, 2].map((a) => max(cutPts.map((p) => p[a])) - Math.min(...cutPts.map((p) => p[a])));
      const [ax, ay] = [0, 1, 2].sort((a, b) => spread[b] - spread[a]).slice(0, 2).sort();
      const k = magnification(Math.max(max(e0), max(e1), max(ep)), 0.06 * Math.max(spread[ax], spread[ay]));
      // Drawn: cutting samples only, deviations from the original path magnified k times.
      const magnify = (run, near, err) => run.map((p, i) => (isFinite(err[i]) ? near.foot[i].map((f, a) => f + k * (p[a] - f)) : [NaN, NaN, NaN]));
      const pc = magnify(cmd1.pts, program, ep), p0 = magnify(t0, before, e0), p1 = magnify(t1, after, e1);
      const pathCut = path.map((p, j) => (rapid[pathLines[j]] ? [NaN, NaN, NaN] : p));
      // One colour scale for both, to the 98th percentile so that a few plunge or corner
      // samples do not wash out the rest (above it: the top colour; the worst is circled).
      const p98 = (a) => { const f = a.filter(isFinite).sort((x, y) => x - y); return f.length ? f[Math.floor(0.98 * (f.length - 1))] : 0; };
      const hi = Math.max(1e-3, p98(e0) * 1000, p98(e1) * 1000);
      const worst = (p, err, lines) => {
        let w = -1;
        err.forEach((e, i) => { if (isFinite(e) && (w < 0 || e > err[w])) w = i; });
        return w < 0 ? [] : [{ x: p[w][ax], y: p[w][ay], label: `max ${um(err[w])}, line ${lines[w]}` }];
      };
      const xlabel = `${xyz[ax]} (mm, machine coordinates)`, ylabel = `${xyz[ay]} (mm)`;
      const times = k > 1 ? ` ×${k}` : "";
      const plots = h("div", { class: "plots" });
      out.append(plots);
      Plot.xy(plots, {
        title: `Programs: original and compensated (difference${times})`, xlabel, ylabel,
        series: [{ x: pathCut.map((p) => p[ax]), y: pathCut.map((p) => p[ay]), label: "original", colour: ORIGINAL, width: 3 },
          { x: pc.map((p) => p[ax]), y: pc.map((p) => p[ay]), label: `compensated (difference${times})`, colour: COMPENSATED, width: 1.3 }],
      });
      const legend = [{ label: "original path", colour: "#b8c0c8", dash: "3 2", width: 1.5 }, { label: `predicted tool tip (deviation${times})`, colour: Plot.errorColour(0.7, 1) }];
      const drawn = (title, p, err, lines) => Plot.colouredPath(plots, {
        title, legend, palette: "error", vmax: hi, unit: "error (µm)", xlabel, ylabel, marks: worst(p, err, lines),
        x: p.map((q) => q[ax]), y: p.map((q) => q[ay]), values: err.map((d) => d * 1000),
        refX: pathCut.map((q) => q[ax]), refY: pathCut.map((q) => q[ay]),
      });
      drawn(`Before: original program, ${um(rms(e0))} RMS`, p0, e0, lines0);
      drawn(`After: compensated, ${um(rms(e1))} RMS (same colours)`, p1, e1, lines1);
      Plot.lines(plots, {
        title: "Error along the path (tool tip to original path)",
        xlabel: "cutting length along the original path (mm)", ylabel: "error (µm)",
        series: [{ x: before.at, y: e0.map((d) => d * 1000), label: "before", colour: BEFORE, width: 1.2, gaps: true },
          { x: after.at, y: e1.map((d) => d * 1000), label: "after", colour: AFTER, width: 1.6, gaps: true }],
      });
      Plot.lines(plots, {
        title: "How far the compensated program moves from the original",
        xlabel: "cutting length along the original path (mm)", ylabel: "distance from the original program (µm)",
        series: [{ x: program.at, y: ep.map((d) => d * 1000), label: done || "none", colour: COMPENSATED, width: 1.2, gaps: true }],
      });
      Plot.bars(plots, {
        title: "Error before and after compensation (µm)", ylabel: "error (µm)",
        labels: ["RMS before", "RMS after", "max before", "max after"],
        values: [rms(e0), rms(e1), max(e0), max(e1)].map((v) => v * 1000),
        colours: [BEFORE, AFTER, BEFORE, AFTER], valueFmt: (v) => v.toFixed(2),
      });
      const what = hasMap ? "the servo simulation plus the machine's volumetric error" : "the servo simulation (this machine has no volumetric map)";
      out.append(h("p", { class: "note" }, `Predicted tool tip: ${what}, every ${period_s} s. Error: its distance (3-D) from the original programmed path, i.e. from what the drawing asks for; rapid (G0) moves are left out.` +
        (k > 1 ? ` In the drawings the deviations from the original path are magnified ×${k}; positions along the path are true.` : "") +
        ` Colours run from 0 to ${hi.toFixed(1)} µm (the 98th percentile); the few samples above it are drawn red and the largest is circled.` +
        (c.contour ? ` The service's own figures (servo only): contour error RMS ${um(c.contour.original_rms_mm, 2)} → ${um(c.contour.compensated_rms_mm, 2)}, max ${um(c.contour.original_max_mm, 2)} → ${um(c.contour.compensated_max_mm, 2)} after ${c.contour.iterations} iterations.` : "")));

      // The compensated program: download, text, and the first blocks it changed.
      if (downloadUrl) URL.revokeObjectURL(downloadUrl);
      downloadUrl = URL.createObjectURL(new Blob([c.gcode], { type: "text/plain" }));
      const outName = fileName.replace(/(\.[^.]*)?$/, (ext) => `_comp${ext || ".nc"}`);
      const text = h("textarea", { spellcheck: "false", readonly: "readonly", "aria-label": "compensated program", class: "program" });
      text.value = c.gcode;
      out.append(h("h3", {}, "Compensated program"),
        h("p", { class: "links" }, h("a", { href: downloadUrl, download: outName, "data-format": "gcode", class: "download" }, `Download ${outName}`),
          ` ${c.blocks} blocks; line endings, comments and non-motion words as in the original.`), text);
      const src = code.value.split(/\r?\n/), dst = c.gcode.split(/\r?\n/);
      const changed = [];
      dst.forEach((line, i) => {
        const from = (c.source_lines || [])[i];
        if (from && line !== src[from - 1]) changed.push([i + 1, from, h("code", {}, src[from - 1] || ""), h("code", {}, line)]);
      });
      out.append(h("h3", {}, `Changed blocks (${changed.length}; the first 15)`),
        table(["output line", "source line", "original block", "compensated block"], changed.slice(0, 15)));
      if (c.warnings.length) {
        out.append(h("details", { class: "warnings" }, h("summary", {}, `Warnings of the reader and the compensation (${c.warnings.length}; click to show)`),
          h("ul", {}, ...c.warnings.map((w) => h("li", {}, w)))));
      }
    });
  });
})();
