//! Widened truth draws for the self-check (issue 23 item 3): truths drawn outside the fitter's
//! assumptions — a play whose table starts anywhere in the gap (and elsewhere again in the
//! validation block), thermal drift that carries on warm into the validation block, cyclic errors
//! on any axis (a slow Z too), two effects of comparable size at once, effects far outside their
//! usual range, and (opt-in, [`crate::gap::truth_clock`]) logs on their own clock.

use rand::{Rng, RngExt, SeedableRng};

use crate::gap::Effect;
use crate::gap::truth::{Truth, draw, measure_at};
use crate::motion::ServoAxis;

/// What kind of truth a case plants.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Category {
    /// The stored model is right.
    None,
    /// One library effect at its usual size, drawn wide (contact, warm, any axis).
    Single,
    /// One library effect far outside its usual range.
    Extreme,
    /// Two library effects of comparable size.
    Pair,
    /// An effect outside the library.
    OutOfLibrary,
    /// One library effect (or none) in a log with its own clock (delay, rate, jitter).
    ClockLog,
}

impl Category {
    /// Name in reports.
    pub fn name(self) -> &'static str {
        match self {
            Category::None => "none",
            Category::Single => "single",
            Category::Extreme => "extreme",
            Category::Pair => "pair",
            Category::OutOfLibrary => "out_of_library",
            Category::ClockLog => "clock_log",
        }
    }
}

/// Truth kinds of one cycle of the widened generator (without clock logs): none, the seven
/// library effects, two extremes, two pairs, one out-of-library plant.
pub const WIDE_KINDS: usize = 13;

/// The category of widened kind `kind` (`0..WIDE_KINDS`, plus `WIDE_KINDS` = a clock log).
pub fn wide_category(kind: usize) -> Category {
    match kind {
        0 => Category::None,
        1..=7 => Category::Single,
        8 | 9 => Category::Extreme,
        10 | 11 => Category::Pair,
        12 => Category::OutOfLibrary,
        _ => Category::ClockLog,
    }
}

/// A truth drawn for both blocks of a case.
#[derive(Clone, Debug)]
pub struct WideTruth {
    /// Its category.
    pub category: Category,
    /// The truth of the main block (which starts when the truth starts).
    pub main: Truth,
    /// The truth of the validation block: the same plant, a play's table elsewhere in the gap.
    pub validation: Truth,
    /// When the validation block starts after the main one started, s (the machine stays
    /// warm: a thermal drift carries on from where the main block left it).
    pub validation_t0_s: f64,
}

fn sign(rng: &mut impl Rng) -> f64 {
    if rng.random_bool(0.5) { 1.0 } else { -1.0 }
}

/// RMS over samples of the noise-free gap vector `|truth − stored|` (mm) for `cmd`.
pub fn gap_rms(servo: &[ServoAxis], truth: &Truth, cmd: &[Vec<f64>], period: f64) -> f64 {
    let mut quiet = rand::rngs::StdRng::seed_from_u64(0);
    let a = measure_at(servo, truth, cmd, period, 0.0, 0.0, &mut quiet);
    let b = measure_at(servo, &Truth::None, cmd, period, 0.0, 0.0, &mut quiet);
    let n = cmd.first().map_or(0, Vec::len).max(1);
    let s: f64 = a
        .iter()
        .zip(&b)
        .flat_map(|(a, b)| a.iter().zip(b).map(|(a, b)| (a - b).powi(2)))
        .sum();
    (s / n as f64).sqrt()
}

