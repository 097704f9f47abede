//! Tests of the canned cycles as read: Fanuc retracts for tapping and boring, LinuxCNC's
//! peck depths, and a Fusion 360 drill-and-tap program.

use crate::motion::error::Error;
use crate::motion::gcode::{Feed, Motion, Program, ReadOptions, parse, parse_with};

fn lenient(text: &str) -> (Program, Vec<crate::motion::gcode::Warning>) {
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

/// (end point, rapid) of every block on `line`.
fn path_of(p: &Program, line: usize) -> Vec<([f64; 3], bool)> {
    p.blocks
        .iter()
        .filter(|b| b.line == line && !matches!(b.motion, Motion::Dwell { .. }))
        .map(|b| (b.end.xyz, b.feed == Feed::Rapid))
        .collect()
}

#[test]
fn tapping_and_boring_cycles_retract_as_fanuc_does() {
    // From Z10, hole at (1, 1), R2, Z-5: (end, rapid) after the rapid to XY and to R.
    let r = |z: f64| ([1.0, 1.0, z], true);
    let f = |z: f64| ([1.0, 1.0, z], false);
    for (code, mode, out) in [
        // Tapping: fed in, fed out to R (spindle reversed), then rapid to the initial Z.
        ("G84", "G98", vec![f(-5.0), f(2.0), r(10.0)]),
        ("G74", "G99", vec![f(-5.0), f(2.0)]),
        // G86: spindle stop, rapid out (under G98 straight on to the initial Z, as LinuxCNC
        // makes it: one move). G88: dwell, manual retract (rapid on cycle start).
        ("G86", "G98", vec![f(-5.0), r(10.0)]),
        ("G88", "G99", vec![f(-5.0), r(2.0)]),
        // G89: dwell, fed out to R.
        ("G89", "G98", vec![f(-5.0), f(2.0), r(10.0)]),
    ] {
        let text = format!("G0 Z10\n{mode} {code} X1 Y1 Z-5 R2 P500 F100\nG80");
        let (p, w) = lenient(&text);
        let mut want = vec![([1.0, 1.0, 10.0], true), r(2.0)];
        want.extend(out);
        assert_eq!(path_of(&p, 2), want, "{code} {mode}");
        let dwell = p
            .blocks
            .iter()
            .any(|b| b.motion == Motion::Dwell { seconds: 0.5 });
        assert_eq!(dwell, code != "G86", "{code}");
        if code == "G89" {
            // Fully modelled: no warning, strict reads it.
            assert!(!w.iter().any(|w| w.word == code), "{w:?}");
            continue;
        }
        let named = w.iter().find(|w| w.word == code).unwrap();
        assert_eq!(named.line, 2, "{code}");
        let (line, message) = strict_error(&text);
        assert_eq!(line, 2);
        assert!(message.starts_with(code), "{message}");
    }
    // G87 back boring: rapid down to R below the part, feed up to Z, rapid to the initial Z.
    let (p, w) = lenient("G0 Z10\nG87 X1 Y1 R-20 Z-5 Q1 F100\nG80");
    let up = vec![
        ([1.0, 1.0, 10.0], true),
        ([1.0, 1.0, -20.0], true),
        ([1.0, 1.0, -5.0], false),
        ([1.0, 1.0, 10.0], true),
    ];
    assert_eq!(path_of(&p, 2), up);
    assert!(
        w.iter()
            .any(|w| w.word == "G87" && w.message.contains("shift"))
    );
    // The old subset still refuses them.
    assert!(
        matches!(parse("G84 X1 Z-1 R1 F10"), Err(Error::UnsupportedCode { ref code, .. }) if code == "G84")
    );
}

#[test]
fn fusion_style_drill_and_tap_reads() {
    // Fusion 360's Fanuc post: tapping as G98 G84 with R and F, modal holes, G80.
    let text = "%\nO1001 (DRILL AND TAP)\nG90 G94 G17 G21\nT3 M6\nS600 M3\nG54 G0 X10. Y10.\n\
                G43 Z15. H3 M8\nG0 Z5.\nG98 G84 X10. Y10. Z-12. R5. F720.\nX30.\nG80\nM30\n%";
    let (p, w) = lenient(text);
    let feeds: Vec<[f64; 3]> = p
        .blocks
        .iter()
        .filter(|b| b.feed != Feed::Rapid)
        .map(|b| b.end.xyz)
        .collect();
    assert_eq!(
        feeds,
        vec![
            [10.0, 10.0, -12.0],
            [10.0, 10.0, 5.0],
            [30.0, 10.0, -12.0],
            [30.0, 10.0, 5.0]
        ]
    );
    assert_eq!(p.blocks.last().unwrap().end.xyz, [30.0, 10.0, 5.0]);
    assert!(w.iter().any(|w| w.word == "G84" && w.line == 9));
}

#[test]
fn pecks_feed_to_the_depths_linuxcnc_prints() {
    // rs274 (LinuxCNC 2.9) prints these feed ends for the same lines (tests/gcode_oracle).
    let feeds = |text: &str| -> Vec<f64> {
        let (p, _) = lenient(text);
        p.blocks
            .iter()
            .filter(|b| b.feed != Feed::Rapid)
            .map(|b| b.end.xyz[2])
            .collect()
    };
    assert_eq!(
        feeds("G0 Z3\nG83 X5 Y5 Z-10 R2 Q3 F100"),
        vec![-1.0, -4.0, -7.0, -10.0]
    );
    assert_eq!(
        feeds("G0 Z3\nG73 X7 Y1 Z-5 R2 Q2 F100"),
        vec![0.0, -2.0, -4.0, -5.0]
    );
    // G83 rapids out to R between pecks and back down to 0.254 mm above the last depth.
    let (p, w) = lenient("G0 Z3\nG83 X5 Y5 Z-10 R2 Q3 F100");
    let rapids: Vec<f64> = p.blocks[2..]
        .iter()
        .filter(|b| b.feed == Feed::Rapid)
        .map(|b| b.end.xyz[2])
        .collect();
    assert!(
        (rapids[1] - 2.0).abs() < 1e-12 && (rapids[2] - -0.746).abs() < 1e-12,
        "{rapids:?}"
    );
    assert!(
        w.iter()
            .any(|w| w.word == "G83" && w.message.contains("0.254"))
    );
    let e = parse_with("G83 X5 Z-10 R2 Q-1 F100", &ReadOptions::default()).unwrap_err();
    assert!(matches!(e, Error::Gcode { line: 1, .. }), "{e:?}");
}

#[test]
fn a_hole_from_below_the_r_plane_rises_to_it_before_moving_across() {
    // LinuxCNC's preliminary motion: from Z1, below R2, up to R first, then across.
    let (p, _) = lenient("G0 X0 Y0 Z1\nG99 G81 X5 Y5 Z-3 R2 F100\nG80");
    let want = vec![
        ([0.0, 0.0, 2.0], true),
        ([5.0, 5.0, 2.0], true),
        ([5.0, 5.0, -3.0], false),
        ([5.0, 5.0, 2.0], true),
    ];
    assert_eq!(path_of(&p, 2), want);
}
