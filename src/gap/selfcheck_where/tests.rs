//! Unit tests of `crate::gap::selfcheck_where`: the literal and the loose reading of `where`
//! on a hand-made move (start, stop, dwell, restart the other way) with hand-made spans.

use super::*;

fn ev(v: &[(usize, &str)]) -> Vec<(usize, String)> {
    v.iter().map(|(i, l)| (*i, l.to_string())).collect()
}

/// Literal events: reversals (friction also at the starts of an axis that never reverses); a
/// play also at its first start when the first move takes up at least a fifth of the play.
#[test]
fn acting_events_per_effect() {
    let events = ev(&[
        (49, "X start"),
        (1751, "X stop"),
        (4570, "X reversal"),
        (7000, "X stop"),
        (7500, "X start"),
    ]);
    assert_eq!(acting_events(&events, true, 0.0), [4570]);
    assert_eq!(acting_events(&events, false, 0.5), [49, 4570]);
    assert_eq!(acting_events(&events, false, 0.1), [4570]);
    // a rising Z: friction acts where it starts
    let z = ev(&[(0, "Z start"), (900, "Z stop"), (1200, "Z start")]);
    assert_eq!(acting_events(&z, true, 0.0), [0, 1200]);
    assert_eq!(acting_events(&z, false, 0.5), [0]);
}

fn servo() -> Vec<ServoAxis> {
    let axis = ServoAxis {
        kv: 40.0,
        kff: 0.5,
        kp_v: Some(480.0),
        ti_v: Some(0.012),
        tc: Some(0.0006),
    };
    vec![axis.clone(), axis]
}

/// X: rest, +20 mm at 20 mm/s, dwell, −20 mm back, rest; Y stands still.
fn command() -> Vec<Vec<f64>> {
    let mut x = vec![100.0; 200];
    x.extend((1..=1000).map(|i| 100.0 + 0.02 * i as f64));
    x.extend(vec![120.0; 400]);
    x.extend((1..=1000).map(|i| 120.0 - 0.02 * i as f64));
    x.extend(vec![100.0; 400]);
    let n = x.len();
    vec![x, vec![50.0; n]]
}

fn span(axis: &str, start: usize, end: usize) -> Span {
    Span {
        start,
        end,
        share: 0.5,
        label: String::new(),
        axis: axis.to_string(),
        line: None,
    }
}

/// A span that starts at the restart after the dwell is right on both readings; one that
/// starts at the stop before it is right on the loose reading only; a span on the still Y axis
/// is wrong on both; the first start counts for a play only when the first move takes up its
/// slack, and for friction on an axis that reverses only on the loose reading.
#[test]
fn literal_and_loose_where() {
    let cmd = command();
    let names = vec!["X".to_string(), "Y".to_string()];
    let events = axis_events(&cmd, 0, "X");
    let at = |label: &str| {
        events
            .iter()
            .find(|(_, l)| l.ends_with(label))
            .map(|e| e.0)
            .unwrap()
    };
    let (start, stop, reversal) = (at("start"), at("stop"), at("reversal"));
    assert!(start < stop && stop < reversal, "{events:?}");
    let judge =
        |truth: &Truth, s: Span| check_where(&servo(), truth, &cmd, 0.001, &names, &[s]).unwrap();
    let both = WhereCheck {
        loose: true,
        literal: true,
    };
    let loose_only = WhereCheck {
        loose: true,
        literal: false,
    };
    let neither = WhereCheck {
        loose: false,
        literal: false,
    };
    let play_ahead = Truth::BacklashAt(vec![0.02, 0.0], vec![1.0, 0.0]);
    let play_in_contact = Truth::BacklashAt(vec![0.02, 0.0], vec![-1.0, 0.0]);
    let friction = Truth::Friction(vec![300.0, 0.0]);
    assert_eq!(
        judge(&play_ahead, span("X", reversal, reversal + 900)),
        both
    );
    assert_eq!(
        judge(&play_ahead, span("X", stop, reversal - 1)),
        loose_only
    );
    assert_eq!(judge(&friction, span("X", stop, reversal - 1)), loose_only);
    assert_eq!(judge(&friction, span("X", reversal, reversal + 900)), both);
    assert_eq!(judge(&friction, span("X", start, stop - 1)), loose_only);
    assert_eq!(
        judge(&play_ahead, span("Y", reversal, reversal + 900)),
        neither
    );
    assert_eq!(judge(&play_ahead, span("X", start, stop - 1)), both);
    assert_eq!(
        judge(&play_in_contact, span("X", start, stop - 1)),
        loose_only
    );
    // a span that begins mid-move, well after the reversal, is wrong on both readings
    assert_eq!(
        judge(&play_ahead, span("X", reversal + 300, reversal + 900)),
        neither
    );
    assert!(
        check_where(
            &servo(),
            &Truth::Scale(vec![1e-4, 0.0]),
            &cmd,
            0.001,
            &names,
            &[]
        )
        .is_none()
    );
}
