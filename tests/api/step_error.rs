//! HTTP end to end: openapi.yaml `POST /v1/step-error` and the `step-error-*` routes — the exact
//! route against the Python study's test vectors, sample generation, training / fine-tuning as
//! jobs, prediction, and bad input.

use crate::helpers::*;
use serde_json::{Value, json};

/// The study's test vectors (vendored in `tests/data/step/`) as (segment JSON, e_um).
fn vectors() -> Vec<(Value, f64)> {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/step/");
    let main =
        std::fs::read_to_string(format!("{dir}testvectors.csv")).expect("reference step vectors");
    let pm = std::fs::read_to_string(format!("{dir}testvectors_pm.csv"))
        .expect("reference step vectors");
    let mut pts: std::collections::HashMap<String, Vec<Value>> = Default::default();
    for line in pm.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let p: Vec<f64> = f[4..7].iter().map(|v| v.parse().unwrap()).collect();
        pts.entry(f[..3].join(",")).or_default().push(json!(p));
    }
    main.lines()
        .skip(1)
        .map(|line| {
            let f: Vec<&str> = line.split(',').collect();
            let n: Vec<f64> = f.iter().map(|v| v.parse().unwrap()).collect();
            let seg = json!({"cl": [[n[15], n[16], n[17]], [n[18], n[19], n[20]]], "cc": pts[&f[..3].join(",")]});
            (seg, n[27])
        })
        .collect()
}

async fn samples(app: &TestApp, reference: u32, lines: usize, points: usize) -> Value {
    let r = app
        .post_json(
            "/v1/step-error/samples",
            &json!({"surface": {"reference": reference}, "plan": {"tool_radius_mm": 5.0, "lines": lines, "points_per_line": points}}),
        )
        .await;
    assert_eq!(r.status(), 200);
    r.json().await.unwrap()
}

/// The exact route reproduces the study's labels (2001 dense points on the true surface) to
/// 2e-5 µm on all 615 vectors of the three surfaces.
async fn exact_matches_reference_vectors(app: TestApp) {
    let v = vectors();
    let segs: Vec<Value> = v.iter().map(|(s, _)| s.clone()).collect();
    let r = app
        .post_json(
            "/v1/step-error",
            &json!({"tool_radius": 5.0, "segments": segs}),
        )
        .await;
    assert_eq!(r.status(), 200);
    let body: Value = r.json().await.unwrap();
    let e = body["step_errors"].as_array().unwrap();
    assert_eq!(e.len(), 615);
    for (i, ((_, want_um), got)) in v.iter().zip(e).enumerate() {
        let got_um = got.as_f64().unwrap() * 1000.0;
        assert!(
            (got_um - want_um).abs() < 2e-5,
            "vector {i}: {got_um} vs {want_um} um"
        );
    }
    assert!(body["inflections"].as_array().unwrap().len() < 615);
}
on_both_backends!(exact_matches_reference_vectors);

