//! Trilinear interpolation on the measured grid: what a CNC's 3-D (volumetric) error
//! compensation table does, and the baseline every other model is compared with.
//! Hand-written (40 lines): it must behave exactly like a controller table (clamped
//! edges, resampling to a table limit), which no interpolation crate promises.

use super::Error;
use super::data::{Bounds, VolumetricData};
use serde::{Deserialize, Serialize};

/// A controller-style error table: errors (mm) at every node of a rectilinear grid.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrilinearMap {
    /// Sorted grid levels per axis (mm).
    pub levels: [Vec<f64>; 3],
    /// Errors (mm) at grid node `ix + nx * (iy + ny * iz)`.
    pub values: Vec<[f64; 3]>,
}

impl TrilinearMap {
    /// Builds the table from measured grid nodes.
    ///
    /// `max_points_per_axis` models the controller's table-size limit (Xiang et al. 2019,
    /// background: FANUC allows at most 25 points per axis): an axis with more levels
    /// is resampled onto that many evenly spaced levels over its range, the values
    /// coming from trilinear interpolation of the full measured grid, which is what an
    /// integrator has to do to fit the table into the control.
    ///
    /// Errors: [`Error::NotAGrid`] unless the nodes are a full rectilinear grid;
    /// [`Error::InvalidOption`] for a limit below 2.
    pub fn fit(
        data: &VolumetricData,
        max_points_per_axis: Option<usize>,
    ) -> Result<TrilinearMap, Error> {
        let g = data.grid()?;
        let full = TrilinearMap {
            values: g.node_of.iter().map(|&i| data.errors[i]).collect(),
            levels: g.levels,
        };
        let Some(limit) = max_points_per_axis else {
            return Ok(full);
        };
        if limit < 2 {
            return Err(Error::InvalidOption {
                name: "max_points_per_axis",
                reason: "must be at least 2".into(),
            });
        }
        if full.levels.iter().all(|l| l.len() <= limit) {
            return Ok(full);
        }
        let levels = full.levels.clone().map(|l| {
            if l.len() <= limit {
                l
            } else {
                let (a, b) = (l[0], l[l.len() - 1]);
                (0..limit)
                    .map(|i| a + (b - a) * i as f64 / (limit - 1) as f64)
                    .collect()
            }
        });
        let mut values = Vec::with_capacity(levels.iter().map(Vec::len).product());
        for &z in &levels[2] {
            for &y in &levels[1] {
                for &x in &levels[0] {
                    values.push(full.eval([x, y, z]));
                }
            }
        }
        Ok(TrilinearMap { levels, values })
    }

    /// Interpolated error (mm) at `p` (mm).
    ///
    /// Formula: inside cell `[x0,x1]×[y0,y1]×[z0,z1]` with local fractions
    /// `u,v,w ∈ [0,1]`, `e = Σ_{corners} e_c · (u|1−u)(v|1−v)(w|1−w)` — exact at nodes,
    /// linear along every grid edge. Off the grid nodes the error is therefore only as
    /// good as the error field is linear between nodes: the interpolation error is
    /// about `h²/8 · |e''|` for node spacing `h`.
    ///
    /// Outside the grid the coordinates are clamped to the box (the edge values are
    /// held), as controllers do; callers flag such points.
    pub fn eval(&self, p: [f64; 3]) -> [f64; 3] {
        let n = [
            self.levels[0].len(),
            self.levels[1].len(),
            self.levels[2].len(),
        ];
        let mut i0 = [0usize; 3];
        let mut t = [0.0; 3];
        for k in 0..3 {
            let l = &self.levels[k];
            let q = p[k].clamp(l[0], l[n[k] - 1]);
            let i = l.partition_point(|&v| v <= q).clamp(1, n[k] - 1) - 1;
            i0[k] = i;
            t[k] = if n[k] == 1 {
                0.0
            } else {
                (q - l[i]) / (l[i + 1] - l[i])
            };
        }
        let mut out = [0.0; 3];
        for c in 0..8 {
            let d = [c & 1, (c >> 1) & 1, (c >> 2) & 1];
            let mut w = 1.0;
            let mut idx = [0usize; 3];
            for k in 0..3 {
                w *= if d[k] == 1 { t[k] } else { 1.0 - t[k] };
                idx[k] = (i0[k] + d[k]).min(n[k] - 1);
            }
            if w == 0.0 {
                continue;
            }
            let v = self.values[idx[0] + n[0] * (idx[1] + n[1] * idx[2])];
            for j in 0..3 {
                out[j] += w * v[j];
            }
        }
        out
    }

    /// Numbers the controller stores: three errors per node plus the grid levels.
    pub fn parameter_count(&self) -> usize {
        3 * self.values.len() + self.levels.iter().map(Vec::len).sum::<usize>()
    }

    /// The table's box (mm).
    pub fn bounds(&self) -> Bounds {
        Bounds {
            min: [0, 1, 2].map(|k| self.levels[k][0]),
            max: [0, 1, 2].map(|k| *self.levels[k].last().unwrap_or(&0.0)),
        }
    }
}

#[cfg(test)]
mod tests;
