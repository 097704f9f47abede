//! The codec's error: why a body was refused, as a sentence for the client.

/// Why a body was rejected: a sentence naming the place (byte or `segments[i]`) and what was
/// expected there (the API answers it as 400 with this sentence).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct DecodeError(pub String);
