//! HTTP end to end: `POST /v1/machines/{machine}/compensated-program` and
//! `.../compensated-points` (openapi.yaml; CONTRACT v1.1 "Compensated programs"), on a map
//! fitted through the API from a synthetic machine's grid, checked against the map's own
//! predict route (`POST .../volumetric-map/predict`) on three post-processor programs
//! (`tests/data/programs/`, see tests/data/README.md).

use crate::helpers::*;

use serde_json::{Value, json};
use truecut::cam::arc_point;
use truecut::motion::gcode::{Block, Feed, Motion, ReadOptions, parse_with, word_spans};
use truecut::volumetric::{ShapeFamily, SyntheticMachine};

const PROGRAM: &str = "/v1/machines/m/compensated-program";
const POINTS: &str = "/v1/machines/m/compensated-points";
const PREDICT: &str = "/v1/machines/m/volumetric-map/predict";

/// Half the output resolution in mm along a diagonal (4 decimals in mm, 5 in inch).
const ROUNDING_MM: f64 = 0.5e-4 * 1.7321;

async fn machine_with_map(app: &TestApp) {
    let r = app.put_json("/v1/machines/m", &machine_xyz()).await;
    assert!(r.status().is_success(), "PUT machine: {}", r.status());
    let m = SyntheticMachine::new(8, ShapeFamily::TrendAndWaviness);
    let d = m.measure_grid([6, 5, 4], 3);
    let body = json!({"nodes": d.nodes, "errors": d.errors, "model": "kinematic",
                      "tool_offset_mm": m.tool_offset_mm});
    let r = app.put_json("/v1/machines/m/volumetric-map", &body).await;
    assert_eq!(r.status(), 201, "PUT map");
}

/// e(p) of the map by its predict route, mm.
async fn predict(app: &TestApp, points: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let mut out = Vec::new();
    for chunk in points.chunks(5000) {
        let r = app.post_json(PREDICT, &json!({"points": chunk})).await;
        assert_eq!(r.status(), 200);
        let b: Value = r.json().await.unwrap();
        out.extend(serde_json::from_value::<Vec<[f64; 3]>>(b["errors"].clone()).unwrap());
    }
    out
}

struct Case {
    name: &'static str,
    text: &'static str,
    offsets: Value,
    tools: Value,
}

fn cases() -> Vec<Case> {
    vec![
        Case {
            name: "fanuc_finish",
            text: include_str!("../data/programs/fanuc_finish.nc"),
            offsets: json!({"G54": [300.0, 150.0, 100.0]}),
            tools: json!({"1": 150.0}),
        },
        Case {
            name: "haas_drill",
            text: include_str!("../data/programs/haas_drill.nc"),
            offsets: json!({"G54": [200.0, 100.0, 150.0]}),
            tools: json!({"3": 100.0}),
        },
        Case {
            name: "siemens_iso_turnmill",
            text: include_str!("../data/programs/siemens_iso_turnmill.nc"),
            offsets: json!({"G54": [300.0, 200.0, 150.0]}),
            tools: json!({"5": 120.0}),
        },
    ]
}

