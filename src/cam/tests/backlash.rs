//! Backlash corrected in a program ([`compensate_with_offsets`], issue 40 item 2): the
//! written program, run through a play operator of its own (the table moves only when the
//! motor pushes it, b/2 either side; in contact against each axis' first move), puts the
//! table on the programmed path: at every source line's end, and all along its arcs.

use super::*;
use crate::cam::paths::arc_point;
use crate::motion::program::Feed;

/// Play per axis in these tests, mm.
const PLAY: [f64; 3] = [0.02, 0.012, 0.0];

/// The written rounding (4 decimals of mm) on three axes, mm.
const ROUNDING: f64 = 1e-4;

/// Motor positions along the blocks of `text` (read with default options), `per_block`
/// samples each, with the source line of each sample; the first is the first block's start.
fn motor_path(text: &str, per_block: usize) -> Vec<([f64; 3], usize)> {
    let (prog, _) = parse_with(text, &ReadOptions::default()).unwrap();
    let mut out = vec![(prog.blocks[0].start.xyz, 0)];
    for b in &prog.blocks {
        for i in 1..=per_block {
            let t = i as f64 / per_block as f64;
            let p = match b.motion {
                Motion::Arc {
                    plane,
                    center,
                    sweep_rad,
                } => arc_point(b, plane, center, sweep_rad, t),
                _ => [0, 1, 2].map(|k| b.start.xyz[k] + t * (b.end.xyz[k] - b.start.xyz[k])),
            };
            out.push((p, b.line));
        }
    }
    out
}

/// The table under a play of `b` (mm per axis) driven by `motor`: in contact against each
/// axis' first motion, then moved only when the motor pushes it.
fn table_path(motor: &[([f64; 3], usize)], b: [f64; 3]) -> Vec<[f64; 3]> {
    let m0 = motor[0].0;
    let mut table = m0;
    for k in 0..3 {
        let first = motor
            .iter()
            .find(|(p, _)| (p[k] - m0[k]).abs() > 1e-9)
            .map_or(0.0, |(p, _)| (p[k] - m0[k]).signum());
        table[k] -= 0.5 * b[k] * first;
    }
    motor
        .iter()
        .map(|(m, _)| {
            for k in 0..3 {
                let h = 0.5 * b[k];
                if m[k] - table[k] > h {
                    table[k] = m[k] - h;
                } else if table[k] - m[k] > h {
                    table[k] = m[k] + h;
                }
            }
            table
        })
        .collect()
}

/// Runs `src` through the correction with [`PLAY`] and no field; returns the answer and the
/// table (per sample) with the answer's line of each sample.
fn corrected(src: &str) -> (Compensated, Vec<([f64; 3], usize)>) {
    let offsets = Offsets {
        backlash_mm: PLAY,
        drift_mm: Vec::new(),
    };
    let out = compensate_with_offsets(
        src,
        &ReadOptions::default(),
        &constant([0.0; 3]),
        1e-3,
        &offsets,
    )
    .unwrap();
    let motor = motor_path(&out.gcode, 400);
    let table = table_path(&motor, PLAY);
    (
        out.clone(),
        table.into_iter().zip(motor.iter().map(|m| m.1)).collect(),
    )
}

/// Straight moves that reverse X, then Y, then both: each source line's end is where the
/// table stands after it, and a take-up move is written before each reversal (and each
/// axis' first move).
#[test]
fn reversals_of_straight_moves_put_the_table_on_the_points() {
    let src = "G0 X5 Y5\nG1 X20 F1000\nG1 Y15\nG1 X10\nG1 Y8\nG1 X25 Y2\nM30\n";
    let (out, table) = corrected(src);
    let (orig, _) = parse_with(src, &ReadOptions::default()).unwrap();
    for b in orig.blocks.iter().filter(|b| b.feed != Feed::Rapid) {
        let last = table
            .iter()
            .rposition(|(_, l)| out.source_lines[l - 1] == b.line)
            .unwrap();
        let miss = dist(table[last].0, b.end.xyz);
        assert!(
            miss < ROUNDING,
            "line {}: table {:?}, programmed {:?}\n{}",
            b.line,
            table[last].0,
            b.end.xyz,
            out.gcode
        );
    }
    // take-ups where X reverses (lines 4 and 6) and Y (5); both first moved in the rapid
    assert_eq!(out.takeups.len(), 3, "{}\n{:?}", out.gcode, out.takeups);
    // each take-up moves the motor by the change of its offsets alone: at most the play
    let (written, _) = parse_with(&out.gcode, &ReadOptions::default()).unwrap();
    for &l in &out.takeups {
        let b = written.blocks.iter().find(|b| b.line == l).unwrap();
        let len = dist(b.start.xyz, b.end.xyz);
        assert!(
            len <= PLAY[0] + ROUNDING,
            "line {l}: {len} mm\n{}",
            out.gcode
        );
    }
    assert!(
        out.warnings.iter().any(|w| w.contains("take-up")),
        "{:?}",
        out.warnings
    );
    // without play the answer is the field's alone
    let same = compensate_with_offsets(
        src,
        &ReadOptions::default(),
        &constant([0.0; 3]),
        1e-3,
        &Offsets::default(),
    )
    .unwrap();
    let plain =
        compensate_program(src, &ReadOptions::default(), &constant([0.0; 3]), 1e-3).unwrap();
    assert_eq!(same, plain);
    assert!(same.takeups.is_empty());
}

