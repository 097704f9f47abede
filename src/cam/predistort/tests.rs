//! Unit tests of `crate::cam::predistort`: a square's corners, a circle's radius, the
//! invariants of every answer (feeds never raised, arcs stay arcs, at most three pieces a
//! block, no Z on a 2-D cut), the model set and the option checks.

use super::*;
use crate::motion::gcode;
use serde_json::json;

/// The demo cascade with position-loop gain `kv` (1/s), kff 0.6, on X, Y, Z.
fn machine_kv(kv: f64) -> Machine {
    let ax = json!({"kv": kv, "kff": 0.6, "kp_v": 400.0, "ti_v": 0.01, "tc": 0.0005});
    Machine::from_json(&json!({"kinematics": "xyz", "axes": {"X": ax, "Y": ax, "Z": ax}})).unwrap()
}

fn opts() -> PredistortOptions {
    PredistortOptions {
        period_s: 1e-3,
        max_iterations: 20,
        max_duration_ratio: DEFAULT_MAX_DURATION_RATIO,
        band_mm: DEFAULT_BAND_MM,
    }
}

fn read(text: &str) -> Program {
    gcode::parse(text).unwrap()
}

/// A 20 mm square at F2000 after a lead-in, at Z-1.
const SQUARE: &str = "G90 G17 G94\nG1 Z-1 F2000\nG1 X10 Y0\nG1 X30 Y0\nG1 X30 Y20\nG1 X10 Y20\nG1 X10 Y0\nG1 X0 Y0\n";

/// The invariants of issue 39 item 1 on an answer of `program`.
fn check_invariants(program: &Program, out: &Predistorted) {
    for (line, pieces) in &out.lines {
        let blocks: Vec<&gcode::Block> =
            program.blocks.iter().filter(|b| b.line == *line).collect();
        assert_eq!(blocks.len(), 1, "line {line}: one block a rewritten line");
        let b = blocks[0];
        assert!(pieces.len() <= 3, "line {line}: {} pieces", pieces.len());
        let gcode::Feed::PerMinute(f) = b.feed else {
            panic!("line {line}: rewritten block not at a feed")
        };
        for p in pieces {
            let (end, feed) = match *p {
                Piece::Line { end, feed_mm_min } => {
                    assert!(
                        matches!(b.motion, gcode::Motion::Linear),
                        "line {line}: a line of an arc"
                    );
                    (end, feed_mm_min)
                }
                Piece::Arc {
                    end, feed_mm_min, ..
                } => {
                    assert!(
                        matches!(b.motion, gcode::Motion::Arc { .. }),
                        "line {line}: an arc of a line"
                    );
                    (end, feed_mm_min)
                }
            };
            assert!(feed <= f + 1e-9, "line {line}: feed {feed} above F{f}");
            assert!(feed >= MIN_FEED_FRACTION * f - 1e-9);
            if b.start.xyz[2] == b.end.xyz[2] {
                assert!(
                    (end[2] - b.end.xyz[2]).abs() < 1e-12,
                    "line {line}: Z moved on a 2-D cut"
                );
            }
        }
    }
}

#[test]
fn square_corners_improve_on_every_model_within_the_duration() {
    let m = machine_kv(40.0);
    let p = read(SQUARE);
    // The route's iteration budget: with half of it the optimiser stops before the band is
    // met and the answer is scaled back (about 0.70x RMS, 0.82x max).
    let o = PredistortOptions {
        max_iterations: super::super::contour::MAX_ITERATIONS,
        ..opts()
    };
    let out = predistort(&m, &p, &o).unwrap();
    check_invariants(&p, &out);
    assert!(!out.lines.is_empty(), "{:?}", out.notes);
    let r = out.compensated.rms_distance_mm / out.original.rms_distance_mm;
    let x = out.compensated.max_mm / out.original.max_mm;
    let t = out.compensated.duration_s / out.original.duration_s;
    eprintln!(
        "square F2000 kv40: RMS {:.2} -> {:.2} µm ({r:.3}x), max {:.2} -> {:.2} µm ({x:.3}x), \
         duration {t:.3}x, {} iterations, {} evaluations",
        1e3 * out.original.rms_distance_mm,
        1e3 * out.compensated.rms_distance_mm,
        1e3 * out.original.max_mm,
        1e3 * out.compensated.max_mm,
        out.iterations,
        out.evaluations
    );
    eprintln!("  notes: {:?}", out.notes);
    for mf in &out.models {
        eprintln!(
            "  {}: RMS {:.3}x max {:.3}x",
            mf.model,
            mf.compensated.rms_distance_mm / mf.original.rms_distance_mm,
            mf.compensated.max_mm / mf.original.max_mm
        );
        assert!(
            mf.compensated.rms_distance_mm < mf.original.rms_distance_mm,
            "{}",
            mf.model
        );
    }
    // Within the band where the original stayed within it (a constraint since issue 39
    // item 1), about 0.32x RMS and 0.71x max.
    assert!(r < 0.6 && x < 0.8, "RMS {r}, max {x}");
    assert!(
        out.compensated.gouge_mm <= BAND_SLACK_MM,
        "{} mm beyond the band",
        out.compensated.gouge_mm
    );
    assert!(t <= DEFAULT_MAX_DURATION_RATIO + 1e-9, "duration {t}");
}

