//! What each stage of a run cost: a log of stage times in which nested work is a
//! sub-stage, so the top-level times never add up to more than the run.

use std::time::Instant;

use fibfluid_linalg::{Choice, impl_choice};
use serde::Serialize;

/// One stage's accumulated cost.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct StageRecord {
    /// The stage.
    pub name: Stage,
    /// The stage this one ran inside (`None`: a top-level stage).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub parent: Option<Stage>,
    /// Total seconds.
    pub seconds: f64,
    /// How many times it ran.
    pub count: usize,
}

/// The stages that ran, in first-run order, with their times.
///
/// [`time`](Self::time) and [`add`](Self::add) record under the innermost stage opened
/// with [`begin`](Self::begin), so time spent inside an open stage is counted once at the
/// top level.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StageLog {
    stages: Vec<StageRecord>,
    open: Vec<(Stage, Instant)>,
}

/// An open stage, closed by [`StageLog::end`].
#[must_use = "close the stage with StageLog::end"]
#[derive(Debug)]
pub struct OpenStage(usize);

impl StageLog {
    /// Runs `f`, adding its time to stage `name`.
    pub fn time<T>(&mut self, name: Stage, f: impl FnOnce() -> T) -> T {
        let start = Instant::now();
        let out = f();
        self.add(name, start.elapsed().as_secs_f64());
        out
    }

    /// Adds `seconds` to stage `name` (a sub-stage of the innermost open stage).
    pub fn add(&mut self, name: Stage, seconds: f64) {
        let parent = self.open.last().map(|(p, _)| *p);
        match self.stages.iter_mut().find(|s| s.name == name && s.parent == parent) {
            Some(s) => {
                s.seconds += seconds;
                s.count += 1;
            }
            None => self.stages.push(StageRecord { name, parent, seconds, count: 1 }),
        }
    }

    /// Opens stage `name`: what is timed until [`end`](Self::end) is its sub-stage.
    pub fn begin(&mut self, name: Stage) -> OpenStage {
        self.open.push((name, Instant::now()));
        OpenStage(self.open.len())
    }

    /// Closes a stage opened by [`begin`](Self::begin) and adds its time.
    pub fn end(&mut self, stage: OpenStage) {
        debug_assert_eq!(stage.0, self.open.len(), "stages close in the order they opened");
        if let Some((name, start)) = self.open.pop() {
            self.add(name, start.elapsed().as_secs_f64());
        }
    }

    /// Every record, top-level stages and sub-stages, in first-run order.
    pub fn records(&self) -> &[StageRecord] {
        &self.stages
    }

    /// Seconds of the top-level stages (never more than the run's wall time).
    pub fn top_level_seconds(&self) -> f64 {
        self.stages.iter().filter(|s| s.parent.is_none()).map(|s| s.seconds).sum()
    }

    /// Whether stage `name` ran (at any level).
    pub fn ran(&self, name: Stage) -> bool {
        self.stages.iter().any(|s| s.name == name)
    }

    /// How many times stage `name` ran (at any level).
    pub fn count(&self, name: Stage) -> usize {
        self.stages.iter().filter(|s| s.name == name).map(|s| s.count).sum()
    }
}

/// A stage of a run, as plans and reports name it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Stage {
    /// Reading the scene and its mesh.
    LoadScene,
    /// Calibrating FFM's fiber modulus against the FEM (a scene with only `[tissue]`).
    Calibration,
    /// Convexity check of the mesh.
    Convexity,
    /// Exit and crossing tests of the fibers.
    Visibility,
    /// The finite-element method's sparse voxel grid (active cells, fill, embedding).
    Voxelization,
    /// Vertex area vectors.
    Areas,
    /// Bulk fibers (Eq. 6) and the Laplacian blocks.
    Assembly,
    /// Surface fibers (Eq. 7), part of the assembly.
    SurfaceFibers,
    /// Factorization of the system.
    Factorization,
    /// The load vector: hydrostatic pressure and point forces.
    Loads,
    /// New border S from the current shape.
    Border,
    /// Volume of the current shape (for the volume target).
    Volume,
    /// Re-assembly on the current shape.
    Reassembly,
    /// Linear solves.
    Solve,
    /// Solves that pull the volume back to V0 after a step.
    VolumeCorrection,
    /// Heun's predictor evaluation.
    Predictor,
    /// Contact constraints set up on the kept factorization (one solve per new contact).
    Contact,
    /// Position update.
    Update,
    /// A timed run's steps (`[time]`).
    TimeSteps,
    /// Writing the output files.
    Outputs,
}

