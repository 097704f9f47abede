//! Unit tests of `crate::gap::align`: logs drawn from the RK4 truth plant (`gap::truth`, not
//! the diagnosis' exact discretization) on a grid ten times finer than the program's, sampled
//! at their own stamps.

use rand::{RngExt, SeedableRng};

use super::*;
use crate::gap::Effect;
use crate::gap::programs::{Program, generate};
use crate::gap::truth::{Truth, measure};
use crate::motion::ServoAxis;

const PERIOD: f64 = 0.001;
const FINE: usize = 10;

fn servo() -> ServoAxis {
    ServoAxis {
        kv: 30.0,
        kff: 0.5,
        kp_v: Some(400.0),
        ti_v: Some(0.01),
        tc: Some(0.0006),
    }
}

fn plants() -> Vec<AxisPlant> {
    ["X", "Y"]
        .iter()
        .map(|a| AxisPlant::new(a, &servo(), PERIOD).unwrap())
        .collect()
}

/// A program's command (per axis, one row a period) and the truth plant's noise-free motion
/// on a grid `FINE` times finer, the command held `HOLD_S` past its end.
struct Scene {
    cmd: Vec<Vec<f64>>,
    fine: Vec<Vec<f64>>,
}

fn scene(program: Program, seed: u64) -> Scene {
    scene_with(program, seed, &Truth::None)
}

/// As [`scene`], the truth plant carrying `truth`.
fn scene_with(program: Program, seed: u64, truth: &Truth) -> Scene {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let cmd = generate(program, 2, PERIOD, false, &mut rng);
    let hold = (HOLD_S / PERIOD) as usize;
    let fine_cmd: Vec<Vec<f64>> = cmd
        .iter()
        .map(|c| {
            let mut e = c.clone();
            e.resize(c.len() + hold, c[c.len() - 1]);
            (0..(e.len() - 1) * FINE + 1)
                .map(|j| {
                    let (i, f) = (j / FINE, (j % FINE) as f64 / FINE as f64);
                    if i + 1 < e.len() {
                        e[i] + f * (e[i + 1] - e[i])
                    } else {
                        e[i]
                    }
                })
                .collect()
        })
        .collect();
    let fine = measure(
        &[servo(), servo()],
        truth,
        &fine_cmd,
        PERIOD / FINE as f64,
        1e-12,
        &mut rng,
    );
    Scene { cmd, fine }
}

impl Scene {
    /// The truth at program time `tau` (s), held outside the simulated stretch.
    fn at(&self, k: usize, tau: f64) -> f64 {
        let c = &self.fine[k];
        let x = (tau / (PERIOD / FINE as f64)).max(0.0);
        let i = (x as usize).min(c.len() - 2);
        let f = (x - i as f64).min(1.0);
        c[i] + f * (c[i + 1] - c[i])
    }

    fn duration(&self) -> f64 {
        (self.cmd[0].len() - 1) as f64 * PERIOD
    }

    /// A log on its own clock (`t = delay + rate·τ`) at `hz` with uniform jitter `±jitter_s`,
    /// from `pre_s` before the program to `post_s` after its end, without samples in `gap`
    /// (log-clock seconds), with Gaussian noise `sigma` mm.
    #[allow(clippy::too_many_arguments)]
    fn log(
        &self,
        delay: f64,
        rate: f64,
        hz: f64,
        jitter_s: f64,
        (pre_s, post_s): (f64, f64),
        gap: Option<(f64, f64)>,
        sigma: f64,
        seed: u64,
    ) -> (Vec<f64>, Vec<Vec<f64>>) {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let normal = rand_distr::Normal::new(0.0, sigma).unwrap();
        let (t0, t1) = (
            delay - rate * pre_s,
            delay + rate * (self.duration() + post_s),
        );
        let mut t = Vec::new();
        let mut cols = vec![Vec::new(), Vec::new()];
        let mut j = 0;
        loop {
            let s = t0 + j as f64 / hz + rng.random_range(-jitter_s..=jitter_s);
            j += 1;
            if s > t1 {
                break;
            }
            if gap.is_some_and(|(a, b)| s > a && s < b) {
                continue;
            }
            let tau = (s - delay) / rate;
            t.push(s);
            for (k, c) in cols.iter_mut().enumerate() {
                c.push(self.at(k, tau) + rng.sample(normal));
            }
        }
        (t, cols)
    }
}

