//! The self-check's cases: a random servo, a program and its validation program, a truth drawn
//! by the classic or the widened generator, measured (on the command's clock or by a logger of
//! its own, then aligned) — ready for the blind diagnosis in [`crate::gap::selfcheck`].

use rand::{RngExt, SeedableRng};

use crate::gap::align::{Aligned, Alignment, TimedLog, refine_delay};
use crate::gap::motion::{MotionBlock, MotionOptions};
use crate::gap::plant::AxisPlant;
use crate::gap::programs::{Program, generate};
use crate::gap::truth::{Truth, draw, measure, measure_at};
use crate::gap::truth_clock::{ClockLog, ClockSpec, draw_clock, naive_on_command_clock, resample};
use crate::gap::truth_wide::{Category, draw_wide};
use crate::gap::{Effect, Error};
use crate::motion::ServoAxis;

/// A case ready to diagnose.
pub(crate) struct Built {
    pub(crate) servo: Vec<ServoAxis>,
    pub(crate) period: f64,
    pub(crate) main: MotionBlock,
    pub(crate) val: MotionBlock,
    pub(crate) truth: Truth,
    pub(crate) category: Category,
    pub(crate) program: Program,
    pub(crate) sigma: f64,
    pub(crate) clock: Option<ClockSpec>,
    /// Clock-log cases: the main and validation logs on their own clocks (`main` and `val`
    /// hold their naive readings until aligned).
    pub(crate) logs: Option<(ClockLog, ClockLog)>,
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

/// The draws every generator opens with, in this order: the seeded generator, the 1 ms
/// period, 2 axes with probability `p_two` (else 3), the servo, the program, and its main and
/// validation blocks (the second run in the other direction).
#[allow(clippy::type_complexity)]
fn opening(
    seed: u64,
    p_two: f64,
) -> (
    rand::rngs::StdRng,
    f64,
    usize,
    Vec<ServoAxis>,
    Program,
    [Vec<Vec<f64>>; 2],
) {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let period = 0.001;
    let axes = if rng.random_bool(p_two) { 2 } else { 3 };
    let servo = random_servo(axes, &mut rng);
    let program = Program::ALL[rng.random_range(0..Program::ALL.len())];
    let flip = rng.random_bool(0.5);
    let cmd = generate(program, axes, period, flip, &mut rng);
    let vcmd = generate(program, axes, period, !flip, &mut rng);
    (rng, period, axes, servo, program, [cmd, vcmd])
}

/// A case of the classic generator: kind 0 none, 1..=7 the library, 8 out of library.
pub(crate) fn build_classic(kind: usize, seed: u64) -> Built {
    let (mut rng, period, axes, servo, program, [cmd, vcmd]) = opening(seed, 0.8);
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
    Built {
        category: match kind {
            0 => Category::None,
            1..=7 => Category::Single,
            _ => Category::OutOfLibrary,
        },
        servo,
        period,
        main: MotionBlock {
            commanded: cmd,
            measured: meas,
        },
        val: MotionBlock {
            commanded: vcmd,
            measured: vmeas,
        },
        truth,
        program,
        sigma,
        clock: None,
        logs: None,
    }
}

/// A case of the widened generator (kinds of [`wide_category`]).
pub(crate) fn build_wide(kind: usize, seed: u64) -> Built {
    let (mut rng, period, _, servo, program, [cmd, vcmd]) = opening(seed, 0.7);
    let w = draw_wide(kind, &servo, &cmd, period, &mut rng);
    let sigma = rng.random_range(0.0002..0.0005);
    let clock = (w.category == Category::ClockLog).then(|| draw_clock(period, &mut rng));
    let mut logs = Vec::new();
    let mut block = |truth: &Truth, c: &[Vec<f64>], t0: f64| match &clock {
        None => measure_at(&servo, truth, c, period, t0, sigma, &mut rng),
        Some(spec) => {
            let clean = measure_at(&servo, truth, c, period, t0, 0.0, &mut rng);
            let log = resample(&clean, period, spec, sigma, &mut rng);
            let naive = naive_on_command_clock(&log, c[0].len(), period);
            logs.push(log);
            naive
        }
    };
    let meas = block(&w.main, &cmd, 0.0);
    let vmeas = block(&w.validation, &vcmd, w.validation_t0_s);
    let logs = (logs.len() == 2).then(|| {
        let v = logs.pop().expect("two logs");
        (logs.pop().expect("two logs"), v)
    });
    Built {
        category: w.category,
        servo,
        period,
        main: MotionBlock {
            commanded: cmd,
            measured: meas,
        },
        val: MotionBlock {
            commanded: vcmd,
            measured: vmeas,
        },
        truth: w.main,
        program,
        sigma,
        clock,
        logs,
    }
}

/// A clock-log case's logs beside their first alignments (to the stored simulation), kept for
/// [`refine_logs`]; `true_delay_s` is the main log's drawn delay (for the note).
pub(crate) struct TimedCase {
    main: (TimedLog, Alignment),
    val: (TimedLog, Alignment),
    true_delay_s: f64,
}

/// Puts a clock-log case's logs on the program's grid (delay and rate found from the motion
/// against the stored simulation, [`TimedLog::estimate`]) and weights the main block's
/// unobserved instants 0; other cases pass. When a log cannot be aligned the case keeps its
/// naive reading (said in its note).
pub(crate) fn align_logs(
    mut b: Built,
    opts: &MotionOptions,
) -> (Built, MotionOptions, String, Option<TimedCase>) {
    let mut opts = opts.clone();
    let Some((main_log, val_log)) = b.logs.take() else {
        return (b, opts, String::new(), None);
    };
    let names = ["X", "Y", "Z"];
    let plants: Result<Vec<AxisPlant>, Error> = b
        .servo
        .iter()
        .enumerate()
        .map(|(k, s)| AxisPlant::new(names[k], s, b.period))
        .collect();
    let true_delay_s = main_log.spec.delay_s;
    let aligned = plants.and_then(|p| {
        let timed = |cmd: &[Vec<f64>], log: ClockLog| -> Result<(TimedLog, Aligned), Error> {
            let timed = TimedLog::new(p.clone(), cmd, log.t, log.measured, b.period)?;
            let a = timed.place(&timed.estimate()?)?;
            Ok((timed, a))
        };
        Ok((
            timed(&b.main.commanded, main_log)?,
            timed(&b.val.commanded, val_log)?,
        ))
    });
    match aligned {
        Ok(((mt, m), (vt, v))) => {
            let note = format!(
                "aligned: delay {:.6} s (true {true_delay_s:.6}), rate {:.6}",
                m.alignment.delay_s, m.alignment.rate_ratio
            );
            b.main = m.block;
            b.val = v.block;
            opts.observed = Some(m.observed);
            let timed = TimedCase {
                main: (mt, m.alignment),
                val: (vt, v.alignment),
                true_delay_s,
            };
            (b, opts, note, Some(timed))
        }
        Err(e) => (
            b,
            opts,
            format!("alignment failed ({e}): naive reading"),
            None,
        ),
    }
}

/// Refines both logs' delays with `effects` ([`refine_delay`]: the effects refitted to each
/// log at every delay tried, the same procedure for the validation log as for the main one)
/// and puts them on the grid again; returns the note.
pub(crate) fn refine_logs(
    b: &mut Built,
    opts: &mut MotionOptions,
    timed: &TimedCase,
    effects: &[Effect],
) -> Result<String, Error> {
    let m = refine_delay(&timed.main.0, &timed.main.1, effects)?;
    let v = refine_delay(&timed.val.0, &timed.val.1, effects)?;
    let note = format!(
        "; refined with {:?}: delay {:.6} s (true {:.6})",
        m.alignment.refined_with, m.alignment.delay_s, timed.true_delay_s
    );
    b.main = m.block;
    b.val = v.block;
    opts.observed = Some(m.observed);
    Ok(note)
}
