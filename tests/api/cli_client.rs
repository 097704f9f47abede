//! The CLI as a client of a running service: `truecut upload`, `compensation`, `jobs`,
//! `iso230-2`, `iso230-4` run as the real binary against a spawned server, with their exit
//! codes (0 ok, 2 usage, 3 refused, 4 unreachable, 5 job failed), and every subcommand's
//! `--help` giving an example.

use std::process::{Command, Output};

use serde_json::{Value, json};

use crate::helpers::{seed_machine_and_surface, spawn_app};

/// Runs the binary off the async runtime (the server shares the process).
async fn truecut(args: Vec<String>) -> Output {
    tokio::task::spawn_blocking(move || {
        Command::new(env!("CARGO_BIN_EXE_truecut"))
            .args(&args)
            .env_remove("TRUECUT_SERVER")
            .env_remove("TRUECUT_TOKEN")
            .env("RUST_LOG", "warn")
            .output()
            .expect("the binary runs")
    })
    .await
    .unwrap()
}

fn args(list: &[&str]) -> Vec<String> {
    list.iter().map(|s| s.to_string()).collect()
}

fn text(out: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn upload_then_compensation_and_exit_codes() {
    let app = spawn_app().await;
    seed_machine_and_surface(&app, "m1", "s1", 5, 4).await;
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("probe.csv");
    let mut body = String::from("deviation\n");
    for k in 0..20 {
        body += &format!("{}\n", 0.001 * (k as f64 - 10.0));
    }
    std::fs::write(&csv, body).unwrap();
    let csv = csv.to_str().unwrap().to_string();
    let out = truecut(args(&["upload", "--server", &app.addr, "m1", "s1", &csv])).await;
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stdout} {stderr}");
    let id = stdout.trim().to_string();
    assert!(
        !id.is_empty() && !id.contains(' '),
        "stdout is the id alone: {stdout:?}"
    );
    // Piped (not a terminal): quiet lines, no progress bar escapes.
    assert!(
        stderr.contains("uploading") && stderr.contains("stored measurement"),
        "{stderr}"
    );
    assert!(!stderr.contains('\u{1b}'), "{stderr:?}");
    let m: Value = app
        .get(&format!("/v1/machines/m1/surfaces/s1/measurements/{id}"))
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(m["n"], 20);
    // With a chosen id.
    let out = truecut(args(&[
        "upload", "--server", &app.addr, "--id", "run-7", "m1", "s1", &csv,
    ]))
    .await;
    assert_eq!(text(&out).0.trim(), "run-7");

    let out = truecut(args(&[
        "compensation",
        "--server",
        &app.addr,
        "m1",
        "s1",
        "--measurement",
        &id,
    ]))
    .await;
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(lines[0], "x,y,z,i,j,k,offset");
    assert_eq!(lines.len(), 21);
    let out = truecut(args(&[
        "compensation",
        "--server",
        &app.addr,
        "m1",
        "s1",
        "--measurement",
        &id,
        "--format",
        "json",
    ]))
    .await;
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["points"].as_array().unwrap().len(), 20);

    // 3: the server refused (unknown surface), with its sentence.
    let out = truecut(args(&["upload", "--server", &app.addr, "m1", "nope", &csv])).await;
    assert_eq!(out.status.code(), Some(3), "{:?}", text(&out));
    assert!(text(&out).1.contains("surface 'nope'"), "{}", text(&out).1);
    // 4: nothing listens there.
    let closed = {
        let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        format!("http://{}", l.local_addr().unwrap())
    };
    let out = truecut(args(&["upload", "--server", &closed, "m1", "s1", &csv])).await;
    assert_eq!(out.status.code(), Some(4), "{:?}", text(&out));
    assert!(
        text(&out).1.contains("cannot be reached"),
        "{}",
        text(&out).1
    );
    // 2: usage; 1: a local file that is not there.
    let out = truecut(args(&["upload", "--server", &app.addr, "m1"])).await;
    assert_eq!(out.status.code(), Some(2));
    let out = truecut(args(&[
        "upload",
        "--server",
        &app.addr,
        "m1",
        "s1",
        "/no/such.csv",
    ]))
    .await;
    assert_eq!(out.status.code(), Some(1));
    // Tokens: 3 (401) without one, 0 with a write token.
    let mut secured =
        crate::helpers::spawn_app_with(|c| c.tokens = Some("w-token write, a-token admin".into()))
            .await;
    secured.token = Some("a-token".into());
    seed_machine_and_surface(&secured, "m1", "s1", 5, 4).await;
    let out = truecut(args(&[
        "upload",
        "--server",
        &secured.addr,
        "m1",
        "s1",
        &csv,
    ]))
    .await;
    assert_eq!(out.status.code(), Some(3), "{:?}", text(&out));
    assert!(text(&out).1.contains("401"), "{}", text(&out).1);
    let out = truecut(args(&[
        "upload",
        "--server",
        &secured.addr,
        "--token",
        "w-token",
        "m1",
        "s1",
        &csv,
    ]))
    .await;
    assert!(out.status.success(), "{:?}", text(&out));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn jobs_submit_wait_and_a_cancelled_job_exits_5() {
    let app = spawn_app().await;
    seed_machine_and_surface(&app, "m", "s1", 5, 5).await;
    let s: Value = app
        .post_json(
            "/v1/step-error/samples",
            &json!({"surface": {"reference": 1}, "plan": {"tool_radius_mm": 5.0, "lines": 8, "points_per_line": 30}}),
        )
        .await
        .json()
        .await
        .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let quick = dir.path().join("quick.json");
    std::fs::write(
        &quick,
        json!({"tool_radius": 5.0, "segments": s["segments"], "epochs": 20}).to_string(),
    )
    .unwrap();
    let path = "/v1/machines/m/surfaces/s1/step-error-model";
    let out = truecut(args(&[
        "jobs",
        "--server",
        &app.addr,
        "submit",
        path,
        quick.to_str().unwrap(),
        "--wait",
    ]))
    .await;
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stdout} {stderr}");
    let result: Value = serde_json::from_str(&stdout).unwrap();
    assert!(result["test_max_abs_um"].is_number(), "{result}");
    assert!(
        stderr.contains("accepted") && stderr.contains("done 100 %"),
        "{stderr}"
    );

    let long = dir.path().join("long.json");
    std::fs::write(
        &long,
        json!({"tool_radius": 5.0, "segments": s["segments"], "epochs": 20_000}).to_string(),
    )
    .unwrap();
    let out = truecut(args(&[
        "jobs",
        "--server",
        &app.addr,
        "submit",
        path,
        long.to_str().unwrap(),
    ]))
    .await;
    let job: Value = serde_json::from_slice(&out.stdout).unwrap();
    let id = job["job"].as_str().unwrap().to_string();
    let out = truecut(args(&["jobs", "--server", &app.addr, "cancel", &id])).await;
    assert!(out.status.success(), "{:?}", text(&out));
    let out = truecut(args(&["jobs", "--server", &app.addr, "get", &id, "--wait"])).await;
    assert_eq!(out.status.code(), Some(5), "{:?}", text(&out));
    assert!(text(&out).1.contains("cancelled"));
    let out = truecut(args(&[
        "jobs",
        "--server",
        &app.addr,
        "list",
        "--state",
        "cancelled",
    ]))
    .await;
    let listed: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(listed["jobs"].as_array().unwrap().len(), 1);
    let out = truecut(args(&["jobs", "--server", &app.addr, "get", "no-such-job"])).await;
    assert_eq!(out.status.code(), Some(3));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn iso_files_locally_and_on_the_server() {
    let app = spawn_app().await;
    let dir = tempfile::tempdir().unwrap();
    // The hand table as the long CSV: target,direction,measured.
    let body = crate::iso230::hand_body(1.0);
    let mut csv = String::from("target,direction,measured\n");
    for (i, t) in body["targets"].as_array().unwrap().iter().enumerate() {
        for j in 0..5 {
            csv += &format!("{t},fwd,{}\n", body["forward"][i][j]);
            csv += &format!("{t},bwd,{}\n", body["backward"][i][j]);
        }
    }
    let table = dir.path().join("x_axis.csv");
    std::fs::write(&table, csv).unwrap();
    let table = table.to_str().unwrap().to_string();
    let local = truecut(args(&["iso230-2", &table])).await;
    let (stdout, stderr) = text(&local);
    assert!(local.status.success(), "{stderr}");
    assert!(
        stdout.contains("R    10.00")
            && stdout.contains("E     8.00")
            && stdout.contains("A    12.00"),
        "{stdout}"
    );
    let remote = truecut(args(&["iso230-2", "--server", &app.addr, &table])).await;
    assert_eq!(
        text(&remote).0,
        stdout,
        "the server and the local core agree"
    );
    // Stored per axis.
    assert!(
        app.put_json("/v1/machines/m1", &crate::helpers::machine_xyz())
            .await
            .status()
            .is_success()
    );
    let out = truecut(args(&[
        "iso230-2",
        "--server",
        &app.addr,
        "--machine",
        "m1",
        "--axis",
        "X",
        "--label",
        "before",
        &table,
        "--json",
    ]))
    .await;
    let stored: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(stored["label"], "before");
    let runs: Value = app
        .get("/v1/machines/m1/axes/X/iso230-2")
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(runs["runs"].as_array().unwrap().len(), 1);
    // --machine without --server is a usage error.
    let out = truecut(args(&[
        "iso230-2",
        "--machine",
        "m1",
        "--axis",
        "X",
        &table,
    ]))
    .await;
    assert_eq!(out.status.code(), Some(2));
    // A refused table is exit 3 on the server and 1 locally, with the same sentence.
    let bad = dir.path().join("bad.csv");
    std::fs::write(
        &bad,
        "target,direction,measured\n0,fwd,0.001\n0,bwd,0\n10,fwd,10\n10,bwd,10\n",
    )
    .unwrap();
    let bad = bad.to_str().unwrap().to_string();
    let out = truecut(args(&["iso230-2", "--server", &app.addr, &bad])).await;
    assert_eq!(out.status.code(), Some(3));
    assert!(
        text(&out).1.contains("at least 2 cycles"),
        "{}",
        text(&out).1
    );
    let out = truecut(args(&["iso230-2", &bad])).await;
    assert_eq!(out.status.code(), Some(1));
    assert!(text(&out).1.contains("at least 2 cycles"));

    // ISO 230-4: a three-lobe circle and its reverse (G = 8 µm, H = 8 µm).
    let ring = |sign: f64| {
        let mut s = String::from("x,y\n");
        for k in 0..360 {
            let t = std::f64::consts::TAU * k as f64 / 360.0;
            let r = 50.003 + sign * 0.004 * (3.0 * t).cos();
            s += &format!("{},{}\n", r * t.cos(), r * t.sin());
        }
        s
    };
    let (ccw, cw) = (dir.path().join("ccw.csv"), dir.path().join("cw.csv"));
    std::fs::write(&ccw, ring(1.0)).unwrap();
    std::fs::write(&cw, ring(-1.0)).unwrap();
    let (ccw, cw) = (
        ccw.to_str().unwrap().to_string(),
        cw.to_str().unwrap().to_string(),
    );
    let local = truecut(args(&[
        "iso230-4",
        &ccw,
        "--radius",
        "50",
        "--reverse",
        &cw,
    ]))
    .await;
    let (stdout, stderr) = text(&local);
    assert!(local.status.success(), "{stderr}");
    assert!(
        stdout.contains("G     8.00") && stdout.contains("H     8.00"),
        "{stdout}"
    );
    let remote = truecut(args(&[
        "iso230-4",
        "--server",
        &app.addr,
        &ccw,
        "--radius",
        "50",
        "--reverse",
        &cw,
    ]))
    .await;
    assert_eq!(text(&remote).0, stdout);
    let sim = truecut(args(&[
        "iso230-4",
        "--server",
        &app.addr,
        "--simulate",
        "m1",
        "--radius",
        "20",
        "--feed",
        "1500",
    ]))
    .await;
    let (stdout, stderr) = text(&sim);
    assert!(sim.status.success(), "{stderr}");
    assert!(
        stdout.contains("ccw: G") && stdout.contains("\nH "),
        "{stdout}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_subcommand_help_has_an_example_and_the_exit_codes_are_listed() {
    let top = truecut(args(&["--help"])).await;
    let (stdout, _) = text(&top);
    assert!(
        stdout.contains("Exit codes: 0 success") && stdout.contains("5 a followed job failed"),
        "{stdout}"
    );
    let subs: Vec<String> = stdout
        .split("Commands:")
        .nth(1)
        .unwrap()
        .lines()
        .skip(1)
        .take_while(|l| !l.trim().is_empty())
        .filter(|l| l.starts_with("  ") && !l.starts_with("   "))
        .filter_map(|l| l.split_whitespace().next().map(str::to_string))
        .filter(|s| s != "help")
        .collect();
    assert!(subs.len() >= 11, "{subs:?}");
    for sub in subs {
        let out = truecut(vec![sub.clone(), "--help".into()]).await;
        let (stdout, _) = text(&out);
        assert!(
            out.status.success() && stdout.contains("Example:\n  truecut"),
            "{sub} --help: {stdout}"
        );
    }
    for sub in ["list", "get", "cancel", "submit"] {
        let out = truecut(args(&["jobs", sub, "--help"])).await;
        assert!(text(&out).0.contains("Example:"), "jobs {sub}");
    }
}

/// `truecut effects accept` stores the `accept` of a saved motion diagnosis as the machine's
/// effects (issue 40 item 3), `versions` lists it, `rollback` serves an earlier one; an
/// answer without `accept` is refused with exit 1 and a sentence.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn effects_accept_versions_and_rollback() {
    let app = spawn_app().await;
    let r = app
        .put_json("/v1/machines/m1", &crate::helpers::machine_xyz())
        .await;
    assert!(r.status().is_success());
    let dir = tempfile::tempdir().unwrap();
    let answer = dir.path().join("diagnosis.json");
    let first = json!({"domain": "motion", "verdict": "backlash",
        "accept": {"effects": [{"effect": "backlash", "params": {"x_mm": 0.02}}],
                   "source": "gap diagnosis of today"}});
    std::fs::write(&answer, first.to_string()).unwrap();
    let answer = answer.to_str().unwrap().to_string();
    let run = |list: &[&str]| {
        let mut a = args(list);
        a.insert(1, "--server".into());
        a.insert(2, app.addr.clone());
        truecut(a)
    };
    let out = run(&["effects", "accept", "m1", "--answer", &answer]).await;
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stdout} {stderr}");
    let stored: Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(stored["version"], 1);
    assert!(
        stored["source"]
            .as_str()
            .unwrap()
            .contains("diagnosis.json"),
        "{stored}"
    );
    assert!(stderr.contains("1 effects stored as version 1"), "{stderr}");
    let out = run(&["effects", "accept", "m1", "--answer", &answer]).await;
    assert!(out.status.success());
    let out = run(&["effects", "versions", "m1"]).await;
    let v: Value = serde_json::from_str(&text(&out).0).unwrap();
    assert_eq!(v["current"], 2);
    let out = run(&["effects", "rollback", "m1", "1"]).await;
    let v: Value = serde_json::from_str(&text(&out).0).unwrap();
    assert_eq!(v["current"], 1);
    let out = run(&["effects", "show", "m1"]).await;
    let v: Value = serde_json::from_str(&text(&out).0).unwrap();
    assert_eq!(v["effects"][0]["params"]["x_mm"], 0.02);
    // a part answer has nothing to accept
    let part = dir.path().join("part.json");
    std::fs::write(&part, json!({"domain": "part"}).to_string()).unwrap();
    let out = run(&[
        "effects",
        "accept",
        "m1",
        "--answer",
        part.to_str().unwrap(),
    ])
    .await;
    let (_, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("only a motion gap diagnosis"), "{stderr}");
}
