//! The self-check: truth plants with each effect withheld from the stored model (plus "none"
//! cases and effects outside the library), diagnosed blind; confusion matrix, accuracy, `where`
//! (literal and loose), median validation shrink, false alarms and out-of-library answers.
//!
//! Two generators: the classic one ([`crate::gap::truth::draw`], the fitter's own ranges) and
//! the widened one of issue 23 ([`crate::gap::truth_wide`]). Seeds come in two sets: thresholds
//! and span ranking are chosen on the tuning set ([`TUNE_SEEDS`]) and figures are reported on
//! the report set ([`REPORT_SEEDS`]), never used to tune.

use crate::gap::align::step_effects;
use crate::gap::motion::{MotionOptions, diagnose_motion};
use crate::gap::programs::Program;
use crate::gap::selfcheck_cases::{Built, align_logs, build_classic, build_wide, refine_logs};
use crate::gap::selfcheck_where::check_where;
use crate::gap::truth_clock::ClockSpec;
use crate::gap::truth_wide::{Category, WIDE_KINDS, wide_category};
use crate::gap::{Effect, Error};

pub use crate::gap::selfcheck_report::{CategoryFigures, SelfCheckReport};
pub use crate::gap::selfcheck_where::acting_intervals;

/// First seed of the tuning set: seeds below [`REPORT_SEEDS`]. Thresholds, span ranking and
/// anything else about the diagnosis are chosen on these.
pub const TUNE_SEEDS: u64 = 1;
/// First seed of the report set: seeds from here on are only ever used to report figures.
pub const REPORT_SEEDS: u64 = 1_000_000;

/// Which truths the self-check draws.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Generator {
    /// The classic draws: one effect at the fitter's own ranges, cycle of 9 kinds.
    Classic,
    /// The widened draws of issue 23 (cycle of [`WIDE_KINDS`] kinds).
    Wide,
    /// The widened draws plus logs on their own clock (cycle of `WIDE_KINDS + 1`), put on the
    /// program's grid by `align_block` (delay and rate estimated from the motion).
    WideWithClocks,
    /// Out-of-library plants only (the classic generator's kind 8: stick-slip, resonance,
    /// bent screw, loose gib, wrong kinematics, sensor fault, velocity-loop gain,
    /// straightness), for issue 23's gate.
    Outside,
}

impl Generator {
    /// Kinds in one cycle.
    pub fn kinds(self) -> usize {
        match self {
            Generator::Classic => 9,
            Generator::Wide => WIDE_KINDS,
            Generator::WideWithClocks => WIDE_KINDS + 1,
            Generator::Outside => 1,
        }
    }

    /// Name in reports.
    pub fn name(self) -> &'static str {
        match self {
            Generator::Classic => "classic",
            Generator::Wide => "wide",
            Generator::WideWithClocks => "wide+clock-logs",
            Generator::Outside => "outside",
        }
    }
}

/// One diagnosed case.
#[derive(Clone, Debug)]
pub struct CaseResult {
    /// Truth label: an effect name, "none", "pair" or "out_of_library".
    pub truth: String,
    /// What kind of truth.
    pub category: Category,
    /// The library effects planted (two for a pair, none for "none" and out of library).
    pub effects: Vec<Effect>,
    /// The diagnosis' verdict.
    pub verdict: Effect,
    /// Whether the verdict counts as right: the planted effect (either one for a pair), or
    /// `none` for "none"; `None` for out-of-library plants, which have no right answer.
    pub right: Option<bool>,
    /// Pairs: whether `steps` names both planted effects.
    pub both_in_steps: Option<bool>,
    /// `1 − rms_after/rms_before` on the validation block (the verdict's effect alone).
    pub shrink: f64,
    /// `1 − rms/rms_before` on the validation block with every step's effect (0 without steps).
    pub shrink_steps: f64,
    /// Program family.
    pub program: Program,
    /// Noise σ used, mm.
    pub sigma: f64,
    /// Single friction and play cases: `where` on the loose reading
    /// ([`crate::gap::selfcheck_where::WhereCheck::loose`]).
    pub where_ok: Option<bool>,
    /// The literal reading: the top span starts at an event where the effect acts.
    pub where_literal: Option<bool>,
    /// The top `where` entry, "label (axis) start..end".
    pub where_top: String,
    /// Effects in `steps`, in order.
    pub steps: Vec<Effect>,
    /// Held-out share of the gap above the noise that the steps leave (`unexplained`).
    pub unexplained_share: f64,
    /// The truth plant (main block), for reading misses.
    pub detail: String,
    /// Clock-log cases: the log's clock.
    pub clock: Option<ClockSpec>,
}

