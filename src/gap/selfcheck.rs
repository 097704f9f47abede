//! The self-check: truth plants with each effect withheld from the stored model (plus "none"
//! cases and effects outside the library), diagnosed blind; confusion matrix, accuracy,
//! median validation shrink and false-alarm rate.

use rand::{RngExt, SeedableRng};

use crate::gap::events::axis_events;
use crate::gap::motion::{MotionBlock, MotionOptions, diagnose_motion};
use crate::gap::programs::{Program, generate};
use crate::gap::truth::{Truth, draw, measure};
use crate::gap::{Effect, Error};
use crate::motion::ServoAxis;

/// One diagnosed case.
#[derive(Clone, Debug)]
pub struct CaseResult {
    /// Truth label: an effect name or "out_of_library".
    pub truth: String,
    /// The diagnosis' verdict.
    pub verdict: Effect,
    /// `1 − rms_after/rms_before` on the validation block.
    pub shrink: f64,
    /// Program family.
    pub program: Program,
    /// Noise σ used, mm.
    pub sigma: f64,
    /// Friction and backlash cases: whether `where`'s top entry names an affected axis and
    /// overlaps one of the events of that axis at which the planted effect acts (affected: the
    /// axes whose noise-free gap RMS or peak is at least half the largest axis'; events: see
    /// [`acting_intervals`]; an axis moving from the first sample starts there).
    pub where_ok: Option<bool>,
    /// The literal reading: the top entry names an affected axis and its span holds
    /// one of that axis' reversal samples (a reversal through a dwell counts only at its
    /// restart, an axis that never reverses can never be right).
    pub where_strict: Option<bool>,
    /// The top `where` entry, "label (axis) start..end".
    pub where_top: String,
    /// Effects in `steps`, in order.
    pub steps: Vec<Effect>,
    /// Held-out share of the gap above the noise that the steps leave (`unexplained`).
    pub unexplained_share: f64,
    /// The truth plant, as drawn (Debug text).
    pub truth_detail: String,
}

/// Summary of a self-check run.
#[derive(Clone, Debug)]
pub struct SelfCheckReport {
    /// Every case.
    pub cases: Vec<CaseResult>,
    /// Correct verdicts / cases, over library effects and "none" (out-of-library excluded).
    pub accuracy: f64,
    /// Median validation shrink over cases whose truth is a library effect.
    pub median_shrink: f64,
    /// Share of "none" cases answered with an effect.
    pub false_alarm_rate: f64,
    /// Per truth class with `where_ok`: (class, right, right by the strict reading, cases).
    pub where_accuracy: Vec<(String, usize, usize, usize)>,
    /// Out-of-library cases answered `unexplained` or named with a held-out unexplained
    /// share of at least 50 % (issue 23's gate), and all out-of-library cases.
    pub outside_answered: (usize, usize),
}

fn random_servo(axes: usize, rng: &mut impl rand::Rng) -> Vec<ServoAxis> {
    let cascade = rng.random_bool(0.8);
    (0..axes)
        .map(|_| {
            loop {
                let kv = rng.random_range(20.0..60.0);
                let s = ServoAxis {
                    kv,
                    kff: if rng.random_bool(0.3) {
                        0.0
                    } else {
                        rng.random_range(0.3..0.9)
                    },
                    kp_v: cascade.then(|| kv * rng.random_range(8.0..20.0)),
                    ti_v: (cascade && rng.random_bool(0.7)).then(|| rng.random_range(0.005..0.03)),
                    tc: (cascade && rng.random_bool(0.7)).then(|| rng.random_range(0.0002..0.0015)),
                };
                if s.validate().is_ok() {
                    break s;
                }
            }
        })
        .collect()
}

/// Runs one case with truth kind `kind` (0 none, 1..=7 library, 8 out of library).
pub fn run_case(kind: usize, seed: u64, opts: &MotionOptions) -> Result<CaseResult, Error> {
    run_case_inner(kind, seed, opts, false)
}

/// As [`run_case`], printing the diagnosis to stderr; returns the case as text.
pub fn run_case_verbose(kind: usize, seed: u64, opts: &MotionOptions) -> Result<String, Error> {
    run_case_inner(kind, seed, opts, true).map(|c| format!("{c:?}"))
}

