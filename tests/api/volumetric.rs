//! HTTP end-to-end tests of the volumetric error map routes (openapi.yaml
//! `/v1/machines/{machine}/volumetric-map`), on a synthetic machine with known ISO 230-1 errors.

use crate::helpers::*;

use serde_json::{Value, json};
use truecut::volumetric::{ShapeFamily, SyntheticMachine};

const MAP: &str = "/v1/machines/m/volumetric-map";

fn machine() -> SyntheticMachine {
    SyntheticMachine::new(8, ShapeFamily::TrendAndWaviness)
}

/// Map body of a synthetic 5×4×3 grid; small network budget to keep the test quick.
fn grid_body(m: &SyntheticMachine, model: &str) -> Value {
    let d = m.measure_grid([5, 4, 3], 3);
    json!({"nodes": d.nodes, "errors": d.errors, "model": model,
           "tool_offset_mm": m.tool_offset_mm, "epochs": 100})
}

async fn put_machine(app: &TestApp) {
    let r = app.put_json("/v1/machines/m", &machine_xyz()).await;
    assert!(r.status().is_success(), "PUT machine: {}", r.status());
}

async fn fit_predict_and_describe(app: TestApp) {
    put_machine(&app).await;
    let m = machine();
    let r = app.put_json(MAP, &grid_body(&m, "auto")).await;
    assert_eq!(r.status(), 201);
    let body: Value = r.json().await.unwrap();
    assert_eq!(body["requested"], "auto");
    assert_eq!(body["truecut_version"], truecut::version(), "issue 25");
    assert_eq!(body["scores"].as_array().unwrap().len(), 4, "{body}");
    let chosen = body["model"].as_str().unwrap().to_string();
    assert!(body["parameter_count"].as_u64().unwrap() > 0);
    assert!(body["scores"][0]["cv_rms_mm"].as_f64().unwrap() > 0.0);
    // the hybrid's residual part: spline by default, the network on request
    let mut hybrid_counts = vec![];
    for residual in ["spline", "network"] {
        let mut b = grid_body(&m, "hybrid");
        b["residual"] = json!(residual);
        let r = app.put_json(MAP, &b).await;
        assert_eq!(r.status(), 200, "hybrid with {residual}");
        let body: Value = r.json().await.unwrap();
        assert_eq!(body["model"], "hybrid");
        assert_eq!(body["residual"], residual);
        hybrid_counts.push(body["parameter_count"].as_u64().unwrap());
    }
    // replacing answers 200
    let r = app.put_json(MAP, &grid_body(&m, "kinematic")).await;
    assert_eq!(r.status(), 200);
    let body: Value = r.json().await.unwrap();
    assert_eq!(body["model"], "kinematic");
    assert!(body["residual"].is_null(), "{body}");
    // the error motions' representation: cubic regression splines for new maps
    assert_eq!(body["error_motions"]["basis"], "spline", "{body}");
    let terms = body["error_motions"]["terms_per_axis"].as_array().unwrap();
    assert_eq!(terms.len(), 3);
    assert!(
        terms.iter().all(|t| (2..=6).contains(&t.as_u64().unwrap())),
        "{terms:?}"
    );
    let kinematic_count = body["parameter_count"].as_u64().unwrap();
    assert!(
        hybrid_counts.iter().all(|&c| c > kinematic_count),
        "hybrid {hybrid_counts:?} vs kinematic {kinematic_count}"
    );
    // predictions follow the machine off the grid, outside points are flagged
    let pts = m.random_points(200, 4);
    let mut query = pts.clone();
    query.push([1000.0, 0.0, 0.0]);
    let r = app
        .post_json(&format!("{MAP}/predict"), &json!({"points": query}))
        .await;
    assert_eq!(r.status(), 200);
    let p: Value = r.json().await.unwrap();
    let errs = p["errors"].as_array().unwrap();
    assert_eq!(errs.len(), 201);
    let flags: Vec<bool> = p["out_of_box"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_bool().unwrap())
        .collect();
    assert!(flags[..200].iter().all(|f| !f) && flags[200]);
    let mut se = 0.0;
    for (q, e) in pts.iter().zip(errs) {
        let t = m.error(*q);
        se += (0..3)
            .map(|j| (e[j].as_f64().unwrap() - t[j]).powi(2))
            .sum::<f64>();
    }
    let rms = (se / 200.0).sqrt();
    assert!(
        rms < 3e-3,
        "off-grid RMS {rms} mm (chosen by auto before: {chosen})"
    );
    // the 21 components, with units
    let r = app.get(&format!("{MAP}?samples=5")).await;
    assert_eq!(r.status(), 200);
    let g: Value = r.json().await.unwrap();
    let axes = g["components"]["axes"].as_array().unwrap();
    let curves: usize = axes
        .iter()
        .map(|a| a["curves"].as_array().unwrap().len())
        .sum();
    assert_eq!(
        curves + g["components"]["squareness"].as_array().unwrap().len(),
        21
    );
    assert_eq!(axes[0]["curves"][0]["name"], "EXX");
    assert_eq!(axes[0]["curves"][0]["unit"], "um");
    assert_eq!(axes[0]["position_mm"].as_array().unwrap().len(), 5);
    assert!(g["components"]["squareness"][0]["value_urad"].is_number());
    // compensation table
    let r = app.get(&format!("{MAP}/table?points=3,2,2")).await;
    assert_eq!(r.status(), 200);
    assert!(
        r.headers()["content-type"]
            .to_str()
            .unwrap()
            .starts_with("text/csv")
    );
    let csv = r.text().await.unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines[0], "x,y,z,dx,dy,dz,comp_x,comp_y,comp_z,out_of_box");
    assert_eq!(lines.len(), 1 + 12);
    let r = app
        .get(&format!("{MAP}/table?points=30&max_points_per_axis=25"))
        .await;
    assert_problem(r, 400, &["controller limit is 25"]).await;
    // the map survives a restart-free reload from the store and can be deleted
    assert_eq!(app.delete(MAP).await.status(), 204);
    let r = app
        .post_json(
            &format!("{MAP}/predict"),
            &json!({"points": [[0.0, 0.0, 0.0]]}),
        )
        .await;
    assert_problem(
        r,
        404,
        &["no volumetric map", "PUT /v1/machines/m/volumetric-map"],
    )
    .await;
}
on_both_backends!(fit_predict_and_describe);