/// Friction per axis whose largest glitch against the stored model is `lo..hi` mm on each axis
/// (drawn as the classic friction, then rescaled twice: the glitch is nearly linear in the
/// friction, not exactly).
fn friction_with_glitch(
    servo: &[ServoAxis],
    cmd: &[Vec<f64>],
    period: f64,
    (lo, hi): (f64, f64),
    rng: &mut impl Rng,
) -> Truth {
    let Truth::Friction(mut f) = draw(1, servo, 1.0, rng) else {
        unreachable!("kind 1 is friction")
    };
    let target: Vec<f64> = f.iter().map(|_| rng.random_range(lo..hi)).collect();
    let mut quiet = rand::rngs::StdRng::seed_from_u64(0);
    let clean = measure_at(servo, &Truth::None, cmd, period, 0.0, 0.0, &mut quiet);
    for _ in 0..2 {
        let probe = measure_at(
            servo,
            &Truth::Friction(f.clone()),
            cmd,
            period,
            0.0,
            0.0,
            &mut quiet,
        );
        for (k, f) in f.iter_mut().enumerate() {
            let peak = probe[k]
                .iter()
                .zip(&clean[k])
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            if peak > 0.0 {
                *f *= target[k] / peak;
            }
        }
    }
    Truth::Friction(f)
}

/// A squareness error of random sign between two distinct random axes, its size (rad)
/// drawn from `size`.
fn squareness(d: usize, size: std::ops::Range<f64>, rng: &mut impl Rng) -> Truth {
    let t = rng.random_range(0..d);
    let s = (t + rng.random_range(1..d.max(2))) % d;
    Truth::Squareness(t, s, sign(rng) * rng.random_range(size))
}

/// A scale error of random sign on every axis, each size (mm/mm) drawn from `size`.
fn scale(d: usize, size: std::ops::Range<f64>, rng: &mut impl Rng) -> Truth {
    Truth::Scale(
        (0..d)
            .map(|_| sign(rng) * rng.random_range(size.clone()))
            .collect(),
    )
}

fn cyclic(d: usize, amp: (f64, f64), rng: &mut impl Rng) -> Truth {
    const PITCHES: [f64; 8] = [1.0, 2.0, 4.0, 5.0, 8.0, 10.0, 16.0, 20.0];
    // any axis: each with probability 0.6, at least one; a 3-axis case plants a slow Z alone
    // one time in four
    let on: Vec<bool> = if d == 3 && rng.random_bool(0.25) {
        vec![false, false, true]
    } else {
        loop {
            let on: Vec<bool> = (0..d).map(|_| rng.random_bool(0.6)).collect();
            if on.iter().any(|&o| o) {
                break on;
            }
        }
    };
    Truth::Cyclic(
        (0..d)
            .map(|_| PITCHES[rng.random_range(0..PITCHES.len())])
            .collect(),
        on.iter()
            .map(|&o| {
                if o {
                    rng.random_range(amp.0..amp.1)
                } else {
                    0.0
                }
            })
            .collect(),
        (0..d)
            .map(|_| rng.random_range(0.0..std::f64::consts::TAU))
            .collect(),
    )
}

fn thermal(d: usize, duration: f64, drift: (f64, f64), rng: &mut impl Rng) -> Truth {
    let tau = duration * rng.random_range(0.3..3.0);
    let gain = 1.0 / -(-duration / tau).exp_m1();
    Truth::Thermal(
        (0..d)
            .map(|_| sign(rng) * rng.random_range(drift.0..drift.1) * gain)
            .collect(),
        tau,
    )
}

