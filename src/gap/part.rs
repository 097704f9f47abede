//! Part-domain diagnosis: the measured deviations of a probed surface against the simulation's
//! predicted deviations; effects `setup_misalignment`, `thermal_drift`, `probe_pretravel`,
//! located in grid regions.
//!
//! Every part effect is linear in its parameters (for a fixed thermal time constant), so each is
//! fitted by SVD least squares (`numeric::lsq::truncated_svd`), truncated where the surface
//! cannot tell parameters apart (e.g. in-plane shifts of a flat plate).

use serde::Serialize;

use crate::gap::Error;
use crate::gap::effects::thermal_basis;
use crate::gap::motion::{GapStats, noise_sigma};
use crate::numeric::lsq::truncated_svd;

/// Part-domain effect names (openapi.yaml) and `none`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PartEffect {
    /// Nothing beats the noise.
    None,
    /// Small rigid-body shift and rotation of the part.
    SetupMisalignment,
    /// Deviation growing from zero at time 0 of the part.
    ThermalDrift,
    /// Deviation depending on the probe approach direction.
    ProbePretravel,
}

impl PartEffect {
    /// The library, fixed order.
    pub const LIBRARY: [PartEffect; 3] = [
        PartEffect::SetupMisalignment,
        PartEffect::ThermalDrift,
        PartEffect::ProbePretravel,
    ];

    /// The name in openapi.yaml.
    pub fn name(self) -> &'static str {
        match self {
            PartEffect::None => "none",
            PartEffect::SetupMisalignment => "setup_misalignment",
            PartEffect::ThermalDrift => "thermal_drift",
            PartEffect::ProbePretravel => "probe_pretravel",
        }
    }
}

/// One measured part on the nominal grid (`k = iv·nu + iu`); deviations in mm along the
/// outward normal, `time` in s, `approach` unit probe directions.
#[derive(Clone, Debug)]
pub struct PartBlock {
    /// Measured deviations, mm.
    pub measured: Vec<f64>,
    /// Simulated (predicted) deviations, mm.
    pub predicted: Vec<f64>,
    /// When each point was cut, s.
    pub time: Vec<f64>,
    /// Probe approach direction per point (unit).
    pub approach: Vec<[f64; 3]>,
}

/// The nominal surface grid.
#[derive(Clone, Debug)]
pub struct PartGrid {
    /// Points along u.
    pub nu: usize,
    /// Points along v.
    pub nv: usize,
    /// Nominal points, mm.
    pub points: Vec<[f64; 3]>,
    /// Outward unit normals.
    pub normals: Vec<[f64; 3]>,
}

/// A grid region `[u0, u1] × [v0, v1]` (inclusive) and its share of the squared gap.
#[derive(Clone, Debug, Serialize)]
pub struct Region {
    /// Inclusive u index range.
    pub u: [usize; 2],
    /// Inclusive v index range.
    pub v: [usize; 2],
    /// Part of Σ residual², 0..1.
    pub share: f64,
    /// "corner", "edge" or "interior" and where.
    pub label: String,
    /// The region's extent in machine coordinates: `[[x_min, x_max], [y_min, y_max],
    /// [z_min, z_max]]` over its grid points, mm.
    pub range_mm: [[f64; 2]; 3],
}

/// A fitted part effect.
#[derive(Clone, Debug)]
pub struct PartEffectResult {
    /// Which effect.
    pub effect: PartEffect,
    /// Named parameters (units in names).
    pub params: Vec<(String, f64)>,
    /// Held-out fraction of the squared gap removed (blocked CV).
    pub score: f64,
    coef: Vec<f64>,
    tau: f64,
}

/// The answer of a part diagnosis.
#[derive(Clone, Debug)]
pub struct PartDiagnosis {
    /// Measured vs predicted.
    pub gap_before: GapStats,
    /// Worst regions first.
    pub regions: Vec<Region>,
    /// Effects, best first.
    pub effects: Vec<PartEffectResult>,
    /// The effect found, or none.
    pub verdict: PartEffect,
    /// With the verdict's effect added.
    pub gap_after: GapStats,
    /// (predicted_before, predicted_after, rms_before, rms_after) on the validation part.
    pub validation: Option<(Vec<f64>, Vec<f64>, f64, f64)>,
}

