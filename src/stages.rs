//! Which stages a run needs (the plan) and what each cost (the log).

use std::time::Instant;

use serde::Serialize;

/// One stage's accumulated cost.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct StageRecord {
    /// Stage name.
    pub name: String,
    /// Total seconds.
    pub seconds: f64,
    /// How many times it ran.
    pub count: usize,
}

/// A stage the plan left out, and why.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct SkippedStage {
    /// Stage name.
    pub name: String,
    /// Why it was not needed.
    pub reason: String,
}

/// The stages that ran, in first-run order, with their times.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct StageLog {
    /// Stages that ran.
    pub stages: Vec<StageRecord>,
    /// Stages left out.
    pub skipped: Vec<SkippedStage>,
}

impl StageLog {
    /// Runs `f`, adding its time to stage `name`.
    pub fn time<T>(&mut self, name: &str, f: impl FnOnce() -> T) -> T {
        let start = Instant::now();
        let out = f();
        self.add(name, start.elapsed().as_secs_f64());
        out
    }

    /// Adds `seconds` to stage `name`.
    pub fn add(&mut self, name: &str, seconds: f64) {
        match self.stages.iter_mut().find(|s| s.name == name) {
            Some(s) => {
                s.seconds += seconds;
                s.count += 1;
            }
            None => self.stages.push(StageRecord { name: name.to_string(), seconds, count: 1 }),
        }
    }

    /// Records a stage the plan left out.
    pub fn skip(&mut self, name: &str, reason: impl Into<String>) {
        if !self.skipped.iter().any(|s| s.name == name) {
            self.skipped.push(SkippedStage { name: name.to_string(), reason: reason.into() });
        }
    }

    /// Whether stage `name` ran.
    pub fn ran(&self, name: &str) -> bool {
        self.stages.iter().any(|s| s.name == name)
    }

    /// How many times stage `name` ran.
    pub fn count(&self, name: &str) -> usize {
        self.stages.iter().find(|s| s.name == name).map(|s| s.count).unwrap_or(0)
    }
}

/// Stage names used in reports.
pub mod names {
    /// Convexity check of the mesh.
    pub const CONVEXITY: &str = "convexity check";
    /// Exit and crossing tests of the fibers.
    pub const VISIBILITY: &str = "fiber visibility tests";
    /// Vertex area vectors.
    pub const AREAS: &str = "area vectors";
    /// Bulk fibers (Eq. 6) and the Laplacian blocks.
    pub const ASSEMBLY: &str = "assembly";
    /// Surface fibers (Eq. 7).
    pub const SURFACE_FIBERS: &str = "surface fibers";
    /// Factorization of the system.
    pub const FACTORIZATION: &str = "factorization";
    /// Depth of each vertex below the top.
    pub const DEPTHS: &str = "depths";
    /// Hydrostatic load rho a h S.
    pub const HYDROSTATIC: &str = "hydrostatic load";
    /// Point forces.
    pub const FORCES: &str = "point forces";
    /// New border S from the current shape.
    pub const BORDER: &str = "border refresh";
    /// Volume of the current shape (for the volume target).
    pub const VOLUME: &str = "volume target";
    /// Solves that pull the volume back to V0 after a step.
    pub const VOLUME_CORRECTION: &str = "volume correction";
    /// Re-assembly on the current shape.
    pub const REASSEMBLY: &str = "re-assembly";
    /// Linear solves.
    pub const SOLVE: &str = "solve";
    /// Position update.
    pub const UPDATE: &str = "geometry update";
    /// Heun's predictor evaluation.
    pub const PREDICTOR: &str = "predictor";
}
