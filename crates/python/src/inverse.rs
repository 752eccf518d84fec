//! `fibfluid.sensitivity` and `fibfluid.fit`'s compiled half: the static finite-element
//! equilibrium's sensitivities to the scene's parameters, and the command line's `fibfluid
//! fit` with the observations given as arrays (lengths in metres, vertices in file order).

use std::sync::{Arc, Mutex};

use fibfluid_geometry::{MeshFile, Vec3};
use fibfluid_sim::inverse::{FitSpec, Observation, Parameter, observation};
use fibfluid_sim::inverse_fit::FitProgress;
use fibfluid_sim::stages::StageLog;
use fibfluid_sim::{Error as SimError, Method, Model, Shape};
use numpy::{PyArray2, PyReadonlyArrayDyn};
use pyo3::prelude::*;

use crate::arrays::{points, points_array};
use crate::scene::NativeScene;
use crate::{error, guard, lib_error};

/// The refusal of what the static fit and its sensitivities do not cover.
fn refuse(model: &Model, problem: &'static str) -> SimError {
    SimError::MethodNeeds { scene: model.display_name(), method: Method::Fem, problem }
}

/// The model's mesh, when its static finite-element solve can be differentiated: a surface
/// without plates, grasps or a run through time.
fn static_mesh(model: &Model) -> Result<&MeshFile, SimError> {
    if !model.plates.is_empty() || !model.fem.grasps.is_empty() || model.fem.time.is_some() {
        return Err(refuse(model, "differentiates a static solve without [[plate]], [[grasp]] or [time]"));
    }
    match &model.shape {
        Shape::Surface(m) => Ok(m),
        Shape::Polygon(_) => Err(refuse(model, "needs a surface mesh (this scene is a 2D polygon)")),
    }
}

/// Mesh-order vectors in file order (a vertex no face uses: zero).
fn in_file_order(file: &MeshFile, v: &[Vec3]) -> Vec<Vec3> {
    let mut out = vec![[0.0; 3]; file.file_vertex_count()];
    for (m, &f) in file.to_file.iter().enumerate() {
        out[f as usize] = v[m];
    }
    out
}

/// The parameters of `keys` on `scene` (one line naming the bad key).
fn parameters_of(scene: &NativeScene, keys: &[String]) -> PyResult<Vec<Parameter>> {
    keys.iter().map(|k| fibfluid_scene::parameter_of_key(k, &scene.scene.model).map_err(error)).collect()
}

/// What a sensitivity gives back: the deformed surface, per parameter its `du/dtheta`, and
/// the parameters' values (all in file order, SI).
type Sensitivities = (Vec<Vec3>, Vec<Vec<Vec3>>, Vec<f64>);

fn sensitivities_of(model: &Model, parameters: &[Parameter], limit: u64) -> Result<Sensitivities, SimError> {
    let file = static_mesh(model)?;
    let tissue = fibfluid_sim::fem_run::tissue_of(model)?;
    let (mut body, solution, _, _) =
        fibfluid_sim::hyper_run::solve(model, &tissue, limit, &mut StageLog::default())?;
    let loads = fibfluid_sim::fem_run::full_loads(model);
    let sens = body
        .sensitivities(&solution, &loads, parameters)
        .map_err(|source| SimError::Fem { scene: model.display_name(), source })?;
    let rest = model.rest_positions();
    let deformed: Vec<Vec3> = rest
        .iter()
        .zip(&solution.surface_displacements)
        .map(|(r, u)| std::array::from_fn(|a| r[a] + u[a]))
        .collect();
    let derivatives = sens.surface.iter().map(|d| in_file_order(file, d)).collect();
    Ok((file.positions_in_file_order(&deformed), derivatives, sens.values))
}

/// The scene's static finite-element equilibrium (its tissue's law, gravity and point forces
/// in full) and, per key of `keys`, each surface vertex's `du/dtheta` (m per SI unit of the
/// parameter), solved with the GIL released. Returns the deformed surface `(N, 3)` (m,
/// file order), the derivatives (one `(N, 3)` array per key) and the parameters' values.
#[pyfunction]
#[pyo3(signature = (scene, keys, max_memory=None))]
#[allow(clippy::type_complexity)]
pub(crate) fn sensitivity(
    py: Python<'_>,
    scene: &NativeScene,
    keys: Vec<String>,
    max_memory: Option<u64>,
) -> PyResult<(Py<PyArray2<f64>>, Vec<Py<PyArray2<f64>>>, Vec<f64>)> {
    guard(|| {
        if keys.is_empty() {
            return Err(error("sensitivity: names no parameter"));
        }
        let parameters = parameters_of(scene, &keys)?;
        let model = &scene.scene.model;
        let limit = fibfluid_sim::memory_budget(max_memory);
        let (positions, derivatives, values) =
            py.detach(|| sensitivities_of(model, &parameters, limit)).map_err(lib_error)?;
        let derivatives = derivatives.iter().map(|d| points_array(py, d).unbind()).collect();
        Ok((points_array(py, &positions).unbind(), derivatives, values))
    })
}

