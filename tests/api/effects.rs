//! HTTP end to end: effects stored with a machine (`/v1/machines/{m}/effects`, its versions
//! and rollback), and every route that simulates the machine including them unless asked
//! `"effects": "none"` (issue 40 item 1).

use crate::helpers::*;

use serde_json::{Value, json};

/// Two full circles of radius 10 mm at 50 mm/s: every quadrant reverses X or Y.
const CIRCLES: &str = "G0 X10 Y0\nG1 F3000\nG3 X10 Y0 I-10 J0\nG3 X10 Y0 I-10 J0\n";

async fn contour(app: &TestApp, body: Value) -> Value {
    let r = app.post_json("/v1/machines/m/contour-error", &body).await;
    assert_eq!(r.status(), 200);
    r.json().await.unwrap()
}

fn backlash(x_mm: f64) -> Value {
    json!({"effects": [{"effect": "backlash", "params": {"x_mm": x_mm, "y_mm": x_mm}}],
        "source": "test"})
}

/// A machine whose axes match and follow closely (kv 30/s, feed-forward 0.9), so that the
/// effects are what the figures show.
fn machine() -> Value {
    let ax = json!({"kv": 30.0, "kff": 0.9});
    json!({"kinematics": "xyz", "axes": {"X": ax, "Y": ax, "Z": ax}})
}

