//! The notes of a pre-distortion: sentences on where it could not help, and why.

use super::corners::{CornerResult, CornerScore, CornerSpot, GOUGE_LIMIT_MM};
use super::reference::Reference;
use crate::motion::Machine;

/// The sentence on corner `s` with its scores `b` before and `a` after, and `why` it kept
/// them.
fn corner_sentence(s: &CornerSpot, b: &CornerScore, a: &CornerScore, why: &str) -> String {
    let rms = |x: &CornerScore| (x.sum_sq / x.len.max(1e-12)).sqrt();
    format!(
        "line {}: corner (turn {:.0}°): contour error {:.1} µm before, {:.1} µm after (max), \
         distance-weighted RMS {:.1} → {:.1} µm; {why}",
        s.line,
        s.turn_rad.to_degrees(),
        b.max * 1e3,
        a.max * 1e3,
        rms(b) * 1e3,
        rms(a) * 1e3
    )
}

/// One sentence per corner of the corner stage whose largest error stayed above 0.5× its
/// original one or whose distance-weighted RMS stayed above 0.3× (corners with an original
/// error above 1 µm), naming what held the search back, at most 20. `max_duration_ratio` is
/// the run's ([`super::PredistortOptions`]), named where time held a corner back.
pub(super) fn corner_notes(
    spots: &[CornerSpot],
    res: &CornerResult,
    max_duration_ratio: f64,
) -> Vec<String> {
    let mut out = Vec::new();
    let mut more = 0;
    for (c, s) in spots.iter().enumerate() {
        let (b, a) = (res.before[c], res.after[c]);
        let rms = |x: super::corners::CornerScore| (x.sum_sq / x.len.max(1e-12)).sqrt();
        if b.max <= 1e-3 || (a.max <= 0.5 * b.max && rms(a) <= 0.3 * rms(b)) {
            continue;
        }
        if out.len() >= 20 {
            more += 1;
            continue;
        }
        let why = if res.refused_gouge[c] > 0 {
            format!(
                "carrying the command further past the corner would take the tool into the \
                 material: more than {:.0} µm beyond the path outside the turn at an inside corner \
                 (G41/G42), deeper into the turn than before at an outside corner",
                GOUGE_LIMIT_MM * 1e3
            )
        } else if res.refused_time[c] > 0 {
            format!(
                "a larger correction would slow the corner beyond its share of the duration \
                 budget (max_duration_ratio {max_duration_ratio}: the program may take up to \
                 {max_duration_ratio}× the original's time; a larger ratio lets the corners slow \
                 further where they follow each other closely)"
            )
        } else {
            format!(
                "the interpolator turns the command within max_accel per period, so at the \
                 junction speed {:.1} mm/s the servo's lag cannot be taken out further with G01 points \
                 at the programmed feed",
                s.v_junction
            )
        };
        out.push(corner_sentence(s, &b, &a, &why));
    }
    if more > 0 {
        out.push(format!("and {more} more corners like these"));
    }
    out
}

/// Why the loops (module `loops`) left corners above the gates.
pub(super) enum LoopLimit {
    /// The program reached its duration budget (`max_duration_ratio`), or the loops were
    /// searched a second time for it (module `loops`).
    Time(f64),
    /// The search stopped at its work bound (the original program's length, s).
    Work(f64),
    /// Neither: no loop shape within the room between the neighbouring corners did better.
    Room,
}

/// One sentence per corner the loops turn whose largest error stayed above 0.5× its error
/// before the corner stages (`before`; `after` with the loops) or whose distance-weighted RMS
/// stayed above 0.3× (corners with an error above 1 µm before), at most 20, each naming what
/// held the loops back (`limit`, the same for every corner: the loops are searched
/// together).
pub(super) fn loop_notes(
    spots: &[CornerSpot],
    before: &[CornerScore],
    after: &[CornerScore],
    limit: &LoopLimit,
) -> Vec<String> {
    let rms = |x: &CornerScore| (x.sum_sq / x.len.max(1e-12)).sqrt();
    let left: Vec<usize> = (0..spots.len())
        .filter(|&c| {
            let (b, a) = (&before[c], &after[c]);
            b.max > 1e-3 && (a.max > 0.5 * b.max || rms(a) > 0.3 * rms(b))
        })
        .collect();
    let why = match limit {
        LoopLimit::Time(ratio) => format!(
            "the duration budget (max_duration_ratio {ratio}) binds: larger loops at the \
             program's corners, or the points around them moved further, would take the program \
             past it; a larger ratio lets the loops grow and take out more of the servo's lag"
        ),
        LoopLimit::Work(seconds) => format!(
            "the search for the loops stopped at its work bound ({} simulated interpolation \
             periods; each trial simulates the whole {seconds:.1} s program): compensating a \
             shorter section of the program around its corners lets it search further",
            super::loops::LOOP_WORK_PERIODS
        ),
        LoopLimit::Room => "no smooth loop within the room between this corner and its \
             neighbours did better: the corners follow each other closer than the servo needs \
             to catch up"
            .to_string(),
    };
    let mut out: Vec<String> = left
        .iter()
        .take(20)
        .map(|&c| corner_sentence(&spots[c], &before[c], &after[c], &why))
        .collect();
    if left.len() > 20 {
        out.push(format!("and {} more corners like these", left.len() - 20));
    }
    out
}

