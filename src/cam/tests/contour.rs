//! Tests of the contour pass of the cam core (issues 24 and 39): rapids stay G0, cycles stay
//! cycles, arcs stay arcs, feeds are never raised, and the notes name source lines, with the
//! volumetric pass before it too.

use super::*;

/// A cascade machine for the contour pass.
fn cascade() -> crate::motion::Machine {
    let c = serde_json::json!({"kv": 30.0, "kff": 0.6, "kp_v": 400.0, "ti_v": 0.01, "tc": 0.0005});
    crate::motion::Machine::from_json(&serde_json::json!({"name": "cascade",
        "kinematics": "xyz", "axes": {"X": c, "Y": c, "Z": c}}))
    .unwrap()
}

fn popts() -> PredistortOptions {
    PredistortOptions {
        period_s: 0.001,
        max_iterations: 10,
        max_duration_ratio: DEFAULT_MAX_DURATION_RATIO,
        band_mm: crate::cam::DEFAULT_BAND_MM,
    }
}

const CYCLE_AND_CONTOUR: &str = "N1 G21 G90 G17 G94\nN2 G0 X0 Y0 Z10 S1000 M3\nN3 G1 Z-1 F600\n\
N4 G1 X30 F1500\nN5 G3 X50 Y20 R20\nN6 G0 Z10\nN7 G99 G82 X20 Y20 Z-8 R2 P200 F150\nN8 X30\n\
N9 G80\nN10 G0 X60 Y0\nN11 G1 Z-1 F600\nN12 X60 Y30 F1500\nN13 G0 Z20\nN14 M30\n";

#[test]
fn contour_keeps_rapids_and_cycles() {
    let opts = ReadOptions::default();
    let (out, p) = contour_program(CYCLE_AND_CONTOUR, &opts, &cascade(), &popts()).unwrap();
    let lines: Vec<&str> = out.gcode.lines().collect();
    let of = |src: usize| -> Vec<&str> {
        (0..lines.len())
            .filter(|&i| out.source_lines[i] == src)
            .map(|i| lines[i])
            .collect()
    };
    // Cycles copied, one motion code a line, R and F kept.
    assert_eq!(of(7), ["N7 G99 G82 X20 Y20 Z-8 R2 P200 F150"]);
    assert_eq!(of(8), ["N8 X30"]);
    // Rapids stay G0 (a modal rapid after the cycle's G80 gets its G0 back when needed).
    for l in [2, 6, 13] {
        let w = of(l);
        assert_eq!(w.len(), 1, "line {l}: {w:?}");
        assert!(
            w[0].contains("G0 ") && !w[0].contains("G1"),
            "line {l}: {w:?}"
        );
    }
    // The arc stays arcs (at most three), its feed never above F1500.
    let arc = of(5);
    assert!((1..=3).contains(&arc.len()), "{arc:?}");
    assert!(
        arc[0].contains("G3") && arc.iter().all(|l| !l.contains("G1")),
        "{arc:?}"
    );
    for l in out.gcode.lines() {
        for f in l.split_whitespace().filter_map(|w| w.strip_prefix('F')) {
            assert!(f.parse::<f64>().unwrap() <= 1500.0, "{l}");
        }
    }
    // It reads back; rapids are rapids, the holes at the programmed feed, points exact.
    let (a, _) = parse_with(CYCLE_AND_CONTOUR, &opts).unwrap();
    let (b, _) = parse_with(&out.gcode, &opts).unwrap();
    for line in [2, 6, 7, 8, 10, 13] {
        let want: Vec<&Block> = a.blocks.iter().filter(|k| k.line == line).collect();
        let got: Vec<&Block> = b
            .blocks
            .iter()
            .filter(|k| out.source_lines[k.line - 1] == line)
            .collect();
        let (w, g) = (want.last().unwrap(), got.last().unwrap());
        assert!(dist(w.end.xyz, g.end.xyz) < 1e-9, "line {line}");
        if (7..=8).contains(&line) {
            assert_eq!(want.len(), got.len(), "line {line}");
            for (w, g) in want.iter().zip(&got) {
                assert_eq!((w.feed, w.motion), (g.feed, g.motion), "line {line}");
                assert!(dist(w.end.xyz, g.end.xyz) < 1e-9, "line {line}");
            }
        } else {
            assert!(
                got.iter()
                    .all(|k| k.feed == crate::motion::gcode::Feed::Rapid)
            );
        }
    }
    // Notes name the lines; the figures are those of the program as written, over the lines
    // that cut: keeping the rapids G0 must not make the cutting worse than the original.
    assert!(
        out.warnings
            .iter()
            .any(|w| w.starts_with("lines 2, 6, 10, 13: rapids")),
        "{:?}",
        out.warnings
    );
    assert!(
        out.warnings
            .iter()
            .any(|w| w.starts_with("lines 7, 8: canned cycles")),
        "{:?}",
        out.warnings
    );
    println!(
        "cycle and contour program: cutting lines' contour error original {:.2} µm RMS / {:.1} \
         µm max, returned program {:.2} / {:.1}",
        p.original.rms_mm * 1e3,
        p.original.max_mm * 1e3,
        p.compensated.rms_mm * 1e3,
        p.compensated.max_mm * 1e3
    );
    assert!(
        p.compensated.rms_mm <= 1.05 * p.original.rms_mm,
        "{:?} vs {:?}",
        p.compensated,
        p.original
    );
}

