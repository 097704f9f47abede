//! The pitch-error compensation table over HTTP: from a stored ISO 230-2 run (both
//! backends) in each format, the refusals with their sentences, and the stateless route end to
//! end through the file: the LinuxCNC file and the CSV of one run, read back as LinuxCNC reads
//! them, applied to a second run of the same axis, cut its E and M (evaluated by
//! `POST /v1/iso230-2`) by at least 80 %.

use serde_json::{Value, json};

use crate::helpers::{TestApp, assert_problem, spawn_app};
use crate::iso230::hand_body;

/// Reads a LinuxCNC compensation file as `usrmotLoadComp` does: three numbers per line until
/// the first line that is not; (nominal, forward trim, reverse trim).
fn linuxcnc_triplets(text: &str) -> Vec<[f64; 3]> {
    let mut out = Vec::new();
    for line in text.lines() {
        let v: Vec<f64> = line
            .split_whitespace()
            .take(3)
            .map_while(|t| t.parse().ok())
            .collect();
        let [a, b, c] = v[..] else { break };
        out.push([a, b, c]);
    }
    out
}

/// The rows of the CSV under its header.
fn csv_triplets(text: &str) -> Vec<[f64; 3]> {
    let mut lines = text.lines().skip_while(|l| l.starts_with('#'));
    assert_eq!(
        lines.next(),
        Some("position_mm,forward_correction_mm,backward_correction_mm")
    );
    lines
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            [v[0], v[1], v[2]]
        })
        .collect()
}

/// The trim LinuxCNC adds at `p` (written again from its `compute_screw_comp`: linear
/// between entries, the end values beyond).
fn trim(table: &[[f64; 3]], p: f64, forward: bool) -> f64 {
    let col = if forward { 1 } else { 2 };
    if p < table[0][0] {
        return table[0][col];
    }
    for w in table.windows(2) {
        if p >= w[0][0] && p < w[1][0] {
            return w[0][col] + (w[1][col] - w[0][col]) * (p - w[0][0]) / (w[1][0] - w[0][0]);
        }
    }
    table[table.len() - 1][col]
}

async fn text(app: &TestApp, path: &str, kind: &str, file: &str) -> String {
    let r = app.get(path).await;
    assert_eq!(r.status(), 200, "{path}");
    let h = r.headers();
    assert!(
        h["content-type"].to_str().unwrap().starts_with(kind),
        "{h:?}"
    );
    let cd = h["content-disposition"].to_str().unwrap();
    assert_eq!(cd, format!("attachment; filename=\"{file}\""));
    r.text().await.unwrap()
}

