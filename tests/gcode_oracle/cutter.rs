//! Cutter radius compensation (G41/G42) against LinuxCNC with real tool diameters (issue 39,
//! item 4): rs274 runs with a tool table whose diameters are the tools' (in inches, as it
//! reads them standalone: `rs274` docs) and truecut with the same `tool_diameters`; their
//! tool-centre paths are compared move by move (`crate::canon`, [`Match::Compensated`]:
//! kinds, end points, arc centres and turns, feed rates, within 1e-6 mm plus the printout's
//! rounding, 0.05 µm in mm and 1.27 µm in inch).
//!
//! Programs: [`CONTOURS`] generated contour programs (`contours`) and
//! `tests/data/programs/pocket_finish.nc` (G41 D1, a 6 mm cutter). Where LinuxCNC refuses a
//! program (the tool does not fit a corner), truecut must refuse it too, with a sentence
//! (counted by reason); where LinuxCNC follows it, truecut must follow it the same way.
//! The real posts of `tests/data/programs` are compared whole as well.

use std::path::Path;

use crate::canon::{Counts, Match};
use crate::{compare_moves, contours, counts_line, on_two_threads, oracle, oracle_options, rs274};

/// Generated contour programs compared.
const CONTOURS: u64 = 800;
/// First seed of the contour programs (any fixed value; reported seeds reproduce a case).
const FIRST_SEED: u64 = 39_000;

/// How one program came out.
enum Outcome {
    /// Both read it and agree: the counts, and how many of truecut's moves came from lines
    /// under G41/G42.
    Agree(Counts, usize),
    /// Both refuse it: truecut's sentence.
    BothRefuse(String),
    Disagree(String),
}

/// Lines (1-based) read while G41/G42 is in force (from the G41/G42 line to the G40 line).
fn compensated_lines(text: &str) -> Vec<bool> {
    let mut on = false;
    let mut out = vec![false];
    for raw in text.lines() {
        let up = raw.to_ascii_uppercase();
        if up.contains("G41") || up.contains("G42") {
            on = true;
        }
        out.push(on);
        if up.contains("G40") {
            on = false;
        }
    }
    out
}

/// Runs one program with tool diameters `diameters` (mm by tool number) on both readers.
fn one(rs: &Path, dir: &Path, name: &str, text: &str, diameters: &[(u32, f64)]) -> Outcome {
    let file = dir.join(format!("{name}.ngc"));
    std::fs::write(&file, text).unwrap();
    let table = dir.join(format!("{name}.tbl"));
    let by_tool = |t: u32| {
        diameters
            .iter()
            .find(|(n, _)| *n == t)
            .map_or(0.0, |(_, d)| *d)
    };
    std::fs::write(&table, rs274::tool_table(&by_tool)).unwrap();
    let options = oracle_options(diameters);
    let truecut = truecut::motion::gcode::parse_with(text, &options);
    match (rs274::run_with_tools(rs, &file, Some(&table)), truecut) {
        (Ok(moves), Ok((program, _))) => {
            let on = compensated_lines(text);
            let inside = crate::canon::from_blocks(&program.blocks)
                .iter()
                .filter(|c| on.get(c.line).copied().unwrap_or(false))
                .count();
            match compare_moves(&moves, text, &options, Match::Compensated) {
                Ok(c) => Outcome::Agree(c, inside),
                Err(e) => Outcome::Disagree(e),
            }
        }
        (Err(_), Err(e)) => Outcome::BothRefuse(e.to_string()),
        (Err(r), Ok(_)) => Outcome::Disagree(format!("rs274 refuses it ({r}), truecut reads it")),
        (Ok(_), Err(t)) => Outcome::Disagree(format!("truecut refuses it ({t}), rs274 reads it")),
    }
}

