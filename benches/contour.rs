//! Contour-error prediction speed: simulated machine time per wall-clock second for a
//! 3-axis and a 5-axis (RTCP) program of more than 10 minutes of machining, one core.
//! Stages timed separately (parse + interpolate, servo, contour, JSON encoding of the HTTP
//! answer); the servo stage is compared against a naive RK4 integration of the same cascade
//! (10 sub-steps per period) measured in the same run. Times are CPU time of the bench thread
//! (wall clock printed beside it, as the machine may be shared).
//!
//! Run: `cargo bench --bench contour`

use std::time::Instant;

use serde_json::json;
use truecut::motion::{
    ContourPrediction, Machine, ServoAxis, contour_error, gcode, interpolate, simulate_machine,
};

fn machine(five: bool) -> Machine {
    let lin = json!({"kv": 30.0, "kff": 0.6, "kp_v": 400.0, "ti_v": 0.02, "tc": 0.0005});
    let rot = json!({"kv": 25.0, "kff": 0.6, "kp_v": 300.0, "ti_v": 0.02, "tc": 0.0008});
    let def = if five {
        json!({"kinematics": "xyzac_table",
            "geometry": {"a_axis_origin": [0.0, 0.0, -120.0], "c_axis_origin": [0.0, 0.0, -80.0], "tool_length": 110.0},
            "axes": {"X": lin, "Y": lin, "Z": lin, "A": rot, "C": rot}})
    } else {
        json!({"kinematics": "xyz", "axes": {"X": lin, "Y": lin, "Z": lin}})
    };
    Machine::from_json(&def).expect("bench machine")
}

/// Pocketing-like 3-axis program: per Z level concentric circles, zig-zag lines, corners.
fn program_3axis() -> String {
    let mut p = String::from("G90 G21 G17 G94\nG0 X0 Y0 Z5\n");
    for level in 0..4 {
        let z = -0.5 * (level + 1) as f64;
        p += &format!("G1 Z{z:.3} F300\n");
        for r in 1..=25 {
            let r = 2.0 * r as f64;
            p += &format!("G1 X{r:.3} Y0 F2500\nG3 X{r:.3} Y0 I{:.3} J0\n", -r);
        }
        for k in 0..40 {
            let y = -50.0 + 2.5 * k as f64;
            let x = if k % 2 == 0 { 50.0 } else { -50.0 };
            p += &format!("G1 X{x:.3} Y{y:.3}\nG1 Y{:.3}\n", y + 1.25);
        }
        p += "G0 Z5\nG0 X0 Y0\n";
    }
    p
}

/// CAM-like 5-axis RTCP program: short linear segments (0.5 mm) along a wavy curve with the
/// tool axis tilting and turning continuously (A ±30°, C sweeping).
fn program_5axis() -> String {
    let mut p = String::from("G90 G21 G94\nG0 X0 Y0 Z50\nG43.4 H1\nG1 X40 Y0 Z0 A0 C0 F1500\n");
    let n = 30000;
    for k in 1..=n {
        let s = k as f64 * 0.5;
        let th = s / 40.0;
        let x = 40.0 * th.cos() + 3.0 * (5.0 * th).sin();
        let y = 40.0 * th.sin();
        let z = -2.0 + 2.0 * (0.5 * th).sin();
        let a = 30.0 * (0.3 * th).sin();
        let c = th.to_degrees() * 0.5;
        p += &format!("X{x:.4} Y{y:.4} Z{z:.4} A{a:.4} C{c:.4}\n");
    }
    p += "G49\n";
    p
}

/// CPU time of this thread (s), from /proc/thread-self/schedstat (first field, ns); wall
/// time is also printed because the machine may be shared while benchmarking.
fn cpu_s() -> f64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| {
            s.split_whitespace()
                .next()
                .and_then(|v| v.parse::<f64>().ok())
        })
        .map_or(f64::NAN, |ns| ns * 1e-9)
}

