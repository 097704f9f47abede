//! Where the gap lies: the timeline cut into spans at motion events (axis reversals, stops,
//! starts, corners, tight arcs), ranked by their share of the squared gap.

use serde::Serialize;

/// A contiguous sample range `[start, end]` (inclusive) and its share of `Σ|measured − sim|²`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Span {
    /// First sample.
    pub start: usize,
    /// Last sample (inclusive).
    pub end: usize,
    /// Part of the total squared gap, 0..1.
    pub share: f64,
    /// The event the span begins with, e.g. "X reversal".
    pub label: String,
}

/// Radius below which an arc counts as tight, mm.
pub const TIGHT_ARC_RADIUS_MM: f64 = 5.0;
/// Direction change between neighbouring segments that counts as a corner, rad (20°).
pub const CORNER_ANGLE_RAD: f64 = 0.35;

/// Motion events of a command (per axis columns, mm), as `(sample, label)` sorted by sample.
///
/// Velocities are the FOH slopes `(c[i+1] − c[i])/T`; an axis reverses where its velocity
/// changes sign (ignoring speeds below 1 % of the peak), a stop is the speed falling below
/// 1 % of the peak, a corner a direction change above 20° between neighbouring segments,
/// a tight arc a turning radius `|ds/dθ|` below 5 mm. Bad cases: noisy commands give spurious
/// reversals (the command is expected to be a clean interpolator output).
pub fn motion_events(cmd: &[Vec<f64>], axes: &[String]) -> Vec<(usize, String)> {
    let n = cmd.first().map_or(0, Vec::len);
    let mut events: Vec<(usize, String)> = Vec::new();
    if n < 3 {
        return events;
    }
    let d = cmd.len();
    let vel = |i: usize| -> Vec<f64> { (0..d).map(|k| cmd[k][i + 1] - cmd[k][i]).collect() };
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let vmax = (0..n - 1).map(|i| norm(&vel(i))).fold(0.0, f64::max);
    if vmax == 0.0 {
        return events;
    }
    let thr = 0.01 * vmax;
    let mut last_sign = vec![0.0f64; d];
    let mut last_strong = vec![0usize; d];
    let mut moving = false;
    let mut in_arc = false;
    let mut prev: Option<Vec<f64>> = None;
    for i in 0..n - 1 {
        let v = vel(i);
        let speed = norm(&v);
        if speed >= thr && !moving {
            if i > 0 {
                events.push((i, "start".to_string()));
            }
            moving = true;
        } else if speed < thr && moving {
            events.push((i + 1, "stop".to_string()));
            moving = false;
        }
        for k in 0..d {
            if v[k].abs() >= thr {
                let s = v[k].signum();
                if last_sign[k] != 0.0 && s != last_sign[k] {
                    // the reversal is where the velocity took its new sign, not where it
                    // crossed the 1 % threshold
                    let mut j = i;
                    while j > last_strong[k] + 1 && (cmd[k][j] - cmd[k][j - 1]) * s > 0.0 {
                        j -= 1;
                    }
                    let name = axes.get(k).map_or("axis", String::as_str);
                    events.push((j, format!("{name} reversal")));
                }
                last_sign[k] = s;
                last_strong[k] = i;
            }
        }
        if let Some(p) = &prev {
            let (np, nv) = (norm(p), speed);
            if np >= thr && nv >= thr {
                let cos = p.iter().zip(&v).map(|(a, b)| a * b).sum::<f64>() / (np * nv);
                let angle = cos.clamp(-1.0, 1.0).acos();
                if angle > CORNER_ANGLE_RAD {
                    events.push((i, "corner".to_string()));
                }
                let radius = 0.5 * (np + nv) / angle.max(1e-300);
                let tight = angle <= CORNER_ANGLE_RAD && radius < TIGHT_ARC_RADIUS_MM;
                if tight && !in_arc {
                    events.push((i, "tight arc".to_string()));
                } else if !tight && in_arc {
                    events.push((i, "arc exit".to_string()));
                }
                in_arc = tight;
            }
        }
        prev = Some(v);
    }
    events.sort_by_key(|e| e.0);
    events
}

/// Cuts `[0, n)` at the events (merging events closer than `max(3, n/1000)` samples into one
/// label), scores each span by its share of `Σ_i |r_i|²` (`residual` per axis, mm) and returns
/// the `max_spans` worst, worst first.
pub fn rank_spans(
    cmd: &[Vec<f64>],
    residual: &[Vec<f64>],
    axes: &[String],
    max_spans: usize,
) -> Vec<Span> {
    let n = residual.first().map_or(0, Vec::len);
    if n == 0 {
        return Vec::new();
    }
    let min_gap = (n / 1000).max(3);
    let mut cuts: Vec<(usize, Vec<String>)> = vec![(0, vec!["program start".to_string()])];
    for (i, label) in motion_events(cmd, axes) {
        let last = cuts.last_mut().expect("non-empty");
        if i < last.0 + min_gap {
            if !last.1.contains(&label) {
                last.1.push(label);
            }
        } else {
            cuts.push((i, vec![label]));
        }
    }
    let sq: Vec<f64> = (0..n)
        .map(|i| residual.iter().map(|c| c[i] * c[i]).sum())
        .collect();
    let total: f64 = sq.iter().sum();
    let mut spans: Vec<Span> = cuts
        .iter()
        .enumerate()
        .map(|(j, (start, labels))| {
            let end = cuts.get(j + 1).map_or(n - 1, |c| c.0 - 1);
            let part: f64 = sq[*start..=end].iter().sum();
            Span {
                start: *start,
                end,
                share: if total > 0.0 { part / total } else { 0.0 },
                label: labels.join(", "),
            }
        })
        .collect();
    spans.sort_by(|a, b| b.share.total_cmp(&a.share).then(a.start.cmp(&b.start)));
    spans.truncate(max_spans);
    spans
}

#[cfg(test)]
mod tests;
