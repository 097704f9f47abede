//! A compensated program is still a valid program (issue 24, item 3): every program in
//! `tests/data/programs` (the real posts and the held-out contours of `heldout/`) and one
//! program per canned cycle truecut models (G73, G74, G81–G89, each with G99 and G98 holes
//! between feed moves and rapids) is compensated as the `compensated-program` route does it
//! — volumetric, contour, and both — and every answer goes through [`crate::valid::check`]:
//! re-read by truecut's reader and by rs274, both must parse it, and every programmed point
//! p is hit at p − e(p) within 1 µm. The answers are computed once ([`answers`]) and shared
//! with `crate::invariants`.
//!
//! The map is fitted (kinematic model) on a synthetic machine's measured grid, the contour
//! machine is the cascade of the route's contour test; the programs run under G54 and tool
//! lengths that put them inside the map's box.

use std::sync::OnceLock;

use serde_json::json;
use truecut::cam::{
    Compensated, DEFAULT_BAND_MM, DEFAULT_MAX_DURATION_RATIO, DEFAULT_TOLERANCE_MM, MAX_ITERATIONS,
    PredistortOptions, Predistorted, compensate_program, contour_program, volumetric_and_contour,
};
use truecut::motion::{DEFAULT_PERIOD_S, Machine, ReadOptions};
use truecut::volumetric::{FitOptions, ModelKind, ShapeFamily, SyntheticMachine, fit};

use crate::valid::{Asked, TOLERANCE_MM, check};

/// Every canned cycle the reader models.
const CYCLES: [u32; 11] = [73, 74, 81, 82, 83, 84, 85, 86, 87, 88, 89];

/// A program around two G99 holes and one G98 hole of cycle `code` (Fanuc words; P in ms).
fn cycle_program(code: u32) -> String {
    let spindle = if code == 74 { "M4" } else { "M3" };
    let (words, feed) = match code {
        73 | 83 => ("Z-12. R2. Q3.", "F200."),
        74 | 84 => ("Z-12. R2.", "F1200."),
        82 | 86 | 88 | 89 => ("Z-12. R2. P500", "F200."),
        // Back boring: R below the part, fed up to Z (always back to the initial level).
        87 => ("Z-2. R-12. Q1.", "F200."),
        _ => ("Z-12. R2.", "F200."),
    };
    let first = if code == 87 { "G98" } else { "G99" };
    format!(
        "%\nO3{code:03} (CANNED CYCLE G{code})\nN10 G21 G90 G17 G94 G40 G49 G80\nN20 T1 M6\n\
         N30 G0 G54 X0. Y0. S1200 {spindle}\nN40 G43 H1 Z30.\nN50 Z5.\nN60 G1 Z-2. F600.\n\
         N70 X40. Y10. F1500.\nN80 G2 X60. Y30. R20.\nN90 G0 Z20.\n\
         N100 {first} G{code} X20. Y20. {words} {feed}\nN110 X40.\nN120 G98 Y40.\nN130 G80\n\
         N140 G0 Z30.\nN150 X80. Y0.\nN160 G1 Z-2. F600.\nN170 X80. Y40. F1200.\n\
         N180 G0 Z50.\nN190 M30\n%\n"
    )
}

/// The held-out programs' folder under `tests/data/programs` (issue 39 item 3's held-out
/// set: short contours, run here like the posts).
const HELDOUT: &str = "heldout";

/// A program: name, text, G54 offset (mm) and tool (H number, length mm).
type Case = (String, String, [f64; 3], (u32, f64));

/// The programs with the G54 offset and tool length that place them in the map's box.
fn programs() -> Vec<Case> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/programs");
    let nc = |dir: &std::path::Path| {
        let mut files: Vec<_> = std::fs::read_dir(dir)
            .unwrap()
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|x| x == "nc"))
            .collect();
        files.sort();
        assert!(!files.is_empty(), "no programs in {}", dir.display());
        files
    };
    let mut files = nc(&dir);
    files.extend(nc(&dir.join(HELDOUT)));
    let mut out: Vec<_> = files
        .iter()
        .map(|p| {
            let stem = p.file_stem().unwrap().to_string_lossy().to_string();
            let name = if p.parent().is_some_and(|d| d.ends_with(HELDOUT)) {
                format!("{HELDOUT}/{stem}")
            } else {
                stem
            };
            let text = std::fs::read_to_string(p).unwrap();
            let (g54, tool) = match name.as_str() {
                "haas_drill" => ([200.0, 100.0, 150.0], (3, 100.0)),
                "siemens_iso_turnmill" => ([300.0, 200.0, 150.0], (5, 120.0)),
                _ => ([300.0, 150.0, 100.0], (1, 150.0)),
            };
            (name, text, g54, tool)
        })
        .collect();
    for code in CYCLES {
        out.push((
            format!("cycle_g{code}"),
            cycle_program(code),
            [300.0, 150.0, 100.0],
            (1, 150.0),
        ));
    }
    out
}

