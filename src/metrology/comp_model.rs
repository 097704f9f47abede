//! The fitted pitch-error model of an axis from its ISO 230-2 run: a linear scale error, a
//! backlash (the reversal split half to each direction) and, on request, a cyclic error of a
//! given or fitted pitch, by weighted least squares on the per-target mean deviations.
//!
//! Why a model next to the per-target means: a table of means carries each target's noise
//! (s_i/√n) into the controller and says nothing between targets but straight lines; a
//! model with three to six parameters averages the noise over the whole run and can be
//! sampled on whatever spacing the controller wants. Its price is what it leaves out (a bend
//! of the guideway, a reversal that changes along the axis): the residual it reports says how
//! much. Written here: a five-column weighted least-squares problem on the crate's
//! [`crate::numeric::lsq`] and one Brent search over the pitch.

use std::f64::consts::PI;

use super::error::Error;
use super::iso230_2::Axis230_2;
use crate::numeric::brent::minimize_on_grid;
use crate::numeric::lsq::LeastSquares;

/// Whether the model has a cyclic (periodic) term, and how its pitch is found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Cyclic {
    /// No cyclic term: scale and backlash only.
    Off,
    /// A cyclic term of this pitch, mm (e.g. the ball screw's lead), amplitude and phase fitted.
    Pitch(f64),
    /// A cyclic term whose pitch is fitted too, between twice the widest gap between targets
    /// and twice the run's range.
    Fit,
}

/// A fitted cyclic term `sin_mm · sin(2πP/pitch) + cos_mm · cos(2πP/pitch)`, P the axis
/// position in mm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CyclicTerm {
    /// Pitch (period along the axis), mm.
    pub pitch_mm: f64,
    /// Coefficient of sin(2πP/pitch), mm.
    pub sin_mm: f64,
    /// Coefficient of cos(2πP/pitch), mm.
    pub cos_mm: f64,
}

impl CyclicTerm {
    /// Amplitude `sqrt(sin² + cos²)`, mm.
    pub fn amplitude_mm(&self) -> f64 {
        self.sin_mm.hypot(self.cos_mm)
    }

    /// The term at position `p_mm`, mm.
    pub fn at(&self, p_mm: f64) -> f64 {
        let a = 2.0 * PI * p_mm / self.pitch_mm;
        self.sin_mm * a.sin() + self.cos_mm * a.cos()
    }
}

/// The systematic positional deviation (measured − target) of an axis as a model, mm:
/// `e(P, ↑) = offset + scale·(P − reference) + backlash/2 + cyclic(P)` and
/// `e(P, ↓) = … − backlash/2 …`.
#[derive(Clone, Debug, PartialEq)]
pub struct PitchModel {
    /// Position the scale term is taken about (the middle of the run's range), mm.
    pub reference_mm: f64,
    /// Mean bidirectional deviation at the reference position, mm.
    pub offset_mm: f64,
    /// Scale (linear positioning) error, mm per mm (× 10⁶ for µm/m).
    pub scale: f64,
    /// Backlash = the fitted reversal e(P, ↑) − e(P, ↓), mm, signed; with equal cycles at every
    /// target and direction it is the mean reversal value B̄ of ISO 230-2:2014 §3.12.
    pub backlash_mm: f64,
    /// The cyclic term, when asked for.
    pub cyclic: Option<CyclicTerm>,
    /// Root mean square of the model's misfit to the per-target means, weighted by cycles, mm.
    pub rms_residual_mm: f64,
}

impl PitchModel {
    /// The modelled deviation (measured − target) at `position_mm` approached in the positive
    /// (`forward`) or negative direction, mm.
    pub fn deviation_mm(&self, position_mm: f64, forward: bool) -> f64 {
        let half = if forward { 0.5 } else { -0.5 } * self.backlash_mm;
        self.offset_mm
            + self.scale * (position_mm - self.reference_mm)
            + half
            + self.cyclic.map_or(0.0, |c| c.at(position_mm))
    }
}

/// Fewest targets per kind of model: scale and backlash need 3, a cyclic term of a given
/// pitch 4, a fitted pitch 5 (ISO 230-2's minimum).
fn check_targets(m: usize, cyclic: Cyclic) -> Result<(), Error> {
    let (need, why) = match cyclic {
        Cyclic::Off => (
            3,
            "the scale and backlash model needs at least 3 targets (use mode=mean)",
        ),
        Cyclic::Pitch(_) => (
            4,
            "a cyclic term of a given pitch needs at least 4 targets (leave out cyclic_pitch_mm)",
        ),
        Cyclic::Fit => (
            5,
            "fitting the pitch of a cyclic term needs at least 5 targets (leave out fit_cyclic)",
        ),
    };
    if m < need {
        return Err(Error::TooFew {
            field: "targets".into(),
            got: m,
            need: why,
        });
    }
    Ok(())
}

/// The widest gap between neighbouring targets and the range of the targets, mm.
fn gap_and_range(axis: &Axis230_2) -> (f64, f64, f64) {
    let mut p: Vec<f64> = axis.targets.iter().map(|t| t.target_mm).collect();
    p.sort_by(f64::total_cmp);
    let gap = p.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max);
    (gap, p[0], p[p.len() - 1])
}

