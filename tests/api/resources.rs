//! HTTP end to end on SQLite and PostgreSQL: machines, surfaces, measurements (JSON and
//! CSV uploads), restart persistence, bad input.

use crate::helpers::*;
use serde_json::{Value, json};

async fn machine_crud(app: TestApp) {
    let def = json!({"name": "DMU 50", "kinematics": "xyzac_table",
        "axes": {"X": {"kv": 30.0, "kff": 0.8, "inertia_kg": 120.0}, "C": {"kv": 20.0}},
        "geometry": {"c_offset": [0.0, 0.0, 100.0]}});
    let r = app.put_json("/v1/machines/m1", &def).await;
    assert_eq!(r.status(), 201);
    assert_eq!(r.headers()["location"], "/v1/machines/m1");
    // Stored exactly as PUT, unknown fields included.
    let got: Value = app.get("/v1/machines/m1").await.json().await.unwrap();
    assert_eq!(got, def);
    let def2 = json!({"kinematics": "xyz"});
    assert_eq!(app.put_json("/v1/machines/m1", &def2).await.status(), 200);
    assert_eq!(
        app.get("/v1/machines/m1")
            .await
            .json::<Value>()
            .await
            .unwrap(),
        def2
    );
    assert_eq!(
        app.put_json("/v1/machines/m2", &machine_xyz())
            .await
            .status(),
        201
    );
    let list: Value = app.get("/v1/machines").await.json().await.unwrap();
    let ids: Vec<&str> = list["machines"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["id"].as_str().unwrap())
        .collect();
    assert_eq!(ids, ["m1", "m2"]);
    assert_eq!(list["machines"][1]["definition"], machine_xyz());
    assert_eq!(app.delete("/v1/machines/m1").await.status(), 204);
    assert_problem(
        app.get("/v1/machines/m1").await,
        404,
        &["machine 'm1' does not exist", "PUT /v1/machines/m1"],
    )
    .await;
    assert_problem(app.delete("/v1/machines/m1").await, 404, &["m1"]).await;
}
on_both_backends!(machine_crud);