fn run_case_inner(
    kind: usize,
    seed: u64,
    opts: &MotionOptions,
    verbose: bool,
) -> Result<CaseResult, Error> {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let period = 0.001;
    let axes = if rng.random_bool(0.8) { 2 } else { 3 };
    let servo = random_servo(axes, &mut rng);
    let program = Program::ALL[rng.random_range(0..Program::ALL.len())];
    let flip = rng.random_bool(0.5);
    let cmd = generate(program, axes, period, flip, &mut rng);
    let vcmd = generate(program, axes, period, !flip, &mut rng);
    let duration = (cmd[0].len() - 1) as f64 * period;
    let mut truth = draw(kind, &servo, duration, &mut rng);
    if let Truth::Friction(f) = &mut truth {
        // scale each axis' friction so its worst glitch is 2–6 µm (the magnitude)
        let probe = measure(
            &servo,
            &Truth::Friction(f.clone()),
            &cmd,
            period,
            0.0,
            &mut rng,
        );
        let clean = measure(&servo, &Truth::None, &cmd, period, 0.0, &mut rng);
        for k in 0..axes {
            let peak = probe[k]
                .iter()
                .zip(&clean[k])
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            if peak > 0.0 {
                f[k] *= rng.random_range(0.002..0.006) / peak;
            }
        }
    }
    let sigma = rng.random_range(0.0002..0.0005);
    let meas = measure(&servo, &truth, &cmd, period, sigma, &mut rng);
    let vmeas = measure(&servo, &truth, &vcmd, period, sigma, &mut rng);
    let names: Vec<String> = ["X", "Y", "Z"][..axes]
        .iter()
        .map(|s| s.to_string())
        .collect();
    let main = MotionBlock {
        commanded: cmd,
        measured: meas,
    };
    let val = MotionBlock {
        commanded: vcmd,
        measured: vmeas,
    };
    let d = diagnose_motion(&names, &servo, period, &main, Some(&val), opts)?;
    if verbose {
        eprintln!(
            "servo {servo:?}\ntruth {truth:?}\nprogram {program:?} n {} gap {:.3} um noise {:.3} um",
            main.commanded[0].len(),
            d.gap_before.rms * 1e3,
            d.noise_mm * 1e3
        );
        for e in &d.effects {
            eprintln!(
                "  {:<22} score {:>8.4}  {:?}",
                e.fitted.effect().name(),
                e.score,
                e.params
            );
        }
    }
    let where_check = matches!(truth, Truth::Friction(_) | Truth::Backlash(..)).then(|| {
        let clean = measure(&servo, &Truth::None, &main.commanded, period, 0.0, &mut rng);
        let hidden = measure(&servo, &truth, &main.commanded, period, 0.0, &mut rng);
        // an axis is affected when its noise-free gap reaches half the largest axis' in RMS
        // or in peak: a glitch that an integrator clears quickly is small in RMS next to a
        // persistent lag on another axis, yet it is where that axis' gap arises
        let (rms, peak): (Vec<f64>, Vec<f64>) = (0..axes)
            .map(|k| {
                let d: Vec<f64> = clean[k]
                    .iter()
                    .zip(&hidden[k])
                    .map(|(a, b)| a - b)
                    .collect();
                let s: f64 = d.iter().map(|v| v * v).sum();
                let p = d.iter().fold(0.0, |m: f64, v| m.max(v.abs()));
                ((s / d.len() as f64).sqrt(), p)
            })
            .unzip();
        let top_rms = rms.iter().copied().fold(0.0, f64::max);
        let top_peak = peak.iter().copied().fold(0.0, f64::max);
        let Some(span) = d.spans.first() else {
            return (false, false);
        };
        let Some(k) = names.iter().position(|a| *a == span.axis) else {
            return (false, false);
        };
        if rms[k] < 0.5 * top_rms && peak[k] < 0.5 * top_peak {
            return (false, false);
        }
        let mut events = axis_events(&main.commanded, k, &names[k]);
        // an axis that moves from the first sample, or only creeps below the events'
        // threshold, starts at the program start
        let c = &main.commanded[k];
        let span_mm = c.iter().fold(f64::NEG_INFINITY, |m: f64, v| m.max(*v))
            - c.iter().fold(f64::INFINITY, |m: f64, v| m.min(*v));
        let started = events
            .first()
            .is_some_and(|(_, l)| l.ends_with("start") || l.ends_with("reversal"));
        if !started && span_mm > 1e-3 {
            events.insert(0, (0, format!("{} start", names[k])));
        }
        let overlaps = |a: usize, b: usize| a <= span.end && b + 5 >= span.start;
        let strict = events
            .iter()
            .any(|(i, l)| l.ends_with("reversal") && overlaps(*i, *i));
        let physical = acting_intervals(&events, matches!(truth, Truth::Friction(_)))
            .iter()
            .any(|&(a, b)| overlaps(a, b));
        (physical, strict)
    });
    let where_top = d.spans.first().map_or(String::new(), |s| {
        format!("{} ({}) {}..{}", s.label, s.axis, s.start, s.end)
    });
    if verbose {
        eprintln!("where: {:?}", &d.spans[..d.spans.len().min(4)]);
        for s in &d.steps {
            eprintln!(
                "  step {:<22} score {:.4} {:?}",
                s.fitted.effect().name(),
                s.score,
                s.params
            );
        }
        eprintln!("  unexplained {:?}", d.unexplained);
    }
    let v = d.validation.expect("validation requested");
    Ok(CaseResult {
        truth: truth
            .effect()
            .map_or("out_of_library", Effect::name)
            .to_string(),
        verdict: d.verdict,
        shrink: if v.rms_before > 0.0 {
            1.0 - v.rms_after / v.rms_before
        } else {
            0.0
        },
        program,
        sigma,
        where_ok: where_check.map(|c| c.0),
        where_strict: where_check.map(|c| c.1),
        where_top,
        steps: d.steps.iter().map(|s| s.fitted.effect()).collect(),
        unexplained_share: d.unexplained.heldout_share,
        truth_detail: format!("{truth:?}"),
    })
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

/// Runs `cases` cases cycling through the truth kinds (none, the 7 effects, out of library),
/// seeds `seed, seed+1, ...`, and summarises them.
pub fn run(cases: usize, seed: u64, opts: &MotionOptions) -> Result<SelfCheckReport, Error> {
    let seeds: Vec<u64> = (0..cases as u64).map(|i| seed + i).collect();
    let serial = MotionOptions {
        threads: 1,
        ..opts.clone()
    };
    let results = crate::numeric::parallel::map_dynamic(&seeds, opts.threads, |s| {
        run_case(((s - seed) % 9) as usize, s, &serial)
    });
    let cases: Vec<CaseResult> = results.into_iter().collect::<Result<_, _>>()?;
    let scored: Vec<&CaseResult> = cases
        .iter()
        .filter(|c| c.truth != "out_of_library")
        .collect();
    let correct = scored
        .iter()
        .filter(|c| c.truth == c.verdict.name())
        .count();
    let mut shrinks: Vec<f64> = scored
        .iter()
        .filter(|c| c.truth != "none")
        .map(|c| c.shrink)
        .collect();
    shrinks.sort_by(f64::total_cmp);
    let nones: Vec<&&CaseResult> = scored.iter().filter(|c| c.truth == "none").collect();
    let alarms = nones.iter().filter(|c| c.verdict != Effect::None).count();
    let where_accuracy = ["coulomb_friction", "backlash"]
        .iter()
        .map(|class| {
            let rows: Vec<(bool, bool)> = cases
                .iter()
                .filter(|c| c.truth == *class)
                .filter_map(|c| c.where_ok.zip(c.where_strict))
                .collect();
            (
                class.to_string(),
                rows.iter().filter(|ok| ok.0).count(),
                rows.iter().filter(|ok| ok.1).count(),
                rows.len(),
            )
        })
        .collect();
    let outside: Vec<&CaseResult> = cases
        .iter()
        .filter(|c| c.truth == "out_of_library")
        .collect();
    let answered = outside
        .iter()
        .filter(|c| {
            c.verdict == Effect::Unexplained
                || (c.verdict != Effect::None && c.unexplained_share >= 0.5)
        })
        .count();
    Ok(SelfCheckReport {
        outside_answered: (answered, outside.len()),
        where_accuracy,
        accuracy: correct as f64 / scored.len().max(1) as f64,
        median_shrink: shrinks.get(shrinks.len() / 2).copied().unwrap_or(0.0),
        false_alarm_rate: alarms as f64 / nones.len().max(1) as f64,
        cases,
    })
}

impl SelfCheckReport {
    /// The confusion matrix (rows: truth, columns: verdict) and the summary, as text.
    pub fn render(&self) -> String {
        let verdicts: Vec<Effect> = std::iter::once(Effect::None)
            .chain(Effect::LIBRARY)
            .chain([Effect::Unexplained])
            .collect();
        let mut truths: Vec<String> = verdicts.iter().map(|e| e.name().to_string()).collect();
        truths.push("out_of_library".into());
        let short = |s: &str| s.chars().take(9).collect::<String>();
        let mut out = format!("{:<20}", "truth \\ verdict");
        for v in &verdicts {
            out += &format!("{:>10}", short(v.name()));
        }
        out += "\n";
        for t in &truths {
            let row: Vec<&CaseResult> = self.cases.iter().filter(|c| &c.truth == t).collect();
            if row.is_empty() {
                continue;
            }
            out += &format!("{:<20}", t);
            for v in &verdicts {
                out += &format!("{:>10}", row.iter().filter(|c| c.verdict == *v).count());
            }
            out += "\n";
        }
        out += &format!(
            "cases {}  accuracy {:.1} %  median validation shrink {:.1} %  false alarms {:.1} %\n",
            self.cases.len(),
            100.0 * self.accuracy,
            100.0 * self.median_shrink,
            100.0 * self.false_alarm_rate
        );
        let (answered, outside) = self.outside_answered;
        out += &format!(
            "out of library answered unexplained (or named leaving >= 50 % held-out): \
             {answered}/{outside}\n"
        );
        for (class, ok, strict, total) in &self.where_accuracy {
            out += &format!(
                "where right on {class}: {ok}/{total} ({:.0} %); top span on a reversal \
                 sample: {strict}/{total} ({:.0} %)\n",
                100.0 * *ok as f64 / (*total).max(1) as f64,
                100.0 * *strict as f64 / (*total).max(1) as f64
            );
        }
        out
    }
}

/// Truth kinds cycle in this order: index → label (for reports and tests).
pub fn kind_label(kind: usize) -> &'static str {
    match kind {
        0 => "none",
        1..=7 => Effect::LIBRARY[kind - 1].name(),
        _ => "out_of_library",
    }
}

#[cfg(test)]
mod tests;
