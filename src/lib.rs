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
//! by default, `openblas`) and at run time by name (`structured`, always built).

pub mod accuracy;
pub mod bench;
mod effects;
mod error;
mod output;
mod report;
mod scene;
mod simulate;
pub mod stages;

pub use effects::{Ineffective, ineffective};
pub use error::{Error, Result};
pub use output::{
    OUTPUT_FILES, render_png, write_fibers_vtk, write_files_atomically, write_outputs, write_vtk,
};
pub use report::{Report, RoundTrip, roundtrip, roundtrip_error};
pub use scene::{ForceTiming, Mode, PointForce, Scene, Shape, SolverOptions, Stepping};
pub use simulate::{Direction, RunOptions, Simulation};

pub use fibfluid_assembly as assembly;
pub use fibfluid_geometry as geometry;
pub use fibfluid_linalg as linalg;
pub use fibfluid_render as render;
