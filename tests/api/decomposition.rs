//! HTTP end to end: decomposition (stateless and of a stored measurement) and compensation
//! (JSON, CSV, resampled reconstruction, CL points), on SQLite and PostgreSQL.

use crate::helpers::*;
use serde_json::{Value, json};

/// A smooth field plus deterministic pseudo-noise on an nu × nv grid, mm.
fn field(nu: usize, nv: usize) -> Vec<f64> {
    (0..nu * nv)
        .map(|k| {
            let (u, v) = (
                (k % nu) as f64 / (nu - 1) as f64,
                (k / nu) as f64 / (nv - 1) as f64,
            );
            let noise = (((k * 7919) % 1000) as f64 / 1000.0 - 0.5) * 0.01;
            0.03 + 0.01 * (3.0 * u).sin() * (2.0 * v).cos() + 0.005 * u + noise
        })
        .collect()
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .expect("array")
        .iter()
        .map(|x| x.as_f64().expect("number"))
        .collect()
}

async fn stateless_decompose(app: TestApp) {
    let signal: Vec<f64> = (0..300)
        .map(|k| 0.02 * (k as f64 / 20.0).sin() + (((k * 31) % 17) as f64 - 8.0) * 5e-4)
        .collect();
    for method in ["coarse_to_fine", "vmd", "emd", "wavelet"] {
        let r = app
            .post_json(
                "/v1/decompose",
                &json!({"signal": signal, "method": method}),
            )
            .await;
        assert_eq!(r.status(), 200, "{method}");
        let b: Value = r.json().await.unwrap();
        assert_eq!(b["method"], method);
        let (s, rnd) = (floats(&b["systematic"]), floats(&b["random"]));
        assert_eq!(s.len(), signal.len());
        for i in 0..signal.len() {
            assert!(
                (s[i] + rnd[i] - signal[i]).abs() < 1e-9,
                "{method} sample {i}"
            );
        }
        assert!(b["components"].is_object());
    }
    // Default method, grid reading and parameters.
    let f = field(12, 10);
    let r = app
        .post_json(
            "/v1/decompose",
            &json!({"signal": f, "params": {"nu": 12, "nv": 10, "vmd": {"K": 4}, "full_components": true}}),
        )
        .await;
    assert_eq!(r.status(), 200);
    let b: Value = r.json().await.unwrap();
    assert_eq!(b["method"], "coarse_to_fine");
    assert_eq!(b["components"]["order"], "2d");
    assert_eq!(b["components"]["stages"]["k"], 4);
    assert_eq!(floats(&b["components"]["arrays"]["x4"]).len(), 120);
}
on_both_backends!(stateless_decompose);

async fn bad_decompose_input(app: TestApp) {
    let p = "/v1/decompose";
    assert_problem(
        app.post_json(p, &json!({"signal": []})).await,
        400,
        &["signal"],
    )
    .await;
    assert_problem(
        app.post_json(p, &json!({"signal": vec![0.1; 5]})).await,
        422,
        &["16"],
    )
    .await;
    // Schemathesis found samples near f64::MAX answered as 200 with null parts.
    let mut huge = vec![0.1; 40];
    huge[13] = -1.7976931348623157e308;
    assert_problem(
        app.post_json(p, &json!({"signal": huge})).await,
        400,
        &["signal[13]", "100 m"],
    )
    .await;
    let mut big = vec![0.1; 40];
    big[3] = 9.0e4;
    assert_eq!(
        app.post_json(p, &json!({"signal": big})).await.status(),
        200
    );
    let sig = vec![0.1; 40];
    assert_problem(
        app.post_json(p, &json!({"signal": sig, "method": "fft"}))
            .await,
        400,
        &["fft"],
    )
    .await;
    assert_problem(
        app.post_json(p, &json!({"signal": sig, "params": {"vmd": {"alpha": -3}}}))
            .await,
        400,
        &["alpha"],
    )
    .await;
    assert_problem(
        app.post_json(p, &json!({"signal": sig, "params": {"alhpa": 1}}))
            .await,
        400,
        &["alhpa"],
    )
    .await;
    assert_problem(
        app.post_json(p, &json!({"signal": sig, "params": {"nu": 7, "nv": 7}}))
            .await,
        400,
        &["nu*nv"],
    )
    .await;
    assert_problem(
        app.post_json(p, &json!({"signal": sig, "params": {"wavelet": "coif5"}}))
            .await,
        400,
        &["coif5"],
    )
    .await;
    assert_problem(
        app.post_raw(p, "application/json", "{\"signal\": [1, NaN]}")
            .await,
        400,
        &[],
    )
    .await;
}
on_both_backends!(bad_decompose_input);

