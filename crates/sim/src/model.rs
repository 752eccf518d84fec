//! The model a simulation runs: a body, its material, constraints, loads and solver
//! choices, as validated values (the scene crate builds them from files; code builds them
//! directly).

use std::path::PathBuf;

use fibfluid_assembly::{ConstraintKind, ConstraintMethod, Constraints, DEFAULT_PENALTY, Material};
use fibfluid_geometry::{LengthUnit, MeshFile, Polygon, Vec3};
use fibfluid_linalg::{Backend, Precision};

use crate::choices::{ForceTiming, Method, Mode, Stepping};

use crate::contact::Plate;
use crate::guards::Guards;

/// A point force on a vertex (mesh index).
#[derive(Clone, Debug, PartialEq)]
pub struct PointForce {
    /// Vertex, in the mesh's (compacted) order.
    pub vertex: usize,
    /// Force vector.
    pub value: Vec3,
    /// When it is applied.
    pub timing: ForceTiming,
}

/// The loads of a model and how they are stepped.
#[derive(Clone, Debug, PartialEq)]
pub struct Load {
    /// Final acceleration, reached in `steps` equal increments.
    pub gravity: Vec3,
    /// Point forces.
    pub forces: Vec<PointForce>,
    /// Number of load steps (with `tolerance`: the first step is 1/steps of the load).
    pub steps: usize,
    /// Adaptive load steps: the largest error estimate of a step, relative to the step's
    /// displacement (`[load] tolerance`); `None`: `steps` equal steps.
    pub tolerance: Option<f64>,
}

impl Default for Load {
    /// No loads, one step.
    fn default() -> Self {
        Self { gravity: [0.0; 3], forces: vec![], steps: 1, tolerance: None }
    }
}

/// Solver choices.
#[derive(Clone, Debug, PartialEq)]
pub struct SolverOptions {
    /// Linear backend.
    pub backend: Backend,
    /// Stepping mode.
    pub mode: Mode,
    /// Stepping scheme.
    pub stepping: Stepping,
    /// Factorization precision.
    pub precision: Precision,
    /// How fixed degrees of freedom are imposed.
    pub constraints: ConstraintKind,
    /// The penalty's diagonal value (used when `constraints` is `penalty`).
    pub penalty: f64,
    /// The method a batch run uses (`[solver] method`): FFM or the FEM.
    pub method: Method,
}

impl SolverOptions {
    /// The constraint method these options describe.
    pub fn constraint_method(&self) -> ConstraintMethod {
        ConstraintMethod::of_kind(self.constraints, self.penalty)
    }
}

impl Default for SolverOptions {
    /// Structured backend, refresh mode, Euler steps, f64, elimination.
    fn default() -> Self {
        Self {
            backend: Backend::Structured,
            mode: Mode::Refresh,
            stepping: Stepping::Euler,
            precision: Precision::F64,
            constraints: ConstraintKind::Eliminate,
            penalty: DEFAULT_PENALTY,
            method: Method::Ffm,
        }
    }
}

/// The body: a closed triangle surface or the paper's 2D polygon.
#[derive(Clone, Debug)]
pub enum Shape {
    /// A closed surface read from a file (or built in code).
    Surface(Box<MeshFile>),
    /// A closed polygon (2D variant).
    Polygon(Polygon),
}

/// A model: everything a run needs, validated.
#[derive(Clone, Debug)]
pub struct Model {
    /// Name (the file stem).
    pub name: String,
    /// The scene file, when read from one.
    pub source: Option<PathBuf>,
    /// The body.
    pub shape: Shape,
    /// Material.
    pub material: Material,
    /// Constraints (per vertex and axis).
    pub constraints: Constraints,
    /// The loads and how they are stepped (`[gravity]`, `[[force]]`, `[load]`).
    pub load: Load,
    /// Step guards (`[guards]`).
    pub guards: Guards,
    /// Rigid plates (`[[plate]]`), moving along their normals over the load.
    pub plates: Vec<Plate>,
    /// Solver choices.
    pub solver: SolverOptions,
    /// What the tissue is, in SI units (`[tissue]`): the finite-element method's material.
    pub tissue: Option<fibfluid_fem::Tissue>,
    /// The finite-element method's settings (`[fem]`).
    pub fem: FemSettings,
    /// The fiber–fluid method's fiber settings (`[ffm]`).
    pub ffm: FfmSettings,
    /// The length unit of the mesh file: positions inside are in metres.
    pub unit: LengthUnit,
}

