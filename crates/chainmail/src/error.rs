//! The crate's error type.

use thiserror::Error;

/// Everything that can go wrong in this crate. No public function panics on bad input;
/// it returns one of these instead.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ChainmailError {
    /// A material or option parameter is out of its allowed range (negative alpha,
    /// `alpha_min > alpha_max`, non-finite value, non-positive spacing, ...).
    #[error("invalid parameter `{name}`: {reason}")]
    InvalidParameter {
        /// Name of the offending parameter.
        name: &'static str,
        /// Why it was rejected.
        reason: String,
    },
    /// The lattice would have no chain element (empty grid, or a surface whose interior
    /// contains no grid node at the chosen spacing).
    #[error("the lattice has no chain element")]
    EmptyLattice,
    /// The grid requested is larger than [`crate::MAX_GRID_NODES`].
    #[error("grid of {nodes} nodes exceeds the limit of {limit}")]
    LatticeTooLarge {
        /// Number of grid nodes requested.
        nodes: u128,
        /// The limit.
        limit: usize,
    },
    /// An element (or vertex) index is not below the number of elements (vertices).
    #[error("index {index} out of range (length {len})")]
    IndexOutOfRange {
        /// The index given.
        index: usize,
        /// The length it must be below.
        len: usize,
    },
    /// A per-element array does not have one entry per chain element.
    #[error("expected {expected} per-element values, found {found}")]
    LengthMismatch {
        /// Number of chain elements.
        expected: usize,
        /// Length supplied.
        found: usize,
    },
    /// A target position (or input vertex) has a NaN or infinite coordinate.
    #[error("non-finite coordinate for item {index}")]
    NonFinite {
        /// Index of the offending target or vertex.
        index: usize,
    },
    /// The same element appears twice in a list of moves.
    #[error("element {index} is moved twice in one call")]
    DuplicateElement {
        /// The repeated element.
        index: usize,
    },
}

/// Result alias used throughout the crate.
pub type Result<T> = std::result::Result<T, ChainmailError>;