/// Naive baseline: RK4 on the four-state cascade, `sub` sub-steps per period.
fn rk4_axis(servo: &ServoAxis, cmd: &[f64], period: f64, sub: usize) -> Vec<f64> {
    let (kv, kff) = (servo.kv, servo.kff);
    let (kp, ti, tc) = (servo.kp_v.unwrap(), servo.ti_v.unwrap(), servo.tc.unwrap());
    let mut out = Vec::with_capacity(cmd.len());
    let (mut x, mut v, mut a, mut z) = (cmd[0], 0.0, 0.0, 0.0);
    out.push(x);
    let h = period / sub as f64;
    for k in 1..cmd.len() {
        let slope = (cmd[k] - cmd[k - 1]) / period;
        for m in 0..sub {
            let t0 = m as f64 * h;
            let f = |t: f64, s: [f64; 4]| -> [f64; 4] {
                let r = cmd[k - 1] + slope * t;
                let ev = kff * slope + kv * (r - s[0]) - s[1];
                let acmd = kp * (ev + s[3] / ti);
                [s[1], s[2], (acmd - s[2]) / tc, ev]
            };
            let s0 = [x, v, a, z];
            let k1 = f(t0, s0);
            let s1: [f64; 4] = std::array::from_fn(|i| s0[i] + 0.5 * h * k1[i]);
            let k2 = f(t0 + 0.5 * h, s1);
            let s2: [f64; 4] = std::array::from_fn(|i| s0[i] + 0.5 * h * k2[i]);
            let k3 = f(t0 + 0.5 * h, s2);
            let s3: [f64; 4] = std::array::from_fn(|i| s0[i] + h * k3[i]);
            let k4 = f(t0 + h, s3);
            let n: [f64; 4] = std::array::from_fn(|i| {
                s0[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
            });
            (x, v, a, z) = (n[0], n[1], n[2], n[3]);
        }
        out.push(x);
    }
    out
}

/// (wall seconds, CPU seconds of this thread) spent in `f`, and its result.
fn timed<T>(f: impl FnOnce() -> T) -> (f64, f64, T) {
    let (w, c) = (Instant::now(), cpu_s());
    let out = f();
    (w.elapsed().as_secs_f64(), cpu_s() - c, out)
}

fn run(name: &str, five: bool, text: &str) {
    let m = machine(five);
    let period = 1e-3;
    let (w_int, c_int, (prog, traj)) = timed(|| {
        let prog = gcode::parse(text).expect("program parses");
        let traj = interpolate(&prog, &m, period, 10_000_000).expect("interpolates");
        (prog, traj)
    });
    let (w_servo, c_servo, actual) = timed(|| simulate_machine(&m, &traj).expect("servo"));
    let (w_con, c_con, rep) =
        timed(|| contour_error(&m.kinematics, &traj.axes, &actual, &traj.corners));
    let (wall, cpu) = (w_int + w_servo + w_con, c_int + c_servo + c_con);
    let machine_s = *traj.t.last().unwrap();
    let n = traj.t.len();
    // The HTTP answer, encoded exactly as the route does (streaming rows, no copies).
    let prediction = ContourPrediction {
        commanded: traj,
        actual,
        report: rep,
    };
    let (w_enc, c_enc, bytes) =
        timed(|| truecut::wire::contour::encode_answer(&m, &prediction).expect("encodes"));
    let ContourPrediction {
        commanded: traj,
        actual,
        report: rep,
    } = prediction;
    // Baseline: naive RK4 (10 sub-steps) on every axis, same commands.
    let (w_rk4, c_rk4, base) = timed(|| {
        m.axes
            .iter()
            .zip(&traj.axes)
            .map(|(ax, col)| rk4_axis(&ax.servo, col, period, 10))
            .collect::<Vec<_>>()
    });
    let worst_diff = base
        .iter()
        .zip(&actual)
        .flat_map(|(b, a)| b.iter().zip(a).map(|(x, y)| (x - y).abs()))
        .fold(0.0f64, f64::max);
    println!(
        "{name}: {n} periods = {machine_s:.1} s of machining ({} blocks)",
        prog.blocks.len()
    );
    println!(
        "  CPU s: parse+interpolate {c_int:.3}, servo {c_servo:.3}, contour {c_con:.3}, total {cpu:.3} (wall {wall:.3})"
    );
    println!(
        "  speed: {:.0}x real time by CPU time, {:.0}x by wall clock (simulation, one core)",
        machine_s / cpu,
        machine_s / wall
    );
    println!(
        "  servo exact vs naive RK4 with 10 sub-steps: CPU {c_servo:.3} s vs {c_rk4:.3} s = {:.1}x faster (wall {:.1}x), max |diff| {worst_diff:.2e} mm",
        c_rk4 / c_servo,
        w_rk4 / w_servo
    );
    println!(
        "  JSON answer: {:.1} MB encoded in {c_enc:.3} s CPU ({w_enc:.3} s wall, {:.0} MB/s) = {:.2}x the simulation CPU time",
        bytes.len() as f64 / 1e6,
        bytes.len() as f64 / 1e6 / c_enc,
        c_enc / cpu
    );
    println!(
        "  contour error: max {:.4} mm, rms {:.4} mm{}",
        rep.max,
        rep.rms,
        rep.orientation_max_deg
            .map(|o| format!(", orientation max {o:.4} deg"))
            .unwrap_or_default()
    );
}

fn main() {
    run("3-axis pocket", false, &program_3axis());
    run("5-axis RTCP", true, &program_5axis());
}
