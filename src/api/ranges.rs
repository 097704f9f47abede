//! Physical ranges of the numbers the API stores or computes on, checked at the door
//! (issue 13): a value outside them is refused with 400 naming the field, the value and
//! the range allowed, so a physically impossible number is never stored.
//!
//! Coordinates are machine or part coordinates in mm: [`COORD_LIMIT_MM`] (100 m) is beyond
//! the travel of the largest gantry mills. A ball-end tool radius is in (0, 100] mm. Probe
//! deviations are bounded by the `--max-deviation-mm` setting, measured points also by their
//! tangential distance from the nominal they are paired with (`--max-tangential-mm`, and
//! never more than half the local grid spacing): points are paired by order, so a reversed
//! or shifted upload shows as points far from their nominals along the surface.

use super::error::{ApiError, ApiResult};
use crate::config::Config;

/// Largest |coordinate| accepted, mm (100 m).
pub const COORD_LIMIT_MM: f64 = 100_000.0;
/// Largest ball-end tool radius accepted, mm.
pub const TOOL_RADIUS_MAX_MM: f64 = 100.0;
/// Largest |component| of a volumetric positioning error accepted, mm. A machine tool's
/// volumetric error is micrometres to tenths of a millimetre; 10 mm is a wrong unit
/// (µm sent as mm) or a wrong sign convention, not an error to compensate.
pub const VOLUMETRIC_ERROR_LIMIT_MM: f64 = 10.0;
/// Points named in a refusal before "and N more".
const SHOWN: usize = 5;

/// Plausibility limits of measured values, from the settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// Largest |probe deviation|, mm (`--max-deviation-mm`).
    pub max_deviation_mm: f64,
    /// Largest tangential distance of a measured point from its nominal, mm
    /// (`--max-tangential-mm`).
    pub max_tangential_mm: f64,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_deviation_mm: crate::config::DEFAULT_MAX_DEVIATION_MM,
            max_tangential_mm: crate::config::DEFAULT_MAX_TANGENTIAL_MM,
        }
    }
}

impl Limits {
    /// The limits a configuration sets; a non-positive or non-finite one is refused.
    pub fn from_config(config: &Config) -> anyhow::Result<Limits> {
        for (flag, v) in [
            ("--max-deviation-mm", config.max_deviation_mm),
            ("--max-tangential-mm", config.max_tangential_mm),
        ] {
            if !(v.is_finite() && v > 0.0 && v <= COORD_LIMIT_MM) {
                anyhow::bail!("{flag} must be a positive number of mm, got {v}");
            }
        }
        Ok(Limits {
            max_deviation_mm: config.max_deviation_mm,
            max_tangential_mm: config.max_tangential_mm,
        })
    }

    /// Refuses a deviation (mm) beyond ±`max_deviation_mm`, naming `field[k]` and the setting.
    pub fn check_deviations(&self, field: &str, deviations: &[f64]) -> ApiResult<()> {
        let limit = self.max_deviation_mm;
        let bad: Vec<usize> = (0..deviations.len())
            .filter(|&k| deviations[k].is_nan() || deviations[k].abs() > limit)
            .collect();
        let Some(&first) = bad.first() else {
            return Ok(());
        };
        Err(ApiError::bad_request(format!(
            "{field}[{first}] is {} mm off the nominal ({} point(s) in all: {}); a probe \
             deviation must lie within ±{limit} mm (the server's plausibility limit, \
             --max-deviation-mm). Check the units (mm), the datum and the surface id, or \
             re-probe",
            deviations[first],
            bad.len(),
            list(&bad, |k| format!("{k}: {:+.4}", deviations[k])),
        )))
    }