async fn stored_versioned_and_simulated(app: TestApp) {
    let r = app.put_json("/v1/machines/m", &machine()).await;
    assert!(r.status().is_success());
    assert_problem(app.get("/v1/machines/m/effects").await, 404, &["PUT"]).await;
    let plain = contour(&app, json!({"gcode": CIRCLES})).await;
    assert_eq!(plain["effects_version"], Value::Null);

    // adopt 50 µm of backlash on X and Y: the first version
    let r = app
        .put_json("/v1/machines/m/effects", &backlash(0.05))
        .await;
    assert_eq!(r.status(), 201);
    let a: Value = r.json().await.unwrap();
    assert_eq!(a["version"], 1);
    let with = contour(&app, json!({"gcode": CIRCLES})).await;
    assert_eq!(with["effects_version"], 1);
    assert_eq!(
        with["commanded"], plain["commanded"],
        "effects never change the command"
    );
    // the play keeps the table b/2 = 25 µm behind the motor, on one side then the other
    let rows =
        |a: &Value| -> Vec<Vec<f64>> { serde_json::from_value(a["actual"].clone()).unwrap() };
    let shift = rows(&plain)
        .iter()
        .zip(rows(&with))
        .flat_map(|(p, w)| {
            p.iter()
                .zip(w)
                .map(|(p, w)| (p - w).abs())
                .collect::<Vec<_>>()
        })
        .fold(0.0, f64::max);
    assert!(
        (shift - 0.025).abs() < 1e-3,
        "largest shift {shift} mm, want 0.025"
    );
    assert_ne!(with["rms"], plain["rms"]);
    let none = contour(&app, json!({"gcode": CIRCLES, "effects": "none"})).await;
    assert_eq!(none["effects_version"], Value::Null);
    assert_eq!(none["actual"], plain["actual"]);
    let r = app
        .post_json(
            "/v1/machines/m/contour-error",
            &json!({"gcode": CIRCLES, "effects": "all"}),
        )
        .await;
    assert_problem(r, 400, &["effects", "none"]).await;

    // the ballbar simulation sees the reversal steps too
    let sim = |effects: &str| json!({"radius": 10.0, "feed": 3000.0, "directions": ["ccw"], "effects": effects});
    let url = "/v1/machines/m/iso230-4/simulate";
    let r = app.post_json(url, &sim("stored")).await;
    assert_eq!(r.status(), 200);
    let s1: Value = r.json().await.unwrap();
    let r = app.post_json(url, &sim("none")).await;
    let s0: Value = r.json().await.unwrap();
    assert_eq!(
        (&s1["effects_version"], &s0["effects_version"]),
        (&json!(1), &Value::Null)
    );
    let g = |s: &Value| s["runs"]["ccw"]["G"].as_f64().unwrap();
    assert!(
        g(&s1) > g(&s0) + 0.01,
        "circular deviation G {} -> {} mm",
        g(&s0),
        g(&s1)
    );

    // a second version, the list, and a rollback to the first
    let scale = json!({"effects": [{"effect": "scale_error", "params": {"x_ppm": 500.0}}]});
    let r = app.put_json("/v1/machines/m/effects", &scale).await;
    assert_eq!(r.status(), 200);
    let v: Value = app
        .get("/v1/machines/m/effects/versions")
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(v["current"], 2);
    assert_eq!(v["versions"].as_array().unwrap().len(), 2);
    let r = app
        .post_json("/v1/machines/m/effects/rollback", &json!({"version": 1}))
        .await;
    assert_eq!(r.status(), 200);
    let g: Value = app
        .get("/v1/machines/m/effects")
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(g["version"], 1);
    assert_eq!(g["effects"][0]["effect"], "backlash");
    assert_eq!(g["source"], "test");
    let again = contour(&app, json!({"gcode": CIRCLES})).await;
    assert_eq!(again["actual"], with["actual"]);

    // refusals name the key and the fix
    let bad = [
        (
            json!({"effects": [{"effect": "backlash", "params": {"b_mm": 0.01}}]}),
            "b_mm",
        ),
        (
            json!({"effects": [{"effect": "backlash", "params": {"x_gap": 0.01}}]}),
            "x_gap",
        ),
        (
            json!({"effects": [{"effect": "wear", "params": {"x_mm": 0.01}}]}),
            "wear",
        ),
        (
            json!({"effects": [{"effect": "backlash", "params": {"x_mm": 0.01}, "k": 1}]}),
            "k",
        ),
    ];
    for (body, word) in bad {
        let r = app.put_json("/v1/machines/m/effects", &body).await;
        assert_problem(r, 400, &[word]).await;
    }
    let r = app
        .put_json("/v1/machines/nobody/effects", &backlash(0.01))
        .await;
    assert_problem(r, 404, &["nobody"]).await;

    // compensated-program in contour mode judges on the machine with its effects
    let prog = "G0 X0 Y0\nG1 X10 F2000\nG1 Y10\nG1 X0\n";
    let r = app
        .post_json(
            "/v1/machines/m/compensated-program",
            &json!({"gcode": prog, "contour": true}),
        )
        .await;
    assert_eq!(r.status(), 200);
    let c: Value = r.json().await.unwrap();
    assert_eq!(c["contour"]["effects_version"], 1, "{}", c["contour"]);

    let r = app.delete("/v1/machines/m/effects").await;
    assert_eq!(r.status(), 204);
    assert_problem(app.get("/v1/machines/m/effects").await, 404, &["PUT"]).await;
    let after = contour(&app, json!({"gcode": CIRCLES})).await;
    assert_eq!(after["actual"], plain["actual"]);
}
on_both_backends!(stored_versioned_and_simulated);

/// A finishing contour well off machine zero: a lead-in, a straight, a half circle, a
/// straight back and a side that reverses Y, at 2 m/min.
pub(crate) const FINISH: &str = "G21 G90 G17 G94\nG0 X100 Y40\nG1 X100 Y50 F2000\nG1 X160 Y50\n\
                      G3 X160 Y90 I0 J20\nG1 X100 Y90\nG1 X100 Y50\nM30\n";

/// Scale of X and Y, squareness of Y on X (the geometric effects) and 10 µm of backlash.
const SCALE_X: f64 = 600e-6;
const SCALE_Y: f64 = -400e-6;
const SQUARENESS: f64 = 3e-4;