async fn measurement_decomposition_and_compensation(app: TestApp) {
    let (nu, nv) = (15, 11);
    seed_machine_and_surface(&app, "m1", "s1", nu, nv).await;
    let devs = field(nu, nv);
    let base = "/v1/machines/m1/surfaces/s1";
    let r = app
        .post_json(
            &format!("{base}/measurements"),
            &json!({"deviations": devs, "id": "probe-1"}),
        )
        .await;
    assert_eq!(r.status(), 201);
    // No stored decomposition yet.
    assert_problem(
        app.get(&format!("{base}/measurements/probe-1/decomposition"))
            .await,
        404,
        &["POST"],
    )
    .await;
    // Compensation before any decomposition uses a fresh coarse-to-fine one.
    let r = app
        .get(&format!("{base}/compensation?measurement=probe-1"))
        .await;
    assert_eq!(r.status(), 200);
    let fresh: Value = r.json().await.unwrap();
    // Store a VMD decomposition: compensation follows the one stored last.
    let r = app
        .post_raw(
            &format!("{base}/measurements/probe-1/decomposition"),
            "application/json",
            json!({"method": "vmd"}).to_string(),
        )
        .await;
    assert_eq!(r.status(), 200);
    let d: Value = r.json().await.unwrap();
    let (s, rnd) = (floats(&d["systematic"]), floats(&d["random"]));
    for i in 0..devs.len() {
        assert!((s[i] + rnd[i] - devs[i]).abs() < 1e-9);
    }
    let stored: Value = app
        .get(&format!("{base}/measurements/probe-1/decomposition"))
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(stored["method"], "vmd");
    let r = app
        .get(&format!("{base}/compensation?measurement=probe-1"))
        .await;
    assert_eq!(r.status(), 200);
    let c: Value = r.json().await.unwrap();
    let offs = floats(&c["offsets"]);
    assert_eq!(offs, s);
    assert_ne!(floats(&fresh["offsets"]), offs);
    // points = nominal - offsets * normals (flat surface, normals +z).
    for (k, p) in c["points"].as_array().unwrap().iter().enumerate() {
        let p = floats(p);
        assert!((p[0] - (k % nu) as f64).abs() < 1e-12);
        assert!((p[2] - (0.0 - offs[k])).abs() < 1e-12);
    }
    // Default (coarse-to-fine) decomposition with an empty body.
    let r = app
        .post_raw(
            &format!("{base}/measurements/probe-1/decomposition"),
            "application/json",
            "",
        )
        .await;
    assert_eq!(r.status(), 200);
    let d: Value = r.json().await.unwrap();
    assert_eq!(d["method"], "coarse_to_fine");
    assert_eq!(d["components"]["grid"], json!([nu, nv]));
    // CSV with the contract header.
    let r = app
        .client
        .get(app.url(&format!("{base}/compensation?measurement=probe-1")))
        .header("accept", "text/csv")
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let text = r.text().await.unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("x,y,z,i,j,k,offset"));
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|c| c.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), nu * nv);
    let sys = floats(&d["systematic"]);
    assert!((rows[7][6] - sys[7]).abs() < 1e-12 && (rows[7][2] + sys[7]).abs() < 1e-12);
    // Reconstructed surface at another density, with CL points (tool radius 3 from the surface).
    let r = app
        .get(&format!(
            "{base}/compensation?measurement=probe-1&nu=29&nv=21&cl=true"
        ))
        .await;
    assert_eq!(r.status(), 200);
    let g: Value = r.json().await.unwrap();
    assert_eq!(g["points"].as_array().unwrap().len(), 29 * 21);
    let (p0, cl0) = (floats(&g["points"][0]), floats(&g["cl"][0]));
    assert!((cl0[2] - p0[2] - 3.0).abs() < 1e-9);
    assert!((floats(&g["offsets"])[0] - sys[0]).abs() < 1e-12);
    // Bad queries.
    assert_problem(
        app.get(&format!("{base}/compensation")).await,
        400,
        &["measurement"],
    )
    .await;
    assert_problem(
        app.get(&format!("{base}/compensation?measurement=nope"))
            .await,
        404,
        &["nope"],
    )
    .await;
    assert_problem(
        app.get(&format!(
            "{base}/compensation?measurement=probe-1&nu=1&nv=5"
        ))
        .await,
        400,
        &["nu"],
    )
    .await;
    assert_problem(
        app.get(&format!("{base}/compensation?measurement=probe-1&nu=5"))
            .await,
        400,
        &["nv"],
    )
    .await;
    assert_problem(
        app.get(&format!("{base}/compensation?measurement=probe-1&foo=1"))
            .await,
        400,
        &["foo"],
    )
    .await;
    assert_problem(
        app.post_json(
            &format!("{base}/measurements/nope/decomposition"),
            &json!({}),
        )
        .await,
        404,
        &["nope"],
    )
    .await;
    assert_problem(
        app.post_json(
            &format!("{base}/measurements/probe-1/decomposition"),
            &json!({"params": {"nu": 3}}),
        )
        .await,
        400,
        &["nu"],
    )
    .await;
    assert_problem(
        app.get("/v1/machines/ghost/surfaces/s1/compensation?measurement=probe-1")
            .await,
        404,
        &["ghost"],
    )
    .await;
}
on_both_backends!(measurement_decomposition_and_compensation);

