//! The verdict of a motion diagnosis (issue 23, item 2): a library effect, `none`, or
//! `unexplained` — "none of these" is an answer.
//!
//! The steps (forward selection) say which effects remove part of the gap on held-out data;
//! the verdict asks whether together they remove *most* of it. The held-out squared gap holds
//! the measurement noise, which no effect can remove, so the share is taken of the gap above
//! the noise floor `n·d·σ̂²` (n samples, d axes, σ̂ the noise estimate).

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

/// The verdict and the held-out share of the gap above the noise that the steps leave
/// (`heldout_share`, 0..1; 1 without steps or without a gap above the noise).
///
/// Formula: `floor = samples·σ̂²`, `share = clamp((held_left − floor)/(held_stored − floor))`;
/// `Unexplained` when `held_stored − floor ≥ min_excess_noise·floor` and
/// `1 − share < min_explained`; else `Named` with a step, `None` without.
/// `held_stored` and `held_left` are the held-out sums of squares (mm²) of the stored
/// simulation and of the steps, `samples` = n·d. Reference: blocked cross-validation as in
/// [`crate::gap::motion::diagnose_motion`]. Known bad cases: a noise estimate far off (a
/// quantized or filtered log) moves the floor and with it the line between the outcomes.
pub fn judge(
    held_stored: f64,
    held_left: f64,
    noise_mm: f64,
    samples: usize,
    has_step: bool,
    min_explained: f64,
    min_excess_noise: f64,
) -> (Outcome, f64) {
    let floor = samples as f64 * noise_mm * noise_mm;
    let excess = held_stored - floor;
    let share = if excess > 0.0 {
        ((held_left - floor) / excess).clamp(0.0, 1.0)
    } else {
        1.0
    };
    let beyond_noise = excess > 0.0 && excess >= min_excess_noise * floor;
    let outcome = if beyond_noise && 1.0 - share < min_explained {
        Outcome::Unexplained
    } else if has_step {
        Outcome::Named
    } else {
        Outcome::None
    };
    (outcome, share)
}

#[cfg(test)]
mod tests;