/// The tool tip's distance (mm) to FINISH's programmed path, of the samples from the command's
/// arrival within 0.5 mm of the lead-in's end on: (RMS over samples, max, samples, RMS weighted by the path
/// length each sample covers).
pub(crate) fn finish_distance(answer: &Value) -> (f64, f64, usize, f64) {
    let rows = |k: &str| -> Vec<[f64; 3]> { serde_json::from_value(answer[k].clone()).unwrap() };
    let (cmd, act) = (rows("commanded"), rows("actual"));
    // from the lead-in's end on: before it the servo still lags the rapid's approach
    let start = cmd
        .iter()
        .position(|c| (c[0] - 100.0).hypot(c[1] - 50.0) < 0.5)
        .expect("the lead-in arrives");
    let seg = |p: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let t = (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / (dx * dx + dy * dy)).clamp(0.0, 1.0);
        (p[0] - a[0] - t * dx).hypot(p[1] - a[1] - t * dy)
    };
    let dist = |p: [f64; 2]| {
        let lines = [
            ([100.0, 40.0], [100.0, 50.0]),
            ([100.0, 50.0], [160.0, 50.0]),
            ([160.0, 90.0], [100.0, 90.0]),
            ([100.0, 90.0], [100.0, 50.0]),
        ];
        let arc = if p[0] >= 160.0 {
            ((p[0] - 160.0).hypot(p[1] - 70.0) - 20.0).abs()
        } else {
            f64::INFINITY
        };
        lines
            .iter()
            .map(|(a, b)| seg(p, *a, *b))
            .fold(arc, f64::min)
    };
    let d: Vec<f64> = act[start..].iter().map(|a| dist([a[0], a[1]])).collect();
    let rms = (d.iter().map(|v| v * v).sum::<f64>() / d.len() as f64).sqrt();
    let (mut sw, mut swd) = (0.0, 0.0);
    for (i, a) in act.iter().enumerate().skip(start + 1) {
        let w = (a[0] - act[i - 1][0]).hypot(a[1] - act[i - 1][1]);
        sw += w;
        swd += w * d[i - start] * d[i - start];
    }
    let weighted = (swd / sw.max(1e-300)).sqrt();
    (
        rms,
        d.iter().copied().fold(0.0, f64::max),
        d.len(),
        weighted,
    )
}

