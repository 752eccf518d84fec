//! Effects a scene asks for that cannot act, found before a run so the user is told.
//!
//! A scene can be valid and still ask for something that does nothing: gravity acts only
//! through the hydrostatic pressure `rho a h` (REFERENCE §3), so `[gravity]` without a fluid
//! density leaves the body where it is, and the run prints max |u| = 0 without a word. The
//! plan skips such stages (the report lists them); [`ineffective`] says which of the
//! scene's own settings caused it and what to change. The CLI prints each as
//! `warning: ...` and `report.json` lists them under `warnings`.

use std::fmt;

use fibfluid_assembly::StiffnessLaw;
use fibfluid_geometry::Vec3;

use crate::choices::{Method, Mode};
use crate::model::{Model, Shape};

/// A setting of a scene that has no effect on the run.
#[derive(Clone, Debug, PartialEq)]
pub enum Ineffective {
    /// `[gravity]` is set but the fluid density is 0: gravity acts only through the
    /// hydrostatic load `rho a h S`, which is then zero.
    GravityWithoutDensity {
        /// The acceleration asked for.
        acceleration: Vec3,
    },
    /// `[gravity]` is set for the finite-element method but `[tissue] density` is 0.
    GravityWithoutTissueDensity {
        /// The acceleration asked for.
        acceleration: Vec3,
    },
    /// `[[region]]`s in a scene run by a method that has none (FFM, ChainMail): the whole
    /// body is the base tissue.
    RegionsOutsideFem {
        /// How many regions the scene gives.
        regions: usize,
    },
    /// `[[grasp]]`s in a scene run by a method or body that does not carry them (FFM,
    /// ChainMail, interactive bodies): only the finite-element batch run (`run` with
    /// `method = "fem"`) moves grasped patches.
    GraspsOutsideFemRun {
        /// How many grasps the scene gives.
        grasps: usize,
    },
    /// `[[pressure]]`s in a scene run by an interactive body, which does not carry them:
    /// only the finite-element batch run applies pressures.
    PressuresOutsideFemRun {
        /// How many pressures the scene gives.
        pressures: usize,
    },
    /// A fluid density without gravity: the density enters only the hydrostatic load.
    DensityWithoutGravity {
        /// The density given.
        density: f64,
    },
    /// A strain-dependent modulus (`[material] stiffening`) in a mode that assembles K once,
    /// at the rest shape, where every strain is 0.
    StiffeningOutsideNonlinear {
        /// The scene's mode (paper or refresh).
        mode: Mode,
    },
    /// A point force whose value is zero.
    ZeroForce {
        /// 1-based position among the scene's forces (`[[force]] #k`).
        index: usize,
        /// The vertex, as the scene names it (the file's 0-based index).
        vertex: usize,
    },
    /// `[load] steps` (or `tolerance`) in a finite-element run: the FEM steps its load on its
    /// own (Newton's adaptive increments; a plain linear body is one solve), so the count
    /// does not act.
    StepsInFem {
        /// The steps asked for.
        steps: usize,
    },
    /// A point force on a vertex that is constrained along every axis the force pushes.
    ForceOnFixedVertex {
        /// 1-based position among the scene's forces (`[[force]] #k`).
        index: usize,
        /// The vertex, as the scene names it (the file's 0-based index).
        vertex: usize,
    },
}

impl fmt::Display for Ineffective {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Ineffective::GravityWithoutDensity { acceleration: a } => write!(
                f,
                "[gravity] acceleration = [{}, {}, {}] has no effect: the fluid density is 0 and gravity acts only through the hydrostatic pressure; set [fluid] density (e.g. 1000)",
                a[0], a[1], a[2]
            ),
            Ineffective::GravityWithoutTissueDensity { acceleration: a } => write!(
                f,
                "[gravity] acceleration = [{}, {}, {}] has no effect: [tissue] density is 0 (set it in kg/m^3, e.g. 1000)",
                a[0], a[1], a[2]
            ),
            Ineffective::RegionsOutsideFem { regions } => write!(
                f,
                "{regions} [[region]] table(s) have no effect: regions of other tissue are a finite-element feature (method = \"fem\"); this method treats the whole body as one material"
            ),
            Ineffective::GraspsOutsideFemRun { grasps } => write!(
                f,
                "{grasps} [[grasp]] table(s) are ignored: grasps are carried by the finite-element batch run only (`run` with method = \"fem\"); interactive bodies grasp through tool paths"
            ),
            Ineffective::PressuresOutsideFemRun { pressures } => write!(
                f,
                "{pressures} [[pressure]] table(s) are ignored: pressures are carried by the finite-element batch run only (`run` with method = \"fem\")"
            ),
            Ineffective::DensityWithoutGravity { density } => write!(
                f,
                "[fluid] density = {density} has no effect without gravity (it enters only the hydrostatic load); add [gravity] acceleration or remove [fluid]"
            ),
            Ineffective::StiffeningOutsideNonlinear { mode } => write!(
                f,
                "[material] stiffening has no effect in {} mode (K is assembled once, at the rest shape, where the strain is 0); set [solver] mode = \"nonlinear\"",
                mode
            ),
            Ineffective::StepsInFem { steps } => write!(
                f,
                "[load] steps = {steps} has no effect on the finite-element method: the FEM steps its load adaptively (Newton's method picks its own increments; a linear body without plates is one solve); it acts with method = \"ffm\", and with [[plate]] as the largest increment"
            ),
            Ineffective::ZeroForce { index, vertex } => write!(
                f,
                "[[force]] #{index} on vertex {vertex} is zero and has no effect; give it a non-zero value or remove it"
            ),
            Ineffective::ForceOnFixedVertex { index, vertex } => write!(
                f,
                "[[force]] #{index} pushes vertex {vertex}, which is fixed along every axis the force has a component on, so it has no effect; apply it to a free vertex or fix fewer axes there"
            ),
        }
    }
}

