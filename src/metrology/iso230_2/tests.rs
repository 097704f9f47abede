//! Hand-computed ISO 230-2:2014 cases that pin each definition.

use super::*;

/// The hand table, deviations in µm per target (targets 0, 100, …, 400 mm), five cycles.
/// Each row is a mean m with a spread whose s is exact: {m−1, m−1, m, m+1, m+1} has
/// Σ(x − m)² = 4, so s = sqrt(4/4) = 1 with n − 1 (it would be 0.894 with n); the ±2 pattern
/// has s = 2; five equal values s = 0.
///
/// | target | x̄↑ | s↑ | x̄↓ | s↓ | B_i | 2s↑+2s↓+|B_i| | 4s↑ | 4s↓ | R_i | x̄_i |
/// |---|---|---|---|---|---|---|---|---|---|---|
/// |   0 |  2 | 1 | −1 | 1 | 3 |  7 | 4 | 4 |  7 |  0.5 |
/// | 100 |  4 | 1 |  0 | 2 | 4 | 10 | 4 | 8 | 10 |  2   |
/// | 200 |  1 | 0 | −3 | 1 | 4 |  6 | 0 | 4 |  6 | −1   |
/// | 300 | −1 | 2 | −4 | 1 | 3 |  9 | 8 | 4 |  9 | −2.5 |
/// | 400 |  3 | 1 |  1 | 2 | 2 |  8 | 4 | 8 |  8 |  2   |
///
/// Axis (µm): R↑ = max 4s↑ = 8, R↓ = 8, R = max R_i = 10 (so max(R↑, R↓) = 8 is wrong);
/// E↑ = 4 − (−1) = 5, E↓ = 1 − (−4) = 5, E over both = 4 − (−4) = 8 (one direction gives 5);
/// x̄ + 2s: ↑ 4, 6, 1, 3, 5; ↓ 1, 4, −1, −2, 5.  x̄ − 2s: ↑ 0, 2, 1, −5, 1; ↓ −3, −4, −5, −6, −3.
/// A↑ = 6 − (−5) = 11, A↓ = 5 − (−6) = 11, A = 6 − (−6) = 12;
/// M = 2 − (−2.5) = 4.5; B = max |B_i| = 4; B̄ = (3 + 4 + 4 + 3 + 2)/5 = 3.2.
pub(crate) fn hand_table() -> PositionTable {
    let um: [([f64; 5], [f64; 5]); 5] = [
        ([1., 3., 2., 1., 3.], [-2., 0., -1., -2., 0.]),
        ([3., 5., 4., 5., 3.], [-2., 2., 0., 2., -2.]),
        ([1., 1., 1., 1., 1.], [-4., -2., -3., -4., -2.]),
        ([-3., 1., -1., -3., 1.], [-5., -3., -4., -3., -5.]),
        ([2., 4., 3., 4., 2.], [-1., 3., 1., -1., 3.]),
    ];
    let targets: Vec<f64> = (0..5).map(|i| 100.0 * i as f64).collect();
    type Pick = fn(&([f64; 5], [f64; 5])) -> [f64; 5];
    let rows = |f: Pick| {
        um.iter()
            .zip(&targets)
            .map(|(r, &p)| f(r).iter().map(|d| p + d * 1e-3).collect())
            .collect()
    };
    PositionTable {
        forward_mm: rows(|r| r.0),
        backward_mm: rows(|r| r.1),
        targets_mm: targets,
    }
}

fn close(got: f64, want_um: f64) {
    assert!(
        (got - want_um * 1e-3).abs() < 1e-9,
        "got {} µm, want {want_um} µm",
        got * 1e3
    );
}

#[test]
fn hand_table_axis_figures() {
    let a = evaluate_table(&hand_table()).unwrap();
    close(a.r, 10.0);
    close(a.r_fwd, 8.0);
    close(a.r_bwd, 8.0);
    close(a.e, 8.0);
    close(a.e_fwd, 5.0);
    close(a.e_bwd, 5.0);
    close(a.a, 12.0);
    close(a.a_fwd, 11.0);
    close(a.a_bwd, 11.0);
    close(a.m, 4.5);
    close(a.b, 4.0);
    close(a.b_avg, 3.2);
    assert!(a.warnings.is_empty(), "{:?}", a.warnings);
}

#[test]
fn r_is_the_bidirectional_max_not_max_of_the_directions() {
    let a = evaluate_table(&hand_table()).unwrap();
    // The published-calculator shortcut would say 8 µm; the standard's R is 10 µm (T = 100).
    assert!((a.r - a.r_fwd.max(a.r_bwd)).abs() > 1.9e-3);
    close(a.targets[1].r, 10.0);
}

#[test]
fn e_and_a_are_taken_over_both_directions() {
    let a = evaluate_table(&hand_table()).unwrap();
    assert!(
        a.e > a.e_fwd.max(a.e_bwd) + 2.9e-3,
        "E from one direction is 5 µm, over both 8"
    );
    assert!(
        a.a > a.a_fwd.max(a.a_bwd) + 0.9e-3,
        "A over both is 12 µm, per direction 11"
    );
}