#[test]
fn compensated_contours_agree_with_linuxcnc() {
    let Some(rs) = oracle() else { return };
    let dir = tempfile::tempdir().unwrap();
    let pocket = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/programs/pocket_finish.nc"),
    )
    .unwrap();
    let pocket = crate::valid::numbered(&pocket);
    // The pocket first: LinuxCNC follows it with its 6 mm cutter.
    match one(&rs, dir.path(), "pocket_finish", &pocket, &[(1, 6.0)]) {
        Outcome::Agree(c, inside) => println!(
            "pocket_finish.nc (G41 D1, 6 mm): agrees with rs274: {}; {inside} moves under G41",
            counts_line(&c)
        ),
        Outcome::BothRefuse(e) => panic!("pocket_finish.nc: both refuse it: {e}"),
        Outcome::Disagree(e) => panic!("pocket_finish.nc: {e}"),
    }
    if let Some(seed) = std::env::var("TRUECUT_ORACLE_CONTOUR")
        .ok()
        .and_then(|s| s.parse().ok())
    {
        // Both readings of one program, to look at a disagreement.
        let g = contours::program(seed);
        let (file, table) = (dir.path().join("one.ngc"), dir.path().join("one.tbl"));
        std::fs::write(&file, &g.text).unwrap();
        std::fs::write(&table, rs274::tool_table(&|_| g.diameter_mm)).unwrap();
        let options = oracle_options(&[(1, g.diameter_mm)]);
        println!("{}tool {} mm", g.text, g.diameter_mm);
        let moves = rs274::run_with_tools(&rs, &file, Some(&table));
        let read = truecut::motion::gcode::parse_with(&g.text, &options);
        let (Ok(moves), Ok((p, _))) = (&moves, &read) else {
            println!("rs274 {:?}\ntruecut {:?}", moves.as_ref().err(), read.err());
            return;
        };
        let want = crate::canon::from_oracle(moves, &crate::canon::cycle_lines(&g.text));
        let got = crate::canon::from_blocks(&p.blocks);
        for i in 0..want.len().max(got.len()) {
            println!(
                "{i}\n  rs274   {:?}\n  truecut {:?}",
                want.get(i),
                got.get(i)
            );
        }
        return;
    }
    let results = on_two_threads(CONTOURS as usize, |i| {
        let g = contours::program(FIRST_SEED + i as u64);
        let name = format!("c{}", g.seed);
        let r = one(&rs, dir.path(), &name, &g.text, &[(1, g.diameter_mm)]);
        (g, r)
    });
    let (mut total, mut inside, mut agree) = (Counts::default(), 0, 0);
    let (mut refused, mut failures) = (Vec::new(), Vec::new());
    for (g, r) in &results {
        match r {
            Outcome::Agree(c, n) => {
                agree += 1;
                total += *c;
                inside += n;
            }
            Outcome::BothRefuse(e) => refused.push(format!("seed {}: {e}", g.seed)),
            Outcome::Disagree(e) => failures.push(format!(
                "seed {} (tool {} mm): {e}\n{}",
                g.seed, g.diameter_mm, g.text
            )),
        }
    }
    // truecut's refusals by reason (the sentence without its line and numbers).
    let mut reasons = std::collections::BTreeMap::new();
    for r in &refused {
        let why = r.split("cutter compensation: ").nth(1).unwrap_or(r);
        let why: String = why
            .chars()
            .take_while(|c| *c != '(' && !c.is_ascii_digit())
            .collect();
        *reasons.entry(why.trim().to_string()).or_insert(0) += 1;
    }
    println!(
        "compensated contours: {} programs; {agree} agree with rs274: {}; {inside} of those moves \
         from lines under G41/G42; {} refused by both, truecut's reasons: {reasons:?}; {} disagree",
        results.len(),
        counts_line(&total),
        refused.len(),
        failures.len()
    );
    let heads: Vec<&str> = failures
        .iter()
        .take(40)
        .map(|f| f.lines().next().unwrap_or(""))
        .collect();
    assert!(
        failures.is_empty(),
        "{} of {} contour programs disagree:\n{}\nfirst:\n{}",
        failures.len(),
        results.len(),
        heads.join("\n"),
        failures[0]
    );
    assert!(
        agree * 4 >= results.len() * 3,
        "only {agree} of {} contour programs were read by both: the generator makes too many \
         the tool cannot follow",
        results.len()
    );
}