#[test]
fn a_circle_stays_an_arc_with_a_larger_radius() {
    let m = machine_kv(30.0);
    let p = read("G90 G17 G94\nG1 X0 Y15 F3000\nG3 X0 Y15 I-10 J0\nG1 Y30\n");
    let out = predistort(&m, &p, &opts()).unwrap();
    check_invariants(&p, &out);
    let pieces = out.lines.get(&3).expect("the circle is rewritten");
    assert!(pieces.iter().all(|p| matches!(p, Piece::Arc { .. })));
    // The middle piece runs about the original centre (-10, 15) on a larger radius.
    let Piece::Arc { end, centre, .. } = pieces[pieces.len() / 2] else {
        unreachable!()
    };
    let r = (end[0] - centre[0]).hypot(end[1] - centre[1]);
    assert!(r > 10.0, "radius {r}");
    assert!(
        out.compensated.rms_distance_mm < 0.5 * out.original.rms_distance_mm,
        "{:?} -> {:?}",
        out.original,
        out.compensated
    );
}

#[test]
fn no_iterations_change_nothing() {
    let m = machine_kv(40.0);
    let p = read(SQUARE);
    let out = predistort(
        &m,
        &p,
        &PredistortOptions {
            max_iterations: 0,
            ..opts()
        },
    )
    .unwrap();
    assert!(out.lines.is_empty());
    assert_eq!(
        out.original.rms_distance_mm,
        out.compensated.rms_distance_mm
    );
}

#[test]
fn kept_lines_stay_and_plunges_stay_on_their_axis() {
    let m = machine_kv(40.0);
    let p = read(SQUARE);
    let out = predistort_sided(
        &m,
        &p,
        &PathControl::default(),
        &opts(),
        &|l| l == 4,
        &|_| None,
        &|_| [true; 3],
        &|_| false,
    )
    .unwrap();
    assert!(!out.lines.contains_key(&4));
    // The plunge (line 2) may only be slowed before its corner: its pieces stay on Z.
    for p in out.lines.get(&2).into_iter().flatten() {
        let Piece::Line { end, .. } = *p else {
            panic!("an arc on a plunge")
        };
        assert_eq!((end[0], end[1]), (0.0, 0.0), "an X/Y word on a pure Z move");
    }
}

#[test]
fn the_model_set_spans_gain_feed_forward_and_period() {
    let m = machine_kv(40.0);
    let set = model_set(&m, 1e-3);
    let names: Vec<&str> = set.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "nominal",
            "kv -15 %",
            "kv +15 %",
            "kff -0.1",
            "kff +0.1",
            "period x0.5"
        ]
    );
    assert_eq!(set[1].machine.axes[0].servo.kv, 40.0 * 0.85);
    assert!((set[4].machine.axes[0].servo.kff - 0.7).abs() < 1e-12);
    assert_eq!(set[5].period_s, 5e-4);
}

