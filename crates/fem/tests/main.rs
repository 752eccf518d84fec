//! The integration tests of this package, in one binary (one link instead of one per file).

mod beam;
mod clamp;
mod common;
mod errors;
mod golden;
mod held;
mod hyper;
mod law;
mod multigrid;
mod ordering;
mod patch;
mod point_force;
mod pressure;
mod region;
mod sensitivity;
mod time;
mod tracking;