async fn csv_upload_and_trilinear(app: TestApp) {
    put_machine(&app).await;
    let m = machine();
    let d = m.measure_grid([4, 3, 3], 5);
    let mut csv = String::from("x,y,z,dx,dy,dz\n");
    for (p, e) in d.nodes.iter().zip(&d.errors) {
        csv += &format!("{},{},{},{},{},{}\n", p[0], p[1], p[2], e[0], e[1], e[2]);
    }
    let r = app
        .client
        .put(app.url(&format!("{MAP}?model=trilinear&max_points_per_axis=25")))
        .header("content-type", "text/csv")
        .body(csv)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 201);
    let body: Value = r.json().await.unwrap();
    assert_eq!(body["model"], "trilinear");
    assert_eq!(body["parameter_count"], 3 * 36 + 10);
    // trilinear reproduces the nodes
    let r = app
        .post_json(&format!("{MAP}/predict"), &json!({"points": [d.nodes[7]]}))
        .await;
    let p: Value = r.json().await.unwrap();
    for j in 0..3 {
        assert!((p["errors"][0][j].as_f64().unwrap() - d.errors[7][j]).abs() < 1e-12);
    }
    // Wang, Dai & Hong's axis lines build the grid by the additive rule
    let line = |k: usize| {
        let positions: Vec<f64> = (0..4).map(|i| m.travel_mm[k] * i as f64 / 3.0).collect();
        let errors: Vec<[f64; 3]> = positions
            .iter()
            .map(|&q| {
                let mut p = [0.0; 3];
                p[k] = q;
                m.error(p)
            })
            .collect();
        json!({"positions": positions, "errors": errors})
    };
    let r = app
        .put_json(MAP, &json!({"lines": {"reference": [0.0, 0.0, 0.0], "x": line(0), "y": line(1), "z": line(2)}, "model": "trilinear"}))
        .await;
    assert_eq!(r.status(), 200);
    assert_eq!(r.json::<Value>().await.unwrap()["n_nodes"], 64);
}
on_both_backends!(csv_upload_and_trilinear);