/// Tables of stored runs: the latest by default or one by id, each format, and the refusals.
async fn stored_run_tables(app: TestApp) {
    let base = "/v1/machines/m1/axes/X/iso230-2";
    let comp = format!("{base}/compensation");
    assert!(
        app.put_json("/v1/machines/m1", &crate::helpers::machine_xyz())
            .await
            .status()
            .is_success()
    );
    assert_problem(
        app.get(&comp).await,
        404,
        &["no stored ISO 230-2 run", "POST one"],
    )
    .await;
    let r = app.post_json(base, &hand_body(1.0)).await;
    assert_eq!(r.status(), 201);
    let first: Value = r.json().await.unwrap();
    let first_id = first["id"].as_str().unwrap().to_string();

    // JSON (the default): the negated means, E 8 → 0 µm and M 4.5 → 0 µm on its own run.
    let a: Value = app.get(&comp).await.json().await.unwrap();
    assert_eq!(
        (a["mode"].as_str(), a["run"].as_str()),
        (Some("mean"), Some(first_id.as_str()))
    );
    assert_eq!(a["positions"], json!([0.0, 100.0, 200.0, 300.0, 400.0]));
    assert!((a["forward_correction"][1].as_f64().unwrap() + 0.004).abs() < 1e-12);
    assert!((a["before"]["E"].as_f64().unwrap() - 0.008).abs() < 1e-12);
    assert!(a["after"]["E"].as_f64().unwrap().abs() < 1e-12);
    assert!(
        a["sign"]
            .as_str()
            .unwrap()
            .starts_with("correction = what the controller adds")
    );

    // LinuxCNC: the triplets first (target 100: x̄↑ +4 µm → trim −0.004), the notes after.
    let f = text(
        &app,
        &format!("{comp}?format=linuxcnc"),
        "text/plain",
        "m1-X-mean-comp.txt",
    )
    .await;
    let t = linuxcnc_triplets(&f);
    assert_eq!(t.len(), 5, "{f}");
    assert_eq!(t[1], [100.0, -0.004, 0.0]);
    assert!(f.contains(&format!("from ISO 230-2 run {first_id}")), "{f}");
    assert!(f.contains("COMP_FILE_TYPE = 1"));

    // A second run becomes the latest; the first stays reachable by id.
    assert_eq!(app.post_json(base, &hand_body(0.5)).await.status(), 201);
    let latest: Value = app.get(&comp).await.json().await.unwrap();
    assert_ne!(latest["run"], json!(first_id));
    assert!((latest["forward_correction"][1].as_f64().unwrap() + 0.002).abs() < 1e-12);
    let model = format!("{comp}?run={first_id}&format=csv&mode=model&spacing_mm=50");
    let c = csv_triplets(&text(&app, &model, "text/csv", "m1-X-model-comp.csv").await);
    assert_eq!(c.len(), 9);
    assert_eq!((c[0][0], c[8][0]), (0.0, 400.0));
    // The model splits the mean reversal B̄ = 3.2 µm between the directions everywhere.
    assert!(
        c.iter().all(|r| (r[2] - r[1] - 0.0032).abs() < 2e-6),
        "{c:?}"
    );
    let fit: Value = app
        .get(&format!("{comp}?mode=model&fit_cyclic=true"))
        .await
        .json()
        .await
        .unwrap();
    assert!(
        fit["model"]["cyclic"]["pitch_mm"].as_f64().unwrap() >= 200.0,
        "{fit}"
    );

    // Refusals, each with the sentence that says what to change.
    for (query, status, needles) in [
        ("?run=zzz", 404, &["run 'zzz'", "lists the runs"][..]),
        ("?spacing_mm=5", 400, &["mode=model"][..]),
        ("?mode=model&spacing_mm=-1", 400, &["spacing_mm = -1"][..]),
        ("?mode=model&spacing_mm=abc", 400, &["spacing_mm='abc'"][..]),
        (
            "?mode=model&spacing_mm=0.01",
            422,
            &["at most 10001", "spacing_mm of at least"][..],
        ),
        (
            "?format=linuxcnc&mode=model&spacing_mm=1",
            422,
            &["at most 256", "spacing_mm of at least 1.569"][..],
        ),
        (
            "?mode=model&cyclic_pitch_mm=150",
            422,
            &["cannot resolve", "150 mm"][..],
        ),
        (
            "?mode=model&cyclic_pitch_mm=500&fit_cyclic=true",
            400,
            &["not both"][..],
        ),
        ("?format=xml", 400, &["format 'xml'", "linuxcnc"][..]),
        ("?mode=spline", 400, &["mode 'spline'"][..]),
        ("?table=1", 400, &["unknown query parameter 'table'"][..]),
    ] {
        assert_problem(app.get(&format!("{comp}{query}")).await, status, needles).await;
    }
    assert_problem(
        app.get("/v1/machines/m1/axes/Q/iso230-2/compensation")
            .await,
        400,
        &["axis 'Q'"],
    )
    .await;
    assert_problem(
        app.get("/v1/machines/nope/axes/X/iso230-2/compensation")
            .await,
        404,
        &["nope"],
    )
    .await;
}
on_both_backends!(stored_run_tables);

/// A 1.2 m axis read at 13 uneven targets, five cycles each way: 35 µm/m scale, a 6 µm
/// reversal growing along the axis, a 3 µm cyclic error of 700 mm pitch, a 2 µm bow, and a
/// scatter (deterministic, ±0.8 µm) that differs between `run` 0 and 1.
fn axis_run(run: usize) -> Value {
    let targets: Vec<f64> = (0..13)
        .map(|i| {
            -100.0
                + 100.0 * i as f64
                + if i % 12 == 0 {
                    0.0
                } else {
                    [7.3, -11.9, 3.1][i % 3]
                }
        })
        .collect();
    let dev = |p: f64, fwd: bool| {
        let u = (p + 100.0) / 1200.0;
        let b = 0.006 * (0.85 + 0.3 * u);
        35e-6 * p
            + if fwd { 0.5 * b } else { -0.5 * b }
            + 0.003 * (std::f64::consts::TAU * p / 700.0 + 1.1).sin()
            + 0.008 * u * (1.0 - u)
    };
    let scatter = |i: usize, j: usize, fwd: bool| {
        let k = (i * 7 + j * 3 + usize::from(fwd) * 5 + run * 11) % 9;
        (k as f64 - 4.0) * 0.2e-3
    };
    let rows = |fwd: bool| -> Vec<Vec<f64>> {
        targets
            .iter()
            .enumerate()
            .map(|(i, &p)| {
                (0..5)
                    .map(|j| p + dev(p, fwd) + scatter(i, j, fwd))
                    .collect()
            })
            .collect()
    };
    json!({"targets": targets, "forward": rows(true), "backward": rows(false)})
}