#[test]
fn known_delay_and_rate_are_recovered() {
    // goal (stated here): delay within 50 us, rate within 5 ppm, on a 125 Hz log with +-1 ms
    // jitter, a 0.2 s gap and 0.3 um noise; rate exactly 1 when the clocks agree
    let sc = scene(Program::Circle, 11);
    for (delay, rate) in [(0.37, 1.0), (-0.8, 1.0 + 200e-6), (12.5, 1.0 - 150e-6)] {
        let gap = Some((delay + 1.0, delay + 1.2));
        let (t, log) = sc.log(delay, rate, 125.0, 0.001, (0.5, 0.3), gap, 0.0003, 7);
        let a = align_block(&plants(), &sc.cmd, &t, &log, PERIOD).unwrap();
        let al = &a.alignment;
        eprintln!(
            "truth delay {delay} s rate {rate}: ours delay {:.6} s rate {:.7} ({} samples, {} used, {} before, gaps {:?}, residual {:.5} mm)",
            al.delay_s,
            al.rate_ratio,
            al.samples,
            al.samples_used,
            al.samples_before,
            al.gaps,
            al.residual_rms_mm
        );
        assert!((al.delay_s - delay).abs() < 50e-6, "{al:?}");
        assert!((al.rate_ratio - rate).abs() < 5e-6, "{al:?}");
        if rate == 1.0 {
            assert_eq!(al.rate_ratio, 1.0, "no drift is reported as none");
        }
        assert_eq!(al.gaps.len(), 1, "{al:?}");
        assert!((al.gaps[0].t_end - al.gaps[0].t_start - 0.2).abs() < 0.02);
        assert_eq!(al.samples, t.len());
        assert!(al.samples_before > 0);
        // the observed grid instants hold the truth there (interpolation error + noise)
        let mut worst: f64 = 0.0;
        for (i, w) in a.observed.iter().enumerate() {
            if *w > 0.0 {
                for k in 0..2 {
                    worst = worst.max((a.block.measured[k][i] - sc.at(k, i as f64 * PERIOD)).abs());
                }
            }
        }
        assert!(worst < 0.003, "{worst}");
        // nothing is observed inside the gap
        let (ga, gb) = (
            (al.gaps[0].t_start - delay) / rate,
            (al.gaps[0].t_end - delay) / rate,
        );
        let inside = (0..a.observed.len())
            .filter(|&i| a.observed[i] > 0.0)
            .map(|i| i as f64 * PERIOD)
            .filter(|&g| g > ga + PERIOD && g < gb - PERIOD)
            .count();
        assert_eq!(inside, 0);
    }
}

#[test]
fn the_delay_refined_with_the_effect_is_the_true_one() {
    // a 15 um play on X: matched to the stored simulation alone, the first delay takes in part
    // of the play's lag; refitting the play at every delay tried takes it back out. Goal
    // (stated here): the refined delay within 2 % of a period (20 us at 1 ms) of the truth, and
    // no further from it than the first estimate
    let truth = Truth::Backlash(vec![0.015, 0.0], true);
    let delay = 0.37;
    for (program, seed) in [(Program::ZigZag, 21), (Program::Rectangle, 22)] {
        let sc = scene_with(program, seed, &truth);
        let gap = Some((delay + 1.0, delay + 1.2));
        let (t, log) = sc.log(delay, 1.0, 125.0, 0.001, (0.5, 0.3), gap, 0.0003, 9);
        let timed = TimedLog::new(plants(), &sc.cmd, t, log, PERIOD).unwrap();
        let first = timed.place(&timed.estimate().unwrap()).unwrap();
        let refined = refine_delay(&timed, &first.alignment, &[Effect::Backlash]).unwrap();
        let (d0, d1) = (first.alignment.delay_s, refined.alignment.delay_s);
        eprintln!(
            "{program:?} with a 15 um play, truth delay {delay} s: first {:+.2} us, refined \
             {:+.2} us (residual {:.2} um against the stored simulation, {:.2} um with the play)",
            (d0 - delay) * 1e6,
            (d1 - delay) * 1e6,
            refined.alignment.residual_rms_mm * 1e3,
            refined.alignment.residual_effects_rms_mm.unwrap() * 1e3
        );
        assert!(
            (d1 - delay).abs() < 0.02 * PERIOD,
            "{:?}",
            refined.alignment
        );
        assert!((d1 - delay).abs() <= (d0 - delay).abs(), "{d0} {d1}");
        assert_eq!(refined.alignment.delay_stored_s, d0);
        assert_eq!(refined.alignment.refined_with, vec!["backlash".to_string()]);
        assert_eq!(refined.alignment.rate_ratio, 1.0);
    }
    // without effects the first estimate stands
    let sc = scene(Program::Circle, 11);
    let (t, log) = sc.log(delay, 1.0, 125.0, 0.001, (0.5, 0.3), None, 0.0003, 7);
    let timed = TimedLog::new(plants(), &sc.cmd, t, log, PERIOD).unwrap();
    let first = timed.place(&timed.estimate().unwrap()).unwrap();
    let same = refine_delay(&timed, &first.alignment, &[]).unwrap();
    assert_eq!(same.alignment, first.alignment);
}