async fn exact_rejects_bad_input(app: TestApp) {
    let seg = vectors()[0].0.clone();
    let app = &app;
    let post = |b: Value| async move { app.post_json("/v1/step-error", &b).await };
    assert_problem(
        post(json!({"segments": [seg.clone()]})).await,
        400,
        &["tool_radius"],
    )
    .await;
    assert_problem(
        post(json!({"tool_radius": -1.0, "segments": [seg.clone()]})).await,
        400,
        &["tool_radius"],
    )
    .await;
    assert_problem(
        post(json!({"tool_radius": 5.0, "segments": []})).await,
        400,
        &["segments is empty"],
    )
    .await;
    assert_problem(
        post(json!({"tool_radius": 5.0, "segments": [seg.clone()], "x": 1})).await,
        400,
        &["unknown field"],
    )
    .await;
    let mut short = seg.clone();
    short["cc"] = json!([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]);
    assert_problem(
        post(json!({"tool_radius": 5.0, "segments": [seg.clone(), short]})).await,
        422,
        &["segments[1]"],
    )
    .await;
    // tool radius that does not match |cl - cc|
    assert_problem(
        post(json!({"tool_radius": 4.0, "segments": [seg.clone()]})).await,
        422,
        &["segments[0]", "tool_radius"],
    )
    .await;
    let mut bad = seg.clone();
    bad["cl"] = json!([[0.0, 0.0, 5.0]]);
    assert_problem(
        post(json!({"tool_radius": 5.0, "segments": [bad]})).await,
        400,
        &["segments[0]", "cl must be two points"],
    )
    .await;
    let mut extra = seg.clone();
    extra["normals"] = json!([]);
    assert_problem(
        post(json!({"tool_radius": 5.0, "segments": [extra]})).await,
        400,
        &["unknown or repeated field 'normals'"],
    )
    .await;
    // 1e999 overflows to infinity: rejected as non-finite
    let raw = r#"{"tool_radius": 5, "segments": [{"cl": [[0,0,5],[1,0,5]], "cc": [[0,0,0],[0.5,0,1e999],[1,0,0]]}]}"#;
    let r = app
        .post_raw(
            "/v1/step-error",
            "application/json",
            raw.as_bytes().to_vec(),
        )
        .await;
    assert_problem(r, 400, &["segments[0]: cc[1][2] is not a finite number"]).await;
    let r = app
        .post_raw("/v1/step-error", "text/plain", b"{}".to_vec())
        .await;
    assert_problem(r, 415, &["application/json"]).await;
}
on_both_backends!(exact_rejects_bad_input);

