//! HTTP end to end on SQLite and PostgreSQL: machines, surfaces, measurements (JSON and
//! CSV uploads), restart persistence, bad input.

use crate::helpers::*;
use serde_json::{Value, json};

async fn machine_crud(app: TestApp) {
    // v1.0 kept unknown keys; v1.1 refuses them (CONTRACT "Definitions are validated when
    // stored"), so the extension keys here are the ones the service knows.
    let def = json!({"name": "DMU 50", "kinematics": "xyzac_table",
        "axes": {"X": {"kv": 30.0, "kff": 0.8, "max_accel": 2000.0,
                       "physical": {"motor_inertia_kg_m2": 0.001, "velocity_gain_nm_s_per_rad": 0.5,
                                    "lead_mm": 10.0, "table_mass_kg": 120.0}},
                 "C": {"kv": 20.0}},
        "geometry": {"c_axis_origin": [0.0, 0.0, 100.0]}, "rapid_mm_min": 24000.0});
    let r = app.put_json("/v1/machines/m1", &def).await;
    assert_eq!(r.status(), 201);
    assert_eq!(r.headers()["location"], "/v1/machines/m1");
    // Stored exactly as PUT, extension keys included.
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

/// Machine definitions the service accepts (the CONTRACT body and every extension).
fn accepted_machines() -> Vec<Value> {
    let full = json!({"kv": 30.0, "kff": 0.6, "kp_v": 400.0, "ti_v": 0.01, "tc": 0.0005});
    vec![
        machine_xyz(),
        json!({"name": "Demo 3-axis vertical mill", "kinematics": "xyz",
               "axes": {"X": full, "Y": full, "Z": full}}),
        json!({"kinematics": "xyz", "rapid_mm_min": 20000,
               "axes": {"X": {"kv": 30, "max_vel": 1e6, "max_accel": 1e7, "max_jerk": 1e10},
                        "Y": {"kv": 10000}, "Z": {"kv": 0.5, "kff": 1}}}),
        json!({"kinematics": "xyzac_table",
               "geometry": {"a_axis_origin": [0, 0, -100], "c_axis_origin": [0, 0, -100], "tool_length": 80},
               "axes": {
                   "X": {"kv": 30, "physical": {"motor_inertia_kg_m2": 0.001, "velocity_gain_nm_s_per_rad": 0.5,
                         "current_bandwidth_hz": 1000, "lead_mm": 10, "table_mass_kg": 200,
                         "axial_stiffness_n_per_um": 150}},
                   "Y": {"kv": 30}, "Z": {"kv": 30}, "A": {"kv": 20},
                   "C": {"kv": 20, "physical": {"motor_inertia_kg_m2": 0.002, "velocity_gain_nm_s_per_rad": 1.0,
                         "gear_ratio": 90, "table_inertia_kg_m2": 2.0}}}}),
    ]
}

/// Machine definitions a simulation would refuse, each with the field the 400 must name.
fn refused_machines() -> Vec<(Value, Vec<&'static str>)> {
    let x = |servo: Value| json!({"kinematics": "xyz", "axes": {"X": servo}});
    vec![
        (
            json!({"kinematics": "xyz", "colour": "red"}),
            vec!["colour", "kinematics", "axes"],
        ),
        (
            x(json!({"kv": 30, "inertia_kg": 120})),
            vec!["axes.X", "inertia_kg", "kp_v"],
        ),
        (x(json!({"kv": 0})), vec!["axes.X.kv", "> 0"]),
        (x(json!({"kv": 1e300})), vec!["axes.X.kv", "10000"]),
        (x(json!({"kv": 20000})), vec!["axes.X.kv", "10000"]),
        (x(json!({"kv": 30, "kff": 1.5})), vec!["axes.X.kff", "0..1"]),
        (x(json!({"kv": 30, "tc": -0.001})), vec!["axes.X.tc"]),
        (x(json!({"kv": 30, "kp_v": 1e9})), vec!["axes.X.kp_v"]),
        (
            x(json!({"kv": 30, "max_jerk": -1})),
            vec!["axes.X.max_jerk"],
        ),
        (
            x(json!({"kv": 9000, "kp_v": 90000, "ti_v": 0.00001, "tc": 0.1})),
            vec!["axes.X", "unstable"],
        ),
        (
            x(json!({"kv": 30, "physical": {"motor_inertia_kg_m2": 0.001, "friction": 3}})),
            vec!["axes.X.physical", "friction", "lead_mm"],
        ),
        (
            x(
                json!({"kv": 30, "physical": {"motor_inertia_kg_m2": 0.001, "velocity_gain_nm_s_per_rad": 0.5}}),
            ),
            vec!["axes.X", "lead_mm"],
        ),
        (
            json!({"kinematics": "xyz", "axes": {"A": {"kv": 1.0}}}),
            vec!["axes.A", "X, Y, Z"],
        ),
        (
            json!({"kinematics": "xyz", "geometry": {"tool_length": 80}}),
            vec!["geometry", "xyzac_table"],
        ),
        (
            json!({"kinematics": "xyzac_table", "geometry": {"c_offset": [0, 0, 100]}}),
            vec!["geometry", "c_offset", "c_axis_origin"],
        ),
        (
            json!({"kinematics": "xyz", "rapid_mm_min": -1}),
            vec!["rapid_mm_min"],
        ),
        (json!({"kinematics": "xyz", "name": 5}), vec!["name"]),
    ]
}

async fn machine_definitions_are_validated_when_stored(app: TestApp) {
    for (def, fields) in refused_machines() {
        assert_problem(app.put_json("/v1/machines/m9", &def).await, 400, &fields).await;
    }
    // A number JSON cannot hold is named by its path, not just by line and column.
    let r = app
        .client
        .put(app.url("/v1/machines/m9"))
        .header("content-type", "application/json")
        .body(r#"{"kinematics": "xyz", "axes": {"X": {"kv": 1e400}}}"#)
        .send()
        .await
        .unwrap();
    assert_problem(r, 400, &["axes.X.kv"]).await;
    assert_eq!(app.get("/v1/machines/m9").await.status(), 404);
    // Null-valued optional keys are not stored or echoed (they would break the schema).
    let r = app
        .put_json(
            "/v1/machines/n",
            &json!({"name": null, "kinematics": "xyz", "axes": {"X": {"kv": 30, "kff": null}}}),
        )
        .await;
    assert_eq!(r.status(), 201);
    let clean = json!({"kinematics": "xyz", "axes": {"X": {"kv": 30}}});
    assert_eq!(r.json::<Value>().await.unwrap(), clean);
    assert_eq!(
        app.get("/v1/machines/n")
            .await
            .json::<Value>()
            .await
            .unwrap(),
        clean
    );
}
on_both_backends!(machine_definitions_are_validated_when_stored);

/// PUT refuses every machine definition that a simulation would refuse: every definition PUT
/// accepts answers a contour and a motion-gap diagnosis.
async fn accepted_machines_simulate(app: TestApp) {
    let rows: Vec<Vec<f64>> = (0..300)
        .map(|i| {
            let t = i as f64 * 0.001;
            vec![20.0 * t, 10.0 * t]
        })
        .collect();
    for (k, def) in accepted_machines().into_iter().enumerate() {
        let url = format!("/v1/machines/a{k}");
        let r = app.put_json(&url, &def).await;
        assert_eq!(r.status(), 201, "{def}");
        let r = app
            .post_json(
                &format!("{url}/contour-error"),
                &json!({"gcode": "G1 X1 Y1 F600"}),
            )
            .await;
        assert_eq!(r.status(), 200, "{def}: {}", r.text().await.unwrap());
        let r = app
            .post_json(
                &format!("{url}/gap-diagnosis"),
                &json!({"domain": "motion", "period_s": 0.001, "commanded": rows, "measured": rows}),
            )
            .await;
        assert_eq!(r.status(), 200, "{def}: {}", r.text().await.unwrap());
    }
}
on_both_backends!(accepted_machines_simulate);

/// Sends one raw HTTP/1.1 request (no client-side URL normalization of `.` and `..`) and
/// returns the status code.
async fn raw_status(app: &TestApp, method: &str, path: &str, body: &str) -> u16 {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let host = app.addr.trim_start_matches("http://");
    let mut stream = tokio::net::TcpStream::connect(host).await.unwrap();
    let req = format!(
        "{method} {path} HTTP/1.1\r\nHost: {host}\r\nContent-Type: application/json\r\n\
         Content-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    );
    stream.write_all(req.as_bytes()).await.unwrap();
    let mut answer = Vec::new();
    stream.read_to_end(&mut answer).await.unwrap();
    let text = String::from_utf8_lossy(&answer);
    let status = text.split_whitespace().nth(1).unwrap().parse().unwrap();
    if status == 400 {
        // Our problem+json naming the id, not a refusal of the request line.
        assert!(text.contains("id '.") && text.contains("'.'"), "{text}");
    }
    status
}

async fn dot_ids_are_refused(app: TestApp) {
    seed_machine_and_surface(&app, "m", "s", 2, 2).await;
    let machine = machine_xyz().to_string();
    for id in ["..", "%2E%2E", ".", "%2e"] {
        assert_eq!(
            raw_status(&app, "PUT", &format!("/v1/machines/{id}"), &machine).await,
            400,
            "{id}"
        );
        assert_eq!(
            raw_status(&app, "GET", &format!("/v1/machines/{id}"), "").await,
            400,
            "{id}"
        );
        let surface = flat_surface(2, 2).to_string();
        let path = format!("/v1/machines/m/surfaces/{id}");
        assert_eq!(raw_status(&app, "PUT", &path, &surface).await, 400, "{id}");
        let path = format!("/v1/machines/m/surfaces/s/measurements/{id}");
        assert_eq!(raw_status(&app, "GET", &path, "").await, 400, "{id}");
        assert_eq!(
            raw_status(&app, "GET", &format!("/v1/jobs/{id}"), "").await,
            400,
            "{id}"
        );
    }
    assert_problem(
        app.get("/v1/machines/%2E%2E%2E%2E").await,
        404,
        &["machine '....' does not exist"],
    )
    .await;
    // Ids in bodies and queries follow the same rule.
    let up = "/v1/machines/m/surfaces/s/measurements";
    assert_problem(
        app.post_json(
            &format!("{up}?id=.."),
            &json!({"deviations": [0.0, 0.0, 0.0, 0.0]}),
        )
        .await,
        400,
        &["measurement id '..'"],
    )
    .await;
    assert_problem(
        app.get("/v1/machines/m/surfaces/s/compensation?measurement=..")
            .await,
        400,
        &["measurement id '..'"],
    )
    .await;
}
on_both_backends!(dot_ids_are_refused);

async fn surface_definitions_refuse_unknown_keys(app: TestApp) {
    assert_eq!(
        app.put_json("/v1/machines/m", &machine_xyz())
            .await
            .status(),
        201
    );
    let mut s = flat_surface(2, 2);
    s["colour"] = json!("red");
    assert_problem(
        app.put_json("/v1/machines/m/surfaces/t", &s).await,
        400,
        &["colour", "nominal", "tool_radius", "name"],
    )
    .await;
    let mut s = flat_surface(2, 2);
    s["nominal"]["grid"]["spacing"] = json!(1.0);
    assert_problem(
        app.put_json("/v1/machines/m/surfaces/t", &s).await,
        400,
        &["nominal.grid", "spacing", "normals"],
    )
    .await;
    let mut s = flat_surface(2, 2);
    s["nominal"]["cad"] = json!("x.step");
    assert_problem(
        app.put_json("/v1/machines/m/surfaces/t", &s).await,
        400,
        &["nominal", "cad", "grid"],
    )
    .await;
    let mut s = flat_surface(2, 2);
    s["name"] = json!("pocket floor");
    assert_eq!(
        app.put_json("/v1/machines/m/surfaces/t", &s).await.status(),
        201
    );
}
on_both_backends!(surface_definitions_refuse_unknown_keys);
