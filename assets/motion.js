// truecut dashboard: sim-to-real gap diagnosis of a motion (a program or commanded positions
// against measured positions), with a built-in demo run.
"use strict";

(() => {
  const { api, h, enc, table, figures, um, view, runner, csvRows } = App;

  const MAIN = ["(demo run: a 60 x 30 mm rectangle twice, X reverses at both ends)", "G21 G90 G17", "G0 X0 Y0",
    "G1 X60 Y0 F3000", "G1 X60 Y30", "G1 X0 Y30", "G1 X0 Y0", "G1 X60 Y0", "G1 X60 Y30", "G1 X0 Y30", "G1 X0 Y0"].join("\n");
  const VALIDATION = ["(validation run: a different shape and feed)", "G21 G90 G17", "G0 X0 Y0",
    "G1 X40 Y10 F2000", "G1 X10 Y25", "G1 X50 Y25", "G1 X0 Y0"].join("\n");
  const BACKLASH_MM = 0.008;

  /**
   * The demo's "measured" run: this machine's own servo simulation of the program (from the
   * contour-error route) with 8 µm of X backlash and 0.5 µm of seeded noise added, so the
   * diagnosis has a known answer (backlash).
   */
  async function demoRun(m, gcode) {
    // the truth is the servo model alone plus the backlash, whatever the machine has stored
    const sim = await api("POST", `/v1/machines/${enc(m)}/contour-error`, { gcode, period_s: 0.001, effects: "none" });
    let seed = 12345;
    const noise = () => { seed = (seed * 1103515245 + 12345) % 2147483648; return (seed / 2147483648 - 0.5) * 0.001; };
    // Play operator: the table follows the simulated drive on X only once the drive has
    // crossed the play; it starts at the end of the play a move in +X leaves it at.
    const half = BACKLASH_MM / 2;
    let table = sim.actual[0][0] - half;
    const measured = sim.actual.map((p) => {
      if (p[0] - table > half) table = p[0] - half;
      else if (p[0] - table < -half) table = p[0] + half;
      return [table + noise(), p[1] + noise(), p[2]];
    });
    return { sim, measured };
  }
  const toCsv = (rows) => "x,y,z\n" + rows.map((r) => r.map((v) => v.toFixed(5)).join(",")).join("\n");
  const gapSeries = (measured, sim) => measured.map((p, i) => {
    const q = sim[Math.min(i, sim.length - 1)];
    return Math.hypot(p[0] - q[0], p[1] - q[1], (p[2] || 0) - (q[2] || 0)) * 1000;
  });

  view(/^\/m\/([^/]+)\/gap$/, async (main, [, m]) => {
    main.append(h("h2", {}, `Sim-to-real gap diagnosis (motion) on machine ${m}`),
      h("p", { class: "note" }, "Compares measured positions (scales, ballbar, laser) with this machine's servo simulation of the same command: where the gap arises, which unmodelled effect explains it, and how far it shrinks on a validation run the effect was not fitted on. " +
        `Demo data filled in: the measured runs are synthetic, this machine's own simulation plus ${BACKLASH_MM * 1000} µm of X backlash and 0.5 µm noise, so the diagnosis should say backlash. Paste or load your own: measured rows x,y[,z] in mm, one every period from the program's start.`));
    const mode = h("select", {}, h("option", { value: "gcode" }, "program (G-code)"), h("option", { value: "commanded" }, "commanded positions (CSV x,y[,z])"));
    const cmd = h("textarea", { spellcheck: "false", "aria-label": "main program or commanded positions" });
    const meas = h("textarea", { spellcheck: "false", "aria-label": "main measured positions" });
    const vcmd = h("textarea", { spellcheck: "false", "aria-label": "validation program or commanded positions" });
    const vmeas = h("textarea", { spellcheck: "false", "aria-label": "validation measured positions" });
    const period = h("input", { type: "number", value: "0.001", step: "0.0005", min: "0.0001" });
    const button = h("button", {}, "Diagnose");
    const demo = h("button", {}, "Fill in demo data");
    main.append(h("form", { class: "inputs" },
      h("div", {}, h("label", {}, "Command given as"), mode, h("label", {}, "Sample period (s)"), period, h("p", {}, button, " ", demo)),
      h("div", {}, h("label", {}, "Main run: command"), cmd, App.fileInto(cmd)),
      h("div", {}, h("label", {}, "Main run: measured x,y,z (mm)"), meas, App.fileInto(meas)),
      h("div", {}, h("label", {}, "Validation run: command (optional)"), vcmd, App.fileInto(vcmd)),
      h("div", {}, h("label", {}, "Validation run: measured (optional)"), vmeas, App.fileInto(vmeas))));
    const out = h("div");
    main.append(out);
    let demoCache = null;
    async function fillDemo() {
      const [a, b] = await Promise.all([demoRun(m, MAIN), demoRun(m, VALIDATION)]);
      mode.value = "gcode"; period.value = "0.001";
      cmd.value = MAIN; meas.value = toCsv(a.measured); vcmd.value = VALIDATION; vmeas.value = toCsv(b.measured);
      demoCache = { main: a.sim, validation: b.sim };
    }
    demo.addEventListener("click", (e) => { e.preventDefault(); fillDemo(); });
    await fillDemo();
    /** "Accept these effects": stores the diagnosis' `accept` with the machine, then diagnoses
     *  the same run again with them and shows the gap before and after. */
    function acceptBox(out, body, d) {
      const names = d.steps.map((x) => x.effect).join(" + ");
      const b = h("button", { class: "accept" }, `Accept these effects (${names}) for machine ${m}`);
      const said = h("div");
      out.append(h("p", {}, b), said);
      b.addEventListener("click", async (e) => {
        e.preventDefault();
        document.body.dataset.state = "loading";
        try {
          const stored = await api("PUT", `/v1/machines/${enc(m)}/effects`, d.accept);
          const again = await api("POST", `/v1/machines/${enc(m)}/gap-diagnosis`, body);
          said.append(h("p", { class: "note" }, `Stored as version ${stored.version}: contour error, compensated programs (contour) and the next diagnosis of machine ${m} include them. The same run diagnosed again:`),
            figures([[um(d.gap_before.rms), "gap RMS before (servo model)"], [um(again.gap_before.rms), `gap RMS with effects v${stored.version}`],
              [`${(again.gap_before.rms / d.gap_before.rms).toFixed(3)}×`, "what is left"], [again.verdict, "verdict now"]]));
          b.disabled = true;
          document.body.dataset.state = "ready";
        } catch (err) {
          said.append(App.problemBox(err));
          document.body.dataset.state = "error";
        }
      });
    }
    await runner(button, out, async (out) => {
      const period_s = Number(period.value);
      const measured = csvRows(meas.value).map((r) => r.slice(0, 3));
      const body = { domain: "motion", period_s, measured };
      const byProgram = mode.value === "gcode";
      if (byProgram) body.gcode = cmd.value; else body.commanded = csvRows(cmd.value).map((r) => r.slice(0, 3));
      const vMeasured = csvRows(vmeas.value).map((r) => r.slice(0, 3));
      let vCommanded = null;
      if (vMeasured.length) {
        // The validation block takes commanded rows: a program is interpolated by the service first.
        if (byProgram) {
          const sim = demoCache && vcmd.value === VALIDATION ? demoCache.validation
            : await api("POST", `/v1/machines/${enc(m)}/contour-error`, { gcode: vcmd.value, period_s });
          vCommanded = sim.commanded.slice(0, vMeasured.length);
          while (vCommanded.length < vMeasured.length) vCommanded.push(vCommanded[vCommanded.length - 1]);
        } else vCommanded = csvRows(vcmd.value).map((r) => r.slice(0, 3));
        body.validation = { commanded: vCommanded, measured: vMeasured };
      }
      const d = await api("POST", `/v1/machines/${enc(m)}/gap-diagnosis`, body);
      out.append(figures([[d.verdict, "verdict: the unmodelled effect"], [um(d.gap_before.rms), "gap RMS as simulated"], [um(d.gap_after.rms), "gap RMS with the effect"],
        [um(d.gap_before.max), "gap max as simulated"], [um(d.gap_after.max), "gap max with the effect"]].concat(
        d.validation ? [[um(d.validation.rms_before), "validation RMS before"], [um(d.validation.rms_after), "validation RMS after"]] : [])));
      const plots = h("div", { class: "plots" });
      out.append(plots);
      const t = measured.map((_, i) => i * period_s);
      const spans = d.where.slice(0, 6).map((w, i) => ({ x0: w.start * period_s, x1: w.end * period_s, label: `${i + 1}` }));
      out.append(h("p", { class: "note" }, d.effects_version === null || d.effects_version === undefined
        ? "Simulated with the machine's servo model alone (no effects stored)."
        : `Simulated with the servo model and the effects stored with the machine (version ${d.effects_version}).`));
      if (d.accept && (d.steps || []).length) acceptBox(out, body, d);
      if (byProgram) {
        const cached = demoCache && cmd.value === MAIN && d.effects_version === null;
        const sim = cached ? demoCache.main : await api("POST", `/v1/machines/${enc(m)}/contour-error`, { gcode: cmd.value, period_s });
        const axes = d.axes || ["X", "Y", "Z"];
        Plot.lines(plots, { title: "Gap over time per axis; shaded: spans where it arises", xlabel: "time (s)", ylabel: "gap measured − simulated (µm)", spans, hline: 0,
          series: axes.slice(0, measured[0].length).map((a, k) => ({ x: t, y: measured.map((p, i) => (p[k] - sim.actual[Math.min(i, sim.actual.length - 1)][k]) * 1000), label: a, colour: ["#1f5f99", "#c0392b", "#2e8b57"][k], width: 1 })) });
      } else {
        Plot.lines(plots, { title: "Commanded positions; shaded: where the gap arises", xlabel: "time (s)", ylabel: "position (mm)", spans,
          series: ["X", "Y"].map((a, k) => ({ x: t, y: body.commanded.map((r) => r[k]), label: a, colour: ["#1f5f99", "#c0392b"][k] })) });
      }
      const eff = d.effects || [];
      Plot.bars(plots, { title: "Effects: held-out score (share of the gap removed)", labels: eff.map((e) => e.effect), values: eff.map((e) => e.score || 0), ylabel: "score (0–1)", valueFmt: (v) => v.toFixed(2) });
      if (d.validation) {
        const v = d.validation;
        const labels = ["as simulated"].concat((d.steps || []).map((s, i) => `+ ${s.effect}`));
        const values = [v.rms_before].concat(v.rms_steps || [v.rms_after]).map((x) => x * 1000);
        Plot.bars(plots, { title: "Validation run: gap RMS before and after (µm)", labels, values, ylabel: "RMS gap (µm)", colours: values.map((_, i) => (i ? "#2e8b57" : "#c0392b")), valueFmt: (x) => x.toFixed(2) });
        const tv = vMeasured.map((_, i) => i * period_s);
        Plot.lines(plots, { title: "Validation run: gap over time before and after", xlabel: "time (s)", ylabel: "gap (µm)",
          series: [{ x: tv, y: gapSeries(vMeasured, v.predicted_before), label: "as simulated", colour: "#c0392b" },
            { x: tv, y: gapSeries(vMeasured, v.predicted_after), label: `with ${d.verdict}`, colour: "#2e8b57" }] });
      }
      out.append(h("h3", {}, "Where the gap arises (largest share first; spans under 0.5 % left out)"), table(["#", "event", "axis", "program line", "samples", "time", "share"],
        d.where.filter((w, i) => i < 3 || w.share >= 0.005).slice(0, 10).map((w, i) => [i + 1, w.label, w.axis || "–", w.line === undefined ? "–" : w.line, `${w.start}–${w.end}`,
          `${(w.start * period_s).toFixed(3)}–${(w.end * period_s).toFixed(3)} s`, `${(w.share * 100).toFixed(1)} %`])));
      out.append(h("h3", {}, "Effects"), table(["effect", "score", "parameters"], eff.map((e) => [e.effect, e.score === null ? "–" : Number(e.score).toFixed(3),
        Object.entries(e.params || {}).map(([k, x]) => `${k} = ${Number(x).toPrecision(4)}`).join(", ")])));
      if (d.unexplained) out.append(h("p", { class: "note" }, `Unexplained after the steps: ${um(d.unexplained.rms)} RMS (${(d.unexplained.share * 100).toFixed(1)} % of the squared gap).`));
    });
  });
})();