/// One library effect (`none` and `unexplained`: no effect) at its usual size, drawn wider than the classic draws
/// ([`crate::gap::truth::draw`]): a play's table anywhere in its gap, a gain or squareness on
/// any axis, a cyclic error on any axes (pitch 1–20 mm); friction glitch 2–6 µm, play 4–25 µm,
/// gain ±5–25 %, squareness 10–80 µrad, scale 10–80 ppm, cyclic 1–5 µm, drift 3–20 µm.
pub fn draw_single(
    effect: Effect,
    servo: &[ServoAxis],
    cmd: &[Vec<f64>],
    period: f64,
    rng: &mut impl Rng,
) -> Truth {
    let d = servo.len();
    let duration = (cmd[0].len().max(2) - 1) as f64 * period;
    match effect {
        Effect::None | Effect::Unexplained => Truth::None,
        Effect::CoulombFriction => friction_with_glitch(servo, cmd, period, (0.002, 0.006), rng),
        Effect::Backlash => Truth::BacklashAt(
            (0..d).map(|_| rng.random_range(0.004..0.025)).collect(),
            (0..d).map(|_| rng.random_range(-1.0..=1.0)).collect(),
        ),
        Effect::ServoGainMismatch => {
            let k = rng.random_range(0..d);
            let mut kv: Vec<f64> = servo.iter().map(|s| s.kv).collect();
            kv[k] *= 1.0 + sign(rng) * rng.random_range(0.05..0.25);
            Truth::Mismatch(kv)
        }
        Effect::AxisSquareness => squareness(d, 10e-6..80e-6, rng),
        Effect::ScaleError => scale(d, 10e-6..80e-6, rng),
        Effect::CyclicError => cyclic(d, (0.001, 0.005), rng),
        Effect::ThermalDrift => thermal(d, duration, (0.003, 0.020), rng),
    }
}

/// One library effect far outside its usual range: friction glitch 20–60 µm, play 0.3–0.5 mm
/// on one axis, gain ×2.5–3.5 or ÷2.5–3.5 on one axis, squareness 2–5 mrad, scale
/// 3,000–7,000 ppm, cyclic 50–150 µm, drift 0.5–1.5 mm over the block.
pub fn draw_extreme(
    effect: Effect,
    servo: &[ServoAxis],
    cmd: &[Vec<f64>],
    period: f64,
    rng: &mut impl Rng,
) -> Truth {
    let d = servo.len();
    let duration = (cmd[0].len().max(2) - 1) as f64 * period;
    match effect {
        Effect::None | Effect::Unexplained => Truth::None,
        Effect::CoulombFriction => friction_with_glitch(servo, cmd, period, (0.020, 0.060), rng),
        Effect::Backlash => {
            let k = rng.random_range(0..d);
            Truth::BacklashAt(
                (0..d)
                    .map(|j| {
                        if j == k {
                            rng.random_range(0.3..0.5)
                        } else {
                            0.0
                        }
                    })
                    .collect(),
                (0..d).map(|_| rng.random_range(-1.0..=1.0)).collect(),
            )
        }
        Effect::ServoGainMismatch => {
            let k = rng.random_range(0..d);
            let mut kv: Vec<f64> = servo.iter().map(|s| s.kv).collect();
            let r: f64 = rng.random_range(2.5..3.5);
            kv[k] *= if rng.random_bool(0.5) { r } else { 1.0 / r };
            Truth::Mismatch(kv)
        }
        Effect::AxisSquareness => squareness(d, 2e-3..5e-3, rng),
        Effect::ScaleError => scale(d, 3000e-6..7000e-6, rng),
        Effect::CyclicError => cyclic(d, (0.05, 0.15), rng),
        Effect::ThermalDrift => thermal(d, duration, (0.5, 1.5), rng),
    }
}

/// The truth scaled in size by `k` (the stored `servo` anchors a gain mismatch: `kv` moves
/// `k` times as far from the stored gain). Out-of-library plants and pairs are kept.
pub fn scaled(truth: &Truth, k: f64, servo: &[ServoAxis]) -> Truth {
    let times = |v: &[f64]| v.iter().map(|x| x * k).collect::<Vec<f64>>();
    match truth {
        Truth::Friction(f) => Truth::Friction(times(f)),
        Truth::BacklashAt(b, s) => Truth::BacklashAt(times(b), s.clone()),
        Truth::Backlash(b, c) => Truth::Backlash(times(b), *c),
        Truth::Mismatch(kv) => Truth::Mismatch(
            kv.iter()
                .zip(servo)
                .map(|(kv, s)| (s.kv + k * (kv - s.kv)).max(0.2 * s.kv))
                .collect(),
        ),
        Truth::Squareness(t, s, a) => Truth::Squareness(*t, *s, a * k),
        Truth::Scale(s) => Truth::Scale(times(s)),
        Truth::Cyclic(p, a, ph) => Truth::Cyclic(p.clone(), times(a), ph.clone()),
        Truth::Thermal(dr, tau) => Truth::Thermal(times(dr), *tau),
        other => other.clone(),
    }
}

