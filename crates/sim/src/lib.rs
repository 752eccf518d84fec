//! The fibfluid engine: a validated [`Model`] (body, material, constraints, loads, solver
//! choices, in code values) turned into a [`Simulation`] that plans its stages, assembles
//! and factors the fiber–fluid system once, steps the loads with guards and plate contact,
//! and reports what each stage cost.
//!
//! The fiber–fluid method (FFM) is Costa's (Med Image Anal 16, 2012) as published by
//! Sardinha, Oyama, Maroja and Costa (Source Code for Biology and Medicine 11:7, 2016): the
//! body is a fluid of constant volume held by elastic fibers between every pair of surface
//! vertices that see each other; each load step solves the bordered system
//! `[K S; S' 0] [u; P] = [f; g]` (REFERENCE §3–5).
//!
//! This crate knows no file format, no renderer and no ChainMail: the scene crate builds a
//! [`Model`] from a TOML file, code builds one directly ([`Model::from_mesh`]).
//!
//! - [`Plan`]: which stages a model needs, what each costs in bytes and flops, and a
//!   refusal before anything large is allocated.
//! - [`Simulation`]: load stepping (`paper`, `refresh`, `nonlinear` modes; Euler, Heun or
//!   adaptive steps), [`guards`] after every step, frictionless [`contact`] with rigid
//!   plates through capacitance rows on the kept factorization.
//! - [`Report`]: the data of `report.json` (stages, counters, warnings, plates).
//! - [`inverse_fit`]: the tissues' parameters fitted to observed surface positions (`[fit]`).

pub mod accuracy;
pub mod calibration;
mod choices;
pub mod contact;
mod effects;
mod error;
mod fem_inputs;
pub mod fem_run;
mod fit;
pub mod guards;
pub mod hyper_run;
pub mod inverse;
pub mod inverse_fit;
mod model;
mod pipeline;
pub mod plan;
mod report;
pub mod result_guards;
#[cfg(feature = "testing")]
pub mod samples;
mod simulate;
pub mod stages;

pub use choices::{FiberModel, ForceTiming, Method, Mode, Stepping};
pub use effects::{Ineffective, ineffective, ineffective_interactive};
pub use error::{Error, Result};
/// The length unit of a mesh file (`[mesh] unit`), shared with the label images.
pub use fibfluid_geometry::LengthUnit;
pub use model::{
    FemSettings, FfmSettings, Load, MAX_STEPS, Model, NamedPressure, NamedRegion, PLATE_REST_TOLERANCE,
    PointForce, Shape, SolverOptions, TimedRun, VOLUME_NEWTON_ITERATIONS, VOLUME_TOLERANCE,
};
pub use plan::{Plan, PlannedStage};
pub use report::{
    BodyFacts, CostFacts, FfmFacts, GuardFacts, Report, ResultFacts, RoundTrip, SkippedStage, SolverFacts,
    StepFacts, roundtrip, roundtrip_error,
};
pub use simulate::{
    BodyShape, Counters, Direction, MIN_ADAPTIVE_STEP, Response, RunOptions, SetupOptions, Simulation, State,
    StepStats, check_every_vertex_is_held,
};
pub use stages::{Stage, StageLog, StageRecord};

pub use fibfluid_assembly::ConstraintKind;
pub use fibfluid_fem::Tissue;
pub use fibfluid_linalg::{Backend, Choice, ParseChoiceError, Precision, memory_budget};
