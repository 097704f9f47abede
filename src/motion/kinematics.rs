//! Machine kinematics: `xyz` and `xyzac_table` (A tilting table about X carrying a C rotary
//! table about Z; the spindle moves in X, Y, Z and stays parallel to machine Z).
//!
//! Conventions: machine coordinates coincide with the workpiece frame when A = C = 0.
//! A point `p_w` fixed to the workpiece sits in the machine frame at
//! `p_m = T_A(A)·T_C(C)·p_w`, with `T_C(C) p = R_z(C)(p − o_C) + o_C` and
//! `T_A(A) p = R_x(A)(p − o_A) + o_A` (right-hand rotations, degrees), `o_A` a point on the
//! A axis and `o_C` a point on the C axis, both given at A = C = 0. Machine X, Y, Z are the
//! spindle gauge point; the tool tip is `tool_length` mm below it along −Z.

use serde::{Deserialize, Serialize};

use crate::numeric::vec3::{add, sub};

/// Table offsets and tool length of an `xyzac_table` machine (the machine JSON "geometry").
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TableGeometry {
    /// A point on the A (tilt, about X) axis at A = C = 0, machine coordinates, mm.
    #[serde(default)]
    pub a_axis_origin: [f64; 3],
    /// A point on the C (rotary, about Z) axis at A = C = 0, machine coordinates, mm.
    #[serde(default)]
    pub c_axis_origin: [f64; 3],
    /// Tool length from the spindle gauge point to the tool tip, mm.
    #[serde(default)]
    pub tool_length: f64,
}

impl Default for TableGeometry {
    fn default() -> Self {
        TableGeometry {
            a_axis_origin: [0.0; 3],
            c_axis_origin: [0.0; 3],
            tool_length: 0.0,
        }
    }
}

/// Kinematic chain of a machine.
#[derive(Clone, Debug, PartialEq)]
pub enum Kinematics {
    /// Three orthogonal linear axes; the tool tip is (X, Y, Z).
    Xyz,
    /// Five axes X, Y, Z, A (table tilt about X), C (table rotation about Z).
    XyzacTable(TableGeometry),
}

/// Tool tip (mm) and unit tool axis (pointing from tip into the spindle), both in the
/// workpiece frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ToolPose {
    /// Tool tip, mm, workpiece frame.
    pub tip: [f64; 3],
    /// Unit tool axis, from the tip into the spindle, workpiece frame.
    pub axis: [f64; 3],
}

fn rot_x(deg: f64, p: [f64; 3]) -> [f64; 3] {
    let (s, c) = deg.to_radians().sin_cos();
    [p[0], c * p[1] - s * p[2], s * p[1] + c * p[2]]
}

fn rot_z(deg: f64, p: [f64; 3]) -> [f64; 3] {
    let (s, c) = deg.to_radians().sin_cos();
    [c * p[0] - s * p[1], s * p[0] + c * p[1], p[2]]
}

impl Kinematics {
    /// Number of machine axes (3 or 5), in the order X, Y, Z[, A, C].
    pub fn axis_count(&self) -> usize {
        match self {
            Kinematics::Xyz => 3,
            Kinematics::XyzacTable(_) => 5,
        }
    }

    /// Forward transform: machine axes `[X, Y, Z, A, C]` (mm, degrees; A and C ignored for
    /// `xyz`) → tool tip and tool axis in the workpiece frame.
    /// Formula: `p_w = T_C(C)⁻¹ T_A(A)⁻¹ (X, Y, Z − L)`, axis `= R_z(−C) R_x(−A) e_z`
    /// = (sin A sin C, sin A cos C, cos A). Reference: Zhang & Chen 2025 §2.1 eq. 1 (tool axis
    /// vector from the rotary angles), with this crate's sign conventions (module docs).
    pub fn forward(&self, q: &[f64; 5]) -> ToolPose {
        match self {
            Kinematics::Xyz => ToolPose {
                tip: [q[0], q[1], q[2]],
                axis: [0.0, 0.0, 1.0],
            },
            Kinematics::XyzacTable(g) => {
                let tip_m = [q[0], q[1], q[2] - g.tool_length];
                let p = add(rot_x(-q[3], sub(tip_m, g.a_axis_origin)), g.a_axis_origin);
                let tip = add(rot_z(-q[4], sub(p, g.c_axis_origin)), g.c_axis_origin);
                let axis = rot_z(-q[4], rot_x(-q[3], [0.0, 0.0, 1.0]));
                ToolPose { tip, axis }
            }
        }
    }

    /// Inverse transform (what RTCP does): tool tip `tip` in the workpiece frame (mm) and
    /// rotary positions `a`, `c` (degrees) → machine axes `[X, Y, Z, A, C]`.
    /// Formula: `(X, Y, Z) = T_A(A) T_C(C) tip + (0, 0, L)`. Exact inverse of [`forward`]
    /// for any angles (no singularity: the rotary angles are given, not solved for).
    ///
    /// [`forward`]: Kinematics::forward
    pub fn inverse(&self, tip: &[f64; 3], a: f64, c: f64) -> [f64; 5] {
        match self {
            Kinematics::Xyz => [tip[0], tip[1], tip[2], a, c],
            Kinematics::XyzacTable(g) => {
                let p = add(rot_z(c, sub(*tip, g.c_axis_origin)), g.c_axis_origin);
                let m = add(rot_x(a, sub(p, g.a_axis_origin)), g.a_axis_origin);
                [m[0], m[1], m[2] + g.tool_length, a, c]
            }
        }
    }
}

/// Rotary angles (degrees) that put the tool axis along the unit vector `axis` (workpiece
/// frame) on an `xyzac_table` machine: A = acos(k) ∈ [0°, 180°], C = atan2(i, j).
/// Inverse of the axis formula of [`Kinematics::forward`]. Bad case: at A = 0 (axis along Z)
/// C is arbitrary and 0 is returned; the other branch (−A, C + 180°) is not returned.
pub fn orientation_to_ac(axis: &[f64; 3]) -> (f64, f64) {
    let n = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
    let k = (axis[2] / n).clamp(-1.0, 1.0);
    let a = k.acos().to_degrees();
    let c = if (axis[0] / n).hypot(axis[1] / n) < 1e-12 {
        0.0
    } else {
        axis[0].atan2(axis[1]).to_degrees()
    };
    (a, c)
}

/// Angle between two tool axes, degrees (robust near 0 via atan2 of |u×v| and u·v).
pub fn angle_between_deg(u: &[f64; 3], v: &[f64; 3]) -> f64 {
    let cross = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    let cn = (cross[0] * cross[0] + cross[1] * cross[1] + cross[2] * cross[2]).sqrt();
    let dot = u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
    cn.atan2(dot).to_degrees()
}

#[cfg(test)]
mod tests;
