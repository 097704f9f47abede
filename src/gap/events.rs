//! Where the gap lies: each axis' timeline cut into spans at its motion events (reversals,
//! starts, stops), ranked by the gap that arises in each span on that axis; plus the path
//! events (corners, tight arcs) of the whole command.

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
    /// The axis that carries the span's gap (its events cut the span).
    pub axis: String,
    /// The program line executing at the span's first sample, when the command came from a
    /// program.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub line: Option<u32>,
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

/// Events of one axis `k` of a command (per axis columns, mm), as `(sample, label)` sorted
/// by sample: its reversals (`"X reversal"`, where the velocity took its new sign), starts
/// from rest (`"X start"`) and stops (`"X stop"`). The axis counts as moving while its FOH
/// speed `|c[i+1] − c[i]|/T` is at least 1 % of the peak path speed. Bad cases: an axis
/// creeping below 1 % of the peak speed has no events.
pub fn axis_events(cmd: &[Vec<f64>], k: usize, name: &str) -> Vec<(usize, String)> {
    let n = cmd.first().map_or(0, Vec::len);
    let mut events = Vec::new();
    if n < 3 || k >= cmd.len() {
        return events;
    }
    let vmax = (0..n - 1)
        .map(|i| {
            cmd.iter()
                .map(|c| (c[i + 1] - c[i]).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .fold(0.0, f64::max);
    if vmax == 0.0 {
        return events;
    }
    let thr = 0.01 * vmax;
    let c = &cmd[k];
    let (mut last_sign, mut last_strong, mut moving) = (0.0f64, 0usize, false);
    for i in 0..n - 1 {
        let v = c[i + 1] - c[i];
        if v.abs() >= thr {
            let s = v.signum();
            if last_sign != 0.0 && s != last_sign {
                let mut j = i;
                while j > last_strong + 1 && (c[j] - c[j - 1]) * s > 0.0 {
                    j -= 1;
                }
                events.push((j, format!("{name} reversal")));
            } else if !moving && i > 0 {
                let mut j = i;
                while j > last_strong + 1 && (c[j] - c[j - 1]) * s > 0.0 {
                    j -= 1;
                }
                events.push((j, format!("{name} start")));
            }
            last_sign = s;
            last_strong = i;
            moving = true;
        } else if moving {
            events.push((i + 1, format!("{name} stop")));
            moving = false;
        }
    }
    events.sort_by_key(|e| e.0);
    events
}

/// Where the gap arises, per axis (CONTRACT v1.1 "where"): each axis' timeline is cut at its
/// own events ([`axis_events`], events closer than `max(3, n/1000)` samples merged), and a span
/// is scored by the gap that *arises* in it on that axis,
/// `Σ_{i∈span} (r_k[i] − r̄_k)²` with `r̄_k` the mean residual of the `max(5, n/1000)` samples
/// before the span (0 for the first span): a lag that sets in at an X reversal and persists
/// until the next counts in the span that begins at that reversal, and nowhere after, while a
/// spike counts where it occurs. `share` is the span's part of the sum of all spans' scores
/// over all axes; the `max_spans` largest are returned, largest first, each naming its axis.
///
/// Tried and measured on the blind self-check (`truecut gap selfcheck --cases 180`, seeds 1000
/// and 5000, friction cases whose top span holds a reversal sample): scoring only a settling
/// window of 4/kv after each event (a step counted once whatever the span's length) gave 11
/// and 13 of 20 against 13 and 16; subtracting each axis' noise floor σ²·len changed nothing.
/// Bad cases: a gap that grows slowly (drift) is spread over many spans of small share; at a
/// reversal through a dwell (a rectangle's corner) friction's stop and restart glitches are
/// equal, so the stop's span may rank first.
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
    let lookback = (n / 1000).max(5);
    let mut spans = Vec::new();
    for (k, r) in residual.iter().enumerate() {
        let name = axes.get(k).map_or("axis", String::as_str);
        let mut cuts: Vec<(usize, Vec<String>)> = vec![(0, vec!["program start".to_string()])];
        for (i, label) in axis_events(cmd, k, name) {
            let last = cuts.last_mut().expect("non-empty");
            if i < last.0 + min_gap {
                if !last.1.contains(&label) {
                    last.1.push(label);
                }
            } else {
                cuts.push((i, vec![label]));
            }
        }
        for (j, (start, labels)) in cuts.iter().enumerate() {
            let end = cuts.get(j + 1).map_or(n - 1, |c| c.0 - 1);
            let carry = if *start == 0 {
                0.0
            } else {
                let from = start.saturating_sub(lookback);
                r[from..*start].iter().sum::<f64>() / (start - from) as f64
            };
            let score: f64 = r[*start..=end].iter().map(|v| (v - carry).powi(2)).sum();
            // a reversal names the span even when the axis also starts there
            let mut labels = labels.clone();
            labels.sort_by_key(|l| !l.ends_with("reversal"));
            if labels.iter().any(|l| l.ends_with("reversal")) {
                labels.retain(|l| !l.ends_with("start"));
            }
            spans.push(Span {
                start: *start,
                end,
                share: score,
                label: labels.join(", "),
                axis: name.to_string(),
                line: None,
            });
        }
    }
    let total: f64 = spans.iter().map(|s| s.share).sum();
    for s in spans.iter_mut() {
        s.share = if total > 0.0 { s.share / total } else { 0.0 };
    }
    spans.sort_by(|a, b| b.share.total_cmp(&a.share).then(a.start.cmp(&b.start)));
    spans.truncate(max_spans);
    spans
}

#[cfg(test)]
mod tests;
