//! A synthetic three-axis machine with known ISO 230-1 errors, for tests and benches.

use super::data::VolumetricData;
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal};

/// How error motions vary along travel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShapeFamily {
    /// A low-order trend (slope, bow, S-shape with decaying weights) plus a waviness of
    /// 10 % of the trend's size and a period of 0.6–1.5 travel (resolved by a 7-node axis, not by a 4-node one): how interferometer
    /// curves of ground ways and ballscrews usually look.
    TrendAndWaviness,
    /// A slope plus a sine of 0.35–0.9 periods over travel at full size: long-wave
    /// errors that coarse grids cannot resolve (a stress case).
    LongWave,
}

/// One error motion: `v(s) = scale · (c1·s + c2·s² + c3·s³ + w·sin(π k s + φ))`,
/// `s ∈ [0, 1]` the normalised axis position. Not a polynomial, so no model fits it
/// exactly.
#[derive(Clone, Copy, Debug)]
struct Shape {
    scale: f64,
    c: [f64; 3],
    wave: f64,
    k: f64,
    phase: f64,
}

impl Shape {
    fn random(rng: &mut StdRng, peak_to_peak: f64, family: ShapeFamily) -> Shape {
        let mut s = match family {
            ShapeFamily::TrendAndWaviness => Shape {
                scale: 1.0,
                c: [
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-0.6..0.6),
                    rng.random_range(-0.3..0.3),
                ],
                wave: 0.0,
                k: rng.random_range(1.3..3.3),
                phase: rng.random_range(0.0..std::f64::consts::TAU),
            },
            ShapeFamily::LongWave => Shape {
                scale: 1.0,
                c: [rng.random_range(-1.5..1.5), 0.0, 0.0],
                wave: 1.0,
                k: rng.random_range(0.7..1.8),
                phase: rng.random_range(0.0..std::f64::consts::TAU),
            },
        };
        if family == ShapeFamily::TrendAndWaviness {
            let trend: Vec<f64> = (0..=200).map(|i| s.raw(i as f64 / 200.0)).collect();
            s.wave = 0.1
                * (trend.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
                    - trend.iter().cloned().fold(f64::INFINITY, f64::min))
                / 2.0;
        }
        let vals: Vec<f64> = (0..=200).map(|i| s.raw(i as f64 / 200.0)).collect();
        let pp = vals.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
            - vals.iter().cloned().fold(f64::INFINITY, f64::min);
        s.scale = peak_to_peak / pp;
        s
    }
    fn raw(&self, s: f64) -> f64 {
        let [c1, c2, c3] = self.c;
        s * (c1 + s * (c2 + s * c3))
            + self.wave * (std::f64::consts::PI * self.k * s + self.phase).sin()
    }
    fn at(&self, s: f64) -> f64 {
        self.scale * self.raw(s)
    }
}

/// A machine with axes X ∈ [0, travel_x], Y ∈ [0, travel_y], Z ∈ [0, travel_z] (mm)
/// stacked as the serial chain base→X→Y→Z→tool, whose 18 error motions and three
/// squareness errors are drawn at the magnitudes of issue 7: positioning 5–30 µm
/// peak-to-peak over travel, straightness 2–15 µm, angular 5–40 µrad, squareness
/// 10–60 µrad.
#[derive(Clone, Debug)]
pub struct SyntheticMachine {
    /// Travel per axis (mm), each axis from 0.
    pub travel_mm: [f64; 3],
    /// Tool tip offset from the Z carriage (mm).
    pub tool_offset_mm: [f64; 3],
    /// EC0Y, EB0Z, EA0Z (rad).
    pub squareness_rad: [f64; 3],
    /// Standard deviation of the measurement noise per component (mm).
    pub noise_mm: f64,
    /// Amplitude (mm) of a non-rigid sag `dz −= a·sin(πx/X)·sin(πy/Y)` (e.g. a bridge
    /// bending under its carriage) that no rigid-body model can express; 0 by default.
    pub sag_mm: f64,
    motions: [[Shape; 6]; 3],
}

impl SyntheticMachine {
    /// Draws a machine with 800 × 500 × 400 mm travel, a 150 mm tool, 1 µm noise and
    /// the given shape family.
    pub fn new(seed: u64, family: ShapeFamily) -> SyntheticMachine {
        let mut rng = StdRng::seed_from_u64(seed);
        let motions = [0, 1, 2].map(|axis| {
            [0, 1, 2, 3, 4, 5].map(|f| {
                let pp = if f == axis {
                    rng.random_range(5e-3..30e-3)
                } else if f < 3 {
                    rng.random_range(2e-3..15e-3)
                } else {
                    rng.random_range(5e-6..40e-6)
                };
                Shape::random(&mut rng, pp, family)
            })
        });
        let squareness_rad = [0, 1, 2].map(|_| {
            let m = rng.random_range(10e-6..60e-6);
            if rng.random_bool(0.5) { m } else { -m }
        });
        SyntheticMachine {
            travel_mm: [800.0, 500.0, 400.0],
            tool_offset_mm: [0.0, 0.0, -150.0],
            squareness_rad,
            noise_mm: 1e-3,
            sag_mm: 0.0,
            motions,
        }
    }