/// The map and contour machine every case is compensated with (built once).
pub struct Setup {
    /// The kinematic map fitted on the synthetic machine's grid.
    pub map: truecut::volumetric::VolumetricMap,
    /// The contour machine: the route test's cascade on X, Y, Z.
    pub machine: Machine,
}

/// The setup (module docs), built once for every test of the binary.
pub fn setup() -> &'static Setup {
    static SETUP: OnceLock<Setup> = OnceLock::new();
    SETUP.get_or_init(|| {
        let synthetic = SyntheticMachine::new(8, ShapeFamily::TrendAndWaviness);
        let data = synthetic.measure_grid([6, 5, 4], 3);
        let map = fit(
            &data,
            &FitOptions {
                model: ModelKind::Kinematic,
                tool_offset_mm: synthetic.tool_offset_mm,
                ..FitOptions::default()
            },
        )
        .unwrap();
        let cascade = json!({"kv": 30.0, "kff": 0.6, "kp_v": 400.0, "ti_v": 0.01, "tc": 0.0005});
        let machine = Machine::from_json(&json!({"name": "demo cascade", "kinematics": "xyz",
            "axes": {"X": cascade, "Y": cascade, "Z": cascade}}))
        .unwrap();
        Setup { map, machine }
    })
}

/// One (program, mode) case and the service's answer.
pub struct Answered {
    /// Program name (file stem, `heldout/` for the held-out folder, `cycle_g<code>`).
    pub name: String,
    /// The original program.
    pub text: String,
    /// The reading options (G54 offset and tool length placing it in the map's box).
    pub options: ReadOptions,
    /// "volumetric", "contour" or "both".
    pub mode: &'static str,
    /// The answer and, with contour, its figures; Err: the service's refusal.
    pub answer: Result<(Compensated, Option<Predistorted>), String>,
}

/// The modes of the `compensated-program` route.
pub const MODES: [&str; 3] = ["volumetric", "contour", "both"];

/// Every (program, mode) answer, compensated once on two threads for every test of the
/// binary (`valid` here, the invariants of issue 39 in `crate::invariants`).
pub fn answers() -> &'static [Answered] {
    static ANSWERS: OnceLock<Vec<Answered>> = OnceLock::new();
    ANSWERS.get_or_init(|| {
        let s = setup();
        let cases: Vec<(String, String, ReadOptions, &'static str)> = programs()
            .into_iter()
            .flat_map(|(name, text, g54, (tool, length))| {
                let mut options = ReadOptions::default();
                options.work_offsets_mm[0] = Some(g54);
                options.tool_lengths_mm.insert(tool, length);
                MODES.map(|mode| (name.clone(), text.clone(), options.clone(), mode))
            })
            .collect();
        crate::on_two_threads(cases.len(), |i| {
            let (name, text, options, mode) = &cases[i];
            Answered {
                name: name.clone(),
                text: text.clone(),
                options: options.clone(),
                mode,
                answer: compensate(text, options, mode, &s.map, &s.machine),
            }
        })
    })
}

/// `text` (read with `options`) compensated in `mode` as the route does it.
fn compensate(
    text: &str,
    options: &ReadOptions,
    mode: &str,
    map: &truecut::volumetric::VolumetricMap,
    machine: &Machine,
) -> Result<(Compensated, Option<Predistorted>), String> {
    let answer = match mode {
        "volumetric" => {
            compensate_program(text, options, map, DEFAULT_TOLERANCE_MM).map(|c| (c, None))
        }
        "contour" => {
            contour_program(text, options, machine, &contour_options()).map(|(c, p)| (c, Some(p)))
        }
        _ => volumetric_and_contour(
            text,
            options,
            map,
            DEFAULT_TOLERANCE_MM,
            machine,
            &contour_options(),
        )
        .map(|(c, p)| (c, Some(p))),
    };
    answer.map_err(|e| e.to_string())
}