/// One weighted least-squares solve for a fixed pitch (or none): the coefficients
/// `[offset, scale·half_range, backlash, sin, cos]` and the weighted residual sum of squares.
fn solve(axis: &Axis230_2, pitch_mm: Option<f64>, centre: f64, half: f64) -> (Vec<f64>, f64) {
    let n = if pitch_mm.is_some() { 5 } else { 3 };
    let mut ls = LeastSquares::new(n);
    for t in &axis.targets {
        let u = (t.target_mm - centre) / half;
        let (s, c) = pitch_mm.map_or((0.0, 0.0), |l| (2.0 * PI * t.target_mm / l).sin_cos());
        for (mean, cycles, dir) in [(t.mean_fwd, t.n_fwd, 0.5), (t.mean_bwd, t.n_bwd, -0.5)] {
            let w = (cycles as f64).sqrt();
            let mut row = vec![(0, w), (1, w * u), (2, w * dir)];
            if n == 5 {
                row.extend([(3, w * s), (4, w * c)]);
            }
            ls.add(&row, w * mean);
        }
    }
    match ls.solve() {
        Ok(sol) => {
            let rss = ls.rss(&sol.coef);
            (sol.coef, rss)
        }
        // Only non-finite data fails, and the table was checked finite.
        Err(_) => (vec![f64::NAN; n], f64::INFINITY),
    }
}

/// Points of the pitch grid scanned before Brent's refinement.
const PITCH_GRID: usize = 400;

/// Fits the [`PitchModel`] to an evaluated ISO 230-2 run.
///
/// What: the weighted least-squares fit of offset, scale, backlash and (optionally) a cyclic
/// term to the per-target mean deviations x̄_i↑ and x̄_i↓, each weighted by its cycles n (so
/// the fit equals one over every reading). Units mm.
///
/// Formula: minimise Σ_i Σ_dir n_i,dir (x̄_i,dir − e(P_i, dir))² with e as in [`PitchModel`],
/// linear in its coefficients for a fixed pitch λ (columns 1, (P − P_c)/h, ±½, sin 2πP/λ,
/// cos 2πP/λ with P_c the middle and h the half of the range); with [`Cyclic::Fit`] the
/// residual sum of squares is minimised over λ by a log-spaced scan of 400 pitches between
/// 2·(widest gap between targets) and 2·(range), refined by Brent's method. With equal cycles
/// the backlash column is orthogonal to the rest, so the backlash is exactly B̄.
///
/// Reference: ISO 230-2:2014 §3.9 (x̄), §3.12 (B̄); least squares by the ordered policy of
/// [`crate::numeric::lsq`]; Brent (1973) ch. 5 for the pitch.
///
/// Known bad cases: a cyclic error shorter than twice the target spacing is aliased and
/// cannot be fitted (refused for a given pitch, outside the scanned range for a fitted one);
/// a fitted pitch longer than the range trades off against the scale term (both are then
/// a smooth bend, and the table is still right within the range); position-dependent backlash
/// and guideway bends are left in `rms_residual_mm`.
pub fn fit_model(axis: &Axis230_2, cyclic: Cyclic) -> Result<PitchModel, Error> {
    check_targets(axis.targets.len(), cyclic)?;
    let (gap, lo, hi) = gap_and_range(axis);
    let (centre, half) = (0.5 * (lo + hi), 0.5 * (hi - lo));
    let (min_pitch, max_pitch) = (2.0 * gap, 2.0 * (hi - lo));
    let pitch = match cyclic {
        Cyclic::Off => None,
        Cyclic::Pitch(p) => {
            if !(p.is_finite() && p > 0.0) {
                return Err(Error::Invalid {
                    field: "cyclic_pitch_mm",
                    value: p,
                    reason: "the pitch of the cyclic term is a positive number of mm",
                });
            }
            if p < min_pitch {
                return Err(Error::Unresolvable {
                    field: "cyclic_pitch_mm",
                    reason: format!(
                        "a pitch of {p} mm is shorter than twice the widest gap between targets \
                         ({min_pitch} mm): the run's targets cannot resolve it (it aliases); \
                         measure with targets closer than half the pitch, or leave it out"
                    ),
                });
            }
            Some(p)
        }
        Cyclic::Fit => {
            let ratio = max_pitch / min_pitch;
            let grid: Vec<f64> = (0..PITCH_GRID)
                .map(|k| min_pitch * ratio.powf(k as f64 / (PITCH_GRID - 1) as f64))
                .collect();
            let rss = |l: f64| solve(axis, Some(l), centre, half).1;
            let (best, _) = minimize_on_grid(rss, &grid, 60, 1e-6);
            Some(best.clamp(min_pitch, max_pitch))
        }
    };
    let (coef, rss) = solve(axis, pitch, centre, half);
    if coef.iter().any(|c| !c.is_finite()) {
        return Err(Error::Unresolvable {
            field: "targets",
            reason: "the model could not be fitted to these readings (non-finite solution)".into(),
        });
    }
    let weight: f64 = axis
        .targets
        .iter()
        .map(|t| (t.n_fwd + t.n_bwd) as f64)
        .sum();
    Ok(PitchModel {
        reference_mm: centre,
        offset_mm: coef[0],
        scale: coef[1] / half,
        backlash_mm: coef[2],
        cyclic: pitch.map(|pitch_mm| CyclicTerm {
            pitch_mm,
            sin_mm: coef[3],
            cos_mm: coef[4],
        }),
        rms_residual_mm: (rss / weight).sqrt(),
    })
}
