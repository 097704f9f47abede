//! Tests of the G-code reader: modal state, arcs, rejected input, and never panicking.

use super::*;
use crate::motion::error::Error;
use proptest::prelude::*;
use std::f64::consts::{PI, TAU};

fn one(text: &str) -> Block {
    let p = parse(text).unwrap();
    p.blocks.last().unwrap().clone()
}

#[test]
fn modal_state_units_and_incremental() {
    let p =
        parse("N10 G21 G90 G94 F600 (set up)\nG1 X10 Y5 ; first\nY7\nG91 X1\nG20 G90 G1 X1 F10")
            .unwrap();
    assert_eq!(p.blocks.len(), 4);
    assert_eq!(p.blocks[0].end.xyz, [10.0, 5.0, 0.0]);
    assert_eq!(p.blocks[1].end.xyz, [10.0, 7.0, 0.0]);
    assert_eq!(p.blocks[2].end.xyz, [11.0, 7.0, 0.0]);
    assert_eq!(p.blocks[3].end.xyz[0], 25.4);
    assert_eq!(p.blocks[3].feed, Feed::PerMinute(254.0));
    assert_eq!(p.blocks[0].line, 2);
}

#[test]
fn arcs_ijk_r_full_circle_and_helix() {
    // Quarter CCW in XY by IJK and by R: same centre and sweep.
    let a = one("G17 G1 X10 Y0 F100\nG3 X0 Y10 I-10 J0");
    let b = one("G17 G1 X10 Y0 F100\nG3 X0 Y10 R10");
    for blk in [&a, &b] {
        let Motion::Arc {
            center, sweep_rad, ..
        } = blk.motion
        else {
            panic!()
        };
        assert!(
            center[0].abs() < 1e-12 && center[1].abs() < 1e-12,
            "{center:?}"
        );
        assert!((sweep_rad - PI / 2.0).abs() < 1e-12);
    }
    // R < 0: the long way round (270°), CW.
    let c = one("G1 X10 Y0 F100\nG2 X0 Y10 R-10");
    let Motion::Arc { sweep_rad, .. } = c.motion else {
        panic!()
    };
    assert!((sweep_rad + 1.5 * PI).abs() < 1e-12, "{sweep_rad}");
    // Full helical circle in G17: end == start in XY, Z climbs.
    let h = one("G1 X5 Y0 F100\nG2 X5 Y0 Z-2 I-5 J0");
    let Motion::Arc { sweep_rad, .. } = h.motion else {
        panic!()
    };
    assert!((sweep_rad + TAU).abs() < 1e-12);
    let mid = h.pose_at(0.5);
    assert!((mid.xyz[0] + 5.0).abs() < 1e-9 && (mid.xyz[2] + 1.0).abs() < 1e-12);
    assert!((h.xyz_length() - (TAU * 5.0f64).hypot(2.0)).abs() < 1e-9);
    // G18 (ZX plane): G3 turns from Z towards X.
    let g = one("G18 G1 X0 Z10 F100\nG3 X10 Z0 K-10");
    let Motion::Arc { sweep_rad, .. } = g.motion else {
        panic!()
    };
    assert!((sweep_rad - PI / 2.0).abs() < 1e-12, "{sweep_rad}");
    let m = g.pose_at(0.5);
    assert!((m.xyz[0] - 10.0 * (PI / 4.0).sin()).abs() < 1e-9);
}

#[test]
fn rtcp_and_rotary_words() {
    let p =
        parse("G43.4 H1\nG1 X1 A10 C20 F500\nG49\nG1 X2\nTRAORI\nG1 C30\nTRAFOOF\nG1 A0").unwrap();
    let rtcp: Vec<bool> = p.blocks.iter().map(|b| b.rtcp).collect();
    assert_eq!(rtcp, vec![true, false, true, false]);
    assert_eq!(p.first_a_line, Some(2));
    assert_eq!(p.first_c_line, Some(2));
    assert_eq!(p.blocks[2].end.c, 30.0);
}

#[test]
fn inverse_time_needs_f_per_block_and_dwell() {
    let e = parse("G93 G1 X1 F2\nG1 X2").unwrap_err();
    assert_eq!(
        e,
        Error::gcode(2, "G93 inverse-time mode needs F on every G1/G2/G3 block")
    );
    let p = parse("G93 G1 X1 F2\nG4 P500\nG94 G1 X3 F100").unwrap();
    assert_eq!(p.blocks[0].feed, Feed::InverseTime(2.0));
    assert_eq!(p.blocks[1].motion, Motion::Dwell { seconds: 0.5 });
}

