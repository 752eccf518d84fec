//! Scenes: a body, its material, constraints, loads and solver choices, from TOML or code.

use std::path::{Path, PathBuf};

use fibfluid_assembly::{ConstraintMethod, Constraints, Material, Selector, StiffnessLaw};
use fibfluid_geometry::{MeshFile, Polygon, ReadOptions, Vec3, load_mesh_with};
use fibfluid_linalg::Precision;
use serde::Deserialize;

use crate::{Error, Result};

/// How load steps are taken (REFERENCE §4–5).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Mode {
    /// The paper: K and the border from the rest shape, factored once; each step adds the
    /// increment computed on the current shape. Volume drifts to first order.
    Paper,
    /// K factored once, but the border S and the volume target `V0 - V` are refreshed from
    /// the current shape every step: no volume drift, triangular solves only.
    #[default]
    Refresh,
    /// K, S and the loads re-assembled and refactored on the current shape every step (the
    /// paper's "slower procedure"); supports strain-dependent moduli.
    Nonlinear,
}

impl Mode {
    /// Scene and report name.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Paper => "paper",
            Mode::Refresh => "refresh",
            Mode::Nonlinear => "nonlinear",
        }
    }

    /// Parses a scene or command-line name.
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "paper" => Some(Mode::Paper),
            "refresh" => Some(Mode::Refresh),
            "nonlinear" => Some(Mode::Nonlinear),
            _ => None,
        }
    }

    /// Every mode.
    pub const ALL: [Mode; 3] = [Mode::Paper, Mode::Refresh, Mode::Nonlinear];
}

/// The load-stepping scheme.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Stepping {
    /// Explicit first-order steps (the paper).
    #[default]
    Euler,
    /// Predictor–corrector: the load (and, outside paper mode, the operator) is evaluated
    /// again on the predicted shape and the two increments are averaged. Second order.
    Heun,
}

impl Stepping {
    /// Scene and report name.
    pub fn name(self) -> &'static str {
        match self {
            Stepping::Euler => "euler",
            Stepping::Heun => "heun",
        }
    }

    /// Parses a scene or command-line name.
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "euler" => Some(Stepping::Euler),
            "heun" => Some(Stepping::Heun),
            _ => None,
        }
    }
}

/// When a point force is applied.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ForceTiming {
    /// All of it at the last step (the paper's sphere example).
    #[default]
    Last,
    /// Spread evenly over the load steps.
    Ramp,
}

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

/// Solver choices.
#[derive(Clone, Debug, PartialEq)]
pub struct SolverOptions {
    /// Linear backend name (`structured`, `faer-lu`, `nalgebra-lu`, `openblas-lu`).
    pub backend: String,
    /// Stepping mode.
    pub mode: Mode,
    /// Stepping scheme.
    pub stepping: Stepping,
    /// Factorization precision.
    pub precision: Precision,
    /// How fixed degrees of freedom are imposed.
    pub constraints: ConstraintMethod,
}

