//! Load stepping: the simulation of one scene.
//!
//! A [`Simulation`] holds four things: the [`BodyShape`] (boundary, fibers, rest shape;
//! fixed once set up), the [`State`] (positions, pressure, how much of the load is
//! applied), the factored system (assembled matrix, its factorization, the border it
//! describes) and the [`Counters`] (solves, factorizations, residuals). Loads move through
//! one call, [`Simulation::step_load`], which takes the load factor from where it is to a
//! new value; [`Simulation::run`] and [`Simulation::run_steps`] are equal steps of it.

mod contact_steps;
mod core;
mod factored;
mod response;
mod setup;
mod solve;
mod state;
mod stepping;

pub use self::core::Simulation;
pub use setup::check_every_vertex_is_held;
pub(crate) use setup::refuse_projected;
pub use state::{
    BodyShape, Counters, Direction, MIN_ADAPTIVE_STEP, Response, RunOptions, SetupOptions, State, StepStats,
};
