//! The safety invariants of a volumetric answer (issue 39 item 1), on the answer as the
//! reader reads it back: arcs stay arcs, blocks only where the field needs them, moves that
//! carry G40/G41/G42 (and the move after) stay whole, feeds never rise and are written as
//! the source writes them, rapids gain no words, no dwell is added.

use super::*;
use crate::motion::gcode::Feed;

/// Most pieces [`need_reference`] cuts a block into.
const MAX_REFERENCE_PIECES: usize = 4000;

/// The fewest pieces of `block` along which e(p) of `f` is linear within `tol_mm` (slow
/// reference: pieces grow by 1/4000 of the block while 32 samples of each stay within
/// `tol_mm` of the chord of e between its ends).
fn need_reference(f: &dyn ErrorField, block: &Block, tol_mm: f64) -> usize {
    let at = |t: f64| match block.motion {
        Motion::Arc {
            plane,
            center,
            sweep_rad,
        } => arc_point(block, plane, center, sweep_rad, t),
        _ => {
            let (s, e) = (block.start.xyz, block.end.xyz);
            [0, 1, 2].map(|k| s[k] + (e[k] - s[k]) * t)
        }
    };
    let e = |t: f64| f.error_at(at(t));
    let linear = |t0: f64, t1: f64| {
        let (e0, e1) = (e(t0), e(t1));
        (1..32).all(|k| {
            let u = k as f64 / 32.0;
            let lin = [0, 1, 2].map(|i| e0[i] + (e1[i] - e0[i]) * u);
            dist(e(t0 + (t1 - t0) * u), lin) <= tol_mm
        })
    };
    let step = 1.0 / MAX_REFERENCE_PIECES as f64;
    let (mut pieces, mut t0) = (0, 0.0);
    while t0 < 1.0 - 1e-12 {
        let mut t1 = (t0 + step).min(1.0);
        while t1 < 1.0 && linear(t0, (t1 + step).min(1.0)) {
            t1 = (t1 + step).min(1.0);
        }
        pieces += 1;
        t0 = t1;
    }
    pieces
}

/// A field that bends strongly (a quadratic in x and y of tens of µm over 100 mm).
fn bending() -> Field {
    Field {
        c: [0.004, -0.003, 0.002],
        b: [[2e-5, 1e-5, 0.0], [-1e-5, 3e-5, 0.0], [1e-5, 1e-5, 0.0]],
        q: 8e-6,
        max: [1e6; 3],
    }
}

#[test]
fn arcs_stay_arcs_and_blocks_only_where_the_field_needs_them() {
    let f = bending();
    let opts = fanuc_options();
    let (src, _) = parse_with(FANUC, &opts).unwrap();
    let out = compensate_program(FANUC, &opts, &f, 0.001).unwrap();
    check(FANUC, &opts, &f, &out, 0.001);
    let (got, _) = parse_with(&out.gcode, &opts).unwrap();
    let (mut need, mut written, mut arcs_in, mut arcs_out) = (0, 0, 0, 0);
    for b in src.blocks.iter().filter(|b| b.feed != Feed::Rapid) {
        need += need_reference(&f, b, 0.0005);
        let outs: Vec<&Block> = got
            .blocks
            .iter()
            .filter(|k| out.source_lines[k.line - 1] == b.line)
            .collect();
        written += outs.len();
        if matches!(b.motion, Motion::Arc { .. }) {
            arcs_in += 1;
            arcs_out += outs.len();
            assert!(
                outs.iter().all(|k| matches!(k.motion, Motion::Arc { .. })),
                "line {}: an arc came back with straight pieces:\n{}",
                b.line,
                out.gcode
            );
        }
    }
    println!(
        "feed blocks: need {need} (e linear within 0.5 µm), written {written}; arcs {arcs_in} in, \
         {arcs_out} sub-arcs out"
    );
    assert!(
        written > src.blocks.len() / 2,
        "the field splits some blocks"
    );
    assert!(
        written as f64 <= 1.5 * need as f64,
        "{written} blocks written, {need} needed"
    );
}

