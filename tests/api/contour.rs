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
    // G41 is read with a warning by default (issue 14); strict refuses it.
    let r = contour(
        &app,
        "m",
        &json!({"gcode": "G1 X1 F100\nG41 X2\n", "strict": true}),
    )
    .await;
    assert_problem(r, 422, &["line 2", "G41"]).await;
    let r = contour(&app, "m", &json!({"gcode": "G1 X1 F100\nG12.1\n"})).await;
    assert_problem(r, 422, &["line 2", "G12.1"]).await;
    let r = contour(
        &app,
        "m",
        &json!({"gcode": "G1 X10 Y0 F100\nG2 X0 Y10 I-3 J0\n"}),
    )
    .await;
    assert_problem(r, 422, &["line 2", "circle"]).await;
    let r = contour(&app, "m", &json!({"gcode": "G1 X1 F100\nG1 A10\n"})).await;
    assert_problem(r, 422, &["line 2", "A"]).await;
    // An A word that never moves the axis is a warning on an xyz machine (422 when strict).
    let still = json!({"gcode": "G1 X1 A0 F100\nG1 X2\n"});
    let r = contour(&app, "m", &still).await;
    assert_eq!(r.status(), 200);
    let b: Value = r.json().await.unwrap();
    assert!(
        b["warnings"][0]
            .as_str()
            .unwrap()
            .starts_with("line 1: A0: "),
        "{b}"
    );
    let still = json!({"gcode": "G1 X1 A0 F100\nG1 X2\n", "strict": true});
    assert_problem(contour(&app, "m", &still).await, 422, &["line 1", "A"]).await;
    let r = contour(&app, "m", &json!({"gcode": "G1 X100000 F10\n"})).await;
    assert_problem(r, 422, &["1000000", "period_s"]).await;
}
on_both_backends!(gcode_errors_name_line_and_code);

/// A finishing program as a Fanuc-style post writes it (issue 14).
const POST: &str = "%
O1234 (FINISH POCKET)
(T1 D6 FLAT ENDMILL)
N10 G21 G90 G17 G40 G49 G80
N20 T1 M6
N30 G54
N40 G43 H1 Z50.
N50 S12000 M3
N60 M8
N70 G0 X10. Y0.
N80 G1 Z-1. F300.
N90 G3 X0. Y10. I-10. J0.
N100 G2 X-10. Y0. R10.
N110 G1 X-10. Y-5.
N120 G0 Z5.
N130 G98 G83 X20. Y20. Z-10. R2. Q1. F200.
N140 X30.
N150 G80
N160 G28 G91 Z0.
N170 M30
%
";

async fn post_processor_program_lenient_and_strict(app: TestApp) {
    put_machine(&app, "m", &xyz_kv(30.0, 0.0)).await;
    let r = contour(&app, "m", &json!({"gcode": POST})).await;
    assert_eq!(r.status(), 200);
    let b: Value = r.json().await.unwrap();
    let warnings: Vec<String> = serde_json::from_value(b["warnings"].clone()).unwrap();
    for (word, line) in [
        ("%", 1),
        ("O1234", 2),
        ("comment", 2),
        ("N", 4),
        ("G40", 4),
        ("G49", 4),
        ("G80", 4),
        ("T1", 5),
        ("M6", 5),
        ("G54", 6),
        ("G43 H1", 7),
        ("S12000", 8),
        ("M3", 8),
        ("M8", 9),
        ("G83", 16),
        ("G28", 19),
        ("M30", 20),
    ] {
        let hits: Vec<&String> = warnings
            .iter()
            .filter(|w| w.contains(&format!(": {word}: ")))
            .collect();
        assert_eq!(hits.len(), 1, "{word}: {warnings:#?}");
        assert!(hits[0].starts_with(&format!("line {line}: ")), "{hits:?}");
    }
    assert!(!warnings.iter().any(|w| w.contains("Q1")), "{warnings:#?}");
    // The tool-tip path: down to the hole bottom Z-10 at X20 and X30, Z50 at the start.
    let cmd: Vec<Vec<f64>> = serde_json::from_value(b["commanded"].clone()).unwrap();
    let zmin = cmd.iter().map(|r| r[2]).fold(f64::MAX, f64::min);
    let zmax = cmd.iter().map(|r| r[2]).fold(f64::MIN, f64::max);
    assert!(
        (zmin + 10.0).abs() < 1e-3 && (zmax - 50.0).abs() < 1e-3,
        "{zmin} {zmax}"
    );
    let line: Vec<u32> = serde_json::from_value(b["line"].clone()).unwrap();
    assert!(line.contains(&17) && line.contains(&13));
    // Strict: 422 naming the first such line and word.
    let r = contour(&app, "m", &json!({"gcode": POST, "strict": true})).await;
    assert_problem(r, 422, &["line 1", "%", "strict"]).await;
    let body = POST.replacen(
        "%\nO1234 (FINISH POCKET)\n(T1 D6 FLAT ENDMILL)\nN10 ",
        "",
        1,
    );
    let r = contour(&app, "m", &json!({"gcode": body, "strict": true})).await;
    assert_problem(r, 422, &["line 1", "G40"]).await;
}
on_both_backends!(post_processor_program_lenient_and_strict);

