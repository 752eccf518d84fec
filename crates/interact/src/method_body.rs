//! A model's interactive body for each [`Method`]: the fiber–fluid method's precomputed
//! response on top of a base solve, or a ChainMail lattice.

use std::sync::Arc;
use std::time::Instant;

use fibfluid_geometry::Vec3;
use fibfluid_linalg::{Backend, Precision};
use fibfluid_sim::{Method, Mode, Model, RunOptions, Shape, Simulation};

use crate::chainmail_body::ChainmailBody;
use crate::chainmail_settings::{ChainmailSettings, Variant};
use crate::fem_body::FemInteractive;
use crate::hyper_body::{ChordBudget, HyperInteractive, RefreshMode};
use crate::replay::ProbeError;
use crate::{
    Compliance, ComplianceOptions, FfmBody, InteractError, Interactive, Precompute, Storage, memory_budget,
};

/// Options of [`build_body`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ProbeOptions {
    /// Storage of the full precomputed response (the lazy response is f64).
    pub storage: Storage,
    /// The full precompute, or the lazy columns on the base solve's factorization (the
    /// default).
    pub precompute: Precompute,
    /// Memory budget (see [`fibfluid_interact::memory_budget`]).
    pub max_memory_bytes: Option<u64>,
    /// When a hyperelastic body refreshes its linearization.
    pub refresh: RefreshMode,
    /// Chord refreshes of a hyperelastic body between two refactorizations (`None`:
    /// [`crate::ChordBudget::Balanced`]; `Some(0)`: Newton's iterations only).
    pub chord_refreshes: Option<usize>,
}

/// A scene's interactive body and what building it cost.
#[derive(Debug)]
pub struct ProbeBody {
    /// The body (base state applied).
    pub body: FfmBody,
    /// Seconds of the base solve (assembly, factorization and one solve).
    pub base_seconds: f64,
    /// Seconds of the precompute of the response (lazy: the one solve for the border terms;
    /// each vertex's columns are computed when it is first touched).
    pub precompute_seconds: f64,
}

/// The scene as the probe solves it with the fiber–fluid method (whatever method the scene
/// runs in batch): paper mode, one step (loads in full), structured backend, f64.
pub fn linearized(scene: &Model) -> Model {
    let mut s = scene.clone();
    s.solver.method = Method::Ffm;
    s.solver.mode = Mode::Paper;
    s.load.steps = 1;
    s.solver.backend = Backend::Structured;
    s.solver.precision = Precision::F64;
    s
}

/// Builds the interactive body of a scene: one full solve of the scene's loads (the base
/// state) and the response of the same assembled system, precomputed in full (a second
/// factorization and the inverse) or lazily (the base solve's factorization kept, each
/// vertex's columns computed when it is first touched), as `opts.precompute` says.
///
/// Refuses before assembling anything when the assembled system, its factorization and
/// (full) the precompute's peak would exceed the memory budget, naming the bytes.
pub fn build_body(scene: &Model, opts: &ProbeOptions) -> Result<ProbeBody, ProbeError> {
    if !matches!(scene.shape, Shape::Surface(_)) {
        return Err(ProbeError::NotASurface { scene: scene.display_name() });
    }
    if scene.ffm.fibers == fibfluid_sim::FiberModel::Projected {
        return Err(fibfluid_sim::Error::MethodNeeds {
            scene: scene.display_name(),
            method: Method::Ffm,
            problem: "with fibers = \"projected\" has no interactive body yet (its response is the coupled 3N x 3N factor; use fibers = \"paper\" to probe)",
        }
        .into());
    }
    let n = scene.n_vertices();
    let nblocks = if scene.material.is_isotropic() && scene.constraints.is_uniform(3) { 1 } else { 3 };
    // The assembled blocks and their factorization stay alive (lazy: for good).
    let system_bytes = 2 * (nblocks * n * n * 8) as u64;
    let need = match opts.precompute {
        Precompute::Full => Compliance::estimate_for(n, nblocks, opts.storage).peak + system_bytes,
        Precompute::Lazy => system_bytes,
    };
    let budget = memory_budget(opts.max_memory_bytes);
    let scene_name = scene.display_name();
    let build = |source: InteractError| ProbeError::Build { scene: scene_name.clone(), source };
    if need > budget {
        return Err(build(InteractError::OutOfMemory { bytes: need, available: budget }));
    }
    let start = Instant::now();
    let mut sim = Simulation::new(linearized(scene))?;
    sim.run(&RunOptions::default())?;
    let base: Vec<Vec3> = sim
        .positions()
        .iter()
        .zip(sim.rest_positions())
        .map(|(p, r)| [p[0] - r[0], p[1] - r[1], p[2] - r[2]])
        .collect();
    let base_pressure = sim.pressure();
    let base_seconds = start.elapsed().as_secs_f64();
    let rest = sim.rest_positions().to_vec();
    let compliance = match opts.precompute {
        Precompute::Full => {
            let copts =
                ComplianceOptions { storage: opts.storage, max_memory_bytes: Some(budget - system_bytes) };
            Compliance::from_system(sim.system(), &copts).map_err(build)?
        }
        Precompute::Lazy => {
            let (system, factorization) = sim.into_factored();
            Compliance::lazy(&system, Arc::from(factorization)).map_err(build)?
        }
    };
    let precompute_seconds = compliance.seconds();
    let mut body = FfmBody::new(compliance, rest).map_err(build)?;
    body.set_base(base, base_pressure).map_err(build)?;
    Ok(ProbeBody { body, base_seconds, precompute_seconds })
}