#[test]
fn a_small_semicircle_stays_within_the_tolerance() {
    // Issue 39: a 1.34 mm semicircle chorded so coarsely that its midpoint landed 1.13 µm
    // off p − e(p). Sub-arcs checked at seven interior points each.
    let src = "G0 X0 Y0 Z0\nG1 X10. F500.\nG2 X11.34 Y0 I0.67 J0\nG1 X20.\nM30\n";
    let f = Field {
        c: [0.0; 3],
        b: [[0.0; 3]; 3],
        q: 4e-4,
        max: [1e6; 3],
    };
    let opts = ReadOptions::default();
    let out = compensate_program(src, &opts, &f, 0.001).unwrap();
    let miss = check(src, &opts, &f, &out, 0.001);
    println!(
        "semicircle: {}\nlargest end miss {:.3} µm",
        out.gcode,
        miss * 1e3
    );
    assert!(!out.gcode.contains("G1 X10.1") && out.gcode.contains("G2"));
}

const POCKET: &str = "%\nO1003\nN10 G90 G17 G21 G40 G49 G80\nN20 T1 M6\nN30 G0 G54 X15. Y10. S10000 M3\n\
N40 G43 H1 Z2.\nN50 G1 Z-3. F300.\nN60 G41 D1 X30. F1500.\nN70 Y20.\nN80 X0.\nN90 Y0.\nN100 X30.\n\
N110 Y10.\nN120 G40 X15.\nN130 G0 Z25.\nN140 M30\n%\n";

#[test]
fn cutter_compensation_moves_stay_whole() {
    let f = bending();
    let opts = fanuc_options();
    // A tolerance tight enough that the field splits every long move.
    let out = compensate_program(POCKET, &opts, &f, 0.0001).unwrap();
    let count = |line: usize| out.source_lines.iter().filter(|&&l| l == line).count();
    for (line, what) in [(8, "G41 entry"), (9, "move after G41"), (14, "G40 exit")] {
        assert_eq!(count(line), 1, "{what} (line {line}) split:\n{}", out.gcode);
    }
    assert!(
        count(10) > 1,
        "the field splits a long move:\n{}",
        out.gcode
    );
    // The G41 move ends at the compensated end of its source.
    let (a, _) = parse_with(POCKET, &opts).unwrap();
    let (b, _) = parse_with(&out.gcode, &opts).unwrap();
    for line in [8, 9, 14] {
        let o = a.blocks.iter().find(|k| k.line == line).unwrap();
        let w = b
            .blocks
            .iter()
            .find(|k| out.source_lines[k.line - 1] == line)
            .unwrap();
        assert!(dist(w.end.xyz, comp(&f, o.end.xyz)) < 1e-4, "line {line}");
    }
}

#[test]
fn feeds_never_rise_and_are_written_as_the_source_writes_them() {
    let f = bending();
    let opts = fanuc_options();
    let out = compensate_program(POCKET, &opts, &f, 0.0001).unwrap();
    let (a, _) = parse_with(POCKET, &opts).unwrap();
    let (b, _) = parse_with(&out.gcode, &opts).unwrap();
    for k in b.blocks.iter().filter(|k| k.feed != Feed::Rapid) {
        let src = out.source_lines[k.line - 1];
        let o = a.blocks.iter().find(|o| o.line == src).unwrap();
        assert_eq!(k.feed, o.feed, "line {src}: feed changed");
    }
    // F words only on the source's lines, in the source's style.
    for (text, &src) in out.gcode.lines().zip(&out.source_lines) {
        let source = POCKET.lines().nth(src - 1).unwrap();
        assert_eq!(
            text.contains('F'),
            source.contains('F') && text.contains(source.split('F').nth(1).unwrap_or("?")),
            "line {src}: {text}"
        );
    }
    let dwells = |t: &str| {
        t.lines()
            .flat_map(word_spans)
            .filter(|w| w.letter == 'G' && w.value == 4.0)
            .count()
    };
    assert_eq!(dwells(&out.gcode), dwells(POCKET), "no dwell added");
}

#[test]
fn rapids_gain_no_words() {
    let f = bending();
    let opts = fanuc_options();
    let out = compensate_program(POCKET, &opts, &f, 0.001).unwrap();
    for (text, &src) in out.gcode.lines().zip(&out.source_lines) {
        let source = POCKET.lines().nth(src - 1).unwrap();
        if source.contains("G0") {
            let letters = |s: &str| word_spans(s).iter().map(|w| w.letter).collect::<String>();
            assert_eq!(letters(text), letters(source), "{source} -> {text}");
        }
    }
}
