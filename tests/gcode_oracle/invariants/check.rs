//! One case of [`super`]: the original and its answer read by rs274 and every invariant
//! checked on their moves (the rules are in the parent module's docs).

use std::collections::{BTreeMap, HashSet};
use std::path::Path;

use truecut::cam::predistort::CORNER_MIN_RAD;
use truecut::cam::{Compensated, Predistorted};
use truecut::motion::gcode::{WordSpan, parse_traced, word_spans};

use super::{
    CONTOUR_EXTRA, CONTOUR_FACTOR, END_MM, FLOOR_MM, Mv, PRINT_HALF_DIGIT, Reading, Report, Rule,
    VOLUMETRIC_BUDGET, need, read, simulated_lows, whole_lines,
};
use crate::compensated::{Answered, Setup};

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
}

fn g10(v: f64) -> i64 {
    (v * 10.0).round() as i64
}

/// Axis letters (X Y Z) written on a line.
pub fn axis_letters(words: &[WordSpan]) -> Vec<char> {
    words
        .iter()
        .filter(|w| matches!(w.letter, 'X' | 'Y' | 'Z'))
        .map(|w| w.letter)
        .collect()
}

/// Feed runs: for each move the index of the cutting level (the feed moves between two
/// traverses) it belongs to, None for traverses.
fn runs(moves: &[Mv]) -> (Vec<Option<usize>>, usize) {
    let (mut out, mut cur, mut n) = (Vec::with_capacity(moves.len()), None, 0);
    for m in moves {
        if !m.feed {
            cur = None;
            out.push(None);
            continue;
        }
        let k = *cur.get_or_insert_with(|| {
            n += 1;
            n - 1
        });
        out.push(Some(k));
    }
    (out, n)
}

/// The answer's levels as the original's: the j-th level of the answer that holds moves of
/// source line L is the j-th of the original's that does (pecks and holes keep their order);
/// a source line the original has no feed move of takes the level of the line before.
fn answer_levels(o: &Reading, o_runs: &[Option<usize>], a: &Reading) -> Vec<Option<usize>> {
    let mut of_src: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for (m, r) in o.moves.iter().zip(o_runs) {
        if let Some(r) = *r {
            let v = of_src.entry(m.src).or_default();
            if v.last() != Some(&r) {
                v.push(r);
            }
        }
    }
    let (a_runs, _) = runs(&a.moves);
    let mut seen: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    a.moves
        .iter()
        .zip(&a_runs)
        .map(|(m, r)| {
            let r = (*r)?;
            let v = seen.entry(m.src).or_default();
            if v.last() != Some(&r) {
                v.push(r);
            }
            let j = v.len() - 1;
            let levels = of_src.range(..=m.src).next_back().map(|(_, l)| l)?;
            levels.get(j).or(levels.last()).copied()
        })
        .collect()
}

/// The unit direction of `m` at fraction `t` (towards increasing t).
fn tangent(m: &Mv, t: f64) -> [f64; 3] {
    const DT: f64 = 1e-4;
    let (a, b) = (m.at((t - DT).max(0.0)), m.at((t + DT).min(1.0)));
    let d = dist(a, b);
    if d == 0.0 {
        return [0.0; 3];
    }
    [0, 1, 2].map(|k| (b[k] - a[k]) / d)
}