#[test]
fn hand_table_per_target_rows() {
    let a = evaluate_table(&hand_table()).unwrap();
    let want = [
        (2.0, 1.0, -1.0, 1.0, 3.0, 7.0, 0.5),
        (4.0, 1.0, 0.0, 2.0, 4.0, 10.0, 2.0),
        (1.0, 0.0, -3.0, 1.0, 4.0, 6.0, -1.0),
        (-1.0, 2.0, -4.0, 1.0, 3.0, 9.0, -2.5),
        (3.0, 1.0, 1.0, 2.0, 2.0, 8.0, 2.0),
    ];
    for (t, w) in a.targets.iter().zip(want) {
        close(t.mean_fwd, w.0);
        close(t.s_fwd, w.1);
        close(t.mean_bwd, w.2);
        close(t.s_bwd, w.3);
        close(t.reversal, w.4);
        close(t.r, w.5);
        close(t.mean, w.6);
        assert_eq!((t.n_fwd, t.n_bwd), (5, 5));
    }
}

#[test]
fn deviation_is_measured_minus_target() {
    // A machine that stops 3 µm short of every target going up (measured = P − 0.003) and
    // exactly on it going down has x̄↑ = −3 µm, B_i = −3 µm, B̄ = −3 µm (signed), B = 3 µm.
    let targets: Vec<f64> = vec![0.0, 10.0, 20.0, 30.0, 40.0];
    let jitter = [0.0, 1e-3, -1e-3, 1e-3, -1e-3];
    let table = PositionTable {
        forward_mm: targets
            .iter()
            .map(|p| jitter.iter().map(|j| p - 3e-3 + j).collect())
            .collect(),
        backward_mm: targets
            .iter()
            .map(|p| jitter.iter().map(|j| p + j).collect())
            .collect(),
        targets_mm: targets,
    };
    let a = evaluate_table(&table).unwrap();
    close(a.targets[0].mean_fwd, -3.0);
    close(a.b_avg, -3.0);
    close(a.b, 3.0);
    close(a.e, 3.0);
    // s of {0, 1, −1, 1, −1} µm: Σx² = 4, mean 0, s = 1 µm; R_i = 2 + 2 + 3 = 7 µm.
    close(a.r, 7.0);
}

#[test]
fn few_targets_and_cycles_warn_but_too_few_refuse() {
    let mut t = hand_table();
    t.targets_mm.truncate(3);
    t.forward_mm.truncate(3);
    t.backward_mm.truncate(3);
    for row in t.forward_mm.iter_mut().chain(t.backward_mm.iter_mut()) {
        row.truncate(3);
    }
    let a = evaluate_table(&t).unwrap();
    assert_eq!(a.warnings.len(), 2, "{:?}", a.warnings);
    let mut one = t.clone();
    one.forward_mm[1].truncate(1);
    assert!(matches!(evaluate_table(&one), Err(Error::TooFew { .. })));
    let mut single = t.clone();
    single.targets_mm.truncate(1);
    single.forward_mm.truncate(1);
    single.backward_mm.truncate(1);
    assert!(matches!(evaluate_table(&single), Err(Error::TooFew { .. })));
}

#[test]
fn bad_tables_are_refused_naming_the_field() {
    let mut t = hand_table();
    t.backward_mm.pop();
    let e = evaluate_table(&t).unwrap_err();
    assert!(e.to_string().starts_with("backward has 4 entries"), "{e}");
    let mut t = hand_table();
    t.forward_mm[2][3] = f64::NAN;
    assert_eq!(
        evaluate_table(&t).unwrap_err().to_string(),
        "forward[2][3] is not a finite number; send finite mm"
    );
    let mut t = hand_table();
    t.targets_mm[4] = 0.0;
    assert!(matches!(
        evaluate_table(&t),
        Err(Error::DuplicateTarget {
            first: 0,
            second: 4,
            ..
        })
    ));
}

#[test]
fn unequal_cycles_use_each_targets_own_n() {
    let mut t = hand_table();
    // Drop the last cycle (3 µm) of target 0 going up: {1, 3, 2, 1} µm, mean 1.75,
    // Σ(x − 1.75)² = 0.5625 + 1.5625 + 0.0625 + 0.5625 = 2.75, s = sqrt(2.75/3).
    t.forward_mm[0].pop();
    let a = evaluate_table(&t).unwrap();
    close(a.targets[0].mean_fwd, 1.75);
    close(a.targets[0].s_fwd, (2.75_f64 / 3.0).sqrt());
    assert_eq!(a.targets[0].n_fwd, 4);
    assert!(
        a.warnings.iter().any(|w| w.contains("unequal")),
        "{:?}",
        a.warnings
    );
}