fn centroid(points: &[[f64; 3]]) -> [f64; 3] {
    let n = points.len().max(1) as f64;
    let mut c = [0.0; 3];
    for p in points {
        for i in 0..3 {
            c[i] += p[i] / n;
        }
    }
    c
}

/// Design matrix columns of `effect` at point `k`: the deviation is `Σ_j coef_j · col_j`.
///
/// - misalignment: `δ = n·t + ω·((p − c) × n)` (small rigid motion about the centroid c);
/// - thermal: `δ = b(t)·(d·n)`, `b(t) = τ(1 − e^{−t/τ})` (or t), drift rate vector d;
/// - pretravel: `δ = (a·n)·P(a)`, `P = p₀ + p₁a_z² + (1 − a_z²)(p₂cos3θ + p₃sin3θ)` (the
///   three-lobed pretravel of a kinematic touch-trigger probe), θ the approach azimuth.
fn columns(
    effect: PartEffect,
    grid: &PartGrid,
    block: &PartBlock,
    c: [f64; 3],
    tau: f64,
    k: usize,
) -> Vec<f64> {
    let n = grid.normals[k];
    match effect {
        PartEffect::None => Vec::new(),
        PartEffect::SetupMisalignment => {
            let p = grid.points[k];
            let r = [p[0] - c[0], p[1] - c[1], p[2] - c[2]];
            let rxn = [
                r[1] * n[2] - r[2] * n[1],
                r[2] * n[0] - r[0] * n[2],
                r[0] * n[1] - r[1] * n[0],
            ];
            vec![n[0], n[1], n[2], rxn[0], rxn[1], rxn[2]]
        }
        PartEffect::ThermalDrift => {
            let b = thermal_basis(block.time[k], tau);
            vec![b * n[0], b * n[1], b * n[2]]
        }
        PartEffect::ProbePretravel => {
            let a = block.approach[k];
            let an = a[0] * n[0] + a[1] * n[1] + a[2] * n[2];
            let th = a[1].atan2(a[0]);
            let h = 1.0 - a[2] * a[2];
            vec![
                an,
                an * a[2] * a[2],
                an * h * (3.0 * th).cos(),
                an * h * (3.0 * th).sin(),
            ]
        }
    }
}

fn check(field: &str, grid: &PartGrid, b: &PartBlock) -> Result<(), Error> {
    let n = grid.nu * grid.nv;
    for (name, len) in [
        ("deviations", b.measured.len()),
        ("predicted", b.predicted.len()),
        ("time", b.time.len()),
        ("approach", b.approach.len()),
    ] {
        if len != n {
            return Err(Error::shape(
                &format!("{field}.{name}"),
                format!("needs one value per grid point ({n}), got {len}"),
            ));
        }
    }
    for (name, xs) in [
        ("deviations", &b.measured),
        ("predicted", &b.predicted),
        ("time", &b.time),
    ] {
        if let Some(index) = xs.iter().position(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                field: format!("{field}.{name}"),
                index,
            });
        }
    }
    if let Some(index) = b.approach.iter().position(|a| {
        a.iter().any(|v| !v.is_finite())
            || (a[0] * a[0] + a[1] * a[1] + a[2] * a[2] - 1.0).abs() > 1e-3
    }) {
        return Err(Error::shape(
            &format!("{field}.approach[{index}]"),
            "must be a finite unit vector [i, j, k]",
        ));
    }
    Ok(())
}