#[test]
fn options_out_of_range_are_named() {
    let m = machine_kv(40.0);
    let p = read(SQUARE);
    let e = predistort(
        &m,
        &p,
        &PredistortOptions {
            band_mm: 0.0,
            ..opts()
        },
    )
    .unwrap_err();
    assert!(
        matches!(
            e,
            Error::Option {
                field: "band_mm",
                ..
            }
        ),
        "{e}"
    );
    let e = predistort(
        &m,
        &p,
        &PredistortOptions {
            max_duration_ratio: 3.0,
            ..opts()
        },
    )
    .unwrap_err();
    assert!(
        matches!(
            e,
            Error::Option {
                field: "max_duration_ratio",
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn colours_keep_overlapping_windows_apart() {
    let bins = vec![0..10, 5..15, 12..20, 30..40, 16..25];
    let c = solve::colours(&bins);
    for v in &c {
        for (i, &a) in v.iter().enumerate() {
            for &b in &v[i + 1..] {
                let (x, y) = (&bins[a], &bins[b]);
                assert!(
                    x.end <= y.start || y.end <= x.start,
                    "{x:?} {y:?} share a colour"
                );
            }
        }
    }
    assert_eq!(c.iter().map(Vec::len).sum::<usize>(), bins.len());
    assert!(c.len() <= 3, "{c:?}");
}

#[test]
fn sparse_dot_matches_dense() {
    let a = [(1, 2.0), (3, 1.0), (7, -1.0)];
    let b = [(0, 5.0), (3, 4.0), (7, 2.0), (9, 1.0)];
    assert_eq!(solve::dot_sparse(&a, &b), 4.0 - 2.0);
}

/// A machine at kv 30/s with feed-forward 0.9.
fn machine_kff09() -> Machine {
    let ax = json!({"kv": 30.0, "kff": 0.9});
    Machine::from_json(&json!({"kinematics": "xyz", "axes": {"X": ax, "Y": ax, "Z": ax}})).unwrap()
}

/// A finishing contour after a rapid: lead-in, straight, half circle, straight back and a
/// side, two 90° corners, at F2000.
const FINISH: &str = "G21 G90 G17 G94\nG0 X100 Y40\nG1 X100 Y50 F2000\nG1 X160 Y50\n\
                      G3 X160 Y90 I0 J20\nG1 X100 Y90\nG1 X100 Y50\n";

/// At kff 0.9 the model set's kff + 0.1 follows the path perfectly: its original error is
/// zero and was once the scale of its residuals (every change then cost 10⁵⁰ and the answer
/// was the program as written). The lead-in's catch-up after the rapid, which no feature
/// can change, no longer sets the scale either: both corners are pre-distorted and the
/// nominal error falls.
#[test]
fn a_model_that_follows_the_path_does_not_freeze_the_answer() {
    let m = machine_kff09();
    let p = read(FINISH);
    let o = PredistortOptions {
        max_iterations: 40,
        ..opts()
    };
    let out = predistort(&m, &p, &o).unwrap();
    check_invariants(&p, &out);
    let perfect = &out.models[4];
    assert_eq!(perfect.model, "kff +0.1");
    assert!(perfect.original.max_mm < 1e-9, "{:?}", perfect.original);
    for l in [3, 4, 6, 7] {
        assert!(out.lines.contains_key(&l), "line {l}: {:?}", out.notes);
    }
    let (a, b) = (out.original, out.compensated);
    assert!(
        b.rms_distance_mm < 0.95 * a.rms_distance_mm,
        "{a:?} -> {b:?}: {:?}",
        out.notes
    );
    assert!(b.duration_s <= DEFAULT_MAX_DURATION_RATIO * a.duration_s);
}

/// A backlash take-up (a 10 µm Y move written between the two blocks of a corner, kept as
/// written) does not hide the corner: its two blocks are slowed, the corner point stays.
#[test]
fn a_corner_across_a_take_up_is_slowed_not_moved() {
    let m = machine_kff09();
    let text = "G21 G90 G17 G94\nG0 X100 Y40\nG1 X100 Y50 F2000\nG1 X160 Y50\nG1 Y49.99\n\
                G1 X160 Y10\n";
    let p = read(text);
    let o = PredistortOptions {
        max_iterations: 40,
        ..opts()
    };
    let out = predistort_sided(
        &m,
        &p,
        &PathControl::default(),
        &o,
        &|l| l == 5,
        &|_| None,
        &|_| [true; 3],
        &|l| l == 5,
    )
    .unwrap();
    check_invariants(&p, &out);
    assert!(!out.lines.contains_key(&5));
    let before = out
        .lines
        .get(&4)
        .expect("the block before the take-up is slowed");
    let after = out.lines.get(&6).expect("the block after it is slowed");
    let Piece::Line { end, feed_mm_min } = *before.last().unwrap() else {
        panic!("a line")
    };
    assert_eq!(end, [160.0, 50.0, 0.0], "the corner point stays");
    assert!(feed_mm_min < 2000.0);
    let Piece::Line { feed_mm_min, .. } = after[0] else {
        panic!("a line")
    };
    assert!(feed_mm_min < 2000.0);
}
