//! The verdict of a motion diagnosis (issue 23, item 2): a library effect, `none`, or
//! `unexplained` — "none of these" is an answer.
//!
//! The steps (forward selection) say which effects remove part of the gap on held-out data;
//! the verdict asks whether together they remove *most* of it. The held-out squared gap holds
//! the measurement noise, which no effect can remove, so the share is taken of the gap above
//! the noise floor `n·d·σ̂²` (n samples, d axes, σ̂ the noise estimate).
//!
//! A library effect that fits is not always the right model: stick-slip fits as Coulomb
//! friction, a loose gib or a resonance as a gain mismatch, a sensor's lost counts as a
//! thermal drift, each removing most of the gap *in the block it was fitted on*. A wrong model
//! does not carry over to other conditions (another program, the other direction, other
//! speeds); a right one does. So when a validation block is given, the steps fitted on the
//! main block alone predict it, and the share of its gap above the noise that they leave
//! ([`validation_share`]) must also be small: above `max_validation_left` the verdict is
//! `unexplained`. Thermal drift is exempt as the verdict: it is a function of the time since
//! a warm-up the service cannot see, so a block recorded later starts from an unknown state.

/// What the verdict names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// The first step's effect.
    Named,
    /// Nothing beyond the noise.
    None,
    /// A gap above the noise that the steps do not explain.
    Unexplained,
}

/// Share of a validation block's squared gap above the noise that a prediction leaves, 0..;
/// `None` when that gap is not above the noise.
///
/// Formula: with `r₀ = measured − before` (stored simulation), `r₁ = measured − after` (the
/// steps fitted on the main block only), `floor = n·d·σ̂ᵥ²` (σ̂ᵥ the noise estimate of `r₀`,
/// `noise_mm`): `share = (Σr₁² − floor)/(Σr₀² − floor)` when `Σr₀² − floor ≥
/// min_excess_noise·floor`. Not clamped: above 1 the steps make the prediction worse. Units:
/// columns per axis in mm. Reference: validation on data from other conditions (Roberts et al.
/// 2017, Ecography 40, "extrapolation" blocks). Bad cases: a validation block that hardly
/// excites the effect (its gap at the noise) tests nothing and answers `None`.
pub fn validation_share(
    measured: &[Vec<f64>],
    before: &[Vec<f64>],
    after: &[Vec<f64>],
    noise_mm: f64,
    min_excess_noise: f64,
) -> Option<f64> {
    let ss = |p: &[Vec<f64>]| -> f64 {
        measured
            .iter()
            .zip(p)
            .flat_map(|(m, p)| m.iter().zip(p).map(|(m, p)| (m - p) * (m - p)))
            .sum()
    };
    let samples: usize = measured.iter().map(Vec::len).sum();
    let floor = samples as f64 * noise_mm * noise_mm;
    let excess = ss(before) - floor;
    (excess > 0.0 && excess >= min_excess_noise * floor).then(|| (ss(after) - floor) / excess)
}

/// [`validation_share`] with σ̂ᵥ from [`noise_sigma`] of `measured − before` (per axis
/// columns, mm).
pub fn validation_left(
    measured: &[Vec<f64>],
    before: &[Vec<f64>],
    after: &[Vec<f64>],
    min_excess_noise: f64,
) -> Option<f64> {
    let r0: Vec<Vec<f64>> = (measured.iter().zip(before))
        .map(|(m, b)| m.iter().zip(b).map(|(m, b)| m - b).collect())
        .collect();
    validation_share(measured, before, after, noise_sigma(&r0), min_excess_noise)
}

/// The verdict and the held-out share of the gap above the noise that the steps leave
/// (`heldout_share`, 0..1; 1 without steps or without a gap above the noise).
///
/// Formula: `floor = samples·σ̂²`, `share = clamp((held_left − floor)/(held_stored − floor))`;
/// `Unexplained` when `held_stored − floor ≥ min_excess_noise·floor` and
/// `1 − share < min_explained`, or with a step and a `validation` share
/// ([`validation_share`]) above `max_validation_left`; else `Named` with a step, `None`
/// without.
/// `held_stored` and `held_left` are the held-out sums of squares (mm²) of the stored
/// simulation and of the steps, `samples` = n·d. Reference: blocked cross-validation as in
/// [`crate::gap::motion::diagnose_motion`]. Known bad cases: a noise estimate far off (a
/// quantized or filtered log) moves the floor and with it the line between the outcomes.
#[allow(clippy::too_many_arguments)]
pub fn judge(
    held_stored: f64,
    held_left: f64,
    noise_mm: f64,
    samples: usize,
    has_step: bool,
    min_explained: f64,
    min_excess_noise: f64,
    validation: Option<f64>,
    max_validation_left: f64,
) -> (Outcome, f64) {
    let floor = samples as f64 * noise_mm * noise_mm;
    let excess = held_stored - floor;
    let share = if excess > 0.0 {
        ((held_left - floor) / excess).clamp(0.0, 1.0)
    } else {
        1.0
    };
    let beyond_noise = excess > 0.0 && excess >= min_excess_noise * floor;
    let carries_over = validation.is_none_or(|v| v <= max_validation_left);
    let outcome = if (beyond_noise && 1.0 - share < min_explained) || (has_step && !carries_over) {
        Outcome::Unexplained
    } else if has_step {
        Outcome::Named
    } else {
        Outcome::None
    };
    (outcome, share)
}

/// Noise standard deviation of a residual (mm), per axis then pooled as
/// `σ̂ = √(mean_k σ̂_k²)`, so that `n·d·σ̂²` is the noise of all `d` axes, `n·Σ σ̂_k²`, even when
/// one axis is noise-free (a commanded-only Z). Per axis `σ̂_k = 1.4826·median|Δ²r| / √6`:
/// white noise of variance σ² has second differences of variance 6σ², while the smooth part of
/// the gap barely contributes; never below half the RMS-based estimate `rms(Δ²r)/√6`
/// (quantized data make the median of |Δ²r| nearly 0). Bad cases: gaps with many
/// steps per sample inflate it.
pub fn noise_sigma(residual: &[Vec<f64>]) -> f64 {
    let per_axis: Vec<f64> = residual
        .iter()
        .filter(|r| r.len() >= 3)
        .map(|r| axis_noise(r))
        .collect();
    if per_axis.is_empty() {
        return 0.0;
    }
    (per_axis.iter().map(|s| s * s).sum::<f64>() / per_axis.len() as f64).sqrt()
}

/// [`noise_sigma`] of one axis' residual (at least 3 samples), mm.
fn axis_noise(r: &[f64]) -> f64 {
    let mut d2: Vec<f64> = r
        .windows(3)
        .map(|w| (w[0] - 2.0 * w[1] + w[2]).abs())
        .collect();
    let rms = (d2.iter().map(|d| d * d).sum::<f64>() / d2.len() as f64).sqrt() / 6f64.sqrt();
    let mid = d2.len() / 2;
    let (_, m, _) = d2.select_nth_unstable_by(mid, f64::total_cmp);
    let robust = 1.4826 * *m / 6f64.sqrt();
    // quantized measurements (most second differences exactly or nearly 0) make the median
    // useless: never report less than half the RMS-based estimate (steps and spikes of a real
    // gap inflate the RMS one, hence only half of it)
    robust.max(0.5 * rms)
}

#[cfg(test)]
mod tests;
