//! `truecut_version` in the answers that are measurements (issue 25: the same input and
//! version give the same bits, so an answer names the version that computed it): the
//! decomposition, gap-diagnosis and volumetric-map answers. Stored job results get it where
//! they are recorded (`jobs`).

use serde::Serialize;
use serde_json::Value;

/// An answer `T` with `truecut_version` ([`crate::version`]) beside its own fields, written
/// in one pass (no intermediate [`Value`]).
#[derive(Debug, Serialize)]
pub struct Versioned<T> {
    /// The answer.
    #[serde(flatten)]
    pub answer: T,
    /// The version of truecut that computed it.
    pub truecut_version: &'static str,
}

impl<T> Versioned<T> {
    /// `answer` as computed by this build.
    pub fn new(answer: T) -> Self {
        Self {
            answer,
            truecut_version: crate::version(),
        }
    }
}

/// Adds `truecut_version` (this build's) to an answer object, unless it has one; other
/// values are left alone.
pub fn stamp(mut answer: Value) -> Value {
    if let Value::Object(fields) = &mut answer {
        fields
            .entry("truecut_version")
            .or_insert_with(|| Value::from(crate::version()));
    }
    answer
}
