//! Decoding probe-measurement uploads: JSON (`points` or `deviations`) and CSV (header
//! `x,y,z` or `deviation`, optionally after a leading point-id column; comma, semicolon or
//! tab separated; with semicolons a decimal comma is accepted). Errors name the line.
//! Hand-written: the layouts are few and line-numbered messages matter more than generality.

use serde::Deserialize;

use super::error::{ApiError, ApiResult};
use super::extract::{check_finite, check_points, decode_json};

/// What a probe upload carries, in nominal grid order.
#[derive(Clone, Debug, PartialEq)]
pub enum ProbeData {
    /// Measured points, mm.
    Points(Vec<[f64; 3]>),
    /// Deviations along the outward normal, mm.
    Deviations(Vec<f64>),
}

impl ProbeData {
    /// Number of probed points.
    pub fn len(&self) -> usize {
        match self {
            ProbeData::Points(p) => p.len(),
            ProbeData::Deviations(d) => d.len(),
        }
    }

    /// True when nothing was sent.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Name of the field for messages.
    pub fn field(&self) -> &'static str {
        match self {
            ProbeData::Points(_) => "points",
            ProbeData::Deviations(_) => "deviations",
        }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct JsonUpload {
    points: Option<Vec<[f64; 3]>>,
    deviations: Option<Vec<f64>>,
    id: Option<String>,
}

/// Parses a JSON upload `{"points": [[x,y,z]...]}` or `{"deviations": [...]}` (optional
/// `"id"`). Returns the data and the client-chosen id.
pub fn parse_json_upload(body: &[u8]) -> ApiResult<(ProbeData, Option<String>)> {
    let up: JsonUpload = decode_json(body)?;
    let data = match (up.points, up.deviations) {
        (Some(_), Some(_)) => {
            return Err(ApiError::bad_request(
                "send either points or deviations, not both",
            ));
        }
        (None, None) => {
            return Err(ApiError::bad_request(
                "send {\"points\": [[x,y,z], ...]} (measured points, mm, in nominal order) \
                 or {\"deviations\": [mm, ...]}",
            ));
        }
        (Some(p), None) => {
            check_points("points", &p)?;
            ProbeData::Points(p)
        }
        (None, Some(d)) => {
            if d.is_empty() {
                return Err(ApiError::bad_request(
                    "deviations is empty; send one deviation (mm) per grid point",
                ));
            }
            check_finite("deviations", &d)?;
            ProbeData::Deviations(d)
        }
    };
    Ok((data, up.id))
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Layout {
    Xyz,
    Deviation,
}

fn normalize_header(name: &str) -> String {
    let mut s = name.trim().trim_matches('"').trim().to_ascii_lowercase();
    for suffix in ["[mm]", "(mm)", "_mm", " mm"] {
        if let Some(stripped) = s.strip_suffix(suffix) {
            s = stripped.trim().to_string();
        }
    }
    if s == "dev" {
        s = "deviation".into();
    }
    s
}

fn header_error(line_no: usize, header: &str) -> ApiError {
    ApiError::bad_request(format!(
        "CSV line {line_no}: header '{header}' is not a known layout; use one of \
         'x,y,z', 'deviation', 'ID,x,y,z' or 'ID,deviation' (comma, semicolon or tab separated, units mm)"
    ))
}

/// Parses a CSV upload. See the module docs for the accepted layouts.
pub fn parse_csv_upload(body: &[u8]) -> ApiResult<ProbeData> {
    let text = std::str::from_utf8(body).map_err(|e| {
        ApiError::bad_request(format!(
            "the CSV is not UTF-8 text (byte {}); export it as UTF-8",
            e.valid_up_to()
        ))
    })?;
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut lines = text
        .split('\n')
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim_end_matches('\r')))
        .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    let (header_no, header) = lines.next().ok_or_else(|| {
        ApiError::bad_request(
            "the CSV is empty; send a header row (x,y,z or deviation) and one row per point",
        )
    })?;
    let sep = if header.contains(';') {
        ';'
    } else if header.contains(',') {
        ','
    } else if header.contains('\t') {
        '\t'
    } else {
        ','
    };
    let names: Vec<String> = header.split(sep).map(normalize_header).collect();
    let known = |n: &str| matches!(n, "x" | "y" | "z" | "deviation");
    let (has_id, rest) = match names.first() {
        Some(first) if !known(first) && !first.is_empty() => (true, &names[1..]),
        _ => (false, &names[..]),
    };
    let layout = match rest
        .iter()
        .map(String::as_str)
        .collect::<Vec<_>>()
        .as_slice()
    {
        ["x", "y", "z"] => Layout::Xyz,
        ["deviation"] => Layout::Deviation,
        _ => return Err(header_error(header_no, header)),
    };
    let width = names.len();
    let first_value = usize::from(has_id);
    let decimal_comma = sep == ';';
    let mut points = Vec::new();
    let mut devs = Vec::new();
    let mut values = [0.0_f64; 3];
    for (line_no, line) in lines {
        let mut count = 0;
        for (col, field) in line.split(sep).enumerate() {
            count += 1;
            if col < first_value || col >= width {
                continue;
            }
            let raw = field.trim().trim_matches('"').trim();
            let parsed = if decimal_comma && raw.contains(',') {
                raw.replace(',', ".").parse::<f64>()
            } else {
                raw.parse::<f64>()
            };
            let v = match parsed {
                Ok(v) if v.is_finite() => v,
                _ => {
                    return Err(ApiError::bad_request(format!(
                        "CSV line {line_no}, column '{}': '{raw}' is not a finite number (mm)",
                        names[col]
                    )));
                }
            };
            values[col - first_value] = v;
        }
        if count != width {
            return Err(ApiError::bad_request(format!(
                "CSV line {line_no}: expected {width} fields ({}), found {count}",
                names.join(&sep.to_string())
            )));
        }
        match layout {
            Layout::Xyz => points.push(values),
            Layout::Deviation => devs.push(values[0]),
        }
    }
    match layout {
        Layout::Xyz if points.is_empty() => Err(ApiError::bad_request(
            "the CSV has a header but no data rows; send one row per probed point",
        )),
        Layout::Deviation if devs.is_empty() => Err(ApiError::bad_request(
            "the CSV has a header but no data rows; send one row per probed point",
        )),
        Layout::Xyz => Ok(ProbeData::Points(points)),
        Layout::Deviation => Ok(ProbeData::Deviations(devs)),
    }
}

/// Deviations `(measured − nominal) · n` (mm) of measured points from nominal points with
/// outward unit normals `n`. Positive where material was left. Lengths must match.
pub fn deviations_along_normals(
    measured: &[[f64; 3]],
    nominal: &[[f64; 3]],
    normals: &[[f64; 3]],
) -> Vec<f64> {
    measured
        .iter()
        .zip(nominal)
        .zip(normals)
        .map(|((p, q), n)| (p[0] - q[0]) * n[0] + (p[1] - q[1]) * n[1] + (p[2] - q[2]) * n[2])
        .collect()
}

#[cfg(test)]
mod tests;