/// Fusion 360's Fanuc post, drill and tap (issue 24: it used to be refused at G84).
const FUSION_TAP: &str = "%\nO1001 (DRILL AND TAP)\nG90 G94 G17 G21\nT3 M6\nS600 M3\n\
G54 G0 X10. Y10.\nG43 Z15. H3 M8\nG0 Z5.\nG98 G84 X10. Y10. Z-12. R5. F720.\nX30.\nG80\nM30\n%\n";

async fn fusion_tapping_and_haas_mid_block_delete(app: TestApp) {
    let mut def = xyz_kv(30.0, 0.0);
    def["g30"] = json!([0.0, 0.0, 40.0]);
    put_machine(&app, "m", &def).await;
    // Tapping: read, fed in to Z-12 and out to R at both holes, named on its line.
    let r = contour(&app, "m", &json!({"gcode": FUSION_TAP})).await;
    assert_eq!(r.status(), 200);
    let b: Value = r.json().await.unwrap();
    let warnings: Vec<String> = serde_json::from_value(b["warnings"].clone()).unwrap();
    assert!(
        warnings.iter().any(|w| w.starts_with("line 9: G84: ")),
        "{warnings:#?}"
    );
    let cmd: Vec<Vec<f64>> = serde_json::from_value(b["commanded"].clone()).unwrap();
    let zmin = cmd.iter().map(|r| r[2]).fold(f64::MAX, f64::min);
    let at_x30 = cmd
        .iter()
        .any(|r| (r[0] - 30.0).abs() < 1e-6 && (r[2] + 12.0).abs() < 1e-3);
    assert!((zmin + 12.0).abs() < 1e-3 && at_x30, "{zmin}");
    let tap = "G0 X10 Y10 Z5\nG98 G84 X10. Y10. Z-12. R5. F720.\nG80\n";
    let r = contour(&app, "m", &json!({"gcode": tap, "strict": true})).await;
    assert_problem(r, 422, &["line 2", "G84", "strict"]).await;
    // Mastercam's Haas post: coolant optional in mid-block; the Z move is read.
    let haas = "G0 X0 Y0 Z1.\nG43 H6 Z.25 /M8\nG1 X5. F300.\n";
    let body = json!({"gcode": haas, "tool_lengths": {"6": 0.0}});
    let r = contour(&app, "m", &body).await;
    assert_eq!(r.status(), 200);
    let b: Value = r.json().await.unwrap();
    let warnings: Vec<String> = serde_json::from_value(b["warnings"].clone()).unwrap();
    assert!(
        warnings
            .iter()
            .any(|w| w.starts_with("line 2: / (mid-block): ")),
        "{warnings:#?}"
    );
    let cmd: Vec<Vec<f64>> = serde_json::from_value(b["commanded"].clone()).unwrap();
    let last = cmd.last().unwrap();
    assert!(
        (last[0] - 5.0).abs() < 1e-6 && (last[2] - 0.25).abs() < 1e-6,
        "{last:?}"
    );
    let body = json!({"gcode": haas, "tool_lengths": {"6": 0.0}, "strict": true});
    let r = contour(&app, "m", &body).await;
    assert_problem(r, 422, &["line 2", "/ (mid-block)", "strict"]).await;
    // G30 goes to the machine's own G30 position (Z40), not to an unknown one.
    let g30 = "G0 X1 Y1 Z5\nG91 G30 Z0\nG90 G1 X2 F600\n";
    let r = contour(&app, "m", &json!({"gcode": g30, "strict": true})).await;
    assert_eq!(r.status(), 200);
    let b: Value = r.json().await.unwrap();
    let cmd: Vec<Vec<f64>> = serde_json::from_value(b["commanded"].clone()).unwrap();
    let zmax = cmd.iter().map(|r| r[2]).fold(f64::MIN, f64::max);
    assert!((zmax - 40.0).abs() < 1e-6, "{zmax}");
    // A G30 position that is not a point is refused when stored.
    let mut bad = xyz_kv(30.0, 0.0);
    bad["g30"] = json!([0.0, 0.0, 1e9]);
    let r = app.put_json("/v1/machines/m2", &bad).await;
    assert_problem(r, 400, &["g30"]).await;
}
on_both_backends!(fusion_tapping_and_haas_mid_block_delete);

