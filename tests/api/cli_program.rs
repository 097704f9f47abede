//! `truecut program` (issue 24, one command for a post-processor's pipeline) as the real binary
//! against a spawned server: the compensated program on stdout byte for byte as the route
//! answers it, the warnings on stderr, `--output` replaced only on success, a Latin-1 post
//! written back in Latin-1, a `202` job followed (`--job`), and the exit codes (1 local file,
//! 2 usage, 3 refused, 4 unreachable, 5 the followed job failed).

use std::io::Write;
use std::process::{Command, Output, Stdio};

use serde_json::{Value, json};
use truecut::volumetric::{ShapeFamily, SyntheticMachine};

use crate::helpers::{TestApp, machine_xyz, spawn_app};

/// Runs the binary off the async runtime (the server shares the process), `stdin` piped in.
async fn truecut(args: &[&str], stdin: &[u8]) -> Output {
    let args: Vec<String> = args.iter().map(|s| s.to_string()).collect();
    let stdin = stdin.to_vec();
    tokio::task::spawn_blocking(move || {
        let mut child = Command::new(env!("CARGO_BIN_EXE_truecut"))
            .args(&args)
            .env_remove("TRUECUT_SERVER")
            .env_remove("TRUECUT_TOKEN")
            .env("RUST_LOG", "warn")
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("the binary runs");
        child.stdin.take().unwrap().write_all(&stdin).unwrap();
        child.wait_with_output().unwrap()
    })
    .await
    .unwrap()
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Machine `m1` (the helpers' servo models) with a volumetric map fitted to a synthetic
/// machine's grid (as tests/api/compensated.rs).
async fn machine_with_map(app: &TestApp) {
    let r = app.put_json("/v1/machines/m1", &machine_xyz()).await;
    assert!(r.status().is_success(), "PUT machine: {}", r.status());
    let m = SyntheticMachine::new(8, ShapeFamily::TrendAndWaviness);
    let d = m.measure_grid([6, 5, 4], 3);
    let body = json!({"nodes": d.nodes, "errors": d.errors, "model": "kinematic",
                      "tool_offset_mm": m.tool_offset_mm});
    let r = app.put_json("/v1/machines/m1/volumetric-map", &body).await;
    assert_eq!(r.status(), 201, "PUT map");
}

const FANUC: &str = include_str!("../data/programs/fanuc_finish.nc");

/// A circle at F 2000 with a spindle line (one warning), placed in the map's box by G54.
const CIRCLE: &str = "%\nO1001 (CIRCLE R25 F2000)\nN10 G21 G90 G17 G94 G54\nN20 M3 S8000\n\
                      N30 G1 X0 Y15. Z0 F2000\nN40 G3 X0 Y15. I-25. J0\nN50 G1 Y30.\nN60 M5\nM30\n%\n";

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn program_to_stdout_warnings_to_stderr_and_output_file() {
    let app = spawn_app().await;
    machine_with_map(&app).await;
    let dir = tempfile::tempdir().unwrap();
    let nc = dir.path().join("part.nc");
    std::fs::write(&nc, FANUC).unwrap();
    let nc = nc.to_str().unwrap();
    let flags = ["--work-offset", "G54=300,150,100", "--tool-length", "1=150"];
    let mut argv = vec!["program", "--server", &app.addr, "--machine", "m1"];
    argv.extend(flags);
    argv.push(nc);
    let out = truecut(&argv, b"").await;
    assert!(out.status.success(), "{}", stderr(&out));
    // The route's own answer for the same body.
    let r = app
        .post_json(
            "/v1/machines/m1/compensated-program",
            &json!({"gcode": FANUC, "work_offsets": {"G54": [300.0, 150.0, 100.0]},
                    "tool_lengths": {"1": 150.0}}),
        )
        .await;
    assert_eq!(r.status(), 200);
    let want: Value = r.json().await.unwrap();
    let program = want["gcode"].as_str().unwrap();
    assert_eq!(
        String::from_utf8(out.stdout.clone()).unwrap(),
        program,
        "stdout is the program alone, byte for byte"
    );
    assert_ne!(program, FANUC, "the map moved some axis words");
    let err = stderr(&out);
    let warnings = want["warnings"].as_array().unwrap();
    assert!(!warnings.is_empty(), "the Fanuc post has T/M/S words");
    for w in warnings {
        let line = format!("warning: {nc}: {}", w.as_str().unwrap());
        assert!(err.contains(&line), "{line} missing from stderr:\n{err}");
    }
    assert!(
        err.contains("compensated on machine m1") && err.contains("largest volumetric shift"),
        "{err}"
    );
    assert!(!err.contains('\u{1b}'), "no terminal escapes when piped");

    // The same from stdin into --output; a failed run leaves an existing output untouched.
    let target = dir.path().join("part_comp.nc");
    let target_s = target.to_str().unwrap();
    let mut argv = vec!["program", "--server", &app.addr, "--machine", "m1"];
    argv.extend(flags);
    argv.extend(["-o", target_s, "-"]);
    let out = truecut(&argv, FANUC.as_bytes()).await;
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(out.stdout.is_empty());
    assert_eq!(std::fs::read_to_string(&target).unwrap(), program);
    let out = truecut(
        &[
            "program",
            "--server",
            &app.addr,
            "--machine",
            "nope",
            "-o",
            target_s,
            nc,
        ],
        b"",
    )
    .await;
    assert_eq!(out.status.code(), Some(3), "{}", stderr(&out));
    assert_eq!(std::fs::read_to_string(&target).unwrap(), program);
    let leftovers = std::fs::read_dir(dir.path()).unwrap().count();
    assert_eq!(
        leftovers, 2,
        "part.nc and part_comp.nc only, no temporary file"
    );

    // A Windows post's Latin-1 comment comes back in Latin-1, byte for byte.
    let mut latin1 = b"(\xD810 FR\xC4SER)\n".to_vec();
    latin1.extend_from_slice(b"G21 G90 G54\nG0 X10 Y10 Z5\nG1 X60 F1000\nM30\n");
    let out = truecut(
        &["program", "--server", &app.addr, "--machine", "m1", "-"],
        &latin1,
    )
    .await;
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        out.stdout.starts_with(b"(\xD810 FR\xC4SER)\n"),
        "{:?}",
        String::from_utf8_lossy(&out.stdout)
    );
    assert!(out.stdout.ends_with(b"M30\n"));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn contour_as_a_followed_job_and_exit_codes() {
    let app = spawn_app().await;
    machine_with_map(&app).await;
    let dir = tempfile::tempdir().unwrap();
    let nc = dir.path().join("circle.nc");
    std::fs::write(&nc, CIRCLE).unwrap();
    let nc = nc.to_str().unwrap();
    let base = ["program", "--server", &app.addr, "--machine", "m1"];
    let offset = ["--work-offset", "G54=300,200,150"];

    // --job: the route answers 202, the command follows the job and prints its program.
    let mut argv = base.to_vec();
    argv.extend(offset);
    argv.extend(["--contour", "--job", nc]);
    let out = truecut(&argv, b"").await;
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("accepted; following it") && err.contains(": done"),
        "{err}"
    );
    assert!(err.contains("simulated contour error RMS"), "{err}");
    let id = err
        .lines()
        .find_map(|l| {
            l.strip_prefix("job ")?
                .strip_suffix(" accepted; following it")
        })
        .expect("the job's id on stderr");
    let job: Value = app
        .get(&format!("/v1/jobs/{id}"))
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(job["state"], "done", "{job}");
    assert_eq!(job["kind"], "compensated-program", "{job}");
    assert_eq!(
        String::from_utf8(out.stdout.clone()).unwrap(),
        job["result"]["gcode"].as_str().unwrap_or_default(),
    );
    // The same request answered directly (no job) gives the same program.
    let r = app
        .post_json(
            "/v1/machines/m1/compensated-program",
            &json!({"gcode": CIRCLE, "contour": true,
                    "work_offsets": {"G54": [300.0, 200.0, 150.0]}}),
        )
        .await;
    assert_eq!(r.status(), 200);
    let direct: Value = r.json().await.unwrap();
    assert_eq!(
        String::from_utf8(out.stdout).unwrap(),
        direct["gcode"].as_str().unwrap()
    );
    assert!(
        direct["contour"]["iterations"].as_u64().unwrap() >= 1,
        "{direct}"
    );

    // 5: the followed job failed (the service refuses the arc).
    // An arc whose R is shorter than half its chord: the service refuses it while reading.
    let dwell = dir.path().join("bad_arc.nc");
    std::fs::write(&dwell, "G21 G90\nG1 X5 F600\nG2 X10 Y0 R1\nG1 X12\n").unwrap();
    let mut argv = base.to_vec();
    argv.extend([
        "--contour",
        "--no-volumetric",
        "--job",
        dwell.to_str().unwrap(),
    ]);
    let out = truecut(&argv, b"").await;
    assert_eq!(out.status.code(), Some(5), "{}", stderr(&out));
    assert!(stderr(&out).contains("failed"), "{}", stderr(&out));
    assert!(out.stdout.is_empty());
    // 3: refused without a job (the same arc, 422), an unknown machine (404), strict.
    let mut argv = base.to_vec();
    argv.extend(["--contour", "--no-volumetric", dwell.to_str().unwrap()]);
    let out = truecut(&argv, b"").await;
    assert_eq!(out.status.code(), Some(3), "{}", stderr(&out));
    assert!(stderr(&out).contains("422"), "{}", stderr(&out));
    let out = truecut(
        &["program", "--server", &app.addr, "--machine", "nope", nc],
        b"",
    )
    .await;
    assert_eq!(out.status.code(), Some(3), "{}", stderr(&out));
    assert!(stderr(&out).contains("nope"), "{}", stderr(&out));
    let mut argv = base.to_vec();
    argv.extend(offset);
    argv.extend(["--strict", nc]);
    let out = truecut(&argv, b"").await;
    assert_eq!(out.status.code(), Some(3), "{}", stderr(&out));
    assert!(out.stdout.is_empty());
    // --max-duration-ratio reaches the service, which refuses a ratio outside 1..2.
    let mut argv = base.to_vec();
    argv.extend(offset);
    argv.extend(["--contour", "--max-duration-ratio", "3", nc]);
    let out = truecut(&argv, b"").await;
    assert_eq!(out.status.code(), Some(3), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("max_duration_ratio must be within 1..2"),
        "{}",
        stderr(&out)
    );
    // 4: nothing listens there.
    let closed = {
        let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        format!("http://{}", l.local_addr().unwrap())
    };
    let out = truecut(
        &["program", "--server", &closed, "--machine", "m1", nc],
        b"",
    )
    .await;
    assert_eq!(out.status.code(), Some(4), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("cannot be reached"),
        "{}",
        stderr(&out)
    );
    // 2: usage (no --machine; a bad --work-offset is 1, a local mistake); 1: no such file.
    let out = truecut(&["program", "--server", &app.addr, nc], b"").await;
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    let out = truecut(
        &[
            "program",
            "--server",
            &app.addr,
            "--machine",
            "m1",
            "--work-offset",
            "G54=1,2",
            nc,
        ],
        b"",
    )
    .await;
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(stderr(&out).contains("three numbers"), "{}", stderr(&out));
    let out = truecut(
        &[
            "program",
            "--server",
            &app.addr,
            "--machine",
            "m1",
            "/no/such.nc",
        ],
        b"",
    )
    .await;
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
}
