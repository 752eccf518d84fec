//! Load stepping: the simulation of one scene.
//!
//! A [`Simulation`] holds four things: the [`BodyShape`] (boundary, fibers, rest shape;
//! fixed once set up), the [`State`] (positions, pressure, how much of the load is
//! applied), the factored system (assembled matrix, its factorization, the border it
//! describes) and the [`Counters`] (solves, factorizations, residuals). Loads move through
//! one call, [`Simulation::step_load`], which takes the load factor from where it is to a
//! new value; [`Simulation::run`] and [`Simulation::run_steps`] are equal steps of it.
//!
//! Each stage lives in a module of its own, its state in a type of its own; the modules
//! import `core` (the struct) and the data modules, never each other:
//!
//! | module | stage | its state |
//! |---|---|---|
//! | `state` | the data: options, body, state, counters, the contact stage's [`PlateContact`](state::PlateContact) | — |
//! | `factored` | the assembled operator and its factorization (paper's or projected fibers) | `Factored`, `Coupled`, `Holds` |
//! | `setup` | plan, fibers, areas, assembly, first factorization (after the calibration step of [`crate::pipeline`]) | — |
//! | `stepping` | fixed and adaptive load steps, the step guards | `StepStats`, guard warnings |
//! | `contact_steps` | plate contact inside a step: active set, forces, records | `PlateContact` |
//! | `solve` | the operator of a step (border refresh or refactorization), volume correction, solves | — |
//! | `response` | the interactive response: forces and held vertices on the kept factorization | `Holds` |

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