/// The body with each reading plus the table's trim at its target in its direction.
fn compensated(body: &Value, table: &[[f64; 3]]) -> Value {
    let targets: Vec<f64> = serde_json::from_value(body["targets"].clone()).unwrap();
    let shift = |dir: &str, fwd: bool| -> Vec<Vec<f64>> {
        let rows: Vec<Vec<f64>> = serde_json::from_value(body[dir].clone()).unwrap();
        rows.iter()
            .zip(&targets)
            .map(|(row, &p)| row.iter().map(|x| x + trim(table, p, fwd)).collect())
            .collect()
    };
    json!({"targets": targets, "forward": shift("forward", true), "backward": shift("backward", false)})
}

async fn e_and_m(app: &TestApp, body: &Value) -> (f64, f64) {
    let a: Value = app
        .post_json("/v1/iso230-2", body)
        .await
        .json()
        .await
        .unwrap();
    (a["E"].as_f64().unwrap(), a["M"].as_f64().unwrap())
}

/// The test through HTTP and the files: tables of run 1 (mean as LinuxCNC file, model
/// with a fitted cyclic term as CSV) applied to run 1 and to run 2 cut E and M by ≥ 80 %.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn posted_tables_cut_e_and_m_of_a_second_run() {
    let app = spawn_app().await;
    let (one, two) = (axis_run(0), axis_run(1));
    for (query, csv) in [
        ("format=linuxcnc", false),
        ("format=csv&mode=model&fit_cyclic=true", true),
    ] {
        let r = app
            .post_json(&format!("/v1/iso230-2/compensation?{query}"), &one)
            .await;
        assert_eq!(r.status(), 200, "{query}");
        let f = r.text().await.unwrap();
        let table = if csv {
            csv_triplets(&f)
        } else {
            linuxcnc_triplets(&f)
        };
        assert!(table.len() >= 13, "{query}: {f}");
        for (name, run) in [("run 1", &one), ("run 2", &two)] {
            let (e0, m0) = e_and_m(&app, run).await;
            let (e1, m1) = e_and_m(&app, &compensated(run, &table)).await;
            println!(
                "goal >= 80 %: {query} on {name}: E {:.2} -> {:.2} um ({:.1} %), M {:.2} -> {:.2} um ({:.1} %)",
                e0 * 1e3,
                e1 * 1e3,
                (1.0 - e1 / e0) * 100.0,
                m0 * 1e3,
                m1 * 1e3,
                (1.0 - m1 / m0) * 100.0
            );
            assert!(
                e1 <= 0.2 * e0 && m1 <= 0.2 * m0,
                "{query} on {name}: E {e0} -> {e1}, M {m0} -> {m1}"
            );
        }
    }
    // The route's own prediction agrees with the file read back on run 1.
    let a: Value = app
        .post_json("/v1/iso230-2/compensation?mode=model", &one)
        .await
        .json()
        .await
        .unwrap();
    assert!(a["after"]["E"].as_f64().unwrap() < a["before"]["E"].as_f64().unwrap());
    // Refusals of the stateless route.
    let mut labelled = one.clone();
    labelled["label"] = json!("x");
    assert_problem(
        app.post_json("/v1/iso230-2/compensation", &labelled).await,
        400,
        &["label"],
    )
    .await;
    assert_problem(
        app.post_json("/v1/iso230-2/compensation?run=latest", &one)
            .await,
        400,
        &["unknown query parameter 'run'"],
    )
    .await;
    let mut three = hand_body(1.0);
    for k in ["targets", "forward", "backward"] {
        three[k].as_array_mut().unwrap().truncate(3);
    }
    assert_problem(
        app.post_json(
            "/v1/iso230-2/compensation?mode=model&fit_cyclic=true",
            &three,
        )
        .await,
        422,
        &["at least 5 targets"],
    )
    .await;
}