async fn offsets_tool_lengths_and_inch_programs(app: TestApp) {
    put_machine(&app, "m", &xyz_kv(30.0, 0.0)).await;
    let body = json!({"gcode": POST, "work_offsets": {"G54": [100.0, -20.0, 5.0]},
        "tool_lengths": {"1": 80.0}, "home": [0.0, 0.0, 200.0]});
    let r = contour(&app, "m", &body).await;
    assert_eq!(r.status(), 200);
    let b: Value = r.json().await.unwrap();
    let warnings: Vec<String> = serde_json::from_value(b["warnings"].clone()).unwrap();
    assert!(
        warnings
            .iter()
            .any(|w| w.contains("G54") && w.contains("[100, -20, 5]"))
    );
    assert!(
        warnings
            .iter()
            .any(|w| w.contains("G43 H1") && w.contains("80 mm"))
    );
    assert!(!warnings.iter().any(|w| w.contains("G28")), "{warnings:#?}");
    let cmd: Vec<Vec<f64>> = serde_json::from_value(b["commanded"].clone()).unwrap();
    let line: Vec<u32> = serde_json::from_value(b["line"].clone()).unwrap();
    // The hole bottom in machine Z: -10 + work offset 5 + tool length 80.
    let zmin = (0..cmd.len())
        .filter(|&i| line[i] == 16)
        .map(|i| cmd[i][2])
        .fold(f64::MAX, f64::min);
    assert!((zmin - (-10.0 + 5.0 + 80.0)).abs() < 1e-3, "{zmin}");
    let last = cmd.last().unwrap();
    assert!(
        (last[0] - 130.0).abs() < 1e-9 && (last[2] - 200.0).abs() < 1e-9,
        "{last:?}"
    );
    // Bad keys are the caller's to fix.
    let r = contour(
        &app,
        "m",
        &json!({"gcode": POST, "work_offsets": {"G60": [0.0, 0.0, 0.0]}}),
    )
    .await;
    assert_problem(r, 400, &["work_offsets.G60", "G54"]).await;
    let r = contour(
        &app,
        "m",
        &json!({"gcode": POST, "tool_lengths": {"T1": 5.0}}),
    )
    .await;
    assert_problem(r, 400, &["tool_lengths.T1"]).await;
    // An inch program answers the path of its mm twin.
    let mm =
        "G21 G17 G90\nG0 X25.4 Y0\nG1 Z-2.54 F2540\nG2 X0 Y25.4 R25.4\nG3 X-25.4 Y0 I0 J-25.4\n";
    let inch = "G20 G17 G90\nG0 X1 Y0\nG1 Z-.1 F100\nG2 X0 Y1 R1\nG3 X-1 Y0 I0 J-1\n";
    let mut answers = Vec::new();
    for text in [mm, inch] {
        let r = contour(&app, "m", &json!({"gcode": text})).await;
        assert_eq!(r.status(), 200);
        let b: Value = r.json().await.unwrap();
        let cmd: Vec<Vec<f64>> = serde_json::from_value(b["commanded"].clone()).unwrap();
        answers.push(cmd);
    }
    assert_eq!(answers[0].len(), answers[1].len());
    for (a, b) in answers[0].iter().zip(&answers[1]) {
        for k in 0..3 {
            assert!((a[k] - b[k]).abs() < 1e-6, "{a:?} vs {b:?}");
        }
    }
}
on_both_backends!(offsets_tool_lengths_and_inch_programs);

