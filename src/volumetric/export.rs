//! Export of a map as a compensation table on a requested grid (CSV), ready to be
//! loaded into a controller's 3-D error compensation.

use super::Error;
use super::data::AXES;
use super::fit::VolumetricMap;
use serde::{Deserialize, Serialize};

/// The grid of a compensation table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TableSpec {
    /// Lower corner (mm).
    pub min: [f64; 3],
    /// Upper corner (mm).
    pub max: [f64; 3],
    /// Points per axis (≥ 2 each, or 1 with `min == max`).
    pub points: [usize; 3],
    /// The controller's limit of points per axis (Xiang et al. 2019: FANUC allows 25), checked.
    pub max_points_per_axis: Option<usize>,
}

/// At most this many table rows (a controller table is far smaller).
pub const MAX_TABLE_ROWS: usize = 1_000_000;

impl TableSpec {
    /// The map's measured box with `points` per axis.
    pub fn over(map: &VolumetricMap, points: [usize; 3]) -> TableSpec {
        TableSpec {
            min: map.bounds.min,
            max: map.bounds.max,
            points,
            max_points_per_axis: None,
        }
    }

    fn validate(&self) -> Result<(), Error> {
        for (k, &axis) in AXES.iter().enumerate() {
            if !self.min[k].is_finite() || !self.max[k].is_finite() || self.min[k] > self.max[k] {
                return Err(Error::InvalidOption {
                    name: "table bounds",
                    reason: format!("need finite min ≤ max on {} (mm)", axis),
                });
            }
            let n = self.points[k];
            if n == 0 || (n == 1 && self.min[k] != self.max[k]) {
                return Err(Error::InvalidOption {
                    name: "table points",
                    reason: format!("{} needs at least 2 points (1 only when min = max)", axis),
                });
            }
            if let Some(limit) = self.max_points_per_axis
                && n > limit
            {
                return Err(Error::TableTooLarge {
                    axis,
                    points: n,
                    limit,
                });
            }
        }
        if self
            .points
            .iter()
            .try_fold(1usize, |a, &n| a.checked_mul(n))
            .is_none_or(|t| t > MAX_TABLE_ROWS)
        {
            return Err(Error::InvalidOption {
                name: "table points",
                reason: format!("at most {MAX_TABLE_ROWS} rows in total"),
            });
        }
        Ok(())
    }

    /// Coordinates of axis `k` (mm).
    fn levels(&self, k: usize) -> Vec<f64> {
        let n = self.points[k];
        (0..n)
            .map(|i| {
                if n == 1 {
                    self.min[k]
                } else {
                    self.min[k] + (self.max[k] - self.min[k]) * i as f64 / (n - 1) as f64
                }
            })
            .collect()
    }
}

/// Writes the compensation table as CSV with header
/// `x,y,z,dx,dy,dz,comp_x,comp_y,comp_z,out_of_box`: node (mm), predicted error
/// (actual − commanded, mm) and the compensation a controller adds to the command
/// (`comp = −error`, mm), x running fastest, then y, then z (the order Xiang et al. 2019
/// measures in). Values with 6 decimals (nm). `out_of_box` is 1 where the node lies
/// outside the measured volume (the nearest measured value is held there).
pub fn compensation_table_csv(map: &VolumetricMap, spec: &TableSpec) -> Result<String, Error> {
    spec.validate()?;
    let lv = [spec.levels(0), spec.levels(1), spec.levels(2)];
    let mut points = Vec::with_capacity(lv.iter().map(Vec::len).product());
    for &z in &lv[2] {
        for &y in &lv[1] {
            for &x in &lv[0] {
                points.push([x, y, z]);
            }
        }
    }
    let pred = map.predict(&points)?;
    let mut out = String::with_capacity(points.len() * 90);
    out.push_str("x,y,z,dx,dy,dz,comp_x,comp_y,comp_z,out_of_box\n");
    for ((p, e), o) in points.iter().zip(&pred.errors).zip(&pred.out_of_box) {
        use std::fmt::Write;
        let _ = writeln!(
            out,
            "{},{},{},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{}",
            p[0],
            p[1],
            p[2],
            e[0],
            e[1],
            e[2],
            -e[0] + 0.0,
            -e[1] + 0.0,
            -e[2] + 0.0,
            u8::from(*o)
        );
    }
    Ok(out)
}

#[cfg(test)]
mod tests;
