//! The fibfluid scene format: a TOML file (body, material, constraints, loads, solver
//! choices, ChainMail settings) read into the engine's validated values, and tool-path
//! files (`PATH.csv`) read into [`ToolPath`]s. Every problem names the file, the line
//! where it can be found and the key (`scene.toml:12: [load].steps: must be ...`).
//!
//! The format is described in `docs/scene-format.md`. Files are read through
//! [`fibfluid_geometry::read_file_limited`] (regular files only, a size limit), like meshes.
//!
//! ```no_run
//! let scene = fibfluid_scene::Scene::load("fixtures/scenes/sphere.toml")?;
//! let mut sim = fibfluid_sim::Simulation::new(scene)?;
//! sim.run(&Default::default())?;
//! # Ok::<(), fibfluid_scene::Error>(())
//! ```

use std::ops::{Deref, DerefMut};
use std::path::Path;

use fibfluid_assembly::Material;
use fibfluid_geometry::MeshFile;
use fibfluid_interact::chainmail_settings::ChainmailSettings;
use fibfluid_sim::Model;

mod build;
mod chainmail_section;
mod error;
mod fit_table;
mod invalid;
mod lines;
mod path_file;
mod pressure_table;
mod regions;
mod spec;
mod time_table;
mod tissue_table;

pub use error::{Error, Result, SceneError, SceneProblem};
pub use fit_table::{fit_parameters, parameter_of_key};
pub use path_file::{load_tool_path, parse_tool_path};

use invalid::Invalid;
use lines::{line_of_key, toml_problem};
use spec::SceneToml;

/// A scene: the engine's [`Model`] and the settings of the interactive-only methods
/// (ChainMail's `[chainmail]` section). It dereferences to the model, so
/// `scene.steps` or `scene.solver.backend` read and write the model's values.
#[derive(Clone, Debug)]
pub struct Scene {
    /// What the engine runs.
    pub model: Model,
    /// How the ChainMail methods voxelize and deform the body (`[chainmail]`).
    pub chainmail: ChainmailSettings,
    /// Whether FFM can run the scene: its fibers are given (`[ffm]` or the older
    /// `[material]`), or calibrated from `[tissue]` against the FEM
    /// (`model.ffm.calibrate`).
    pub ffm_material: bool,
}

impl Deref for Scene {
    type Target = Model;
    fn deref(&self) -> &Model {
        &self.model
    }
}

impl DerefMut for Scene {
    fn deref_mut(&mut self) -> &mut Model {
        &mut self.model
    }
}

impl From<Scene> for Model {
    fn from(scene: Scene) -> Model {
        scene.model
    }
}

impl From<Model> for Scene {
    fn from(model: Model) -> Scene {
        Scene { model, chainmail: ChainmailSettings::default(), ffm_material: true }
    }
}

impl Scene {
    /// A scene for a mesh with the given material, no constraints, no loads, default
    /// solver and ChainMail settings.
    pub fn from_mesh(name: impl Into<String>, mesh: MeshFile, material: Material) -> Self {
        Model::from_mesh(name, mesh, material).into()
    }

    /// Reads a scene file; paths inside are relative to it. Every problem is a
    /// [`SceneError`] naming the file, the key and, where it can be found, the line.
    pub fn load(path: impl AsRef<Path>) -> Result<Self> {
        Self::read(path.as_ref(), None)
    }

    /// Reads a scene file with its `[mesh]` replaced by `mesh` (a surface built in code,
    /// for example from arrays): the file's `[mesh]` is not read, and `[mesh].scale` does
    /// not apply (`mesh` is in the scene's units). Everything that depends on the vertices
    /// is built again against `mesh` as the file's own mesh would be: the `[[fix]]`
    /// selectors (above, below, top, bottom, box) select among its vertices, and vertex
    /// indices (`[[fix]].vertices`, `[[force]].vertex`) are `mesh`'s file order, checked
    /// against its vertex count; plates are checked against its rest shape. Errors name
    /// the scene file, the line and the key, as [`load`](Self::load)'s do.
    ///
    /// A scene whose body is a `[polygon]` has no mesh to replace: that is an error.
    pub fn load_with_mesh(path: impl AsRef<Path>, mesh: MeshFile) -> Result<Self> {
        Self::read(path.as_ref(), Some(mesh))
    }

    fn read(path: &Path, mesh: Option<MeshFile>) -> Result<Self> {
        let at = |key: Option<String>, line: Option<usize>, problem: SceneProblem| {
            Error::Scene(Box::new(SceneError { path: path.to_path_buf(), line, key, problem }))
        };
        if path.is_dir() {
            return Err(at(None, None, SceneProblem::IsDirectory));
        }
        // Regular files only, at most the file size limit (`fibfluid_geometry::read_file_limited`).
        let bytes = fibfluid_geometry::read_file_limited(path, None).map_err(|e| match e {
            fibfluid_geometry::ReadError::Io(source) => Error::Io { path: path.to_path_buf(), source },
            other => at(None, None, SceneProblem::Read(other)),
        })?;
        // A UTF-8 byte-order mark is not part of the first line.
        let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(&bytes);
        let text = std::str::from_utf8(bytes).map_err(|_| at(None, None, SceneProblem::NotUtf8))?;
        let mut spec: SceneToml = toml::from_str(text).map_err(|e| {
            let (line, key, problem) = toml_problem(text, &e);
            at(key, line, problem)
        })?;
        let dir = path.parent().unwrap_or(Path::new("."));
        let name = path.file_stem().and_then(|s| s.to_str()).unwrap_or("scene").to_string();
        let located = |Invalid { key, problem }| {
            let line = key.as_deref().and_then(|k| line_of_key(text, k));
            at(key, line, problem)
        };
        let chainmail = chainmail_section::parse(spec.chainmail.take()).map_err(located)?;
        let ffm_material = spec.material.is_some()
            || spec.ffm.as_ref().is_some_and(|f| f.fiber_modulus.is_some() || f.young.is_some())
            || spec.tissue.is_some();
        let mut model = build::build(spec, dir, name, mesh).map_err(located)?;
        model.source = Some(path.to_path_buf());
        Ok(Self { model, chainmail, ffm_material })
    }
}
