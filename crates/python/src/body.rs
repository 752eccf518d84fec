//! `fibfluid.Body`'s compiled half: a scene's interactive body for one method, driven in
//! the mesh file's vertex order (as path files are).

use fibfluid_geometry::{MeshFile, Vec3};
use fibfluid_interact::{FrameGuardError, FrameGuards};
use fibfluid_interact::{
    InteractError, MethodBody, ProbeError, ProbeOptions, RigidMotion, ToolLoad, ToolSet,
};
use fibfluid_sim::result_guards::{ResultChecks, ResultWarning};
use fibfluid_sim::{Choice, Method, Shape};
use numpy::IntoPyArray;
use numpy::PyArray2;
use numpy::ndarray::Array2;
use pyo3::prelude::*;

use crate::arrays::{points_array, vec3};
use crate::scene::NativeScene;
use crate::{error, guard, lib_error};

/// A frame as `step` returns it: positions `(N, 3)` and reactions `(k, 4)`.
type Frame<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<f64>>);

/// An interactive body: grab, push, release, step.
#[pyclass(module = "fibfluid._native", name = "NativeBody")]
pub(crate) struct NativeBody {
    body: MethodBody,
    /// The mesh file: its vertex order is the one callers use.
    file: MeshFile,
    /// File index -> body (mesh) index.
    file_to_mesh: Vec<Option<usize>>,
    method: Method,
    setup_seconds: f64,
    /// Grasps and the pressing tip.
    tools: ToolSet,
    /// The tools' loads after the last step.
    loads: Vec<ToolLoad>,
    /// The result guards of every frame, in the body's vertex order.
    guards: FrameGuards,
    /// What the guards check of this method's frames.
    checks: ResultChecks,
    /// The result guards that fired on the last step.
    warnings: Vec<ResultWarning>,
}

impl NativeBody {
    /// The body's index of file vertex `v`, checked.
    fn vertex(&self, v: i64) -> PyResult<usize> {
        let count = self.file_to_mesh.len();
        let m = usize::try_from(v).ok().and_then(|i| self.file_to_mesh.get(i).copied());
        match m {
            None => {
                Err(error(format!("vertex {v} is out of range (the mesh has {count} vertices, 0-based)")))
            }
            Some(None) => Err(error(format!("vertex {v} is not used by any face"))),
            Some(Some(i)) => Ok(i),
        }
    }

    /// The library's error for a body request, its vertex named in file order (as the
    /// command line's probe names it).
    fn body_error(&self, e: InteractError) -> PyErr {
        let file = |v: usize| self.file.to_file.get(v).map(|&f| f as usize).unwrap_or(v);
        let e = match e {
            InteractError::FixedVertex { vertex, axis, action } => {
                InteractError::FixedVertex { vertex: file(vertex), axis, action }
            }
            InteractError::NonFinite { vertex, what, value } => {
                InteractError::NonFinite { vertex: file(vertex), what, value }
            }
            other => other,
        };
        lib_error(ProbeError::Body(e))
    }

    /// Positions (or any per-vertex vectors) of the body in file order.
    fn in_file_order(&self, p: &[Vec3]) -> Vec<Vec3> {
        self.file.positions_in_file_order(p)
    }

    /// Reactions as a `(k, 4)` array: file vertex, then the force, sorted by vertex.
    fn reactions_array<'py>(&self, py: Python<'py>, r: &[(usize, Vec3)]) -> Bound<'py, PyArray2<f64>> {
        let mut rows: Vec<(usize, Vec3)> =
            r.iter().map(|&(v, f)| (self.file.to_file[v] as usize, f)).collect();
        rows.sort_unstable_by_key(|r| r.0);
        Array2::from_shape_fn(
            (rows.len(), 4),
            |(k, c)| if c == 0 { rows[k].0 as f64 } else { rows[k].1[c - 1] },
        )
        .into_pyarray(py)
    }
}

/// Issues a Python `UserWarning` for each thing `model` asks for that an interactive FEM
/// body does not carry (the scene's grasps), as `probe` and `view` print it.
fn warn_ignored(py: Python<'_>, model: &fibfluid_sim::Model) -> PyResult<()> {
    for w in fibfluid_sim::ineffective_interactive(model) {
        let message = std::ffi::CString::new(crate::one_line(&w.to_string())).unwrap_or_default();
        let category = py.get_type::<pyo3::exceptions::PyUserWarning>();
        PyErr::warn(py, category.as_any(), &message, 1)?;
    }
    Ok(())
}

