//! The one error type of the metrology core.

/// Why an ISO 230-2 or ISO 230-4 evaluation could not be made; each sentence names the input
/// to fix.
#[non_exhaustive]
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum Error {
    /// A value is NaN or infinite.
    #[error("{field}[{index}] is not a finite number; send finite mm")]
    NonFinite {
        /// Name of the array in the request.
        field: String,
        /// Index of the first bad entry.
        index: usize,
    },
    /// Two arrays that must have one entry each per target (or per sample) do not.
    #[error("{field} has {got} entries but {expected} are expected ({why})")]
    LengthMismatch {
        /// Name of the array in the request.
        field: String,
        /// Entries it has.
        got: usize,
        /// Entries it must have.
        expected: usize,
        /// What the length must match.
        why: &'static str,
    },
    /// Too few targets or cycles to compute the figures at all.
    #[error("{field}: {got} is too few; {need}")]
    TooFew {
        /// What is counted (e.g. `targets`, `forward[2] cycles`).
        field: String,
        /// How many were sent or found.
        got: usize,
        /// What is needed, as a sentence.
        need: &'static str,
    },
    /// The same target position appears twice.
    #[error("targets[{second}] = {value} mm repeats targets[{first}]; each target position once")]
    DuplicateTarget {
        /// Index of the first occurrence.
        first: usize,
        /// Index of the repeat.
        second: usize,
        /// The repeated position, mm.
        value: f64,
    },
    /// A logged run in which some commanded approaches to a target gave no settled reading.
    #[error(
        "target {target_mm} mm, {direction}: {got} settled readings, {expected} cycles expected \
         (the command approaches it {expected} times; the approach commanded from sample \
         {command_sample} has none). A reading needs the measured position to move slower than \
         settle_speed_mm_s = {settle_speed_mm_s} mm/s for min_settled_s = {min_settled_s} s: \
         raise settle_speed_mm_s or shorten min_settled_s, or cut the approaches the axis never \
         finished out of the log"
    )]
    MissingReadings {
        /// The target, mm.
        target_mm: f64,
        /// `forward` or `backward`.
        direction: &'static str,
        /// Settled readings found.
        got: usize,
        /// Approaches the command makes.
        expected: usize,
        /// First command sample of the first approach without a reading.
        command_sample: usize,
        /// The speed threshold used, mm/s.
        settle_speed_mm_s: f64,
        /// The minimum settled time used, s.
        min_settled_s: f64,
    },
    /// A parameter outside its range.
    #[error("{field} = {value} is out of range: {reason}")]
    Invalid {
        /// Name of the parameter.
        field: &'static str,
        /// The value sent.
        value: f64,
        /// The allowed range, as a sentence.
        reason: &'static str,
    },
    /// The request asks for something the run cannot give (a cyclic pitch its targets cannot
    /// resolve, a table longer than the controller loads); the sentence names the fix.
    #[error("{field}: {reason}")]
    Unresolvable {
        /// Name of the parameter or input.
        field: &'static str,
        /// Why, and what to change, as a sentence.
        reason: String,
    },
    /// A compensation table would carry a correction no pitch error has: an offset, another
    /// axis' readings or other units.
    #[error(
        "the {direction} correction at {position_mm} mm is {correction_mm:.6} mm (relative to the \
         reference target {reference_mm} mm); a pitch-error table corrects at most {limit_mm} \
         mm: a correction that large means the readings carry an offset, belong to another axis \
         or are in other units. Check the readings, or name another reference_mm"
    )]
    CorrectionTooLarge {
        /// The table position (a target of a mean table), mm.
        position_mm: f64,
        /// `forward` or `backward`.
        direction: &'static str,
        /// The correction, mm.
        correction_mm: f64,
        /// The limit, mm ([`crate::metrology::comp_table::MAX_CORRECTION_MM`]).
        limit_mm: f64,
        /// The reference target, mm.
        reference_mm: f64,
    },
    /// The points do not define a circle (collinear, coincident, or too few).
    #[error("{field}: the points do not define a circle ({reason})")]
    Degenerate {
        /// Name of the point array.
        field: &'static str,
        /// Why, as a sentence.
        reason: String,
    },
}
