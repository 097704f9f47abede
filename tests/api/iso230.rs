//! ISO 230-2 and ISO 230-4 over HTTP (CONTRACT v1.1): the hand-computed table of
//! `src/metrology/iso230_2/tests.rs` through the route, a logged run, refusals, circles with
//! closed-form figures, the simulated ballbar test against the first-order servo's closed
//! form, and runs stored per machine axis on both backends.

use serde_json::{Value, json};

use crate::helpers::{TestApp, assert_problem, spawn_app};

/// The hand table (µm deviations; see `src/metrology/iso230_2/tests.rs` for the arithmetic):
/// A 12, A↑ 11, A↓ 11, E 8, E↑ 5, E↓ 5, M 4.5, R 10 (max(R↑, R↓) = 8), B 4, B̄ 3.2.
pub fn hand_body(scale: f64) -> Value {
    let um: [([f64; 5], [f64; 5]); 5] = [
        ([1., 3., 2., 1., 3.], [-2., 0., -1., -2., 0.]),
        ([3., 5., 4., 5., 3.], [-2., 2., 0., 2., -2.]),
        ([1., 1., 1., 1., 1.], [-4., -2., -3., -4., -2.]),
        ([-3., 1., -1., -3., 1.], [-5., -3., -4., -3., -5.]),
        ([2., 4., 3., 4., 2.], [-1., 3., 1., -1., 3.]),
    ];
    let targets: Vec<f64> = (0..5).map(|i| 100.0 * i as f64).collect();
    type Pick = fn(&([f64; 5], [f64; 5])) -> [f64; 5];
    let rows = |pick: Pick| -> Vec<Vec<f64>> {
        um.iter()
            .zip(&targets)
            .map(|(r, &p)| pick(r).iter().map(|d| p + scale * d * 1e-3).collect())
            .collect()
    };
    json!({"targets": targets, "forward": rows(|r| r.0), "backward": rows(|r| r.1)})
}

fn um(v: &Value, field: &str) -> f64 {
    v[field]
        .as_f64()
        .unwrap_or_else(|| panic!("{field} missing in {v}"))
        * 1e3
}

