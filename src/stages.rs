//! What each stage of a run cost: a log of stage times in which nested work is a
//! sub-stage, so the top-level times never add up to more than the run.

use std::time::Instant;

use serde::Serialize;

/// One stage's accumulated cost.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct StageRecord {
    /// Stage name.
    pub name: String,
    /// The stage this one ran inside (`None`: a top-level stage).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub parent: Option<String>,
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
    open: Vec<(&'static str, Instant)>,
}

/// An open stage, closed by [`StageLog::end`].
#[must_use = "close the stage with StageLog::end"]
#[derive(Debug)]
pub struct OpenStage(usize);

impl StageLog {
    /// Runs `f`, adding its time to stage `name`.
    pub fn time<T>(&mut self, name: &'static str, f: impl FnOnce() -> T) -> T {
        let start = Instant::now();
        let out = f();
        self.add(name, start.elapsed().as_secs_f64());
        out
    }

    /// Adds `seconds` to stage `name` (a sub-stage of the innermost open stage).
    pub fn add(&mut self, name: &'static str, seconds: f64) {
        let parent = self.open.last().map(|(p, _)| *p);
        match self.stages.iter_mut().find(|s| s.name == name && s.parent.as_deref() == parent) {
            Some(s) => {
                s.seconds += seconds;
                s.count += 1;
            }
            None => self.stages.push(StageRecord {
                name: name.to_string(),
                parent: parent.map(String::from),
                seconds,
                count: 1,
            }),
        }
    }

    /// Opens stage `name`: what is timed until [`end`](Self::end) is its sub-stage.
    pub fn begin(&mut self, name: &'static str) -> OpenStage {
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
    pub fn ran(&self, name: &str) -> bool {
        self.stages.iter().any(|s| s.name == name)
    }

    /// How many times stage `name` ran (at any level).
    pub fn count(&self, name: &str) -> usize {
        self.stages.iter().filter(|s| s.name == name).map(|s| s.count).sum()
    }
}

/// Stage names used in plans and reports.
pub mod names {
    /// Reading the scene and its mesh.
    pub const LOAD_SCENE: &str = "load scene and mesh";
    /// Convexity check of the mesh.
    pub const CONVEXITY: &str = "convexity check";
    /// Exit and crossing tests of the fibers.
    pub const VISIBILITY: &str = "fiber visibility tests";
    /// Vertex area vectors.
    pub const AREAS: &str = "area vectors";
    /// Bulk fibers (Eq. 6) and the Laplacian blocks.
    pub const ASSEMBLY: &str = "assembly";
    /// Surface fibers (Eq. 7), part of the assembly.
    pub const SURFACE_FIBERS: &str = "surface fibers";
    /// Factorization of the system.
    pub const FACTORIZATION: &str = "factorization";
    /// The load vector: hydrostatic pressure and point forces.
    pub const LOADS: &str = "loads";
    /// New border S from the current shape.
    pub const BORDER: &str = "border refresh";
    /// Volume of the current shape (for the volume target).
    pub const VOLUME: &str = "volume target";
    /// Re-assembly on the current shape.
    pub const REASSEMBLY: &str = "re-assembly";
    /// Linear solves.
    pub const SOLVE: &str = "solve";
    /// Solves that pull the volume back to V0 after a step.
    pub const VOLUME_CORRECTION: &str = "volume correction";
    /// Heun's predictor evaluation.
    pub const PREDICTOR: &str = "predictor";
    /// Contact constraints set up on the kept factorization (one solve per new contact).
    pub const CONTACT: &str = "contact constraints";
    /// Position update.
    pub const UPDATE: &str = "geometry update";
    /// Writing the output files.
    pub const OUTPUTS: &str = "outputs";
}
