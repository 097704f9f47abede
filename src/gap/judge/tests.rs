//! Unit tests of `crate::gap::judge`.

use super::*;

#[test]
fn named_when_the_steps_remove_most_of_the_gap_above_the_noise() {
    // 1,000 samples of σ̂ = 1: floor 1,000; stored 11,000 (excess 10,000)
    let j = |left: f64, step: bool| judge(11_000.0, left, 1.0, 1000, step, 0.5, 1.0, None, 0.4);
    assert_eq!(j(3_000.0, true), (Outcome::Named, 0.2));
    assert_eq!(j(6_000.0, true), (Outcome::Named, 0.5));
    assert_eq!(j(6_001.0, true).0, Outcome::Unexplained);
    assert_eq!(j(11_000.0, false), (Outcome::Unexplained, 1.0));
    // below the floor: nothing left
    assert_eq!(j(900.0, true), (Outcome::Named, 0.0));
}

#[test]
fn a_gap_at_the_noise_is_none_or_the_step_never_unexplained() {
    let j = |stored: f64, step: bool| judge(stored, stored, 1.0, 1000, step, 0.5, 1.0, None, 0.4);
    assert_eq!(j(1_500.0, false).0, Outcome::None);
    assert_eq!(j(1_500.0, true).0, Outcome::Named);
    assert_eq!(j(900.0, false), (Outcome::None, 1.0));
    assert_eq!(j(2_000.0, false).0, Outcome::Unexplained);
}

#[test]
fn a_step_that_does_not_carry_over_to_the_validation_block_is_unexplained() {
    // the steps remove 90 % of the main block's held-out gap above the noise
    let j =
        |v: Option<f64>, step: bool| judge(11_000.0, 2_000.0, 1.0, 1000, step, 0.8, 1.0, v, 0.4);
    assert_eq!(j(None, true), (Outcome::Named, 0.1));
    assert_eq!(j(Some(0.1), true), (Outcome::Named, 0.1));
    assert_eq!(j(Some(0.4), true).0, Outcome::Named);
    assert_eq!(j(Some(0.41), true), (Outcome::Unexplained, 0.1));
    // worse than the stored simulation on the validation block
    assert_eq!(j(Some(2.5), true).0, Outcome::Unexplained);
    // no step: nothing to carry over
    assert_eq!(j(Some(2.5), false).0, Outcome::None);
    assert_eq!(
        judge(900.0, 900.0, 1.0, 1000, false, 0.8, 1.0, Some(3.0), 0.4).0,
        Outcome::None
    );
}

#[test]
fn validation_share_is_the_gap_above_the_noise_left_or_none_at_the_noise() {
    let n = 1000;
    // a ±0.01 mm alternating noise (σ̂ = 0.01) on two axes; a 0.05 mm offset on X
    let noise: Vec<f64> = (0..n)
        .map(|i| if i % 2 == 0 { 0.01 } else { -0.01 })
        .collect();
    let measured = vec![
        noise.iter().map(|e| 0.05 + e).collect::<Vec<_>>(),
        noise.clone(),
    ];
    let zero = vec![vec![0.0; n]; 2];
    let half = vec![vec![0.025; n], vec![0.0; n]];
    let exact = vec![vec![0.05; n], vec![0.0; n]];
    let wrong = vec![vec![-0.05; n], vec![0.0; n]];
    let s = |after: &Vec<Vec<f64>>| validation_share(&measured, &zero, after, 0.01, 1.0);
    // stored: 1000·(0.05² + 0.01²) + 1000·0.01² = 2.7; floor 2000·0.01² = 0.2; excess 2.5
    assert!((s(&exact).unwrap() - 0.0).abs() < 1e-9);
    assert!((s(&half).unwrap() - 0.25).abs() < 1e-9);
    assert!((s(&wrong).unwrap() - 4.0).abs() < 1e-9);
    // a gap at the noise tests nothing
    assert_eq!(validation_share(&measured, &exact, &zero, 0.01, 1.0), None);
}

/// The noise of all axes is the sum of each axis' own: an axis without noise (a Z column
/// copied from the command) does not pull the others' estimate down, as one median over the
/// pooled second differences did (to about 0.55 of it with one axis in three noise-free).
#[test]
fn a_noise_free_axis_does_not_lower_the_others_noise() {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let mut rng = rand::rngs::StdRng::seed_from_u64(4);
    let normal = Normal::new(0.0, 0.0003).unwrap();
    let noisy = |rng: &mut rand::rngs::StdRng| -> Vec<f64> {
        (0..20_000).map(|_| normal.sample(rng)).collect()
    };
    let r = vec![noisy(&mut rng), noisy(&mut rng), vec![0.0; 20_000]];
    let total = 3.0 * noise_sigma(&r).powi(2);
    let want = 2.0 * 0.0003f64.powi(2);
    assert!(
        (total / want - 1.0).abs() < 0.03,
        "d·σ̂² = {total}, want {want}"
    );
}