    /// Deviations `(measured − nominal)·n` (mm) of points paired by order with the nominals,
    /// refusing (422) points farther than the tangential tolerance from their nominal along
    /// the surface. The tolerance at point k is min(`max_tangential_mm`, ½ of the distance
    /// to its nearest grid neighbour): beyond half a spacing the point is closer to another
    /// nominal than to its own. The sentence says whether the points look reversed or
    /// shifted. Deviations beyond `max_deviation_mm` are refused as in [`Self::check_deviations`].
    pub fn pair_points(
        &self,
        measured: &[[f64; 3]],
        nominal: &[[f64; 3]],
        normals: &[[f64; 3]],
        nu: usize,
    ) -> ApiResult<Vec<f64>> {
        let tol = tolerances(nominal, nu, self.max_tangential_mm);
        let mut deviations = Vec::with_capacity(measured.len());
        let mut bad = Vec::new();
        for k in 0..measured.len() {
            let (along, tangential) = split(measured[k], nominal[k], normals[k]);
            deviations.push(along);
            if tangential.is_nan() || tangential > tol[k] {
                bad.push((k, tangential));
            }
        }
        if let Some(&(first, t)) = bad.first() {
            let cause = likely_cause(measured, nominal, normals, nu, &tol);
            return Err(ApiError::unprocessable(format!(
                "points[{first}] lies {t:.3} mm from its nominal along the surface, more than \
                 the {:.3} mm allowed there (--max-tangential-mm, at most half the grid \
                 spacing); {} point(s) in all ({}). Points are paired with the surface's \
                 nominal points by order (u fastest, then v): {cause}",
                tol[first],
                bad.len(),
                list(&(0..bad.len()).collect::<Vec<_>>(), |i| format!(
                    "{}: {:.3} mm",
                    bad[i].0, bad[i].1
                )),
            )));
        }
        self.check_deviations("points", &deviations)?;
        Ok(deviations)
    }
}