#[test]
fn volumetric_and_contour_name_source_lines() {
    let opts = ReadOptions::default();
    let (out, _) = volumetric_and_contour(
        CYCLE_AND_CONTOUR,
        &opts,
        &curved(),
        0.001,
        &cascade(),
        &popts(),
    )
    .unwrap();
    let n = CYCLE_AND_CONTOUR.lines().count();
    assert!(out.source_lines.iter().all(|&l| (1..=n).contains(&l)));
    // Every note names a source line (but the one on the iteration count).
    for w in &out.warnings {
        let named = w.strip_prefix("lines ").or(w.strip_prefix("line "));
        let first = named.and_then(|r| r.split(|c: char| !c.is_ascii_digit()).next()?.parse().ok());
        assert!(
            first.is_some_and(|l: usize| (1..=n).contains(&l)) || w.starts_with("stopped after"),
            "{w}"
        );
    }
    assert!(
        out.warnings
            .iter()
            .any(|w| w.starts_with("lines 7, 8: canned cycles")),
        "{:?}",
        out.warnings
    );
    let lines: Vec<&str> = out.gcode.lines().collect();
    let hole = (0..lines.len())
        .find(|&i| out.source_lines[i] == 7)
        .unwrap();
    assert!(
        lines[hole].starts_with("N7 G99 G82 X")
            && lines[hole].contains(" R")
            && lines[hole].contains("F150"),
        "{}",
        lines[hole]
    );
    assert!(!lines[hole].contains("G1"));
}

/// A corner whose level has an axis the program never placed (here Y, until line 3) cannot
/// be moved: the written program could not say where on Y (the machine may be anywhere on
/// it), so the optimiser only slows it, and what is written is what was judged.
#[test]
fn a_corner_on_an_unplaced_axis_is_only_slowed() {
    let text = "G90 G17 G94\nG1 X2 F2000\nG1 Y2\nG1 X4\nG1 Y4\nG1 X6\n";
    let (out, p) = contour_program(text, &ReadOptions::default(), &cascade(), &popts()).unwrap();
    assert!(
        !out.warnings
            .iter()
            .any(|w| w.contains("judging the written")),
        "{:?}",
        out.warnings
    );
    // Line 2's pieces stay on Y = 0 (no Y word can be written there).
    for piece in p.lines.get(&2).into_iter().flatten() {
        let Piece::Line { end, .. } = *piece else {
            panic!("an arc on a line")
        };
        assert_eq!(end[1], 0.0, "line 2 moved on Y: {piece:?}");
    }
    // The corners after Y is placed (lines 3-5) may move.
    assert!(p.lines.len() > 1, "{:?}", p.notes);
}
