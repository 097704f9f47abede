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
mod tests {
    use super::*;

    fn data_from(f: impl Fn([f64; 3]) -> [f64; 3], n: [usize; 3]) -> VolumetricData {
        let mut d = VolumetricData {
            nodes: vec![],
            errors: vec![],
        };
        for iz in 0..n[2] {
            for iy in 0..n[1] {
                for ix in 0..n[0] {
                    let p = [ix as f64 * 100.0, iy as f64 * 50.0, iz as f64 * 40.0];
                    d.nodes.push(p);
                    d.errors.push(f(p));
                }
            }
        }
        d
    }

    #[test]
    fn reproduces_nodes_and_trilinear_fields_exactly() {
        let f = |p: [f64; 3]| {
            [
                1e-3 + 2e-5 * p[0] - 1e-5 * p[1] * p[2] * 1e-2,
                3e-6 * p[0] * p[1] * 1e-2,
                -4e-5 * p[2],
            ]
        };
        let d = data_from(f, [4, 3, 3]);
        let m = TrilinearMap::fit(&d, None).unwrap();
        for (p, e) in d.nodes.iter().zip(&d.errors) {
            let q = m.eval(*p);
            (0..3).for_each(|j| assert!((q[j] - e[j]).abs() < 1e-15));
        }
        let p = [123.0, 77.0, 51.0];
        let (q, e) = (m.eval(p), f(p));
        (0..3).for_each(|j| assert!((q[j] - e[j]).abs() < 1e-12, "{q:?} {e:?}"));
        // off the box: edge value held
        let out = m.eval([1e4, -50.0, 40.0]);
        let edge = f([300.0, 0.0, 40.0]);
        (0..3).for_each(|j| assert!((out[j] - edge[j]).abs() < 1e-12));
        assert_eq!(m.parameter_count(), 3 * 36 + 10);
    }

    #[test]
    fn curvature_between_nodes_is_missed_and_limit_resamples() {
        let f = |p: [f64; 3]| [1e-8 * p[0] * p[0], 0.0, 0.0];
        let d = data_from(f, [5, 2, 2]);
        let m = TrilinearMap::fit(&d, None).unwrap();
        // midway between nodes 100 apart the chord overshoots by h²/4·a = 2.5e-5
        let q = m.eval([150.0, 0.0, 0.0]);
        assert!((q[0] - f([150.0, 0.0, 0.0])[0] - 2.5e-5).abs() < 1e-12);
        let lim = TrilinearMap::fit(&d, Some(3)).unwrap();
        assert_eq!(lim.levels[0], vec![0.0, 200.0, 400.0]);
        assert_eq!(lim.values.len(), 3 * 2 * 2);
        assert!(TrilinearMap::fit(&d, Some(1)).is_err());
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig {
            cases: 64,
            rng_seed: proptest::test_runner::RngSeed::Fixed(7),
            failure_persistence: None,
            ..Default::default()
        })]
        /// Laws: affine fields are reproduced everywhere; values stay within the corners' range.
        #[test]
        fn affine_exact_and_bounded(
            a in proptest::array::uniform4(-1e-2f64..1e-2),
            vals in proptest::collection::vec(-1e-2f64..1e-2, 27),
            q in proptest::array::uniform3(0.0f64..1.0),
        ) {
            let affine = |p: [f64; 3]| [a[0] + 1e-5 * (a[1] * p[0] + a[2] * p[1] + a[3] * p[2]), 0.0, 0.0];
            let m = TrilinearMap::fit(&data_from(affine, [3, 3, 3]), None).unwrap();
            let p = [q[0] * 200.0, q[1] * 100.0, q[2] * 80.0];
            proptest::prop_assert!((m.eval(p)[0] - affine(p)[0]).abs() < 1e-12);
            let table = TrilinearMap { levels: m.levels.clone(), values: vals.iter().map(|&v| [v, -v, 0.0]).collect() };
            let v = table.eval(p)[0];
            let (lo, hi) = vals.iter().fold((f64::MAX, f64::MIN), |(l, h), &x| (l.min(x), h.max(x)));
            proptest::prop_assert!(v >= lo - 1e-15 && v <= hi + 1e-15);
        }
    }
}
