//! Zhang & Chen 2025's physical feed-drive parameters mapped onto the normalized servo cascade
//! (openapi.yaml schema `Servo`).
//!
//! Seed 003 §3.2 models a ball-screw axis as motor inertia `Jm`, lead `l`, table mass `Mt`,
//! nut/table stiffness `Kj`, screw torsional stiffness `Ks`, table damping `Bt` (eq. 8) with
//! the equivalent stiffness `K = 1/(1/Kj + l²/(4π²Ks))` (eq. 9) and the structural transfer
//! `G(s) = x/x_m = K/(Mt s² + Bt s + K)` (eq. 10). The mapping onto the cascade:
//! - rigid body: the velocity loop's torque gain `Kvp` (N·m·s/rad at the motor) acts on the
//!   reflected inertia `J_eq = Jm + Mt (l/2π)²`, so `kp_v = Kvp / J_eq` (1/s), independent of
//!   the lead (the lead scales the velocity error and the acceleration alike);
//! - current loop: `tc = 1/(2π f_c)` from its bandwidth `f_c`;
//! - compliance: the cascade drives the motor-side position `x_m` (semi-closed loop, encoder
//!   feedback) and the table follows through `G(s)`, simulated exactly ([`StructuralMode`]).
//!   This neglects the table's reaction on the motor, valid while the structural mode
//!   `ωn = √(K/Mt)` lies well above the velocity-loop bandwidth.
//!
//! Rotary axes likewise with a gear ratio `N` instead of the lead: `J_eq = Jm + Jt/N²`,
//! `G(s) = Kt/(Jt s² + Bt s + Kt)` with the drive train's torsional stiffness `Kt` at the table.

use nalgebra::Matrix4;
use serde::{Deserialize, Serialize};

use super::error::Error;

/// Physical drive parameters of one axis (the optional `"physical"` object of a machine axis).
/// Linear axes use `lead_mm`, `table_mass_kg`, `axial_stiffness_n_per_um`,
/// `screw_torsional_stiffness_nm_per_rad`, `table_damping_n_s_per_m`; rotary axes use
/// `gear_ratio`, `table_inertia_kg_m2`, `torsional_stiffness_nm_per_rad`,
/// `table_damping_nm_s_per_rad`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PhysicalAxis {
    /// Motor-side inertia `Jm`, kg·m² (motor, coupling, screw).
    pub motor_inertia_kg_m2: f64,
    /// Velocity-loop proportional torque gain `Kvp`, N·m·s/rad at the motor (gives `kp_v`).
    pub velocity_gain_nm_s_per_rad: Option<f64>,
    /// Current-loop bandwidth `f_c`, Hz (gives `tc`).
    pub current_bandwidth_hz: Option<f64>,
    /// Ball-screw lead `l`, mm per motor revolution (linear axes).
    pub lead_mm: Option<f64>,
    /// Table (and workpiece) mass `Mt`, kg (linear axes).
    pub table_mass_kg: Option<f64>,
    /// Nut–table translational stiffness `Kj`, N/µm (linear axes).
    pub axial_stiffness_n_per_um: Option<f64>,
    /// Screw torsional stiffness `Ks`, N·m/rad (linear axes).
    pub screw_torsional_stiffness_nm_per_rad: Option<f64>,
    /// Guideway viscous damping `Bt`, N·s/m (linear axes).
    pub table_damping_n_s_per_m: Option<f64>,
    /// Motor revolutions per table revolution `N` (rotary axes).
    pub gear_ratio: Option<f64>,
    /// Table inertia `Jt`, kg·m² (rotary axes).
    pub table_inertia_kg_m2: Option<f64>,
    /// Drive-train torsional stiffness at the table `Kt`, N·m/rad (rotary axes).
    pub torsional_stiffness_nm_per_rad: Option<f64>,
    /// Table viscous damping `Bt`, N·m·s/rad (rotary axes).
    pub table_damping_nm_s_per_rad: Option<f64>,
}

/// A lightly damped second-order structural mode `ωn²/(s² + 2ζωn s + ωn²)` between motor-side
/// and table position. Reference: Zhang & Chen 2025 eq. 10 with `ωn = √(K/M)`, `ζ = B/(2√(KM))`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StructuralMode {
    /// Natural frequency, rad/s.
    pub omega_n: f64,
    /// Damping ratio (dimensionless, ≥ 0).
    pub zeta: f64,
}

fn check_pos(field: &str, v: Option<f64>) -> Result<Option<f64>, Error> {
    match v {
        Some(x) if !(x.is_finite() && x > 0.0) => Err(Error::parameter(
            format!("physical.{field}"),
            format!("must be a positive finite number, got {x}"),
        )),
        other => Ok(other),
    }
}

impl PhysicalAxis {
    fn require(&self, field: &str, v: Option<f64>) -> Result<f64, Error> {
        check_pos(field, v)?.ok_or_else(|| {
            Error::parameter(
                format!("physical.{field}"),
                "is required for this axis kind",
            )
        })
    }

    /// Equivalent inertia at the motor `J_eq`, kg·m²: `Jm + Mt (l/2π)²` (linear, l in m) or
    /// `Jm + Jt/N²` (rotary). Reference: Zhang & Chen 2025 eq. 8 (rigid transmission).
    pub fn equivalent_inertia(&self, rotary: bool) -> Result<f64, Error> {
        check_pos("motor_inertia_kg_m2", Some(self.motor_inertia_kg_m2))?;
        if rotary {
            let n = self.require("gear_ratio", self.gear_ratio)?;
            let jt = self.require("table_inertia_kg_m2", self.table_inertia_kg_m2)?;
            Ok(self.motor_inertia_kg_m2 + jt / (n * n))
        } else {
            let l = self.require("lead_mm", self.lead_mm)? * 1e-3;
            let m = self.require("table_mass_kg", self.table_mass_kg)?;
            let r = l / std::f64::consts::TAU;
            Ok(self.motor_inertia_kg_m2 + m * r * r)
        }
    }