/// The observations of the file vertices `vertices` at `positions` (m), checked as the rows
/// of `observed.csv` are (one line naming the row).
fn observations(
    model: &Model,
    vertices: &Bound<'_, PyAny>,
    positions: &Bound<'_, PyAny>,
) -> PyResult<Vec<Observation>> {
    let file = static_mesh(model).map_err(lib_error)?;
    let v: PyReadonlyArrayDyn<'_, i64> = vertices
        .extract()
        .map_err(|_| error("fit: observed vertices must be an integer array of shape (M,)"))?;
    let v = v.as_array();
    if v.ndim() != 1 {
        return Err(error(format!("fit: observed vertices must have shape (M,), got {:?}", v.shape())));
    }
    let p = points(positions, "fit: observed positions")?;
    if p.len() != v.len() {
        return Err(error(format!("fit: {} observed vertices but {} positions", v.len(), p.len())));
    }
    if p.is_empty() {
        return Err(error("fit: no observed vertex"));
    }
    let mut out: Vec<Observation> = Vec::with_capacity(p.len());
    for (row, (&i, &x)) in v.iter().zip(&p).enumerate() {
        if !x.iter().all(|c| c.is_finite()) {
            return Err(error(format!("fit: observed row {row}: the position {x:?} is not finite")));
        }
        let index = usize::try_from(i)
            .map_err(|_| error(format!("fit: observed row {row}: vertex {i} is not an index")))?;
        let o = observation(file, index, x, &out)
            .map_err(|problem| error(format!("fit: observed row {row}: {problem}")))?;
        out.push(o);
    }
    Ok(out)
}

/// Fits the parameters `keys` of `scene` within `bounds` (one `[lower, upper]` each, SI)
/// to the observed file vertices `vertices` `(M,)` at `positions` `(M, 3)` (m), as `fibfluid
/// fit` does, with the GIL released; `progress(iteration, rms, relative, values)` is called
/// after each iteration with the GIL held (an exception it raises is raised when the fit
/// ends). Returns `fit.json`'s text.
#[pyfunction]
#[pyo3(signature = (scene, vertices, positions, keys, bounds, progress=None, max_memory=None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn fit(
    py: Python<'_>,
    scene: &NativeScene,
    vertices: &Bound<'_, PyAny>,
    positions: &Bound<'_, PyAny>,
    keys: Vec<String>,
    bounds: Vec<[f64; 2]>,
    progress: Option<Py<PyAny>>,
    max_memory: Option<u64>,
) -> PyResult<String> {
    guard(|| {
        let model = &scene.scene.model;
        let parameters = fibfluid_scene::fit_parameters(&keys, &bounds, model)
            .map_err(|(what, problem)| error(format!("fit: {what}: {problem}")))?;
        let observed = observations(model, vertices, positions)?;
        let spec = FitSpec { parameters, bounds, observed: "<arrays>".into(), metres: 1.0 };
        let limit = fibfluid_sim::memory_budget(max_memory);
        let failed: Arc<Mutex<Option<PyErr>>> = Arc::new(Mutex::new(None));
        let tell = |p: &FitProgress| {
            let Some(cb) = &progress else { return };
            Python::attach(|py| {
                let Ok(mut slot) = failed.lock() else { return };
                if slot.is_none()
                    && let Err(e) = cb.call1(py, (p.iteration, p.rms, p.relative, p.values.clone()))
                {
                    *slot = Some(e);
                }
            })
        };
        let report = py
            .detach(|| {
                let mut tell = tell;
                fibfluid_sim::inverse_fit::fit(model, &spec, &observed, limit, &mut tell)
            })
            .map_err(lib_error)?;
        if let Some(e) = failed.lock().map_err(|_| error("the progress callback failed"))?.take() {
            return Err(e);
        }
        serde_json::to_string(&report).map_err(|e| error(format!("fit: {e}")))
    })
}
