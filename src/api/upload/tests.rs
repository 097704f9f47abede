//! Unit tests of `crate::api::upload`.

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
    let d = deviations_along_normals(&[[0.0, 0.0, 1.1]], &[[0.0, 0.0, 1.0]], &[[0.0, 0.0, 1.0]]);
    assert!((d[0] - 0.1).abs() < 1e-12);
    let d = deviations_along_normals(&[[0.0, 0.0, 0.9]], &[[0.0, 0.0, 1.0]], &[[0.0, 0.0, 1.0]]);
    assert!((d[0] + 0.1).abs() < 1e-12);
}