async fn bad_input_is_4xx(app: TestApp) {
    let m = machine();
    let r = app.put_json(MAP, &grid_body(&m, "auto")).await;
    assert_problem(r, 404, &["machine 'm' does not exist"]).await;
    put_machine(&app).await;
    let mut b = grid_body(&m, "auto");
    b["errors"].as_array_mut().unwrap().pop();
    assert_problem(
        app.put_json(MAP, &b).await,
        400,
        &["'errors' has 59 entries", "one entry per node"],
    )
    .await;
    let b = grid_body(&m, "spline");
    assert_problem(
        app.put_json(MAP, &b).await,
        400,
        &["unknown model 'spline'"],
    )
    .await;
    let mut b = grid_body(&m, "hybrid");
    b["residual"] = json!("kriging");
    assert_problem(
        app.put_json(MAP, &b).await,
        400,
        &["residual must be \"spline\" or \"network\"", "'kriging'"],
    )
    .await;
    let d = m.measure_grid([8, 6, 5], 1);
    let b = json!({"nodes": d.nodes, "errors": d.errors, "epochs": 20_000});
    assert_problem(
        app.put_json(MAP, &b).await,
        400,
        &["epochs × nodes = 20000 × 240", "at most 16666 epochs"],
    )
    .await;
    let mut b = grid_body(&m, "auto");
    b["epochs"] = json!(0);
    assert_problem(app.put_json(MAP, &b).await, 400, &["epochs"]).await;
    let b = json!({"nodes": [[0.0, 0.0, 0.0]]});
    assert_problem(app.put_json(MAP, &b).await, 400, &["'errors' is missing"]).await;
    let d = m.measure(m.random_points(40, 1), 2);
    let b = json!({"nodes": d.nodes, "errors": d.errors, "model": "trilinear"});
    assert_problem(
        app.put_json(MAP, &b).await,
        422,
        &["not a full rectilinear grid"],
    )
    .await;
    let flat: Vec<[f64; 3]> = (0..10).map(|i| [i as f64, (i % 3) as f64, 5.0]).collect();
    let b = json!({"nodes": flat, "errors": vec![[0.0; 3]; 10]});
    assert_problem(app.put_json(MAP, &b).await, 422, &["same z coordinate"]).await;
    let r = app
        .client
        .put(app.url(MAP))
        .header("content-type", "text/csv")
        .body("x,y,z,dx,dy\n1,2,3,4,5\n")
        .send()
        .await
        .unwrap();
    assert_problem(r, 400, &["no column 'dz'"]).await;
    let r = app
        .post_json(
            &format!("{MAP}/predict"),
            &json!({"points": [[0.0, 0.0, 0.0]]}),
        )
        .await;
    assert_problem(r, 404, &["no volumetric map"]).await;
    app.put_json(MAP, &grid_body(&m, "kinematic")).await;
    let r = app
        .post_json(&format!("{MAP}/predict"), &json!({"points": []}))
        .await;
    assert_problem(r, 400, &["points"]).await;
    let many: Vec<[f64; 3]> = (0..100_001).map(|i| [i as f64, 0.0, 0.0]).collect();
    let r = app
        .post_json(&format!("{MAP}/predict"), &json!({"points": many}))
        .await;
    assert_problem(r, 413, &["at most 100000"]).await;
    let b = json!({"nodes": &many[..20_001], "errors": vec![[0.0; 3]; 20_001]});
    assert_problem(app.put_json(MAP, &b).await, 413, &["at most 20000"]).await;
    let r = app.get(&format!("{MAP}/table?points=1,2,2")).await;
    assert_problem(r, 400, &["at least 2 points"]).await;
    let r = app.get(&format!("{MAP}/table?colour=red")).await;
    assert_problem(r, 400, &["unknown query parameter 'colour'"]).await;
    // nothing partial was stored by the rejected PUTs: the kinematic map is still there
    let g: Value = app.get(MAP).await.json().await.unwrap();
    assert_eq!(g["model"], "kinematic");
    assert_eq!(
        g["truecut_version"],
        truecut::version(),
        "stored with the map"
    );
}
on_both_backends!(bad_input_is_4xx);

