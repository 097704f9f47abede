//! The part-domain self-check: random curved surfaces probed with a withheld effect
//! (setup misalignment, thermal drift, probe pretravel) or none, diagnosed blind.

use rand::{Rng, RngExt, SeedableRng};

use crate::gap::Error;
use crate::gap::part::{PartBlock, PartEffect, PartGrid, diagnose_part};

/// One diagnosed part case.
#[derive(Clone, Debug)]
pub struct PartCase {
    /// Truth effect.
    pub truth: PartEffect,
    /// Verdict.
    pub verdict: PartEffect,
    /// `1 − rms_after/rms_before` on the validation part.
    pub shrink: f64,
}

/// Summary of a part self-check.
#[derive(Clone, Debug)]
pub struct PartReport {
    /// Every case.
    pub cases: Vec<PartCase>,
    /// Correct verdicts / cases.
    pub accuracy: f64,
    /// Median validation shrink over cases with an effect.
    pub median_shrink: f64,
    /// Share of "none" cases answered with an effect.
    pub false_alarm_rate: f64,
}

fn unit(v: [f64; 3]) -> [f64; 3] {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [v[0] / l, v[1] / l, v[2] / l]
}

/// A random quadric patch `z = a·x² + b·y² + c·x·y` in machine coordinates.
fn surface(rng: &mut impl Rng) -> PartGrid {
    let (nu, nv) = (rng.random_range(15..30), rng.random_range(12..25));
    let (wx, wy) = (rng.random_range(30.0..60.0), rng.random_range(25.0..50.0));
    let (a, b, c) = (
        rng.random_range(-1.0..1.0) / 150.0,
        rng.random_range(-1.0..1.0) / 150.0,
        rng.random_range(-1.0..1.0) / 300.0,
    );
    let o = [
        rng.random_range(50.0..300.0),
        rng.random_range(50.0..250.0),
        rng.random_range(-150.0..0.0),
    ];
    let (mut points, mut normals) = (Vec::new(), Vec::new());
    for iv in 0..nv {
        for iu in 0..nu {
            let x = -wx + 2.0 * wx * iu as f64 / (nu - 1) as f64;
            let y = -wy + 2.0 * wy * iv as f64 / (nv - 1) as f64;
            points.push([o[0] + x, o[1] + y, o[2] + a * x * x + b * y * y + c * x * y]);
            normals.push(unit([-(2.0 * a * x + c * y), -(2.0 * b * y + c * x), 1.0]));
        }
    }
    PartGrid {
        nu,
        nv,
        points,
        normals,
    }
}