/// Runs one classic case with truth kind `kind` (0 none, 1..=7 library, 8 out of library).
pub fn run_case(kind: usize, seed: u64, opts: &MotionOptions) -> Result<CaseResult, Error> {
    diagnose_case(build_classic(kind, seed), opts, false)
}

/// Runs case number `index` of `generator` (its kind is `index` modulo the cycle) with `seed`.
pub fn run_generated(
    generator: Generator,
    index: usize,
    seed: u64,
    opts: &MotionOptions,
    verbose: bool,
) -> Result<CaseResult, Error> {
    let kind = index % generator.kinds();
    let built = match generator {
        Generator::Classic => build_classic(kind, seed),
        Generator::Outside => build_classic(8, seed),
        _ => build_wide(kind, seed),
    };
    diagnose_case(built, opts, verbose)
}

/// As [`run_case`], printing the diagnosis to stderr; returns the case as text.
pub fn run_case_verbose(kind: usize, seed: u64, opts: &MotionOptions) -> Result<String, Error> {
    diagnose_case(build_classic(kind, seed), opts, true).map(|c| format!("{c:?}"))
}

fn diagnose_case(b: Built, opts: &MotionOptions, verbose: bool) -> Result<CaseResult, Error> {
    let (mut b, mut opts, mut note, timed) = align_logs(b, opts);
    let axes = b.servo.len();
    let names: Vec<String> = ["X", "Y", "Z"][..axes]
        .iter()
        .map(|s| s.to_string())
        .collect();
    let mut d = diagnose_motion(&names, &b.servo, b.period, &b.main, Some(&b.val), &opts)?;
    // a clock-log case is diagnosed again at the delay its steps' effects fit best, as the
    // route does (`crate::gap::align::refine_delay`)
    let effects = step_effects(&d);
    if let Some(timed) = timed.filter(|_| !effects.is_empty()) {
        match refine_logs(&mut b, &mut opts, &timed, &effects) {
            Ok(more) => {
                note.push_str(&more);
                d = diagnose_motion(&names, &b.servo, b.period, &b.main, Some(&b.val), &opts)?;
            }
            Err(e) => note.push_str(&format!("; delay not refined ({e})")),
        }
    }
    if verbose {
        eprintln!(
            "servo {:?}\ntruth {:?}\nprogram {:?} n {} gap {:.3} um noise {:.3} um",
            b.servo,
            b.truth,
            b.program,
            b.main.commanded[0].len(),
            d.gap_before.rms * 1e3,
            d.noise_mm * 1e3
        );
        for e in &d.effects {
            let name = e.fitted.effect().name();
            eprintln!("  {name:<22} score {:>8.4}  {:?}", e.score, e.params);
        }
        eprintln!("where: {:?}", &d.spans[..d.spans.len().min(4)]);
        for s in &d.steps {
            let name = s.fitted.effect().name();
            eprintln!("  step {name:<22} score {:.4} {:?}", s.score, s.params);
        }
        eprintln!("  unexplained {:?}", d.unexplained);
    }
    // where is judged on single friction and play plants only (a pair's top span may belong
    // to its other effect, which acts at no event)
    let judged = matches!(b.category, Category::Single | Category::Extreme);
    let check = judged
        .then(|| {
            check_where(
                &b.servo,
                &b.truth,
                &b.main.commanded,
                b.period,
                &names,
                &d.spans,
            )
        })
        .flatten();
    let effects = b.truth.effects();
    let steps: Vec<Effect> = d.steps.iter().map(|s| s.fitted.effect()).collect();
    let right = match b.category {
        Category::OutOfLibrary => None,
        Category::Pair => Some(effects.contains(&d.verdict)),
        _ => Some(d.verdict == effects.first().copied().unwrap_or(Effect::None)),
    };
    let v = d.validation.as_ref().expect("validation requested");
    Ok(CaseResult {
        truth: match b.category {
            Category::OutOfLibrary => "out_of_library".to_string(),
            Category::Pair => "pair".to_string(),
            _ => effects.first().map_or("none", |e| e.name()).to_string(),
        },
        category: b.category,
        both_in_steps: (b.category == Category::Pair)
            .then(|| effects.iter().all(|e| steps.contains(e))),
        effects,
        verdict: d.verdict,
        right,
        shrink: if v.rms_before > 0.0 {
            1.0 - v.rms_after / v.rms_before
        } else {
            0.0
        },
        shrink_steps: match v.rms_steps.last() {
            Some(r) if v.rms_before > 0.0 => 1.0 - r / v.rms_before,
            _ => 0.0,
        },
        program: b.program,
        sigma: b.sigma,
        where_ok: check.map(|c| c.loose),
        where_literal: check.map(|c| c.literal),
        where_top: d.spans.first().map_or(String::new(), |s| {
            format!("{} ({}) {}..{}", s.label, s.axis, s.start, s.end)
        }),
        steps,
        unexplained_share: d.unexplained.heldout_share,
        detail: if note.is_empty() {
            format!("{:?}", b.truth)
        } else {
            format!("{:?}; {note}", b.truth)
        },
        clock: b.clock,
    })
}