/// Above the sync limit (openapi.yaml: sync up to 250,000 samples) the stateless route answers
/// 202 with a job whose result is the same decomposition (default method, coarse-to-fine);
/// at the limit it answers 200.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn large_decomposition_runs_as_a_job() {
    let app = spawn_app().await;
    let n = 250_001;
    let signal: Vec<f64> = (0..n)
        .map(|k| 0.02 * (k as f64 / 3000.0).sin() + (((k * 7919) % 1000) as f64 - 500.0) * 1e-5)
        .collect();
    let body = json!({ "signal": signal });
    let r = app.post_json("/v1/decompose", &body).await;
    assert_eq!(r.status(), 202);
    let id = r.json::<Value>().await.unwrap()["job"]
        .as_str()
        .expect("job id")
        .to_string();
    let done = app.wait_job(&id).await;
    let res = &done["result"];
    assert_eq!(res["method"], "coarse_to_fine");
    let (s, rnd) = (floats(&res["systematic"]), floats(&res["random"]));
    assert_eq!(s.len(), n);
    assert_eq!(rnd.len(), n);
    for i in (0..n).step_by(997) {
        assert!((s[i] + rnd[i] - signal[i]).abs() < 1e-9, "sample {i}");
    }
    // The same signal one sample shorter is at the limit: answered directly, and the job's
    // systematic part agrees with it away from the end.
    let r = app
        .post_json("/v1/decompose", &json!({ "signal": &signal[..n - 1] }))
        .await;
    assert_eq!(r.status(), 200);
    let sync: Value = r.json().await.unwrap();
    let s2 = floats(&sync["systematic"]);
    assert_eq!(s2.len(), n - 1);
    let mid = n / 2;
    assert!((s2[mid] - s[mid]).abs() < 1e-4, "{} vs {}", s2[mid], s[mid]);
}

/// A long machining error: a slow wave, a 0.04-cycle/sample tone and pseudo-noise whose
/// pattern depends on `seed`, mm.
pub fn long_signal(n: usize, seed: usize) -> Vec<f64> {
    (0..n)
        .map(|k| {
            let t = k as f64;
            0.02 * (t / 3000.0).sin()
                + 0.003 * (0.25 * t).sin()
                + (((k * 7919 + seed * 104_729) % 1000) as f64 - 500.0) * 1e-5
        })
        .collect()
}

/// Submits a stored decomposition job (above the sync limit) and returns its id.
async fn submit(app: &TestApp, body: &Value) -> String {
    let r = app.post_json("/v1/decompose", body).await;
    assert_eq!(r.status(), 202);
    r.json::<Value>().await.unwrap()["job"]
        .as_str()
        .expect("job id")
        .to_string()
}

/// Asserts two decomposition answers hold the same numbers, bit for bit.
pub fn same_numbers(what: &str, a: &Value, b: &Value) {
    for part in ["systematic", "random"] {
        let (x, y) = (floats(&a[part]), floats(&b[part]));
        assert_eq!(x.len(), y.len(), "{what}: {part} lengths");
        if let Some(i) = (0..x.len()).find(|&i| x[i].to_bits() != y[i].to_bits()) {
            panic!("{what}: {part}[{i}] {:e} vs {:e}", x[i], y[i]);
        }
    }
    assert!(
        a["components"] == b["components"] && a["outliers"] == b["outliers"],
        "{what}: components {} vs {}",
        a["components"],
        b["components"]
    );
}