/// A scene's body for one [`Method`], with what building it cost.
#[derive(Debug)]
pub enum MethodBody {
    /// The fiber–fluid method's body.
    Ffm(Box<ProbeBody>),
    /// A ChainMail body.
    Chainmail(Box<ChainmailBody>),
    /// The finite-element body of a linear tissue.
    Fem(Box<FemInteractive>),
    /// The finite-element body of a neo-Hookean tissue, at two rates.
    Hyper(Box<HyperInteractive>),
}

impl MethodBody {
    /// Builds the body of `scene` for `method` (ChainMail takes `chainmail`'s settings),
    /// within the memory budget of `opts`.
    pub fn build(
        scene: &Model,
        chainmail: &ChainmailSettings,
        method: Method,
        opts: &ProbeOptions,
    ) -> Result<Self, ProbeError> {
        match (method, Variant::of_method(method)) {
            (Method::Fem, _) if scene.tissue.is_some_and(|t| !t.is_linear()) => {
                Ok(MethodBody::Hyper(Box::new(HyperInteractive::with_chord_budget(
                    scene,
                    opts.max_memory_bytes,
                    opts.refresh,
                    opts.chord_refreshes.map_or(ChordBudget::Balanced, ChordBudget::AtMost),
                )?)))
            }
            (Method::Fem, _) => {
                Ok(MethodBody::Fem(Box::new(FemInteractive::new(scene, opts.max_memory_bytes)?)))
            }
            (_, None) => Ok(MethodBody::Ffm(Box::new(build_body(scene, opts)?))),
            (_, Some(variant)) => {
                let budget = memory_budget(opts.max_memory_bytes);
                let body = ChainmailBody::from_model(scene, chainmail, variant, budget)
                    .map_err(|source| ProbeError::Chainmail { scene: scene.display_name(), source })?;
                Ok(MethodBody::Chainmail(Box::new(body)))
            }
        }
    }

    /// The body behind the method-neutral trait.
    pub fn interactive(&mut self) -> &mut dyn Interactive {
        match self {
            MethodBody::Ffm(b) => &mut b.body,
            MethodBody::Chainmail(b) => b.as_mut(),
            MethodBody::Fem(b) => b.as_mut(),
            MethodBody::Hyper(b) => b.as_mut(),
        }
    }

    /// The body behind the method-neutral trait, owned (a viewer client's).
    pub fn into_interactive(self) -> Box<dyn Interactive + Send> {
        match self {
            MethodBody::Ffm(b) => Box::new(b.body),
            MethodBody::Chainmail(b) => b,
            MethodBody::Fem(b) => b,
            MethodBody::Hyper(b) => b,
        }
    }

    /// The body behind the method-neutral trait, read only.
    pub fn interactive_ref(&self) -> &dyn Interactive {
        match self {
            MethodBody::Ffm(b) => &b.body,
            MethodBody::Chainmail(b) => b.as_ref(),
            MethodBody::Fem(b) => b.as_ref(),
            MethodBody::Hyper(b) => b.as_ref(),
        }
    }

    /// Seconds of the setup: base solve and precompute (FFM), voxelization and embedding
    /// (ChainMail), voxelization, assembly, factorization and base solve (FEM).
    pub fn setup_seconds(&self) -> f64 {
        match self {
            MethodBody::Ffm(b) => b.base_seconds + b.precompute_seconds,
            MethodBody::Chainmail(b) => b.setup_seconds(),
            MethodBody::Fem(b) => b.setup_seconds(),
            MethodBody::Hyper(b) => b.setup_seconds(),
        }
    }
}
