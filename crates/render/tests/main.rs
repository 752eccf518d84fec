//! The integration tests of this package, in one binary (one link instead of one per file).

mod common;
mod chart;
mod surfaces;
