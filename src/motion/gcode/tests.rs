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