#[test]
fn unsupported_codes_name_line_and_code() {
    let cases = [
        ("G1 X1 F10\nG41 D1", 2, "G41"),
        ("G1 X1 F10\n\nM0444444444", 3, "M444444444"),
        ("G12.1", 1, "G12.1"),
        ("G1 B10 F100", 1, "B10"),
        ("CYCLE800()", 1, "CYCLE"),
        ("G1 X1 F1\nG1 X2 #1", 2, "#"),
    ];
    for (text, line, code) in cases {
        match parse(text) {
            Err(Error::UnsupportedCode { line: l, code: c }) => {
                assert_eq!(l, line, "{text}");
                assert!(c.starts_with(code), "{text}: {c}");
            }
            other => panic!("{text}: {other:?}"),
        }
    }
}

#[test]
fn malformed_blocks_are_errors_not_skips() {
    for (text, line) in [
        ("G1 X10 Y0 F100\nG2 X0 Y10 I-3 J0", 2), // end not on circle
        ("G1 X1\n", 1),                          // no feed
        ("X1", 1),                               // no motion mode
        ("G1 X1 X2 F1", 1),                      // duplicate word
        ("G1 X F1", 1),                          // missing number
        ("G1 X1 F1 (open", 1),                   // unclosed comment
        ("G1 X1 F100\nG2 X1 R5", 2),             // R full circle ambiguous
        ("G1 X1 F100\nG2 X30 R5", 2),            // R too small
        ("G0 G1 X1 F1", 1),                      // two motion codes
    ] {
        let e = parse(text).unwrap_err();
        match e {
            Error::Gcode { line: l, .. } => assert_eq!(l, line, "{text}"),
            other => panic!("{text}: {other:?}"),
        }
    }
}

#[test]
fn program_end_stops_reading() {
    let p = parse("G1 X1 F100\nM30\nG1 X99 B2").unwrap();
    assert_eq!(p.blocks.len(), 1);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]
    #[test]
    fn random_text_never_panics(s in "\\PC{0,200}") {
        let _ = parse(&s);
    }

    #[test]
    fn random_gcode_like_text_never_panics(
        s in "([GMXYZACIJKRFNPHT][-+]?[0-9]{0,12}(\\.[0-9]{0,6})?[ ;()\n]?){0,40}"
    ) {
        if let Ok(p) = parse(&s) {
            for b in &p.blocks {
                let q = b.pose_at(0.37);
                prop_assert!(q.xyz.iter().all(|v| v.is_finite()));
            }
        }
    }
}

// ---- lenient / strict reading (issue 14, CONTRACT v1.1 "Reading real programs") ----

/// A finishing program as a Fanuc-style post writes it.
const POST: &str = "%
O1234 (FINISH POCKET)
(T1 D6 FLAT ENDMILL)
N10 G21 G90 G17 G40 G49 G80
N20 T1 M6
N30 G54
N40 G43 H1 Z50.
N50 S12000 M3
N60 M8
N70 G0 X10. Y0.
N80 G1 Z-1. F300.
N90 G3 X0. Y10. I-10. J0.
N100 G1 X-10.
N110 G0 Z5.
N120 G98 G83 X20. Y20. Z-10. R2. Q1. F200.
N130 X30.
N140 G80
N150 G28 G91 Z0.
N160 M30
%
";

fn lenient(text: &str) -> (Program, Vec<Warning>) {
    parse_with(text, &ReadOptions::default()).unwrap()
}

fn strict_error(text: &str) -> (usize, String) {
    let opts = ReadOptions {
        strict: true,
        ..ReadOptions::default()
    };
    match parse_with(text, &opts) {
        Err(Error::Gcode { line, message }) => (line, message),
        other => panic!("{text}: {other:?}"),
    }
}