#[test]
fn compensated_programs_are_valid_programs() {
    let rs = crate::oracle();
    let s = setup();
    let dir = tempfile::tempdir().unwrap();
    // Every (program, mode) answer checked on two threads (each case is independent;
    // rs274's files are named by the case), reported in order.
    let all = answers();
    let outcomes = crate::on_two_threads(all.len(), |i| {
        one_case(&all[i], &s.map, rs.as_deref(), dir.path())
    });
    let (mut answers, mut by_rs274, mut points) = (0, 0, 0);
    let (mut worst, mut worst_rs): ((f64, String), (f64, String)) = Default::default();
    let mut skipped = Vec::new();
    let mut failures = Vec::new();
    for outcome in outcomes {
        let o = match outcome {
            Ok(o) => o,
            Err(failure) => {
                if !failure.refused {
                    answers += 1;
                }
                failures.push(failure.text);
                continue;
            }
        };
        answers += 1;
        points += o.points;
        if o.worst_truecut_mm >= worst.0 {
            worst = (o.worst_truecut_mm, o.tag.clone());
        }
        match &o.worst_rs274_mm {
            Ok(d) => {
                by_rs274 += 1;
                if *d >= worst_rs.0 {
                    worst_rs = (*d, o.tag.clone());
                }
            }
            Err(why) => skipped.push(format!("{}: {why}", o.tag)),
        }
        if !o.unnamed.is_empty() {
            failures.push(format!(
                "{}: warnings naming no line: {:?}",
                o.tag, o.unnamed
            ));
        }
        println!("{}", o.line);
    }
    println!(
        "{answers} answers ({} programs x 3 modes) re-read by truecut, {by_rs274} by rs274; {points} \
         programmed points; worst |q - (p - e(p))| truecut {:.3} µm ({}), rs274 {:.3} µm ({}) \
         before its printout's rounding; goal {:.1} µm. Not read by rs274:\n  {}",
        answers / 3,
        worst.0 * 1e3,
        worst.1,
        worst_rs.0 * 1e3,
        worst_rs.1,
        TOLERANCE_MM * 1e3,
        skipped.join("\n  ")
    );
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
    assert!(answers >= 3 * (5 + CYCLES.len()));
}

/// What one checked answer gave (see [`one_case`]).
struct Outcome {
    tag: String,
    points: usize,
    worst_truecut_mm: f64,
    worst_rs274_mm: Result<f64, String>,
    /// Warnings that name no source line.
    unnamed: Vec<String>,
    /// The case's report line.
    line: String,
}

/// A case that failed: refused by the service, or its answer failed the check.
struct Failure {
    refused: bool,
    text: String,
}

/// The route's contour options (default period, duration limit and band).
pub fn contour_options() -> PredistortOptions {
    PredistortOptions {
        period_s: DEFAULT_PERIOD_S,
        max_iterations: MAX_ITERATIONS,
        max_duration_ratio: DEFAULT_MAX_DURATION_RATIO,
        band_mm: DEFAULT_BAND_MM,
    }
}

/// The answer of case `case` checked by [`check`] against the map `map` (rs274's files in
/// `dir`).
fn one_case(
    case: &Answered,
    map: &truecut::volumetric::VolumetricMap,
    rs: Option<&std::path::Path>,
    dir: &std::path::Path,
) -> Result<Outcome, Failure> {
    let (name, text, options, mode) = (&case.name, &case.text, &case.options, case.mode);
    let e = |p: [f64; 3]| map.error_at(p);
    let tag = format!("{}_{mode}", name.replace('/', "_"));
    let (answer, figures) = match &case.answer {
        Ok((a, p)) => (
            a,
            p.as_ref().map(|p| {
                format!(
                    "; cutting lines' contour error {:.2} -> {:.2} µm RMS, {:.1} -> {:.1} µm max",
                    p.original.rms_mm * 1e3,
                    p.compensated.rms_mm * 1e3,
                    p.original.max_mm * 1e3,
                    p.compensated.max_mm * 1e3
                )
            }),
        ),
        Err(err) => {
            return Err(Failure {
                refused: true,
                text: format!("{tag}: the service refused it: {err}"),
            });
        }
    };
    let asked = Asked {
        error: (mode != "contour").then_some(&e as &dyn Fn([f64; 3]) -> [f64; 3]),
        contour: mode != "volumetric",
    };
    let c = check(
        &tag,
        text,
        options,
        &asked,
        &answer.gcode,
        &answer.source_lines,
        rs,
        dir,
    )
    .map_err(|err| Failure {
        refused: false,
        text: format!("{err}\n--- answer:\n{}", answer.gcode),
    })?;
    let rs_text = match &c.worst_rs274_mm {
        Ok(d) => format!("{:.3} µm", d * 1e3),
        Err(_) => "not read".to_string(),
    };
    let unnamed: Vec<String> = answer
        .warnings
        .iter()
        .filter(|w| !w.starts_with("line") && !w.starts_with("tolerance_mm"))
        .filter(|w| !w.starts_with("stopped after") && !w.starts_with("and "))
        .cloned()
        .collect();
    let line = format!(
        "{tag}: {} lines -> {}; {} points; worst |q - (p - e(p))| truecut {:.3} µm, rs274 \
         {rs_text}{}{}",
        text.lines().count(),
        answer.blocks,
        c.points,
        c.worst_truecut_mm * 1e3,
        if mode == "volumetric" {
            String::new()
        } else {
            format!(
                "; feed-move ends pre-distorted by up to {:.1} µm",
                c.feed_ends_mm * 1e3
            )
        },
        figures.unwrap_or_default()
    );
    Ok(Outcome {
        tag,
        points: c.points,
        worst_truecut_mm: c.worst_truecut_mm,
        worst_rs274_mm: c.worst_rs274_mm,
        unnamed,
        line,
    })
}
