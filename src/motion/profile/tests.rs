//! Unit tests of `crate::motion::profile`.

use super::*;

/// Numerical derivatives of the planned s(t) respect the caps and hit the length.
#[test]
fn planned_block_respects_caps_and_length() {
    let cases = [
        (100.0, 0.0, 0.0, 50.0, 2000.0, 50000.0),
        (0.5, 0.0, 0.0, 50.0, 2000.0, 50000.0),
        (10.0, 20.0, 5.0, 80.0, 1000.0, 20000.0),
        (3.0, 30.0, 30.0, 30.0, 1000.0, 20000.0),
    ];
    for (len, v0, v1, vcap, a, j) in cases {
        let mut out = Vec::new();
        let t_end = plan_block(
            &mut out,
            0,
            0.0,
            BlockLimits {
                len,
                v0,
                v1,
                vcap,
                a,
                j,
            },
        );
        let last = out.last().unwrap();
        let s_end = last.s_at(t_end);
        assert!(
            (s_end - len).abs() < 1e-9 * len.max(1.0),
            "len {len}: got {s_end}"
        );
        // Sample finely and check v, a, j by finite differences.
        let n = 20000;
        let h = t_end / n as f64;
        let s = |t: f64| {
            let p = out.iter().rev().find(|p| p.t0 <= t).unwrap_or(&out[0]);
            p.s_at(t)
        };
        let mut vmax: f64 = 0.0;
        let mut amax: f64 = 0.0;
        for k in 1..n {
            let t = k as f64 * h;
            let v = (s(t + h) - s(t - h)) / (2.0 * h);
            let acc = (s(t + h) - 2.0 * s(t) + s(t - h)) / (h * h);
            vmax = vmax.max(v);
            amax = amax.max(acc.abs());
            assert!(v > -1e-6, "negative speed {v}");
        }
        assert!(vmax <= vcap * (1.0 + 1e-6), "v {vmax} > {vcap}");
        assert!(amax <= a * 1.01, "a {amax} > {a}");
        let v_start = (s(h) - s(0.0)) / h;
        assert!((v_start - v0).abs() < a * h * 2.0 + 1e-9);
    }
}

#[test]
fn reach_inverts_ramp_distance() {
    for &(v0, d) in &[(0.0, 1.0), (10.0, 0.01), (5.0, 300.0)] {
        let v1 = max_reachable_speed(v0, d, 3000.0, 60000.0);
        let back = ramp_distance(v0, v1, 3000.0, 60000.0);
        assert!((back - d).abs() < 1e-9 * d.max(1.0), "{v0} {d}: {back}");
    }
}