#[test]
fn post_program_reads_with_each_word_named_once() {
    let (p, warnings) = lenient(POST);
    let words: Vec<&str> = warnings.iter().map(|w| w.word.as_str()).collect();
    for word in [
        "%", "O1234", "comment", "N", "G40", "G49", "G80", "T1", "M6", "G54", "G43 H1", "S12000",
        "M3", "M8", "G83", "G28", "M30",
    ] {
        let n = words.iter().filter(|w| **w == word).count();
        assert_eq!(n, 1, "{word} in {words:?}");
    }
    assert!(!words.iter().any(|w| w.starts_with('Q')), "{words:?}");
    let first = |word: &str| warnings.iter().find(|w| w.word == word).unwrap().line;
    assert_eq!(first("%"), 1);
    assert_eq!(first("comment"), 2);
    assert_eq!(first("G43 H1"), 7);
    assert!(warnings[0].to_string().starts_with("line 1: %: "));
    // The tool-tip path: Z50 (no tool length given), the arc, the two holes.
    assert_eq!(p.blocks[0].end.xyz, [0.0, 0.0, 50.0]);
    let arc = p.blocks.iter().find(|b| b.line == 12).unwrap();
    assert!(matches!(arc.motion, Motion::Arc { .. }));
    let holes: Vec<&Block> = p.blocks.iter().filter(|b| b.line == 15).collect();
    let bottom = holes.iter().map(|b| b.end.xyz[2]).fold(f64::MAX, f64::min);
    assert_eq!(bottom, -10.0);
    // G98: back to the initial level (Z5) after each hole; the second hole at X30.
    let last = p.blocks.iter().rfind(|b| b.line == 16).unwrap();
    assert_eq!(last.end.xyz, [30.0, 20.0, 5.0]);
    // G28 G91 Z0: through the intermediate point (here, where it is); Z unknown after, and
    // nothing moves before M30.
    assert_eq!(p.blocks.last().unwrap().line, 16);
}

#[test]
fn strict_refuses_each_word_naming_line_and_word() {
    let (line, message) = strict_error(POST);
    assert_eq!(line, 1);
    assert!(message.starts_with("%:"), "{message}");
    for (text, line, word) in [
        ("G1 X1 F100\nG41 D1 X2", 2, "D1"),
        ("G1 X1 F100\nG41 X2", 2, "G41"),
        ("G0 X1\nM3", 2, "M3"),
        ("G0 X1\nS1000", 2, "S1000"),
        ("G0 X1\n(comment)", 2, "comment"),
        ("G0 X1\nG55 G0 X2", 2, "G55"),
        ("/G0 X1", 1, "/"),
    ] {
        let (l, m) = strict_error(text);
        assert_eq!(l, line, "{text}");
        assert!(m.starts_with(word), "{text}: {m}");
        assert!(m.contains("strict"), "{m}");
    }
}

#[test]
fn the_old_subset_still_refuses_what_it_refused() {
    for (text, code) in [
        ("G43 H1 Z5", "G43"),
        ("G55", "G55"),
        ("G81 X1 Y1 Z-1 R1 F10", "G81"),
        ("G1 X1 F1\nM98 P100", "M98"),
        ("G1 X1 F1\nQ1", "Q1"),
        ("/G1 X1 F1", "/"),
    ] {
        match parse(text) {
            Err(Error::UnsupportedCode { code: c, .. }) => assert_eq!(c, code, "{text}"),
            other => panic!("{text}: {other:?}"),
        }
    }
}

#[test]
fn inch_program_is_its_mm_twin() {
    let mm = "G21 G90 G17\nG0 X25.4 Y0\nG1 Z-2.54 F254\nG2 X0 Y25.4 R25.4\nG3 X-25.4 Y0 I0 J-25.4\n\
              G81 X50.8 Y50.8 Z-12.7 R2.54 F127\nG80";
    let inch = "G20 G90 G17\nG0 X1 Y0\nG1 Z-.1 F10\nG2 X0 Y1 R1\nG3 X-1 Y0 I0 J-1\n\
                G81 X2 Y2 Z-.5 R.1 F5\nG80";
    let (a, _) = lenient(mm);
    let (b, _) = lenient(inch);
    assert_eq!(a.blocks.len(), b.blocks.len());
    for (x, y) in a.blocks.iter().zip(&b.blocks) {
        for k in 0..3 {
            assert!((x.end.xyz[k] - y.end.xyz[k]).abs() < 1e-9, "{x:?} {y:?}");
        }
        match (x.feed, y.feed) {
            (Feed::PerMinute(f), Feed::PerMinute(g)) => assert!((f - g).abs() < 1e-9),
            (f, g) => assert_eq!(f, g),
        }
        assert_eq!(
            std::mem::discriminant(&x.motion),
            std::mem::discriminant(&y.motion)
        );
    }
}

