//! Contour-error pre-compensation (issue 39 item 3, `contour: true`): the program is
//! rewritten so that the simulated servo follows the *original* path on a set of machine
//! models, by one objective and one optimiser.
//!
//! **What may change** (module `shape`): at each corner of two cutting blocks, the corner
//! point (in its XY level) and a slowed stretch on each side (length and feed fraction); at
//! each G17 arc, its radius (written as three sub-arcs). Nothing else: rapids, canned
//! cycles, dwells, plunges and every line the caller keeps are written as programmed (a
//! corner whose two blocks a kept backlash take-up separates is slowed, not moved). Feeds
//! are only lowered, arcs stay arcs, no dwell is added, no Z word is added to a 2-D cut,
//! and a block becomes at most three.
//!
//! **What is judged** (module `objective`): the simulated tool tip's distance to the
//! original programmed lines and arcs, weighted by path length, its RMS and (as an 8-norm)
//! its max, a hinge on the tolerance band about the path (towards the material: the band;
//! on both sides where G41/G42 do not say the side), and the duration — over the model set
//! of module `models` (nominal; kv ±15 %; kff ±0.1; half the period), the nominal weighing
//! as much as the others together. Each run is simulated until the servo settles
//! ([`SETTLE_TIME_CONSTANTS`]).
//!
//! **How** (module `solve`): projected Levenberg–Marquardt on those residuals, with a
//! finite-difference Jacobian coloured by the features' path windows. The band is a
//! constraint on the nominal model wherever the original stayed within it (issue 39 item
//! 1), held by the quadratic penalty method: while the optimum leaves it there, the band
//! hinge's weight grows ([`PENALTY_GROWTH`], at most [`PENALTY_ROUNDS`] times) and the
//! optimiser goes on from that optimum; should it still leave the band, every change is
//! scaled back until it stays within (`within_band`). The answer is pruned of features that
//! change nothing worth a block; when it is no better than the original on the objective,
//! the program is returned unchanged.
//!
//! Machines with rotary axes are refused ([`Error::Unsupported`]).

mod models;
mod objective;
mod options;
mod path;
mod shape;
mod solve;

use std::collections::BTreeMap;

use crate::motion::program::{Feed, Motion};
use crate::motion::{self, Kinematics, Machine, PathControl, Program};
pub use models::{KFF_SPREAD, KV_SPREAD, Model, PERIOD_FACTOR, model_set};
pub use objective::{
    BIN_MM, ENVELOPE_MM, FOOT_SPREAD, HINGE_WIDTH, MAX_BINS, MAX_TARGET, PENALTY, RMS_TARGET,
    TIME_MARGIN,
};
pub use options::{
    BAND_RANGE_MM, DEFAULT_BAND_MM, DEFAULT_MAX_DURATION_RATIO, MAX_DURATION_RATIO,
    PredistortOptions,
};
pub use shape::{
    CORNER_MIN_RAD, MAX_LENGTH_SHARE, MIN_FEED_FRACTION, Piece, REACH_FACTOR, START_FEED_FRACTION,
    TRANSITION_TIME_CONSTANTS,
};
pub use solve::{CONVERGED, TRIALS};

/// Longest program (interpolation periods of every simulated run) the pre-distortion runs:
/// 2,000,000 periods, 33 min of machining at the default 1 ms period.
pub const MAX_PERIODS: usize = 2_000_000;

/// Every run is held at its end for this many servo time constants (1/kv of the slowest
/// axis) so that the error left when the command stops is judged: e⁻⁵ < 1 % of it remains.
pub const SETTLE_TIME_CONSTANTS: f64 = 5.0;

/// A slowed stretch whose feed fraction is within this of 1 (1 %) and whose corner point
/// moved less than [`PRUNE_MM`] is dropped: it would add two blocks for no effect a
/// machine shows.
pub const PRUNE_FEED: f64 = 0.01;

/// An excursion beyond the band smaller than this (1 nm) is the simulation's arithmetic,
/// not an overshoot (`within_band`), mm.
pub const BAND_SLACK_MM: f64 = 1e-6;

/// Growth of the band hinge's weight per round of the penalty method (the factor Nocedal
/// and Wright give for a quadratic penalty): the cost of a violation grows 100× a round.
pub const PENALTY_GROWTH: f64 = 10.0;