/// Two full circles (every quadrant reverses X or Y): written as sub-arcs about shifted
/// centres with take-up moves between them, and the table runs on the programmed circle all
/// along (the quadrant glitches gone).
#[test]
fn a_circle_is_split_at_its_reversals_and_stays_on_the_circle() {
    let src = "G0 X10 Y0\nG1 X12 F2000\nG3 X12 Y0 I-12 J0\nG3 X12 Y0 I-12 J0\nM30\n";
    let (out, table) = corrected(src);
    let arcs = out.gcode.lines().filter(|l| l.contains("G3")).count();
    assert!(arcs >= 2, "{}", out.gcode);
    let mut worst: f64 = 0.0;
    for (p, l) in &table {
        if *l > 0 && out.source_lines[l - 1] >= 3 {
            worst = worst.max((p[0].hypot(p[1]) - 12.0).abs());
        }
    }
    println!(
        "circle R12 with play X {} Y {} mm: table within {:.3} µm of the circle, {} take-ups",
        PLAY[0],
        PLAY[1],
        worst * 1e3,
        out.takeups.len()
    );
    assert!(worst < ROUNDING, "{worst} mm off the circle\n{}", out.gcode);
    // each turn reverses X at 0° and 180° and Y at 90° and 270° (the first X reversal
    // where the circle starts after the +X lead-in)
    assert!(out.takeups.len() >= 8, "{:?}\n{}", out.takeups, out.gcode);
    // without the correction the table leaves the circle by about half the play
    let motor = motor_path(src, 400);
    let raw = table_path(&motor, PLAY);
    let off = raw
        .iter()
        .zip(&motor)
        .filter(|(_, m)| m.1 >= 3)
        .map(|(p, _)| (p[0].hypot(p[1]) - 12.0).abs())
        .fold(0.0, f64::max);
    assert!(off > 0.4 * PLAY[0], "{off}");
}

/// Thermal drift at each line's time: every point of a line is written −drift(line) from
/// its programmed place (arcs with their centres).
#[test]
fn each_line_is_written_against_its_drift() {
    let src = "G0 X5 Y5\nG1 X20 F1000\nG1 Y15\nG3 X10 Y25 I-10 J0\nM30\n";
    let drift = |l: usize| [1e-3 * l as f64, -2e-3 * l as f64, 0.0];
    let offsets = Offsets {
        backlash_mm: [0.0; 3],
        drift_mm: (1..=5).map(drift).collect(),
    };
    let opts = ReadOptions::default();
    let out = compensate_with_offsets(src, &opts, &constant([0.0; 3]), 1e-3, &offsets).unwrap();
    let (orig, _) = parse_with(src, &opts).unwrap();
    let (written, _) = parse_with(&out.gcode, &opts).unwrap();
    for b in &orig.blocks {
        let w = written
            .blocks
            .iter()
            .rev()
            .find(|w| out.source_lines[w.line - 1] == b.line)
            .unwrap();
        let want = sub(b.end.xyz, drift(b.line));
        assert!(
            dist(w.end.xyz, want) < ROUNDING,
            "line {}\n{}",
            b.line,
            out.gcode
        );
        if let (Motion::Arc { center: c0, .. }, Motion::Arc { center: c1, .. }) =
            (b.motion, w.motion)
        {
            // the sub-arc's centre keeps start and end radii equal across the drift's change
            // from the line before (√5 µm here)
            let step = dist(drift(b.line), drift(b.line - 1));
            assert!(
                dist(c1, sub(c0, drift(b.line))) < step + ROUNDING,
                "{}",
                out.gcode
            );
        }
    }
    assert!(out.takeups.is_empty());
}