/// What a scene asks for that an interactive body does not carry: the scene's grasps
/// (a tool grasps instead) and pressures.
pub fn ineffective_interactive(scene: &Model) -> Vec<Ineffective> {
    let mut found = Vec::new();
    if !scene.fem.grasps.is_empty() {
        found.push(Ineffective::GraspsOutsideFemRun { grasps: scene.fem.grasps.len() });
    }
    if !scene.fem.pressures.is_empty() {
        found.push(Ineffective::PressuresOutsideFemRun { pressures: scene.fem.pressures.len() });
    }
    found
}

/// Every setting of `scene` that cannot act, in scene order (gravity and fluid, material,
/// forces). Cheap: no assembly, one pass over the forces.
///
/// A `[[fix]]` that selects only vertices an earlier `[[fix]]` already holds is not
/// reported: a [`Model`] keeps the merged constraints, not the tables they came from.
pub fn ineffective(scene: &Model) -> Vec<Ineffective> {
    let mut found = Vec::new();
    let has_gravity = scene.load.gravity.iter().any(|&g| g != 0.0);
    let fem = scene.solver.method == Method::Fem;
    // FFM's gravity acts through the fluid's density, the FEM's through the tissue's.
    let density =
        if fem { scene.tissue.map(|t| t.density()).unwrap_or(0.0) } else { scene.material.density() };
    if has_gravity && density == 0.0 {
        found.push(if fem {
            Ineffective::GravityWithoutTissueDensity { acceleration: scene.load.gravity }
        } else {
            Ineffective::GravityWithoutDensity { acceleration: scene.load.gravity }
        });
    }
    // A density FFM took from `[tissue]` (its fibers calibrated) describes the tissue; it
    // asks for no effect, so its absence of gravity is no mistake.
    let from_tissue = scene.ffm.calibrate && scene.tissue.is_some_and(|t| t.density() == density);
    if !fem && !scene.fem.regions.is_empty() {
        found.push(Ineffective::RegionsOutsideFem { regions: scene.fem.regions.len() });
    }
    if !fem && !scene.fem.grasps.is_empty() {
        found.push(Ineffective::GraspsOutsideFemRun { grasps: scene.fem.grasps.len() });
    }
    if !has_gravity && density > 0.0 && !fem && !from_tissue {
        found.push(Ineffective::DensityWithoutGravity { density });
    }
    let stiffens = match &scene.material.law() {
        StiffnessLaw::Linear => false,
        StiffnessLaw::Quadratic { c } => *c != 0.0,
        StiffnessLaw::Custom(_) => true,
    };
    if stiffens && scene.solver.mode != Mode::Nonlinear && !fem {
        found.push(Ineffective::StiffeningOutsideNonlinear { mode: scene.solver.mode });
    }
    // A static FEM run with plates takes at most 1/steps of the travel per increment.
    let steps_act = scene.load.steps > 1 && !scene.plates.is_empty() && scene.fem.time.is_none();
    if fem && ((scene.load.steps > 1 && !steps_act) || scene.load.tolerance.is_some()) {
        found.push(Ineffective::StepsInFem { steps: scene.load.steps });
    }
    let axes = if matches!(scene.shape, Shape::Polygon(_)) { 2 } else { 3 };
    let n = scene.constraints.n_vertices();
    for (k, force) in scene.load.forces.iter().enumerate() {
        let vertex = match &scene.shape {
            Shape::Surface(m) => m.to_file.get(force.vertex).map(|&f| f as usize).unwrap_or(force.vertex),
            Shape::Polygon(_) => force.vertex,
        };
        let index = k + 1;
        let zero = force.value[..axes].iter().all(|&c| c == 0.0);
        // Every axis the force pushes along is constrained at its vertex.
        let held = force.vertex < n
            && (0..axes)
                .filter(|&c| force.value[c] != 0.0)
                .all(|c| scene.constraints.get(force.vertex, c).is_some());
        if zero {
            found.push(Ineffective::ZeroForce { index, vertex });
        } else if held {
            found.push(Ineffective::ForceOnFixedVertex { index, vertex });
        }
    }
    found
}
