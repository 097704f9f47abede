//! HTTP end to end: POST /v1/machines/{machine}/contour-error (openapi.yaml), and the
//! `truecut contour` CLI.

use crate::helpers::*;

use serde_json::{Value, json};

fn xyz_kv(kv: f64, kff: f64) -> Value {
    let ax = json!({"kv": kv, "kff": kff});
    json!({"kinematics": "xyz", "axes": {"X": ax, "Y": ax, "Z": ax}})
}

fn five_axis(kff: f64) -> Value {
    let ax = json!({"kv": 30.0, "kff": kff});
    json!({"kinematics": "xyzac_table",
        "geometry": {"a_axis_origin": [0.0, 0.0, -150.0], "c_axis_origin": [5.0, -3.0, -100.0], "tool_length": 100.0},
        "axes": {"X": ax, "Y": ax, "Z": ax, "A": ax, "C": ax}})
}

/// Three CCW circles of radius 10 mm at 100 mm/s (ω = 10 rad/s); line 4 is the middle one.
const CIRCLES: &str =
    "G0 X10 Y0\nG1 F6000\nG3 X10 Y0 I-10 J0\nG3 X10 Y0 I-10 J0\nG3 X10 Y0 I-10 J0\n";

async fn put_machine(app: &TestApp, id: &str, def: &Value) {
    let r = app.put_json(&format!("/v1/machines/{id}"), def).await;
    assert!(r.status().is_success(), "PUT machine: {}", r.status());
}

async fn contour(app: &TestApp, id: &str, body: &Value) -> reqwest::Response {
    app.post_json(&format!("/v1/machines/{id}/contour-error"), body)
        .await
}

/// First-order loop on a circle: radial error r(1 − 1/√(1+(ω/kv)²)) = 0.51317 mm.
async fn circle_matches_closed_form(app: TestApp) {
    put_machine(&app, "m", &xyz_kv(30.0, 0.0)).await;
    let r = contour(&app, "m", &json!({"gcode": CIRCLES})).await;
    assert_eq!(r.status(), 200);
    let b: Value = r.json().await.unwrap();
    let n = b["t"].as_array().unwrap().len();
    for key in ["commanded", "actual", "contour_error", "line"] {
        assert_eq!(b[key].as_array().unwrap().len(), n, "{key}");
    }
    assert_eq!(b["commanded"][0].as_array().unwrap().len(), 3);
    assert!((b["t"][1].as_f64().unwrap() - 0.001).abs() < 1e-12);
    assert_eq!(b["axes"], json!(["X", "Y", "Z"]));
    let ce: Vec<f64> = serde_json::from_value(b["contour_error"].clone()).unwrap();
    let line: Vec<u32> = serde_json::from_value(b["line"].clone()).unwrap();
    let max = b["max"].as_f64().unwrap();
    assert!(ce.iter().all(|v| *v <= max + 1e-15));
    let expect = 10.0 * (1.0 - 1.0 / (1.0f64 + (10.0f64 / 30.0).powi(2)).sqrt());
    let mid: Vec<f64> = (0..n).filter(|&i| line[i] == 4).map(|i| ce[i]).collect();
    assert!(mid.len() > 600);
    for v in mid {
        assert!((v - expect).abs() < 0.01 * expect, "{v} vs {expect}");
    }
    assert_eq!(b["worst"]["contour_error"].as_f64().unwrap(), max);
}
on_both_backends!(circle_matches_closed_form);

