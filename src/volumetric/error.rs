//! The volumetric core's one error type.

/// Everything that can go wrong while building, fitting, evaluating or exporting a
/// volumetric error map. Bad-input variants name the field and what to fix.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum Error {
    /// A required array is empty.
    #[error("'{field}' is empty: send at least {need} entries")]
    Empty {
        /// Name of the array in the request.
        field: &'static str,
        /// Fewest entries it needs.
        need: usize,
    },
    /// Too few nodes for the requested model.
    #[error("{what} needs at least {need} nodes, got {got}")]
    TooFewNodes {
        /// The model or step that needs the nodes.
        what: &'static str,
        /// Fewest nodes it needs.
        need: usize,
        /// Nodes sent.
        got: usize,
    },
    /// Two arrays that must pair up have different lengths.
    #[error("'{field}' has {got} entries but 'nodes' has {expected}: send one entry per node")]
    LengthMismatch {
        /// Name of the array in the request.
        field: &'static str,
        /// Entries it has.
        got: usize,
        /// Entries it must have (one per node).
        expected: usize,
    },
    /// A NaN or infinite number.
    #[error("'{field}[{index}]' is not a finite number")]
    NonFinite {
        /// Name of the array in the request.
        field: &'static str,
        /// Index of the first bad entry.
        index: usize,
    },
    /// All nodes share one coordinate on an axis, so the map cannot span 3-D.
    #[error(
        "all nodes have the same {axis} coordinate: a volumetric map needs at least two distinct positions on every axis"
    )]
    FlatAxis {
        /// The flat axis: `x`, `y` or `z`.
        axis: char,
    },
    /// Trilinear interpolation was asked for on nodes that are not a full rectilinear grid.
    #[error(
        "the nodes are not a full rectilinear grid ({reason}); trilinear interpolation needs every combination of the x, y and z levels exactly once: use model \"kinematic\", \"network\", \"hybrid\" or \"auto\""
    )]
    NotAGrid {
        /// Which level combination is missing or repeated.
        reason: String,
    },
    /// Unknown model name.
    #[error("unknown model '{0}': use one of auto, trilinear, network, kinematic, hybrid")]
    UnknownModel(String),
    /// An option is out of its range.
    #[error("option '{name}' {reason}")]
    InvalidOption {
        /// Name of the option (as the API names it).
        name: &'static str,
        /// Its allowed range, as a sentence.
        reason: String,
    },
    /// A CSV body could not be read.
    #[error("CSV line {line}: {reason}")]
    Csv {
        /// 1-based line of the CSV body.
        line: usize,
        /// What is wrong with it.
        reason: String,
    },
    /// Axis-line input (Wang, Dai & Hong §3–4) is inconsistent.
    #[error("axis line '{line}': {reason}")]
    AxisLine {
        /// The line's axis: `x`, `y` or `z`.
        line: char,
        /// What is inconsistent.
        reason: String,
    },
    /// A requested compensation table exceeds the controller's table size.
    #[error(
        "the {axis} axis of the table has {points} points but the controller limit is {limit} per axis: ask for fewer points"
    )]
    TableTooLarge {
        /// The table axis: `x`, `y` or `z`.
        axis: char,
        /// Points asked for on that axis.
        points: usize,
        /// The controller's most points per axis.
        limit: usize,
    },
    /// A stored model could not be decoded.
    #[error("stored volumetric model is unreadable: {0}")]
    ModelFormat(String),
    /// The least-squares or network fit failed numerically.
    #[error("fit failed: {0}")]
    Fit(String),
}
