//! The reference of a pitch-error compensation table: the target its corrections are counted
//! from (its forward correction is 0 by definition), so that the measuring device's zero never
//! enters the table (see [`crate::metrology::comp_table`], **Reference**).

use super::error::Error;
use super::iso230_2::Axis230_2;

/// Two positions closer than this are one target when a reference is named, mm (the files
/// print 1 nm).
const SAME_TARGET_MM: f64 = 1e-6;

/// The target a table is referenced to: its forward correction is 0, every other correction is
/// counted from it ([`crate::metrology::comp_table`] module docs, **Reference**).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Reference {
    /// The first target approached in the positive direction, mm: the default. For a logged
    /// run the caller knows it from the time order of the readings; for a table, whose order is
    /// unknown, it is the lowest target ([`Reference::first_forward_of`]), where ISO 230-2's
    /// cycles start their forward approaches (§5.3.2).
    FirstForward(f64),
    /// A target position the request names, mm.
    Named(f64),
}

impl Reference {
    /// The default reference of a run whose order of approaches is not known: the lowest
    /// target, the first a forward sweep of ISO 230-2's cycles approaches.
    pub fn first_forward_of(axis: &Axis230_2) -> Reference {
        let lowest = axis
            .targets
            .iter()
            .map(|t| t.target_mm)
            .fold(f64::INFINITY, f64::min);
        Reference::FirstForward(lowest)
    }

    /// The reference position, mm.
    pub fn position_mm(&self) -> f64 {
        match *self {
            Reference::FirstForward(p) | Reference::Named(p) => p,
        }
    }

    /// Which reference it is, as one sentence for file headers and answers.
    pub fn describe(&self) -> String {
        let how = match self {
            Reference::FirstForward(_) => "the first target approached in the positive direction",
            Reference::Named(_) => "the target named by reference_mm",
        };
        format!(
            "corrections are relative to {} mm approached forward ({how}), whose forward \
             correction is 0 by definition; the measuring device's zero does not enter",
            self.position_mm()
        )
    }

    /// Which rule chose it: `first_forward` or `named`.
    pub fn rule(&self) -> &'static str {
        match self {
            Reference::FirstForward(_) => "first_forward",
            Reference::Named(_) => "named",
        }
    }
}

/// The target `reference` names: its index in `axis.targets`, or why it is none.
pub(super) fn reference_target(axis: &Axis230_2, reference: Reference) -> Result<usize, Error> {
    let p = reference.position_mm();
    if !p.is_finite() {
        return Err(Error::Invalid {
            field: "reference_mm",
            value: p,
            reason: "the reference is a target position, a finite number of mm",
        });
    }
    if let Some(i) = axis
        .targets
        .iter()
        .position(|t| (t.target_mm - p).abs() <= SAME_TARGET_MM)
    {
        return Ok(i);
    }
    let mut targets: Vec<f64> = axis.targets.iter().map(|t| t.target_mm).collect();
    targets.sort_by(f64::total_cmp);
    let shown: Vec<String> = targets.iter().take(20).map(|t| t.to_string()).collect();
    let more = if targets.len() > 20 { ", ..." } else { "" };
    Err(Error::Unresolvable {
        field: "reference_mm",
        reason: format!(
            "{p} mm is not a target of this run; the reference must be one of its targets \
             (mm): {}{more}",
            shown.join(", ")
        ),
    })
}
