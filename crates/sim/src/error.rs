//! The engine's error type.

/// Everything that can go wrong while setting up or running a simulation.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A mesh file could not be read or is not a valid closed surface.
    #[error(transparent)]
    Geometry(#[from] fibfluid_geometry::GeometryError),
    /// Assembling the system failed (bad material, constraints).
    #[error("assembly: {0}")]
    Assembly(#[from] fibfluid_assembly::AssemblyError),
    /// A linear solve failed (singular system, residual too large).
    #[error("linear solver: {0}")]
    Linalg(#[from] fibfluid_linalg::LinalgError),
    /// The finite-element method failed (grid, tissue, factorization, solve).
    #[error("{scene}: fem: {source}")]
    Fem {
        /// The scene.
        scene: String,
        /// What failed.
        source: fibfluid_fem::FemError,
    },
    /// A `[[region]]` holds no part of the body: named with where its shape comes from.
    #[error(
        "{scene}: fem: {name} ({origin}) lies outside the body: none of its points is inside the surface"
    )]
    RegionOutsideBody {
        /// The scene.
        scene: String,
        /// The region's name (`[[region]] name`, or `region k`).
        name: String,
        /// Where its shape comes from (`mesh lesion.obj`, `box`, `label 2`).
        origin: String,
    },
    /// The model lacks what its method needs, or asks what the method cannot do.
    #[error("{scene}: {method}: {problem}")]
    MethodNeeds {
        /// The scene.
        scene: String,
        /// The method.
        method: crate::Method,
        /// What is missing or unsupported.
        problem: &'static str,
    },
    /// A load or query names a vertex the body does not have.
    #[error("vertex {vertex} does not exist: the body has {vertices} vertices")]
    VertexOutOfRange {
        /// The vertex asked for.
        vertex: usize,
        /// Vertex count.
        vertices: usize,
    },
    /// A vertex fixed by the scene cannot be held somewhere else.
    #[error("vertex {vertex} is fixed by the scene and cannot be held at a displacement")]
    HeldFixedVertex {
        /// The vertex.
        vertex: usize,
    },
    /// The plan needs more memory than the limit; refused before anything was allocated.
    #[error(
        "{scene}: the plan needs {needed} bytes ({:.2} GiB) at its largest stage ({stage}), but {available} bytes ({:.2} GiB) are available; {hint}",
        *needed as f64 / GIB, *available as f64 / GIB
    )]
    TooLarge {
        /// Scene name.
        scene: String,
        /// The stage that needs the most memory.
        stage: crate::stages::Stage,
        /// Bytes needed.
        needed: u64,
        /// Bytes available (the machine's memory or the given limit).
        available: u64,
        /// What to change.
        hint: &'static str,
    },
    /// A numeric failure during a load step, with its likely cause in the user's terms.
    #[error("step {step} (load {from:.4} -> {to:.4}): {cause}; {hint} ({source})")]
    Step {
        /// The step (1-based).
        step: usize,
        /// Load factor at the start of the step.
        from: f64,
        /// Load factor the step was going to.
        to: f64,
        /// What went wrong, named (a vertex, a pivot).
        cause: String,
        /// What to try.
        hint: &'static str,
        /// The failure as the solver reported it.
        source: Box<Error>,
    },
    /// A step guard fired under `[guards] on_failure = "error"`.
    #[error("{0} (stopped: [guards] on_failure = \"error\")")]
    Guard(crate::guards::GuardWarning),
    /// Adaptive stepping could not meet its tolerance.
    #[error(
        "adaptive steps shrank below 1e-6 of the load at load factor {load_factor:.6} without meeting tolerance {tolerance:e}; the response may be unstable there: raise the tolerance or check the material and constraints"
    )]
    StepTooSmall {
        /// Load factor reached.
        load_factor: f64,
        /// The tolerance asked for.
        tolerance: f64,
    },
    /// The answer has a non-finite position: nothing is written from it.
    #[error(
        "{scene}: {method}: the answer is not finite at vertex {vertex}: the tissue (or fiber modulus) is far too soft for its loads, or the constraints do not hold the body"
    )]
    NonFiniteAnswer {
        /// The scene.
        scene: String,
        /// The method that gave it.
        method: crate::Method,
        /// The first vertex whose position is not finite.
        vertex: usize,
    },
    /// Vertices that keep no fiber inside the body after culling, with no surface fibers
    /// to hold them instead.
    #[error(
        "{scene}: ffm: {count} vertices keep no fiber inside the body after culling, so nothing holds them (file vertices {vertices}): give [ffm] surface_tension > 0 (surface fibers hold every vertex), or use a coarser or smoothed mesh; `fibfluid mesh-info --fibers` shows the kept fibers"
    )]
    UnheldVertices {
        /// The scene.
        scene: String,
        /// The first vertices (file order), listed.
        vertices: String,
        /// How many.
        count: usize,
    },
    /// Two plates facing each other whose travels close the gap between them during the
    /// load, found from the scene before anything is built.
    #[error(
        "{scene}: [[plate]] #{first} and [[plate]] #{second} meet at load factor {load_factor:.4}: they face each other {gap:.3e} m apart at rest and their travels close {closing:.3e} m, so the body would have to pass through a plate; make their travels add up to less than the gap (less than the body's thickness there, in practice)"
    )]
    PlatesMeet {
        /// The scene.
        scene: String,
        /// The first plate (1-based, as `[[plate]] #k`).
        first: usize,
        /// The second plate (1-based).
        second: usize,
        /// The load factor where they meet.
        load_factor: f64,
        /// Their gap at rest (m).
        gap: f64,
        /// How much their travels close it (m).
        closing: f64,
    },
    /// The caller stopped the run ([`crate::RunOptions::cancel`]) before a load step.
    #[error("stopped at load factor {load_factor:.4} (interrupted)")]
    Cancelled {
        /// The load factor of the last finished step.
        load_factor: f64,
    },
    /// The observed file of a fit (or its `[fit]` input) is wrong: named with the line.
    #[error("{}{}: {problem}", path.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
    FitInput {
        /// The file.
        path: std::path::PathBuf,
        /// The line (1-based), where one is to blame.
        line: Option<usize>,
        /// What is wrong.
        problem: String,
    },
    /// The contact active set kept changing.
    #[error(
        "step {step}: the plate contacts did not settle after {iterations} active-set iterations; take more load steps"
    )]
    ContactNotConverged {
        /// The step.
        step: usize,
        /// Iterations made.
        iterations: usize,
    },
}

const GIB: f64 = 1024.0 * 1024.0 * 1024.0;

/// Result alias of the engine.
pub type Result<T> = std::result::Result<T, Error>;