#[test]
fn absolute_arc_centres_match_incremental_ones() {
    let inc = one("G1 X10 Y5 F100\nG3 X0 Y15 I-10 J0");
    let (p, w) = lenient("G90.1\nG1 X10 Y5 F100\nG3 X0 Y15 I0 J5");
    assert!(w.is_empty(), "{w:?}");
    assert_eq!(p.blocks.last().unwrap().motion, inc.motion);
}

#[test]
fn block_delete_runs_the_block_with_a_warning() {
    let (p, w) = lenient("G1 X1 F100\n/G1 X2\nX3");
    assert_eq!(p.blocks.len(), 3);
    assert_eq!(p.blocks[1].end.xyz[0], 2.0);
    assert_eq!((w[0].line, w[0].word.as_str()), (2, "/"));
}

#[test]
fn canned_cycles_expand_with_r_plane_semantics() {
    // G99 G81: rapid XY, rapid to R, feed to Z, rapid to R; next hole modal; G80 cancels.
    let (p, _) = lenient("G0 Z10\nG99 G81 X5 Y5 Z-3 R1 F60\nX8\nG80");
    let path: Vec<([f64; 3], bool)> = p
        .blocks
        .iter()
        .map(|b| (b.end.xyz, b.feed == Feed::Rapid))
        .collect();
    assert_eq!(
        path,
        vec![
            ([0.0, 0.0, 10.0], true),
            ([5.0, 5.0, 10.0], true),
            ([5.0, 5.0, 1.0], true),
            ([5.0, 5.0, -3.0], false),
            ([5.0, 5.0, 1.0], true),
            ([8.0, 5.0, 1.0], true),
            ([8.0, 5.0, -3.0], false),
            ([8.0, 5.0, 1.0], true),
        ]
    );
    // X0 after G80: no motion mode in force, so no hole: read as G0 with a warning.
    let (p, w) = lenient("G81 X1 Z-1 R1 F10\nG80\nX0");
    assert_eq!(p.blocks.last().unwrap().feed, Feed::Rapid);
    assert_eq!(p.blocks.last().unwrap().end.xyz, [0.0, 0.0, 1.0]);
    assert!(w.iter().any(|w| w.line == 3 && w.word == "no motion mode"));
    // G98 G82 dwell P ms, G85 feeds back; G91: R from the initial level, Z from R.
    let (p, _) = lenient("G0 Z10\nG98 G82 X1 Z-2 R2 P500 F60\nG85 X2\nG91 G81 X1 R-7 Z-4");
    let dwell = p
        .blocks
        .iter()
        .find(|b| matches!(b.motion, Motion::Dwell { .. }));
    assert_eq!(dwell.unwrap().motion, Motion::Dwell { seconds: 0.5 });
    assert_eq!(p.blocks[p.blocks.len() - 1].end.xyz, [3.0, 0.0, 10.0]);
    let g85: Vec<&Block> = p.blocks.iter().filter(|b| b.line == 3).collect();
    assert!(matches!(g85[g85.len() - 2].feed, Feed::PerMinute(_)));
    let bottom = p
        .blocks
        .iter()
        .filter(|b| b.line == 4)
        .map(|b| b.end.xyz[2]);
    assert_eq!(bottom.fold(f64::MAX, f64::min), -1.0);
}

#[test]
fn work_offsets_and_tool_lengths_from_the_caller() {
    let mut opts = ReadOptions::default();
    opts.work_offsets_mm[1] = Some([100.0, 200.0, -50.0]);
    opts.tool_lengths_mm.insert(3, 80.0);
    let text = "G55 G43 H3 G0 X1 Y2 Z3\nG49 G0 Z3\nG56 G0 X0";
    let (p, w) = parse_with(text, &opts).unwrap();
    assert_eq!(p.blocks[0].end.xyz, [101.0, 202.0, 33.0]);
    assert_eq!(p.blocks[1].end.xyz, [101.0, 202.0, -47.0]);
    assert_eq!(p.blocks[2].end.xyz, [0.0, 202.0, -47.0]);
    let named: Vec<String> = w.iter().map(ToString::to_string).collect();
    assert!(
        named[0].contains("G55") && named[0].contains("[100, 200, -50]"),
        "{named:?}"
    );
    assert!(
        named
            .iter()
            .any(|s| s.contains("G43 H3") && s.contains("80 mm"))
    );
    assert!(
        named
            .iter()
            .any(|s| s.contains("G56") && s.contains("zero"))
    );
    // Strict accepts offsets it was given, refuses the one it was not.
    opts.strict = true;
    let e = parse_with(text, &opts).unwrap_err();
    assert!(matches!(e, Error::Gcode { line: 2, ref message } if message.starts_with("G49")));
}