/// Issue 25 (same input, same bits): a stored decomposition job run alone (its VMD split over
/// two threads when the machine has two cores) and the same input run while two other
/// decomposition jobs run beside it (then on one) give the same numbers bit for bit; the
/// result and the direct answer name the version that computed them.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_decomposition_job_gives_the_same_bits_alone_or_beside_two_others() {
    let app = spawn_app_with(|c| c.workers = Some(3)).await;
    let n = 250_001;
    // Fewer VMD iterations than the default keep three jobs side by side quick; the f32
    // sweep and the split are the default ones.
    let params = json!({"vmd": {"max_iter": 60}});
    let body = json!({"signal": long_signal(n, 0), "params": params});
    let alone = submit(&app, &body).await;
    let alone = app.wait_job(&alone).await;
    // The others first: jobs are claimed oldest first, so ours starts with both running.
    let mut others = Vec::new();
    for seed in [1, 2] {
        let other = json!({"signal": long_signal(n, seed), "params": params});
        others.push(submit(&app, &other).await);
    }
    let ours = submit(&app, &body).await;
    let busy = app.wait_job(&ours).await;
    for o in &others {
        app.wait_job(o).await;
    }
    same_numbers(
        "alone vs beside two others",
        &alone["result"],
        &busy["result"],
    );
    assert_eq!(alone["result"]["truecut_version"], truecut::version());
    let r = app
        .post_json("/v1/decompose", &json!({"signal": long_signal(300, 0)}))
        .await;
    assert_eq!(r.status(), 200);
    let direct: Value = r.json().await.unwrap();
    assert_eq!(direct["truecut_version"], truecut::version());
    // Asked for a job (Prefer: respond-async) at a size answered directly: a stored job,
    // whose result is the direct answer, bit for bit.
    let r = app
        .client
        .post(app.url("/v1/decompose"))
        .header("prefer", "respond-async")
        .json(&json!({"signal": long_signal(300, 0)}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 202);
    let id = r.json::<Value>().await.unwrap()["job"]
        .as_str()
        .unwrap()
        .to_string();
    let job = app.wait_job(&id).await;
    assert_eq!(job["state"], "done", "{job}");
    same_numbers("direct vs Prefer: respond-async", &direct, &job["result"]);
}

/// Probe flyers (openapi.yaml): the upload warns, the decomposition names them, and the
/// compensation of every other point stays within 2 µm of the clean upload's.
async fn probe_flyers_leave_the_compensation_alone(app: TestApp) {
    let n = 41;
    seed_machine_and_surface(&app, "m1", "s1", n, n).await;
    let clean = field(n, n);
    let flyers = [(0usize, 2.0f64), (20 * n + 20, -1.5), (33 * n + 7, 0.8)];
    let mut dirty = clean.clone();
    for (k, d) in flyers {
        dirty[k] += d;
    }
    let base = "/v1/machines/m1/surfaces/s1/measurements";
    let r = app
        .post_json(base, &json!({"id": "clean", "deviations": clean}))
        .await;
    assert_eq!(r.status(), 201);
    let b: Value = r.json().await.unwrap();
    assert_eq!(b["outliers"], json!([]));
    assert_eq!(b["warnings"], json!([]));
    let r = app
        .post_json(base, &json!({"id": "chip", "deviations": dirty}))
        .await;
    assert_eq!(r.status(), 201);
    let b: Value = r.json().await.unwrap();
    let want = json!(
        [0, 33 * n + 7, 20 * n + 20]
            .iter()
            .copied()
            .collect::<std::collections::BTreeSet<usize>>()
    );
    assert_eq!(b["outliers"], want, "{b}");
    let w = b["warnings"][0].as_str().expect("a warning");
    assert!(
        w.contains("3 point(s) look like probe flyers") && w.contains("+2.0"),
        "{w}"
    );

    let mut offsets = Vec::new();
    for id in ["clean", "chip"] {
        let r = app
            .post_json(&format!("{base}/{id}/decomposition"), &json!({}))
            .await;
        assert_eq!(r.status(), 200);
        let d: Value = r.json().await.unwrap();
        if id == "chip" {
            assert_eq!(d["outliers"], want);
        } else {
            assert_eq!(d["outliers"], json!([]));
        }
        let r = app
            .get(&format!(
                "/v1/machines/m1/surfaces/s1/compensation?measurement={id}"
            ))
            .await;
        assert_eq!(r.status(), 200);
        let c: Value = r.json().await.unwrap();
        assert_eq!(c["outliers"], d["outliers"]);
        offsets.push(floats(&c["offsets"]));
    }
    let is_flyer = |k: usize| flyers.iter().any(|f| f.0 == k);
    let worst = (0..n * n)
        .filter(|&k| !is_flyer(k))
        .map(|k| (offsets[0][k] - offsets[1][k]).abs())
        .fold(0.0, f64::max);
    assert!(worst <= 0.002, "other offsets moved by {worst} mm");
    // The flyers' own offsets come from their neighbours, not from the chip: near the
    // noise-free field (the clean upload's own value there follows its noise at a corner).
    let truth: Vec<f64> = field(n, n)
        .iter()
        .enumerate()
        .map(|(k, v)| v - (((k * 7919) % 1000) as f64 / 1000.0 - 0.5) * 0.01)
        .collect();
    for (k, _) in flyers {
        let got = offsets[1][k];
        assert!(
            (got - truth[k]).abs() <= 0.005,
            "flyer {k}: {got} vs {}",
            truth[k]
        );
    }
}
on_both_backends!(probe_flyers_leave_the_compensation_alone);
