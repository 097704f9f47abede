//! Tests of the reader's path-control codes (`super`): what each code makes of the blocks'
//! ends, the words they take, and that the readers which do not model them answer as before.

use crate::motion::error::Error;
use crate::motion::gcode::{ReadOptions, parse, parse_modes, parse_with};
use crate::motion::path_control::{BlockEnd, PathControl};

fn lenient(text: &str) -> (PathControl, Vec<String>) {
    let (_, control, warnings) = parse_modes(text, &ReadOptions::default()).unwrap();
    (control, warnings.iter().map(ToString::to_string).collect())
}

fn strict(text: &str) -> Result<PathControl, Error> {
    let options = ReadOptions {
        strict: true,
        ..ReadOptions::default()
    };
    parse_modes(text, &options).map(|(_, c, _)| c)
}

#[test]
fn each_code_sets_how_the_blocks_end() {
    use BlockEnd::{Blend, Continuous, Stop};
    let (c, w) = lenient(
        "G1 X1 F100\nG61\nX2\nX3\nG64\nX4\nG9 X5\nX6\nG61.1 X7\nG64 P0.05\nX8\nG64 P0\nX9\n\
         G20\nG64 P0.002\nX1\nG21 G08 P0\nX2\nG64 P0.1\nX3\nG08 P1\nX4\nG05.1 Q0\nX5\nG05.1 Q1\nX6\n",
    );
    let ends: Vec<BlockEnd> = [1, 3, 4, 6, 7, 8, 9, 11, 13, 16, 18, 20, 22, 24, 26]
        .iter()
        .map(|&l| c.end_of(l))
        .collect();
    let inch = Blend {
        tolerance_mm: 0.002 * 25.4,
    };
    assert_eq!(
        ends,
        [
            Continuous,
            Stop,
            Stop,
            Continuous,
            Stop,
            Continuous,
            Stop,
            Blend { tolerance_mm: 0.05 },
            Continuous,
            inch,
            Stop,
            Stop,
            Blend { tolerance_mm: 0.1 },
            Stop,
            Blend { tolerance_mm: 0.1 },
        ]
    );
    // Look-ahead off is read with a warning; look-ahead on, G61, G9 and G64 P without one.
    assert_eq!(w.len(), 2, "{w:#?}");
    assert!(
        w[0].starts_with("line 17: G8 P0: look-ahead off is read as a stop"),
        "{w:#?}"
    );
    assert!(w[1].starts_with("line 23: G5.1 Q0:"), "{w:#?}");
    assert!(
        lenient("G61\n").0.is_continuous(),
        "a mode without blocks sets no end"
    );
}

#[test]
fn the_words_of_the_codes_are_theirs() {
    // G64's P is its tolerance and G05.1's R its condition level: neither is "not used by
    // the motion" nor an arc radius; G64's Q (LinuxCNC's naive-CAM merge) is named.
    let (_, w) = lenient("G64 P0.01\nG05.1 Q1 R5\nG08 P1\nG1 X1 F100\n");
    assert_eq!(w.len(), 1, "{w:#?}");
    assert!(
        w[0].starts_with("line 2: R5: G5.1 R (machining condition level)"),
        "{w:#?}"
    );
    let (_, w) = lenient("G64 P0.01 Q0.005\nG1 X1 F100\n");
    assert!(
        w[0].starts_with("line 1: Q0.005: G64 Q (LinuxCNC's naive-CAM tolerance)"),
        "{w:#?}"
    );
}

#[test]
fn bad_words_are_refused_with_what_to_write() {
    let gcode = |r: Result<PathControl, Error>| match r {
        Err(Error::Gcode { line, message }) => (line, message),
        other => panic!("{other:?}"),
    };
    let (line, m) = gcode(strict("G1 X1 F100\nG64 P-0.1\n"));
    assert_eq!(
        (line, m.as_str()),
        (2, "G64 P (blending tolerance) must be >= 0")
    );
    let (_, m) = gcode(strict("G8\n"));
    assert_eq!(m, "G8 needs P1 (look-ahead on) or P0 (off)");
    let (_, m) = gcode(strict("G05.1 Q2\n"));
    assert_eq!(m, "G5.1 needs Q1 (look-ahead on) or Q0 (off)");
    // Strict refuses what is not modelled faithfully: look-ahead off, G64 Q.
    let (_, m) = gcode(strict("G08 P0\n"));
    assert!(m.contains("refused because \"strict\" is true"), "{m}");
    assert!(strict("G64 P0.1 Q0.1\n").is_err());
    assert!(strict("G61\nG9 G1 X1 F100\nG64 P0.1\nG05.1 Q1\nG08 P1\n").is_ok());
}

#[test]
fn readers_that_plan_in_the_look_ahead_answer_as_before() {
    // parse_with (the compensated programs' reader) keeps G61/G61.1/G64 as warnings and the
    // codes it never read as unsupported; parse (the legacy subset) refuses them all.
    let (_, w) = parse_with("G61\nG64 P0.01\nG1 X1 F100\n", &ReadOptions::default()).unwrap();
    let w: Vec<String> = w.iter().map(ToString::to_string).collect();
    assert!(
        w[0].contains("G61: path-control mode is not modelled"),
        "{w:#?}"
    );
    assert!(
        w.iter()
            .any(|x| x.contains("P0.01: not used by the motion")),
        "{w:#?}"
    );
    for code in ["G9 G1 X1 F100", "G05.1 Q1", "G08 P1"] {
        let e = parse_with(code, &ReadOptions::default()).unwrap_err();
        assert!(
            matches!(e, Error::UnsupportedCode { line: 1, .. }),
            "{code}: {e:?}"
        );
    }
    for code in ["G61", "G61.1", "G64", "G9 G1 X1 F100", "G05.1 Q1", "G08 P1"] {
        let e = parse(code).unwrap_err();
        assert!(
            matches!(e, Error::UnsupportedCode { line: 1, .. }),
            "{code}: {e:?}"
        );
    }
}