/// Two distinct library effects drawn as [`draw_single`], the second rescaled so that its
/// noise-free gap RMS on `cmd` is 0.5–2 × the first's (three secant corrections; friction and
/// play are not linear in their size). Returns the pair and the ratio reached.
pub fn draw_pair(
    servo: &[ServoAxis],
    cmd: &[Vec<f64>],
    period: f64,
    rng: &mut impl Rng,
) -> (Truth, f64) {
    let i = rng.random_range(0..Effect::LIBRARY.len());
    let j = (i + rng.random_range(1..Effect::LIBRARY.len())) % Effect::LIBRARY.len();
    let a = draw_single(Effect::LIBRARY[i], servo, cmd, period, rng);
    let mut b = draw_single(Effect::LIBRARY[j], servo, cmd, period, rng);
    let ga = gap_rms(servo, &a, cmd, period);
    let target = ga * rng.random_range(0.5..2.0);
    let mut gb = gap_rms(servo, &b, cmd, period);
    for _ in 0..3 {
        if gb <= 0.0 || ga <= 0.0 || (gb / target - 1.0).abs() < 0.05 {
            break;
        }
        b = scaled(&b, target / gb, servo);
        gb = gap_rms(servo, &b, cmd, period);
    }
    let ratio = if ga > 0.0 { gb / ga } else { 0.0 };
    (Truth::Pair(Box::new(a), Box::new(b)), ratio)
}

/// The same plant for another block: a play's table redrawn anywhere in its gap.
pub fn revalidate(truth: &Truth, rng: &mut impl Rng) -> Truth {
    match truth {
        Truth::BacklashAt(b, s) => Truth::BacklashAt(
            b.clone(),
            s.iter().map(|_| rng.random_range(-1.0..=1.0)).collect(),
        ),
        Truth::Pair(a, b) => {
            Truth::Pair(Box::new(revalidate(a, rng)), Box::new(revalidate(b, rng)))
        }
        other => other.clone(),
    }
}

/// Draws the widened truth of kind `kind` (see [`wide_category`]; the library effect of kinds
/// 1..=7 is `Effect::LIBRARY[kind − 1]`, of extremes and clock logs drawn at random) for the
/// main command `cmd` sampled every `period` s. The validation block starts 1–1.3 main-block
/// durations after the main one (warm).
pub fn draw_wide(
    kind: usize,
    servo: &[ServoAxis],
    cmd: &[Vec<f64>],
    period: f64,
    rng: &mut impl Rng,
) -> WideTruth {
    let category = wide_category(kind);
    let duration = (cmd[0].len().max(2) - 1) as f64 * period;
    let pick =
        |rng: &mut dyn rand::Rng| Effect::LIBRARY[rng.random_range(0..Effect::LIBRARY.len())];
    let main = match category {
        Category::None => Truth::None,
        Category::Single => draw_single(Effect::LIBRARY[kind - 1], servo, cmd, period, rng),
        Category::Extreme => {
            let e = pick(rng);
            draw_extreme(e, servo, cmd, period, rng)
        }
        Category::Pair => draw_pair(servo, cmd, period, rng).0,
        Category::OutOfLibrary => draw(8, servo, duration, rng),
        Category::ClockLog => {
            // none one time in eight, else a library effect at its usual size
            let e = if rng.random_bool(0.125) {
                Effect::None
            } else {
                pick(rng)
            };
            draw_single(e, servo, cmd, period, rng)
        }
    };
    let validation = revalidate(&main, rng);
    WideTruth {
        category,
        main,
        validation,
        validation_t0_s: duration * rng.random_range(1.0..1.3),
    }
}

#[cfg(test)]
mod tests;
