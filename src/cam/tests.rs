//! Tests of the cam core: re-emission keeps every non-motion line byte for byte, every
//! written point is p − e(p) of its source point (the oracle: the reader run on the answer),
//! split moves stay within the tolerance of the compensated path (dense sampling), and the
//! safety rules (no word for an axis not yet placed, G28 without home copied).

use super::*;
use crate::motion::gcode::{Block, Motion, ReadOptions, parse_with, word_spans};
use crate::numeric::vec3::{dist, sub};

/// e(p) = c + B p + q (x², 0, 0): constant, linear or quadratic in x.
struct Field {
    c: [f64; 3],
    b: [[f64; 3]; 3],
    q: f64,
    max: [f64; 3],
}

impl ErrorField for Field {
    fn error_at(&self, p: [f64; 3]) -> [f64; 3] {
        let mut e = self.c;
        for (i, ei) in e.iter_mut().enumerate() {
            *ei += (0..3).map(|j| self.b[i][j] * p[j]).sum::<f64>();
        }
        e[0] += self.q * p[0] * p[0];
        e
    }
    fn contains(&self, p: [f64; 3]) -> bool {
        (0..3).all(|k| p[k] >= -1000.0 && p[k] <= self.max[k])
    }
}

fn constant(c: [f64; 3]) -> Field {
    Field {
        c,
        b: [[0.0; 3]; 3],
        q: 0.0,
        max: [1e6; 3],
    }
}

fn curved() -> Field {
    Field {
        c: [0.002, -0.001, 0.003],
        b: [[1e-5, 2e-5, 0.0], [0.0, -3e-5, 1e-5], [2e-5, 0.0, 1e-5]],
        q: 2e-6,
        max: [1e6; 3],
    }
}

fn comp(f: &dyn ErrorField, p: [f64; 3]) -> [f64; 3] {
    sub(p, f.error_at(p))
}

/// Checks the answer against the field: every source block's end p is written at
/// p − e(p) (within `tol`), and every written polyline stays within `tol` of the
/// compensated source path (sampled densely). Returns the largest end-point miss, mm.
fn check(src: &str, opts: &ReadOptions, f: &dyn ErrorField, out: &Compensated, tol: f64) -> f64 {
    let (a, _) = parse_with(src, opts).unwrap();
    let (b, _) = parse_with(&out.gcode, opts).unwrap();
    let mut worst: f64 = 0.0;
    let mut placed = [false; 3];
    for (idx, raw) in src.lines().enumerate() {
        let line = idx + 1;
        for s in word_spans(raw) {
            if let Some(k) = "XYZ".find(s.letter) {
                placed[k] |= !raw.contains("G4");
            }
        }
        let orig: Vec<&Block> = a.blocks.iter().filter(|k| k.line == line).collect();
        let got: Vec<&Block> = b
            .blocks
            .iter()
            .filter(|k| out.source_lines[k.line - 1] == line)
            .collect();
        let [o] = orig.as_slice() else { continue };
        if matches!(o.motion, Motion::Dwell { .. }) {
            continue;
        }
        let last = got.last().expect("a motion line is written");
        let want = comp(f, o.end.xyz);
        // A rapid gains no axis word: only the axes it names are compensated.
        let rapid = o.feed == crate::motion::gcode::Feed::Rapid;
        let named: Vec<bool> = (0..3)
            .map(|k| {
                word_spans(raw)
                    .iter()
                    .any(|s| "XYZ".find(s.letter) == Some(k))
            })
            .collect();
        let miss = (0..3)
            .filter(|&k| placed[k] && (!rapid || named[k]))
            .map(|k| (last.end.xyz[k] - want[k]).abs())
            .fold(0.0, f64::max);
        assert!(miss <= tol, "line {line}: {:?} vs {want:?}", last.end.xyz);
        worst = worst.max(miss);
        if o.feed == crate::motion::gcode::Feed::Rapid || placed.contains(&false) {
            continue;
        }
        // Dense samples of the compensated source path, each near the written path. A move
        // after a rapid starts where the rapid left the axes it did not name (uncompensated):
        // its path may lie that far off at its start, fading linearly to its end.
        let start_miss = dist(got[0].start.xyz, comp(f, o.start.xyz));
        for i in 0..=200 {
            let t = i as f64 / 200.0;
            let p = match o.motion {
                Motion::Arc {
                    plane,
                    center,
                    sweep_rad,
                } => arc_point(o, plane, center, sweep_rad, t),
                _ => {
                    let s = o.start.xyz;
                    [0, 1, 2].map(|k| s[k] + (o.end.xyz[k] - s[k]) * t)
                }
            };
            let c = comp(f, p);
            let d = got
                .iter()
                .map(|g| distance_to_block(g, c))
                .fold(f64::INFINITY, f64::min);
            let allowed = tol + (1.0 - t) * start_miss;
            assert!(
                d <= allowed,
                "line {line} t {t}: {d} mm from the written path (allowed {allowed})"
            );
        }
    }
    worst
}

