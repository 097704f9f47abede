//! The files as their readers read them: LinuxCNC's joint compensation file through a
//! re-statement of LinuxCNC's own loader (`usrmotLoadComp`: a line at a time, three numbers
//! or stop; type 1 keeps the trims, type 0 turns positions into `nominal − value`), and the
//! CSV through its header.

use super::*;
use crate::metrology::comp_model::Cyclic;
use crate::metrology::comp_table::TableSource;
use crate::metrology::comp_table::tests::build_first;
use crate::metrology::iso230_2::evaluate_table;
use crate::metrology::iso230_2::tests::hand_table;

/// LinuxCNC's loader restated (`usrmotLoadComp`, `src/emc/motion/usrmotintf.cc`): reads lines
/// until one does not start with three numbers (`sscanf("%lf %lf %lf") != 3`); returns the
/// entries as (nominal, forward trim, reverse trim).
fn reference_linuxcnc_load(text: &str, comp_file_type: u8) -> Vec<(f64, f64, f64)> {
    let mut out = Vec::new();
    for line in text.lines() {
        let nums: Vec<f64> = line
            .split_whitespace()
            .take(3)
            .map_while(|t| t.parse::<f64>().ok())
            .collect();
        let [nom, fwd, rev] = nums[..] else { break };
        out.push(if comp_file_type == 0 {
            (nom, nom - fwd, nom - rev)
        } else {
            (nom, fwd, rev)
        });
    }
    out
}

fn hand_mean_table() -> CompTable {
    build_first(&evaluate_table(&hand_table()).unwrap(), TableSource::Mean).unwrap()
}

#[test]
fn the_reference_loader_stops_at_the_first_line_that_is_not_a_triplet() {
    // Why the notes go last: a comment on top loads nothing.
    assert!(reference_linuxcnc_load("# header\n0 0.001 -0.001\n", 1).is_empty());
    assert_eq!(
        reference_linuxcnc_load("0 0.001 -0.001\n10 0 0\n\n5 1 1\n", 1).len(),
        2
    );
    // LinuxCNC's own type-0 example turns into trims nominal − actual.
    let t0 = reference_linuxcnc_load("-1.000 -1.005 -0.995\n0.000 0.002 -0.003\n", 0);
    assert!((t0[0].1 - 0.005).abs() < 1e-12 && (t0[1].2 - 0.003).abs() < 1e-12);
}

#[test]
fn linuxcnc_loads_every_position_of_the_file_with_the_sign_of_a_correction() {
    let table = hand_mean_table();
    let text = linuxcnc_file(&table, &["run r1 of axis X".into()]).unwrap();
    let loaded = reference_linuxcnc_load(&text, 1);
    assert_eq!(loaded.len(), table.len(), "{text}");
    for (k, (nom, fwd, rev)) in loaded.iter().enumerate() {
        assert!((nom - table.positions_mm[k]).abs() < 1e-9);
        assert!((fwd - table.forward_mm[k]).abs() <= 5e-7);
        assert!((rev - table.backward_mm[k]).abs() <= 5e-7);
    }
    // Target 100 mm: x̄↑ = +4 µm (stops past the target going up), 2 µm more than at the
    // reference (0 mm, x̄↑ = +2 µm) → trim −0.002 mm, which LinuxCNC adds to the command;
    // x̄↓ = 0 → +0.002. The reference itself: 0 forward (no "-0").
    assert!(
        text.lines().any(|l| l == "100.000000 -0.002000 0.002000"),
        "{text}"
    );
    assert!(text.starts_with("0.000000 0.000000 0.003000\n"), "{text}");
    // The notes: after a blank line, provenance first, every one a comment.
    let notes: Vec<&str> = text.lines().skip(table.len()).collect();
    assert_eq!(notes[0], "");
    assert_eq!(notes[1], "# run r1 of axis X");
    assert!(notes[1..].iter().all(|l| l.starts_with("# ")));
    assert!(
        text.contains("COMP_FILE_TYPE = 1")
            && text.contains("sign: correction = what the controller adds")
            && text.contains("# reference: corrections are relative to 0 mm approached forward")
    );
}

#[test]
fn linuxcnc_refuses_more_than_256_positions_naming_the_spacing() {
    let axis = evaluate_table(&hand_table()).unwrap();
    let source = |spacing_mm| TableSource::Model {
        cyclic: Cyclic::Off,
        spacing_mm: Some(spacing_mm),
    };
    let long = build_first(&axis, source(1.0)).unwrap();
    assert_eq!(long.len(), 401);
    let e = linuxcnc_file(&long, &[]).unwrap_err();
    assert!(
        e.to_string().contains("spacing_mm of at least 1.569"),
        "{e}"
    );
    // 400 mm / 1.569 mm = 254.9 steps: 256 positions, loaded whole.
    let fits = build_first(&axis, source(1.569)).unwrap();
    assert_eq!(fits.len(), 256);
    let text = linuxcnc_file(&fits, &[]).unwrap();
    assert_eq!(reference_linuxcnc_load(&text, 1).len(), 256);
    assert!(text.contains("mode model: scale"), "{text}");
}

#[test]
fn linuxcnc_refuses_positions_equal_to_a_nanometre() {
    let mut table = hand_mean_table();
    table.positions_mm[1] = table.positions_mm[0] + 4e-7;
    let e = linuxcnc_file(&table, &[]).unwrap_err();
    assert!(e.to_string().contains("strictly increasing"), "{e}");
}

#[test]
fn csv_has_the_sign_the_header_and_a_row_per_position() {
    let table = hand_mean_table();
    let text = csv_file(&table, &["machine m1 axis X".into()]);
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("# machine m1 axis X"));
    let mut rest = lines.skip_while(|l| l.starts_with('#'));
    assert_eq!(
        rest.next(),
        Some("position_mm,forward_correction_mm,backward_correction_mm")
    );
    let rows: Vec<Vec<f64>> = rest
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), table.len());
    for (k, r) in rows.iter().enumerate() {
        assert_eq!(r.len(), 3);
        assert!((r[0] - table.positions_mm[k]).abs() < 1e-9);
        assert!((r[1] - table.forward_mm[k]).abs() <= 5e-7);
        assert!((r[2] - table.backward_mm[k]).abs() <= 5e-7);
    }
    assert!(
        text.contains("# sign: correction = what the controller adds to the commanded position")
    );
}

#[test]
fn fixed_writes_zero_without_a_sign() {
    assert_eq!(fixed(-1e-9), "0.000000");
    assert_eq!(fixed(-0.0), "0.000000");
    assert_eq!(fixed(-0.0000012), "-0.000001");
    assert_eq!(fixed(12.5), "12.500000");
}