/// The fiber–fluid method's fiber settings (`[ffm]`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FfmSettings {
    /// How a fiber resists (`fibers`).
    pub fibers: crate::choices::FiberModel,
    /// Whether the fiber modulus is to be calibrated on the body against the
    /// finite-element method before a run (a scene that gives only `[tissue]`; the
    /// material's fiber modulus is then the tissue's Young's modulus until calibrated).
    pub calibrate: bool,
}

/// The finite-element method's settings (`[fem]`) and the regions of other tissue
/// (`[[region]]`).
#[derive(Clone, Debug, PartialEq)]
pub struct FemSettings {
    /// Cells along the bounding box's longest side.
    pub resolution: usize,
    /// The linear solver (`[fem] solver`: auto, direct or multigrid).
    pub solver: fibfluid_fem::FemSolver,
    /// Regions of other tissue inside the body, in the scene's order (region ids 1, 2,
    /// ...).
    pub regions: Vec<NamedRegion>,
    /// `[tissue] model = "auto"`: solve linear, and again neo-Hookean when the linear
    /// answer's largest strain is above `result_guards::LINEAR_STRAIN_LIMIT`.
    pub auto_model: bool,
    /// Grasps (`[[grasp]]`): patches of the surface moved rigidly with the load factor;
    /// vertices are mesh indices, lengths in metres.
    pub grasps: Vec<fibfluid_fem::hyper::Grasp>,
    /// A run through time (`[time]`, `[load] curve`); `None`: one equilibrium.
    pub time: Option<TimedRun>,
    /// `[fem] tolerance`: the resolution grows from `resolution` until the surface
    /// displacement's estimated relative discretization error is at most this
    /// ([`crate::accuracy`]); `None`: `resolution` as set.
    pub tolerance: Option<f64>,
    /// `[fit]`: the parameters to fit to observed surface positions (`fibfluid fit`).
    pub fit: Option<FitSpec>,
    /// Pressures (`[[pressure]]`) on faces of the surface, in the scene's order.
    pub pressures: Vec<NamedPressure>,
}

/// A pressure with the surface the scene names (`outer`, `cavity K` or `box`).
#[derive(Clone, Debug, PartialEq)]
pub struct NamedPressure {
    /// The surface as the scene names it.
    pub surface: String,
    /// The pressure (Pa) and its faces (mesh indices).
    pub pressure: fibfluid_fem::hyper::Pressure,
}

/// A run through time: how it steps and the load curve every load follows.
#[derive(Clone, Debug, PartialEq)]
pub struct TimedRun {
    /// End, step, inertia, damping and output interval.
    pub settings: fibfluid_fem::hyper::TimeSettings,
    /// The load factor over time (a ramp to 1 at the end when the scene gives none).
    pub curve: fibfluid_fem::hyper::LoadCurve,
}

/// A region of other tissue with the name reports give it.
#[derive(Clone, Debug, PartialEq)]
pub struct NamedRegion {
    /// Its name (`[[region]] name`, or `region k`).
    pub name: String,
    /// Where its shape comes from, as the scene gives it (`mesh lesion.obj`, `box`,
    /// `label 2`): named in errors about the region.
    pub origin: String,
    /// Its shape (in metres) and tissue.
    pub region: fibfluid_fem::Region,
}

impl Default for FemSettings {
    fn default() -> Self {
        Self {
            resolution: fibfluid_fem::DEFAULT_RESOLUTION,
            solver: fibfluid_fem::FemSolver::Auto,
            regions: Vec::new(),
            auto_model: false,
            grasps: Vec::new(),
            time: None,
            tolerance: None,
            fit: None,
            pressures: Vec::new(),
        }
    }
}

