//! fibfluid: soft tissue as a body of fluid held by elastic fibers.
//!
//! This facade re-exports the workspace's crates under one name, as nalgebra's root does;
//! it holds no logic of its own. A [`Scene`] (a TOML file read by
//! [`fibfluid_scene`], or built in code) carries the engine's [`Model`]; a [`Simulation`]
//! plans the stages the model needs, culls the fibers that leave the body, assembles the
//! bordered system, factors it once with the chosen linear backend and steps the loads; the
//! [`Report`] lists each stage's time and the skipped ones with the reason.
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
//! | module | crate | what |
//! |---|---|---|
//! | [`geometry`] | `fibfluid-geometry` | meshes, OBJ/STL/PLY/OFF, validation, area vectors, fiber visibility |
//! | [`linalg`] | `fibfluid-linalg` | linear backends, capacitance updates, the memory policy |
//! | [`assembly`] | `fibfluid-assembly` | FFM's bordered system |
//! | [`chainmail`] | `fibfluid-chainmail` | Generalized and TSVE ChainMail |
//! | [`sim`] | `fibfluid-sim` | the engine: model, plan, stepping, guards, contact, report |
//! | [`scene`] | `fibfluid-scene` | the scene and path file formats |
//! | [`interact`] | `fibfluid-interact` | interactive bodies, tool paths and their replay |
//! | [`render`] | `fibfluid-render` | PNG renders and charts |
//!
//! Linear backends are chosen at build time by Cargo features (`faer-lu`, `nalgebra-lu`
//! by default, `openblas`) and at run time by [`Backend`] (`structured` is always built).
//! Every choice ([`Backend`], [`Mode`], [`Stepping`], [`Precision`], [`ConstraintKind`],
//! [`Method`]) is an enum with one parser shared by scene files, the command line and
//! reports. [`Plan::from_scene`] says, before any work, which stages a model needs, what
//! they cost, and refuses one that would not fit in memory.

#[cfg(feature = "ndarray")]
pub mod ndarray_io;

pub use fibfluid_scene::{Error, Result, Scene, SceneError, SceneProblem, load_tool_path, parse_tool_path};
pub use fibfluid_sim::{
    Backend, BodyShape, Choice, ConstraintKind, Counters, Direction, FemSettings, ForceTiming, Ineffective,
    LengthUnit, MAX_STEPS, MIN_ADAPTIVE_STEP, Method, Mode, Model, ParseChoiceError, Plan, PlannedStage,
    PointForce, Precision, Report, Response, RoundTrip, RunOptions, SetupOptions, Shape, Simulation,
    SkippedStage, SolverOptions, Stage, StageRecord, State, StepStats, Stepping, Tissue,
    VOLUME_NEWTON_ITERATIONS, VOLUME_TOLERANCE, ineffective, ineffective_interactive, memory_budget,
    roundtrip, roundtrip_error,
};
pub use fibfluid_sim::{contact, guards, plan, stages};

pub use fibfluid_assembly as assembly;
pub use fibfluid_chainmail as chainmail;
pub use fibfluid_fem as fem;
pub use fibfluid_geometry as geometry;
pub use fibfluid_interact as interact;
pub use fibfluid_linalg as linalg;
pub use fibfluid_render as render;
pub use fibfluid_scene as scene;
pub use fibfluid_sim as sim;