async fn surface_and_measurement_crud(app: TestApp) {
    seed_machine_and_surface(&app, "m", "s", 4, 3).await;
    let s: Value = app
        .get("/v1/machines/m/surfaces/s")
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(s["nominal"]["grid"]["nu"], 4);
    assert_eq!(s["nominal"]["grid"]["points"].as_array().unwrap().len(), 12);
    assert_eq!(s["tool_radius"], 3.0);
    let list: Value = app
        .get("/v1/machines/m/surfaces")
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(list["surfaces"][0]["id"], "s");

    // JSON deviations.
    let devs: Vec<f64> = (0..12).map(|i| (i as f64 - 6.0) * 0.01).collect();
    let r = app
        .post_json(
            "/v1/machines/m/surfaces/s/measurements",
            &json!({"deviations": devs}),
        )
        .await;
    assert_eq!(r.status(), 201);
    let created: Value = r.json().await.unwrap();
    assert_eq!(created["n"], 12);
    assert!((created["max_abs"].as_f64().unwrap() - 0.06).abs() < 1e-12);
    let mean: f64 = devs.iter().map(|d| d.abs()).sum::<f64>() / 12.0;
    assert!((created["mean_abs"].as_f64().unwrap() - mean).abs() < 1e-12);
    let id = created["id"].as_str().unwrap().to_string();
    let got: Value = app
        .get(&format!("/v1/machines/m/surfaces/s/measurements/{id}"))
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(got["deviations"], json!(devs));
    assert_eq!(got["id"], id.as_str());

    // JSON points: deviation is (measured - nominal) · n, normals +z.
    let pts: Vec<Value> = (0..12)
        .map(|k| json!([(k % 4) as f64 + 0.5, (k / 4) as f64, 0.02]))
        .collect();
    let r = app
        .post_json(
            "/v1/machines/m/surfaces/s/measurements",
            &json!({"points": pts, "id": "probe-2"}),
        )
        .await;
    assert_eq!(r.status(), 201);
    let got: Value = app
        .get("/v1/machines/m/surfaces/s/measurements/probe-2")
        .await
        .json()
        .await
        .unwrap();
    for d in got["deviations"].as_array().unwrap() {
        assert!((d.as_f64().unwrap() - 0.02).abs() < 1e-12, "{d}");
    }
    assert_eq!(got["points"].as_array().unwrap().len(), 12);

    // CSV, export layout with id column, semicolons and decimal commas.
    let mut csv = String::from("Point;X [mm];Y [mm];Z [mm]\r\n");
    for k in 0..12 {
        csv.push_str(&format!("P{k};{};{};-0,005\r\n", k % 4, k / 4));
    }
    let r = app
        .post_raw(
            "/v1/machines/m/surfaces/s/measurements?id=csv-1",
            "text/csv",
            csv,
        )
        .await;
    assert_eq!(r.status(), 201);
    let created: Value = r.json().await.unwrap();
    assert_eq!(created["id"], "csv-1");
    assert!((created["max_abs"].as_f64().unwrap() - 0.005).abs() < 1e-12);
    // CSV deviations, comma separated.
    let csv: String = std::iter::once("deviation\n".to_string())
        .chain((0..12).map(|k| format!("{}\n", k as f64 * 0.001)))
        .collect();
    let r = app
        .post_raw(
            "/v1/machines/m/surfaces/s/measurements",
            "text/csv; charset=utf-8",
            csv,
        )
        .await;
    assert_eq!(r.status(), 201);
    let csv_id = r.json::<Value>().await.unwrap()["id"]
        .as_str()
        .unwrap()
        .to_string();
    // CSV out.
    let r = app
        .client
        .get(app.url(&format!("/v1/machines/m/surfaces/s/measurements/{csv_id}")))
        .header("accept", "text/csv")
        .send()
        .await
        .unwrap();
    assert!(
        r.headers()["content-type"]
            .to_str()
            .unwrap()
            .starts_with("text/csv")
    );
    let text = r.text().await.unwrap();
    assert!(text.starts_with("deviation\n0\n0.001\n"), "{text}");

    let list: Value = app
        .get("/v1/machines/m/surfaces/s/measurements")
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(list["measurements"].as_array().unwrap().len(), 4);

    // Duplicate id.
    assert_problem(
        app.post_json(
            "/v1/machines/m/surfaces/s/measurements",
            &json!({"deviations": devs, "id": "probe-2"}),
        )
        .await,
        409,
        &["probe-2", "already exists"],
    )
    .await;
    // Changing the grid with measurements present is a conflict; same grid is fine.
    assert_problem(
        app.put_json("/v1/machines/m/surfaces/s", &flat_surface(3, 3))
            .await,
        409,
        &["4x3", "3x3"],
    )
    .await;
    assert_eq!(
        app.put_json("/v1/machines/m/surfaces/s", &flat_surface(4, 3))
            .await
            .status(),
        200
    );

    assert_eq!(
        app.delete("/v1/machines/m/surfaces/s/measurements/probe-2")
            .await
            .status(),
        204
    );
    assert_problem(
        app.get("/v1/machines/m/surfaces/s/measurements/probe-2")
            .await,
        404,
        &["probe-2"],
    )
    .await;
    assert_eq!(app.delete("/v1/machines/m/surfaces/s").await.status(), 204);
    assert_problem(
        app.get("/v1/machines/m/surfaces/s/measurements").await,
        404,
        &["surface 's'"],
    )
    .await;
    // Deleting the machine removes its surfaces.
    seed_machine_and_surface(&app, "m", "s2", 2, 2).await;
    assert_eq!(app.delete("/v1/machines/m").await.status(), 204);
    assert_eq!(
        app.put_json("/v1/machines/m", &machine_xyz())
            .await
            .status(),
        201
    );
    assert_problem(
        app.get("/v1/machines/m/surfaces/s2").await,
        404,
        &["surface 's2'"],
    )
    .await;
}
on_both_backends!(surface_and_measurement_crud);

