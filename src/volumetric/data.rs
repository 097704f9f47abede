//! Measured nodes, their bounding box, and detection of a rectilinear grid.

use super::Error;
use serde::{Deserialize, Serialize};

/// Measured positioning errors at nodes of the machine's working volume.
///
/// `nodes` are commanded positions (mm, machine coordinates); `errors` are the
/// measured positioning errors there, actual − commanded (mm), as a laser tracker or
/// interferometer reports them (Xiang et al. 2019 §1, step 1).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct VolumetricData {
    /// Commanded positions (x, y, z), mm, machine coordinates.
    pub nodes: Vec<[f64; 3]>,
    /// Positioning error at each node (ex, ey, ez) = actual − commanded, mm.
    pub errors: Vec<[f64; 3]>,
}

/// Axis-aligned box of the measured nodes (mm).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Bounds {
    /// Smallest x, y, z of the nodes, mm.
    pub min: [f64; 3],
    /// Largest x, y, z of the nodes, mm.
    pub max: [f64; 3],
}

/// The levels of a full rectilinear grid and, for every grid index, the node's index.
#[derive(Clone, Debug, PartialEq)]
pub struct GridIndex {
    /// Sorted distinct coordinates per axis (mm).
    pub levels: [Vec<f64>; 3],
    /// `node_of[ix + nx * (iy + ny * iz)]` is the index of that node in the data.
    pub node_of: Vec<usize>,
}

pub(crate) const AXES: [char; 3] = ['x', 'y', 'z'];

impl Bounds {
    /// Smallest box holding all `points` (mm). `points` must be non-empty.
    pub fn of(points: &[[f64; 3]]) -> Bounds {
        let mut min = [f64::INFINITY; 3];
        let mut max = [f64::NEG_INFINITY; 3];
        for p in points {
            for k in 0..3 {
                min[k] = min[k].min(p[k]);
                max[k] = max[k].max(p[k]);
            }
        }
        Bounds { min, max }
    }

    /// Whether `p` lies in the box, allowing 1e-9 of the box size (mm) for round-off.
    pub fn contains(&self, p: [f64; 3]) -> bool {
        (0..3).all(|k| {
            let tol = 1e-9 * (self.max[k] - self.min[k]).abs().max(1.0);
            p[k] >= self.min[k] - tol && p[k] <= self.max[k] + tol
        })
    }

    /// `p` with every coordinate clamped into the box (mm): the point every model
    /// evaluates for a query outside the measured volume.
    pub fn clamp(&self, p: [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|k| p[k].clamp(self.min[k], self.max[k]))
    }
}

impl VolumetricData {
    /// Checks that nodes and errors pair up, are finite, number at least `need`, and
    /// span all three axes. Returns the bounding box.
    pub fn validate(&self, need: usize) -> Result<Bounds, Error> {
        if self.nodes.is_empty() {
            return Err(Error::Empty {
                field: "nodes",
                need: need.max(1),
            });
        }
        if self.errors.len() != self.nodes.len() {
            return Err(Error::LengthMismatch {
                field: "errors",
                got: self.errors.len(),
                expected: self.nodes.len(),
            });
        }
        check_finite("nodes", &self.nodes)?;
        check_finite("errors", &self.errors)?;
        if self.nodes.len() < need {
            return Err(Error::TooFewNodes {
                what: "a volumetric map",
                need,
                got: self.nodes.len(),
            });
        }
        let b = Bounds::of(&self.nodes);
        for (k, &axis) in AXES.iter().enumerate() {
            if b.max[k] - b.min[k] <= 1e-9 * b.max[k].abs().max(1.0) {
                return Err(Error::FlatAxis { axis });
            }
        }
        Ok(b)
    }