#[test]
fn g28_without_home_names_the_lines_at_unknown_positions() {
    let text = "G1 X10 Y10 Z10 F100\nG91 G28 Z5\nG90 G1 X20\nG1 Z2\nG1 X30";
    let (p, w) = lenient(text);
    // The intermediate point is known (Z15), then Z is unknown until Z2 (line 4).
    assert_eq!(p.blocks[1].end.xyz, [10.0, 10.0, 15.0]);
    let lines: Vec<usize> = p.blocks.iter().map(|b| b.line).collect();
    assert_eq!(lines, vec![1, 2, 4, 5]);
    assert!(w.iter().any(|w| w.word == "G28" && w.message.contains('Z')));
    assert!(
        w.iter()
            .any(|w| w.line == 3 && w.message.contains("unknown"))
    );
    assert!(
        w.iter()
            .any(|w| w.line == 4 && w.message.contains("unknown"))
    );
    // With a home: through the intermediate point to home.
    let opts = ReadOptions {
        home_mm: Some([0.0, 0.0, 100.0]),
        ..ReadOptions::default()
    };
    let (p, _) = parse_with(text, &opts).unwrap();
    assert_eq!(p.blocks[2].end.xyz, [10.0, 10.0, 100.0]);
    assert_eq!(p.blocks[3].end.xyz, [20.0, 10.0, 100.0]);
}