impl Model {
    /// A model of a mesh with the given material, no constraints, no loads, default solver.
    pub fn from_mesh(name: impl Into<String>, mesh: MeshFile, material: Material) -> Self {
        Self::new(name, Shape::Surface(Box::new(mesh)), material)
    }

    /// The body's cavities (closed surfaces inside the outer one; 0 for a polygon).
    pub fn cavities(&self) -> usize {
        match &self.shape {
            Shape::Surface(m) => m.validation.cavities.len(),
            Shape::Polygon(_) => 0,
        }
    }

    /// A model of a body (surface or polygon) with the given material, no constraints, no
    /// loads, default solver.
    pub fn new(name: impl Into<String>, shape: Shape, material: Material) -> Self {
        let n = match &shape {
            Shape::Surface(m) => m.mesh.n_vertices(),
            Shape::Polygon(p) => p.n_vertices(),
        };
        Self {
            name: name.into(),
            source: None,
            shape,
            material,
            constraints: Constraints::new(n),
            load: Load::default(),
            guards: Guards::default(),
            plates: vec![],
            solver: SolverOptions::default(),
            tissue: None,
            fem: FemSettings::default(),
            ffm: FfmSettings::default(),
            unit: LengthUnit::Metre,
        }
    }

    /// Number of vertices.
    pub fn n_vertices(&self) -> usize {
        match &self.shape {
            Shape::Surface(m) => m.mesh.n_vertices(),
            Shape::Polygon(p) => p.n_vertices(),
        }
    }

    /// Rest positions (3D; z = 0 for a polygon).
    pub fn rest_positions(&self) -> Vec<Vec3> {
        match &self.shape {
            Shape::Surface(m) => m.mesh.positions().to_vec(),
            Shape::Polygon(p) => p.positions_3d(),
        }
    }

    /// The name used in messages: the scene file when read from one, else the name.
    pub fn display_name(&self) -> String {
        self.source.as_ref().map(|p| p.display().to_string()).unwrap_or_else(|| self.name.clone())
    }

    /// Whether the body is a closed surface (not the 2D polygon).
    pub fn is_surface(&self) -> bool {
        matches!(self.shape, Shape::Surface(_))
    }
}

/// Newton iterations allowed for the volume correction of a step.
pub const VOLUME_NEWTON_ITERATIONS: usize = 30;

/// Relative volume error the correction aims for.
pub const VOLUME_TOLERANCE: f64 = 1e-12;

/// A plate may reach through the body at rest by this fraction of the body's diagonal (a
/// coordinate rounded when the scene was written, a plate placed "at" a face): the
/// vertices it reaches join its contact at the first step.
pub const PLATE_REST_TOLERANCE: f64 = 1e-4;

/// The largest number of load steps a scene may ask for.
pub const MAX_STEPS: usize = 1_000_000;

/// A scene's `[fit]`: what to fit, within which bounds, against which observations.
#[derive(Clone, Debug, PartialEq)]
pub struct FitSpec {
    /// The parameters, in the scene's order.
    pub parameters: Vec<FitParameter>,
    /// Per parameter, `[lower, upper]` (SI, both above 0: the fit works in their logarithms).
    pub bounds: Vec<[f64; 2]>,
    /// The observed positions' file (`vertex,x,y,z`).
    pub observed: std::path::PathBuf,
    /// Metres per unit of the observed file's positions (the mesh's unit and scale).
    pub metres: f64,
}

/// One fitted parameter: its scene key (`tissue.young`, `region.lesion.young`, `gravity`)
/// and what it is on the body.
#[derive(Clone, Debug, PartialEq)]
pub struct FitParameter {
    /// The dotted key the scene names it by.
    pub key: String,
    /// The body's parameter (tissue 0: `[tissue]`, `k`: the `k`-th `[[region]]`).
    pub parameter: fibfluid_fem::hyper::Parameter,
}
