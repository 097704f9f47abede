//! The self-check's judge of `where` for planted friction and play: the loose reading (the top
//! span overlaps an event interval at which the effect acts) and the literal reading
//! (the top span *starts* at an event where the effect acts), both on an affected axis.

use rand::SeedableRng;

use crate::gap::effects::first_direction;
use crate::gap::events::{Span, axis_events};
use crate::gap::truth::{Truth, measure};
use crate::motion::ServoAxis;

/// `where` judged two ways for one case.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WhereCheck {
    /// Loose (the reading before issue 23): the top span names an affected axis and overlaps
    /// one of the intervals of [`acting_intervals`] (5 samples of slack after them).
    pub loose: bool,
    /// Literal: the top span names an affected axis and starts within `max(3, n/1000)` samples
    /// (the events' merge distance in `rank_spans`) of an event at which the effect acts
    /// ([`acting_events`]).
    pub literal: bool,
}

/// Sample intervals `[a, b]` of one axis' events (from [`axis_events`]) at which a planted
/// friction (`friction`) or backlash acts:
///
/// - every reversal, as the interval from the stop before it (when the axis dwelt before
///   turning, as at a rectangle's corner) to the restart in the new direction: the lost
///   motion or the friction step of a reversal through a dwell shows at either end;
/// - friction also at every start from rest and every stop (the friction force switches on or
///   off there, a glitch as large as a reversal through a dwell);
/// - backlash also at the axis' first start (the slack is taken up in the first move).
///
/// An axis that never reverses (a slowly rising Z) thus carries its friction or backlash gap
/// from its first start.
pub fn acting_intervals(events: &[(usize, String)], friction: bool) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut last_stop: Option<usize> = None;
    let mut started = false;
    for (i, label) in events {
        let i = *i;
        if label.ends_with("reversal") {
            out.push((last_stop.unwrap_or(i), i));
            last_stop = None;
            started = true;
        } else if label.ends_with("start") {
            if friction || !started {
                out.push((i, i));
            }
            last_stop = None;
            started = true;
        } else if label.ends_with("stop") {
            if friction {
                out.push((i, i));
            }
            last_stop = Some(i);
        }
    }
    out
}

/// The event samples of one axis at which a planted effect acts, for the literal reading: its
/// reversals (the sample where the motor takes its new direction, after a dwell too) — where a
/// friction force flips by twice its size and a play's slack is taken up; for friction on an
/// axis that never reverses (a slowly rising Z) its starts from rest instead; for a play also
/// the first start when the slack taken up there is at least a fifth of the play
/// (`first_slack` = that slack / play). Starts and stops of an axis that does reverse are not
/// counted for friction: the loose reading counts them.
pub fn acting_events(events: &[(usize, String)], friction: bool, first_slack: f64) -> Vec<usize> {
    let reverses = events.iter().any(|(_, l)| l.ends_with("reversal"));
    let mut out = Vec::new();
    let mut started = false;
    for (i, label) in events {
        let reversal = label.ends_with("reversal");
        let start = label.ends_with("start");
        let acts = reversal
            || (friction && start && !reverses)
            || (!friction && start && !started && first_slack >= 0.2);
        if acts {
            out.push(*i);
        }
        started |= reversal || start;
    }
    out
}

/// Judges `where` (the ranked `spans`) for a truth that is a single friction or play (`None`
/// for every other truth): the affected axes are those whose noise-free gap RMS or peak is at
/// least half the largest axis' (a glitch that an integrator clears quickly is small in RMS next
/// to a persistent lag on another axis, yet it is where that axis' gap arises); an axis moving
/// from the first sample, or only creeping below the events' threshold, starts at sample 0.
pub fn check_where(
    servo: &[ServoAxis],
    truth: &Truth,
    cmd: &[Vec<f64>],
    period: f64,
    names: &[String],
    spans: &[Span],
) -> Option<WhereCheck> {
    let friction = match truth {
        Truth::Friction(_) => true,
        Truth::Backlash(..) | Truth::BacklashAt(..) => false,
        _ => return None,
    };
    let miss = WhereCheck {
        loose: false,
        literal: false,
    };
    let mut quiet = rand::rngs::StdRng::seed_from_u64(0);
    let clean = measure(servo, &Truth::None, cmd, period, 0.0, &mut quiet);
    let hidden = measure(servo, truth, cmd, period, 0.0, &mut quiet);
    let (rms, peak): (Vec<f64>, Vec<f64>) = clean
        .iter()
        .zip(&hidden)
        .map(|(c, h)| {
            let d: Vec<f64> = c.iter().zip(h).map(|(a, b)| a - b).collect();
            let s: f64 = d.iter().map(|v| v * v).sum();
            let p = d.iter().fold(0.0, |m: f64, v| m.max(v.abs()));
            ((s / d.len().max(1) as f64).sqrt(), p)
        })
        .unzip();
    let top_rms = rms.iter().copied().fold(0.0, f64::max);
    let top_peak = peak.iter().copied().fold(0.0, f64::max);
    let Some(span) = spans.first() else {
        return Some(miss);
    };
    let Some(k) = names.iter().position(|a| *a == span.axis) else {
        return Some(miss);
    };
    if rms[k] < 0.5 * top_rms && peak[k] < 0.5 * top_peak {
        return Some(miss);
    }
    let mut events = axis_events(cmd, k, &names[k]);
    let c = &cmd[k];
    let travel = c.iter().fold(f64::NEG_INFINITY, |m: f64, v| m.max(*v))
        - c.iter().fold(f64::INFINITY, |m: f64, v| m.min(*v));
    let started = events
        .first()
        .is_some_and(|(_, l)| l.ends_with("start") || l.ends_with("reversal"));
    if !started && travel > 1e-3 {
        events.insert(0, (0, format!("{} start", names[k])));
    }
    let overlaps = |a: usize, b: usize| a <= span.end && b + 5 >= span.start;
    let loose = acting_intervals(&events, friction)
        .iter()
        .any(|&(a, b)| overlaps(a, b));
    // slack taken up by the first move, as a share of the play
    let first_slack = match truth {
        Truth::Backlash(_, centred) => {
            if *centred {
                0.5
            } else {
                0.0
            }
        }
        Truth::BacklashAt(_, s) => 0.5 * (1.0 + s[k].clamp(-1.0, 1.0) * first_direction(c)),
        _ => 1.0,
    };
    let tol = (c.len() / 1000).max(3);
    let literal = acting_events(&events, friction, first_slack)
        .iter()
        .any(|&e| e.abs_diff(span.start) <= tol);
    Some(WhereCheck { loose, literal })
}

#[cfg(test)]
mod tests;