fn distance_to_block(g: &Block, c: [f64; 3]) -> f64 {
    match g.motion {
        Motion::Arc {
            plane,
            center,
            sweep_rad,
        } => {
            // Coarse samples find the nearest part, a fine search around it the distance.
            let at = |t: f64| dist(arc_point(g, plane, center, sweep_rad, t), c);
            let n = 400;
            let k = (0..=n)
                .min_by(|&a, &b| at(a as f64 / n as f64).total_cmp(&at(b as f64 / n as f64)))
                .unwrap();
            let (lo, hi) = (
                (k as f64 - 1.0).max(0.0) / n as f64,
                (k as f64 + 1.0).min(n as f64) / n as f64,
            );
            (0..=2000)
                .map(|i| at(lo + (hi - lo) * i as f64 / 2000.0))
                .fold(f64::INFINITY, f64::min)
        }
        _ => {
            let (s, e) = (g.start.xyz, g.end.xyz);
            let d = sub(e, s);
            let l2: f64 = d.iter().map(|v| v * v).sum();
            let t = if l2 > 0.0 {
                ((0..3).map(|k| (c[k] - s[k]) * d[k]).sum::<f64>() / l2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            dist([0, 1, 2].map(|k| s[k] + d[k] * t), c)
        }
    }
}

const FANUC: &str = "%
O1001 (FINISH POCKET)
N10 G90 G17 G21 G40 G80
N20 T1 M6
N30 G0 G54 X10. Y10.
N40 G43 H1 Z50. S8000 M3
N50 M8
N60 G1 Z-2. F300.
N70 G1 X110. F1200.
N80 G3 X130. Y30. I0. J20.
N90 G2 X150. Y50. R20.
N100 X170. Y70. R20.
N110 G1 Y150.
N120 G91 X-20. Y5.
N130 X-40.
N140 G90 G1 X60. Y60.
N150 G0 Z50.
N160 M9
N170 G91 G28 Z0.
N180 G28 X0. Y0.
N190 M30
%
";

fn fanuc_options() -> ReadOptions {
    let mut o = ReadOptions::default();
    o.work_offsets_mm[0] = Some([200.0, 100.0, 50.0]);
    o.tool_lengths_mm.insert(1, 120.0);
    o
}

#[test]
fn constant_error_shifts_everything_and_keeps_arcs() {
    let f = constant([0.010, -0.020, 0.005]);
    let opts = fanuc_options();
    let out = compensate_program(FANUC, &opts, &f, 0.001).unwrap();
    let miss = check(FANUC, &opts, &f, &out, 0.001);
    println!(
        "constant field: largest end-point miss {:.3} µm",
        miss * 1e3
    );
    assert!(
        (out.max_shift_mm - 0.0229).abs() < 1e-3,
        "{}",
        out.max_shift_mm
    );
    // Same number of lines, arcs stay arcs (R form keeps R), non-motion lines identical.
    assert_eq!(out.blocks, FANUC.lines().count());
    for (a, b) in FANUC.lines().zip(out.gcode.lines()) {
        let moves = word_spans(a).iter().any(|s| "XYZ".contains(s.letter));
        if !moves || a.contains("G28") {
            assert_eq!(a, b);
        }
    }
    assert!(out.gcode.contains("N90 G2 X"), "{}", out.gcode);
    assert!(out.gcode.contains("R20."), "{}", out.gcode);
    assert!(
        out.gcode
            .contains("N80 G3 X129.9900 Y30.0200 I0.0000 J20.0000")
    );
    // G91 lines are increments of compensated positions: a constant shift keeps them.
    assert!(out.gcode.contains("N130 X-40.0000\n"), "{}", out.gcode);
    // The first rapid places X Y only: Z is not yet placed, so no Z word is added.
    assert!(
        out.gcode.contains("N30 G0 G54 X9.9900 Y10.0200\n"),
        "{}",
        out.gcode
    );
    assert!(
        out.warnings.iter().any(|w| w.contains("G28")),
        "{:?}",
        out.warnings
    );
}

#[test]
fn varying_error_splits_within_tolerance() {
    let f = curved();
    let opts = fanuc_options();
    for tol in [0.001, 0.0002] {
        let out = compensate_program(FANUC, &opts, &f, tol).unwrap();
        let miss = check(FANUC, &opts, &f, &out, tol);
        println!(
            "curved field, tolerance {tol} mm: {} blocks (source {}), largest end miss {:.3} µm",
            out.blocks,
            FANUC.lines().count(),
            miss * 1e3
        );
        assert!(out.blocks > FANUC.lines().count());
        assert!(out.warnings.iter().any(|w| w.contains("split into")));
    }
}

#[test]
fn inch_programs_stay_inch_and_all_planes() {
    let src = "G20 G90 G17\nG0 X1. Y1. Z1.\nG1 X2. F20.\nG18 G2 X3. Z2. I0.5 K0.5\n\
               G19 G3 Y2. Z3. J0.5 K0.5\nG17 G3 X2. Y3. Z2. I-0.5 J0.5\nM30\n";
    let f = curved();
    let opts = ReadOptions::default();
    let out = compensate_program(src, &opts, &f, 0.001).unwrap();
    let miss = check(src, &opts, &f, &out, 0.001);
    println!("inch program: largest end miss {:.3} µm", miss * 1e3);
    let second = out.gcode.lines().nth(1).unwrap();
    for w in second.split(' ').skip(1) {
        let decimals = w.split('.').nth(1).map_or(0, str::len);
        assert_eq!(decimals, 5, "inch words have 5 decimals: {second}");
    }
}

#[test]
fn compact_style_and_modal_arcs_after_a_split() {
    // An arc split into sub-arcs leaves its G2 in force: the next modal arc line needs no
    // motion word, and no G1 appears (arcs stay arcs).
    let src = "G0X0Y0Z0\nG1X100.F500\nG2X200.Y0I50.J0\nX300.Y0I50.J0\nM30\n";
    let f = curved();
    let opts = ReadOptions::default();
    let out = compensate_program(src, &opts, &f, 0.001).unwrap();
    check(src, &opts, &f, &out, 0.001);
    let lines: Vec<&str> = out.gcode.lines().collect();
    assert!(lines[0].starts_with("G0X"), "{}", out.gcode);
    assert!(!lines[2].contains(' '), "compact style kept: {}", lines[2]);
    let after = out.source_lines.iter().position(|&l| l == 4).unwrap();
    assert!(lines[after].starts_with('X'), "{}", out.gcode);
    assert_eq!(out.gcode.matches("G1").count(), 1, "{}", out.gcode);
    assert!(out.source_lines.iter().filter(|&&l| l == 3).count() > 1);
}

#[test]
fn canned_cycles_compensate_the_hole_bottom() {
    let src = "G90 G0 X0 Y0 Z20\nG99 G81 X10. Y10. Z-5. R2. F100\nX20.\nG98 G83 X30. Q2. Z-8. R1.\nG80\nM30\n";
    let f = curved();
    let opts = ReadOptions::default();
    let out = compensate_program(src, &opts, &f, 0.001).unwrap();
    let (a, _) = parse_with(src, &opts).unwrap();
    let (b, _) = parse_with(&out.gcode, &opts).unwrap();
    // The bottom of each hole: its deepest feed end (G83 feeds in pecks on the way down).
    let bottoms = |p: &crate::motion::gcode::Program| -> Vec<[f64; 3]> {
        let mut out: Vec<(usize, [f64; 3])> = Vec::new();
        for k in &p.blocks {
            if k.feed == crate::motion::gcode::Feed::Rapid {
                continue;
            }
            match out.last_mut() {
                Some((line, end)) if *line == k.line => {
                    if k.end.xyz[2] < end[2] {
                        *end = k.end.xyz;
                    }
                }
                _ => out.push((k.line, k.end.xyz)),
            }
        }
        out.into_iter().map(|(_, e)| e).collect()
    };
    let (ba, bb) = (bottoms(&a), bottoms(&b));
    assert_eq!(ba.len(), 3);
    assert_eq!(bb.len(), 3);
    for (p, q) in ba.iter().zip(&bb) {
        assert!(
            dist(*q, comp(&f, *p)) < 1e-4,
            "{q:?} vs {:?}\n{}",
            comp(&f, *p),
            out.gcode
        );
    }
    assert!(out.warnings.iter().any(|w| w.contains("pecks")));
    assert!(out.gcode.contains("G80\n"));
}

#[test]
fn unknown_positions_pass_through() {
    let src = "G90 G0 X10 Y10 Z10\nG28 Z0\nG0 X20\nG1 Z5 F100\nG1 X30\nM30\n";
    let f = constant([0.01, 0.0, 0.0]);
    let out = compensate_program(src, &ReadOptions::default(), &f, 0.001).unwrap();
    let lines: Vec<&str> = out.gcode.lines().collect();
    assert_eq!(lines[1], "G28 Z0");
    assert_eq!(lines[2], "G0 X20", "X at an unknown Z is copied");
    assert!(
        out.warnings.iter().any(|w| w.contains("lines 3")),
        "{:?}",
        out.warnings
    );
    assert_eq!(lines[4], "G1 X29.9900");
}

#[test]
fn lines_after_m30_and_crlf_are_kept() {
    let src = "G0 X1 Y1 Z1\r\nM30\r\n(after)\r\nG0 X5\r\n";
    let out = compensate_program(src, &ReadOptions::default(), &constant([0.1; 3]), 0.001).unwrap();
    assert_eq!(
        out.gcode,
        "G0 X0.9000 Y0.9000 Z0.9000\r\nM30\r\n(after)\r\nG0 X5\r\n"
    );
}

#[test]
fn tolerance_strict_and_points() {
    let f = constant([0.1, 0.0, 0.0]);
    let opts = ReadOptions::default();
    assert!(matches!(
        compensate_program("G0 X1", &opts, &f, 0.5),
        Err(Error::Tolerance { .. })
    ));
    let strict = ReadOptions {
        strict: true,
        ..ReadOptions::default()
    };
    let e = compensate_program("G0 X1 M8", &strict, &f, 0.001).unwrap_err();
    assert!(e.to_string().contains("M8"), "{e}");
    let p = compensate_points(&f, &[[1.0, 2.0, 3.0]]).unwrap();
    assert_eq!(p.points, vec![[0.9, 2.0, 3.0]]);
    let csv = points_to_csv(&p.points);
    assert_eq!(csv, "x_mm,y_mm,z_mm\n0.900000,2.000000,3.000000\n");
    assert_eq!(points_from_csv(&csv).unwrap(), p.points);
    assert!(points_from_csv("a,b\n1,2\n").is_err());
    assert!(compensate_points(&f, &[]).is_err());
}

#[test]
fn rewrite_keeps_everything_but_the_replaced_words() {
    let raw = "N70 G02 X1. Y2. I3. J4. F100 (cut)";
    let spans = word_spans(raw);
    let out = rewrite(
        raw,
        &spans,
        |s| "XYIJ".contains(s.letter),
        &["X5.0000".into(), "Y6.0000".into()],
        Some("G01"),
    );
    assert_eq!(out, "N70 G01 X5.0000 Y6.0000 F100 (cut)");
    let raw = "N5 X1Y2";
    let out = rewrite(
        raw,
        &word_spans(raw),
        |s| s.letter == 'X',
        &["X0.5".into()],
        Some("G1"),
    );
    assert_eq!(out, "N5 G1 X0.5Y2");
    assert_eq!(format_number(-0.00001, 4), "0.0000");
    assert_eq!(word_spans("O1234 (X1)").len(), 0);
    assert_eq!(word_spans("G1 X 1.5 (Y2) Z-3 ; A4").len(), 3);
}

#[test]
fn rapids_are_not_split() {
    let src = "G0 X0 Y0 Z0\nG0 X500 Y300\n";
    let out = compensate_program(src, &ReadOptions::default(), &curved(), 0.001).unwrap();
    assert_eq!(out.blocks, 2);
}

#[test]
fn out_of_box_points_are_named() {
    let f = Field {
        max: [50.0, 1e6, 1e6],
        ..constant([0.01, 0.0, 0.0])
    };
    let src = "G0 X10 Y0 Z0\nG0 X100\nG0 X20\n";
    let out = compensate_program(src, &ReadOptions::default(), &f, 0.001).unwrap();
    let w = out
        .warnings
        .iter()
        .find(|w| w.contains("outside the volumetric map's box"))
        .expect("warning");
    assert!(w.starts_with("lines 2:"), "{w}");
}

#[test]
fn inverse_time_splits_carry_their_own_feed() {
    // G93: the block takes 1/F min; split pieces keep the block's time in total.
    let src = "G0 X0 Y0 Z0\nG93 G1 X400. F2.\nG94\n";
    let f = curved();
    let out = compensate_program(src, &ReadOptions::default(), &f, 0.001).unwrap();
    let lines: Vec<&str> = out.gcode.lines().collect();
    assert!(lines.len() > 4, "{}", out.gcode);
    let minutes: f64 = lines[1..lines.len() - 1]
        .iter()
        .map(|l| {
            let f: f64 = l.split('F').nth(1).unwrap().parse().unwrap();
            1.0 / f
        })
        .sum();
    assert!(
        (minutes - 0.5).abs() < 1e-4,
        "{minutes} min for the split block"
    );
}

#[test]
fn incremental_cycles_are_copied() {
    let src = "G90 G0 X0 Y0 Z20\nG91 G81 X10. Y10. Z-5. R-18. F100\nX10.\nG80 G90\n";
    let out = compensate_program(src, &ReadOptions::default(), &curved(), 0.001).unwrap();
    let lines: Vec<&str> = out.gcode.lines().collect();
    assert_eq!(lines[1], "G91 G81 X10. Y10. Z-5. R-18. F100");
    assert_eq!(lines[2], "X10.");
    assert!(out.warnings.iter().any(|w| w.contains("G91")));
}

#[test]
fn every_cycle_code_is_a_hole() {
    // G74/G84/G86..G89 were once missed by the emitter's motion codes: their holes came back
    // uncompensated with "cannot place" warnings.
    let f = constant([0.01, -0.02, 0.005]);
    for (code, extra) in [
        (74, ""),
        (84, ""),
        (86, " P100"),
        (88, " P100"),
        (89, " P100"),
    ] {
        let src =
            format!("G90 G0 X0 Y0 Z20 M3\nG99 G{code} X10 Y10 Z-5 R2{extra} F100\nX20\nG80\nM30\n");
        let out = compensate_program(&src, &ReadOptions::default(), &f, 0.001).unwrap();
        let lines: Vec<&str> = out.gcode.lines().collect();
        assert_eq!(
            lines[1],
            format!("G99 G{code} X9.9900 Y10.0200 Z-5.0050 R1.9950{extra} F100"),
            "{out:?}"
        );
        assert_eq!(lines[2], "X19.9900", "{out:?}");
        assert!(
            !out.warnings.iter().any(|w| w.contains("cannot place")),
            "{:?}",
            out.warnings
        );
    }
}

mod backlash;
mod contour;
mod invariants;