async fn fitting_needs_admin(mut app: TestApp) {
    app.token = Some("admin-token".into());
    put_machine(&app).await;
    let m = machine();
    app.token = Some("writer-token".into());
    assert_problem(
        app.put_json(MAP, &grid_body(&m, "kinematic")).await,
        403,
        &[],
    )
    .await;
    app.token = Some("admin-token".into());
    assert_eq!(
        app.put_json(MAP, &grid_body(&m, "kinematic"))
            .await
            .status(),
        201
    );
    app.token = Some("reader-token".into());
    let r = app
        .post_json(
            &format!("{MAP}/predict"),
            &json!({"points": [[1.0, 2.0, 3.0]]}),
        )
        .await;
    assert_eq!(r.status(), 200);
    assert_eq!(app.get(MAP).await.status(), 200);
}
on_both_backends!(fitting_needs_admin, |c| c.tokens =
    Some("admin-token admin\nwriter-token write\nreader-token read\n".into()));

/// Whether machine `m` has a volumetric map, as the machine list says.
async fn has_map(app: &TestApp) -> bool {
    let list: Value = app.get("/v1/machines").await.json().await.unwrap();
    let m = list["machines"]
        .as_array()
        .unwrap()
        .iter()
        .find(|x| x["id"] == "m")
        .cloned()
        .unwrap();
    m["volumetric_map"].as_bool().unwrap()
}

/// Every PUT keeps the previous maps: list them, roll back (the predictions follow), refuse
/// unknown versions; a delete removes them all.
async fn versions_and_rollback(app: TestApp) {
    put_machine(&app).await;
    // The machine list says whether each machine has a map (so that a client, such as the
    // dashboard, asks only for what exists): not yet, then yes, then no again after a delete.
    assert!(!has_map(&app).await);
    let m = machine();
    let at = json!({"points": [[10.0, 20.0, 30.0]]});
    assert_eq!(
        app.put_json(MAP, &grid_body(&m, "trilinear"))
            .await
            .status(),
        201
    );
    let first: Value = app
        .post_json(&format!("{MAP}/predict"), &at)
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(
        app.put_json(MAP, &grid_body(&m, "kinematic"))
            .await
            .status(),
        200
    );
    let second: Value = app
        .post_json(&format!("{MAP}/predict"), &at)
        .await
        .json()
        .await
        .unwrap();
    assert_ne!(first["model"], second["model"]);
    let v: Value = app
        .get(&format!("{MAP}/versions"))
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(v["current"], 2, "{v}");
    assert!(has_map(&app).await);
    assert_eq!(v["versions"].as_array().unwrap().len(), 2, "{v}");
    assert_eq!(v["versions"][0]["version"], 2);
    assert_eq!(v["versions"][0]["sha256"].as_str().unwrap().len(), 64);
    let r = app
        .post_json(&format!("{MAP}/rollback"), &json!({"version": 1}))
        .await;
    assert_eq!(r.status(), 200);
    let back: Value = app
        .post_json(&format!("{MAP}/predict"), &at)
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(back, first, "version 1 is served again");
    assert_problem(
        app.post_json(&format!("{MAP}/rollback"), &json!({"version": 7}))
            .await,
        404,
        &["version 7", "2, 1"],
    )
    .await;
    assert_problem(
        app.post_json(&format!("{MAP}/rollback"), &json!({"version": 0}))
            .await,
        400,
        &["version"],
    )
    .await;
    assert_eq!(app.delete(MAP).await.status(), 204);
    assert_problem(app.get(&format!("{MAP}/versions")).await, 404, &["PUT"]).await;
    assert!(!has_map(&app).await);
}
on_both_backends!(versions_and_rollback);