    /// Normalized velocity-loop gain `kp_v = Kvp / J_eq`, 1/s, if `Kvp` is given.
    pub fn kp_v(&self, rotary: bool) -> Result<Option<f64>, Error> {
        match check_pos(
            "velocity_gain_nm_s_per_rad",
            self.velocity_gain_nm_s_per_rad,
        )? {
            Some(k) => Ok(Some(k / self.equivalent_inertia(rotary)?)),
            None => Ok(None),
        }
    }

    /// Current-loop time constant `tc = 1/(2π f_c)`, s, if `f_c` is given.
    pub fn tc(&self) -> Result<Option<f64>, Error> {
        Ok(
            check_pos("current_bandwidth_hz", self.current_bandwidth_hz)?
                .map(|f| 1.0 / (std::f64::consts::TAU * f)),
        )
    }

    /// Equivalent stiffness `K`, N/m (linear) or N·m/rad (rotary), if any stiffness is given.
    /// Linear: `K = 1/(1/Kj + l²/(4π² Ks))` (Zhang & Chen 2025 eq. 9); a missing term counts as rigid.
    pub fn equivalent_stiffness(&self, rotary: bool) -> Result<Option<f64>, Error> {
        if rotary {
            return check_pos(
                "torsional_stiffness_nm_per_rad",
                self.torsional_stiffness_nm_per_rad,
            );
        }
        let kj =
            check_pos("axial_stiffness_n_per_um", self.axial_stiffness_n_per_um)?.map(|k| k * 1e6);
        let ks = check_pos(
            "screw_torsional_stiffness_nm_per_rad",
            self.screw_torsional_stiffness_nm_per_rad,
        )?;
        if kj.is_none() && ks.is_none() {
            return Ok(None);
        }
        let mut compliance = kj.map_or(0.0, |k| 1.0 / k);
        if let Some(ks) = ks {
            let l = self.require("lead_mm", self.lead_mm)? * 1e-3;
            compliance += l * l / (4.0 * std::f64::consts::PI.powi(2) * ks);
        }
        Ok(Some(1.0 / compliance))
    }

    /// The structural mode of eq. 10 if a stiffness is given (mass/inertia then required).
    pub fn structural_mode(&self, rotary: bool) -> Result<Option<StructuralMode>, Error> {
        let Some(k) = self.equivalent_stiffness(rotary)? else {
            return Ok(None);
        };
        let (m, b) = if rotary {
            (
                self.require("table_inertia_kg_m2", self.table_inertia_kg_m2)?,
                self.table_damping_nm_s_per_rad,
            )
        } else {
            (
                self.require("table_mass_kg", self.table_mass_kg)?,
                self.table_damping_n_s_per_m,
            )
        };
        let b = b.unwrap_or(0.0);
        if !(b.is_finite() && b >= 0.0) {
            return Err(Error::parameter(
                "physical.table_damping",
                "must be a finite number >= 0",
            ));
        }
        Ok(Some(StructuralMode {
            omega_n: (k / m).sqrt(),
            zeta: b / (2.0 * (k * m).sqrt()),
        }))
    }
}

impl StructuralMode {
    /// Table position (mm or deg) for a motor-side position `x_m` sampled every `period_s`
    /// and linear between samples (first-order hold), starting at rest at `x_m[0]`.
    /// Exact discretization: `exp` of the 4×4 augmented matrix `[[A, B, 0], [0, 0, 1], [0, 0, 0]]·h`
    /// with `A = [[0, 1], [−ωn², −2ζωn]]`, `B = [0, ωn²]ᵀ`, in error coordinates `x − x_m`.
    /// Bad case: `ωn·period_s` ≫ 1 is exact but the mode is then invisible at that sampling.
    pub fn filter(&self, x_m: &[f64], period_s: f64) -> Vec<f64> {
        let w2 = self.omega_n * self.omega_n;
        let c = 2.0 * self.zeta * self.omega_n;
        // State [e, ė] with e = x − x_m; input: slope s of x_m (constant over a period):
        // ë = −w2 e − c (ė + s) − 0·... since ẍ_m = 0 within a period: ë = ẍ = −w2 e − c ẋ.
        // ẋ = ė + s → ë = −w2 e − c ė − c s.
        let m = Matrix4::new(
            0.0, 1.0, 0.0, 0.0, //
            -w2, -c, -c, 0.0, //
            0.0, 0.0, 0.0, 0.0, //
            0.0, 0.0, 0.0, 0.0,
        ) * period_s;
        let phi = m.exp();
        let mut out = Vec::with_capacity(x_m.len());
        let Some(&x0) = x_m.first() else {
            return out;
        };
        out.push(x0);
        // ė at rest is −s at the start of each period with nonzero slope; keep ẋ continuous:
        // track (e, ẋ) across periods, converting ė = ẋ − s per period.
        let mut e = 0.0;
        let mut xdot = 0.0;
        for k in 1..x_m.len() {
            let s = (x_m[k] - x_m[k - 1]) / period_s;
            let edot = xdot - s;
            let e1 = phi[(0, 0)] * e + phi[(0, 1)] * edot + phi[(0, 2)] * s;
            let edot1 = phi[(1, 0)] * e + phi[(1, 1)] * edot + phi[(1, 2)] * s;
            e = e1;
            xdot = edot1 + s;
            out.push(x_m[k] + e);
        }
        out
    }
}

#[cfg(test)]
mod tests;
