//! `fibfluid.Scene`'s compiled half: a scene file read into the engine's values, its
//! settings by name, its mesh replaced by arrays.

use std::path::PathBuf;
use std::time::Instant;

use fibfluid_geometry::{MeshFile, TriMesh};
use fibfluid_scene::Scene;
use fibfluid_sim::Shape;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{points, points_array, triangles, triangles_array};
use crate::{error, guard, lib_error, settings};

/// What `with_mesh` calls the arrays in messages (where a file's path would be).
const ARRAYS: &str = "<arrays>";

/// A scene: the engine's model and the ChainMail settings, as `Scene::load` reads them.
#[pyclass(module = "fibfluid._native", name = "NativeScene", skip_from_py_object)]
#[derive(Clone)]
pub(crate) struct NativeScene {
    pub(crate) scene: Scene,
    /// Seconds it took to read (the report's `load_scene` stage, as the command line's).
    pub(crate) load_seconds: f64,
}

#[pymethods]
impl NativeScene {
    /// Reads a scene file (TOML); paths inside are relative to it.
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        guard(|| {
            py.detach(|| {
                let start = Instant::now();
                let scene = Scene::load(&path).map_err(|e| e.to_string())?;
                Ok(NativeScene { scene, load_seconds: start.elapsed().as_secs_f64() })
            })
            .map_err(|e: String| error(e))
        })
    }

    /// A new scene with the body replaced by the surface of `vertices` `(N, 3)` and
    /// `faces` `(F, 3)`, validated like a mesh file; the scene file's constraints, forces
    /// and plates are built again against it (see `Scene::load_with_mesh`); this scene's
    /// settings carry over.
    fn with_mesh(
        &self,
        py: Python<'_>,
        vertices: &Bound<'_, PyAny>,
        faces: &Bound<'_, PyAny>,
    ) -> PyResult<Self> {
        guard(|| {
            let start = Instant::now();
            let (p, t) = (points(vertices, "vertices")?, triangles(faces, "faces")?);
            let Some(source) = self.scene.source.clone() else {
                return Err(error("with_mesh needs a scene read from a file (Scene.load)"));
            };
            let old = &self.scene;
            let rebuilt = py
                .detach(|| {
                    let mesh = TriMesh::new(p, t).and_then(|m| MeshFile::from_mesh(ARRAYS, m)).map_err(
                        |source| fibfluid_geometry::GeometryError::Mesh { path: ARRAYS.into(), source },
                    )?;
                    Scene::load_with_mesh(&source, mesh)
                })
                .map_err(lib_error)?;
            // The settings (this scene's, perhaps changed since it was read) carry over;
            // what depends on the vertices comes from the scene file and the new mesh.
            let mut scene = rebuilt;
            scene.model.name = old.name.clone();
            scene.model.material = old.material.clone();
            scene.model.load.gravity = old.load.gravity;
            scene.model.load.steps = old.load.steps;
            scene.model.load.tolerance = old.load.tolerance;
            scene.model.guards = old.guards;
            scene.model.solver = old.solver.clone();
            scene.chainmail = old.chainmail.clone();
            Ok(NativeScene { scene, load_seconds: start.elapsed().as_secs_f64() })
        })
    }

    /// The value of one setting.
    fn get(&self, py: Python<'_>, name: &str) -> PyResult<Py<PyAny>> {
        guard(|| settings::get(py, &self.scene, name))
    }

    /// Sets one setting (checked as the scene file's key is).
    fn set(&mut self, name: &str, value: &Bound<'_, PyAny>) -> PyResult<()> {
        guard(|| settings::set(&mut self.scene, name, value))
    }

    /// Sets several settings at once: all or none (the first bad one raises and nothing
    /// changes).
    fn update(&mut self, values: &Bound<'_, PyDict>) -> PyResult<()> {
        guard(|| {
            let mut next = self.scene.clone();
            for (k, v) in values.iter() {
                let name: String = k.extract().map_err(|_| error("setting names must be strings"))?;
                settings::set(&mut next, &name, &v)?;
            }
            self.scene = next;
            Ok(())
        })
    }

    /// Sets a tissue, region or gravity parameter by its dotted key (`tissue.young`,
    /// `region.NAME.poisson`, `gravity`: the keys of `[fit]` and `fibfluid run --set`).
    fn set_parameter(&mut self, key: &str, value: f64) -> PyResult<()> {
        guard(|| {
            let p = fibfluid_scene::parameter_of_key(key, &self.scene.model).map_err(error)?;
            fibfluid_sim::inverse::set_parameter(&mut self.scene.model, p, value)
                .map_err(|e| error(format!("{key} = {value}: {e}")))
        })
    }

    /// Every setting's name.
    #[staticmethod]
    fn names() -> Vec<&'static str> {
        settings::NAMES.to_vec()
    }

    /// The solver settings' names.
    #[staticmethod]
    fn solver_names() -> Vec<&'static str> {
        settings::SOLVER.to_vec()
    }

    /// A copy (settings changed on it do not change this one).
    fn copy(&self) -> Self {
        self.clone()
    }

    /// The scene's name (the file's stem).
    #[getter]
    fn name(&self) -> String {
        self.scene.name.clone()
    }

    /// The scene file.
    #[getter]
    fn source(&self) -> Option<PathBuf> {
        self.scene.source.clone()
    }

    /// Whether the body is a surface (not the 2D polygon).
    #[getter]
    fn is_surface(&self) -> bool {
        self.scene.is_surface()
    }

    /// Number of vertices in the body's file order (a mesh file's vertices, used or not).
    #[getter]
    fn n_vertices(&self) -> usize {
        match &self.scene.shape {
            Shape::Surface(m) => m.file_vertex_count(),
            Shape::Polygon(p) => p.n_vertices(),
        }
    }

    /// Rest positions `(N, 3)` in file order.
    fn vertices<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray2<f64>> {
        match &self.scene.shape {
            Shape::Surface(m) => points_array(py, &m.file_positions),
            Shape::Polygon(p) => points_array(py, &p.positions_3d()),
        }
    }

    /// Triangles `(F, 3)` in file vertex indices, oriented outward (a polygon: a fan).
    fn faces<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray2<i64>> {
        match &self.scene.shape {
            Shape::Surface(m) => triangles_array(py, &m.triangles_in_file_order()),
            Shape::Polygon(p) => {
                let fan: Vec<[u32; 3]> = (1..p.n_vertices() as u32 - 1).map(|k| [0, k, k + 1]).collect();
                triangles_array(py, &fan)
            }
        }
    }

    /// Vertices (file order) fixed along at least one axis, ascending.
    fn fixed_vertices(&self) -> Vec<usize> {
        let c = &self.scene.constraints;
        let fixed = (0..self.scene.n_vertices()).filter(|&v| (0..3).any(|a| c.get(v, a).is_some()));
        let mut out: Vec<usize> = match &self.scene.shape {
            Shape::Surface(m) => fixed.map(|v| m.to_file[v] as usize).collect(),
            Shape::Polygon(_) => fixed.collect(),
        };
        out.sort_unstable();
        out
    }

    /// The scene's settings that cannot act (gravity without density, ...), one message
    /// each, as the command line's `warning:` lines.
    fn ineffective(&self) -> Vec<String> {
        fibfluid_sim::ineffective(&self.scene).iter().map(|w| crate::one_line(&w.to_string())).collect()
    }

    /// Notes about the mesh (unreferenced vertices dropped, a surface flipped outward).
    fn notes(&self) -> Vec<String> {
        match &self.scene.shape {
            Shape::Surface(m) => m.notes.clone(),
            Shape::Polygon(_) => vec![],
        }
    }
}