#[test]
fn a_servo_trace_faster_than_the_grid_observes_every_instant() {
    let sc = scene(Program::Rectangle, 3);
    // 4 kHz on a 1 kHz grid, log starting 0.2 s after the program
    let (t, log) = sc.log(5.0, 1.0, 4000.0, 0.00002, (-0.2, 0.1), None, 0.0003, 4);
    let a = align_block(&plants(), &sc.cmd, &t, &log, PERIOD).unwrap();
    eprintln!("4 kHz log: {:?}", a.alignment);
    assert!((a.alignment.delay_s - 5.0).abs() < 50e-6);
    let first = (0.2 / PERIOD) as usize + 1;
    assert!(a.observed[..first - 2].iter().all(|w| *w == 0.0));
    assert!(a.observed[first..].iter().all(|w| *w == 1.0));
}

#[test]
fn a_log_of_another_program_is_refused() {
    let sc = scene(Program::Circle, 11);
    let other = scene(Program::ZigZag, 12);
    let (t, log) = other.log(0.37, 1.0, 125.0, 0.001, (0.3, 0.3), None, 0.0003, 5);
    let e = align_block(&plants(), &sc.cmd, &t, &log, PERIOD).unwrap_err();
    assert!(
        matches!(&e, Error::Align(s) if s.contains("does not follow this program")),
        "{e}"
    );
}

#[test]
fn a_log_too_short_or_still_is_refused() {
    let sc = scene(Program::Circle, 11);
    let (t, log) = sc.log(0.37, 1.0, 125.0, 0.001, (0.3, 0.3), None, 0.0003, 5);
    let e = align_block(
        &plants(),
        &sc.cmd,
        &t[..12],
        &[log[0][..12].to_vec(), log[1][..12].to_vec()],
        PERIOD,
    )
    .unwrap_err();
    assert!(
        matches!(&e, Error::Align(s) if s.contains("at least 20")),
        "{e}"
    );
    // 40 samples at rest before the program: nothing to align to
    let e = align_block(
        &plants(),
        &sc.cmd,
        &t[..40],
        &[log[0][..40].to_vec(), log[1][..40].to_vec()],
        PERIOD,
    )
    .unwrap_err();
    assert!(
        matches!(&e, Error::Align(s) if s.contains("does not move")),
        "{e}"
    );
}

#[test]
fn a_repeating_motion_seen_in_its_middle_is_ambiguous() {
    // the same circle program three times over; the log sees 0.6 s of the middle turn only
    let sc = scene(Program::Circle, 11);
    let n = sc.cmd[0].len();
    let cmd: Vec<Vec<f64>> = sc
        .cmd
        .iter()
        .map(|c| c.iter().copied().cycle().take(3 * n).collect())
        .collect();
    let mut rng = rand::rngs::StdRng::seed_from_u64(8);
    let normal = rand_distr::Normal::new(0.0, 0.0003).unwrap();
    let start = n + n / 3;
    let t: Vec<f64> = (0..600).map(|i| i as f64 * 0.001).collect();
    let log: Vec<Vec<f64>> = plants()
        .iter()
        .zip(&cmd)
        .map(|(p, c)| {
            p.linear(c)[start..start + 600]
                .iter()
                .map(|x| x + rng.sample(normal))
                .collect()
        })
        .collect();
    let e = align_block(&plants(), &cmd, &t, &log, PERIOD).unwrap_err();
    assert!(
        matches!(&e, Error::Align(s) if s.contains("about as well")),
        "{e}"
    );
    // from the middle turn on, with a second at rest after the program: one place only
    let tail: Vec<Vec<f64>> = plants()
        .iter()
        .zip(&cmd)
        .map(|(p, c)| {
            let mut held = c.clone();
            held.resize(c.len() + 1000, c[c.len() - 1]);
            p.linear(&held)[n..].to_vec()
        })
        .collect();
    let t: Vec<f64> = (0..tail[0].len()).map(|i| 3.0 + i as f64 * 0.001).collect();
    let a = align_block(&plants(), &cmd, &t, &tail, PERIOD).unwrap();
    assert!(
        (a.alignment.delay_s - (3.0 - n as f64 * PERIOD)).abs() < 1e-5,
        "{:?}",
        a.alignment
    );
}

