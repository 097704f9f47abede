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