/// Issue 40 item 2: with scale, squareness and backlash stored, the contour answer corrects
/// the geometric effects in the commanded points (p − e(p), read back by truecut and rs274
/// with e from the closed forms) and the backlash by offsets and take-up moves; run on the machine with
/// every effect (contour-error, effects stored) its distance to the programmed path is a
/// fraction of the program as written and of the same pre-distortion without the effects.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn geometric_effects_are_corrected_in_the_points() {
    let app = spawn_app().await;
    let r = app.put_json("/v1/machines/m", &machine()).await;
    assert!(r.status().is_success());
    let set = json!({"effects": [
        {"effect": "scale_error", "params": {"x_ppm": SCALE_X * 1e6, "y_ppm": SCALE_Y * 1e6}},
        {"effect": "axis_squareness", "params": {"y_per_x_rad": SQUARENESS}},
        {"effect": "backlash", "params": {"x_mm": 0.01, "y_mm": 0.01}}
    ], "source": "test"});
    let r = app.put_json("/v1/machines/m/effects", &set).await;
    assert_eq!(r.status(), 201);
    let answer = |effects: &'static str| {
        let app = &app;
        async move {
            let r = app
                .post_json(
                    "/v1/machines/m/compensated-program",
                    &json!({"gcode": FINISH, "contour": true, "effects": effects}),
                )
                .await;
            assert_eq!(r.status(), 200);
            r.json::<Value>().await.unwrap()
        }
    };
    let with = answer("stored").await;
    let without = answer("none").await;
    let text = with["gcode"].as_str().unwrap();
    let warnings = with["warnings"].to_string();
    assert!(
        warnings.contains("scale_error, axis_squareness, backlash") && warnings.contains("take-up"),
        "{warnings}"
    );
    assert_eq!(with["contour"]["effects_version"], 1);

    // read back by truecut and rs274: every point not pre-distorted at p - e(p) + b/2·d
    // (the rapid's: X and Y move in +)
    let e = |p: [f64; 3]| {
        [
            SCALE_X * p[0] - 0.005,
            SCALE_Y * p[1] + SQUARENESS * p[0] - 0.005,
            0.0,
        ]
    };
    let lines: Vec<usize> = serde_json::from_value(with["source_lines"].clone()).unwrap();
    let rs = crate::rs274::required();
    let dir = tempfile::tempdir().unwrap();
    let asked = crate::valid::Asked {
        error: Some(&e),
        contour: true,
    };
    let options = truecut::motion::ReadOptions::default();
    let c = crate::valid::check(
        "effects",
        FINISH,
        &options,
        &asked,
        text,
        &lines,
        rs.as_deref(),
        dir.path(),
    )
    .unwrap_or_else(|e| panic!("{e}\n--- answer:\n{text}"));
    println!(
        "geometric effects: {} points re-read, worst truecut {:.3} µm, rs274 {:?}; feed ends \
         {:.1} µm from p - e(p) (|e| up to 97 µm)",
        c.points,
        c.worst_truecut_mm * 1e3,
        c.worst_rs274_mm,
        c.feed_ends_mm * 1e3
    );
    if rs.is_some() {
        assert!(c.worst_rs274_mm.is_ok(), "{:?}", c.worst_rs274_mm);
    }
    // the feed ends are p - e(p) up to the contour pass' corner moves, which reach at most
    // REACH_FACTOR times the servo's error near the corner (the program as written on the
    // model without effects)
    let servo =
        finish_distance(&contour(&app, json!({"gcode": FINISH, "effects": "none"})).await).1;
    let reach = truecut::cam::predistort::REACH_FACTOR * servo;
    assert!(
        c.feed_ends_mm <= reach + 1e-6,
        "{} mm, reach {reach} mm",
        c.feed_ends_mm
    );

    // issue 39's invariants hold, an arc's G1 lines being take-ups of at most √2 plays
    let (read, _) = truecut::motion::gcode::parse_with(text, &options).unwrap();
    let takeup = |l: usize| {
        read.blocks
            .iter()
            .filter(|b| b.line == l)
            .all(|b| truecut::numeric::vec3::dist(b.start.xyz, b.end.xyz) <= 0.0143)
    };
    crate::compensated::assert_contour_invariants_except(FINISH, &with, &takeup);

    // on the machine: each program simulated with every stored effect
    let on_machine = |g: String| {
        let app = &app;
        async move { contour(app, json!({"gcode": g})).await }
    };
    let orig = on_machine(FINISH.to_string()).await;
    let closed = on_machine(text.to_string()).await;
    let blind = on_machine(without["gcode"].as_str().unwrap().to_string()).await;
    let (r0, m0, n0, _) = finish_distance(&orig);
    let (r1, m1, n1, _) = finish_distance(&closed);
    let (r2, _, _, _) = finish_distance(&blind);
    println!(
        "finishing contour on the machine with its effects: RMS {:.1} µm as written, {:.1} µm \
         pre-distorted without the effects, {:.1} µm with them ({:.3}x, {:.3}x); max {:.1} -> \
         {:.1} µm; duration {:.3}x; the route's own RMS ratio {:.3}",
        r0 * 1e3,
        r2 * 1e3,
        r1 * 1e3,
        r1 / r0,
        r1 / r2,
        m0 * 1e3,
        m1 * 1e3,
        n1 as f64 / n0 as f64,
        with["contour"]["compensated_rms_distance_mm"]
            .as_f64()
            .unwrap()
            / with["contour"]["original_rms_distance_mm"]
                .as_f64()
                .unwrap()
    );
    assert!(r1 <= 0.3 * r0, "{r1} vs {r0}");
    assert!(r1 <= 0.6 * r2, "{r1} vs {r2}");
    assert!(m1 <= 0.5 * m0, "{m1} vs {m0}");
    assert!(n1 as f64 <= 1.15 * n0 as f64);
}
