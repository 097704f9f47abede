//! LinuxCNC's example programs (`dpkg -L linuxcnc-uspace | grep ncfiles`) read by both
//! interpreters: every one that uses only what truecut models is compared move by move
//! (`crate::canon`), the others are listed with the reason. rs274 runs with a tool table of
//! real diameters ([`example_diameter_mm`]) and truecut with the same `tool_diameters`, so
//! the programs with G41/G42 are compared on their tool-centre paths; where truecut refuses
//! one with a sentence about cutter compensation (a plane it does not model, ...) it is
//! listed as refused.

use std::collections::BTreeSet;
use std::path::PathBuf;

use truecut::motion::gcode::word_spans;

use crate::canon::{Counts, Match};
use crate::{compare_moves, counts_line, on_two_threads, oracle, oracle_options, rs274};

/// Diameter of tool `t` in the examples' tool table, mm: 0.25 inch per tool number (tool 4
/// is the 1-inch cutter `comp-g1.ngc` asks for).
fn example_diameter_mm(t: u32) -> f64 {
    6.35 * t as f64
}

/// The examples use tools 0..=20 at most.
const EXAMPLE_TOOLS: u32 = 20;

/// LinuxCNC's example programs (`dpkg -L linuxcnc-uspace | grep ncfiles`).
const NCFILES: &str = "/usr/share/linuxcnc/ncfiles";

/// Why an example program is not compared, or None when it uses only what truecut models
/// in the frame rs274 prints (see the module docs for the dialect differences).
fn skip_reason(text: &str) -> Option<String> {
    if text.lines().count() > 99_999 {
        return Some("longer than rs274's 99,999 line numbers".into());
    }
    let mut codes = BTreeSet::new();
    for raw in text.lines() {
        let mut code = String::new();
        let mut depth = 0;
        for ch in raw.chars() {
            match ch {
                ';' if depth == 0 => break,
                '(' => depth += 1,
                ')' => depth -= 1,
                _ if depth == 0 => code.push(ch.to_ascii_uppercase()),
                _ => {}
            }
        }
        if code.contains('#') || code.contains('[') {
            return Some("parameters or expressions (#, [ ])".into());
        }
        if code.contains('@') || code.contains('^') {
            return Some("polar coordinates @ ^ (LinuxCNC only)".into());
        }
        let body = code.trim_start_matches(|c: char| c == '/' || c.is_whitespace());
        let body = body.trim_start_matches(|c: char| c == 'N' || c.is_ascii_digit() || c == ' ');
        if body.starts_with('O') {
            return Some("o-words (LinuxCNC subroutines and control flow)".into());
        }
        for w in word_spans(&code) {
            match w.letter {
                'G' => {
                    codes.insert((w.value * 10.0).round() as u32);
                }
                'M' if matches!(w.value as u32, 98 | 99) => {
                    return Some("subprogram calls (M98/M99)".into());
                }
                'U' | 'V' | 'W' => return Some("U/V/W axes".into()),
                'B' => return Some("B axis (truecut models X Y Z A C)".into()),
                _ => {}
            }
        }
    }
    let reasons: [(&[u32], &str); 10] = [
        (
            &[411, 421],
            "dynamic cutter compensation G41.1/G42.1 (the diameter in the D word)",
        ),
        (&[281, 301], "G28.1/G30.1 (storing the reference positions)"),
        (
            &[100, 520, 920, 921, 922, 923],
            "coordinate system setting G10/G52/G92",
        ),
        (
            &[870],
            "G87 back boring (LinuxCNC and Fanuc take different words)",
        ),
        (&[330, 331, 760], "spindle-synchronised motion G33/G76"),
        (&[50, 51, 52, 53], "splines and NURBS G5.x"),
        (&[70, 80], "lathe diameter/radius mode G7/G8"),
        (&[382, 383, 384, 385], "probing G38.x"),
        (
            &[950, 960, 970],
            "feed per revolution / constant surface speed G95/G96/G97",
        ),
        (&[431, 432], "dynamic tool length G43.1/G43.2"),
    ];
    for (set, why) in reasons {
        if set.iter().any(|g| codes.contains(g)) {
            return Some(why.to_string());
        }
    }
    None
}

