//! `fibfluid.run`'s compiled half: the command line's `run` without the files.

use std::sync::{Arc, Mutex};

use fibfluid_geometry::Vec3;
use fibfluid_sim::stages::{StageRecord, names};
use fibfluid_sim::{Report, RunOptions, SetupOptions, Shape, Simulation};
use numpy::PyArray2;
use pyo3::prelude::*;

use crate::arrays::points_array;
use crate::scene::NativeScene;
use crate::volume::{VolumeArrays, VolumeOutput};
use crate::{error, guard, lib_error};

/// What a run gives back, in the body's file vertex order.
#[pyclass(module = "fibfluid._native", name = "RunOutput", frozen)]
pub(crate) struct RunOutput {
    /// Final positions `(N, 3)`.
    #[pyo3(get)]
    positions: Py<PyArray2<f64>>,
    /// Final minus rest positions `(N, 3)`.
    #[pyo3(get)]
    displacement: Py<PyArray2<f64>>,
    /// The fluid's pressure change at the end.
    #[pyo3(get)]
    pressure: f64,
    /// `report.json` as the command line writes it (JSON text).
    #[pyo3(get)]
    report_json: String,
    /// Guard warnings, one line each (also in the report).
    #[pyo3(get)]
    warnings: Vec<String>,
    /// The finite-element run's volume (`volume.vtu`'s grid and fields); None for the FFM.
    #[pyo3(get)]
    volume: Option<Py<VolumeOutput>>,
}

/// What the detached part of a run returns.
struct Done {
    positions: Vec<Vec3>,
    displacement: Vec<Vec3>,
    pressure: f64,
    report_json: String,
    warnings: Vec<String>,
    volume: Option<VolumeArrays>,
}

impl Done {
    /// The run's output as Python objects (the arrays' buffers move to NumPy).
    fn output(self, py: Python<'_>) -> PyResult<RunOutput> {
        let volume = match self.volume {
            Some(v) => Some(Py::new(py, VolumeOutput::new(py, v)?)?),
            None => None,
        };
        Ok(RunOutput {
            positions: points_array(py, &self.positions).unbind(),
            displacement: points_array(py, &self.displacement).unbind(),
            pressure: self.pressure,
            report_json: self.report_json,
            warnings: self.warnings,
            volume,
        })
    }
}

/// Runs a scene as `fibfluid run` does (the same stages and the same report, without the
/// output files), with the GIL released. `progress(step, total)` is called after each
/// step with the GIL held; an exception it raises, or Ctrl-C, stops the run before its next
/// load step and is raised (the scene is unchanged: runs work on a copy). `max_memory` is
/// the command line's `--max-memory`.
/// `fem` chooses the method as `--method` does, overriding only `[solver] method` (None:
/// the scene's): true runs the finite-element method with the scene's tissue law (linear
/// or neo-Hookean), as `fibfluid run` does it, and `progress` is then not called (Newton's
/// load steps are in the report); false runs FFM, its fibers calibrated on a `[tissue]`-only
/// scene as `method = "ffm"` in the file would.
#[pyfunction]
#[pyo3(signature = (scene, progress=None, max_memory=None, fem=None))]
pub(crate) fn run(
    py: Python<'_>,
    scene: &NativeScene,
    progress: Option<Py<PyAny>>,
    max_memory: Option<u64>,
    fem: Option<bool>,
) -> PyResult<RunOutput> {
    guard(|| {
        if fem.unwrap_or(scene.scene.model.solver.method == fibfluid_sim::Method::Fem) {
            let model = scene.scene.model.clone();
            let load =
                StageRecord { name: names::LOAD_SCENE, parent: None, seconds: scene.load_seconds, count: 1 };
            let done = py.detach(move || solve_fem(model, max_memory, load)).map_err(lib_error)?;
            return done.output(py);
        }
        let failed: Arc<Mutex<Option<PyErr>>> = Arc::new(Mutex::new(None));
        let opts = RunOptions {
            progress: progress.map(|cb| callback(cb, failed.clone())),
            cancel: Some(interrupted(failed.clone())),
        };
        let setup = SetupOptions { max_memory, ..Default::default() };
        let load =
            StageRecord { name: names::LOAD_SCENE, parent: None, seconds: scene.load_seconds, count: 1 };
        let mut model = scene.scene.clone();
        if fem == Some(false) {
            model.model.solver.method = fibfluid_sim::Method::Ffm;
        }
        let done = py.detach(move || solve(model, &setup, &opts, load));
        // A pending exception (Ctrl-C, or the progress callback's) goes first: the run
        // stopped because of it.
        if let Some(e) = failed.lock().map_err(|_| error("the progress callback failed"))?.take() {
            return Err(e);
        }
        done.map_err(lib_error)?.output(py)
    })
}