/// Rounds of the penalty method after the first solve (they share the optimiser's
/// iteration budget with it). After three the hinge's residual
/// weighs 1,000× [`PENALTY`] (its cost 10⁶×): what still leaves the band then is an
/// optimiser stall rather than too light a weight, and `within_band` scales the answer
/// back.
pub const PENALTY_ROUNDS: usize = 3;

/// Bisection steps of `within_band`'s scale: 7 halvings leave it within 1 % of the
/// largest that stays within the band, a digit no figure shows.
pub const BAND_BISECTIONS: usize = 7;

/// A corner point moved, or an arc's radius changed, by less than this (0.1 µm, the last
/// printed digit of a metric program) is left as programmed.
pub const PRUNE_MM: f64 = 1e-4;

/// The side of the programmed path the material lies on, looking along the direction of
/// travel (G41, tool left of the path: [`MaterialSide::Right`]; G42: [`MaterialSide::Left`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MaterialSide {
    /// Material on the left of the direction of travel.
    Left,
    /// Material on the right of the direction of travel.
    Right,
}

/// Contour error of a simulated run against the original programmed path.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ErrorStats {
    /// RMS over the interpolation periods on cutting moves of the distance from the
    /// simulated tool tip to the original path, mm.
    pub rms_mm: f64,
    /// Largest such distance, mm.
    pub max_mm: f64,
    /// RMS of that distance along the tool tip's path (each period weighted by the path
    /// length it covers), mm.
    pub rms_distance_mm: f64,
    /// Largest excursion beyond the band towards the material, or beyond
    /// [`ENVELOPE_MM`] away from it, where the original stayed within them, mm (≤ 0: none).
    pub gouge_mm: f64,
    /// Duration of the command, s.
    pub duration_s: f64,
}

/// The figures of one model of the set.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelFigures {
    /// The model ("nominal", "kv -15 %", …).
    pub model: String,
    /// The original program on it.
    pub original: ErrorStats,
    /// The compensated program on it.
    pub compensated: ErrorStats,
}

/// The compensated program and what it achieves.
#[derive(Clone, Debug, PartialEq)]
pub struct Predistorted {
    /// The pieces of each rewritten source line (machine frame, mm); a line not listed is
    /// written as programmed.
    pub lines: BTreeMap<usize, Vec<Piece>>,
    /// Contour error of the original program on the nominal machine.
    pub original: ErrorStats,
    /// Contour error of the compensated program on the nominal machine.
    pub compensated: ErrorStats,
    /// Both on every model of the set, nominal first.
    pub models: Vec<ModelFigures>,
    /// Optimiser iterations (Jacobians).
    pub iterations: usize,
    /// Evaluations of the objective (each simulates every model once).
    pub evaluations: usize,
    /// Sentences on what was changed and where it could not help.
    pub notes: Vec<String>,
}