fn close(v: &Value, field: &str, want_um: f64) {
    let got = um(v, field);
    assert!(
        (got - want_um).abs() < 1e-6,
        "{field}: {got} µm, want {want_um} µm"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn iso230_2_table_gives_the_hand_figures() {
    let app = spawn_app().await;
    let r = app.post_json("/v1/iso230-2", &hand_body(1.0)).await;
    assert_eq!(r.status(), 200);
    let a: Value = r.json().await.unwrap();
    for (f, w) in [
        ("A", 12.0),
        ("A_fwd", 11.0),
        ("A_bwd", 11.0),
        ("E", 8.0),
        ("E_fwd", 5.0),
        ("E_bwd", 5.0),
        ("M", 4.5),
        ("R", 10.0),
        ("R_fwd", 8.0),
        ("R_bwd", 8.0),
        ("B", 4.0),
        ("B_avg", 3.2),
    ] {
        close(&a, f, w);
    }
    let t = &a["targets"][1];
    assert_eq!(t["target"], 100.0);
    for (f, w) in [
        ("mean_fwd", 4.0),
        ("mean_bwd", 0.0),
        ("s_fwd", 1.0),
        ("s_bwd", 2.0),
        ("B", 4.0),
        ("R", 10.0),
    ] {
        close(t, f, w);
    }
    assert_eq!(a["warnings"], json!([]));
    println!(
        "ISO 230-2 hand table over HTTP: A {:.1} E {:.1} M {:.1} R {:.1} B {:.1} µm",
        um(&a, "A"),
        um(&a, "E"),
        um(&a, "M"),
        um(&a, "R"),
        um(&a, "B")
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn iso230_2_refusals_and_warnings() {
    let app = spawn_app().await;
    let mut b = hand_body(1.0);
    b["backward"].as_array_mut().unwrap().pop();
    assert_problem(
        app.post_json("/v1/iso230-2", &b).await,
        400,
        &["backward has 4 entries"],
    )
    .await;
    let mut b = hand_body(1.0);
    b["forward"][2] = json!([200.001]);
    assert_problem(
        app.post_json("/v1/iso230-2", &b).await,
        422,
        &["forward[2] cycles", "at least 2"],
    )
    .await;
    let mut b = hand_body(1.0);
    b["trace"] = json!({"period_s": 0.01, "commanded": [0.0], "measured": [0.0]});
    assert_problem(app.post_json("/v1/iso230-2", &b).await, 400, &["not both"]).await;
    assert_problem(
        app.post_json("/v1/iso230-2", &json!({"targets": [1.0]}))
            .await,
        400,
        &["either the table"],
    )
    .await;
    let mut b = hand_body(1.0);
    b["targets"][4] = json!(0.0);
    assert_problem(
        app.post_json("/v1/iso230-2", &b).await,
        400,
        &["repeats targets[0]"],
    )
    .await;
    assert_problem(
        app.post_json("/v1/iso230-2", &json!({"targets": [0, 1], "forward": [[0, 0], [1, 1]], "backward": [[0, 0], [1, 1]], "x": 1})).await,
        400,
        &["unknown field"],
    )
    .await;
    // Three targets, three cycles: evaluated, with the departures named.
    let b = json!({"targets": [0, 10, 20], "forward": [[0.001, 0.002, 0.003], [10, 10.001, 10.002], [20, 20, 20.001]],
                   "backward": [[0, 0, 0.001], [10, 10, 10], [20.001, 20, 20]]});
    let r = app.post_json("/v1/iso230-2", &b).await;
    assert_eq!(r.status(), 200);
    let a: Value = r.json().await.unwrap();
    let w = a["warnings"].to_string();
    assert!(w.contains("3 targets") && w.contains("3 cycles"), "{w}");
    // Beyond the physical range (schemathesis found these answered with null figures).
    let mut b = hand_body(1.0);
    b["forward"][2][1] = json!(1.0e16);
    assert_problem(
        app.post_json("/v1/iso230-2", &b).await,
        400,
        &["forward[11]", "100 m"],
    )
    .await;
    let far = json!({"points": [[0.33, -5.3e16], [-4.2e16, 1.4e276], [5.9e16, -3.7e16]],
                     "radius": 3.4e38});
    assert_problem(
        app.post_json("/v1/iso230-4", &far).await,
        400,
        &["points[1]"],
    )
    .await;
    let big = json!({"points": [[1, 0], [0, 1], [-1, 0], [0, -1]], "radius": 3.4e38});
    assert_problem(app.post_json("/v1/iso230-4", &big).await, 400, &["radius"]).await;
}

/// A logged run: five targets 0..40 mm, three cycles, 1 s dwells at 100 Hz, a lag that
/// settles, +2 µm on the way up and −1 µm on the way down; overtravel 2 mm both ends.
fn logged_run() -> Value {
    let mut c: Vec<f64> = vec![-2.0; 50];
    let mut dev: Vec<f64> = vec![0.0; 50];
    let go = |c: &mut Vec<f64>, dev: &mut Vec<f64>, to: f64, dwell: usize, d: f64| {
        let from = *c.last().unwrap();
        let steps = ((to - from).abs() / 0.2).ceil() as usize;
        for k in 1..=steps {
            c.push(from + (to - from) * k as f64 / steps as f64);
            dev.push(d);
        }
        for _ in 0..dwell {
            c.push(to);
            dev.push(d);
        }
    };
    for _ in 0..3 {
        for t in [0.0, 10.0, 20.0, 30.0, 40.0] {
            go(&mut c, &mut dev, t, 100, 0.002);
        }
        go(&mut c, &mut dev, 42.0, 0, 0.0);
        for t in [40.0, 30.0, 20.0, 10.0, 0.0] {
            go(&mut c, &mut dev, t, 100, -0.001);
        }
        go(&mut c, &mut dev, -2.0, 0, 0.0);
    }
    let mut x = c[0];
    let measured: Vec<f64> = c
        .iter()
        .zip(&dev)
        .map(|(ck, d)| {
            x += (1.0 - (-0.3_f64).exp()) * (ck - x);
            x + d
        })
        .collect();
    json!({"trace": {"period_s": 0.01, "commanded": c, "measured": measured}})
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn iso230_2_logged_run_finds_targets_directions_and_settled_readings() {
    let app = spawn_app().await;
    let r = app.post_json("/v1/iso230-2", &logged_run()).await;
    assert_eq!(r.status(), 200);
    let a: Value = r.json().await.unwrap();
    let targets: Vec<f64> = a["targets"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["target"].as_f64().unwrap())
        .collect();
    assert_eq!(targets, vec![0.0, 10.0, 20.0, 30.0, 40.0]);
    // Every reading +2 µm up, −1 µm down: B = 3 µm, E = 3 µm, s = 0, R = 3 µm, A = 3 µm
    // (to the few nm the lag's rest inside the 10 nm settling floor leaves).
    for f in ["B", "E", "R"] {
        assert!((um(&a, f) - 3.0).abs() < 0.01, "{f}: {} µm", um(&a, f));
    }
    assert!(um(&a, "E_fwd").abs() < 0.01);
    let used = a["used"].as_array().unwrap();
    assert_eq!(used.len(), 30);
    assert!(
        used.iter()
            .all(|u| u["samples"][0].as_u64() > u["dwell"][0].as_u64())
    );
    assert_eq!(used[0]["direction"], "fwd");
    assert!(
        a["ignored"][0]["reason"]
            .as_str()
            .unwrap()
            .contains("start position"),
        "{}",
        a["ignored"]
    );
    assert!(a["warnings"].to_string().contains("3 cycles"));
}

fn ring(c: [f64; 2], n: usize, r: impl Fn(f64) -> f64) -> Vec<[f64; 2]> {
    (0..n)
        .map(|k| {
            let t = std::f64::consts::TAU * k as f64 / n as f64;
            [c[0] + r(t) * t.cos(), c[1] + r(t) * t.sin()]
        })
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn iso230_4_closed_form_circles() {
    let app = spawn_app().await;
    // Three lobes of 4 µm on R 50.003 about (12.5, −7.25): G = 8 µm, F_max = 7, F_min = −1.
    let pts = ring([12.5, -7.25], 360, |t| 50.003 + 0.004 * (3.0 * t).cos());
    let r = app
        .post_json("/v1/iso230-4", &json!({"points": pts, "radius": 50.0}))
        .await;
    assert_eq!(r.status(), 200);
    let a: Value = r.json().await.unwrap();
    close(&a, "G", 8.0);
    close(&a, "F_max", 7.0);
    close(&a, "F_min", -1.0);
    close(&a, "radius_fit", 50003.0);
    assert!((a["centre"][0].as_f64().unwrap() - 12.5).abs() < 1e-9);
    assert!(a.get("H").is_none());
    // A reverse run with the opposite lobes: the radii differ by 2·4 µm·cos 3θ, so H = 8 µm.
    let rev = ring([12.5, -7.25], 360, |t| 50.003 - 0.004 * (3.0 * t).cos());
    let r = app
        .post_json(
            "/v1/iso230-4",
            &json!({"points": pts, "reverse_points": rev, "radius": 50.0}),
        )
        .await;
    let a: Value = r.json().await.unwrap();
    close(&a, "H", 8.0);
    close(&a["reverse"], "G", 8.0);
    println!(
        "ISO 230-4 three-lobe circle over HTTP: G {:.2} F_max {:.2} F_min {:.2} H {:.2} µm",
        um(&a, "G"),
        um(&a, "F_max"),
        um(&a, "F_min"),
        um(&a, "H")
    );
    assert_problem(
        app.post_json("/v1/iso230-4", &json!({"points": pts, "radius": -1}))
            .await,
        400,
        &["radius"],
    )
    .await;
    assert_problem(
        app.post_json(
            "/v1/iso230-4",
            &json!({"points": [[0, 0], [1, 1]], "radius": 1}),
        )
        .await,
        422,
        &["at least 3"],
    )
    .await;
    assert_problem(
        app.post_json(
            "/v1/iso230-4",
            &json!({"points": pts, "radius": 50, "reverse_points": [[0, 0]]}),
        )
        .await,
        422,
        &["reverse_points"],
    )
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn iso230_4_simulated_ballbar_matches_the_first_order_servo() {
    let app = spawn_app().await;
    // Equal first-order loops (kv = 30 1/s) on X and Y: in steady state the path is a circle
    // of radius R/sqrt(1 + (ω/kv)²). R 50 mm at 2000 mm/min: ω = 0.6667 rad/s, so
    // F = 50/sqrt(1 + 0.022222²) − 50 = −12.34 µm on both runs, G ≈ 0 and H ≈ 0.
    let m = json!({"kinematics": "xyz", "axes": {"X": {"kv": 30.0}, "Y": {"kv": 30.0}, "Z": {"kv": 30.0}}});
    assert!(
        app.put_json("/v1/machines/round", &m)
            .await
            .status()
            .is_success()
    );
    let r = app
        .post_json(
            "/v1/machines/round/iso230-4/simulate",
            &json!({"radius": 50.0, "feed": 2000.0}),
        )
        .await;
    assert_eq!(r.status(), 200);
    let a: Value = r.json().await.unwrap();
    let want = 50.0 / (1.0 + (2000.0 / 60.0 / 50.0 / 30.0_f64).powi(2)).sqrt() - 50.0;
    for dir in ["ccw", "cw"] {
        let run = &a["runs"][dir];
        let f = run["F_max"].as_f64().unwrap();
        assert!(
            (f - want).abs() < 0.5e-3,
            "{dir}: F_max {f}, closed form {want}"
        );
        assert!(run["G"].as_f64().unwrap() < 0.5e-3, "{dir}: {}", run["G"]);
        assert!(
            run["gcode"]
                .as_str()
                .unwrap()
                .contains(if dir == "cw" { "G2" } else { "G3" })
        );
    }
    assert!(a["H"].as_f64().unwrap() < 0.5e-3, "H {}", a["H"]);
    let f_round = a["runs"]["ccw"]["F_max"].as_f64().unwrap() * 1e3;
    // Mismatched loops (X kv 30 with feed-forward, Y kv 20): an ellipse, tilted the other way
    // in the other direction, so G and H are tens of µm.
    let m = json!({"kinematics": "xyz", "axes": {"X": {"kv": 30.0, "kff": 0.5}, "Y": {"kv": 20.0}, "Z": {"kv": 30.0}}});
    assert!(
        app.put_json("/v1/machines/skew", &m)
            .await
            .status()
            .is_success()
    );
    let r = app
        .post_json(
            "/v1/machines/skew/iso230-4/simulate",
            &json!({"radius": 50.0, "feed": 2000.0, "centre": [100, 50]}),
        )
        .await;
    let a: Value = r.json().await.unwrap();
    let g = a["runs"]["ccw"]["G"].as_f64().unwrap();
    let h = a["H"].as_f64().unwrap();
    assert!(g > 0.01 && h > 0.01, "G {g} H {h}");
    println!(
        "simulated ballbar, kv 30/30: F {:.2} µm (closed form {:.2}); kv 30+ff/20: G {:.1} µm, H {:.1} µm",
        f_round,
        want * 1e3,
        g * 1e3,
        h * 1e3
    );
    assert_problem(
        app.post_json(
            "/v1/machines/skew/iso230-4/simulate",
            &json!({"radius": 50.0, "directions": ["up"]}),
        )
        .await,
        400,
        &["directions"],
    )
    .await;
    assert_problem(
        app.post_json(
            "/v1/machines/none/iso230-4/simulate",
            &json!({"radius": 5.0}),
        )
        .await,
        404,
        &["none"],
    )
    .await;
}

/// Runs stored per machine axis: before and after, listed oldest first with the change.
async fn stored_runs(app: TestApp) {
    assert!(
        app.put_json("/v1/machines/m1", &crate::helpers::machine_xyz())
            .await
            .status()
            .is_success()
    );
    let mut before = hand_body(1.0);
    before["label"] = json!("before compensation");
    let r = app
        .post_json("/v1/machines/m1/axes/X/iso230-2", &before)
        .await;
    assert_eq!(r.status(), 201);
    let loc = r.headers()["location"].to_str().unwrap().to_string();
    let first: Value = r.json().await.unwrap();
    assert_eq!(
        loc,
        format!(
            "/v1/machines/m1/axes/X/iso230-2/{}",
            first["id"].as_str().unwrap()
        )
    );
    close(&first, "R", 10.0);
    let mut after = hand_body(0.5);
    after["label"] = json!("after compensation");
    let r = app
        .post_json("/v1/machines/m1/axes/X/iso230-2", &after)
        .await;
    assert_eq!(r.status(), 201);
    let list: Value = app
        .get("/v1/machines/m1/axes/X/iso230-2")
        .await
        .json()
        .await
        .unwrap();
    let runs = list["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 2);
    assert_eq!(runs[0]["label"], "before compensation");
    close(&runs[1], "R", 5.0);
    close(&runs[1], "E", 4.0);
    close(&list["change"], "R", -5.0);
    close(&list["change"], "A", -6.0);
    let one: Value = app.get(&loc).await.json().await.unwrap();
    assert_eq!(one["input"]["targets"], before["targets"]);
    assert_eq!(one["axis"], "X");
    assert!(one["created_at"].as_str().unwrap().ends_with('Z'));
    // Other axes are separate; bad axis, unknown machine and run are refused.
    let y: Value = app
        .get("/v1/machines/m1/axes/Y/iso230-2")
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(y["runs"], json!([]));
    assert_problem(
        app.get("/v1/machines/m1/axes/Q/iso230-2").await,
        400,
        &["axis 'Q'"],
    )
    .await;
    assert_problem(
        app.post_json("/v1/machines/nope/axes/X/iso230-2", &before)
            .await,
        404,
        &["nope"],
    )
    .await;
    assert_problem(
        app.get("/v1/machines/m1/axes/X/iso230-2/zzz").await,
        404,
        &["zzz"],
    )
    .await;
    // Deleting the machine deletes its runs.
    assert_eq!(app.delete("/v1/machines/m1").await.status(), 204);
    assert!(
        app.put_json("/v1/machines/m1", &crate::helpers::machine_xyz())
            .await
            .status()
            .is_success()
    );
    let list: Value = app
        .get("/v1/machines/m1/axes/X/iso230-2")
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(list["runs"], json!([]));
}
on_both_backends!(stored_runs);
