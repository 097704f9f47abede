// truecut dashboard: a small hand-written SVG plotting module (no library, nothing fetched).
// Every plot is an <svg class="plot"> with a title, axes with units, and (for colour) a
// colour bar with values. Public: Plot.heatmap, Plot.lines, Plot.bars, Plot.colouredPath,
// Plot.xy, Plot.polar, Plot.niceTicks, Plot.fmt.
"use strict";

const Plot = (() => {
  const NS = "http://www.w3.org/2000/svg";
  const W = 560, H = 380;

  function el(name, attrs, parent) {
    const e = document.createElementNS(NS, name);
    for (const k in attrs) e.setAttribute(k, attrs[k]);
    if (parent) parent.appendChild(e);
    return e;
  }
  function text(parent, x, y, s, attrs) {
    const t = el("text", Object.assign({ x, y }, attrs || {}), parent);
    t.textContent = s;
    return t;
  }

  /** About n round tick values covering [lo, hi]. */
  function niceTicks(lo, hi, n) {
    if (!isFinite(lo) || !isFinite(hi)) return [];
    if (hi === lo) { hi = lo + 1; lo = lo - 1; }
    const raw = (hi - lo) / (n || 5);
    const mag = Math.pow(10, Math.floor(Math.log10(raw)));
    const step = [1, 2, 2.5, 5, 10].map((m) => m * mag).find((s) => s >= raw) || 10 * mag;
    const out = [];
    for (let v = Math.ceil(lo / step - 1e-9) * step; v <= hi + step * 1e-9; v += step) {
      out.push(Math.abs(v) < step * 1e-9 ? 0 : v);
    }
    out.step = step;
    return out;
  }
  /** A number with as many decimals as the tick step needs. */
  function fmt(v, step) {
    if (!isFinite(v)) return String(v);
    const s = step || Math.abs(v) || 1;
    const d = Math.max(0, Math.min(6, -Math.floor(Math.log10(s) + 1e-9)));
    return v.toFixed(d);
  }
  function extent(arrays) {
    let lo = Infinity, hi = -Infinity;
    for (const a of arrays) for (const v of a) if (isFinite(v)) { if (v < lo) lo = v; if (v > hi) hi = v; }
    if (lo === Infinity) return [0, 1];
    if (lo === hi) return [lo - (Math.abs(lo) || 1) * 0.1, hi + (Math.abs(hi) || 1) * 0.1];
    return [lo, hi];
  }

  // Colour maps. Diverging (signed values): blue, white, red. Sequential: a viridis-like ramp.
  const DIVERGING = [[33, 102, 172], [103, 169, 207], [209, 229, 240], [247, 247, 247],
    [253, 219, 199], [239, 138, 98], [178, 24, 43]];
  const SEQUENTIAL = [[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]];
  function ramp(stops, t) {
    t = Math.max(0, Math.min(1, t));
    const x = t * (stops.length - 1), i = Math.min(stops.length - 2, Math.floor(x)), f = x - i;
    const c = stops[i].map((v, k) => Math.round(v + (stops[i + 1][k] - v) * f));
    return `rgb(${c[0]},${c[1]},${c[2]})`;
  }
  const diverging = (v, vmax) => ramp(DIVERGING, 0.5 + 0.5 * v / (vmax || 1));
  const sequential = (v, lo, hi) => ramp(SEQUENTIAL, (v - lo) / ((hi - lo) || 1));
  // Errors (0 = good): dark green, olive, orange, red; every stop readable on white.
  const ERROR = [[0, 109, 44], [120, 160, 20], [235, 140, 0], [200, 20, 20]];
  const errorColour = (v, hi) => ramp(ERROR, v / (hi || 1));

  /**
   * SVG path data through (xs[i], ys[i]) every `step` samples (and the last), scaled by `s`;
   * a sample that is not finite lifts the pen (a gap, e.g. a rapid move left out).
   */
  function polyline(s, xs, ys, step) {
    let d = "", pen = false;
    const n = xs.length;
    for (let i = 0; i < n; i = i + step < n || i === n - 1 ? i + step : n - 1) {
      if (!isFinite(xs[i]) || !isFinite(ys[i])) { pen = false; continue; }
      d += `${pen ? "L" : "M"}${s.x(xs[i]).toFixed(1)} ${s.y(ys[i]).toFixed(1)}`;
      pen = true;
    }
    return d;
  }

  /** One row of legend items [{label, colour, dash, width}] under the title, from x = 62. */
  function legendRow(svg, items, y) {
    let x = 62;
    for (const it of items) {
      el("line", { x1: x, x2: x + 22, y1: y, y2: y, stroke: it.colour, "stroke-width": it.width || 2.5, "stroke-dasharray": it.dash || "none" }, svg);
      const t = text(svg, x + 27, y + 4, it.label, { class: "legend" });
      x += 37 + 6.2 * it.label.length;
      t.setAttribute("data-legend", "1");
    }
  }

  /** Equal x/y scales around the extent of `xs`, `ys` inside `box`; returns the ranges. */
  function equalRanges(box, xs, ys, margin) {
    const xr0 = extent(xs), yr0 = extent(ys);
    const bw = box[2] - box[0], bh = box[3] - box[1];
    const scale = Math.min(bw / (xr0[1] - xr0[0]), bh / (yr0[1] - yr0[0])) * (margin || 0.96);
    const cx = (xr0[0] + xr0[1]) / 2, cy = (yr0[0] + yr0[1]) / 2;
    return [[cx - bw / 2 / scale, cx + bw / 2 / scale], [cy - bh / 2 / scale, cy + bh / 2 / scale]];
  }

  /**
   * Paths in the plane at equal scales (a drawing). opts: {title, xlabel, ylabel,
   * series: [{x, y, label, colour, dash, width}]}; the labels make a legend under the title.
   */
  function xy(parent, opts) {
    const svg = frame(parent, opts.title, "xy");
    const box = [62, 46, W - 20, H - 46];
    const series = opts.series || [];
    const [xr, yr] = equalRanges(box, series.map((s) => s.x), series.map((s) => s.y));
    const s = axes(svg, box, xr, yr, opts.xlabel, opts.ylabel);
    const g = el("g", { class: "paths" }, svg);
    for (const sr of series) {
      const d = polyline(s, sr.x, sr.y, Math.max(1, Math.floor(sr.x.length / 4000)));
      el("path", { d, fill: "none", stroke: sr.colour, "stroke-width": sr.width || 1.5, "stroke-dasharray": sr.dash || "none" }, g);
    }
    legendRow(svg, series.filter((x) => x.label), 36);
    return svg;
  }

  /** A new <svg class="plot"> with a title, appended to `parent`. */
  function frame(parent, title, kind) {
    const svg = el("svg", { class: "plot", viewBox: `0 0 ${W} ${H}`, role: "img", "data-kind": kind });
    el("title", {}, svg).textContent = title;
    text(svg, W / 2, 20, title, { class: "plot-title", "text-anchor": "middle" });
    parent.appendChild(svg);
    return svg;
  }

  /** Axes with ticks and labels; returns {x(v), y(v)} scale functions. */
  function axes(svg, box, xr, yr, xlabel, ylabel, opts) {
    opts = opts || {};
    const [x0, y0, x1, y1] = box;
    const sx = (v) => x0 + (v - xr[0]) / (xr[1] - xr[0]) * (x1 - x0);
    const sy = (v) => y1 - (v - yr[0]) / (yr[1] - yr[0]) * (y1 - y0);
    const g = el("g", { class: "axes" }, svg);
    el("rect", { x: x0, y: y0, width: x1 - x0, height: y1 - y0, class: "plot-area" }, g);
    const xt = opts.xticks || niceTicks(xr[0], xr[1], 6);
    for (const v of xt) {
      if (v < xr[0] - 1e-12 || v > xr[1] + 1e-12) continue;
      el("line", { x1: sx(v), x2: sx(v), y1: y1, y2: y1 + 4, class: "tick" }, g);
      if (opts.grid !== false) el("line", { x1: sx(v), x2: sx(v), y1: y0, y2: y1, class: "grid" }, g);
      text(g, sx(v), y1 + 16, opts.xfmt ? opts.xfmt(v) : fmt(v, xt.step), { "text-anchor": "middle", class: "tick-label" });
    }
    const yt = opts.yticks || niceTicks(yr[0], yr[1], 5);
    for (const v of yt) {
      if (v < yr[0] - 1e-12 || v > yr[1] + 1e-12) continue;
      el("line", { x1: x0 - 4, x2: x0, y1: sy(v), y2: sy(v), class: "tick" }, g);
      if (opts.grid !== false) el("line", { x1: x0, x2: x1, y1: sy(v), y2: sy(v), class: "grid" }, g);
      text(g, x0 - 7, sy(v) + 4, fmt(v, yt.step), { "text-anchor": "end", class: "tick-label" });
    }
    text(g, (x0 + x1) / 2, H - 8, xlabel, { "text-anchor": "middle", class: "axis-label" });
    const yl = text(g, 0, 0, ylabel, { "text-anchor": "middle", class: "axis-label" });
    yl.setAttribute("transform", `translate(14 ${(y0 + y1) / 2}) rotate(-90)`);
    return { x: sx, y: sy };
  }

  /** Vertical colour bar at x with tick values and a unit label. */
  function colourBar(svg, x, y0, y1, lo, hi, colour, unit) {
    const g = el("g", { class: "colour-bar" }, svg);
    const n = 40;
    for (let i = 0; i < n; i++) {
      const v = lo + (hi - lo) * (i + 0.5) / n;
      const ya = y1 - (y1 - y0) * (i + 1) / n;
      el("rect", { x, y: ya, width: 14, height: (y1 - y0) / n + 0.5, fill: colour(v) }, g);
    }
    el("rect", { x, y: y0, width: 14, height: y1 - y0, class: "bar-outline" }, g);
    const t = niceTicks(lo, hi, 6);
    for (const v of t) {
      if (v < lo - 1e-12 || v > hi + 1e-12) continue;
      const y = y1 - (v - lo) / ((hi - lo) || 1) * (y1 - y0);
      el("line", { x1: x + 14, x2: x + 18, y1: y, y2: y, class: "tick" }, g);
      text(g, x + 21, y + 4, fmt(v, t.step), { class: "tick-label" });
    }
    text(g, x + 7, y0 - 8, unit, { "text-anchor": "middle", class: "axis-label" });
  }

  /** The two coordinates (of x, y, z) along which the points spread most. */
  function viewAxes(points) {
    const ext = [0, 1, 2].map((k) => extent([points.map((p) => p[k])]));
    const spread = ext.map((e) => e[1] - e[0]);
    const order = [0, 1, 2].sort((a, b) => spread[b] - spread[a]);
    const pair = order.slice(0, 2).sort();
    return pair;
  }

  /**
   * Heat map of `values` over a nu×nv grid of `points` ([x,y,z], u fastest), seen along the
   * axis of least spread. Signed values use a symmetric diverging scale ±vmax.
   * opts: {title, unit, vmax, rects: [{u:[a,b], v:[a,b], label}]}
   */
  function heatmap(parent, opts) {
    const svg = frame(parent, opts.title, "heatmap");
    const { nu, nv, points, values } = opts;
    const [a, b] = viewAxes(points);
    const names = ["x", "y", "z"];
    const xr = extent([points.map((p) => p[a])]), yr = extent([points.map((p) => p[b])]);
    // Equal scales on both axes: the part's shape is kept.
    const box = [62, 34, W - 92, H - 46];
    const bw = box[2] - box[0], bh = box[3] - box[1];
    const scale = Math.min(bw / (xr[1] - xr[0]), bh / (yr[1] - yr[0]));
    const cx = (xr[0] + xr[1]) / 2, cy = (yr[0] + yr[1]) / 2;
    const xr2 = [cx - bw / 2 / scale, cx + bw / 2 / scale], yr2 = [cy - bh / 2 / scale, cy + bh / 2 / scale];
    const s = axes(svg, box, xr2, yr2, `${names[a]} (mm)`, `${names[b]} (mm)`, { grid: false });
    const vmax = opts.vmax || Math.max(1e-12, ...values.map((v) => Math.abs(v)).filter(isFinite));
    // At most about 120 cells a side; a finer grid is drawn by stride.
    const su = Math.max(1, Math.ceil((nu - 1) / 120)), sv = Math.max(1, Math.ceil((nv - 1) / 120));
    const g = el("g", { class: "cells" }, svg);
    for (let iv = 0; iv + sv < nv + sv - 1 && iv < nv - 1; iv += sv) {
      const jv = Math.min(nv - 1, iv + sv);
      for (let iu = 0; iu < nu - 1; iu += su) {
        const ju = Math.min(nu - 1, iu + su);
        const ks = [iv * nu + iu, iv * nu + ju, jv * nu + ju, jv * nu + iu];
        const mean = ks.reduce((acc, k) => acc + values[k], 0) / 4;
        const pts = ks.map((k) => `${s.x(points[k][a]).toFixed(1)},${s.y(points[k][b]).toFixed(1)}`).join(" ");
        el("polygon", { points: pts, fill: diverging(mean, vmax), stroke: diverging(mean, vmax), "stroke-width": 0.4 }, g);
      }
    }
    for (const r of opts.rects || []) {
      const corners = [[r.u[0], r.v[0]], [r.u[1], r.v[0]], [r.u[1], r.v[1]], [r.u[0], r.v[1]]]
        .map(([u, v]) => points[v * nu + u]);
      const pts = corners.map((p) => `${s.x(p[a]).toFixed(1)},${s.y(p[b]).toFixed(1)}`).join(" ");
      el("polygon", { points: pts, class: "region" }, svg);
      const c0 = corners[3];
      text(svg, s.x(c0[a]) + 3, s.y(c0[b]) + 13, r.label, { class: "region-label" });
    }
    colourBar(svg, W - 78, box[1] + 16, box[3], -vmax, vmax, (v) => diverging(v, vmax), opts.unit || "mm");
    return svg;
  }

  /**
   * Line plot. opts: {title, xlabel, ylabel, series: [{x, y, label, colour, dash, width,
   * dots, gaps (a non-finite y lifts the pen)}], bands: [{x, lo, hi, colour, label}], spans: [{x0, x1, label}], yr, xr, hline}
   */
  function lines(parent, opts) {
    const svg = frame(parent, opts.title, "lines");
    const series = opts.series || [], bands = opts.bands || [];
    const xr = opts.xr || extent(series.map((s) => s.x).concat(bands.map((b) => b.x)));
    const yr = opts.yr || extent(series.map((s) => s.y).concat(bands.map((b) => b.lo), bands.map((b) => b.hi), opts.hline !== undefined ? [[opts.hline]] : []));
    const pad = (yr[1] - yr[0]) * 0.05;
    const legendW = series.some((s) => s.label) || bands.some((b) => b.label) ? 150 : 0;
    const box = [70, 34, W - 16 - legendW, H - 46];
    const s = axes(svg, box, xr, [yr[0] - pad, yr[1] + pad], opts.xlabel, opts.ylabel, { xticks: opts.xticks });
    const clip = `clip${Math.random().toString(36).slice(2)}`;
    const cp = el("clipPath", { id: clip }, svg);
    el("rect", { x: box[0], y: box[1], width: box[2] - box[0], height: box[3] - box[1] }, cp);
    const g = el("g", { "clip-path": `url(#${clip})` }, svg);
    for (const sp of opts.spans || []) {
      el("rect", { x: s.x(sp.x0), y: box[1], width: Math.max(1, s.x(sp.x1) - s.x(sp.x0)), height: box[3] - box[1], class: "span" }, g);
      if (sp.label) text(g, s.x(sp.x0) + 2, box[1] + 12, sp.label, { class: "span-label" });
    }
    for (const b of bands) {
      const up = b.x.map((x, i) => `${s.x(x).toFixed(1)},${s.y(b.hi[i]).toFixed(1)}`);
      const dn = b.x.map((x, i) => `${s.x(x).toFixed(1)},${s.y(b.lo[i]).toFixed(1)}`).reverse();
      el("polygon", { points: up.concat(dn).join(" "), fill: b.colour, "fill-opacity": 0.18, stroke: b.colour, "stroke-opacity": 0.5, "stroke-dasharray": "3 2" }, g);
    }
    if (opts.hline !== undefined) el("line", { x1: box[0], x2: box[2], y1: s.y(opts.hline), y2: s.y(opts.hline), class: "zero" }, g);
    for (const sr of series) {
      const step = Math.max(1, Math.floor(sr.x.length / 4000));
      if (!sr.dotsOnly && sr.gaps) {
        const d = polyline(s, sr.x, sr.y, step);
        el("path", { d, fill: "none", stroke: sr.colour, "stroke-width": sr.width || 1.5, "stroke-dasharray": sr.dash || "none" }, g);
      } else if (!sr.dotsOnly) {
        let d = "";
        for (let i = 0; i < sr.x.length; i += step) {
          if (!isFinite(sr.y[i])) continue;
          d += `${d ? "L" : "M"}${s.x(sr.x[i]).toFixed(1)} ${s.y(sr.y[i]).toFixed(1)}`;
        }
        el("path", { d, fill: "none", stroke: sr.colour, "stroke-width": sr.width || 1.5, "stroke-dasharray": sr.dash || "none" }, g);
      }
      if (sr.dots || sr.dotsOnly) {
        for (let i = 0; i < sr.x.length; i++) {
          el("circle", { cx: s.x(sr.x[i]), cy: s.y(sr.y[i]), r: 2.4, fill: sr.colour }, g);
        }
      }
    }
    if (legendW) {
      let y = box[1] + 8;
      const items = series.filter((x) => x.label).map((x) => [x.label, x.colour, false])
        .concat(bands.filter((b) => b.label).map((b) => [b.label, b.colour, true]));
      for (const [label, colour, band] of items) {
        if (band) el("rect", { x: box[2] + 10, y: y - 5, width: 18, height: 10, fill: colour, "fill-opacity": 0.25 }, svg);
        else el("line", { x1: box[2] + 10, x2: box[2] + 28, y1: y, y2: y, stroke: colour, "stroke-width": 2.5 }, svg);
        text(svg, box[2] + 32, y + 4, label, { class: "legend" });
        y += 17;
      }
    }
    return svg;
  }

  /** Bar chart. opts: {title, labels, values, ylabel, colours, valueFmt} */
  function bars(parent, opts) {
    const svg = frame(parent, opts.title, "bars");
    const n = opts.values.length;
    const yr = extent([opts.values.concat([0])]);
    const box = [70, 34, W - 16, H - 78];
    const s = axes(svg, box, [0, Math.max(1, n)], [Math.min(0, yr[0]), yr[1] * 1.12 || 1], "", opts.ylabel, { xticks: [], grid: true });
    const bw = (box[2] - box[0]) / Math.max(1, n);
    opts.values.forEach((v, i) => {
      const x = box[0] + i * bw + bw * 0.15;
      const ya = s.y(Math.max(0, v)), yb = s.y(Math.min(0, v));
      el("rect", { x, y: ya, width: bw * 0.7, height: Math.max(1, yb - ya), fill: (opts.colours && opts.colours[i]) || "#3b6ea8", class: "bar" }, svg);
      text(svg, x + bw * 0.35, ya - 4, opts.valueFmt ? opts.valueFmt(v) : fmt(v, Math.abs(v) / 100), { "text-anchor": "middle", class: "tick-label" });
      const lab = text(svg, 0, 0, opts.labels[i], { "text-anchor": "end", class: "tick-label" });
      lab.setAttribute("transform", `translate(${x + bw * 0.35 + 4} ${box[3] + 12}) rotate(-25)`);
    });
    return svg;
  }

  /**
   * A path in the plane coloured by a value per sample, over a grey reference path.
   * opts: {title, x, y, values, unit, refX, refY, xlabel, ylabel, marks, vmax (shared colour
   * scale), palette ("error": green → red), legend: [{label, colour, dash}] under the title}
   */
  function colouredPath(parent, opts) {
    const svg = frame(parent, opts.title, "path");
    const box = [62, opts.legend ? 46 : 34, W - 96, H - 46];
    const [xr, yr] = equalRanges(box, [opts.x, opts.refX || []], [opts.y, opts.refY || []]);
    const s = axes(svg, box, xr, yr, opts.xlabel, opts.ylabel);
    const hi = opts.vmax || Math.max(1e-12, ...opts.values.filter(isFinite));
    const colour = opts.palette === "error" ? (v) => errorColour(v, hi) : (v) => sequential(v, 0, hi);
    if (opts.legend) legendRow(svg, opts.legend, 36);
    if (opts.refX) {
      const d = polyline(s, opts.refX, opts.refY, Math.max(1, Math.floor(opts.refX.length / 3000)));
      el("path", { d, class: "reference-path" }, svg);
    }
    // One segment per ~1/1500 of the run, coloured by its largest value.
    const n = opts.x.length, st = Math.max(1, Math.floor(n / 1500));
    const g = el("g", { class: "coloured-path" }, svg);
    for (let i = 0; i + 1 < n; i += st) {
      const j = Math.min(n - 1, i + st);
      let v = 0;
      for (let k = i; k <= j; k++) v = Math.max(v, opts.values[k]);
      if (!isFinite(v) || !isFinite(opts.x[i] + opts.y[i] + opts.x[j] + opts.y[j])) continue; // a gap
      el("line", { x1: s.x(opts.x[i]), y1: s.y(opts.y[i]), x2: s.x(opts.x[j]), y2: s.y(opts.y[j]), stroke: colour(v), "stroke-width": 3, "stroke-linecap": "round" }, g);
    }
    for (const m of opts.marks || []) {
      el("circle", { cx: s.x(m.x), cy: s.y(m.y), r: 6, class: "worst-mark" }, svg);
      const left = s.x(m.x) > (box[0] + box[2]) / 2; // keep the label inside the plot
      text(svg, s.x(m.x) + (left ? -8 : 8), s.y(m.y) + (s.y(m.y) < box[1] + 20 ? 18 : -6), m.label, { class: "region-label", "text-anchor": left ? "end" : "start" });
    }
    colourBar(svg, W - 82, box[1] + 16, box[3], 0, hi, colour, opts.unit);
    return svg;
  }

  /**
   * Polar plot of a radial deviation, magnified about a reference circle.
   * opts: {title, angles (rad), dev (µm), ringUm, series: [{angles, dev, colour, label}]}
   */
  function polar(parent, opts) {
    const svg = frame(parent, opts.title, "polar");
    const cx = 220, cy = H / 2 + 14, R0 = 100, ring = opts.ringUm; // R0: the reference circle
    const k = 50 / ring; // ring µm of deviation = 50 px
    const g = el("g", { class: "axes" }, svg);
    for (const d of [-ring, 0, ring]) {
      el("circle", { cx, cy, r: R0 + d * k, class: d === 0 ? "ref-circle" : "grid-circle" }, g);
    }
    for (let a = 0; a < 360; a += 45) {
      const r = a * Math.PI / 180;
      el("line", { x1: cx, y1: cy, x2: cx + (R0 + 55) * Math.cos(r), y2: cy - (R0 + 55) * Math.sin(r), class: "grid" }, g);
      text(g, cx + (R0 + 66) * Math.cos(r), cy - (R0 + 66) * Math.sin(r) + 4, `${a}°`, { "text-anchor": "middle", class: "tick-label" });
    }
    text(g, cx + R0 + ring * k - 2, cy - 5, `+${fmt(ring, opts.ringStep)}`, { "text-anchor": "end", class: "tick-label" });
    text(g, cx + R0 - ring * k + 2, cy - 5, `−${fmt(ring, opts.ringStep)}`, { class: "tick-label" });
    let ly = 60;
    for (const sr of opts.series) {
      let d = "";
      sr.angles.forEach((a, i) => {
        const r = Math.max(0, R0 + sr.dev[i] * k);
        d += `${d ? "L" : "M"}${(cx + r * Math.cos(a)).toFixed(1)} ${(cy - r * Math.sin(a)).toFixed(1)}`;
      });
      el("path", { d: d + "Z", fill: "none", stroke: sr.colour, "stroke-width": 1.8 }, svg);
      el("line", { x1: 410, x2: 428, y1: ly, y2: ly, stroke: sr.colour, "stroke-width": 2.5 }, svg);
      text(svg, 432, ly + 4, sr.label, { class: "legend" });
      ly += 18;
    }
    (opts.notes || []).forEach((note) => { text(svg, 410, ly + 10, note, { class: "legend" }); ly += 16; });
    return svg;
  }

  return { heatmap, lines, bars, colouredPath, xy, polar, niceTicks, fmt, diverging, sequential, errorColour };
})();