#[pymethods]
impl NativeBody {
    /// Builds the body of `scene` for `method` (`ffm`, `fem`, `tsve-chainmail`,
    /// `generalized-chainmail`; `None`: the scene's `[solver] method`), with the GIL released: for the fiber–fluid method one full
    /// solve of the scene's loads and the precomputed response, for ChainMail the lattice.
    #[new]
    #[pyo3(signature = (scene, method=None, max_memory=None))]
    fn new(
        py: Python<'_>,
        scene: &NativeScene,
        method: Option<&str>,
        max_memory: Option<u64>,
    ) -> PyResult<Self> {
        guard(|| {
            let method = match method {
                Some(m) => Method::parse_name(m).map_err(|e| error(e.to_string()))?,
                None => scene.scene.model.solver.method,
            };
            let Shape::Surface(file) = &scene.scene.shape else {
                return Err(error("an interactive body needs a surface mesh; this scene is a 2D polygon"));
            };
            let file = (**file).clone();
            let opts = ProbeOptions { max_memory_bytes: max_memory, ..Default::default() };
            let (model, chainmail) = (&scene.scene.model, &scene.scene.chainmail);
            let body = py.detach(|| MethodBody::build(model, chainmail, method, &opts)).map_err(lib_error)?;
            if method == Method::Fem {
                warn_ignored(py, model)?;
            }
            let setup_seconds = body.setup_seconds();
            let large_strain = body.interactive_ref().linearization().is_some();
            let guards = FrameGuards::new(body.interactive_ref().rest_positions(), file.mesh.triangles())
                .map_err(|e| error(format!("the result guards cannot measure this body: {e}")))?;
            Ok(NativeBody {
                body,
                file_to_mesh: file.file_to_mesh(),
                file,
                method,
                setup_seconds,
                tools: ToolSet::default(),
                loads: Vec::new(),
                guards,
                checks: ResultChecks::for_frames(method, large_strain),
                warnings: Vec::new(),
            })
        })
    }

    /// Holds file vertex `v` at its rest position plus `to` (3 floats) from the next step.
    fn grab(&mut self, v: i64, to: &Bound<'_, PyAny>) -> PyResult<()> {
        guard(|| {
            let m = self.vertex(v)?;
            let d = vec3(to, "the displacement")?;
            self.body.interactive().grab(m, d).map_err(|e| self.body_error(e))
        })
    }

    /// Pushes file vertex `v` with `force` (3 floats) from the next step (the fiber–fluid
    /// method only).
    fn push(&mut self, v: i64, force: &Bound<'_, PyAny>) -> PyResult<()> {
        guard(|| {
            let m = self.vertex(v)?;
            let f = vec3(force, "the force")?;
            self.body.interactive().push(m, f).map_err(|e| self.body_error(e))
        })
    }

    /// Grasps the patch within `radius` (metres, rest positions) of file vertex `v` and
    /// moves it rigidly by the displacement `to` and the rotation vector `rotation` (about
    /// the patch's rest centroid, as a scene's `[[grasp]]`) from the next step.
    #[pyo3(signature = (v, radius, to, rotation=None))]
    fn grasp(
        &mut self,
        v: i64,
        radius: f64,
        to: &Bound<'_, PyAny>,
        rotation: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        guard(|| {
            let m = self.vertex(v)?;
            let t = vec3(to, "the displacement")?;
            let r = rotation.map(|r| vec3(r, "the rotation")).transpose()?.unwrap_or([0.0; 3]);
            let motion = RigidMotion::with_rotation_vector(t, r);
            self.tools.grasp(self.body.interactive(), m, radius, motion).map_err(|e| self.body_error(e))?;
            Ok(())
        })
    }

    /// Places a rigid spherical tip of `radius` (metres) centred at `centre` (absolute,
    /// metres); the next step finds its contacts.
    fn press(&mut self, centre: &Bound<'_, PyAny>, radius: f64) -> PyResult<()> {
        guard(|| {
            let c = vec3(centre, "the centre")?;
            self.tools.press(self.body.interactive(), c, radius).map_err(|e| self.body_error(e))?;
            Ok(())
        })
    }

    /// Takes the tip away from the next step.
    fn lift(&mut self) -> PyResult<()> {
        self.tools.lift(self.body.interactive()).map_err(|e| self.body_error(e))
    }

    /// The result guards that fired on the last step: `(guard, message)` pairs, the message
    /// on one line (see `Body.warnings`).
    fn warnings(&self) -> Vec<(String, String)> {
        self.warnings.iter().map(|w| (w.guard.to_string(), crate::one_line(&w.to_string()))).collect()
    }

    /// The tools' loads after the last step, as JSON (see `Body.tools`).
    fn tools_json(&self) -> String {
        serde_json::to_string(&self.loads).unwrap_or_else(|_| "[]".into())
    }

    /// Drops the hold (or the grasp picked) on file vertex `v` from the next step.
    fn release(&mut self, v: i64) -> PyResult<()> {
        guard(|| {
            let m = self.vertex(v)?;
            if self.tools.release(self.body.interactive(), m).map_err(|e| self.body_error(e))? {
                return Ok(());
            }
            self.body.interactive().release(m).map_err(|e| self.body_error(e))
        })
    }

