//! The checks of [`super`] can fail: answers broken by hand, one invariant each, are held to
//! the same checks and each must be caught by its rule (a contour answer, so that e(p) = 0
//! and each break is the only change).

use std::path::Path;

use truecut::cam::Compensated;
use truecut::motion::ReadOptions;

use super::Rule;
use super::check::check_case;
use crate::compensated::{Answered, setup};

/// `text` with line `line` (1-based) replaced by `with` (each from source line `line`), and
/// the source line of every line.
fn mutate(text: &str, line: usize, with: &[String]) -> Broken {
    let (mut out, mut src) = (String::new(), Vec::new());
    for (i, raw) in text.lines().enumerate() {
        if i + 1 == line {
            for w in with {
                out += w;
                out.push('\n');
                src.push(line);
            }
        } else {
            out += raw;
            out.push('\n');
            src.push(i + 1);
        }
    }
    (out, src)
}

/// A broken answer: its text and the source line of each of its lines.
type Broken = (String, Vec<usize>);

fn program(name: &str) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("tests/data/programs/{name}"));
    std::fs::read_to_string(path).unwrap()
}

#[test]
fn each_invariant_check_catches_its_break() {
    let Some(rs) = crate::oracle() else { return };
    let dir = tempfile::tempdir().unwrap();
    let table = crate::posts::post_tool_table(dir.path(), "tools.tbl");
    let (pocket, corners) = (program("pocket_finish.nc"), program("corners_finish.nc"));
    let s = |v: &[&str]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>();
    // The circle N60 of corners_finish (centre (-10, 15), R10, G3 from (0, 15)) as chords.
    let chords: Vec<String> = (1..=8)
        .map(|k| {
            let a = k as f64 * std::f64::consts::FRAC_PI_4;
            let (x, y) = (-10.0 + 10.0 * a.cos(), 15.0 + 10.0 * a.sin());
            let head = if k == 1 { "N60 G1 " } else { "" };
            let tail = if k == 1 { " F2000." } else { "" };
            format!("{head}X{x:.4} Y{y:.4}{tail}")
        })
        .collect();
    // N70 G1 Y30. of corners_finish (line 10, from Y15) cut into 200 pieces (not under
    // G41, where rs274 would refuse the pieces before the budget is counted).
    let pieces: Vec<String> = (1..=200)
        .map(|k| {
            let y = 15.0 + 15.0 * k as f64 / 200.0;
            if k == 1 {
                format!("N70 G1 Y{y:.4}")
            } else {
                format!("Y{y:.4}")
            }
        })
        .collect();
    let breaks: Vec<(&str, &String, Rule, Broken)> = vec![
        (
            "the G41 move split",
            &pocket,
            Rule::Cutter,
            mutate(&pocket, 9, &s(&["N60 G41 D1 X20. F1500.", "X30."])),
        ),
        (
            "a feed raised",
            &pocket,
            Rule::Feed,
            mutate(&pocket, 10, &s(&["N70 Y20. F1600."])),
        ),
        (
            "a dwell added",
            &pocket,
            Rule::Dwell,
            mutate(&pocket, 10, &s(&["N70 Y20.", "G4 P0.5"])),
        ),
        (
            "the floor cut by 2 µm",
            &pocket,
            Rule::Floor,
            mutate(&pocket, 8, &s(&["N50 G1 Z-3.002 F300."])),
        ),
        (
            "a rapid gains a word",
            &pocket,
            Rule::Words,
            mutate(&pocket, 16, &s(&["N130 G0 X15. Z25."])),
        ),
        (
            "an inserted line numbered",
            &pocket,
            Rule::Words,
            mutate(&pocket, 11, &s(&["N80 X10.", "N85 X0."])),
        ),
        (
            "an arc chorded",
            &corners,
            Rule::Arc,
            mutate(&corners, 9, &chords),
        ),
        (
            "a move cut into 200",
            &corners,
            Rule::Budget,
            mutate(&corners, 10, &pieces),
        ),
    ];
    let mut options = ReadOptions::default();
    options.work_offsets_mm[0] = Some([300.0, 150.0, 100.0]);
    options.tool_lengths_mm.insert(1, 150.0);
    let mut missed = Vec::new();
    for (i, (what, original, rule, (gcode, source_lines))) in breaks.into_iter().enumerate() {
        let a = Answered {
            name: format!("mutant{i}"),
            text: original.clone(),
            options: options.clone(),
            mode: "contour",
            answer: Err("broken by hand".into()),
        };
        let c = Compensated {
            blocks: source_lines.len(),
            gcode,
            warnings: Vec::new(),
            max_shift_mm: 0.0,
            source_lines,
            takeups: Vec::new(),
        };
        let r = check_case(&a, &c, None, None, setup(), &rs, dir.path(), &table)
            .unwrap_or_else(|e| panic!("{what}: {e}"));
        let caught: Vec<&String> = r
            .violations
            .iter()
            .filter(|(k, _)| *k == rule)
            .map(|(_, v)| v)
            .collect();
        println!("{what}: caught by {rule:?}: {caught:?}");
        if caught.is_empty() {
            missed.push(format!("{what} ({rule:?}): {:?}", r.violations));
        }
    }
    assert!(missed.is_empty(), "not caught:\n{}", missed.join("\n"));
}