async fn restart_persistence(mut app: TestApp) {
    seed_machine_and_surface(&app, "m", "s", 3, 3).await;
    let devs: Vec<f64> = (0..9).map(|i| i as f64 * 1e-3).collect();
    let r = app
        .post_json(
            "/v1/machines/m/surfaces/s/measurements",
            &json!({"deviations": devs, "id": "keep"}),
        )
        .await;
    assert_eq!(r.status(), 201);
    let old_addr = app.addr.clone();
    app.restart().await;
    assert_ne!(app.addr, old_addr, "restart binds a new port");
    assert_eq!(
        app.get("/v1/machines/m")
            .await
            .json::<Value>()
            .await
            .unwrap(),
        machine_xyz()
    );
    let got: Value = app
        .get("/v1/machines/m/surfaces/s/measurements/keep")
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(got["deviations"], json!(devs));
    app.stop().await;
}
on_both_backends!(restart_persistence);

async fn bad_input(app: TestApp) {
    seed_machine_and_surface(&app, "m", "s", 2, 2).await;
    let up = "/v1/machines/m/surfaces/s/measurements";
    // Ids.
    assert_problem(
        app.put_json("/v1/machines/bad%20id", &machine_xyz()).await,
        400,
        &["machine id", "A-Z"],
    )
    .await;
    let long = "x".repeat(65);
    assert_problem(
        app.get(&format!("/v1/machines/{long}")).await,
        400,
        &["1 to 64"],
    )
    .await;
    // Machine definitions.
    assert_problem(
        app.put_json("/v1/machines/m9", &json!({"axes": {}})).await,
        400,
        &["kinematics"],
    )
    .await;
    assert_problem(
        app.put_json("/v1/machines/m9", &json!({"kinematics": "hexapod"}))
            .await,
        400,
        &["hexapod"],
    )
    .await;
    assert_problem(
        app.put_json(
            "/v1/machines/m9",
            &json!({"kinematics": "xyz", "axes": {"A": {"kv": 1.0}}}),
        )
        .await,
        400,
        &["axes.A"],
    )
    .await;
    assert_problem(
        app.put_json(
            "/v1/machines/m9",
            &json!({"kinematics": "xyz", "axes": {"X": {"kv": -1.0}}}),
        )
        .await,
        400,
        &["axes.X.kv", "> 0"],
    )
    .await;
    assert_problem(
        app.put_json(
            "/v1/machines/m9",
            &json!({"kinematics": "xyz", "axes": {"X": {"kv": 1.0, "kff": 2.0}}}),
        )
        .await,
        400,
        &["kff", "0..1"],
    )
    .await;
    assert_problem(
        app.put_json("/v1/machines/m9", &json!([1, 2])).await,
        400,
        &["object"],
    )
    .await;
    // Malformed JSON, wrong content type, empty body.
    assert_problem(
        app.post_raw(up, "application/json", "{\"deviations\": [1,")
            .await,
        400,
        &["invalid JSON", "line 1"],
    )
    .await;
    assert_problem(
        app.post_raw(up, "application/xml", "<x/>").await,
        415,
        &["text/csv"],
    )
    .await;
    assert_problem(
        app.post_raw(up, "application/json", "").await,
        400,
        &["empty"],
    )
    .await;
    assert_problem(
        app.post_raw(up, "application/json", "{\"deviations\": [1e400, 0, 0, 0]}")
            .await,
        400,
        &["invalid JSON"],
    )
    .await;
    // Surfaces.
    let mut s = flat_surface(2, 2);
    s["nominal"]["grid"]["points"].as_array_mut().unwrap().pop();
    assert_problem(
        app.put_json("/v1/machines/m/surfaces/t", &s).await,
        400,
        &["nominal.grid.points", "3 entries", "4"],
    )
    .await;
    let mut s = flat_surface(2, 2);
    s["nominal"]["grid"]["normals"][2] = json!([0.0, 0.0, 2.0]);
    assert_problem(
        app.put_json("/v1/machines/m/surfaces/t", &s).await,
        400,
        &["normals[2]", "unit"],
    )
    .await;
    let mut s = flat_surface(2, 2);
    s["nominal"]["grid"]["nu"] = json!(0);
    assert_problem(
        app.put_json("/v1/machines/m/surfaces/t", &s).await,
        400,
        &["at least 1"],
    )
    .await;
    let mut s = flat_surface(2, 2);
    s["tool_radius"] = json!(-1.0);
    assert_problem(
        app.put_json("/v1/machines/m/surfaces/t", &s).await,
        400,
        &["tool_radius"],
    )
    .await;
    assert_problem(
        app.put_json("/v1/machines/nope/surfaces/t", &flat_surface(2, 2))
            .await,
        404,
        &["machine 'nope'"],
    )
    .await;
    // Measurements: mismatched, empty, both, neither, unknown ids.
    assert_problem(
        app.post_json(up, &json!({"deviations": [0.1, 0.2, 0.3]}))
            .await,
        400,
        &["deviations has 3", "4 grid points"],
    )
    .await;
    assert_problem(
        app.post_json(up, &json!({"deviations": []})).await,
        400,
        &["empty"],
    )
    .await;
    assert_problem(
        app.post_json(up, &json!({"points": []})).await,
        400,
        &["points is empty"],
    )
    .await;
    assert_problem(
        app.post_json(up, &json!({"points": [[0,0,0]], "deviations": [0]}))
            .await,
        400,
        &["not both"],
    )
    .await;
    assert_problem(app.post_json(up, &json!({})).await, 400, &["deviations"]).await;
    assert_problem(
        app.post_json(up, &json!({"deviations": [0, 0, 0, 0], "id": "no/slash"}))
            .await,
        400,
        &["measurement id"],
    )
    .await;
    assert_problem(
        app.post_json(
            "/v1/machines/m/surfaces/zz/measurements",
            &json!({"deviations": [0]}),
        )
        .await,
        404,
        &["surface 'zz'", "PUT /v1/machines/m/surfaces/zz"],
    )
    .await;
    assert_problem(
        app.get("/v1/machines/m/surfaces/s/measurements/nope").await,
        404,
        &["measurement 'nope'"],
    )
    .await;
    // CSV problems name the line.
    assert_problem(
        app.post_raw(up, "text/csv", "x,y,z\n0,0,0\n1,0,0\n0,1\n1,1,0\n")
            .await,
        400,
        &["line 4", "expected 3 fields"],
    )
    .await;
    assert_problem(
        app.post_raw(up, "text/csv", "deviation\n0\nNaN\n0\n0\n")
            .await,
        400,
        &["line 3", "not a finite number"],
    )
    .await;
    assert_problem(
        app.post_raw(up, "text/csv", "foo,bar\n1,2\n").await,
        400,
        &["line 1", "header"],
    )
    .await;
    assert_problem(
        app.post_raw(up, "text/csv", "deviation\n0\n0\n").await,
        400,
        &["2 entries", "4 grid points"],
    )
    .await;
    // Nothing was written by any of the above.
    let list: Value = app
        .get("/v1/machines/m/surfaces/s/measurements")
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(list["measurements"].as_array().unwrap().len(), 0);
    assert_problem(
        app.get("/v1/machines/m/surfaces/t").await,
        404,
        &["surface 't'"],
    )
    .await;
    // Unknown route and method are problem+json too.
    assert_problem(app.get("/v1/nothing-here").await, 404, &["no route"]).await;
    assert_problem(
        app.client
            .patch(app.url("/v1/machines/m"))
            .send()
            .await
            .unwrap(),
        405,
        &["PATCH"],
    )
    .await;
}
on_both_backends!(bad_input);