/// The decoder's sentences for bodies that are not the contract's shape, in small bodies and
/// in large ones (decoded in blocks while they arrive).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn exact_explains_malformed_bodies() {
    let app = spawn_app().await;
    let seg = vectors()[0].0.to_string();
    let post = |raw: String| {
        let app = &app;
        async move {
            app.post_raw("/v1/step-error", "application/json", raw.into_bytes())
                .await
        }
    };
    for (raw, needles) in [
        (
            format!(r#"{{"tool_radius": 5, "tool_radius": 5, "segments": [{seg}]}}"#),
            &["tool_radius appears twice"][..],
        ),
        (
            format!(r#"{{"tool_radius": "5", "segments": [{seg}]}}"#),
            &["tool_radius must be a number"],
        ),
        (
            format!(r#"{{"tool_radius": 5, "segments": [{seg}]}} x"#),
            &["invalid JSON body at byte", "expected the end of the body"],
        ),
        (
            format!(r#"{{"tool_radius": 5, "segments": [{seg} {seg}]}}"#),
            &["segments[1]: invalid JSON at byte", "expected ',' or ']'"],
        ),
        (
            format!(r#"{{"tool_radius": 5, "segments": [{seg}, 7]}}"#),
            &["segments[1] must be an object"],
        ),
        (
            r#"{"tool_radius": 5, "segments": [{"cl": [[0,0,5],[1,0,5]], "cc": [[0,0,0],]}]}"#
                .to_string(),
            &["segments[0]: cc must be an array of points"],
        ),
        (
            r#"{"tool_radius": 5, "segments": [{"cl": [[0,0,5],[1,0,5]]}]}"#.to_string(),
            &["segments[0]: cc is missing"],
        ),
    ] {
        assert_problem(post(raw).await, 400, needles).await;
    }
    // Over 1 MB: decoded in blocks on all cores; errors still name the segment in the whole
    // array, and the answers are the segment-by-segment ones.
    let one: Value = app
        .post_json(
            "/v1/step-error",
            &json!({"tool_radius": 5.0, "segments": [vectors()[0].0]}),
        )
        .await
        .json()
        .await
        .unwrap();
    let many = vec![seg.as_str(); 3000].join(",\n");
    let r = post(format!(r#"{{"segments": [{many}], "tool_radius": 5}}"#)).await;
    assert_eq!(r.status(), 200);
    let body: Value = r.json().await.unwrap();
    let e = body["step_errors"].as_array().unwrap();
    assert_eq!(e.len(), 3000);
    assert!(e.iter().all(|v| *v == one["step_errors"][0]), "{}", e[0]);
    let mut segs = vec![seg.clone(); 3000];
    segs[2500] = seg.replace("\"cc\"", "\"cx\"");
    let r = post(format!(
        r#"{{"tool_radius": 5, "segments": [{}]}}"#,
        segs.join(",")
    ))
    .await;
    assert_problem(r, 400, &["segments[2500]: unknown or repeated field 'cx'"]).await;
}

/// A body without Content-Length (chunked) is cut off at the size limit with 413.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn exact_refuses_an_oversize_chunked_body() {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let app = spawn_app_with(|c| c.max_body_bytes = 4096).await;
    let mut s = tokio::net::TcpStream::connect(app.addr.trim_start_matches("http://"))
        .await
        .unwrap();
    let mut req = String::from(
        "POST /v1/step-error HTTP/1.1\r\nHost: localhost\r\nContent-Type: application/json\r\n\
         Transfer-Encoding: chunked\r\nConnection: close\r\n\r\n",
    );
    for _ in 0..4 {
        let data = format!("{{\"segments\": [{}", " ".repeat(2000));
        req.push_str(&format!("{:x}\r\n{data}\r\n", data.len()));
    }
    req.push_str("0\r\n\r\n");
    s.write_all(req.as_bytes()).await.unwrap();
    let mut answer = String::new();
    s.read_to_string(&mut answer).await.unwrap();
    assert!(answer.starts_with("HTTP/1.1 413"), "{answer}");
    assert!(answer.contains("longer than 4096 bytes"), "{answer}");
}

/// Samples of a stored grid surface: flat grid → every step error is 0.
async fn samples_from_stored_grid(app: TestApp) {
    seed_machine_and_surface(&app, "m", "flat", 12, 6).await;
    let r = app
        .post_json(
            "/v1/machines/m/surfaces/flat/step-error-samples",
            &json!({"plan": {"step_over_mm": 1.0, "points_per_line": 11}}),
        )
        .await;
    assert_eq!(r.status(), 200);
    let b: Value = r.json().await.unwrap();
    assert_eq!(
        b["tool_radius"], 3.0,
        "defaults to the surface's tool_radius"
    );
    assert_eq!(b["segments"].as_array().unwrap().len(), 6 * 10);
    assert!(
        b["step_errors"]
            .as_array()
            .unwrap()
            .iter()
            .all(|e| e.as_f64().unwrap().abs() < 1e-12)
    );
    let r = app
        .post_json(
            "/v1/machines/m/surfaces/nope/step-error-samples",
            &json!({"plan": {"lines": 2, "points_per_line": 3}}),
        )
        .await;
    assert_problem(r, 404, &["nope"]).await;
    let r = app.post_json("/v1/step-error/samples", &json!({"surface": {"reference": 9}, "plan": {"tool_radius_mm": 5.0, "lines": 2, "points_per_line": 3}})).await;
    assert_problem(r, 400, &["reference"]).await;
}
on_both_backends!(samples_from_stored_grid);

/// Train on surface-1 samples, predict (close to exact), fine-tune a second surface from it.
async fn train_predict_and_fine_tune(app: TestApp) {
    seed_machine_and_surface(&app, "m", "s1", 5, 5).await;
    seed_machine_and_surface(&app, "m", "s3", 5, 5).await;
    // No model yet: 404 saying how to train one.
    let s1 = samples(&app, 1, 60, 100).await;
    let segs = s1["segments"].clone();
    let r = app
        .post_json(
            "/v1/machines/m/surfaces/s1/step-error-model/predict",
            &json!({"segments": segs}),
        )
        .await;
    assert_problem(r, 404, &["train one", "step-error-model"]).await;
    let r = app
        .post_json(
            "/v1/machines/m/surfaces/s1/step-error-model",
            &json!({"tool_radius": 5.0, "segments": segs, "epochs": 60}),
        )
        .await;
    assert_eq!(r.status(), 202);
    let job: Value = r.json().await.unwrap();
    let done = app.wait_job(job["job"].as_str().unwrap()).await;
    let res = &done["result"];
    assert!(res["test_max_abs_um"].as_f64().unwrap() < 2.0, "{res}");
    let info: Value = app
        .get("/v1/machines/m/surfaces/s1/step-error-model")
        .await
        .json()
        .await
        .unwrap();
    // The default inputs (model version 2): the distance profile at 20 points plus 2, then the
    // hidden layers 28 and 20, two outputs (was 67 local-frame coordinate inputs).
    assert_eq!(info["layers"], json!([22, 28, 20, 2]));
    // Prediction vs exact on the training surface.
    let r = app
        .post_json(
            "/v1/machines/m/surfaces/s1/step-error-model/predict",
            &json!({"segments": segs}),
        )
        .await;
    assert_eq!(r.status(), 200);
    let p: Value = r.json().await.unwrap();
    let (pred, exact) = (
        p["step_errors"].as_array().unwrap(),
        s1["step_errors"].as_array().unwrap(),
    );
    assert_eq!(pred.len(), exact.len());
    let mean_um = pred
        .iter()
        .zip(exact)
        .map(|(a, b)| (a.as_f64().unwrap() - b.as_f64().unwrap()).abs())
        .sum::<f64>()
        * 1000.0
        / pred.len() as f64;
    assert!(mean_um < 0.3, "mean abs error {mean_um} um");
    // Fine-tune on surface 3 from the surface-1 model: the held-out part is no worse than before.
    let s3 = samples(&app, 3, 20, 100).await;
    let r = app
        .post_json(
            "/v1/machines/m/surfaces/s3/step-error-model",
            &json!({"tool_radius": 5.0, "segments": s3["segments"], "base": {"machine": "m", "surface": "s1"}, "epochs": 20, "test_fraction": 0.5}),
        )
        .await;
    assert_eq!(r.status(), 202);
    let job: Value = r.json().await.unwrap();
    let done = app.wait_job(job["job"].as_str().unwrap()).await;
    let res = &done["result"];
    let (before, after) = (
        res["base_test_mean_abs_um"].as_f64().unwrap(),
        res["test_mean_abs_um"].as_f64().unwrap(),
    );
    assert!(
        after <= before * 1.1 + 1e-9,
        "fine-tuning: {before} -> {after} um"
    );
    assert_eq!(
        app.post_json(
            "/v1/machines/m/surfaces/s3/step-error-model/predict",
            &json!({"segments": s3["segments"]})
        )
        .await
        .status(),
        200
    );
    // A base that does not exist.
    let r = app
        .post_json("/v1/machines/m/surfaces/s3/step-error-model", &json!({"tool_radius": 5.0, "segments": s3["segments"], "base": {"machine": "m", "surface": "zz"}}))
        .await;
    assert_problem(r, 404, &["base model", "zz"]).await;
}
on_both_backends!(train_predict_and_fine_tune);

/// Training needs the admin role; computing routes need only read.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn training_needs_admin() {
    let mut app = spawn_app_with(|c| c.tokens = Some("r-tok read, a-tok admin".into())).await;
    app.token = Some("a-tok".into());
    seed_machine_and_surface(&app, "m", "s", 5, 5).await;
    app.token = Some("r-tok".into());
    let seg = vectors()[0].0.clone();
    let r = app
        .post_json(
            "/v1/machines/m/surfaces/s/step-error-model",
            &json!({"tool_radius": 5.0, "segments": [seg.clone()]}),
        )
        .await;
    assert_problem(r, 403, &[]).await;
    let r = app
        .post_json(
            "/v1/step-error",
            &json!({"tool_radius": 5.0, "segments": [seg]}),
        )
        .await;
    assert_eq!(r.status(), 200);
}