#[test]
fn unmodelled_axes_pass_while_still_and_fail_when_moving() {
    let (_, w) = lenient("G0 X1 B0\nG0 X2 B0");
    assert_eq!(w.len(), 1);
    assert_eq!((w[0].line, w[0].word.as_str()), (1, "B0"));
    let e = parse_with("G0 X1 B0\nG0 X2 B10", &ReadOptions::default()).unwrap_err();
    assert!(matches!(e, Error::Gcode { line: 2, .. }), "{e:?}");
    // Unknown G codes and macros stay errors even when lenient.
    for text in ["G12.1", "G1 X1 F1\nG1 X2 #1", "CYCLE800()"] {
        assert!(parse_with(text, &ReadOptions::default()).is_err(), "{text}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]
    #[test]
    fn lenient_reading_never_panics(
        s in "(/?[GMXYZACIJKRFNPHTQSBL][-+]?[0-9]{0,3}(\\.[0-9]{0,3})?[ ;()\n%]?){0,40}"
    ) {
        let mut opts = ReadOptions { home_mm: Some([1.0, 2.0, 3.0]), ..ReadOptions::default() };
        opts.tool_lengths_mm.insert(1, 50.0);
        if let Ok((p, _)) = parse_with(&s, &opts) {
            for b in &p.blocks {
                let q = b.pose_at(0.37);
                prop_assert!(q.xyz.iter().all(|v| v.is_finite()));
            }
        }
    }
}

#[test]
fn g53_and_g30_with_a_home_move_to_machine_positions() {
    let mut opts = ReadOptions {
        home_mm: Some([-5.0, -5.0, 80.0]),
        g30_mm: Some([-7.0, -7.0, 70.0]),
        ..ReadOptions::default()
    };
    opts.work_offsets_mm[0] = Some([10.0, 0.0, 0.0]);
    let (p, w) = parse_with("G54 G0 X1 Z5\nG53 G0 Z60\nG30 X2\nG0 X0", &opts).unwrap();
    let ends: Vec<[f64; 3]> = p.blocks.iter().map(|b| b.end.xyz).collect();
    // G53: machine Z60 (no offset); G30 X2: through program X2 (machine 12) to the G30 X.
    assert_eq!(
        ends,
        vec![
            [11.0, 0.0, 5.0],
            [11.0, 0.0, 60.0],
            [12.0, 0.0, 60.0],
            [-7.0, 0.0, 60.0],
            [10.0, 0.0, 60.0]
        ]
    );
    assert_eq!(w.len(), 1, "{w:?}");
    // G53 without a home: the axes it names are unknown until programmed absolutely.
    let (p, w) = lenient("G0 X1\nG53 Z0\nG0 X2\nG0 Z3 X4");
    assert_eq!(p.blocks.len(), 2);
    assert!(w.iter().any(|w| w.word == "G53"));
    assert!(
        w.iter()
            .any(|w| w.line == 3 && w.message.contains("unknown"))
    );
}

#[test]
fn g30_without_its_position_is_not_the_home() {
    // A home alone does not say where G30 goes: its axes are unknown, named on its line.
    let opts = ReadOptions {
        home_mm: Some([0.0, 0.0, 100.0]),
        ..ReadOptions::default()
    };
    let (p, w) = parse_with("G0 X1 Z5\nG91 G30 Z0\nG90 G0 X3\nG0 Z7", &opts).unwrap();
    let lines: Vec<usize> = p.blocks.iter().map(|b| b.line).collect();
    assert_eq!(lines, vec![1, 4]);
    let g30 = w.iter().find(|w| w.word == "G30").unwrap();
    assert_eq!(g30.line, 2);
    assert!(g30.message.contains("no G30 position"), "{g30:?}");
    let strict = ReadOptions {
        strict: true,
        ..opts.clone()
    };
    let e = parse_with("G0 X1 Z5\nG91 G30 Z0", &strict).unwrap_err();
    assert!(
        matches!(e, Error::Gcode { line: 2, ref message } if message.starts_with("G30")),
        "{e:?}"
    );
    // With it, strict reads it: the position is modelled.
    let given = ReadOptions {
        g30_mm: Some([1.0, 2.0, 50.0]),
        ..strict
    };
    let (p, _) = parse_with("G0 X1 Z5\nG91 G30 Z0", &given).unwrap();
    assert_eq!(p.blocks.last().unwrap().end.xyz, [1.0, 0.0, 50.0]);
}

#[test]
fn block_delete_in_mid_block_reads_the_optional_words() {
    // Mastercam's Haas post: coolant made optional in mid-block.
    let text = "G0 X0 Y0\nG43 H6 Z.25 /M8\nG1 Z-1 F100";
    let (p, w) = lenient(text);
    assert_eq!(p.blocks[1].end.xyz, [0.0, 0.0, 0.25]);
    let slash = w.iter().find(|w| w.word == "/ (mid-block)").unwrap();
    assert_eq!(slash.line, 2);
    assert!(w.iter().any(|w| w.word == "M8" && w.line == 2));
    let (line, message) = strict_error("G0 X0 Y0\nG0 Z.25 /M8");
    assert_eq!(line, 2);
    assert!(message.starts_with("/ (mid-block)"), "{message}");
    // At the start of a block with an axis word after a mid-block slash: both read.
    let (p, _) = lenient("/G0 X1 /Y2");
    assert_eq!(p.blocks[0].end.xyz, [1.0, 2.0, 0.0]);
}

#[test]
fn words_after_a_program_number_are_read() {
    let (p, w) = lenient("O1234 G0 X5 Y6\nG1 X7 F100");
    assert_eq!(p.blocks[0].end.xyz, [5.0, 6.0, 0.0]);
    assert!(
        w.iter()
            .any(|w| w.word == "O1234 (with words)" && w.line == 1)
    );
    let (line, message) = strict_error("G0 X1\nO1234 G0 X5");
    assert_eq!(line, 2);
    assert!(message.starts_with("O1234"), "{message}");
    // The program-number line alone is still just named.
    let (_, w) = lenient("O1234 (PART)\nG0 X1");
    assert!(w.iter().any(|w| w.word == "O1234"));
    assert!(!w.iter().any(|w| w.word.contains("with words")));
    assert_eq!(word_spans("O1234 G0 X5").len(), 2);
}

#[test]
fn vendor_m_codes_are_warnings() {
    // Haas: M31 chip auger, M88 through-spindle coolant; Fanuc: M29 rigid tapping, M19.
    let text = "G0 X1\nM31\nM88\nM29 S600\nM19\nG0 X2";
    let (p, w) = lenient(text);
    assert_eq!(p.blocks.len(), 2);
    for (word, line) in [("M31", 2), ("M88", 3), ("M29", 4), ("M19", 5)] {
        let named = w.iter().find(|w| w.word == word).unwrap();
        assert_eq!(named.line, line, "{word}");
    }
    let (line, message) = strict_error("G0 X1\nM31");
    assert_eq!(line, 2);
    assert!(message.starts_with("M31"), "{message}");
}
