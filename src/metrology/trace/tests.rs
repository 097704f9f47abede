//! The logged-run reader against logs it did not make: the hand table of `iso230_2/tests.rs`
//! run through a lagging servo, and three kinds of drive log from `simlog.rs` (interpolated
//! set-point; the stepped target with a slow axis; a measuring device with its own offset and
//! clock), each checked against the standard's figures of the generator's true dwell readings
//! (issue 23 item 5: goal within 1 µm of E, R, B, M and A).

use super::simlog::{Command, Device, Drive, RunSpec, SimLog, simulate};
use super::*;
use crate::metrology::iso230_2::tests::hand_table;
use crate::metrology::{Error, evaluate_table};

const PERIOD_S: f64 = 0.01;
const SPEED_MM_S: f64 = 50.0;
const KV: f64 = 20.0;

/// Builds the run: start dwell at −5 mm; per cycle the targets up (each a 1 s dwell), an
/// overtravel to +5 mm beyond the last with a 0.3 s pause, the targets down, an overtravel
/// to −5 mm without a pause. The reading is a first-order lag (kv = 20 1/s) of the command
/// plus the table's deviation of the visit being approached, plus `noise_mm` uniform noise.
fn run(noise_mm: f64) -> PositioningTrace {
    let table = hand_table();
    let m = table.targets_mm.len();
    let mut c = vec![-5.0; 100];
    let mut offsets = vec![0.0; 100];
    let go = |c: &mut Vec<f64>, offsets: &mut Vec<f64>, to: f64, dwell_s: f64, dev: f64| {
        let from = *c.last().unwrap();
        let steps = ((to - from).abs() / (SPEED_MM_S * PERIOD_S)).ceil() as usize;
        for k in 1..=steps {
            c.push(from + (to - from) * k as f64 / steps as f64);
            offsets.push(dev);
        }
        for _ in 0..(dwell_s / PERIOD_S).round() as usize {
            c.push(to);
            offsets.push(dev);
        }
    };
    let last = table.targets_mm[m - 1];
    for j in 0..5 {
        for i in 0..m {
            let p = table.targets_mm[i];
            go(&mut c, &mut offsets, p, 1.0, table.forward_mm[i][j] - p);
        }
        go(&mut c, &mut offsets, last + 5.0, 0.3, 0.0);
        for i in (0..m).rev() {
            let p = table.targets_mm[i];
            go(&mut c, &mut offsets, p, 1.0, table.backward_mm[i][j] - p);
        }
        if j < 4 {
            go(&mut c, &mut offsets, -5.0, 0.0, 0.0);
        }
    }
    let alpha = 1.0 - (-KV * PERIOD_S).exp();
    let mut x = c[0];
    let mut seed = 12345_u64;
    let measured = c
        .iter()
        .zip(&offsets)
        .map(|(&ck, &off)| {
            x += alpha * (ck - x);
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let u = (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            x + off + 2.0 * noise_mm * u
        })
        .collect();
    PositioningTrace {
        period_s: PERIOD_S,
        commanded_mm: c,
        measured_mm: measured,
    }
}

#[test]
fn logged_run_gives_back_the_hand_table() {
    let ev = evaluate_trace(&run(0.0), &TraceOptions::default()).unwrap();
    let want = evaluate_table(&hand_table()).unwrap();
    assert_eq!(ev.table.targets_mm, hand_table().targets_mm);
    for (got, want) in [
        (ev.axis.a, want.a),
        (ev.axis.e, want.e),
        (ev.axis.m, want.m),
        (ev.axis.r, want.r),
        (ev.axis.b, want.b),
        (ev.axis.b_avg, want.b_avg),
    ] {
        // The first settled sample sees the lag's rest decayed to ~0.2 µm, and it decays by
        // e every 50 ms after: a reading is biased by ~0.03 µm, a figure by less than 0.1 µm.
        assert!((got - want).abs() < 1e-4, "got {got}, want {want}");
    }
    // The hand figures: R = 10 µm, E = 8 µm, A = 12 µm.
    assert!((ev.axis.r - 0.010).abs() < 1e-4 && (ev.axis.e - 0.008).abs() < 1e-4);
    assert_eq!(ev.used.len(), 50);
    // Ignored: the start stop. The 0.3 s pause at the turnaround is too short for the lagging
    // axis to stand still for 0.3 s, so it is no stop at all.
    assert_eq!(ev.ignored.len(), 1, "{:?}", ev.ignored);
    assert!(ev.ignored[0].2.contains("start position"));
    // The settling (the lag of 2.5 mm decays at kv = 20 1/s; the window is 0.3 s) is left
    // out of every reading, and so is the departure.
    for r in &ev.used {
        assert!(r.settled[0] - r.command[0] >= 40, "{r:?}");
        assert!(r.settled[1] < r.command[1], "{r:?}");
    }
    // Directions: the first reading at 400 mm is the upward approach, the second (after the
    // overtravel to 405 mm and back) the downward one.
    let at400: Vec<&TraceReading> = ev.used.iter().filter(|r| r.target_mm == 400.0).collect();
    assert!(at400[0].forward && !at400[1].forward && at400[0].cycle == 0);
    assert_eq!(ev.settling.settle_speed_mm_s, 0.01);
    assert!(ev.settling.measured_offset_mm.abs() < 0.005);
}

#[test]
fn noisy_run_reads_within_the_noise() {
    // ±0.5 µm uniform noise: each reading averages ~40 samples (σ ≈ 0.05 µm).
    let ev = evaluate_trace(&run(0.0005), &TraceOptions::default()).unwrap();
    assert_eq!(ev.used.len(), 50);
    assert!((ev.axis.e - 0.008).abs() < 3e-4, "E = {}", ev.axis.e);
    assert!((ev.axis.b - 0.004).abs() < 3e-4, "B = {}", ev.axis.b);
}

#[test]
fn bad_runs_are_refused() {
    let mut t = run(0.0);
    t.measured_mm.pop();
    assert!(matches!(
        evaluate_trace(&t, &TraceOptions::default()),
        Err(Error::LengthMismatch { .. })
    ));
    let mut t = run(0.0);
    t.period_s = 0.0;
    assert!(matches!(
        evaluate_trace(&t, &TraceOptions::default()),
        Err(Error::Invalid {
            field: "period_s",
            ..
        })
    ));
    let opts = TraceOptions {
        settle_speed_mm_s: -1.0,
        ..TraceOptions::default()
    };
    assert!(matches!(
        evaluate_trace(&run(0.0), &opts),
        Err(Error::Invalid {
            field: "settle_speed_mm_s",
            ..
        })
    ));
    // A ramp with no dwell has no targets.
    let t = PositioningTrace {
        period_s: 0.01,
        commanded_mm: (0..500).map(f64::from).collect(),
        measured_mm: (0..500).map(f64::from).collect(),
    };
    assert!(matches!(
        evaluate_trace(&t, &TraceOptions::default()),
        Err(Error::TooFew { .. })
    ));
}

/// Nine targets about 50 mm apart, unevenly (ISO 230-2:2014 §5.2), five cycles, 3 mm overrun;
/// backlash 4 µm, stop scatter σ 0.5 µm, pitch error of a few µm, noise σ 0.3 µm.
fn spec(command: Command, drive_kv: f64, v_max_mm_s: f64, device: Device, seed: u64) -> RunSpec {
    let jitter = [0.0, 3.1, -2.4, 4.2, -1.3, 2.7, -3.8, 1.9, 0.0];
    RunSpec {
        targets_mm: (0..9).map(|i| 50.0 * i as f64 + jitter[i]).collect(),
        cycles: 5,
        overrun_mm: 3.0,
        dwell_s: [1.0, 2.0],
        period_s: PERIOD_S,
        command,
        drive: Drive {
            kv_per_s: drive_kv,
            v_max_mm_s,
            backlash_mm: 0.004,
            scatter_mm: 0.0005,
            pitch_mm: 0.003,
        },
        device,
        seed,
        cut_dwell: None,
    }
}

const LASER: Device = Device {
    offset_mm: 0.0,
    clock: 1.0,
    noise_mm: 0.0003,
};

/// |Δ| of E, R, B, M, A in µm between the trace reading and the true dwell readings, after
/// checking that every approach gave one reading.
fn deltas_um(kind: &str, log: &SimLog) -> (TraceEvaluation, [f64; 5]) {
    let ev = evaluate_trace(&log.trace, &TraceOptions::default()).unwrap();
    let want = evaluate_table(&log.truth).unwrap();
    assert_eq!(ev.table.targets_mm, log.truth.targets_mm);
    assert_eq!(ev.used.len(), 90, "{:?}", ev.ignored);
    let d = |a: f64, b: f64| (a - b).abs() * 1e3;
    let deltas = [
        d(ev.axis.e, want.e),
        d(ev.axis.r, want.r),
        d(ev.axis.b, want.b),
        d(ev.axis.m, want.m),
        d(ev.axis.a, want.a),
    ];
    eprintln!(
        "{kind}: truth E {:.2} R {:.2} B {:.2} M {:.2} A {:.2} µm; |ΔE| {:.3} |ΔR| {:.3} |ΔB| {:.3} \
         |ΔM| {:.3} |ΔA| {:.3} µm (goal: each under 1 µm)",
        want.e * 1e3,
        want.r * 1e3,
        want.b * 1e3,
        want.m * 1e3,
        want.a * 1e3,
        deltas[0],
        deltas[1],
        deltas[2],
        deltas[3],
        deltas[4]
    );
    // The figures are not trivial: the pitch error, the backlash and the scatter show.
    assert!(
        want.e > 0.005 && want.b > 0.002 && want.r > 0.004,
        "{want:?}"
    );
    (ev, deltas)
}

fn assert_within_1um(deltas: [f64; 5]) {
    for (name, d) in ["E", "R", "B", "M", "A"].iter().zip(deltas) {
        assert!(d < 1.0, "|Δ{name}| = {d:.3} µm, goal under 1 µm");
    }
}

#[test]
fn interpolated_setpoint_log_reads_the_true_dwells() {
    // (a) The command is the interpolated set-point (20 mm/s, the axis lags 0.8 mm).
    for seed in [101, 102] {
        let log = simulate(&spec(
            Command::Interpolated { feed_mm_s: 20.0 },
            25.0,
            100.0,
            LASER,
            seed,
        ));
        assert_within_1um(deltas_um(&format!("(a) seed {seed}"), &log).1);
    }
}

#[test]
fn stepped_target_slow_axis_log_reads_the_true_dwells() {
    // (b) The command is the target itself, written when the move starts; the axis travels at
    // 2 mm/s (about 25 s between targets) and dwells 1-2 s before the next step.
    for seed in [201, 202] {
        let log = simulate(&spec(Command::Stepped, 8.0, 2.0, LASER, seed));
        let (ev, deltas) = deltas_um(&format!("(b) seed {seed}"), &log);
        assert_within_1um(deltas);
        // The log has the shape of the issue's: the command equals the target tens of seconds
        // before the axis has settled there.
        let lead_s: Vec<f64> = ev
            .used
            .iter()
            .map(|r| (r.settled[0] - r.command[0]) as f64 * PERIOD_S)
            .collect();
        // (All but the approaches from the overrun points, 3 mm away.)
        let far = lead_s.iter().filter(|&&s| s > 20.0).count();
        assert!(far >= 80, "{lead_s:?}");
        // A reader that averaged the command's hold would read the travel: its mean is
        // millimetres from the target (the issue's ±1.4 mm).
        let r = &ev.used[20];
        let hold = &log.trace.measured_mm[r.command[0]..r.command[1]];
        let hold_mean = hold.iter().sum::<f64>() / hold.len() as f64;
        assert!((hold_mean - r.target_mm).abs() > 1.0);
    }
}

#[test]
fn device_offset_and_clock_change_no_figure() {
    // (c) The stepped slow-axis log read by a device zeroed elsewhere (its offset) whose
    // sample clock is 3 % off the command's: by the end of the 40-minute run the two series'
    // sample indices disagree by more than a minute, several targets.
    for (seed, offset_mm, clock) in [(301, -37.215, 1.03), (302, 0.0123, 0.97)] {
        let device = Device {
            offset_mm,
            clock,
            ..LASER
        };
        let log = simulate(&spec(Command::Stepped, 8.0, 2.0, device, seed));
        let (ev, deltas) = deltas_um(&format!("(c) seed {seed}, clock {clock}"), &log);
        assert_within_1um(deltas);
        // The offset is found (to the axis' mean deviation of a few µm) and kept in the
        // readings: every mean deviation carries it.
        assert!((ev.settling.measured_offset_mm - offset_mm).abs() < 0.02);
        let last = ev.used.last().unwrap();
        let drift_s = (last.settled[0] as f64 - last.command[0] as f64).abs() * PERIOD_S;
        assert!(drift_s > 30.0, "{drift_s}");
    }
}

#[test]
fn an_approach_that_never_settles_is_refused_naming_target_and_direction() {
    // The third backward approach of the fourth target dwells 0.1 s: the axis leaves before it
    // has stood still for the 0.3 s a reading needs.
    let mut s = spec(Command::Stepped, 8.0, 2.0, LASER, 401);
    s.cut_dwell = Some((3, false, 2));
    let log = simulate(&s);
    let err = evaluate_trace(&log.trace, &TraceOptions::default()).unwrap_err();
    assert!(
        matches!(
            err,
            Error::MissingReadings {
                direction: "backward",
                got: 4,
                expected: 5,
                ..
            }
        ),
        "{err:?}"
    );
    let target = log.truth.targets_mm[3];
    let text = err.to_string();
    assert!(
        text.starts_with(&format!(
            "target {target} mm, backward: 4 settled readings, 5 cycles expected"
        )),
        "{text}"
    );
    // The same log with every dwell whole reads all 90.
    s.cut_dwell = None;
    let ev = evaluate_trace(&simulate(&s).trace, &TraceOptions::default()).unwrap();
    assert_eq!(ev.used.len(), 90);
}

#[test]
fn a_slowly_settling_first_order_axis_reads_the_settled_end_of_each_dwell() {
    // Issue 39 item 5: a first-order approach with a 1 s time constant (kv = 1 1/s, no speed
    // limit) and 15 s dwells. The speed falls below the 10 µm/s threshold while the axis is
    // still 10 µm short of the target (rest = speed·τ); a reading averaged from there on
    // was 2 µm off in E, R, B and A. Both logs: the interpolated set-point (5 mm/s; the axis
    // lags 5 mm when the command arrives, and follows the overrun's reversal by 0.5 mm) and
    // the stepped target (the dwell counted from the in-position window).
    for (kind, command) in [
        ("interpolated", Command::Interpolated { feed_mm_s: 5.0 }),
        ("stepped", Command::Stepped),
    ] {
        for seed in [501, 502] {
            let mut s = spec(command, 1.0, 1000.0, LASER, seed);
            s.dwell_s = [15.0, 15.0 + 1e-9];
            let log = simulate(&s);
            let (_, deltas) = deltas_um(
                &format!("first order, tau 1 s, 15 s dwells, {kind} seed {seed}"),
                &log,
            );
            assert_within_1um(deltas);
        }
    }
}

#[test]
fn the_settled_end_reads_the_last_window_across_the_stretches_of_one_stop() {
    // A stop that noise split in two: settled samples 0..10 (creeping in: 10, 9, ... µm) and
    // 15..18 (at the target). A five-sample reading takes 15, 16, 17, then 8 and 9.
    let y: Vec<f64> = (0..20)
        .map(|k| if k < 10 { 0.001 * (10 - k) as f64 } else { 0.0 })
        .collect();
    let run = SettledRun {
        start: 0,
        end: 18,
        mean_mm: 0.0,
        count: 13,
        stretches: vec![[0, 10], [15, 18]],
    };
    let (first, reading) = run.settled_end(&y, 5);
    assert_eq!(first, 8);
    assert!((reading - 0.003 / 5.0).abs() < 1e-15, "{reading}");
    // A stop shorter than the window reads all of it.
    let (first, reading) = run.settled_end(&y, 100);
    assert_eq!(first, 0);
    assert!((reading - 0.055 / 13.0).abs() < 1e-15, "{reading}");
}
