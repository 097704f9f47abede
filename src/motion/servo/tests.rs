//! Unit tests of `crate::motion::servo`.

use super::*;

/// Slow obvious reference: RK4 on the equations of openapi.yaml schema `Servo` in absolute
/// coordinates, `sub` steps per period, FOH command.
fn rk4_reference(axis: &ServoAxis, command: &[f64], period: f64, sub: usize) -> Vec<f64> {
    // state: x, v, a, z
    let deriv = |st: [f64; 4], r: f64, s: f64| -> [f64; 4] {
        let [x, v, a, z] = st;
        let v_ref = axis.kff * s + axis.kv * (r - x);
        match axis.kp_v {
            None => [v_ref, 0.0, 0.0, 0.0],
            Some(kp) => {
                let ev = v_ref - v;
                let a_cmd = kp * (ev + axis.ti_v.map_or(0.0, |ti| z / ti));
                let (acc, da) = match axis.tc {
                    Some(tc) => (a, (a_cmd - a) / tc),
                    None => (a_cmd, 0.0),
                };
                [v, acc, da, if axis.ti_v.is_some() { ev } else { 0.0 }]
            }
        }
    };
    crate::motion::rk4::rk4_first_order_hold(command, period, sub, deriv)
}

fn test_command(n: usize, period: f64) -> Vec<f64> {
    // A stop-and-go program with reversals: circle-like sine, hold, ramp back.
    (0..n)
        .map(|i| {
            let t = i as f64 * period;
            if t < 0.3 {
                100.0 + 10.0 * (1.0 - (2.0 * std::f64::consts::PI * 2.0 * t).cos())
            } else if t < 0.4 {
                100.0 + 10.0 * (1.0 - (2.0 * std::f64::consts::PI * 0.6).cos())
            } else {
                100.0 + 10.0 * (1.0 - (2.0 * std::f64::consts::PI * 0.6).cos()) - 50.0 * (t - 0.4)
            }
        })
        .collect()
}

fn cases() -> Vec<ServoAxis> {
    vec![
        ServoAxis::first_order(30.0, 0.0),
        ServoAxis::first_order(50.0, 0.7),
        ServoAxis {
            kv: 40.0,
            kff: 0.5,
            kp_v: Some(400.0),
            ti_v: None,
            tc: None,
        },
        ServoAxis {
            kv: 40.0,
            kff: 0.0,
            kp_v: Some(400.0),
            ti_v: Some(0.02),
            tc: None,
        },
        ServoAxis {
            kv: 40.0,
            kff: 0.8,
            kp_v: Some(400.0),
            ti_v: None,
            tc: Some(0.0005),
        },
        ServoAxis {
            kv: 35.0,
            kff: 0.9,
            kp_v: Some(500.0),
            ti_v: Some(0.015),
            tc: Some(0.0008),
        },
    ]
}

#[test]
fn agrees_with_fine_rk4_to_1e9_mm_for_every_structure() {
    let period = 0.001;
    let cmd = test_command(700, period);
    for axis in cases() {
        let exact = simulate_axis(&axis, &cmd, period).unwrap();
        let reference = rk4_reference(&axis, &cmd, period, 200);
        let worst = exact
            .iter()
            .zip(&reference)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-9, "{axis:?}: worst {worst:e} mm");
        // and the servo actually lags (the comparison is not between two copies of the command)
        let lag = exact
            .iter()
            .zip(&cmd)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(lag > 1e-3, "{axis:?}: lag {lag}");
    }
}

#[test]
fn first_order_matches_closed_form_ramp_then_hold() {
    // r rises linearly from 0 to 1 over the first period, then holds; kff = 0:
    // x(t) = s·(t − (1 − e^{−kv t})/kv) for t ≤ T, then 1 + (x(T) − 1)·e^{−kv (t − T)}.
    let (kv, t) = (25.0, 0.002);
    let mut cmd = vec![0.0, 1.0];
    cmd.extend(std::iter::repeat_n(1.0, 200));
    let x = simulate_axis(&ServoAxis::first_order(kv, 0.0), &cmd, t).unwrap();
    let s = 1.0 / t;
    let xt = s * (t - (1.0 - (-kv * t).exp()) / kv);
    assert!((x[1] - xt).abs() < 1e-12);
    for (i, xi) in x.iter().enumerate().skip(1) {
        let closed = 1.0 + (xt - 1.0) * (-kv * (i - 1) as f64 * t).exp();
        assert!((xi - closed).abs() < 1e-12, "i={i}: {xi} vs {closed}");
    }
}