/// Checks one case (module docs of [`super`]); Err when the harness cannot run it.
#[allow(clippy::too_many_arguments)]
pub fn check_case(
    a: &Answered,
    c: &Compensated,
    p: Option<&Predistorted>,
    volumetric_lines: Option<usize>,
    s: &Setup,
    rs: &Path,
    dir: &Path,
    table: &Path,
) -> Result<Report, String> {
    let tag = format!("{}_{}", a.name.replace('/', "_"), a.mode);
    let mut r = Report {
        tag: tag.clone(),
        not_read: None,
        moves: (0, 0),
        lines: (a.text.lines().count(), c.blocks),
        need: None,
        arcs: (0, 0),
        checked: 0,
        violations: Vec::new(),
        notes: Vec::new(),
    };
    if let Some(why) = crate::valid::rs274_cannot(&a.text) {
        r.not_read = Some(why.to_string());
        return Ok(r);
    }
    let volumetric = a.mode != "contour";
    let e = |q: [f64; 3]| {
        if volumetric {
            s.map.error_at(q)
        } else {
            [0.0; 3]
        }
    };
    let (o_prog, _, o_frames) =
        parse_traced(&a.text, &a.options).map_err(|e| format!("{tag}: {e}"))?;
    let (a_prog, _, a_frames) =
        parse_traced(&c.gcode, &a.options).map_err(|e| format!("{tag}: the answer: {e}"))?;
    let src_of = |l: usize| c.source_lines.get(l.wrapping_sub(1)).copied().unwrap_or(0);
    let o = read(
        rs,
        dir,
        &format!("{tag}_o"),
        &a.text,
        table,
        &o_frames,
        &|l| l,
    )
    .map_err(|e| format!("{tag}: rs274 refuses the original: {e}"))?;
    let mut v: Vec<(Rule, String)> = Vec::new();
    let ans = match read(
        rs,
        dir,
        &format!("{tag}_a"),
        &c.gcode,
        table,
        &a_frames,
        &src_of,
    ) {
        Ok(x) => x,
        Err(err) => {
            r.violations
                .push((Rule::Cutter, format!("rs274 refuses the answer: {err}")));
            return Ok(r);
        }
    };
    // The programmed path (a tool table of zero diameters) where G41/G42 make rs274's
    // points tool centres: the ends of kept-whole moves and the words are checked on it.
    let cutter = a.text.contains("G41") || a.text.contains("G42");
    let (o0, a0) = if cutter {
        let zero = dir.join(format!("{tag}_zero.tbl"));
        std::fs::write(&zero, crate::rs274::tool_table(&|_| 0.0)).map_err(|e| e.to_string())?;
        let o0 = read(
            rs,
            dir,
            &format!("{tag}_o0"),
            &a.text,
            &zero,
            &o_frames,
            &|l| l,
        )
        .map_err(|e| format!("{tag}: rs274 refuses the original: {e}"))?;
        let a0 = read(
            rs,
            dir,
            &format!("{tag}_a0"),
            &c.gcode,
            &zero,
            &a_frames,
            &src_of,
        )
        .map_err(|e| format!("{tag}: rs274 refuses the answer without radii: {e}"))?;
        (Some(o0), Some(a0))
    } else {
        (None, None)
    };
    let (o0, a0) = (o0.as_ref().unwrap_or(&o), a0.as_ref().unwrap_or(&ans));
    r.moves = (o.moves.len(), ans.moves.len());
    r.checked = c.blocks;
    let src_text: Vec<&str> = a.text.lines().collect();
    let out_text: Vec<&str> = c.gcode.lines().collect();
    let slack = |m: &Mv| 3f64.sqrt() * PRINT_HALF_DIGIT * m.unit_mm;
    let of = |rd: &Reading, l: usize| -> Vec<Mv> {
        rd.moves.iter().filter(|m| m.src == l).cloned().collect()
    };

    // Cutter compensation: whole moves.
    for l in whole_lines(&a.text) {
        let n = c.source_lines.iter().filter(|&&x| x == l).count();
        if n != 1 {
            v.push((Rule::Cutter, format!("line {l}: {n} answer lines")));
        }
        let (om, am) = (of(&o, l), of(&ans, l));
        if om.len() != am.len() {
            v.push((
                Rule::Cutter,
                format!(
                    "line {l}: rs274 moves {} in the original, {} in the answer",
                    om.len(),
                    am.len()
                ),
            ));
            continue;
        }
        // Ends on the programmed path; a rapid's on the axes its line names.
        let named = axis_letters(&word_spans(a.text.lines().nth(l - 1).unwrap_or("")));
        // e(p) where the service took it: truecut's reading of the line's end (a rapid's
        // unnamed axes are where the reader has them, which rs274 may place elsewhere).
        let p_end = o_prog
            .blocks
            .iter()
            .rfind(|b| b.line == l)
            .map(|b| b.end.xyz);
        for (x, y) in of(o0, l).iter().zip(&of(a0, l)) {
            let ex = e(p_end.unwrap_or(x.end));
            let want = [0, 1, 2].map(|k| x.end[k] - ex[k]);
            let axes = [0, 1, 2].map(|k| x.feed || named.contains(&['X', 'Y', 'Z'][k]));
            let d = (0..3)
                .filter(|&k| axes[k])
                .map(|k| (y.end[k] - want[k]).powi(2))
                .sum::<f64>()
                .sqrt();
            if d > END_MM + 2.0 * slack(y) {
                v.push((
                    Rule::Cutter,
                    format!(
                        "line {l}: ends {:.3} µm from the original's end less e(p)",
                        d * 1e3
                    ),
                ));
            }
        }
    }

    // Feeds: rs274's rates, and the F words as written.
    let max_vel: Vec<f64> = s.machine.axes.iter().map(|x| x.limits.max_vel).collect();
    for q in ans.moves.iter().filter(|m| m.feed) {
        let bound = o
            .moves
            .iter()
            .filter(|m| m.feed && m.src == q.src)
            .map(|m| m.feed_mm_min)
            .reduce(f64::max)
            .or_else(|| {
                o.moves
                    .iter()
                    .rfind(|m| m.feed && m.src <= q.src)
                    .map(|m| m.feed_mm_min)
            });
        let rounding = PRINT_HALF_DIGIT * q.feed_unit_mm;
        match bound {
            Some(b) if q.feed_mm_min > b + rounding => v.push((
                Rule::Feed,
                format!(
                    "line {}: F {} mm/min above the source's {b}",
                    q.src, q.feed_mm_min
                ),
            )),
            None => v.push((
                Rule::Feed,
                format!("line {}: no original feed to compare", q.src),
            )),
            _ => {}
        }
        for (k, cap) in max_vel.iter().enumerate().take(3) {
            let moves = q.arc.is_some_and(|(pl, _, _)| {
                let (a0, a1, _) = pl.axes();
                k == a0 || k == a1
            }) || q.start[k] != q.end[k];
            if moves && q.feed_mm_min / 60.0 > *cap {
                v.push((
                    Rule::Feed,
                    format!("line {}: F above max_vel of axis {k}", q.src),
                ));
            }
        }
    }
    let f_words = |t: &str| -> Vec<String> {
        word_spans(t)
            .iter()
            .filter(|w| w.letter == 'F')
            .map(|w| t[w.start + 1..w.end].to_string())
            .collect()
    };
    let src_fs: Vec<String> = src_text.iter().flat_map(|t| f_words(t)).collect();
    let frac = |f: &str| f.split_once('.').map_or(0, |(_, d)| d.len());
    let src_decimals = src_fs.iter().map(|f| frac(f)).max().unwrap_or(0);
    let src_dot = src_fs.iter().any(|f| f.ends_with('.'));
    let (mut in_force, mut firsts) = (None::<f64>, HashSet::new());
    for (i, raw) in out_text.iter().enumerate() {
        let l = src_of(i + 1);
        let first = firsts.insert(l);
        let inverse = a_frames
            .iter()
            .find(|f| f.line == i + 1)
            .is_some_and(|f| f.inverse_time);
        for f in f_words(raw) {
            let copied = first && f_words(src_text.get(l - 1).unwrap_or(&"")).contains(&f);
            if !inverse && frac(&f) > src_decimals {
                v.push((
                    Rule::Feed,
                    format!(
                        "answer line {}: F{f}: more decimals than the source's",
                        i + 1
                    ),
                ));
            }
            if src_dot && !f.contains('.') {
                v.push((
                    Rule::Feed,
                    format!("answer line {}: F{f}: the source writes a '.'", i + 1),
                ));
            }
            let value: f64 = f.parse().unwrap_or(f64::NAN);
            if !copied && !inverse && in_force == Some(value) {
                v.push((
                    Rule::Feed,
                    format!("answer line {}: F{f} repeats the feed in force", i + 1),
                ));
            }
            in_force = Some(value);
        }
    }

    // Floor: commanded and simulated, per cutting level.
    let (o_runs, levels) = runs(&o.moves);
    let mut floors = vec![f64::INFINITY; levels];
    for (m, k) in o.moves.iter().zip(&o_runs) {
        if let Some(k) = *k {
            floors[k] = m.points().iter().fold(floors[k], |z, p| z.min(p[2]));
        }
    }
    let a_levels = answer_levels(&o, &o_runs, &ans);
    for (q, k) in ans.moves.iter().zip(&a_levels) {
        let Some(k) = *k else { continue };
        let low = q
            .points()
            .iter()
            .map(|p| p[2] + e(*p)[2])
            .fold(f64::INFINITY, f64::min);
        if low < floors[k] - FLOOR_MM - slack(q) {
            v.push((
                Rule::Floor,
                format!(
                    "line {}: commanded Z {:.4} below the level's floor {:.4} mm",
                    q.src, low, floors[k]
                ),
            ));
        }
    }
    let zero = |_: [f64; 3]| [0.0; 3];
    let o_low = simulated_lows(&s.machine, &o.moves, &o_runs, &zero, levels)?;
    let a_low = simulated_lows(&s.machine, &ans.moves, &a_levels, &e, levels)?;
    for k in 0..levels {
        if o_low[k] < floors[k] - FLOOR_MM {
            r.notes.push(format!(
                "level {k}: the original's simulated tool goes {:.2} µm below its floor",
                (floors[k] - o_low[k]) * 1e3
            ));
        }
        let floor = floors[k].min(o_low[k]);
        if a_low[k] < floor - FLOOR_MM {
            v.push((
                Rule::Floor,
                format!(
                    "level {k}: the simulated tool goes {:.2} µm below the floor {:.4} (original's lowest {:.4})",
                    (floors[k] - a_low[k]) * 1e3,
                    floors[k],
                    o_low[k]
                ),
            ));
        }
    }

    // Band where the material side is unknown (and towards it where G41/G42 say it).
    if let Some(p) = p {
        // The written program's points are rounded by up to `rounding_mm`; the servo is
        // linear, so its excursion moves by no more.
        let inch = a_frames.iter().any(|f| f.inch);
        let band_noise_mm = truecut::cam::rounding_mm(inch);
        if let Some(nominal) = p.models.first() {
            if nominal.compensated.gouge_mm > band_noise_mm {
                v.push((
                    Rule::Band,
                    format!(
                        "{:.2} µm beyond the band on the nominal model; notes {:?}; answer:\n{}",
                        nominal.compensated.gouge_mm * 1e3,
                        p.notes,
                        c.gcode
                    ),
                ));
            }
        }
        let worst = p
            .models
            .iter()
            .map(|m| m.compensated.gouge_mm)
            .fold(0.0, f64::max);
        if worst > band_noise_mm {
            r.notes.push(format!(
                "worst model of the set: {:.2} µm beyond the band",
                worst * 1e3
            ));
        }
    }

    // Dwells.
    if o.dwells != ans.dwells {
        v.push((
            Rule::Dwell,
            format!(
                "rs274 dwells {:?} in the original, {:?} in the answer",
                o.dwells, ans.dwells
            ),
        ));
    }
    for (i, raw) in out_text.iter().enumerate() {
        let g4 = word_spans(raw)
            .iter()
            .any(|w| w.letter == 'G' && g10(w.value) == 40);
        if g4 && src_text.get(src_of(i + 1).wrapping_sub(1)) != Some(raw) {
            v.push((
                Rule::Dwell,
                format!("answer line {}: a G4 not the source's: {raw}", i + 1),
            ));
        }
    }

    // Arcs stay arcs.
    r.arcs = (
        o.moves.iter().filter(|m| m.arc.is_some()).count(),
        ans.moves.iter().filter(|m| m.arc.is_some()).count(),
    );
    let arc_srcs: HashSet<usize> = o
        .moves
        .iter()
        .filter(|m| m.arc.is_some())
        .map(|m| m.src)
        .collect();
    for &l in &arc_srcs {
        let straight = |rd: &Reading| {
            rd.moves
                .iter()
                .filter(|m| m.src == l && m.feed && m.arc.is_none())
                .count()
        };
        if straight(&ans) > straight(&o) {
            v.push((
                Rule::Arc,
                format!("line {l}: an arc came back with straight pieces"),
            ));
        }
    }

    // Block budgets.
    let feeds = |rd: &Reading| rd.moves.iter().filter(|m| m.feed).count();
    if volumetric {
        let n: usize = o
            .moves
            .iter()
            .filter(|m| m.feed)
            .map(|m| need(&|q| s.map.error_at(q), m))
            .sum();
        r.need = Some(n);
        if a.mode == "volumetric" && feeds(&ans) as f64 > VOLUMETRIC_BUDGET * n as f64 {
            v.push((
                Rule::Budget,
                format!("{} feed moves, {n} needed", feeds(&ans)),
            ));
        }
    }
    if a.mode == "contour" {
        for (what, orig, got) in [
            ("lines", r.lines.0, r.lines.1),
            ("feed moves", feeds(&o), feeds(&ans)),
        ] {
            if got > CONTOUR_FACTOR * orig + CONTOUR_EXTRA {
                v.push((Rule::Budget, format!("{got} {what} from {orig}")));
            }
        }
        let mut corner: HashSet<usize> = arc_srcs.clone();
        for w in o.moves.windows(2) {
            if w[0].feed && w[1].feed {
                let (t0, t1) = (tangent(&w[0], 1.0), tangent(&w[1], 0.0));
                let cos = (0..3).map(|k| t0[k] * t1[k]).sum::<f64>().clamp(-1.0, 1.0);
                if cos.acos() >= CORNER_MIN_RAD {
                    corner.insert(w[0].src);
                    corner.insert(w[1].src);
                }
            }
        }
        let srcs: HashSet<usize> = ans.moves.iter().map(|m| m.src).collect();
        for l in srcs {
            let count = |rd: &Reading| rd.moves.iter().filter(|m| m.src == l && m.feed).count();
            if count(&ans) > count(&o) && !corner.contains(&l) {
                v.push((
                    Rule::Budget,
                    format!("line {l}: new points away from any corner"),
                ));
            }
        }
    }
    if a.mode == "both" {
        if let Some(vl) = volumetric_lines {
            if c.blocks > CONTOUR_FACTOR * vl + CONTOUR_EXTRA {
                v.push((
                    Rule::Budget,
                    format!("{} lines from the volumetric answer's {vl}", c.blocks),
                ));
            }
        }
    }

    // Words.
    super::words::words(a, c, o0, a0, &a_prog.blocks, &a_frames, &mut v);
    r.violations = v;
    Ok(r)
}