/// Runs `cases` classic cases cycling through the truth kinds (none, the 7 effects, out of
/// library), seeds `seed, seed+1, ...`, and summarises them.
pub fn run(cases: usize, seed: u64, opts: &MotionOptions) -> Result<SelfCheckReport, Error> {
    run_with(Generator::Classic, cases, seed, opts)
}

/// Runs `cases` cases of `generator` (case `i` has kind `i` modulo the cycle and seed
/// `seed + i`) on `opts.threads` threads and summarises them.
pub fn run_with(
    generator: Generator,
    cases: usize,
    seed: u64,
    opts: &MotionOptions,
) -> Result<SelfCheckReport, Error> {
    let seeds: Vec<u64> = (0..cases as u64).map(|i| seed + i).collect();
    let serial = MotionOptions {
        threads: 1,
        ..opts.clone()
    };
    let results = crate::numeric::parallel::map_dynamic(&seeds, opts.threads, |s| {
        run_generated(generator, (s - seed) as usize, s, &serial, false)
    });
    let cases: Vec<CaseResult> = results.into_iter().collect::<Result<_, _>>()?;
    Ok(SelfCheckReport::summarise(generator, seed, cases))
}

/// Truth kinds of the classic generator cycle in this order: index → label.
pub fn kind_label(kind: usize) -> &'static str {
    match kind {
        0 => "none",
        1..=7 => Effect::LIBRARY[kind - 1].name(),
        _ => "out_of_library",
    }
}

/// The category of case number `index` of `generator`.
pub fn case_category(generator: Generator, index: usize) -> Category {
    let kind = index % generator.kinds();
    match generator {
        Generator::Classic => match kind {
            0 => Category::None,
            1..=7 => Category::Single,
            _ => Category::OutOfLibrary,
        },
        Generator::Outside => Category::OutOfLibrary,
        _ => wide_category(kind),
    }
}

#[cfg(test)]
mod tests;