async fn five_axis_rtcp_answer(app: TestApp) {
    put_machine(&app, "m5", &five_axis(1.0)).await;
    let prog = "G43.4 H1\nG1 X0 Y0 Z0 F3000\nG1 X50 Y20 Z-10 A45 C120\nG49\n";
    let r = contour(&app, "m5", &json!({"gcode": prog, "period_s": 0.002})).await;
    assert_eq!(r.status(), 200);
    let b: Value = r.json().await.unwrap();
    assert_eq!(b["commanded"][0].as_array().unwrap().len(), 5);
    assert_eq!(b["actual"][0].as_array().unwrap().len(), 5);
    assert!((b["t"][1].as_f64().unwrap() - 0.002).abs() < 1e-12);
    // Ideal servo (kff = 1, ideal inner loops) + RTCP: tip on the path to < 0.1 µm.
    assert!(b["max"].as_f64().unwrap() < 1e-4, "{}", b["max"]);
    assert!(b["orientation_error_deg"].is_array());
    assert!(b["orientation_max_deg"].as_f64().unwrap() < 1e-6);
    // The C column really turns through 120°.
    let last = b["commanded"].as_array().unwrap().last().unwrap().clone();
    assert!((last[4].as_f64().unwrap() - 120.0).abs() < 1e-9);
}
on_both_backends!(five_axis_rtcp_answer);

async fn gcode_errors_name_line_and_code(app: TestApp) {
    put_machine(&app, "m", &xyz_kv(30.0, 0.0)).await;
    let r = contour(&app, "m", &json!({"gcode": "G1 X1 F100\nG41 D1\n"})).await;
    assert_problem(r, 422, &["line 2", "G41"]).await;
    let r = contour(
        &app,
        "m",
        &json!({"gcode": "G1 X10 Y0 F100\nG2 X0 Y10 I-3 J0\n"}),
    )
    .await;
    assert_problem(r, 422, &["line 2", "circle"]).await;
    let r = contour(&app, "m", &json!({"gcode": "G1 X1 F100\nG1 A10\n"})).await;
    assert_problem(r, 422, &["line 2", "A"]).await;
    let r = contour(&app, "m", &json!({"gcode": "G1 X100000 F10\n"})).await;
    assert_problem(r, 422, &["1000000", "period_s"]).await;
}
on_both_backends!(gcode_errors_name_line_and_code);

async fn bad_requests_are_4xx(app: TestApp) {
    let r = contour(&app, "nope", &json!({"gcode": "G1 X1 F100"})).await;
    assert_problem(r, 404, &["nope"]).await;
    put_machine(&app, "m", &xyz_kv(30.0, 0.0)).await;
    let r = contour(&app, "m", &json!({"gcode": "  \n"})).await;
    assert_problem(r, 400, &["gcode"]).await;
    let r = contour(&app, "m", &json!({"gcode": "G1 X1 F100", "period_s": 0.0})).await;
    assert_problem(r, 400, &["period_s"]).await;
    let r = contour(&app, "m", &json!({"period_s": 0.001})).await;
    assert_problem(r, 400, &["gcode"]).await;
    // A machine without servo axes cannot be simulated: 422 naming the axis to add.
    put_machine(&app, "bare", &json!({"kinematics": "xyz"})).await;
    let r = contour(&app, "bare", &json!({"gcode": "G1 X1 F100"})).await;
    assert_problem(r, 422, &["axis X", "PUT /v1/machines/bare"]).await;
}
on_both_backends!(bad_requests_are_4xx);

#[test]
fn cli_predicts_from_a_machine_file_and_names_bad_lines() {
    let dir = tempfile::tempdir().unwrap();
    let machine = dir.path().join("machine.json");
    std::fs::write(&machine, xyz_kv(30.0, 0.0).to_string()).unwrap();
    let prog = dir.path().join("circles.nc");
    std::fs::write(&prog, CIRCLES).unwrap();
    let out = dir.path().join("answer.json");
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_truecut"))
        .args(["contour", prog.to_str().unwrap(), "--machine"])
        .arg(&machine)
        .arg("--output")
        .arg(&out)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "{stdout} {}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(stdout.contains("contour error: max 0.51"), "{stdout}");
    let b: Value = serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap();
    assert!(b["contour_error"].is_array() && b["max"].is_number());
    std::fs::write(&prog, "G1 X1 F100\nG12.1\n").unwrap();
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_truecut"))
        .args(["contour", prog.to_str().unwrap(), "--machine"])
        .arg(&machine)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success());
    assert!(
        stderr.contains("line 2") && stderr.contains("G12.1"),
        "{stderr}"
    );
}