fn read_options(c: &Case) -> ReadOptions {
    let mut o = ReadOptions::default();
    o.work_offsets_mm[0] = serde_json::from_value(c.offsets["G54"].clone()).unwrap();
    for (k, v) in c.tools.as_object().unwrap() {
        o.tool_lengths_mm
            .insert(k.parse().unwrap(), v.as_f64().unwrap());
    }
    o
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn to_segment(c: [f64; 3], s: [f64; 3], e: [f64; 3]) -> f64 {
    let d = sub(e, s);
    let l2: f64 = d.iter().map(|v| v * v).sum();
    let t = if l2 > 0.0 {
        ((0..3).map(|k| (c[k] - s[k]) * d[k]).sum::<f64>() / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    dist([0, 1, 2].map(|k| s[k] + d[k] * t), c)
}

/// Distance (mm) from `c` to the written block `g`: its segment, or its arc (sub-arcs of a
/// split arc stay arcs): coarse samples find the nearest part, a fine search the distance.
fn to_block(c: [f64; 3], g: &Block) -> f64 {
    match g.motion {
        Motion::Arc {
            plane,
            center,
            sweep_rad,
        } => {
            let at = |t: f64| dist(arc_point(g, plane, center, sweep_rad, t), c);
            let n = 400;
            let k = (0..=n)
                .min_by(|&a, &b| at(a as f64 / n as f64).total_cmp(&at(b as f64 / n as f64)))
                .unwrap();
            let lo = (k as f64 - 1.0).max(0.0) / n as f64;
            let hi = (k as f64 + 1.0).min(n as f64) / n as f64;
            (0..=2000)
                .map(|i| at(lo + (hi - lo) * i as f64 / 2000.0))
                .fold(f64::INFINITY, f64::min)
        }
        _ => to_segment(c, g.start.xyz, g.end.xyz),
    }
}

/// The point of a source block that the compensation places: its end, or for a canned-cycle
/// line the hole bottom (the end of its feed move).
fn placed_point(blocks: &[&Block]) -> Option<[f64; 3]> {
    match blocks {
        [b] if !matches!(b.motion, Motion::Dwell { .. }) => Some(b.end.xyz),
        // A hole: its deepest feed end (G73/G83 feed in pecks, G84/G85/G89 feed back out).
        [_, _, ..] => blocks
            .iter()
            .filter(|b| b.feed != Feed::Rapid)
            .map(|b| b.end.xyz)
            .reduce(|a, b| if b[2] < a[2] { b } else { a }),
        _ => None,
    }
}

/// Every answer of the route goes through the validity check (issue 24, item 3;
/// `tests/gcode_oracle/valid.rs`): re-read by truecut's reader and by rs274, both parse it,
/// and every programmed point p of `original` is hit at p − e(p) within 1 µm, e from the
/// map's predict route (zero without `volumetric`).
#[allow(clippy::too_many_arguments)]
async fn assert_valid(
    app: &TestApp,
    tag: &str,
    original: &str,
    options: &ReadOptions,
    volumetric: bool,
    contour: bool,
    gcode: &str,
    source_lines: &[usize],
) {
    let mut table = std::collections::HashMap::new();
    if volumetric {
        let pts = crate::valid::needed_points(original, options);
        let e = predict(app, &pts).await;
        table.extend(pts.into_iter().map(|p| p.map(f64::to_bits)).zip(e));
    }
    let lookup = |p: [f64; 3]| -> [f64; 3] {
        *table
            .get(&p.map(f64::to_bits))
            .unwrap_or_else(|| panic!("{tag}: e({p:?}) was not fetched"))
    };
    let rs = crate::rs274::required();
    let dir = tempfile::tempdir().unwrap();
    let asked = crate::valid::Asked {
        error: volumetric.then_some(&lookup as &dyn Fn([f64; 3]) -> [f64; 3]),
        contour,
    };
    let c = crate::valid::check(
        tag,
        original,
        options,
        &asked,
        gcode,
        source_lines,
        rs.as_deref(),
        dir.path(),
    )
    .unwrap_or_else(|e| panic!("{e}\n--- answer:\n{gcode}"));
    println!(
        "{tag}: valid: {} programmed points re-read, worst |q - (p - e(p))| truecut {:.3} µm, \
         rs274 {}",
        c.points,
        c.worst_truecut_mm * 1e3,
        match c.worst_rs274_mm {
            Ok(d) => format!("{:.3} µm", d * 1e3),
            Err(why) => format!("not read ({why})"),
        }
    );
}

async fn programs_match_the_predict_route(app: TestApp) {
    machine_with_map(&app).await;
    let tol = 0.001;
    let mut split_lines_checked = 0;
    for c in cases() {
        let r = app
            .post_json(
                PROGRAM,
                &json!({"gcode": c.text, "work_offsets": c.offsets, "tool_lengths": c.tools}),
            )
            .await;
        assert_eq!(r.status(), 200, "{}", c.name);
        let b: Value = r.json().await.unwrap();
        let out = b["gcode"].as_str().unwrap();
        let source_lines: Vec<usize> = serde_json::from_value(b["source_lines"].clone()).unwrap();
        assert_eq!(b["blocks"].as_u64().unwrap() as usize, out.lines().count());
        assert_eq!(source_lines.len(), out.lines().count());
        let opts = read_options(&c);
        assert_valid(&app, c.name, c.text, &opts, true, false, out, &source_lines).await;
        // The answer parses with the reader.
        let (src_prog, _) = parse_with(c.text, &opts).unwrap();
        let (out_prog, _) = parse_with(out, &opts).expect("the answer parses");
        // Non-motion lines pass through byte for byte.
        let out_lines: Vec<&str> = out.lines().collect();
        for (idx, raw) in c.text.lines().enumerate() {
            let moves = word_spans(raw).iter().any(|s| "XYZ".contains(s.letter));
            if !moves || raw.contains("G28") || raw.contains("G53") {
                let at = source_lines.iter().position(|&l| l == idx + 1).unwrap();
                assert_eq!(out_lines[at], raw, "{}: line {}", c.name, idx + 1);
            }
        }
        // Every placed point q against p − e(p), e from the predict route.
        let n_lines = c.text.lines().count();
        let mut pairs = Vec::new();
        for line in 1..=n_lines {
            let src: Vec<&Block> = src_prog.blocks.iter().filter(|b| b.line == line).collect();
            let got: Vec<&Block> = out_prog
                .blocks
                .iter()
                .filter(|b| source_lines[b.line - 1] == line)
                .collect();
            let q = if src.len() > 1 {
                placed_point(&got)
            } else {
                got.last().map(|b| b.end.xyz)
            };
            let (Some(p), Some(q)) = (placed_point(&src), q) else {
                continue;
            };
            pairs.push((line, p, q, src, got));
        }
        let e = predict(&app, &pairs.iter().map(|x| x.1).collect::<Vec<_>>()).await;
        let mut worst: f64 = 0.0;
        // Axes not placed before the first line that names them keep the reader's guess.
        let first_z = c
            .text
            .lines()
            .position(|l| {
                !l.trim_start().starts_with(';') && word_spans(l).iter().any(|s| s.letter == 'Z')
            })
            .unwrap()
            + 1;
        for ((line, p, q, src, _), e) in pairs.iter().zip(&e) {
            if *line < first_z {
                continue;
            }
            // A rapid gains no axis word (issue 39): only the axes it names are compensated.
            let raw = c.text.lines().nth(line - 1).unwrap_or("");
            let rapid = src
                .iter()
                .all(|b| b.feed == truecut::motion::gcode::Feed::Rapid);
            let want = sub(*p, *e);
            let miss = (0..3)
                .filter(|&k| {
                    !rapid
                        || word_spans(raw)
                            .iter()
                            .any(|s| s.letter == ['X', 'Y', 'Z'][k])
                })
                .map(|k| (q[k] - want[k]).powi(2))
                .sum::<f64>()
                .sqrt();
            assert!(
                miss <= tol + ROUNDING_MM,
                "{} line {line}: q {q:?}, p - e(p) {:?}",
                c.name,
                sub(*p, *e)
            );
            worst = worst.max(miss);
        }
        println!(
            "{}: goal |q - (p - e(p))| <= {:.1} µm (+{:.3} µm rounding); ours max {:.3} µm over {} \
             points; max_shift {:.2} µm; {} -> {} blocks",
            c.name,
            tol * 1e3,
            ROUNDING_MM * 1e3,
            worst * 1e3,
            pairs.len(),
            b["max_shift_mm"].as_f64().unwrap() * 1e3,
            n_lines,
            b["blocks"]
        );
        // Split moves: the original path sampled densely, compensated through predict, lies
        // within the tolerance of the emitted polyline.
        for (line, _, _, src, got) in &pairs {
            let [o] = src.as_slice() else { continue };
            if got.len() < 2 || o.feed == Feed::Rapid {
                continue;
            }
            split_lines_checked += 1;
            let samples: Vec<[f64; 3]> = (0..=400)
                .map(|i| {
                    let t = i as f64 / 400.0;
                    match o.motion {
                        Motion::Arc {
                            plane,
                            center,
                            sweep_rad,
                        } => arc_point(o, plane, center, sweep_rad, t),
                        _ => {
                            [0, 1, 2].map(|k| o.start.xyz[k] + (o.end.xyz[k] - o.start.xyz[k]) * t)
                        }
                    }
                })
                .collect();
            let es = predict(&app, &samples).await;
            let mut far: f64 = 0.0;
            for (p, e) in samples.iter().zip(&es) {
                let c = sub(*p, *e);
                let d = got
                    .iter()
                    .map(|g| to_block(c, g))
                    .fold(f64::INFINITY, f64::min);
                far = far.max(d);
            }
            println!(
                "{} line {line}: split into {} moves; goal <= {:.1} µm from the compensated \
                 path, ours {:.3} µm",
                c.name,
                got.len(),
                tol * 1e3,
                far * 1e3
            );
            assert!(far <= tol + ROUNDING_MM, "{} line {line}: {far} mm", c.name);
        }
    }
    assert!(split_lines_checked > 0, "no split line was exercised");
}
on_both_backends!(programs_match_the_predict_route);

async fn text_plain_and_points(app: TestApp) {
    machine_with_map(&app).await;
    let c = &cases()[0];
    let body = json!({"gcode": c.text, "work_offsets": c.offsets, "tool_lengths": c.tools});
    let json_answer: Value = app.post_json(PROGRAM, &body).await.json().await.unwrap();
    let r = app
        .client
        .post(app.url(PROGRAM))
        .header("accept", "text/plain")
        .json(&body)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    assert_eq!(
        r.headers()["content-type"].to_str().unwrap(),
        "text/plain; charset=utf-8"
    );
    let n: usize = r.headers()["x-truecut-warnings"]
        .to_str()
        .unwrap()
        .parse()
        .unwrap();
    let warnings = json_answer["warnings"].as_array().unwrap();
    assert_eq!(n, warnings.len());
    assert!(n > 0);
    let text = r.text().await.unwrap();
    assert!(text.is_ascii(), "controls read ASCII: {text}");
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], "%");
    assert!(lines[1].starts_with("O2041"));
    assert!(lines[2].starts_with("(TRUECUT"), "{}", lines[2]);
    let comments = lines
        .iter()
        .filter(|l| l.starts_with("(TRUECUT") || l.starts_with("(line"))
        .count();
    assert!(comments > n / 2, "warnings as comments: {comments} of {n}");
    // The text form parses and, without the comment lines, is the JSON form's program.
    parse_with(&text, &read_options(c)).unwrap();
    let mut text_lines: Vec<usize> =
        serde_json::from_value(json_answer["source_lines"].clone()).unwrap();
    text_lines.splice(2..2, std::iter::repeat_n(0, n + 1));
    assert_valid(
        &app,
        "fanuc_finish_text_plain",
        c.text,
        &read_options(c),
        true,
        false,
        &text,
        &text_lines,
    )
    .await;
    let stripped: Vec<&str> = lines[..2].iter().chain(&lines[3 + n..]).copied().collect();
    assert_eq!(
        stripped.join("\n") + "\n",
        json_answer["gcode"].as_str().unwrap()
    );

    // Points form: JSON and CSV against predict.
    let pts = vec![
        [300.0, 200.0, 250.0],
        [650.0, 420.0, 120.0],
        [900.0, 10.0, 10.0],
    ];
    let e = predict(&app, &pts).await;
    let r = app.post_json(POINTS, &json!({"points": pts})).await;
    assert_eq!(r.status(), 200);
    let b: Value = r.json().await.unwrap();
    let got: Vec<[f64; 3]> = serde_json::from_value(b["points"].clone()).unwrap();
    for i in 0..3 {
        assert!(dist(got[i], sub(pts[i], e[i])) < 1e-12);
    }
    assert_eq!(b["out_of_box"], json!([false, false, true]));
    let csv = "x_mm,y_mm,z_mm\n300,200,250\n650,420,120\n900,10,10\n";
    let r = app.post_raw(POINTS, "text/csv", csv).await;
    assert_eq!(r.status(), 200);
    assert!(
        r.headers()["content-type"]
            .to_str()
            .unwrap()
            .starts_with("text/csv")
    );
    let text = r.text().await.unwrap();
    let mut rows = text.lines();
    assert_eq!(rows.next(), Some("x_mm,y_mm,z_mm"));
    for (i, row) in rows.enumerate() {
        let v: Vec<f64> = row.split(',').map(|x| x.parse().unwrap()).collect();
        assert!(dist([v[0], v[1], v[2]], sub(pts[i], e[i])) < 1e-6, "{row}");
    }
    let r = app.post_raw(POINTS, "text/csv", "x_mm,y_mm\n1,2\n").await;
    assert_problem(r, 400, &["z"]).await;
    let r = app.post_raw(POINTS, "application/xml", "<p/>").await;
    assert_problem(r, 415, &["text/csv"]).await;
}
on_both_backends!(text_plain_and_points);

async fn refusals(app: TestApp) {
    let g = json!({"gcode": "G0 X1 Y1 Z1"});
    let r = app
        .post_json("/v1/machines/nope/compensated-program", &g)
        .await;
    assert_problem(r, 404, &["nope"]).await;
    let r = app.put_json("/v1/machines/m", &machine_xyz()).await;
    assert!(r.status().is_success());
    // No map: volumetric asked → 409; nothing asked → 400.
    let r = app
        .post_json(PROGRAM, &json!({"gcode": "G0 X1", "volumetric": true}))
        .await;
    assert_problem(r, 409, &["volumetric-map"]).await;
    let r = app.post_json(PROGRAM, &g).await;
    assert_problem(r, 400, &["nothing to do"]).await;
    let r = app
        .post_json(POINTS, &json!({"points": [[1.0, 2.0, 3.0]]}))
        .await;
    assert_problem(r, 409, &["volumetric-map"]).await;
    machine_with_map(&app).await;
    let r = app
        .post_json(PROGRAM, &json!({"gcode": "G0 X1", "volumetric": false}))
        .await;
    assert_problem(r, 400, &["nothing to do"]).await;
    // A dwell is kept as written (its dialect's unit), never refused or added.
    let r = app
        .post_json(
            PROGRAM,
            &json!({"gcode": "G1 X5 F600\nG4 P1\nG1 X10", "contour": true, "volumetric": false}),
        )
        .await;
    assert_eq!(r.status(), 200);
    let body: Value = r.json().await.unwrap();
    let dwells: Vec<&str> = body["gcode"]
        .as_str()
        .unwrap()
        .lines()
        .filter(|l| l.contains("G4"))
        .collect();
    assert_eq!(dwells, ["G4 P1"]);
    // The band is checked.
    for bad in [0.0, 2.0] {
        let r = app
            .post_json(
                PROGRAM,
                &json!({"gcode": "G1 X5 F600", "contour": true, "band_mm": bad}),
            )
            .await;
        assert_problem(r, 400, &["band_mm"]).await;
    }
    for tol in [1e-6, 0.2] {
        let r = app
            .post_json(PROGRAM, &json!({"gcode": "G0 X1", "tolerance_mm": tol}))
            .await;
        assert_problem(r, 400, &["tolerance_mm"]).await;
    }
    let r = app.post_json(PROGRAM, &json!({"gcode": "  \n"})).await;
    assert_problem(r, 400, &["gcode is empty"]).await;
    let r = app
        .post_json(PROGRAM, &json!({"gcode": "G0 X1", "tolerence_mm": 0.01}))
        .await;
    assert_problem(r, 400, &["tolerence_mm"]).await;
    let r = app
        .post_json(
            PROGRAM,
            &json!({"gcode": "G0 X1 Y1 Z300\nG1 X10 F100 M8", "strict": true}),
        )
        .await;
    assert_problem(r, 422, &["line 2", "M8"]).await;
    let r = app
        .post_json(PROGRAM, &json!({"gcode": "G0 X1\nG12.1"}))
        .await;
    assert_problem(r, 422, &["line 2", "G12.1"]).await;
    // Tool diameters are checked, then left to the controller's G41/G42 (a warning says so).
    let g41 = "G0 X-10 Y0 Z300\nG41 D1 G1 X0 F600\nX10\nG40 X20";
    let r = app
        .post_json(
            PROGRAM,
            &json!({"gcode": g41, "tool_diameters": {"1": 6.0}}),
        )
        .await;
    assert_eq!(r.status(), 200);
    let b: Value = r.json().await.unwrap();
    assert!(
        b["warnings"]
            .to_string()
            .contains("tool_diameters: not used here"),
        "{b}"
    );
    let r = app
        .post_json(
            PROGRAM,
            &json!({"gcode": g41, "tool_diameters": {"one": 6.0}}),
        )
        .await;
    assert_problem(r, 400, &["tool_diameters.one"]).await;
    let r = app
        .post_json(POINTS, &json!({"points": [[1.0, 2.0]]}))
        .await;
    assert_eq!(r.status(), 400);
}
on_both_backends!(refusals);

/// Machine `m`: the demo cascade with `kv` on X, Y, Z (PUT through the API); its definition.
async fn cascade_machine(app: &TestApp, kv: f64) -> Value {
    let cascade = json!({"kv": kv, "kff": 0.6, "kp_v": 400.0, "ti_v": 0.01, "tc": 0.0005});
    let def = json!({"name": "cascade", "kinematics": "xyz",
        "axes": {"X": cascade, "Y": cascade, "Z": cascade}});
    let r = app.put_json("/v1/machines/m", &def).await;
    assert!(r.status().is_success());
    def
}

/// The JSON answer (200) of `original` through the contour pre-compensation on machine `m`.
async fn contour_answer(app: &TestApp, original: &str) -> Value {
    let r = app
        .post_json(PROGRAM, &json!({"gcode": original, "contour": true}))
        .await;
    assert_eq!(r.status(), 200);
    r.json().await.unwrap()
}

/// [`assert_valid`] on a contour answer `body` (JSON) of `original`, read with the default
/// options.
async fn assert_contour_valid(app: &TestApp, tag: &str, original: &str, body: &Value) {
    let text = body["gcode"].as_str().unwrap();
    let lines: Vec<usize> = serde_json::from_value(body["source_lines"].clone()).unwrap();
    let opts = ReadOptions::default();
    assert_valid(app, tag, original, &opts, false, true, text, &lines).await;
}

/// Issue 39 item 1's invariants of a contour answer, on its text: no F above the largest F
/// of the original, no G4 that the original lacks, no Z word on a line whose source line
/// names no Z, no more blocks than 3x the original's + 50, and every G2/G3 of the original
/// still an arc (its source line's output lines carry no G1).
fn assert_contour_invariants(original: &str, body: &Value) {
    assert_contour_invariants_except(original, body, &|_| false);
}

/// [`assert_contour_invariants`] where a G1 on the output line `l` (1-based) of an arc's
/// source line is allowed when `g1_ok(l)` (a backlash take-up move).
pub(crate) fn assert_contour_invariants_except(
    original: &str,
    body: &Value,
    g1_ok: &dyn Fn(usize) -> bool,
) {
    let text = body["gcode"].as_str().unwrap();
    let src: Vec<usize> = serde_json::from_value(body["source_lines"].clone()).unwrap();
    let orig: Vec<&str> = original.lines().collect();
    let code = |l: &str| l.split('(').next().unwrap().to_uppercase();
    let words = |l: &str, c: char| -> Vec<f64> {
        code(l)
            .split_whitespace()
            .filter_map(|w| w.strip_prefix(c).and_then(|v| v.parse().ok()))
            .collect()
    };
    let max_f = orig
        .iter()
        .flat_map(|l| words(l, 'F'))
        .fold(0.0f64, f64::max);
    let out: Vec<&str> = text.lines().collect();
    assert_eq!(out.len(), src.len());
    assert!(
        out.len() <= 3 * orig.len() + 50,
        "{} blocks from {}",
        out.len(),
        orig.len()
    );
    let dwells = |ls: &[&str]| ls.iter().filter(|l| words(l, 'G').contains(&4.0)).count();
    assert_eq!(dwells(&out), dwells(&orig), "dwells added:\n{text}");
    for (i, (l, s)) in out.iter().zip(&src).enumerate() {
        for f in words(l, 'F') {
            assert!(f <= max_f + 1e-9, "F{f} above the original's F{max_f}: {l}");
        }
        let o = orig[s - 1];
        if !code(o).contains('Z') {
            assert!(
                !code(l).contains('Z'),
                "a Z word on a 2-D cut: {l} (from {o})"
            );
        }
        let g = words(o, 'G');
        if (g.contains(&2.0) || g.contains(&3.0)) && !g1_ok(i + 1) {
            assert!(
                !words(l, 'G').contains(&1.0),
                "an arc became a line: {l} (from {o})"
            );
        }
    }
}

/// What the returned program does on machine `def` against the *original* path, both read,
/// interpolated and simulated here with `truecut::motion` directly (padded at rest to the
/// same length): RMS and max over the periods of the motion core's contour error (the
/// distance to the original's commanded path), and the duration ratio.
struct Resimulated {
    rms0: f64,
    max0: f64,
    rms1: f64,
    max1: f64,
    duration: f64,
}

impl Resimulated {
    fn summary(&self) -> String {
        format!(
            "RMS {:.2} -> {:.2} um ({:.3}x), max {:.2} -> {:.2} um ({:.3}x), duration {:.3}x",
            self.rms0 * 1e3,
            self.rms1 * 1e3,
            self.rms1 / self.rms0,
            self.max0 * 1e3,
            self.max1 * 1e3,
            self.max1 / self.max0,
            self.duration
        )
    }
}

fn resimulate(def: &Value, original: &str, answer: &str) -> Resimulated {
    use truecut::motion::{
        DEFAULT_PERIOD_S, Machine, contour_error, interpolate, simulate_machine,
    };
    let m = Machine::from_json(def).unwrap();
    let read = |t: &str| parse_with(t, &ReadOptions::default()).unwrap().0;
    let cmd0 = interpolate(&read(original), &m, DEFAULT_PERIOD_S, 2_000_000).unwrap();
    let cmd1 = interpolate(&read(answer), &m, DEFAULT_PERIOD_S, 2_000_000).unwrap();
    // Both held at their ends for 0.3 s, so the servo settles.
    let n = cmd0.t.len().max(cmd1.t.len()) + 300;
    let pad = |c: &truecut::motion::Trajectory| {
        let mut p = c.clone();
        for col in &mut p.axes {
            let last = *col.last().unwrap();
            col.resize(n, last);
        }
        p.t = (0..n).map(|i| i as f64 * DEFAULT_PERIOD_S).collect();
        p
    };
    let (p0, p1) = (pad(&cmd0), pad(&cmd1));
    let figures = |act: &[Vec<f64>]| {
        let r = contour_error(&m.kinematics, &p0.axes, act, &cmd0.corners);
        (r.rms, r.max)
    };
    let (rms0, max0) = figures(&simulate_machine(&m, &p0).unwrap());
    let (rms1, max1) = figures(&simulate_machine(&m, &p1).unwrap());
    Resimulated {
        rms0,
        max0,
        rms1,
        max1,
        duration: cmd1.t.len() as f64 / cmd0.t.len() as f64,
    }
}

/// A Fanuc-style circle program (R 25 mm at F 2000, tangent lead-in) through the contour
/// pre-compensation on the demo cascade (kv 30): the circle stays G3 arcs (three sub-arcs
/// of a corrected radius), the post's other lines pass through, no feed is raised, the
/// answer reads back (truecut and rs274), and the route's figures agree with an independent
/// simulation of the returned text.
async fn contour_precompensation(app: TestApp) {
    let def = cascade_machine(&app, 30.0).await;
    let original = "%\nO1001 (CIRCLE R25 F2000)\nN10 G21 G90 G17 G94\nN20 M3 S8000 (SPINDLE)\n\
                    N30 G1 X0 Y15. F2000\nN40 G3 X0 Y15. I-25. J0\nN50 G3 X0 Y15. I-25. J0\n\
                    N60 G1 Y30.\nN70 M5\nM30\n%\n";
    let body = contour_answer(&app, original).await;
    let text = body["gcode"].as_str().unwrap();
    for keep in [
        "%",
        "O1001 (CIRCLE R25 F2000)",
        "N20 M3 S8000 (SPINDLE)",
        "N70 M5",
        "M30",
    ] {
        assert!(text.lines().any(|l| l == keep), "{keep} lost:\n{text}");
    }
    assert!(text.contains("G3"), "the circle stays an arc:\n{text}");
    assert_contour_invariants(original, &body);
    assert_contour_valid(&app, "circle_contour", original, &body).await;
    let c = &body["contour"];
    let models = c["models"].as_array().unwrap();
    assert_eq!(models.len(), 6);
    assert_eq!(models[0]["model"], "nominal");
    let fig = resimulate(&def, original, text);
    println!(
        "contour pre-compensation, circle R25 F2000 kv30: {} (independent); route: RMS ratio \
         {:.3}, max ratio {:.3}, duration {:.3}, {} iterations; models: {}",
        fig.summary(),
        c["compensated_rms_distance_mm"].as_f64().unwrap()
            / c["original_rms_distance_mm"].as_f64().unwrap(),
        c["compensated_max_mm"].as_f64().unwrap() / c["original_max_mm"].as_f64().unwrap(),
        c["duration_ratio"].as_f64().unwrap(),
        c["iterations"],
        models
            .iter()
            .map(|m| format!(
                "{} {:.3}/{:.3}",
                m["model"].as_str().unwrap(),
                m["rms_ratio"].as_f64().unwrap(),
                m["max_ratio"].as_f64().unwrap()
            ))
            .collect::<Vec<_>>()
            .join(", ")
    );
    assert!(fig.rms1 <= 0.5 * fig.rms0, "{}", fig.summary());
    assert!(fig.duration <= 1.15, "{}", fig.summary());
    for m in models {
        assert!(m["rms_ratio"].as_f64().unwrap() < 1.0, "{m}");
        assert!(m["duration_ratio"].as_f64().unwrap() <= 1.2, "{m}");
    }
}
on_both_backends!(contour_precompensation);

/// A circle, a 140° and a 90° corner at F 2000 on a kv 40 cascade, and a G41 pocket finish
/// (its G41 and G40 moves and the move after each kept whole): the invariants hold, the
/// answers read back, and the corners' error falls on the nominal machine and on the
/// worst model of the set.
async fn contour_precompensation_at_corners(app: TestApp) {
    let def = cascade_machine(&app, 40.0).await;
    let original = "%\nO1002 (CIRCLE AND CORNERS F2000)\nN10 G21 G90 G17 G94\n\
                    N20 G1 X0 Y15. F2000\nN30 G3 X0 Y15. I-10. J0\nN40 G1 Y30.\n\
                    N50 G1 X-9.6418 Y41.4907\nN60 G1 X-21.1325 Y31.8489\nM30\n%\n";
    let body = contour_answer(&app, original).await;
    assert_contour_invariants(original, &body);
    assert_contour_valid(&app, "circle_corners", original, &body).await;
    let fig = resimulate(&def, original, body["gcode"].as_str().unwrap());
    let models = body["contour"]["models"].as_array().unwrap();
    let worst = |k: &str| {
        models
            .iter()
            .map(|m| m[k].as_f64().unwrap())
            .fold(0.0, f64::max)
    };
    println!(
        "contour pre-compensation, circle + 140° + 90° F2000 kv40: {}; worst of the set: RMS \
         {:.3}x, max {:.3}x",
        fig.summary(),
        worst("rms_ratio"),
        worst("max_ratio")
    );
    assert!(
        fig.rms1 <= 0.6 * fig.rms0 && fig.max1 <= 0.9 * fig.max0,
        "{}",
        fig.summary()
    );
    assert!(worst("rms_ratio") < 1.0, "{models:?}");

    let pocket = "%\nO1003 (POCKET G41)\nN10 G21 G90 G17 G94\nN20 G41 D1 G1 X10. F2000\n\
                  N30 Y10.\nN40 X0\nN50 Y0\nN60 X5.\nN70 G40 G1 X5. Y5.\nM30\n%\n";
    let body = contour_answer(&app, pocket).await;
    assert_contour_invariants(pocket, &body);
    assert_contour_valid(&app, "pocket_g41", pocket, &body).await;
    let text = body["gcode"].as_str().unwrap();
    for whole in ["N20 G41 D1 G1 X10. F2000", "N70 G40 G1 X5. Y5."] {
        assert!(
            text.lines().any(|l| l == whole),
            "{whole} not kept whole:\n{text}"
        );
    }
    let src: Vec<usize> = serde_json::from_value(body["source_lines"].clone()).unwrap();
    // Lines 4 (N20, G41), 5 (N30, the move after) and 9 (N70, G40) come back as one line each.
    for l in [4, 5, 9] {
        assert_eq!(
            src.iter().filter(|&&s| s == l).count(),
            1,
            "line {l}:\n{text}"
        );
    }
}
on_both_backends!(contour_precompensation_at_corners);