    /// Parses CSV text with a header naming the columns `x,y,z,dx,dy,dz` (any order,
    /// extra columns ignored, optional unit suffixes such as `x_mm` are accepted).
    /// Values in mm.
    pub fn from_csv(text: &str) -> Result<VolumetricData, Error> {
        let mut lines = text
            .lines()
            .enumerate()
            .filter(|(_, l)| !l.trim().is_empty());
        let (_, header) = lines.next().ok_or(Error::Csv {
            line: 1,
            reason: "empty body: send a header row x,y,z,dx,dy,dz and one row per node".into(),
        })?;
        let names: Vec<String> = header
            .split(',')
            .map(|h| {
                let h = h.trim().trim_matches('"').to_ascii_lowercase();
                h.strip_suffix("_mm").map(str::to_string).unwrap_or(h)
            })
            .collect();
        let want = ["x", "y", "z", "dx", "dy", "dz"];
        let mut col = [0usize; 6];
        for (c, w) in want.iter().enumerate() {
            col[c] = names
                .iter()
                .position(|n| n == w)
                .ok_or_else(|| Error::Csv {
                    line: 1,
                    reason: format!(
                        "header has no column '{w}': the header must name x,y,z,dx,dy,dz"
                    ),
                })?;
        }
        let mut data = VolumetricData {
            nodes: Vec::new(),
            errors: Vec::new(),
        };
        for (i, line) in lines {
            let cells: Vec<&str> = line.split(',').map(str::trim).collect();
            if cells.len() != names.len() {
                return Err(Error::Csv {
                    line: i + 1,
                    reason: format!("{} cells but the header has {}", cells.len(), names.len()),
                });
            }
            let mut v = [0.0; 6];
            for c in 0..6 {
                let cell = cells[col[c]];
                v[c] = cell
                    .parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| Error::Csv {
                        line: i + 1,
                        reason: format!("'{}' is not a finite number in column {}", cell, want[c]),
                    })?;
            }
            data.nodes.push([v[0], v[1], v[2]]);
            data.errors.push([v[3], v[4], v[5]]);
        }
        if data.nodes.is_empty() {
            return Err(Error::Csv {
                line: 2,
                reason: "no data rows after the header".into(),
            });
        }
        Ok(data)
    }

    /// Detects whether the nodes form a full rectilinear grid (every combination of
    /// the distinct x, y, z levels exactly once, in any order). Levels closer than
    /// 1e-6 of the axis span are merged.
    pub fn grid(&self) -> Result<GridIndex, Error> {
        let b = Bounds::of(&self.nodes);
        let mut levels: [Vec<f64>; 3] = Default::default();
        let mut idx = vec![[0usize; 3]; self.nodes.len()];
        for k in 0..3 {
            let tol = 1e-6 * (b.max[k] - b.min[k]).max(1e-9);
            let mut vals: Vec<f64> = self.nodes.iter().map(|p| p[k]).collect();
            vals.sort_by(f64::total_cmp);
            let mut lv: Vec<f64> = Vec::new();
            for v in vals {
                if lv.last().is_none_or(|&l| v - l > tol) {
                    lv.push(v);
                }
            }
            for (i, p) in self.nodes.iter().enumerate() {
                idx[i][k] = nearest_level(&lv, p[k]);
            }
            levels[k] = lv;
        }
        let (nx, ny, nz) = (levels[0].len(), levels[1].len(), levels[2].len());
        if nx * ny * nz != self.nodes.len() {
            return Err(Error::NotAGrid {
                reason: format!(
                    "{} nodes but {}×{}×{} = {} level combinations",
                    self.nodes.len(),
                    nx,
                    ny,
                    nz,
                    nx * ny * nz
                ),
            });
        }
        let mut node_of = vec![usize::MAX; self.nodes.len()];
        for (i, [ix, iy, iz]) in idx.into_iter().enumerate() {
            let cell = ix + nx * (iy + ny * iz);
            if node_of[cell] != usize::MAX {
                return Err(Error::NotAGrid {
                    reason: format!("nodes {} and {} coincide", node_of[cell], i),
                });
            }
            node_of[cell] = i;
        }
        Ok(GridIndex { levels, node_of })
    }

    /// The subset of the data at the given node indices.
    pub fn subset(&self, keep: &[usize]) -> VolumetricData {
        VolumetricData {
            nodes: keep.iter().map(|&i| self.nodes[i]).collect(),
            errors: keep.iter().map(|&i| self.errors[i]).collect(),
        }
    }
}

fn nearest_level(levels: &[f64], v: f64) -> usize {
    let i = levels.partition_point(|&l| l < v);
    if i == 0 {
        0
    } else if i == levels.len() || (v - levels[i - 1]) <= (levels[i] - v) {
        i - 1
    } else {
        i
    }
}

fn check_finite(field: &'static str, xs: &[[f64; 3]]) -> Result<(), Error> {
    match xs.iter().position(|p| p.iter().any(|v| !v.is_finite())) {
        Some(index) => Err(Error::NonFinite { field, index }),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests;
