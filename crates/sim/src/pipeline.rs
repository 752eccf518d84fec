//! The order of a run's setup: refusals from counts, then the calibration step (when the
//! scene gives only `[tissue]`, it produces FFM's fiber modulus), then the
//! [`Simulation`]'s own setup. The calibration runs before the simulation is built, never
//! inside it.

use std::time::Instant;

use crate::calibration::calibrate;
use crate::choices::Method;
use crate::model::Model;
use crate::plan::Plan;
use crate::simulate::{SetupOptions, Simulation, refuse_projected};
use crate::stages::{StageLog, names};
use crate::{Error, Result};

impl Simulation {
    /// Plans the scene and prepares it: calibration of the fiber modulus (when the scene
    /// asks for it), fibers, assembly and the first factorization. Only the stages the plan
    /// runs are done; a plan that needs more memory than the machine has is refused before
    /// anything large is allocated.
    pub fn new(model: impl Into<Model>) -> Result<Self> {
        Self::with_options(model, &SetupOptions::default())
    }

    /// [`new`](Self::new) with explicit setup options.
    pub fn with_options(model: impl Into<Model>, opts: &SetupOptions) -> Result<Self> {
        let mut scene: Model = model.into();
        if scene.solver.method != Method::Ffm {
            return Err(Error::MethodNeeds {
                scene: scene.display_name(),
                method: scene.solver.method,
                problem: "is not run by the fiber-fluid Simulation (fem: `fem_run::FemRun`; ChainMail: interactive bodies)",
            });
        }
        refuse_projected(&scene)?;
        if !scene.fem.pressures.is_empty() {
            return Err(Error::MethodNeeds {
                scene: scene.display_name(),
                method: Method::Ffm,
                problem: "has [[pressure]] loads, which only the finite-element method carries; set [solver] method = \"fem\" with a [tissue] table",
            });
        }
        if scene.cavities() > 0 {
            return Err(Error::MethodNeeds {
                scene: scene.display_name(),
                method: Method::Ffm,
                problem: "has a body with cavities, which the fiber-fluid method does not represent (its fibers and fluid volume are those of one closed surface); use [solver] method = \"fem\" with a [tissue] table",
            });
        }
        if scene.fem.time.is_some() {
            return Err(Error::MethodNeeds {
                scene: scene.display_name(),
                method: Method::Ffm,
                problem: "has a [time] table: a run through time (viscoelastic relaxation, inertia) is the finite-element method's; set [solver] method = \"fem\" with a [tissue] table, or remove [time]",
            });
        }
        crate::contact::refuse_crossing_plates(&scene)?;
        let started = Instant::now();
        let limit = fibfluid_linalg::memory_budget(opts.max_memory);
        // From counts first: a body too large is refused before its convexity check.
        Plan::from_counts(&scene).check_memory(&scene.name, limit, scene.solver.backend)?;
        let mut log = StageLog::default();
        let calibration = if scene.ffm.calibrate {
            let c = log.time(names::CALIBRATION, || calibrate(&scene, opts.max_memory))?;
            c.apply(&mut scene.material)?;
            scene.ffm.calibrate = false;
            Some(c)
        } else {
            None
        };
        Simulation::setup(scene, calibration, opts, log, started)
    }
}
