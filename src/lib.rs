//! fibfluid: soft tissue as a body of fluid held by elastic fibers.
//!
//! This facade runs the fiber–fluid method (FFM; Sardinha, Oyama, Maroja, Costa, Source
//! Code for Biology and Medicine 11:7, 2016, after Costa, Med Image Anal 16, 2012) on a
//! closed surface: a [`Scene`] (mesh, material, constraints, loads, solver choices, from a
//! TOML file or built in code) is turned into a [`Simulation`] that culls the fibers that
//! leave the body, assembles the bordered system, factors it once with the chosen linear
//! backend and steps the loads. Only the stages the scene needs run; the [`Report`] lists
//! each stage's time and the skipped ones with the reason.
//!
//! ```no_run
//! use fibfluid::{RunOptions, Scene, Simulation};
//! let scene = Scene::load("fixtures/scenes/sphere.toml")?;
//! let mut sim = Simulation::new(scene)?;
//! sim.run(&RunOptions::default())?;
//! println!("volume {} -> {}", sim.volume_initial(), sim.volume());
//! # Ok::<(), fibfluid::Error>(())
//! ```
//!
//! Linear backends are chosen at build time by Cargo features (`faer-lu`, `nalgebra-lu`
//! by default, `openblas`) and at run time by [`Backend`] (`structured` is always built).
//! Every choice ([`Backend`], [`Mode`], [`Stepping`], [`Precision`], [`ConstraintKind`])
//! is an enum with one parser shared by scene files, the command line and reports.
//! [`Plan::from_scene`] says, before any work, which stages a scene needs, what they cost,
//! and refuses a scene that would not fit in memory.

pub mod accuracy;
pub mod bench;
pub mod chainmail_body;
pub mod chainmail_scene;
pub mod compare;
pub mod contact;
mod effects;
mod error;
pub mod guards;
mod info;
#[cfg(feature = "ndarray")]
pub mod ndarray_io;
mod output;
pub mod plan;
pub mod probe;
mod report;
mod scene;
mod simulate;
pub mod stages;

pub use effects::{Ineffective, ineffective};
pub use error::{Error, Result, SceneError, SceneProblem};
pub use info::MeshInfo;
pub use output::{
    COMPRESSION_FILE, OUTPUT_FILES, compression_png, render_png, write_fibers_vtk, write_files_atomically,
    write_outputs, write_vtk,
};
pub use plan::{Plan, PlannedStage};
pub use report::{Report, RoundTrip, SkippedStage, roundtrip, roundtrip_error};
pub use scene::{ForceTiming, MAX_STEPS, Mode, PointForce, Scene, Shape, SolverOptions, Stepping};
pub use simulate::{
    BodyShape, Counters, Direction, MIN_ADAPTIVE_STEP, Response, RunOptions, SetupOptions, Simulation, State,
    StepStats, VOLUME_NEWTON_ITERATIONS, VOLUME_TOLERANCE,
};

pub use fibfluid_assembly::ConstraintKind;
pub use fibfluid_linalg::{Backend, Choice, ParseChoiceError, Precision};

pub use fibfluid_assembly as assembly;
pub use fibfluid_geometry as geometry;
pub use fibfluid_linalg as linalg;
pub use fibfluid_render as render;