/// The progress callback as the engine takes it: the GIL is taken for the call; the first
/// exception is kept and later calls are skipped. Ctrl-C (a pending signal) counts as one.
fn callback(cb: Py<PyAny>, failed: Arc<Mutex<Option<PyErr>>>) -> Arc<dyn Fn(usize, usize) + Send + Sync> {
    Arc::new(move |k, n| {
        Python::attach(|py| {
            let Ok(mut slot) = failed.lock() else { return };
            if slot.is_some() {
                return;
            }
            if let Err(e) = py.check_signals().and_then(|()| cb.call1(py, (k, n)).map(drop)) {
                *slot = Some(e);
            }
        })
    })
}

/// Asked before each load step: a pending signal (Ctrl-C) or an exception of the progress
/// callback stops the run there. The GIL is taken for the check (microseconds per step).
fn interrupted(failed: Arc<Mutex<Option<PyErr>>>) -> Arc<dyn Fn() -> bool + Send + Sync> {
    Arc::new(move || {
        Python::attach(|py| {
            let Ok(mut slot) = failed.lock() else { return true };
            if slot.is_none()
                && let Err(e) = py.check_signals()
            {
                *slot = Some(e);
            }
            slot.is_some()
        })
    })
}

fn solve(
    scene: fibfluid_scene::Scene,
    setup: &SetupOptions,
    opts: &RunOptions,
    load: StageRecord,
) -> Result<Done, fibfluid_scene::Error> {
    let notes = match &scene.shape {
        Shape::Surface(m) => m.notes.clone(),
        Shape::Polygon(_) => vec![],
    };
    let mut sim = Simulation::with_options(scene, setup)?;
    sim.run(opts)?;
    let report = Report::of(&sim, std::slice::from_ref(&load), notes);
    // The file order and the subtraction of `write_outputs` (`deformed.obj`, the VTK's
    // displacement).
    let (positions, rest) = match &sim.model().shape {
        Shape::Surface(m) => {
            (m.positions_in_file_order(sim.positions()), m.positions_in_file_order(sim.rest_positions()))
        }
        Shape::Polygon(_) => (sim.positions().to_vec(), sim.rest_positions().to_vec()),
    };
    let warnings = sim.warnings().iter().map(|w| crate::one_line(&w.to_string())).collect();
    done(positions, &rest, sim.pressure(), serde_json::to_string(&report), warnings, None)
}

/// [`Done`] from file-order positions and rest, the pressure, the report, the warnings and
/// the finite-element volume.
fn done(
    positions: Vec<Vec3>,
    rest: &[Vec3],
    pressure: f64,
    report: serde_json::Result<String>,
    warnings: Vec<String>,
    volume: Option<VolumeArrays>,
) -> Result<Done, fibfluid_scene::Error> {
    let displacement =
        positions.iter().zip(rest).map(|(p, r)| [p[0] - r[0], p[1] - r[1], p[2] - r[2]]).collect();
    let report_json = report.map_err(|e| fibfluid_scene::Error::Io {
        path: "report.json".into(),
        source: std::io::Error::other(e),
    })?;
    Ok(Done { positions, displacement, pressure, report_json, warnings, volume })
}

/// The finite-element run of `model` (its tissue's law), in the mesh file's vertex order, with
/// its volume; the pressure is 0 (the FEM has no fluid).
fn solve_fem(
    mut model: fibfluid_sim::Model,
    max_memory: Option<u64>,
    load: StageRecord,
) -> Result<Done, fibfluid_scene::Error> {
    model.solver.method = fibfluid_sim::Method::Fem;
    let notes = match &model.shape {
        Shape::Surface(m) => m.notes.clone(),
        Shape::Polygon(_) => vec![],
    };
    let run = fibfluid_sim::fem_run::FemRun::new(model, max_memory)?;
    let report = fibfluid_sim::fem_run::FemReport::of(&run, std::slice::from_ref(&load), notes);
    let (positions, rest) = match &run.model.shape {
        Shape::Surface(m) => {
            (m.positions_in_file_order(&run.positions), m.positions_in_file_order(&run.rest))
        }
        Shape::Polygon(_) => (run.positions.clone(), run.rest.clone()),
    };
    let warnings = run.warnings.iter().map(|w| crate::one_line(&w.to_string())).collect();
    let volume = VolumeArrays::of(run.volume);
    done(positions, &rest, 0.0, serde_json::to_string(&report), warnings, Some(volume))
}
