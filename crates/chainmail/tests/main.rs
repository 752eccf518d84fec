//! The integration tests of this package, in one binary (one link instead of one per file).

mod cbr;
mod conservation;
mod lattice;
mod propagation;