/// One sentence per inside corner where the compensated program stops (`dwells`, s per
/// split point; corner `c`'s `P_in` is point `k + 2c + 1`), at most 20: the stop is a change
/// a machinist should know of (the tool rests against the wall there).
pub(super) fn stop_notes(spots: &[CornerSpot], res: &CornerResult, dwells: &[f64]) -> Vec<String> {
    let mut out = Vec::new();
    let mut more = 0;
    for (c, s) in spots.iter().enumerate() {
        let stop = dwells.get(s.k + 2 * c + 1).copied().unwrap_or(0.0);
        if stop <= 0.0 {
            continue;
        }
        if out.len() >= 20 {
            more += 1;
            continue;
        }
        out.push(format!(
            "line {}: inside corner (turn {:.0}°, material outside the turn by G41/G42): the \
             compensated program stops {:.0} ms at the corner (G4 P{:.0}, milliseconds as \
             Fanuc reads P) so that the tool reaches the corner before it turns, since an \
             overshoot there would cut into the material; contour error {:.1} → {:.1} µm (max)",
            s.line,
            s.turn_rad.to_degrees(),
            stop * 1e3,
            stop * 1e3,
            res.before[c].max * 1e3,
            res.after[c].max * 1e3,
        ));
    }
    if more > 0 {
        out.push(format!("and {more} more inside corners with a stop"));
    }
    out
}

/// One sentence per source line where pre-distortion steps were refused.
pub(super) fn refusal_notes(
    machine: &Machine,
    lines: &[usize],
    refused: &[(usize, usize)],
) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    let mut last_line = usize::MAX;
    for (k, &(count, axis)) in refused.iter().enumerate() {
        if count == 0 || lines[k] == last_line {
            continue;
        }
        last_line = lines[k];
        let ax = &machine.axes[axis];
        out.push(format!(
            "line {}: sharp corner at full feed: pre-distortion steps refused, since the compensated \
             path would turn so sharply that axis {} (max_accel {} mm/s²) forces the junction below \
             the programmed feed; following the path there needs a feed reduction, which the goal forbids",
            lines[k], ax.name, ax.limits.max_accel
        ));
    }
    out
}

/// One sentence per source line whose largest contour error the pre-distortion did not bring
/// below 0.3× the original's there (lines with an original error above 1 µm), at most 20.
/// `orig_line` is the source line of each period of the original, `comp_line` that of each
/// period of the compensated run (each run is judged on its own lines: the compensated one may
/// run a little longer); lines written as programmed (`kept`: rapids, cycles) are not
/// pre-distorted and get no sentence.
pub(super) fn residual_notes(
    orig_ce: &[f64],
    orig_line: &[u32],
    comp_ce: &[f64],
    comp_line: &[usize],
    reference: &Reference,
    kept: &dyn Fn(usize) -> bool,
) -> Vec<String> {
    use std::collections::BTreeMap;
    let mut per: BTreeMap<usize, (f64, f64)> = BTreeMap::new();
    for (i, e) in orig_ce.iter().enumerate() {
        let v = per.entry(orig_line[i] as usize).or_default();
        v.0 = v.0.max(*e);
    }
    let last = comp_line.len().saturating_sub(1);
    for (i, e) in comp_ce.iter().enumerate() {
        let Some(&line) = comp_line.get(i.min(last)) else {
            break;
        };
        let v = per.entry(line).or_default();
        v.1 = v.1.max(*e);
    }
    let last_line = reference.line.last().copied().unwrap_or(0);
    let corner_lines: std::collections::BTreeSet<usize> = (0..reference.knots.len())
        .filter(|&k| reference.corner[k])
        .map(|k| reference.line[k])
        .collect();
    let bad: Vec<_> = per
        .iter()
        .filter(|(line, (o, c))| *o > 1e-3 && *c > 0.3 * o && !kept(**line))
        .collect();
    let mut out: Vec<String> = bad
        .iter()
        .take(20)
        .map(|(line, (o, c))| {
            let why = if **line == last_line {
                "the final stop: the deceleration there needs a feed reduction, which the goal forbids"
            } else if corner_lines.contains(line) {
                "a corner: the servo lag there needs a feed reduction, which the goal forbids"
            } else {
                "a speed change or a blend the G01 points cannot reshape at the programmed feed"
            };
            format!(
                "line {line}: contour error {:.1} µm before, {:.1} µm after (max), at {why}",
                o * 1e3,
                c * 1e3
            )
        })
        .collect();
    if bad.len() > 20 {
        out.push(format!("and {} more lines like these", bad.len() - 20));
    }
    out
}
