//! Wang, Dai & Hong's construction of a full 3-D sample set from measurements along a few
//! axis lines, by its additive rule.

use super::Error;
use super::data::{AXES, VolumetricData};
use serde::{Deserialize, Serialize};

/// Errors measured along one line parallel to a machine axis, through the reference
/// point (its other two coordinates are the reference's).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AxisLine {
    /// Positions along the axis (mm), any order, distinct.
    pub positions: Vec<f64>,
    /// Measured errors (actual − commanded, mm) at those positions.
    pub errors: Vec<[f64; 3]>,
}

/// Three orthogonal measurement lines through a common reference point.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AxisLines {
    /// The point all three lines pass through (mm).
    pub reference: [f64; 3],
    /// The line along X (y and z at the reference).
    pub x: AxisLine,
    /// The line along Y (x and z at the reference).
    pub y: AxisLine,
    /// The line along Z (x and y at the reference).
    pub z: AxisLine,
}

impl AxisLine {
    fn sorted(&self, axis: usize) -> Result<Vec<(f64, [f64; 3])>, Error> {
        let line = AXES[axis];
        if self.positions.len() < 2 {
            return Err(Error::AxisLine {
                line,
                reason: "needs at least 2 positions".into(),
            });
        }
        if self.errors.len() != self.positions.len() {
            return Err(Error::AxisLine {
                line,
                reason: format!(
                    "{} errors for {} positions: send one [dx,dy,dz] per position",
                    self.errors.len(),
                    self.positions.len()
                ),
            });
        }
        if let Some(i) = (0..self.positions.len()).find(|&i| {
            !self.positions[i].is_finite() || self.errors[i].iter().any(|v| !v.is_finite())
        }) {
            return Err(Error::AxisLine {
                line,
                reason: format!("entry {i} is not finite"),
            });
        }
        let mut v: Vec<(f64, [f64; 3])> = self
            .positions
            .iter()
            .copied()
            .zip(self.errors.iter().copied())
            .collect();
        v.sort_by(|a, b| a.0.total_cmp(&b.0));
        if v.windows(2).any(|w| w[1].0 <= w[0].0) {
            return Err(Error::AxisLine {
                line,
                reason: "positions repeat: send each position once".into(),
            });
        }
        Ok(v)
    }
}

/// Linear interpolation of a sorted line at `q` (inside its range).
fn at(line: &[(f64, [f64; 3])], q: f64) -> [f64; 3] {
    let i = line.partition_point(|s| s.0 <= q).clamp(1, line.len() - 1) - 1;
    let (q0, e0) = line[i];
    let (q1, e1) = line[i + 1];
    let t = ((q - q0) / (q1 - q0)).clamp(0.0, 1.0);
    [0, 1, 2].map(|j| e0[j] + t * (e1[j] - e0[j]))
}

/// Builds the full grid `positions_x × positions_y × positions_z` (x fastest) by the
/// additive rule of Wang, Dai & Hong §3.3:
/// `e(x, y, z) = e_X(x) + e_Y(y) + e_Z(z) − e_X(x_r) − e_Y(y_r) − e_Z(z_r) + ē_r`,
/// where `e_K` is the error measured along line K, `(x_r, y_r, z_r)` the reference point
/// and `ē_r` the mean of the three lines' (linearly interpolated) errors there. Wang, Dai & Hong
/// writes it for its two gauges as `δx_m = δx_c(v) + (δx_T(u) − δx_c(w))`: the error
/// on one line plus the change along another line relative to their common point.
///
/// Known limits: the rule is exact only when each error component is a sum of
/// single-axis functions. Angular errors act through lever arms that grow with the
/// other axes' positions (Abbe products such as pitch(x)·z), which the rule misses;
/// on the synthetic machine this leaves several µm away from the lines (see tests).
pub fn additive_grid(lines: &AxisLines) -> Result<VolumetricData, Error> {
    if lines.reference.iter().any(|v| !v.is_finite()) {
        return Err(Error::InvalidOption {
            name: "reference",
            reason: "must be finite".into(),
        });
    }
    let sorted = [lines.x.sorted(0)?, lines.y.sorted(1)?, lines.z.sorted(2)?];
    let mut at_ref = [[0.0; 3]; 3];
    for k in 0..3 {
        let (lo, hi) = (sorted[k][0].0, sorted[k][sorted[k].len() - 1].0);
        let r = lines.reference[k];
        if r < lo || r > hi {
            return Err(Error::AxisLine {
                line: AXES[k],
                reason: format!(
                    "the reference {r} mm is outside the line's positions {lo}..{hi} mm: the line must pass through the reference point"
                ),
            });
        }
        at_ref[k] = at(&sorted[k], r);
    }
    let mean_ref = [0, 1, 2].map(|j| (at_ref[0][j] + at_ref[1][j] + at_ref[2][j]) / 3.0);
    let mut data = VolumetricData {
        nodes: Vec::new(),
        errors: Vec::new(),
    };
    for &(z, ez) in &sorted[2] {
        for &(y, ey) in &sorted[1] {
            for &(x, ex) in &sorted[0] {
                data.nodes.push([x, y, z]);
                data.errors.push([0, 1, 2].map(|j| {
                    ex[j] + ey[j] + ez[j] - at_ref[0][j] - at_ref[1][j] - at_ref[2][j] + mean_ref[j]
                }));
            }
        }
    }
    Ok(data)
}

#[cfg(test)]
mod tests;
