//! Cutter radius compensation against tool-centre paths worked out by hand (the oracle binary
//! holds it to LinuxCNC on generated contours), and what it refuses.

use crate::motion::error::Error;
use crate::motion::gcode::{Block, Feed, Motion, ReadOptions, parse_with};

fn with_tool(diameter_mm: f64) -> ReadOptions {
    let mut o = ReadOptions::default();
    o.tool_diameters_mm.insert(1, diameter_mm);
    o
}

/// (line, XY end, arc centre) of every move.
fn path(text: &str, o: &ReadOptions) -> Vec<(usize, [f64; 2], Option<[f64; 2]>)> {
    let (p, _) = parse_with(text, o).unwrap();
    p.blocks
        .iter()
        .filter(|b| !matches!(b.motion, Motion::Dwell { .. }))
        .map(|b: &Block| {
            let centre = match b.motion {
                Motion::Arc { center, .. } => Some([center[0], center[1]]),
                _ => None,
            };
            (b.line, [b.end.xyz[0], b.end.xyz[1]], centre)
        })
        .collect()
}

fn near(a: [f64; 2], b: [f64; 2]) -> bool {
    (a[0] - b[0]).abs() < 1e-9 && (a[1] - b[1]).abs() < 1e-9
}

fn refusal(text: &str, o: &ReadOptions) -> (usize, String) {
    match parse_with(text, o) {
        Err(Error::Gcode { line, message }) => (line, message),
        other => panic!("{text}: {other:?}"),
    }
}

#[test]
fn the_pocket_is_cut_by_the_tool_centre_3_mm_inside_its_walls() {
    let text = include_str!("../../../../tests/data/programs/pocket_finish.nc");
    let (p, w) = parse_with(text, &with_tool(6.0)).unwrap();
    let ends: Vec<(usize, [f64; 2])> = p
        .blocks
        .iter()
        .filter(|b| (9..=15).contains(&b.line))
        .map(|b| (b.line, [b.end.xyz[0], b.end.xyz[1]]))
        .collect();
    // The 30 x 20 pocket's walls, 3 mm in: inside corners trimmed, the entry ends at the
    // first corner, G40 leaves from the last tool position back to X15 Y10.
    let want = [
        (9, [27.0, 13.0]),
        (10, [27.0, 17.0]),
        (11, [3.0, 17.0]),
        (12, [3.0, 3.0]),
        (13, [27.0, 3.0]),
        (14, [27.0, 10.0]),
        (15, [15.0, 10.0]),
    ];
    assert_eq!(ends.len(), want.len(), "{ends:?}");
    for ((line, at), (l, xy)) in ends.iter().zip(want) {
        assert_eq!(*line, l);
        assert!(near(*at, xy), "line {l}: {at:?} != {xy:?}");
    }
    assert!(
        w.iter()
            .any(|w| w.word == "G41 D1" && w.message.contains("3 mm"))
    );
    // Without tool_diameters the programmed path is kept, with the warning of old.
    let (p, w) = parse_with(text, &ReadOptions::default()).unwrap();
    let last = p.blocks.iter().rfind(|b| b.line == 14).unwrap();
    assert!(near([last.end.xyz[0], last.end.xyz[1]], [30.0, 10.0]));
    assert!(
        w.iter()
            .any(|w| w.word == "G41" && w.message.contains("tool_diameters"))
    );
}

#[test]
fn an_outside_corner_gets_an_arc_round_it_and_an_inside_one_is_trimmed() {
    // G41 along +X then down -Y: a right turn with the tool on the left, outside.
    let outside = "G21 G17 G90\nG0 X-10 Y0\nG41 D1 G1 X0 Y0 F100\nX10\nY-10\nG40 X20 Y-20\nM2";
    let p: Vec<_> = path(outside, &with_tool(2.0))
        .into_iter()
        .filter(|m| m.0 >= 3)
        .collect();
    let want = [
        (3, [0.0, 1.0], None),
        (4, [10.0, 1.0], None),
        (5, [11.0, 0.0], Some([10.0, 0.0])),
        (5, [11.0, -10.0], None),
        (6, [20.0, -20.0], None),
    ];
    assert_eq!(p.len(), want.len(), "{p:?}");
    for (got, want) in p.iter().zip(want) {
        assert_eq!(
            (got.0, got.2.is_some()),
            (want.0, want.2.is_some()),
            "{p:?}"
        );
        assert!(near(got.1, want.1), "{got:?} != {want:?}");
    }
    let (prog, _) = parse_with(outside, &with_tool(2.0)).unwrap();
    let arc = prog.blocks.iter().find(|b| b.line == 5).unwrap();
    match arc.motion {
        // Clockwise round the corner, a quarter turn.
        Motion::Arc { sweep_rad, .. } => {
            assert!((sweep_rad + std::f64::consts::FRAC_PI_2).abs() < 1e-12)
        }
        m => panic!("{m:?}"),
    }
    // The exit starts where the tool is, not at the programmed corner.
    let exit = prog.blocks.iter().find(|b| b.line == 6).unwrap();
    assert!(near([exit.start.xyz[0], exit.start.xyz[1]], [11.0, -10.0]));
    // G41 along +X then up +Y: a left turn, the tool inside: both moves end at (9, 1).
    let inside = "G0 X-10 Y0\nG41 D1 G1 X0 Y0 F100\nX10\nY10\nG40 X0 Y20\nM2";
    let p = path(inside, &with_tool(2.0));
    assert!(
        near(p[2].1, [9.0, 1.0]) && near(p[3].1, [9.0, 10.0]),
        "{p:?}"
    );
    // A negative diameter puts the tool on the other side (LinuxCNC): outside again.
    let p = path(inside, &with_tool(-2.0));
    assert!(p.iter().any(|m| m.2.is_some()), "{p:?}");
}