/// (normal component, tangential distance) of `p − q` for the unit normal `n`, mm.
fn split(p: [f64; 3], q: [f64; 3], n: [f64; 3]) -> (f64, f64) {
    let d = [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
    let along = d[0] * n[0] + d[1] * n[1] + d[2] * n[2];
    let t = [
        d[0] - along * n[0],
        d[1] - along * n[1],
        d[2] - along * n[2],
    ];
    (along, (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt())
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Tangential tolerance per grid point: min(`cap`, ½ × distance to the nearest grid
/// neighbour); `cap` alone for a single point.
fn tolerances(nominal: &[[f64; 3]], nu: usize, cap: f64) -> Vec<f64> {
    let n = nominal.len();
    (0..n)
        .map(|k| {
            let (iu, iv) = (k % nu.max(1), k / nu.max(1));
            let mut near = f64::INFINITY;
            let mut consider = |j: usize| {
                let d = dist(nominal[k], nominal[j]);
                if d > 0.0 {
                    near = near.min(d);
                }
            };
            if iu > 0 {
                consider(k - 1);
            }
            if iu + 1 < nu && k + 1 < n {
                consider(k + 1);
            }
            if iv > 0 {
                consider(k - nu);
            }
            if k + nu < n {
                consider(k + nu);
            }
            cap.min(0.5 * near)
        })
        .collect()
}

/// Which pairing the points fit: reversed order, or shifted by one point or one row.
fn likely_cause(
    measured: &[[f64; 3]],
    nominal: &[[f64; 3]],
    normals: &[[f64; 3]],
    nu: usize,
    tol: &[f64],
) -> String {
    let n = measured.len() as isize;
    let fits = |map: &dyn Fn(isize) -> isize| {
        let (mut ok, mut seen) = (0usize, 0usize);
        for k in 0..n {
            let j = map(k);
            if (0..n).contains(&j) {
                seen += 1;
                let j = j as usize;
                let (_, t) = split(measured[k as usize], nominal[j], normals[j]);
                if t <= tol[j].max(tol[k as usize]) {
                    ok += 1;
                }
            }
        }
        seen > 0 && ok * 10 >= seen * 9
    };
    if fits(&|k| n - 1 - k) {
        return "they fit the nominals in reverse order: send them in the surface's order".into();
    }
    let row = nu as isize;
    for (s, what) in [(1, "point"), (-1, "point"), (row, "row"), (-row, "row")] {
        if s.abs() < n && fits(&|k| k + s) {
            let (sign, fix) = if s > 0 {
                (
                    "+",
                    "the first nominal has no point: one is missing at the start",
                )
            } else {
                ("-", "one extra point (or row) comes first")
            };
            return format!(
                "they fit the nominals shifted by one {what} (point k pairs with nominal k {sign}                  {}): {fix}; send exactly one point per nominal, in order",
                s.abs()
            );
        }
    }
    "check the order (u fastest, then v), that the points belong to this surface and that \
     they are in its coordinate frame"
        .into()
}

/// `k: …` for the first [`SHOWN`] indices, then "and N more".
fn list(indices: &[usize], show: impl Fn(usize) -> String) -> String {
    let mut parts: Vec<String> = indices.iter().take(SHOWN).map(|&k| show(k)).collect();
    if indices.len() > SHOWN {
        parts.push(format!("and {} more", indices.len() - SHOWN));
    }
    parts.join(", ")
}

/// Refuses a finite coordinate outside ±[`COORD_LIMIT_MM`], naming `field[i]` (non-finite
/// ones are the finiteness checks' to name).
pub fn check_coords(field: &str, points: &[[f64; 3]]) -> ApiResult<()> {
    match points
        .iter()
        .position(|p| p.iter().any(|c| c.is_finite() && c.abs() > COORD_LIMIT_MM))
    {
        None => Ok(()),
        Some(i) => Err(ApiError::bad_request(format!(
            "{field}[{i}] = {:?} is outside the physical range: every coordinate must lie \
             within ±{COORD_LIMIT_MM} mm (100 m); check the units (mm)",
            points[i]
        ))),
    }
}

/// Refuses a finite length outside ±[`COORD_LIMIT_MM`] (a position, reading or target in
/// mm), naming `field[i]`.
pub fn check_lengths<'a>(field: &str, values: impl IntoIterator<Item = &'a f64>) -> ApiResult<()> {
    check_within_coord_limit(field, values, "positions")
}

/// Refuses a finite machining-error sample outside ±[`COORD_LIMIT_MM`] (the stateless
/// `POST /v1/decompose` signal, mm), naming `field[i]`: beyond 100 m the sample is a wrong
/// unit, and squares of such numbers overflow the decomposition's energy sums.
pub fn check_signal_mm(field: &str, values: &[f64]) -> ApiResult<()> {
    check_within_coord_limit(field, values, "a machining error's samples")
}

/// The check behind [`check_lengths`] and [`check_signal_mm`]; `what` names the values in
/// the sentence.
fn check_within_coord_limit<'a>(
    field: &str,
    values: impl IntoIterator<Item = &'a f64>,
    what: &str,
) -> ApiResult<()> {
    match values
        .into_iter()
        .enumerate()
        .find(|(_, v)| v.is_finite() && v.abs() > COORD_LIMIT_MM)
    {
        None => Ok(()),
        Some((i, v)) => Err(ApiError::bad_request(format!(
            "{field}[{i}] = {v:e} is outside the physical range: {what} must lie within \
             ±{COORD_LIMIT_MM} mm (100 m); check the units (mm)"
        ))),
    }
}

/// Refuses a tool radius outside (0, [`TOOL_RADIUS_MAX_MM`]] mm, naming `field`.
pub fn check_tool_radius(field: &str, r: f64) -> ApiResult<()> {
    if r.is_finite() && r > 0.0 && r <= TOOL_RADIUS_MAX_MM {
        Ok(())
    } else {
        Err(ApiError::bad_request(format!(
            "{field} is {r}; a ball-end tool radius must be a number of mm in \
             (0, {TOOL_RADIUS_MAX_MM}]"
        )))
    }
}

/// Refuses a finite volumetric error component beyond ±[`VOLUMETRIC_ERROR_LIMIT_MM`],
/// naming `field[i]`.
pub fn check_volumetric_errors(field: &str, errors: &[[f64; 3]]) -> ApiResult<()> {
    match errors.iter().position(|e| {
        e.iter()
            .any(|c| c.is_finite() && c.abs() > VOLUMETRIC_ERROR_LIMIT_MM)
    }) {
        None => Ok(()),
        Some(i) => Err(ApiError::bad_request(format!(
            "{field}[{i}] = {:?} is outside the physical range: a positioning error must lie \
             within ±{VOLUMETRIC_ERROR_LIMIT_MM} mm per axis; check the units (mm, not µm)",
            errors[i]
        ))),
    }
}

#[cfg(test)]
mod tests;
