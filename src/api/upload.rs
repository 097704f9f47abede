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
mod tests {
    use super::*;

    fn devs(csv: &str) -> Vec<f64> {
        match parse_csv_upload(csv.as_bytes()).unwrap() {
            ProbeData::Deviations(d) => d,
            other => panic!("expected deviations, got {other:?}"),
        }
    }

    fn pts(csv: &str) -> Vec<[f64; 3]> {
        match parse_csv_upload(csv.as_bytes()).unwrap() {
            ProbeData::Points(p) => p,
            other => panic!("expected points, got {other:?}"),
        }
    }

    fn err(csv: &str) -> String {
        parse_csv_upload(csv.as_bytes())
            .unwrap_err()
            .detail()
            .to_string()
    }

    #[test]
    fn accepted_layouts() {
        assert_eq!(devs("deviation\n0.01\n-0.02\n"), vec![0.01, -0.02]);
        assert_eq!(
            pts("x,y,z\r\n1,2,3\r\n4,5,6\r\n"),
            vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]
        );
        assert_eq!(
            pts("Point;X [mm];Y [mm];Z [mm]\nP1;1,5;2;3\n"),
            vec![[1.5, 2.0, 3.0]]
        );
        assert_eq!(
            devs("\u{feff}id,dev\n# comment\n7,0.5\n\n8,-1e-3\n"),
            vec![0.5, -0.001]
        );
        assert_eq!(pts("\"x\"\t\"y\"\t\"z\"\n1\t2\t3\n"), vec![[1.0, 2.0, 3.0]]);
    }

    #[test]
    fn errors_name_the_line_and_problem() {
        assert!(err("a,b\n1,2\n").contains("line 1"));
        assert!(err("x,y,z\n1,2,3\n1,2\n").contains("line 3: expected 3 fields"));
        let e = err("x,y,z\n1,2,3\n1,abc,3\n");
        assert!(
            e.contains("line 3") && e.contains("'y'") && e.contains("abc"),
            "{e}"
        );
        assert!(err("deviation\nNaN\n").contains("line 2"));
        assert!(err("deviation\ninf\n").contains("not a finite number"));
        assert!(err("deviation\n").contains("no data rows"));
        assert!(err("").contains("empty"));
        assert!(
            parse_csv_upload(&[0xff, 0xfe, 0x00])
                .unwrap_err()
                .detail()
                .contains("UTF-8")
        );
    }

    #[test]
    fn json_upload_rules() {
        let (d, id) = parse_json_upload(br#"{"deviations":[0.1,-0.2],"id":"run-1"}"#).unwrap();
        assert_eq!(d, ProbeData::Deviations(vec![0.1, -0.2]));
        assert_eq!(id.as_deref(), Some("run-1"));
        assert!(parse_json_upload(br#"{"deviations":[]}"#).is_err());
        assert!(parse_json_upload(br#"{"points":[[1,2,3]],"deviations":[1]}"#).is_err());
        assert!(parse_json_upload(br#"{"deviation":[1]}"#).is_err());
        assert!(parse_json_upload(br#"{"points":[[1,2]]}"#).is_err());
    }

    proptest::proptest! {
        /// Any finite values written in any accepted layout parse back bit-exactly.
        #[test]
        fn csv_round_trip(
            values in proptest::collection::vec(-1e3f64..1e3, 1..40),
            semicolon in proptest::bool::ANY,
            with_id in proptest::bool::ANY,
        ) {
            let sep = if semicolon { ";" } else { "," };
            let mut csv = if with_id { format!("Point{sep}x{sep}y{sep}z\n") } else { format!("x{sep}y{sep}z\n") };
            for (k, v) in values.iter().enumerate() {
                let id = if with_id { format!("P{k}{sep}") } else { String::new() };
                csv.push_str(&format!("{id}{v}{sep}{}{sep}{}\r\n", -v, v * 0.5));
            }
            let expected: Vec<[f64; 3]> = values.iter().map(|v| [*v, -v, v * 0.5]).collect();
            proptest::prop_assert_eq!(parse_csv_upload(csv.as_bytes()).unwrap(), ProbeData::Points(expected));
        }
    }

    #[test]
    fn deviation_sign_follows_outward_normal() {
        let d =
            deviations_along_normals(&[[0.0, 0.0, 1.1]], &[[0.0, 0.0, 1.0]], &[[0.0, 0.0, 1.0]]);
        assert!((d[0] - 0.1).abs() < 1e-12);
        let d =
            deviations_along_normals(&[[0.0, 0.0, 0.9]], &[[0.0, 0.0, 1.0]], &[[0.0, 0.0, 1.0]]);
        assert!((d[0] + 0.1).abs() < 1e-12);
    }
}