#[test]
fn the_tool_of_the_last_m6_is_used_without_d_and_g93_keeps_the_programmed_rate() {
    let mut o = with_tool(2.0);
    o.tool_diameters_mm.insert(7, 4.0);
    let text = "T7 M6\nG0 X-10 Y0\nG93\nG41 G1 X0 Y0 F6\nX10 F2\nG40 X20 F1\nM2";
    let (p, _) = parse_with(text, &o).unwrap();
    let first = &p.blocks[1];
    assert!(near([first.end.xyz[0], first.end.xyz[1]], [0.0, 2.0]));
    // 1/F min over the programmed 10 mm: 20 mm/min, kept on the compensated move.
    let second = p.blocks.iter().find(|b| b.line == 5).unwrap();
    assert_eq!(second.feed, Feed::PerMinute(20.0));
    // A tool number not in tool_diameters keeps the programmed path, named.
    let (p, w) = parse_with(&text.replace("T7", "T8"), &o).unwrap();
    assert!(near(
        [p.blocks[1].end.xyz[0], p.blocks[1].end.xyz[1]],
        [0.0, 0.0]
    ));
    assert!(
        w.iter()
            .any(|w| w.message.contains("no diameter given for tool 8"))
    );
}

#[test]
fn what_the_tool_cannot_follow_is_refused_with_a_sentence() {
    let o = with_tool(6.0);
    let cases = [
        // Entry shorter than the radius.
        (
            "G0 X0 Y0\nG41 D1 G1 X2 F100\nX20\nM2",
            2,
            "entry move is not greater",
        ),
        // An inside corner the tool does not fit into.
        (
            "G0 X-10 Y0\nG41 D1 G1 X0 F100\nX10\nY2\nX-5\nG40 X-10 Y-10\nM2",
            5,
            "does not fit",
        ),
        // An arc smaller than the tool, the tool inside it.
        (
            "G0 X-10 Y0\nG41 D1 G1 X0 F100\nG3 X4 Y0 I2 J0\nG40 X10\nM2",
            3,
            "does not fit inside this arc",
        ),
        // Another plane.
        (
            "G18\nG0 X-10 Y0\nG41 D1 G1 X0 F100\nM2",
            3,
            "XY plane (G17)",
        ),
        (
            "G0 X-10 Y0\nG41 D1 G1 X0 F100\nG18\nM2",
            3,
            "a plane other than G17",
        ),
        // Twice, a cycle, G28, a tool change, a stop under it.
        ("G0 X-10\nG41 D1 G1 X0 F9\nG42 D1 X9\nM2", 3, "already on"),
        (
            "G0 X-10\nG41 D1 G1 X0 F9\nG81 X5 Z-1 R1\nM2",
            3,
            "canned cycle",
        ),
        ("G0 X-10\nG41 D1 G1 X0 F9\nG28 X0\nM2", 3, "G28"),
        ("G0 X-10\nG41 D1 G1 X0 F9\nT2 M6\nM2", 3, "tool change"),
        ("G0 X-10\nG41 D1 G1 X0 F9\nM0\nM2", 3, "program stop"),
        ("G0 X-10\nG41 D1 G1 X0 F9\nG43 H1\nM2", 3, "tool length"),
        // An arc right after G40.
        (
            "G0 X-10\nG41 D1 G1 X0 F9\nX10\nG40 G2 X20 I5\nM2",
            4,
            "after G40 must be a straight line",
        ),
    ];
    for (text, line, says) in cases {
        let (l, message) = refusal(text, &o);
        assert_eq!(l, line, "{text}: {message}");
        assert!(message.contains(says), "{text}: {message}");
    }
    // strict refuses G41 that it would read without a diameter.
    let strict = ReadOptions {
        strict: true,
        ..ReadOptions::default()
    };
    let (l, m) = refusal("G0 X-10\nG41 G1 X0 F9\nM2", &strict);
    assert_eq!(l, 2);
    assert!(m.contains("tool_diameters"), "{m}");
}
