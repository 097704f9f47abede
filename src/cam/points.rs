//! The points form for posts that compensate their own CL points: p − e(p) for each point
//! (mm, machine frame), from JSON `[[x, y, z], ...]` or CSV with a header `x_mm,y_mm,z_mm`
//! (also `x,y,z`; extra columns ignored, as the volumetric map's CSV upload reads them).

use super::error::Error;
use super::field::ErrorField;
use crate::numeric::vec3::{norm, sub};

/// Compensated points with what the map said about them.
#[derive(Clone, Debug, PartialEq)]
pub struct CompensatedPoints {
    /// p − e(p) per point, mm.
    pub points: Vec<[f64; 3]>,
    /// True where p lies outside the map's box (compensated with the nearest point's error).
    pub out_of_box: Vec<bool>,
    /// Largest |e(p)|, mm.
    pub max_shift_mm: f64,
}

/// Volumetric pre-compensation of CL points (mm, machine frame): q = p − e(p), e from
/// `field` (Xiang et al. 2019 §2, the map inverted to first order). Errors: no points, a
/// non-finite coordinate.
pub fn compensate_points(
    field: &dyn ErrorField,
    points: &[[f64; 3]],
) -> Result<CompensatedPoints, Error> {
    if points.is_empty() {
        return Err(Error::Empty { field: "points" });
    }
    if let Some(index) = points.iter().position(|p| p.iter().any(|v| !v.is_finite())) {
        return Err(Error::NonFinite {
            field: "points",
            index,
        });
    }
    let mut max_shift_mm: f64 = 0.0;
    let mut out = Vec::with_capacity(points.len());
    for (i, &p) in points.iter().enumerate() {
        if i % 4096 == 0 {
            crate::numeric::stop::check();
        }
        let e = field.error_at(p);
        max_shift_mm = max_shift_mm.max(norm(e));
        out.push(sub(p, e));
    }
    Ok(CompensatedPoints {
        points: out,
        out_of_box: points.iter().map(|&p| !field.contains(p)).collect(),
        max_shift_mm,
    })
}

/// Reads CSV points: a header naming `x`, `y`, `z` (any order, `_mm` suffix allowed, extra
/// columns ignored), then one row per point, mm.
pub fn points_from_csv(text: &str) -> Result<Vec<[f64; 3]>, Error> {
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let (_, header) = lines.next().ok_or(Error::Csv {
        line: 1,
        reason: "empty body: send a header row x_mm,y_mm,z_mm and one row per point".into(),
    })?;
    let names: Vec<String> = header
        .split(',')
        .map(|h| {
            let h = h.trim().trim_matches('"').to_ascii_lowercase();
            h.strip_suffix("_mm").map(str::to_string).unwrap_or(h)
        })
        .collect();
    let mut col = [0usize; 3];
    for (c, w) in ["x", "y", "z"].iter().enumerate() {
        col[c] = names
            .iter()
            .position(|n| n == w)
            .ok_or_else(|| Error::Csv {
                line: 1,
                reason: format!("header has no column '{w}': the header must name x_mm,y_mm,z_mm"),
            })?;
    }
    let mut out = Vec::new();
    for (i, line) in lines {
        let cells: Vec<&str> = line.split(',').map(str::trim).collect();
        if cells.len() != names.len() {
            return Err(Error::Csv {
                line: i + 1,
                reason: format!("{} cells but the header has {}", cells.len(), names.len()),
            });
        }
        let mut p = [0.0; 3];
        for (c, v) in p.iter_mut().enumerate() {
            let cell = cells[col[c]];
            *v = cell
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| Error::Csv {
                    line: i + 1,
                    reason: format!(
                        "'{cell}' is not a finite number in column {}",
                        ["x_mm", "y_mm", "z_mm"][c]
                    ),
                })?;
        }
        out.push(p);
    }
    if out.is_empty() {
        return Err(Error::Csv {
            line: 2,
            reason: "no data rows after the header".into(),
        });
    }
    Ok(out)
}

/// CSV of points (mm) with the header `x_mm,y_mm,z_mm`, 6 decimals (1 nm).
pub fn points_to_csv(points: &[[f64; 3]]) -> String {
    let mut s = String::with_capacity(32 * points.len() + 16);
    s.push_str("x_mm,y_mm,z_mm\n");
    for p in points {
        s.push_str(&format!("{:.6},{:.6},{:.6}\n", p[0], p[1], p[2]));
    }
    s
}