/// Runs `cases` part cases (truth cycling none, misalignment, thermal, pretravel) from `seed`.
pub fn run_part(cases: usize, seed: u64) -> Result<PartReport, Error> {
    let kinds = [
        PartEffect::None,
        PartEffect::SetupMisalignment,
        PartEffect::ThermalDrift,
        PartEffect::ProbePretravel,
    ];
    let mut out = Vec::new();
    for i in 0..cases {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed + i as u64);
        let truth = kinds[i % 4];
        let grid = surface(&mut rng);
        let n = grid.nu * grid.nv;
        let c = {
            let mut c = [0.0; 3];
            grid.points
                .iter()
                .for_each(|p| (0..3).for_each(|k| c[k] += p[k] / n as f64));
            c
        };
        // probe tilted 20–60° off the normal with a random azimuth (5-axis or side probing)
        let approach: Vec<[f64; 3]> = grid
            .normals
            .iter()
            .map(|nn| {
                let tilt = rng.random_range(0.35..1.7);
                let az = rng.random_range(0.0..std::f64::consts::TAU);
                unit([-nn[0] + tilt * az.cos(), -nn[1] + tilt * az.sin(), -nn[2]])
            })
            .collect();
        let time: Vec<f64> = (0..n).map(|k| k as f64 * 2.0).collect();
        let sign = |rng: &mut rand::rngs::StdRng| if rng.random_bool(0.5) { 1.0 } else { -1.0 };
        let t = [0, 1, 2].map(|_| sign(&mut rng) * rng.random_range(0.002..0.015));
        let w = [0, 1, 2].map(|_| sign(&mut rng) * rng.random_range(10e-6..100e-6));
        let tau = time[n - 1] * rng.random_range(0.3..3.0);
        let drift_dir = unit([
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        ]);
        let drift = rng.random_range(0.003..0.020) / -(-time[n - 1] / tau).exp_m1();
        let (p0, p_h, lobe, phase) = (
            rng.random_range(0.001..0.004),
            rng.random_range(0.0..0.003),
            rng.random_range(0.001..0.003),
            rng.random_range(0.0..6.3),
        );
        let sigma = rng.random_range(0.0002..0.001);
        let normal = rand_distr::Normal::new(0.0, sigma).expect("sigma > 0");
        let predicted: Vec<f64> = grid
            .points
            .iter()
            .map(|p| 0.005 * ((p[0] - c[0]) / 15.0).sin())
            .collect();
        let part = |rng: &mut rand::rngs::StdRng| -> PartBlock {
            let measured = (0..n)
                .map(|k| {
                    let (p, nn, a) = (grid.points[k], grid.normals[k], approach[k]);
                    let extra = match truth {
                        PartEffect::SetupMisalignment => {
                            let r = [p[0] - c[0], p[1] - c[1], p[2] - c[2]];
                            let d = [
                                t[0] + w[1] * r[2] - w[2] * r[1],
                                t[1] + w[2] * r[0] - w[0] * r[2],
                                t[2] + w[0] * r[1] - w[1] * r[0],
                            ];
                            d[0] * nn[0] + d[1] * nn[1] + d[2] * nn[2]
                        }
                        PartEffect::ThermalDrift => {
                            let g = drift * (1.0 - (-time[k] / tau).exp());
                            g * (drift_dir[0] * nn[0] + drift_dir[1] * nn[1] + drift_dir[2] * nn[2])
                        }
                        PartEffect::ProbePretravel => {
                            let h = 1.0 - a[2] * a[2];
                            let pre =
                                p0 + p_h * h + lobe * h * (3.0 * a[1].atan2(a[0]) + phase).cos();
                            pre * (a[0] * nn[0] + a[1] * nn[1] + a[2] * nn[2])
                        }
                        PartEffect::None => 0.0,
                    };
                    predicted[k] + extra + rng.sample(normal)
                })
                .collect();
            PartBlock {
                measured,
                predicted: predicted.clone(),
                time: time.clone(),
                approach: approach.clone(),
            }
        };
        let main = part(&mut rng);
        let val = part(&mut rng);
        let d = diagnose_part(&grid, &main, Some(&val), 0.05)?;
        let (_, _, rb, ra) = d.validation.expect("validation given");
        out.push(PartCase {
            truth,
            verdict: d.verdict,
            shrink: if rb > 0.0 { 1.0 - ra / rb } else { 0.0 },
        });
    }
    let correct = out.iter().filter(|c| c.truth == c.verdict).count();
    let mut shrinks: Vec<f64> = out
        .iter()
        .filter(|c| c.truth != PartEffect::None)
        .map(|c| c.shrink)
        .collect();
    shrinks.sort_by(f64::total_cmp);
    let nones: Vec<&PartCase> = out.iter().filter(|c| c.truth == PartEffect::None).collect();
    Ok(PartReport {
        accuracy: correct as f64 / out.len().max(1) as f64,
        median_shrink: shrinks.get(shrinks.len() / 2).copied().unwrap_or(0.0),
        false_alarm_rate: nones
            .iter()
            .filter(|c| c.verdict != PartEffect::None)
            .count() as f64
            / nones.len().max(1) as f64,
        cases: out,
    })
}

impl PartReport {
    /// Confusion matrix (rows truth, columns verdict) and summary, as text.
    pub fn render(&self) -> String {
        let kinds = [
            PartEffect::None,
            PartEffect::SetupMisalignment,
            PartEffect::ThermalDrift,
            PartEffect::ProbePretravel,
        ];
        let mut s = format!("{:<20}", "part truth \\ verdict");
        for k in kinds {
            s += &format!("{:>20}", k.name());
        }
        s += "\n";
        for t in kinds {
            s += &format!("{:<20}", t.name());
            for v in kinds {
                s += &format!(
                    "{:>20}",
                    self.cases
                        .iter()
                        .filter(|c| c.truth == t && c.verdict == v)
                        .count()
                );
            }
            s += "\n";
        }
        s += &format!(
            "part cases {}  accuracy {:.1} %  median validation shrink {:.1} %  false alarms {:.1} %\n",
            self.cases.len(),
            100.0 * self.accuracy,
            100.0 * self.median_shrink,
            100.0 * self.false_alarm_rate
        );
        s
    }
}

#[cfg(test)]
mod tests;