#[test]
fn first_order_ramp_lag_is_rate_times_one_minus_kff_over_kv() {
    let (kv, kff, rate, t) = (30.0, 0.4, 50.0, 0.001);
    let cmd: Vec<f64> = (0..3000).map(|i| 10.0 + rate * i as f64 * t).collect();
    let x = simulate_axis(&ServoAxis::first_order(kv, kff), &cmd, t).unwrap();
    let lag = cmd[2999] - x[2999];
    let expected = rate * (1.0 - kff) / kv;
    assert!((lag - expected).abs() < 1e-9, "lag {lag} vs {expected}");
    // full cascade with integral action: the same steady ramp lag as the outer loop alone
    let full = ServoAxis {
        kv,
        kff,
        kp_v: Some(600.0),
        ti_v: Some(0.01),
        tc: Some(0.0005),
    };
    let x = simulate_axis(&full, &cmd, t).unwrap();
    let lag = cmd[2999] - x[2999];
    assert!(
        (lag - expected).abs() < 1e-6,
        "cascade lag {lag} vs {expected}"
    );
}

#[test]
fn feed_forward_one_with_ideal_inner_loops_tracks_exactly() {
    let cmd: Vec<f64> = (0..500).map(|i| 5.0 * (i as f64 * 0.01).sin()).collect();
    let x = simulate_axis(&ServoAxis::first_order(20.0, 1.0), &cmd, 0.001).unwrap();
    for (a, b) in x.iter().zip(&cmd) {
        assert!((a - b).abs() < 1e-12);
    }
}

#[test]
fn rests_exactly_at_the_first_command_sample() {
    for axis in cases() {
        let cmd = vec![123.456; 50];
        let x = simulate_axis(&axis, &cmd, 0.001).unwrap();
        assert!(x.iter().all(|&xi| xi == 123.456), "{axis:?}");
    }
    assert_eq!(
        simulate_axis(&cases()[5], &[7.0], 0.001).unwrap(),
        vec![7.0]
    );
}

#[test]
fn rejects_bad_parameters_and_inputs() {
    let ok = ServoAxis::first_order(30.0, 0.0);
    assert!(matches!(
        simulate_axis(&ok, &[], 0.001),
        Err(Error::EmptyCommand)
    ));
    assert!(matches!(
        simulate_axis(&ok, &[0.0, f64::NAN], 0.001),
        Err(Error::NonFiniteCommand { index: 1 })
    ));
    assert!(matches!(
        simulate_axis(&ok, &[0.0], 0.0),
        Err(Error::InvalidPeriod(_))
    ));
    for bad in [
        ServoAxis::first_order(-1.0, 0.0),
        ServoAxis::first_order(f64::INFINITY, 0.0),
        ServoAxis::first_order(30.0, 1.5),
        ServoAxis {
            kv: 30.0,
            kff: 0.0,
            kp_v: Some(0.0),
            ti_v: None,
            tc: None,
        },
        ServoAxis {
            kv: 30.0,
            kff: 0.0,
            kp_v: Some(300.0),
            ti_v: Some(f64::NAN),
            tc: None,
        },
    ] {
        assert!(
            matches!(bad.validate(), Err(Error::InvalidServo { .. })),
            "{bad:?}"
        );
    }
    // P velocity loop + current lag: stable iff tc·kv < 1 (Routh–Hurwitz of tc s³ + s² + kp s + kv kp).
    let unstable = ServoAxis {
        kv: 300.0,
        kff: 0.0,
        kp_v: Some(100.0),
        ti_v: None,
        tc: Some(0.01),
    };
    assert!(matches!(
        unstable.validate(),
        Err(Error::UnstableServo { .. })
    ));
    let stable = ServoAxis {
        kv: 90.0,
        kff: 0.0,
        kp_v: Some(100.0),
        ti_v: None,
        tc: Some(0.01),
    };
    assert!(stable.validate().is_ok());
}

#[test]
fn deserializes_contract_json_with_optional_fields() {
    let a: ServoAxis = serde_json::from_str(r#"{"kv": 30}"#).unwrap();
    assert_eq!(a, ServoAxis::first_order(30.0, 0.0));
    let b: ServoAxis = serde_json::from_str(
        r#"{"kv": 30, "kff": 0.5, "kp_v": 300, "ti_v": 0.02, "tc": 0.001, "mass": 3}"#,
    )
    .unwrap();
    assert_eq!(b.tc, Some(0.001));
}
