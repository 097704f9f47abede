//! Unit tests of `crate::motion::physical`.

use super::*;

fn ball_screw() -> PhysicalAxis {
    PhysicalAxis {
        motor_inertia_kg_m2: 1.2e-3,
        velocity_gain_nm_s_per_rad: Some(0.6),
        current_bandwidth_hz: Some(800.0),
        lead_mm: Some(10.0),
        table_mass_kg: Some(300.0),
        axial_stiffness_n_per_um: Some(200.0),
        screw_torsional_stiffness_nm_per_rad: Some(8000.0),
        table_damping_n_s_per_m: Some(4000.0),
        ..Default::default()
    }
}

#[test]
fn mapping_matches_hand_calculation() {
    let p = ball_screw();
    // J_eq = 1.2e-3 + 300·(0.01/2π)² = 1.2e-3 + 7.599e-4
    let r: f64 = 0.01 / std::f64::consts::TAU;
    let jeq = 1.2e-3 + 300.0 * r * r;
    assert!((p.equivalent_inertia(false).unwrap() - jeq).abs() < 1e-15);
    assert!((p.kp_v(false).unwrap().unwrap() - 0.6 / jeq).abs() < 1e-9);
    assert!((p.tc().unwrap().unwrap() - 1.0 / (std::f64::consts::TAU * 800.0)).abs() < 1e-15);
    // eq. 9: 1/K = 1/2e8 + 1e-4/(4π²·8000)
    let k = 1.0 / (1.0 / 2e8 + 1e-4 / (4.0 * std::f64::consts::PI.powi(2) * 8000.0));
    assert!((p.equivalent_stiffness(false).unwrap().unwrap() - k).abs() < 1e-6 * k);
    let mode = p.structural_mode(false).unwrap().unwrap();
    assert!((mode.omega_n - (k / 300.0).sqrt()).abs() < 1e-9);
    assert!((mode.zeta - 4000.0 / (2.0 * (k * 300.0).sqrt())).abs() < 1e-12);
}

#[test]
fn missing_lead_is_a_named_error() {
    let mut p = ball_screw();
    p.lead_mm = None;
    let e = p.kp_v(false).unwrap_err();
    assert!(e.to_string().contains("lead_mm"), "{e}");
}

/// Ramp response of ωn²/(s²+2ζωn s+ωn²) in closed form:
/// y(t) = v[t − 2ζ/ωn + e^{−ζωn t}/ωn (2ζ cos ωd t + (2ζ²−1)/√(1−ζ²) sin ωd t)].
#[test]
fn ramp_response_matches_closed_form() {
    let mode = StructuralMode {
        omega_n: 2.0 * std::f64::consts::PI * 60.0,
        zeta: 0.08,
    };
    let (wn, z) = (mode.omega_n, mode.zeta);
    let wd = wn * (1.0 - z * z).sqrt();
    let v = 50.0; // mm/s
    let h = 1e-3;
    let xm: Vec<f64> = (0..500).map(|k| v * k as f64 * h).collect();
    let y = mode.filter(&xm, h);
    for (k, yk) in y.iter().enumerate() {
        let t = k as f64 * h;
        let exact = v
            * (t - 2.0 * z / wn
                + (-z * wn * t).exp() / wn
                    * (2.0 * z * (wd * t).cos()
                        + (2.0 * z * z - 1.0) / (1.0 - z * z).sqrt() * (wd * t).sin()));
        assert!((yk - exact).abs() < 1e-9, "t={t}: {yk} vs {exact}");
    }
    // Steady ramp lag = B/K·v = 2ζ/ωn·v.
    let lag = xm[499] - y[499];
    assert!((lag - 2.0 * z / wn * v).abs() < 1e-6);
}