impl Default for SolverOptions {
    /// Structured backend, refresh mode, Euler steps, f64, elimination.
    fn default() -> Self {
        Self {
            backend: "structured".into(),
            mode: Mode::Refresh,
            stepping: Stepping::Euler,
            precision: Precision::F64,
            constraints: ConstraintMethod::Eliminate,
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

/// A scene: everything a run needs.
#[derive(Clone, Debug)]
pub struct Scene {
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
    /// Final acceleration, reached in `steps` equal increments.
    pub gravity: Vec3,
    /// Point forces.
    pub forces: Vec<PointForce>,
    /// Number of load steps.
    pub steps: usize,
    /// Solver choices.
    pub solver: SolverOptions,
}

impl Scene {
    /// A scene for a mesh with the given material, no constraints, no loads, default solver.
    pub fn from_mesh(name: impl Into<String>, mesh: MeshFile, material: Material) -> Self {
        let n = mesh.mesh.n_vertices();
        Self {
            name: name.into(),
            source: None,
            shape: Shape::Surface(Box::new(mesh)),
            material,
            constraints: Constraints::new(n),
            gravity: [0.0; 3],
            forces: vec![],
            steps: 1,
            solver: SolverOptions::default(),
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

    /// Reads a scene file; paths inside are relative to it.
    pub fn load(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let err = |message: String| Error::Scene { path: path.to_path_buf(), message };
        if path.is_dir() {
            return Err(err("is a directory, not a scene file".into()));
        }
        // Regular files only, at most the file size limit (`fibfluid_geometry::read_file_limited`).
        let bytes = fibfluid_geometry::read_file_limited(path, None).map_err(|e| match e {
            fibfluid_geometry::ReadError::Io(source) => Error::Io { path: path.to_path_buf(), source },
            other => err(other.to_string()),
        })?;
        // A UTF-8 byte-order mark is not part of the first line.
        let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(&bytes);
        let text = std::str::from_utf8(bytes).map_err(|_| err("not a text file (invalid UTF-8)".into()))?;
        let spec: SceneToml = toml::from_str(text).map_err(|e| err(toml_message(text, &e)))?;
        let dir = path.parent().unwrap_or(Path::new("."));
        let name = path.file_stem().and_then(|s| s.to_str()).unwrap_or("scene").to_string();
        build(spec, dir, name, path).map_err(|e| match e {
            Error::Invalid(message) => err(message),
            // A bad mesh file: name the scene and its key too, not only the mesh file.
            Error::Geometry(g) => err(format!("[mesh].path: {g}")),
            other => other,
        })
    }
}

/// One line for a TOML error: the key it concerns (with its table), what is wrong, and
/// where (toml's own text is several lines with a source excerpt).
fn toml_message(text: &str, e: &toml::de::Error) -> String {
    let msg = e.message().split_whitespace().collect::<Vec<_>>().join(" ");
    let Some(span) = e.span() else { return msg };
    if span.start == 0 && span.end >= text.trim_end().len() {
        return msg; // about the whole document, e.g. a missing top-level table
    }
    let before = text.get(..span.start).unwrap_or(text);
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().unwrap_or("").chars().count() + 1;
    let (table, key) = key_at(text, line);
    let place = match (table, key) {
        // The key itself is named by the message; the table is what it lacks.
        (Some(t), _) if msg.starts_with("unknown field") => format!("{t}: "),
        (_, _) if msg.starts_with("unknown field") => String::new(),
        (Some(t), Some(k)) => format!("{t}.{k}: "),
        (None, Some(k)) => format!("{k}: "),
        (Some(t), None) => format!("{t}: "),
        (None, None) => String::new(),
    };
    format!("{place}{msg} (line {line}, column {column})")
}

/// The table (`[load]`, `[[fix]] #2`) and the key whose value covers 1-based `line`,
/// found by a light scan of the text (good enough to name them in a message).
fn key_at(text: &str, line: usize) -> (Option<String>, Option<String>) {
    let (mut table, mut key) = (None, None);
    let mut arrays: std::collections::HashMap<String, usize> = Default::default();
    let mut depth = 0i64; // open brackets of a multi-line value
    for raw in text.lines().take(line) {
        let l = raw.split('#').next().unwrap_or("").trim();
        if depth > 0 {
            depth += bracket_balance(l);
            continue;
        }
        if let Some(name) = l.strip_prefix("[[").and_then(|r| r.strip_suffix("]]")) {
            let name = name.trim().to_string();
            let k = arrays.entry(name.clone()).or_insert(0);
            *k += 1;
            table = Some(format!("[[{name}]] #{k}"));
            key = None;
        } else if let Some(name) = l.strip_prefix('[').and_then(|r| r.strip_suffix(']')) {
            table = Some(format!("[{}]", name.trim()));
            key = None;
        } else if let Some((k, v)) = l.split_once('=') {
            key = Some(k.trim().to_string());
            depth = bracket_balance(v).max(0);
        }
    }
    (table, key)
}

fn bracket_balance(s: &str) -> i64 {
    s.chars()
        .map(|c| {
            if c == '[' {
                1
            } else if c == ']' {
                -1
            } else {
                0
            }
        })
        .sum()
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneToml {
    mesh: Option<MeshToml>,
    polygon: Option<PolygonToml>,
    material: MaterialToml,
    fluid: Option<FluidToml>,
    load: Option<LoadToml>,
    gravity: Option<GravityToml>,
    #[serde(default)]
    fix: Vec<FixToml>,
    #[serde(default)]
    force: Vec<ForceToml>,
    solver: Option<SolverToml>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MeshToml {
    path: String,
    scale: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PolygonToml {
    points: Vec<[f64; 2]>,
}

#[derive(Deserialize)]
#[serde(untagged, expecting = "expected a number or an array of three numbers [x, y, z]")]
enum Young {
    One(f64),
    Three([f64; 3]),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MaterialToml {
    young: Young,
    #[serde(default)]
    surface_tension: f64,
    /// Quadratic stiffening coefficient c: Y (1 + c strain^2).
    stiffening: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FluidToml {
    density: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LoadToml {
    steps: Option<i64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GravityToml {
    acceleration: [f64; 3],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FixToml {
    axis: Option<String>,
    above: Option<f64>,
    below: Option<f64>,
    top: Option<f64>,
    bottom: Option<f64>,
    vertices: Option<Vec<i64>>,
    #[serde(rename = "box")]
    bbox: Option<[[f64; 3]; 2]>,
    dofs: Option<Vec<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ForceToml {
    vertex: i64,
    value: [f64; 3],
    at: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SolverToml {
    backend: Option<String>,
    mode: Option<String>,
    stepping: Option<String>,
    precision: Option<String>,
    constraints: Option<String>,
    penalty: Option<f64>,
}

fn axis_index(s: &str, key: &str) -> Result<usize> {
    match s {
        "x" => Ok(0),
        "y" => Ok(1),
        "z" => Ok(2),
        other => Err(Error::Invalid(format!("{key}: `{other}` is not an axis (x, y or z)"))),
    }
}

fn build(spec: SceneToml, dir: &Path, name: String, scene_path: &Path) -> Result<Scene> {
    let inv = |m: String| Error::Invalid(m);
    let shape = match (spec.mesh, spec.polygon) {
        (Some(m), None) => {
            let mesh_path = dir.join(&m.path);
            if !mesh_path.exists() {
                return Err(inv(format!(
                    "[mesh].path: `{}` does not exist (resolved to {})",
                    m.path,
                    mesh_path.display()
                )));
            }
            if let Some(s) = m.scale
                && !(s.is_finite() && s > 0.0)
            {
                return Err(inv(format!("[mesh].scale must be positive, got {s}")));
            }
            // Scaled before validation: coordinates too large or small for f64 are checked
            // in the units the scene uses.
            let file = load_mesh_with(&mesh_path, &ReadOptions { scale: m.scale, ..Default::default() })?;
            Shape::Surface(Box::new(file))
        }
        (None, Some(p)) => Shape::Polygon(
            Polygon::new(p.points)
                .ok_or_else(|| inv("[polygon].points: at least 3 finite points are needed".into()))?,
        ),
        (Some(_), Some(_)) => return Err(inv("give either [mesh] or [polygon], not both".into())),
        (None, None) => return Err(inv("missing [mesh] (or [polygon]) table".into())),
    };
    let axes = if matches!(shape, Shape::Polygon(_)) { 2 } else { 3 };
    let young = match spec.material.young {
        Young::One(y) => [y; 3],
        Young::Three(y) => y,
    };
    for (c, y) in young.iter().enumerate().take(axes) {
        if !(y.is_finite() && *y > 0.0) {
            return Err(inv(format!(
                "[material].young: must be positive, got {y} along {}",
                ['x', 'y', 'z'][c]
            )));
        }
    }
    let gamma = spec.material.surface_tension;
    if !(gamma.is_finite() && gamma >= 0.0) {
        return Err(inv(format!("[material].surface_tension: must be >= 0, got {gamma}")));
    }
    let law = match spec.material.stiffening {
        None => StiffnessLaw::Linear,
        Some(c) if c.is_finite() && c >= 0.0 => StiffnessLaw::Quadratic { c },
        Some(c) => return Err(inv(format!("[material].stiffening: must be >= 0, got {c}"))),
    };
    let density = spec.fluid.map(|f| f.density).unwrap_or(0.0);
    if !(density.is_finite() && density >= 0.0) {
        return Err(inv(format!("[fluid].density: must be >= 0, got {density}")));
    }
    let steps = spec.load.and_then(|l| l.steps).unwrap_or(1);
    if !(1..=1_000_000).contains(&steps) {
        return Err(inv(format!("[load].steps: must be between 1 and 1000000, got {steps}")));
    }
    let gravity = spec.gravity.map(|g| g.acceleration).unwrap_or([0.0; 3]);
    if gravity.iter().any(|c| !c.is_finite()) {
        return Err(inv("[gravity].acceleration: must be finite".into()));
    }
    let (n, positions, file) = match &shape {
        Shape::Surface(m) => (m.mesh.n_vertices(), m.mesh.positions().to_vec(), Some(m.as_ref())),
        Shape::Polygon(p) => (p.n_vertices(), p.positions_3d(), None),
    };
    let to_mesh_index = |v: i64, key: &str| -> Result<usize> {
        let count = file.map(|f| f.file_vertex_count()).unwrap_or(n);
        if v < 0 || v as usize >= count {
            return Err(inv(format!(
                "{key}: vertex {v} is out of range (the mesh file has {count} vertices, 0-based)"
            )));
        }
        match file {
            Some(f) => f
                .from_file_index(v as usize)
                .ok_or_else(|| inv(format!("{key}: vertex {v} is not used by any face"))),
            None => Ok(v as usize),
        }
    };
    let mut constraints = Constraints::new(n);
    for (k, fix) in spec.fix.iter().enumerate() {
        let key = format!("[[fix]] #{}", k + 1);
        let mut dofs = [false; 3];
        match &fix.dofs {
            None => dofs[..axes].iter_mut().for_each(|d| *d = true),
            Some(list) => {
                if list.is_empty() {
                    return Err(inv(format!("{key}.dofs: empty list")));
                }
                for d in list {
                    let c = axis_index(d, &format!("{key}.dofs"))?;
                    if c >= axes {
                        return Err(inv(format!("{key}.dofs: a 2D scene has no z axis")));
                    }
                    dofs[c] = true;
                }
            }
        }
        let axis = fix.axis.as_deref().map(|a| axis_index(a, &format!("{key}.axis"))).transpose()?;
        let kinds = [
            fix.above.is_some(),
            fix.below.is_some(),
            fix.top.is_some(),
            fix.bottom.is_some(),
            fix.vertices.is_some(),
            fix.bbox.is_some(),
        ];
        if kinds.iter().filter(|k| **k).count() != 1 {
            return Err(inv(format!("{key}: give exactly one of above, below, top, bottom, vertices, box")));
        }
        let need_axis =
            || axis.ok_or_else(|| inv(format!("{key}: `axis` is required with above/below/top/bottom")));
        let selector = if let Some(v) = fix.above {
            Selector::Above { axis: need_axis()?, value: v }
        } else if let Some(v) = fix.below {
            Selector::Below { axis: need_axis()?, value: v }
        } else if let Some(v) = fix.top {
            if v.is_nan() || v < 0.0 {
                return Err(inv(format!("{key}.top: must be >= 0")));
            }
            Selector::Top { axis: need_axis()?, within: v }
        } else if let Some(v) = fix.bottom {
            if v.is_nan() || v < 0.0 {
                return Err(inv(format!("{key}.bottom: must be >= 0")));
            }
            Selector::Bottom { axis: need_axis()?, within: v }
        } else if let Some(b) = fix.bbox {
            Selector::Box { min: b[0], max: b[1] }
        } else {
            let list = fix.vertices.as_deref().unwrap_or(&[]);
            let idx = list
                .iter()
                .map(|&v| to_mesh_index(v, &format!("{key}.vertices")))
                .collect::<Result<Vec<_>>>()?;
            Selector::Vertices(idx)
        };
        constraints.fix_selected(&selector, &positions, dofs).map_err(|e| inv(format!("{key}: {e}")))?;
    }
    let mut forces = Vec::new();
    for (k, f) in spec.force.iter().enumerate() {
        let key = format!("[[force]] #{}", k + 1);
        let vertex = to_mesh_index(f.vertex, &format!("{key}.vertex"))?;
        if f.value.iter().any(|c| !c.is_finite()) {
            return Err(inv(format!("{key}.value: must be finite")));
        }
        let timing = match f.at.as_deref() {
            None | Some("last") => ForceTiming::Last,
            Some("ramp") => ForceTiming::Ramp,
            Some(o) => return Err(inv(format!("{key}.at: `{o}` is not `last` or `ramp`"))),
        };
        forces.push(PointForce { vertex, value: f.value, timing });
    }
    let mut solver = SolverOptions::default();
    if let Some(s) = spec.solver {
        if let Some(b) = s.backend {
            fibfluid_linalg::backend_by_name(&b).map_err(|e| inv(format!("[solver].backend: {e}")))?;
            solver.backend = b;
        }
        if let Some(m) = s.mode {
            solver.mode = Mode::parse(&m)
                .ok_or_else(|| inv(format!("[solver].mode: `{m}` is not paper, refresh or nonlinear")))?;
        }
        if let Some(m) = s.stepping {
            solver.stepping = Stepping::parse(&m)
                .ok_or_else(|| inv(format!("[solver].stepping: `{m}` is not euler or heun")))?;
        }
        if let Some(p) = s.precision {
            solver.precision = match p.as_str() {
                "f64" => Precision::F64,
                "mixed" => Precision::Mixed,
                o => return Err(inv(format!("[solver].precision: `{o}` is not f64 or mixed"))),
            };
        }
        let big = s.penalty.unwrap_or(1e9);
        if !(big.is_finite() && big > 0.0) {
            return Err(inv(format!("[solver].penalty: must be positive, got {big}")));
        }
        match s.constraints.as_deref() {
            None => {}
            Some("penalty") => solver.constraints = ConstraintMethod::Penalty { big },
            Some("eliminate") => solver.constraints = ConstraintMethod::Eliminate,
            Some(o) => return Err(inv(format!("[solver].constraints: `{o}` is not penalty or eliminate"))),
        }
    }
    for c in 0..axes {
        if constraints.count(c) == 0 {
            return Err(inv(format!(
                "[[fix]]: no vertex is fixed along {}; with the volume conserved the body could still translate freely (add a [[fix]] table)",
                ['x', 'y', 'z'][c]
            )));
        }
    }
    let material = Material { young, surface_tension: gamma, density, law };
    Ok(Scene {
        name,
        source: Some(scene_path.to_path_buf()),
        shape,
        material,
        constraints,
        gravity,
        forces,
        steps: steps as usize,
        solver,
    })
}