impl Choice for Stage {
    const WHAT: &'static str = "stage";
    const ALL: &'static [Self] = &[
        Stage::LoadScene,
        Stage::Calibration,
        Stage::Convexity,
        Stage::Visibility,
        Stage::Voxelization,
        Stage::Areas,
        Stage::Assembly,
        Stage::SurfaceFibers,
        Stage::Factorization,
        Stage::Loads,
        Stage::Border,
        Stage::Volume,
        Stage::Reassembly,
        Stage::Solve,
        Stage::VolumeCorrection,
        Stage::Predictor,
        Stage::Contact,
        Stage::Update,
        Stage::TimeSteps,
        Stage::Outputs,
    ];
    fn name(self) -> &'static str {
        match self {
            Stage::LoadScene => "load scene and mesh",
            Stage::Calibration => "calibration against the FEM",
            Stage::Convexity => "convexity check",
            Stage::Visibility => "fiber visibility tests",
            Stage::Voxelization => "voxelization",
            Stage::Areas => "area vectors",
            Stage::Assembly => "assembly",
            Stage::SurfaceFibers => "surface fibers",
            Stage::Factorization => "factorization",
            Stage::Loads => "loads",
            Stage::Border => "border refresh",
            Stage::Volume => "volume target",
            Stage::Reassembly => "re-assembly",
            Stage::Solve => "solve",
            Stage::VolumeCorrection => "volume correction",
            Stage::Predictor => "predictor",
            Stage::Contact => "contact constraints",
            Stage::Update => "geometry update",
            Stage::TimeSteps => "time steps",
            Stage::Outputs => "outputs",
        }
    }
}
impl_choice!(Stage);

/// The stages under their constant names (`names::ASSEMBLY` is [`Stage::Assembly`]).
pub mod names {
    use super::Stage;
    /// Reading the scene and its mesh.
    pub const LOAD_SCENE: Stage = Stage::LoadScene;
    /// Calibrating FFM's fiber modulus against the FEM.
    pub const CALIBRATION: Stage = Stage::Calibration;
    /// Convexity check of the mesh.
    pub const CONVEXITY: Stage = Stage::Convexity;
    /// Exit and crossing tests of the fibers.
    pub const VISIBILITY: Stage = Stage::Visibility;
    /// The finite-element method's sparse voxel grid.
    pub const VOXELIZATION: Stage = Stage::Voxelization;
    /// Vertex area vectors.
    pub const AREAS: Stage = Stage::Areas;
    /// Bulk fibers (Eq. 6) and the Laplacian blocks.
    pub const ASSEMBLY: Stage = Stage::Assembly;
    /// Surface fibers (Eq. 7), part of the assembly.
    pub const SURFACE_FIBERS: Stage = Stage::SurfaceFibers;
    /// Factorization of the system.
    pub const FACTORIZATION: Stage = Stage::Factorization;
    /// The load vector: hydrostatic pressure and point forces.
    pub const LOADS: Stage = Stage::Loads;
    /// New border S from the current shape.
    pub const BORDER: Stage = Stage::Border;
    /// Volume of the current shape (for the volume target).
    pub const VOLUME: Stage = Stage::Volume;
    /// Re-assembly on the current shape.
    pub const REASSEMBLY: Stage = Stage::Reassembly;
    /// Linear solves.
    pub const SOLVE: Stage = Stage::Solve;
    /// Solves that pull the volume back to V0 after a step.
    pub const VOLUME_CORRECTION: Stage = Stage::VolumeCorrection;
    /// Heun's predictor evaluation.
    pub const PREDICTOR: Stage = Stage::Predictor;
    /// Contact constraints set up on the kept factorization (one solve per new contact).
    pub const CONTACT: Stage = Stage::Contact;
    /// Position update.
    pub const UPDATE: Stage = Stage::Update;
    /// A timed run's steps.
    pub const TIME_STEPS: Stage = Stage::TimeSteps;
    /// Writing the output files.
    pub const OUTPUTS: Stage = Stage::Outputs;
}