    /// Drops every hold, grasp and the tip from the next step.
    fn release_all(&mut self) -> PyResult<()> {
        guard(|| {
            self.tools.clear();
            self.body.interactive().release_all();
            Ok(())
        })
    }

    /// Makes the next `count` refreshes of a neo-Hookean finite-element body fail (see
    /// `HyperInteractive::fail_next_refreshes`): for testing what a caller does then. Only
    /// with the `testing` feature.
    #[cfg(feature = "testing")]
    fn fail_next_refreshes(&mut self, count: u32) -> PyResult<()> {
        match &mut self.body {
            MethodBody::Hyper(b) => {
                b.fail_next_refreshes(count);
                Ok(())
            }
            _ => Err(error("only a neo-Hookean finite-element body has refreshes")),
        }
    }

    /// Applies the holds and computes the frame (the GIL released), then checks it with the
    /// result guards (see `warnings`): returns the positions `(N, 3)` in file order and the
    /// reactions `(k, 4)`: file vertex, force x, y, z. A non-finite answer is an error.
    fn step<'py>(&mut self, py: Python<'py>) -> PyResult<Frame<'py>> {
        guard(|| {
            let (body, tools, to_file) = (&mut self.body, &mut self.tools, &self.file.to_file);
            let loads =
                py.detach(|| tools.frame(body.interactive(), to_file)).map_err(|e| self.body_error(e))?;
            self.loads = loads;
            self.warnings.clear();
            let checked = self.guards.check(self.body.interactive_ref().positions(), self.checks);
            self.warnings = checked.map_err(|e| {
                let e = match e {
                    FrameGuardError::NonFinite { vertex } => {
                        let file = self.file.to_file.get(vertex).map_or(vertex, |&f| f as usize);
                        FrameGuardError::NonFinite { vertex: file }
                    }
                    other => other,
                };
                error(e.to_string())
            })?;
            let reactions = self.body.interactive_ref().reactions().to_vec();
            let positions = self.in_file_order(self.body.interactive_ref().positions());
            Ok((points_array(py, &positions), self.reactions_array(py, &reactions)))
        })
    }

    /// Current positions `(N, 3)`, file order.
    fn positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        points_array(py, &self.in_file_order(self.body.interactive_ref().positions()))
    }

    /// Current displacement from rest `(N, 3)`, file order (zero at unused file vertices).
    fn displacement<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let body = self.body.interactive_ref();
        let mut d = vec![[0.0; 3]; self.file.file_vertex_count()];
        for (m, &f) in self.file.to_file.iter().enumerate() {
            d[f as usize] = body.field()[m];
        }
        points_array(py, &d)
    }

    /// Rest positions `(N, 3)`, file order.
    fn rest_positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        points_array(py, &self.in_file_order(self.body.interactive_ref().rest_positions()))
    }

    /// The current reactions `(k, 4)`.
    fn reactions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        self.reactions_array(py, self.body.interactive_ref().reactions())
    }

    /// The method's name.
    #[getter]
    fn method(&self) -> &'static str {
        self.method.name()
    }

    /// Whether the method takes forces (`push`) and gives reactions.
    #[getter]
    fn supports_forces(&self) -> bool {
        self.body.interactive_ref().supports_forces()
    }

    /// Number of vertices in file order.
    #[getter]
    fn n_vertices(&self) -> usize {
        self.file_to_mesh.len()
    }

    /// Frames computed so far.
    #[getter]
    fn frame(&self) -> u64 {
        self.body.interactive_ref().frame()
    }

    /// The linearization the last step used, as JSON (`null` for a body without one: FFM,
    /// ChainMail, the linear FEM); see `Body.linearization`.
    fn linearization_json(&self) -> String {
        let status = self.body.interactive_ref().linearization().map(|s| {
            serde_json::json!({
                "refreshes": s.refreshes,
                "refactorizations": s.refactorizations,
                "age_frames": s.age_frames,
                "age_seconds": s.age_seconds,
                "step": s.step,
                "estimated_error": s.estimated_error,
                "refresh_seconds": s.refresh_seconds,
                "pending": s.pending,
                "failure": s.failure,
            })
        });
        serde_json::to_string(&status).unwrap_or_else(|_| "null".into())
    }

    /// Seconds the setup took (base solve and precompute, or the lattice).
    #[getter]
    fn setup_seconds(&self) -> f64 {
        self.setup_seconds
    }

    /// Whether the scene fixes file vertex `v` along any axis.
    fn is_fixed(&self, v: i64) -> PyResult<bool> {
        let m = self.vertex(v)?;
        Ok(self.body.interactive_ref().is_fixed(m))
    }
}