/// Everything that can go wrong in the pre-distortion.
#[non_exhaustive]
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum Error {
    /// The program or the machine cannot be simulated (G-code, machine, period, length).
    #[error(transparent)]
    Motion(#[from] motion::Error),
    /// An option is out of its range.
    #[error("{field}: {message}")]
    Option {
        /// The option's name.
        field: &'static str,
        /// Its allowed range.
        message: String,
    },
    /// The program or the machine uses something the pre-distortion does not handle yet.
    #[error("{0}")]
    Unsupported(String),
}

/// [`predistort_sided`] of a whole program with no path-control codes, no kept lines and no
/// known material side.
pub fn predistort(
    machine: &Machine,
    program: &Program,
    opts: &PredistortOptions,
) -> Result<Predistorted, Error> {
    predistort_sided(
        machine,
        program,
        &PathControl::default(),
        opts,
        &|_| false,
        &|_| None,
        &|_| [true; 3],
        &|_| false,
    )
}

fn stats(a: &objective::Acc, period_s: f64) -> ErrorStats {
    ErrorStats {
        rms_mm: a.rms(),
        max_mm: a.max,
        rms_distance_mm: a.rms_distance(),
        gouge_mm: a.gouge,
        duration_s: a.periods as f64 * period_s,
    }
}

/// Rewrites the cutting blocks of `program` (read with its path-control modes `control`)
/// so that `machine`'s simulated servo follows the original path over the model set
/// (module docs). Lines for which `keep(line)` holds are written as programmed; `side(line)`
/// is the material side where G41/G42 say it; `placed(line)` the axes the written program
/// can state at the end of that line (a corner is moved only where both axes of its level
/// are); `through(line)` holds for a kept line a corner may span (a backlash take-up: a
/// move of the motor alone, written between the two blocks of a corner, which is then
/// slowed but not moved). Returns the pieces of the rewritten lines,
/// the figures of the original and the answer on each model (RMS and max distance of the
/// simulated tool tip to the original path, mm; duration, s), and notes.
/// Errors: [`Error::Motion`] for programs the motion core refuses, [`Error::Option`] for
/// options out of range, [`Error::Unsupported`] for rotary axes.
#[allow(clippy::too_many_arguments)]
pub fn predistort_sided(
    machine: &Machine,
    program: &Program,
    control: &PathControl,
    opts: &PredistortOptions,
    keep: &dyn Fn(usize) -> bool,
    side: &dyn Fn(usize) -> Option<MaterialSide>,
    placed: &dyn Fn(usize) -> [bool; 3],
    through: &dyn Fn(usize) -> bool,
) -> Result<Predistorted, Error> {
    opts.check()?;
    if !matches!(machine.kinematics, Kinematics::Xyz) {
        return Err(Error::Unsupported(
            "contour pre-distortion handles xyz machines only so far; this machine has rotary axes"
                .into(),
        ));
    }
    let path = path::Path::new(program, keep, side);
    let models = model_set(machine, opts.period_s);
    let mut obj = objective::Objective::new(
        program,
        control,
        path,
        models,
        opts.band_mm,
        opts.max_duration_ratio,
    )?;
    let base = &obj.base[0];
    let near = shape::Near {
        max_dist: base.block_max.clone(),
        inside: base
            .block_inside
            .iter()
            .map(|&(s, n)| if n > 0 { s / n as f64 } else { 0.0 })
            .collect(),
    };
    let mut per_line = BTreeMap::<usize, usize>::new();
    for b in &program.blocks {
        *per_line.entry(b.line).or_default() += 1;
    }
    let movable = |i: usize| {
        let b = &program.blocks[i];
        matches!(b.motion, Motion::Linear | Motion::Arc { .. })
            && matches!(b.feed, Feed::PerMinute(_))
            && !keep(b.line)
            && per_line[&b.line] == 1
            // A full circle starts where it ends; a line must go somewhere.
            && (matches!(b.motion, Motion::Arc { .. }) || b.start.xyz != b.end.xyz)
    };
    let placed_xy = |i: usize| {
        let p = placed(program.blocks[i].line);
        p[0] && p[1]
    };
    let shape = shape::Shape::new(
        program,
        &obj.path,
        machine,
        (&movable, &placed_xy, &|i: usize| {
            through(program.blocks[i].line)
        }),
        &near,
        opts.band_mm,
    );
    let windows: Vec<std::ops::Range<usize>> = shape.window.iter().map(|w| obj.bins(*w)).collect();
    obj.set_focus(&windows);
    let layout = solve::Layout {
        bins: windows,
        rows: shape
            .window
            .iter()
            .map(|w| obj.rows(&obj.bins(*w)))
            .collect(),
    };
    let eval_weighted = |x: &[f64], w: f64| obj.eval(&shape.program(program, x).0, w);
    let eval = |x: &[f64]| eval_weighted(x, 1.0);
    let neutral = obj.eval(program, 1.0)?;
    let mut notes = Vec::new();
    let (mut x, mut best, iterations, evaluations) = if opts.max_iterations == 0 || shape.is_empty()
    {
        (Vec::new(), neutral.clone(), 0, 1)
    } else {
        // The band as a constraint by the quadratic penalty method: while the optimum leaves
        // the band where the original stayed within it, the band hinge weighs
        // PENALTY_GROWTH times more and the optimiser goes on from that optimum.
        // The rounds share the iteration budget.
        let (mut start, mut weight) = (shape.x0.clone(), 1.0);
        let (mut iterations, mut evaluations) = (0, 1);
        let mut round = 0;
        let s = loop {
            let s = solve::solve(
                &shape,
                &layout,
                &start,
                opts.max_iterations - iterations,
                &|x| eval_weighted(x, weight),
            )?;
            iterations += s.iterations;
            evaluations += s.evaluations;
            round += 1;
            if s.eval.runs[0].gouge <= BAND_SLACK_MM
                || round > PENALTY_ROUNDS
                || iterations >= opts.max_iterations
            {
                break s;
            }
            start = s.x;
            weight *= PENALTY_GROWTH;
        };
        if s.stalled {
            notes.push(format!(
                "stopped after {iterations} optimiser iterations, where no damped step lowered \
                 the objective further",
            ));
        } else if iterations >= opts.max_iterations {
            notes.push(format!(
                "stopped after max_iterations = {} before the objective stopped improving; \
                 more iterations may lower it further",
                opts.max_iterations
            ));
        }
        if weight > 1.0 {
            notes.push(format!(
                "the band was held as a constraint with its weight raised {weight:.0}x where \
                 the unconstrained optimum left it"
            ));
        }
        // The answer's objective as documented (the band at its own weight).
        let e = if weight > 1.0 { eval(&s.x)? } else { s.eval };
        (s.x, e, iterations, evaluations + 1)
    };
    let mut evaluations = evaluations;
    if !x.is_empty() {
        let mut pruned = x.clone();
        if !shape.prune(&mut pruned, PRUNE_FEED, PRUNE_MM).is_empty() {
            let e = eval(&pruned)?;
            evaluations += 1;
            if e.cost() <= best.cost() * (1.0 + CONVERGED) {
                x = pruned;
                best = e;
            }
        }
    }
    let alpha = if x.is_empty() {
        1.0
    } else {
        within_band(&shape, &mut x, &mut best, &eval, &mut evaluations)?
    };
    if alpha < 1.0 {
        notes.push(format!(
            "corner and arc changes scaled to {:.0} % of the optimum: beyond it the overshoot \
             left the band (both sides of the path where G41/G42 do not give the material \
             side) where the original stayed within it",
            alpha * 100.0
        ));
    }
    let lines: BTreeMap<usize, Vec<Piece>> = if !x.is_empty() && best.cost() < neutral.cost() {
        shape
            .program(program, &x)
            .1
            .into_iter()
            .map(|(i, p)| (program.blocks[i].line, p))
            .collect()
    } else {
        if !shape.is_empty() && opts.max_iterations > 0 {
            // How the optimiser stopped no longer matters: this note says what was returned.
            notes.retain(|n| !n.starts_with("stopped after"));
            notes.push(format!(
                "stopped after {iterations} optimiser iterations: no change lowered the contour \
                 error over the model set, so the program is returned as written"
            ));
        }
        best = neutral.clone();
        BTreeMap::new()
    };
    notes.extend(describe(&shape, &x, &lines, program));
    let models: Vec<ModelFigures> = obj
        .models
        .iter()
        .enumerate()
        .map(|(k, m)| ModelFigures {
            model: m.name.clone(),
            original: stats(&obj.base[k], m.period_s),
            compensated: stats(&best.runs[k], m.period_s),
        })
        .collect();
    Ok(Predistorted {
        lines,
        original: models[0].original,
        compensated: models[0].compensated,
        models,
        iterations,
        evaluations,
        notes,
    })
}

/// The band is a constraint, not only a term of the objective (issue 39 item 1): where the
/// answer `x` (evaluated as `best`) leaves it on the nominal model — towards the material,
/// on both sides where the side is unknown — by more than [`BAND_SLACK_MM`] where the
/// original stayed within it, every change is scaled back towards none (corner offsets and
/// radius changes by a factor α, feed fractions towards 1 by it) by bisection over α in
/// [`BAND_BISECTIONS`] steps, keeping the largest α that stays within. At α = 0 the answer
/// is the original, which is within by definition. Returns the α kept (1: unchanged).
fn within_band(
    shape: &shape::Shape,
    x: &mut Vec<f64>,
    best: &mut objective::Eval,
    eval: &dyn Fn(&[f64]) -> Result<objective::Eval, Error>,
    evaluations: &mut usize,
) -> Result<f64, Error> {
    let over = |e: &objective::Eval| e.runs[0].gouge > BAND_SLACK_MM;
    if !over(best) {
        return Ok(1.0);
    }
    let mut none = x.clone();
    for k in 0..shape.features.len() {
        shape.neutralize(&mut none, k);
    }
    let at = |alpha: f64| -> Vec<f64> {
        x.iter()
            .zip(&none)
            .map(|(v, n)| n + alpha * (v - n))
            .collect()
    };
    let (mut lo, mut hi) = (0.0, 1.0);
    let mut kept: Option<(Vec<f64>, objective::Eval)> = None;
    for _ in 0..BAND_BISECTIONS {
        let mid = 0.5 * (lo + hi);
        let t = at(mid);
        let e = eval(&t)?;
        *evaluations += 1;
        if over(&e) {
            hi = mid;
        } else {
            lo = mid;
            kept = Some((t, e));
        }
    }
    match kept {
        Some((t, e)) => {
            *x = t;
            *best = e;
        }
        None => {
            *best = eval(&none)?;
            *evaluations += 1;
            *x = none;
            lo = 0.0;
        }
    }
    Ok(lo)
}

/// The figures of `written` (a program written from an answer and read back, with its own
/// path-control modes `written_control`) against the original `program` on the model set of
/// `machine` (the same measure as [`predistort_sided`]'s, with the same `keep`, `side` and
/// options): nominal first.
#[allow(clippy::too_many_arguments)]
pub fn judge(
    machine: &Machine,
    program: &Program,
    control: &PathControl,
    opts: &PredistortOptions,
    keep: &dyn Fn(usize) -> bool,
    side: &dyn Fn(usize) -> Option<MaterialSide>,
    written: &Program,
    written_control: &PathControl,
) -> Result<Vec<ModelFigures>, Error> {
    opts.check()?;
    let path = path::Path::new(program, keep, side);
    let obj = objective::Objective::new(
        program,
        control,
        path,
        model_set(machine, opts.period_s),
        opts.band_mm,
        opts.max_duration_ratio,
    )?;
    obj.models
        .iter()
        .enumerate()
        .map(|(k, m)| {
            Ok(ModelFigures {
                model: m.name.clone(),
                original: stats(&obj.base[k], m.period_s),
                compensated: stats(&obj.run_with(k, written, written_control, 1.0)?, m.period_s),
            })
        })
        .collect()
}

/// Sentences on what parameters `x` of `shape` change (empty when `lines` is: nothing
/// written).
fn describe(
    shape: &shape::Shape,
    x: &[f64],
    lines: &std::collections::BTreeMap<usize, Vec<Piece>>,
    program: &Program,
) -> Vec<String> {
    if lines.is_empty() || x.is_empty() {
        return Vec::new();
    }
    let (mut corners, mut lowest, mut longest, mut moved) = (Vec::new(), 1.0f64, 0.0f64, 0.0f64);
    let (mut arcs, mut radius) = (Vec::new(), 0.0f64);
    for (k, f) in shape.features.iter().enumerate() {
        let o = shape.offset[k];
        match f {
            shape::Feature::Corner { line, .. } => {
                if x[o + 3] < 1.0 || x[o] != 0.0 || x[o + 1] != 0.0 {
                    corners.push(*line);
                    if x[o + 3] < 1.0 {
                        lowest = lowest.min(x[o + 3]);
                        longest = longest.max(x[o + 2]);
                    }
                    moved = moved.max(x[o].hypot(x[o + 1]));
                }
            }
            shape::Feature::Arc { line, block } => {
                if x[o] != 0.0 && lines.contains_key(&program.blocks[*block].line) {
                    arcs.push(*line);
                    radius = radius.max(x[o].abs());
                }
            }
        }
    }
    let mut out = Vec::new();
    if !corners.is_empty() {
        out.push(format!(
            "{} corner(s) pre-distorted: feed lowered to {:.0} % of F at the lowest over \
                 stretches of up to {:.3} mm, corner points moved by up to {:.1} µm",
            corners.len(),
            100.0 * lowest,
            longest,
            1e3 * moved,
        ));
    }
    if !arcs.is_empty() {
        out.push(format!(
            "{} arc(s) written as three sub-arcs with the radius changed by up to {:.1} µm \
                 against the servo's radius loss",
            arcs.len(),
            1e3 * radius
        ));
    }
    out
}

#[cfg(test)]
mod tests;