#[test]
fn time_stamps_are_checked_at_the_door() {
    assert!(check_times("measured_t", &[0.0, 0.1, 0.2], 3).is_ok());
    let e = check_times("measured_t", &[0.0, 0.1], 3).unwrap_err();
    assert!(e.to_string().contains("measured_t"), "{e}");
    let e = check_times("measured_t", &[0.0, f64::NAN, 0.2], 3).unwrap_err();
    assert_eq!(
        e,
        Error::NonFinite {
            field: "measured_t".into(),
            index: 1
        }
    );
    let e = check_times("measured_t", &[0.0, 0.2, 0.2], 3).unwrap_err();
    assert!(e.to_string().contains("measured_t[2]"), "{e}");
}

#[test]
fn masked_statistics_read_only_the_observed_samples() {
    let meas = vec![vec![1.0, 5.0, 3.0, 7.0]];
    let sim = vec![vec![0.0, 0.0, 0.0, 0.0]];
    let w = [1.0, 0.0, 1.0, 0.0];
    let s = masked_stats(&meas, &sim, Some(&w));
    assert!((s.rms - 5f64.sqrt()).abs() < 1e-12 && s.max == 3.0);
    assert_eq!(masked_stats(&meas, &sim, None), gap_stats_all(&meas, &sim));
    let filled = fill_unobserved(&meas, Some(&w));
    assert_eq!(filled[0], vec![1.0, 2.0, 3.0, 3.0]);
    let only = observed_only(std::borrow::Cow::Borrowed(&meas), Some(&w));
    assert_eq!(only[0], vec![1.0, 3.0]);
}

fn gap_stats_all(m: &[Vec<f64>], s: &[Vec<f64>]) -> crate::gap::GapStats {
    crate::gap::motion::gap_stats(m, s)
}

#[test]
fn unobserved_samples_do_not_reach_the_diagnosis() {
    // the law of the hook in `diagnose_motion_structured`: whatever the placeholders at
    // weight-0 instants hold, the diagnosis is the same, bit for bit
    use crate::gap::motion::MotionOptions;
    let sc = scene(Program::Rectangle, 5);
    let n = sc.cmd[0].len();
    let measured: Vec<Vec<f64>> = (0..2)
        .map(|k| {
            (0..n)
                .map(|i| sc.at(k, i as f64 * PERIOD) + 0.004 * i as f64 / n as f64)
                .collect()
        })
        .collect();
    let hole = n / 3..n / 3 + 200;
    let observed: Vec<f64> = (0..n)
        .map(|i| f64::from(u8::from(i % 8 == 3 && !hole.contains(&i))))
        .collect();
    let mut spoiled = measured.clone();
    for col in spoiled.iter_mut() {
        for (i, v) in col.iter_mut().enumerate() {
            if observed[i] == 0.0 {
                *v += 5.0 * ((i % 7) as f64 - 3.0);
            }
        }
    }
    let opts = MotionOptions {
        threads: 1,
        observed: Some(observed),
        ..MotionOptions::default()
    };
    let names = vec!["X".to_string(), "Y".to_string()];
    let run = |measured: Vec<Vec<f64>>| {
        let block = MotionBlock {
            commanded: sc.cmd.clone(),
            measured,
        };
        let d =
            crate::gap::diagnose_motion(&names, &[servo(), servo()], PERIOD, &block, None, &opts)
                .unwrap();
        format!("{d:?}")
    };
    assert_eq!(run(measured), run(spoiled));
}