/// `text` with every line numbered `N<line>` (an existing leading N number replaced) so
/// that rs274 names the source line of each move.
fn numbered(text: &str) -> String {
    let mut out = String::with_capacity(text.len() + text.len() / 4);
    for (i, raw) in text.lines().enumerate() {
        let t = raw.trim_start();
        if t.is_empty() || t.starts_with('%') {
            out += raw;
        } else {
            let (slash, rest) = match t.strip_prefix('/') {
                Some(r) => ("/", r.trim_start()),
                None => ("", t),
            };
            let rest = match rest.strip_prefix(['N', 'n']) {
                Some(r) if r.starts_with(|c: char| c.is_ascii_digit()) => {
                    r.trim_start_matches(|c: char| c.is_ascii_digit())
                }
                _ => rest,
            };
            out += &format!("{slash}N{} {}", i + 1, rest.trim_start());
        }
        out.push('\n');
    }
    out
}

#[test]
fn linuxcnc_example_programs_agree() {
    let Some(rs) = oracle() else { return };
    let mut files = Vec::new();
    let mut folders = vec![PathBuf::from(NCFILES)];
    while let Some(d) = folders.pop() {
        for e in std::fs::read_dir(&d).into_iter().flatten().flatten() {
            let p = e.path();
            if p.is_dir() {
                folders.push(p);
            } else {
                files.push(p);
            }
        }
    }
    files.retain(|p| {
        p.extension()
            .is_some_and(|x| x.eq_ignore_ascii_case("ngc") || x.eq_ignore_ascii_case("nc"))
    });
    files.sort();
    assert!(
        !files.is_empty(),
        "rs274 is installed but {NCFILES} has no programs"
    );
    let dir = tempfile::tempdir().unwrap();
    let table = dir.path().join("tools.tbl");
    std::fs::write(&table, rs274::tool_table(&example_diameter_mm)).unwrap();
    let diameters: Vec<(u32, f64)> = (0..=EXAMPLE_TOOLS)
        .map(|t| (t, example_diameter_mm(t)))
        .collect();
    let options = oracle_options(&diameters);
    let results = on_two_threads(files.len(), |i| {
        let name = files[i]
            .strip_prefix(NCFILES)
            .unwrap()
            .display()
            .to_string();
        let text = String::from_utf8_lossy(&std::fs::read(&files[i]).unwrap()).into_owned();
        if let Some(why) = skip_reason(&text) {
            return (name, Err(why));
        }
        let text = numbered(&text);
        let file = dir.path().join(format!("x{i}.ngc"));
        std::fs::write(&file, &text).unwrap();
        let cutter = word_spans_of(&text)
            .any(|(l, v)| l == 'G' && matches!((v * 10.0).round() as u32, 410 | 420));
        let how = if cutter {
            Match::Compensated
        } else {
            Match::AsPrinted
        };
        match rs274::run_with_tools(&rs, &file, Some(&table)) {
            Err(e) => (name, Err(format!("rs274 refuses it standalone: {e}"))),
            Ok(moves) => (
                name,
                Ok((cutter, compare_moves(&moves, &text, &options, how))),
            ),
        }
    });
    let (mut compared, mut skipped, mut failures) = (0, Vec::new(), Vec::new());
    let (mut names, mut refused) = (Vec::new(), Vec::new());
    let mut total = Counts::default();
    for (name, r) in results {
        match r {
            Err(why) => skipped.push(format!("  {name}: {why}")),
            Ok((cutter, Ok(c))) => {
                compared += 1;
                total += c;
                names.push(if cutter {
                    format!("{name} (G41/G42)")
                } else {
                    name
                });
            }
            // truecut may refuse what it does not model of cutter compensation, with a
            // sentence (`src/motion/gcode/cutter_reader.rs`).
            Ok((true, Err(e))) if e.starts_with("truecut refused it") && e.contains("cutter") => {
                refused.push(format!("  {name}: {e}"))
            }
            Ok((_, Err(e))) => failures.push(format!("{name}: {e}")),
        }
    }
    println!(
        "examples: {compared} compared with rs274 (rounded as it prints, four decimals): {}; {} \
         disagree; {}; refused by truecut with a sentence ({}):\n{}\n{} skipped:\n{}",
        names.join(", "),
        failures.len(),
        counts_line(&total),
        refused.len(),
        refused.join("\n"),
        skipped.len(),
        skipped.join("\n")
    );
    assert!(compared > 0, "no example program was compared");
    assert!(
        failures.is_empty(),
        "disagreements:\n{}",
        failures.join("\n")
    );
}

/// The (letter, value) words of every line of `text`.
fn word_spans_of(text: &str) -> impl Iterator<Item = (char, f64)> + '_ {
    text.lines()
        .flat_map(word_spans)
        .map(|w| (w.letter, w.value))
}