/// The G41 pocket of `tests/data/programs` (a 30 x 20 pocket, D1 a 6 mm cutter).
const POCKET: &str = include_str!("../data/programs/pocket_finish.nc");

async fn cutter_compensation_with_tool_diameters(app: TestApp) {
    put_machine(&app, "m", &xyz_kv(30.0, 0.0)).await;
    // Largest commanded X on the wall lines (9..=15): the tool centre, 3 mm inside X30.
    let x_max = |b: &Value| {
        let cmd: Vec<Vec<f64>> = serde_json::from_value(b["commanded"].clone()).unwrap();
        let line: Vec<u32> = serde_json::from_value(b["line"].clone()).unwrap();
        (0..cmd.len())
            .filter(|&i| (9..=15).contains(&line[i]))
            .map(|i| cmd[i][0])
            .fold(f64::MIN, f64::max)
    };
    let r = contour(
        &app,
        "m",
        &json!({"gcode": POCKET, "tool_diameters": {"1": 6.0}}),
    )
    .await;
    assert_eq!(r.status(), 200);
    let b: Value = r.json().await.unwrap();
    assert!((x_max(&b) - 27.0).abs() < 1e-9, "{}", x_max(&b));
    let warnings: Vec<String> = serde_json::from_value(b["warnings"].clone()).unwrap();
    assert!(
        warnings
            .iter()
            .any(|w| w.contains("G41 D1") && w.contains("3 mm")),
        "{warnings:#?}"
    );
    // Without diameters: the programmed path, with the warning of old.
    let r = contour(&app, "m", &json!({"gcode": POCKET})).await;
    let b: Value = r.json().await.unwrap();
    assert!((x_max(&b) - 30.0).abs() < 1e-9);
    assert!(b["warnings"].to_string().contains("without tool_diameters"));
    // A tool the entry is too short for: 422 naming the line and why.
    let r = contour(
        &app,
        "m",
        &json!({"gcode": POCKET, "tool_diameters": {"1": 40.0}}),
    )
    .await;
    assert_problem(
        r,
        422,
        &["line 9", "entry move is not greater than the tool radius"],
    )
    .await;
    let body = json!({"gcode": POCKET, "tool_diameters": {"T1": 6.0}});
    assert_problem(contour(&app, "m", &body).await, 400, &["tool_diameters.T1"]).await;
}
on_both_backends!(cutter_compensation_with_tool_diameters);

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

/// The dashboard's demo program on the demo machine (`truecut demo`: kv 30, kff 0.6, PI
/// velocity loop, 0.5 ms current loop): it ends at X30 Y0 after an F4000 pocket outline.
const DEMO_PROGRAM: &str = "G21 G90 G17\nG0 X20 Y0 Z0\nG2 X20 Y0 I-20 J0 F3000\nG1 X30 Y0 F4000\n\
    G1 X30 Y-20\nG1 X-30 Y-20\nG1 X-30 Y20\nG1 X30 Y20\nG1 X30 Y0\nM30\n";