/// Diagnoses the part-domain gap (openapi.yaml `POST /v1/machines/{machine}/gap-diagnosis` (domain
/// `part`)).
///
/// Residual `r = measured − predicted`; each effect is fitted by least squares on 4 of 5
/// contiguous folds and scored on the fifth (`score = 1 − ΣSSE_eff/ΣSSE_none`); verdict = best
/// effect with score ≥ `min_score` and mean held-out improvement ≥ 0.1·σ̂² (σ̂ from second
/// differences along u), else none. Bad cases: on a flat plate a normal shift, a constant
/// pretravel and a fast-saturating drift are the same offset; the first-ranked wins.
pub fn diagnose_part(
    grid: &PartGrid,
    main: &PartBlock,
    validation: Option<&PartBlock>,
    min_score: f64,
) -> Result<PartDiagnosis, Error> {
    let n = grid.nu * grid.nv;
    if n < 10 || grid.points.len() != n || grid.normals.len() != n {
        return Err(Error::shape(
            "surface",
            "the surface grid needs at least 10 points with one normal each",
        ));
    }
    check("main", grid, main)?;
    if let Some(v) = validation {
        check("validation", grid, v)?;
    }
    let c = centroid(&grid.points);
    let r: Vec<f64> = main
        .measured
        .iter()
        .zip(&main.predicted)
        .map(|(m, p)| m - p)
        .collect();
    let stats = |res: &[f64]| GapStats {
        rms: (res.iter().map(|x| x * x).sum::<f64>() / res.len() as f64).sqrt(),
        max: res.iter().fold(0.0f64, |a, x| a.max(x.abs())),
    };
    let rows_u: Vec<Vec<f64>> = (0..grid.nv)
        .map(|iv| r[iv * grid.nu..(iv + 1) * grid.nu].to_vec())
        .collect();
    let noise = noise_sigma(&rows_u);
    let t_end = main.time.iter().fold(0.0f64, |a, &t| a.max(t)).max(1e-9);
    let taus: Vec<f64> = std::iter::once(f64::INFINITY)
        .chain([0.1, 0.3, 1.0, 3.0].iter().map(|m| m * t_end))
        .collect();
    let folds = 5;
    let fold_of = |i: usize| i * folds / n;
    let fit = |effect: PartEffect, w: &[f64]| -> (Vec<f64>, f64) {
        let cands: Vec<f64> = if effect == PartEffect::ThermalDrift {
            taus.clone()
        } else {
            vec![f64::INFINITY]
        };
        let mut best = (Vec::new(), f64::INFINITY, f64::INFINITY);
        for tau in cands {
            let rows: Vec<Vec<f64>> = (0..n)
                .map(|k| columns(effect, grid, main, c, tau, k))
                .collect();
            let coef = truncated_svd(&rows, &r, w);
            let loss: f64 = (0..n)
                .map(|k| w[k] * (r[k] - dot(&rows[k], &coef)).powi(2))
                .sum();
            if loss < best.1 {
                best = (coef, loss, tau);
            }
        }
        (best.0, best.2)
    };
    let mut effects: Vec<(PartEffectResult, f64)> = PartEffect::LIBRARY
        .iter()
        .map(|&effect| {
            let (mut held_eff, mut held_none) = (0.0, 0.0);
            for j in 0..folds {
                let w: Vec<f64> = (0..n)
                    .map(|i| if fold_of(i) == j { 0.0 } else { 1.0 })
                    .collect();
                let (coef, tau) = fit(effect, &w);
                for k in (0..n).filter(|&k| fold_of(k) == j) {
                    held_eff +=
                        (r[k] - dot(&columns(effect, grid, main, c, tau, k), &coef)).powi(2);
                    held_none += r[k] * r[k];
                }
            }
            let (coef, tau) = fit(effect, &vec![1.0; n]);
            let score = if held_none > 0.0 {
                1.0 - held_eff / held_none
            } else {
                0.0
            };
            let params = part_params(effect, &coef, tau, c, t_end);
            (
                PartEffectResult {
                    effect,
                    params,
                    score,
                    coef,
                    tau,
                },
                (held_none - held_eff) / n as f64,
            )
        })
        .collect();
    effects.sort_by(|a, b| b.0.score.total_cmp(&a.0.score));
    let chosen = effects
        .first()
        .filter(|(e, gain)| e.score >= min_score && *gain >= 0.1 * noise * noise)
        .map(|(e, _)| e.clone());
    let add = |block: &PartBlock| -> Vec<f64> {
        (0..n)
            .map(|k| {
                block.predicted[k]
                    + chosen.as_ref().map_or(0.0, |e| {
                        dot(&columns(e.effect, grid, block, c, e.tau, k), &e.coef)
                    })
            })
            .collect()
    };
    let after = add(main);
    let res_after: Vec<f64> = main
        .measured
        .iter()
        .zip(&after)
        .map(|(m, p)| m - p)
        .collect();
    let validation = validation.map(|v| {
        let pa = add(v);
        let rb: Vec<f64> = v
            .measured
            .iter()
            .zip(&v.predicted)
            .map(|(m, p)| m - p)
            .collect();
        let ra: Vec<f64> = v.measured.iter().zip(&pa).map(|(m, p)| m - p).collect();
        (v.predicted.clone(), pa, stats(&rb).rms, stats(&ra).rms)
    });
    Ok(PartDiagnosis {
        gap_before: stats(&r),
        regions: regions(grid, &r),
        verdict: chosen.as_ref().map_or(PartEffect::None, |e| e.effect),
        gap_after: stats(&res_after),
        effects: effects.into_iter().map(|e| e.0).collect(),
        validation,
    })
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn part_params(
    effect: PartEffect,
    coef: &[f64],
    tau: f64,
    c: [f64; 3],
    t_end: f64,
) -> Vec<(String, f64)> {
    let named = |names: &[&str]| {
        names
            .iter()
            .zip(coef)
            .map(|(n, v)| (n.to_string(), *v))
            .collect::<Vec<_>>()
    };
    match effect {
        PartEffect::None => Vec::new(),
        PartEffect::SetupMisalignment => {
            let mut p = named(&["tx_mm", "ty_mm", "tz_mm", "rx_rad", "ry_rad", "rz_rad"]);
            p.extend([
                ("centroid_x_mm".to_string(), c[0]),
                ("centroid_y_mm".to_string(), c[1]),
                ("centroid_z_mm".to_string(), c[2]),
            ]);
            p
        }
        PartEffect::ThermalDrift => {
            let mut p = named(&["x_rate_mm_s", "y_rate_mm_s", "z_rate_mm_s"]);
            let b = thermal_basis(t_end, tau);
            p.extend(
                coef.iter()
                    .zip(["x", "y", "z"])
                    .map(|(v, a)| (format!("{a}_drift_at_end_mm"), v * b)),
            );
            if tau.is_finite() {
                p.push(("tau_s".to_string(), tau));
            }
            p
        }
        PartEffect::ProbePretravel => named(&[
            "pretravel_mm",
            "pretravel_z2_mm",
            "lobe_cos3_mm",
            "lobe_sin3_mm",
        ]),
    }
}

/// Splits the grid into up to 4×4 regions and ranks them by share of Σr²; each region gives
/// its extent in mm beside its grid indices.
fn regions(grid: &PartGrid, r: &[f64]) -> Vec<Region> {
    let total: f64 = r.iter().map(|x| x * x).sum();
    let bu = grid.nu.min(4);
    let bv = grid.nv.min(4);
    let mut out = Vec::new();
    for jv in 0..bv {
        for ju in 0..bu {
            let (u0, u1) = (ju * grid.nu / bu, (ju + 1) * grid.nu / bu - 1);
            let (v0, v1) = (jv * grid.nv / bv, (jv + 1) * grid.nv / bv - 1);
            let mut s = 0.0;
            let mut range_mm = [[f64::INFINITY, f64::NEG_INFINITY]; 3];
            for iv in v0..=v1 {
                for iu in u0..=u1 {
                    s += r[iv * grid.nu + iu].powi(2);
                    if let Some(p) = grid.points.get(iv * grid.nu + iu) {
                        for (c, rg) in range_mm.iter_mut().enumerate() {
                            rg[0] = rg[0].min(p[c]);
                            rg[1] = rg[1].max(p[c]);
                        }
                    }
                }
            }
            let edge_u = ju == 0 || ju + 1 == bu;
            let edge_v = jv == 0 || jv + 1 == bv;
            let kind = match (edge_u && bu > 1, edge_v && bv > 1) {
                (true, true) => "corner",
                (true, false) | (false, true) => "edge",
                _ => "interior",
            };
            let side = |j: usize, b: usize, lo: &str, hi: &str| {
                if j == 0 {
                    lo.to_string()
                } else if j + 1 == b {
                    hi.to_string()
                } else {
                    "mid".to_string()
                }
            };
            out.push(Region {
                u: [u0, u1],
                v: [v0, v1],
                share: if total > 0.0 { s / total } else { 0.0 },
                label: format!(
                    "{kind} ({} u, {} v)",
                    side(ju, bu, "low", "high"),
                    side(jv, bv, "low", "high")
                ),
                range_mm,
            });
        }
    }
    out.sort_by(|a, b| b.share.total_cmp(&a.share));
    out
}

#[cfg(test)]
mod tests;
