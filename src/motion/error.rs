//! The one error type of the `motion` core.

/// Everything that can go wrong in the motion core. Variants name the field and what to fix,
/// so `api` can map them to 4xx answers without rewording.
#[non_exhaustive]
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum Error {
    /// The effects stored with the machine cannot be added to this simulation (the sentence
    /// names the effect and the fix).
    #[error("the effects stored with the machine: {0}")]
    Effects(String),
    /// A servo parameter is out of its physical range (non-finite, non-positive, kff outside 0..1).
    #[error("servo parameter '{field}' = {value} is invalid: {reason}")]
    InvalidServo {
        /// Parameter name as in openapi.yaml schema `Servo` ("kv", "kff", "kp_v", "ti_v", "tc").
        field: &'static str,
        /// The offending value.
        value: f64,
        /// What to fix, in one sentence.
        reason: &'static str,
    },
    /// The cascade's closed loop has a pole with non-negative real part.
    #[error(
        "servo axis is unstable (closed-loop pole with real part {max_real_part:.3} 1/s): lower kv or tc, or raise kp_v / ti_v"
    )]
    UnstableServo {
        /// Largest real part of the closed-loop poles, 1/s.
        max_real_part: f64,
    },
    /// The interpolation period is not a positive finite number of seconds.
    #[error("period_s = {0} is invalid: it must be a positive finite number of seconds")]
    InvalidPeriod(f64),
    /// The command sequence is empty.
    #[error("the command is empty: send at least one sample")]
    EmptyCommand,
    /// A command sample is NaN or infinite.
    #[error("command sample {index} is not a finite number")]
    NonFiniteCommand {
        /// Index of the first bad sample.
        index: usize,
    },
    /// A G/M code, word or keyword outside the supported subset (never skipped silently).
    #[error("line {line}: unsupported code {code}")]
    UnsupportedCode {
        /// 1-based line of the program.
        line: usize,
        /// The code as written (e.g. `G41`, `M98`).
        code: String,
    },
    /// A malformed or geometrically impossible block (bad number, arc radius mismatch, ...).
    #[error("line {line}: {message}")]
    Gcode {
        /// 1-based line of the program.
        line: usize,
        /// What is wrong with the block and how to fix it.
        message: String,
    },
    /// The machine definition cannot drive this program (missing axis, bad geometry, ...).
    #[error("machine definition: {0}")]
    InvalidMachine(String),
    /// A numeric argument of a core function is out of range.
    #[error("parameter {field}: {message}")]
    InvalidParameter {
        /// Name of the argument (as the API names it).
        field: String,
        /// Its allowed range, as a sentence.
        message: String,
    },
    /// The program needs more interpolation periods than the caller allows.
    #[error(
        "the program needs {periods} interpolation periods, more than the limit of {limit}: \
         raise period_s or split the program"
    )]
    TooManyPeriods {
        /// Interpolation periods the program needs (duration / period_s).
        periods: u64,
        /// Most periods the caller allows.
        limit: usize,
    },
    /// The program contains no motion at all.
    #[error("the program contains no motion (no G0/G1/G2/G3 block moves an axis)")]
    EmptyProgram,
    /// The interpolation period asked of a simulation is outside what it answers.
    #[error(
        "period_s must be a number of seconds between 0.00001 and 0.1 (default 0.001), got {0}"
    )]
    PeriodOutOfRange(f64),
    /// A stored machine definition does not make a simulable machine.
    #[error(
        "machine '{machine}' cannot be simulated: {reason}. Fix it with PUT /v1/machines/{machine}"
    )]
    NotSimulable {
        /// Machine id.
        machine: String,
        /// Why, as the machine model says it.
        reason: String,
    },
    /// A machine definition key is missing, unknown, of the wrong type or out of its range
    /// (`field` is its JSON path, e.g. `axes.X.kv`; the message names the range or the keys
    /// allowed).
    #[error("{field}: {message}")]
    BadDefinition {
        /// JSON path of the refused key.
        field: String,
        /// What is wrong and what is allowed.
        message: String,
    },
}

impl Error {
    pub(crate) fn gcode(line: usize, message: impl Into<String>) -> Self {
        Error::Gcode {
            line,
            message: message.into(),
        }
    }
    pub(crate) fn parameter(field: impl Into<String>, message: impl Into<String>) -> Self {
        Error::InvalidParameter {
            field: field.into(),
            message: message.into(),
        }
    }
}