/// Issue 39 item 5: the simulation goes on after the command's last sample until the tool is
/// within 0.1 µm of the program's end point in every axis, and the answer says how long.
async fn the_simulation_runs_until_the_servo_settles(app: TestApp) {
    let servo = json!({"kv": 30.0, "kff": 0.6, "kp_v": 400.0, "ti_v": 0.01, "tc": 0.0005});
    put_machine(
        &app,
        "demo",
        &json!({"kinematics": "xyz", "axes": {"X": servo, "Y": servo, "Z": servo}}),
    )
    .await;
    let r = contour(&app, "demo", &json!({"gcode": DEMO_PROGRAM})).await;
    assert_eq!(r.status(), 200);
    let b: Value = r.json().await.unwrap();
    let t: Vec<f64> = serde_json::from_value(b["t"].clone()).unwrap();
    let actual: Vec<Vec<f64>> = serde_json::from_value(b["actual"].clone()).unwrap();
    let commanded: Vec<Vec<f64>> = serde_json::from_value(b["commanded"].clone()).unwrap();
    let line: Vec<u32> = serde_json::from_value(b["line"].clone()).unwrap();
    assert!(actual.len() == t.len() && commanded.len() == t.len() && line.len() == t.len());
    let s = &b["settle"];
    let (end_s, settle_s) = (
        s["command_end_s"].as_f64().unwrap(),
        s["settle_s"].as_f64().unwrap(),
    );
    // Where the tool was when the command stopped (the old answer's last row), and now.
    let at_end = t.iter().position(|&x| (x - end_s).abs() < 1e-9).unwrap();
    let dist = |i: usize| {
        (0..3)
            .map(|k| (actual[i][k] - [30.0, 0.0, 0.0][k]).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    let last = t.len() - 1;
    println!(
        "contour-error run-out on the demo machine: tool {:.1} um from the end point when the \
         command ended (t = {end_s:.3} s), {:.3} um after {settle_s:.3} s more",
        dist(at_end) * 1e3,
        dist(last) * 1e3
    );
    assert!(s["settled"].as_bool().unwrap(), "{s}");
    assert!(dist(at_end) > 0.05, "{}", dist(at_end));
    assert!((s["lag_at_command_end_mm"].as_f64().unwrap() - dist(at_end)).abs() < 1e-12);
    assert!(
        settle_s > 0.05 && (t[last] - end_s - settle_s).abs() < 1e-9,
        "{s}"
    );
    for k in 0..3 {
        assert!(
            (actual[last][k] - commanded[last][k]).abs() <= 1e-4,
            "{:?}",
            actual[last]
        );
        assert_eq!(commanded[last][k], commanded[at_end][k]);
    }
    // One period earlier some axis was still outside the band.
    assert!((0..3).any(|k| (actual[last - 1][k] - commanded[last][k]).abs() > 1e-4));
    assert_eq!(line[last], line[at_end]);
    let note = s["note"].as_str().unwrap();
    assert!(note.contains("past the command's end"), "{note}");
    // A slow loop does not settle within 10 s: the answer stops there and warns.
    put_machine(&app, "slow", &xyz_kv(0.3, 0.0)).await;
    let r = contour(&app, "slow", &json!({"gcode": "G1 X20 F3000\n"})).await;
    assert_eq!(r.status(), 200);
    let b: Value = r.json().await.unwrap();
    assert_eq!(b["settle"]["settled"], json!(false));
    assert!((b["settle"]["settle_s"].as_f64().unwrap() - 10.0).abs() < 2e-3);
    let w: Vec<String> = serde_json::from_value(b["warnings"].clone()).unwrap();
    assert!(w.iter().any(|w| w.contains("did not settle")), "{w:?}");
}
on_both_backends!(the_simulation_runs_until_the_servo_settles);

/// Path-control modes and the machine's controller (issue 39 item 2): G61 and G9 are read
/// without a warning and stop the tool, LinuxCNC's segment cap slows 20 µm chords to
/// 19.6 mm/s, and a bad controller is refused at PUT naming the field.
async fn path_control_modes_and_the_controllers_limits(app: TestApp) {
    put_machine(&app, "m", &xyz_kv(30.0, 0.0)).await;
    let seconds = |b: &Value| b["t"].as_array().unwrap().last().unwrap().as_f64().unwrap();
    let line = "G1 X10 F6000\nG1 X20\nG1 X30\n";
    let r = contour(&app, "m", &json!({"gcode": line})).await;
    let free: Value = r.json().await.unwrap();
    for modes in [
        "G61\n",
        "G61.1\n",
        "G9 ",
        "G05.1 Q1\nG08 P1\nG64 P0.01\nG61\n",
    ] {
        let r = contour(
            &app,
            "m",
            &json!({"gcode": format!("{modes}{line}"), "strict": true}),
        )
        .await;
        assert_eq!(r.status(), 200, "{modes}");
        let b: Value = r.json().await.unwrap();
        assert_eq!(b["warnings"], json!([]), "{modes}");
        assert!(
            seconds(&b) > seconds(&free) + 0.01,
            "{modes}: the stops take time"
        );
    }
    let r = contour(&app, "m", &json!({"gcode": format!("G08 P0\n{line}")})).await;
    let b: Value = r.json().await.unwrap();
    assert!(
        b["warnings"][0]
            .as_str()
            .unwrap()
            .starts_with("line 1: G8 P0: look-ahead off")
    );
    // 1,000 chords of 20 µm: LinuxCNC's cap at 1 ms.
    let mut chords = String::from("G1 F6000\n");
    for k in 1..=1000 {
        chords += &format!("X{:.3}\n", k as f64 * 0.02);
    }
    let mut linuxcnc = xyz_kv(30.0, 0.0);
    linuxcnc["controller"] = json!({"kind": "linuxcnc"});
    put_machine(&app, "lcnc", &linuxcnc).await;
    let top = |b: &Value| -> f64 {
        let cmd: Vec<Vec<f64>> = serde_json::from_value(b["commanded"].clone()).unwrap();
        cmd.windows(2)
            .map(|w| (w[1][0] - w[0][0]) / 0.001)
            .fold(0.0, f64::max)
    };
    let body = json!({"gcode": chords});
    let fast: Value = contour(&app, "m", &body).await.json().await.unwrap();
    let capped: Value = contour(&app, "lcnc", &body).await.json().await.unwrap();
    assert!((top(&fast) - 100.0).abs() < 1e-6, "{}", top(&fast));
    assert!(
        top(&capped) <= 0.02 / 1.02e-3 + 1e-9 && top(&capped) > 19.5,
        "{}",
        top(&capped)
    );
    let got: Value = app.get("/v1/machines/lcnc").await.json().await.unwrap();
    assert_eq!(got["controller"], json!({"kind": "linuxcnc"}), "{got}");
    let mut bad = xyz_kv(30.0, 0.0);
    bad["controller"] = json!({"kind": "grbl", "lookahead_blocks": 0});
    let r = app.put_json("/v1/machines/bad", &bad).await;
    assert_problem(
        r,
        400,
        &["controller.lookahead_blocks", "must be in 1..100000"],
    )
    .await;
}
on_both_backends!(path_control_modes_and_the_controllers_limits);

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
    assert!(
        stdout.contains("run-out: the tool was") && stdout.contains("until it was within 0.1 um"),
        "{stdout}"
    );
    let b: Value = serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap();
    assert!(b["contour_error"].is_array() && b["max"].is_number());
    assert!(b["settle"]["settled"].as_bool().unwrap(), "{}", b["settle"]);
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
    // A post's words pass with one warning each on stderr; --strict refuses the first.
    std::fs::write(&prog, "%\nO1000 (FINISH)\nT1 M6\nG1 X1 F100\nM30\n%\n").unwrap();
    let run = |strict: bool| {
        let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_truecut"));
        cmd.args(["contour", prog.to_str().unwrap(), "--machine"])
            .arg(&machine);
        if strict {
            cmd.arg("--strict");
        }
        cmd.output().unwrap()
    };
    let lenient = run(false);
    let stderr = String::from_utf8_lossy(&lenient.stderr);
    assert!(lenient.status.success(), "{stderr}");
    assert!(
        stderr.contains("warning:") && stderr.contains("M6") && stderr.contains("O1000"),
        "{stderr}"
    );
    let strict = run(true);
    let stderr = String::from_utf8_lossy(&strict.stderr);
    assert!(!strict.status.success());
    assert!(
        stderr.contains("line 1") && stderr.contains("strict"),
        "{stderr}"
    );
}
