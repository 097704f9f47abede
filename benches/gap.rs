//! Gap diagnosis speed (with steps, where and unexplained): one diagnosis of ≥ 10,000 samples (2 axes, cascade servo, friction
//! truth), multi-threaded vs the single-threaded run of the same code, and the exact
//! discretization vs a naive RK4 re-simulation (16 sub-steps per period) of the same block.
use std::time::Instant;

use rand::SeedableRng;
use truecut::gap::programs::{Program, generate};
use truecut::gap::truth::{Truth, measure};
use truecut::gap::{MotionBlock, MotionOptions, diagnose_motion};
use truecut::motion::{ServoAxis, simulate_axis};

fn best_of(reps: usize, mut f: impl FnMut()) -> f64 {
    (0..reps)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    let period = 0.001;
    let servo = vec![
        ServoAxis {
            kv: 35.0,
            kff: 0.6,
            kp_v: Some(450.0),
            ti_v: Some(0.012),
            tc: Some(0.0006),
        },
        ServoAxis {
            kv: 40.0,
            kff: 0.6,
            kp_v: Some(500.0),
            ti_v: Some(0.012),
            tc: Some(0.0006),
        },
    ];
    let mut cmd = generate(Program::Circle, 2, period, false, &mut rng);
    while cmd[0].len() < 10_000 {
        let more = generate(Program::ZigZag, 2, period, false, &mut rng);
        for k in 0..2 {
            let off = cmd[k].last().copied().unwrap() - more[k][0];
            cmd[k].extend(more[k].iter().map(|v| v + off));
        }
    }
    for c in cmd.iter_mut() {
        c.truncate(10_000);
    }
    let truth = Truth::Friction(vec![450.0 * 35.0 * 0.003, 500.0 * 40.0 * 0.003]);
    let meas = measure(&servo, &truth, &cmd, period, 0.0003, &mut rng);
    let names = vec!["X".to_string(), "Y".to_string()];
    let block = MotionBlock {
        commanded: cmd.clone(),
        measured: meas,
    };
    let run = |threads: usize| {
        let opts = MotionOptions {
            threads,
            ..MotionOptions::default()
        };
        diagnose_motion(&names, &servo, period, &block, None, &opts).unwrap()
    };
    let d = run(2);
    println!(
        "verdict on the bench block: {} (gap {:.2} -> {:.2} um)",
        d.verdict.name(),
        d.gap_before.rms * 1e3,
        d.gap_after.rms * 1e3
    );
    let t2 = best_of(3, || {
        run(2);
    });
    let t1 = best_of(3, || {
        run(1);
    });
    println!(
        "diagnosis of 10,000 samples x 2 axes: 2 threads {t2:.3} s, 1 thread {t1:.3} s, speed-up x{:.2} (goal < 2 s)",
        t1 / t2
    );
    // the route's sync limit: 100,000 samples x 3 axes, one run each (2 threads as the route
    // uses for large blocks, then 1 thread)
    let servo3 = vec![servo[0].clone(), servo[1].clone(), servo[1].clone()];
    let mut big = generate(Program::ZigZag, 3, period, false, &mut rng);
    while big[0].len() < 100_000 {
        let more = generate(Program::Circle, 3, period, true, &mut rng);
        for k in 0..3 {
            let off = big[k].last().copied().unwrap() - more[k][0];
            big[k].extend(more[k].iter().map(|v| v + off));
        }
    }
    for c in big.iter_mut() {
        c.truncate(100_000);
    }
    let big_meas = measure(
        &servo3,
        &Truth::Backlash(vec![0.01, 0.008, 0.006], true),
        &big,
        period,
        0.0003,
        &mut rng,
    );
    let names3 = vec!["X".to_string(), "Y".to_string(), "Z".to_string()];
    let big_block = MotionBlock {
        commanded: big,
        measured: big_meas,
    };
    let run_big = |threads: usize| {
        let opts = MotionOptions {
            threads,
            ..MotionOptions::default()
        };
        let t = Instant::now();
        let d = diagnose_motion(&names3, &servo3, period, &big_block, None, &opts).unwrap();
        (t.elapsed().as_secs_f64(), d.verdict.name())
    };
    let (b2, v2) = run_big(2);
    let (b1, _) = run_big(1);
    println!(
        "diagnosis of 100,000 samples x 3 axes (verdict {v2}): 2 threads {b2:.2} s, 1 thread {b1:.2} s, speed-up x{:.2}",
        b1 / b2
    );
    let exact = best_of(5, || {
        for (s, c) in servo.iter().zip(&cmd) {
            std::hint::black_box(simulate_axis(s, c, period).unwrap());
        }
    });
    let rk4 = best_of(2, || {
        std::hint::black_box(measure(
            &servo,
            &Truth::None,
            &cmd,
            period,
            0.0,
            &mut rand::rngs::StdRng::seed_from_u64(1),
        ));
    });
    println!(
        "one re-simulation of the block: exact discretization {:.3} ms, naive RK4 (16 sub-steps) {:.3} ms, ratio x{:.0}",
        exact * 1e3,
        rk4 * 1e3,
        rk4 / exact
    );
    println!(
        "diagnosis (steps, where, unexplained) of the 10,000-sample block = x{:.0} one plain simulation of it",
        t2 / exact
    );
}