    /// True error motion `function` (0–2 translation mm, 3–5 rotation rad, order of
    /// [`super::kinematic::FUNCTION_NAMES`]) of `axis` at position `q` (mm).
    pub fn motion(&self, axis: usize, function: usize, q: f64) -> f64 {
        self.motions[axis][function].at(q / self.travel_mm[axis])
    }

    /// Exact (not linearised) positioning error of the tool tip at commanded `p` (mm):
    /// tip = X(x)·Y(y)·Z(z)·t with each carriage a homogeneous transform
    /// Trans(q·u + δ(q))·Rot(ε(q)), Rot = Rz·Ry·Rx, and Y, Z directions tilted by the
    /// squareness errors; error = tip − (p + t).
    pub fn error(&self, p: [f64; 3]) -> [f64; 3] {
        let t = self.tool_offset_mm;
        let [c0y, b0z, a0z] = self.squareness_rad;
        let uy = [-c0y.sin(), c0y.cos(), 0.0];
        let uz = [b0z.sin(), -b0z.cos() * a0z.sin(), b0z.cos() * a0z.cos()];
        let dirs = [[1.0, 0.0, 0.0], uy, uz];
        // innermost first: v = R_Z t + z uz + δZ ; v = R_Y v + y uy + δY ; ...
        let mut v = t;
        for axis in (0..3).rev() {
            let q = p[axis];
            let ang = [3, 4, 5].map(|f| self.motion(axis, f, q));
            let r = rotation(ang);
            let mut w = [0.0; 3];
            for i in 0..3 {
                w[i] = (0..3).map(|j| r[i][j] * v[j]).sum::<f64>()
                    + q * dirs[axis][i]
                    + self.motion(axis, i, q);
            }
            v = w;
        }
        let sag = self.sag_mm
            * (std::f64::consts::PI * p[0] / self.travel_mm[0]).sin()
            * (std::f64::consts::PI * p[1] / self.travel_mm[1]).sin();
        [
            v[0] - p[0] - t[0],
            v[1] - p[1] - t[1],
            v[2] - p[2] - t[2] - sag,
        ]
    }

    /// Measured data on an `n[0] × n[1] × n[2]` grid spanning the full travel, with
    /// Gaussian noise of `noise_mm` per component (seeded).
    pub fn measure_grid(&self, n: [usize; 3], seed: u64) -> VolumetricData {
        let mut nodes = Vec::new();
        for iz in 0..n[2] {
            for iy in 0..n[1] {
                for ix in 0..n[0] {
                    let i = [ix, iy, iz];
                    nodes.push(
                        [0, 1, 2]
                            .map(|k| self.travel_mm[k] * i[k] as f64 / (n[k] - 1).max(1) as f64),
                    );
                }
            }
        }
        self.measure(nodes, seed)
    }

    /// Measured data at the given commanded points, with noise (seeded).
    pub fn measure(&self, nodes: Vec<[f64; 3]>, seed: u64) -> VolumetricData {
        let mut rng = StdRng::seed_from_u64(seed);
        let noise = Normal::new(0.0, self.noise_mm.max(0.0)).expect("finite sigma");
        let errors = nodes
            .iter()
            .map(|&p| self.error(p).map(|e| e + noise.sample(&mut rng)))
            .collect();
        VolumetricData { nodes, errors }
    }

    /// `n` points drawn uniformly in the travel box (seeded): off-grid check points.
    pub fn random_points(&self, n: usize, seed: u64) -> Vec<[f64; 3]> {
        let mut rng = StdRng::seed_from_u64(seed);
        (0..n)
            .map(|_| self.travel_mm.map(|t| rng.random_range(0.0..t)))
            .collect()
    }
}

/// Rz(γ)·Ry(β)·Rx(α) for `[α, β, γ]` (rad).
fn rotation([a, b, c]: [f64; 3]) -> [[f64; 3]; 3] {
    let (sa, ca, sb, cb, sc, cc) = (a.sin(), a.cos(), b.sin(), b.cos(), c.sin(), c.cos());
    [
        [cc * cb, cc * sb * sa - sc * ca, cc * sb * ca + sc * sa],
        [sc * cb, sc * sb * sa + cc * ca, sc * sb * ca - cc * sa],
        [-sb, cb * sa, cb * ca],
    ]
}

#[cfg(test)]
mod tests;
