//! Decoding probe-measurement uploads: JSON (`points` or `deviations`) and CSV (header
//! `x,y,z` or `deviation`, optionally after a leading point-id column; comma, semicolon or
//! tab separated; with semicolons a decimal comma is accepted). Errors name the line.
//! Hand-written: the layouts are few and line-numbered messages matter more than generality.
//! Both are read from a `std::io::Read` as the body arrives (`api/intake.rs` feeds it), so
//! an upload is held as its parsed arrays, never as its text.

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
    checked_json_upload(decode_json(body)?)
}

/// Like [`parse_json_upload`], reading the JSON from `input` as it arrives: the arrays are
/// built while the body streams in, the text is never held whole.
pub fn read_json_upload(input: impl std::io::Read) -> ApiResult<(ProbeData, Option<String>)> {
    // serde_json reads a byte at a time; std's `BufReader` gives those reads a fast path
    // (33 s → a few s for 120 MiB on the dev profile, BENCHMARKS.md "The door").
    let input = std::io::BufReader::with_capacity(64 * 1024, input);
    let up: JsonUpload = serde_json::from_reader(input).map_err(|e| {
        if e.is_io() {
            ApiError::bad_request(format!("could not read the request body: {e}"))
        } else if e.is_eof() && e.line() == 1 && e.column() == 0 {
            ApiError::bad_request("the request body is empty; send a JSON document")
        } else {
            ApiError::bad_request(format!("invalid JSON body: {e}"))
        }
    })?;
    checked_json_upload(up)
}

fn checked_json_upload(up: JsonUpload) -> ApiResult<(ProbeData, Option<String>)> {
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

/// Parses a CSV upload held whole. See the module docs for the accepted layouts.
pub fn parse_csv_upload(body: &[u8]) -> ApiResult<ProbeData> {
    read_csv_upload(body, None)
}

/// The header of a CSV upload: separator and columns.
struct CsvHead {
    sep: char,
    names: Vec<String>,
    layout: Layout,
    /// Index of the first value column (1 after a point-id column).
    first_value: usize,
}

impl CsvHead {
    fn parse(header_no: usize, header: &str) -> ApiResult<CsvHead> {
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
        Ok(CsvHead {
            sep,
            layout,
            first_value: usize::from(has_id),
            names,
        })
    }

    /// The values of data row `line` (1 or 3, in `values`).
    fn row(&self, line_no: usize, line: &str, values: &mut [f64; 3]) -> ApiResult<()> {
        let width = self.names.len();
        let decimal_comma = self.sep == ';';
        let mut count = 0;
        for (col, field) in line.split(self.sep).enumerate() {
            count += 1;
            if col < self.first_value || col >= width {
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
                        self.names[col]
                    )));
                }
            };
            values[col - self.first_value] = v;
        }
        if count != width {
            return Err(ApiError::bad_request(format!(
                "CSV line {line_no}: expected {width} fields ({}), found {count}",
                self.names.join(&self.sep.to_string())
            )));
        }
        Ok(())
    }
}

/// Reads a CSV upload line by line from `input` as it arrives, holding one line of text at
/// a time. With `max_rows` (the surface's grid size) room for that many rows is reserved and
/// a longer upload is refused at the first extra row. A read error (the body cut off) is
/// a 400 that the pace or budget middleware may turn into 408, 413 or 503.
pub fn read_csv_upload(
    mut input: impl std::io::BufRead,
    max_rows: Option<usize>,
) -> ApiResult<ProbeData> {
    let mut line = Vec::new();
    let mut offset = 0usize;
    let mut line_no = 0usize;
    let mut head: Option<CsvHead> = None;
    let mut points = Vec::new();
    let mut devs = Vec::new();
    let mut values = [0.0_f64; 3];
    loop {
        line.clear();
        let n = input
            .read_until(b'\n', &mut line)
            .map_err(|e| ApiError::bad_request(format!("could not read the request body: {e}")))?;
        if n == 0 {
            break;
        }
        line_no += 1;
        let text = std::str::from_utf8(&line).map_err(|e| {
            ApiError::bad_request(format!(
                "the CSV is not UTF-8 text (byte {}); export it as UTF-8",
                offset + e.valid_up_to()
            ))
        })?;
        offset += n;
        let mut text = text
            .strip_suffix('\n')
            .unwrap_or(text)
            .trim_end_matches('\r');
        if line_no == 1 {
            text = text.strip_prefix('\u{feff}').unwrap_or(text);
        }
        if text.trim().is_empty() || text.trim_start().starts_with('#') {
            continue;
        }
        let Some(h) = &head else {
            let h = CsvHead::parse(line_no, text)?;
            if let Some(max) = max_rows {
                match h.layout {
                    Layout::Xyz => points.reserve_exact(max),
                    Layout::Deviation => devs.reserve_exact(max),
                }
            }
            head = Some(h);
            continue;
        };
        h.row(line_no, text, &mut values)?;
        let rows = match h.layout {
            Layout::Xyz => {
                points.push(values);
                points.len()
            }
            Layout::Deviation => {
                devs.push(values[0]);
                devs.len()
            }
        };
        if let Some(max) = max_rows
            && rows > max
        {
            return Err(too_many(
                if h.layout == Layout::Xyz {
                    "points"
                } else {
                    "deviations"
                },
                max,
                line_no,
            ));
        }
    }
    let Some(h) = head else {
        return Err(ApiError::bad_request(
            "the CSV is empty; send a header row (x,y,z or deviation) and one row per point",
        ));
    };
    match h.layout {
        Layout::Xyz if points.is_empty() => Err(no_rows()),
        Layout::Deviation if devs.is_empty() => Err(no_rows()),
        Layout::Xyz => Ok(ProbeData::Points(points)),
        Layout::Deviation => Ok(ProbeData::Deviations(devs)),
    }
}

fn no_rows() -> ApiError {
    ApiError::bad_request("the CSV has a header but no data rows; send one row per probed point")
}

/// 400 for an upload with more than `max` entries, found at `line_no` (0: not line-numbered).
pub fn too_many(field: &str, max: usize, line_no: usize) -> ApiError {
    let at = if line_no > 0 {
        format!(" (CSV line {line_no} is entry {})", max + 1)
    } else {
        String::new()
    };
    ApiError::bad_request(format!(
        "{field} has more than {max} entries{at} but the surface has {max} grid points; \
         send one per grid point in nominal order (u fastest)"
    ))
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
