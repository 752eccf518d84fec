//! Scenes: a body, its material, constraints, loads and solver choices, from TOML or code.

use std::path::{Path, PathBuf};

use fibfluid_assembly::{
    ConstraintKind, ConstraintMethod, Constraints, DEFAULT_PENALTY, Material, Selector, StiffnessLaw,
};
use fibfluid_geometry::{MeshFile, Polygon, ReadOptions, Vec3, load_mesh_with};
use fibfluid_linalg::{Backend, Choice, Precision, impl_choice};
use serde::Deserialize;

use crate::contact::{Plate, PlateProblem, check_plates};
use crate::error::{SceneError, SceneProblem};
use crate::guards::Guards;
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

impl Choice for Mode {
    const WHAT: &'static str = "mode";
    const ALL: &'static [Self] = &[Mode::Paper, Mode::Refresh, Mode::Nonlinear];
    fn name(self) -> &'static str {
        match self {
            Mode::Paper => "paper",
            Mode::Refresh => "refresh",
            Mode::Nonlinear => "nonlinear",
        }
    }
}
impl_choice!(Mode);

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

impl Choice for Stepping {
    const WHAT: &'static str = "stepping scheme";
    const ALL: &'static [Self] = &[Stepping::Euler, Stepping::Heun];
    fn name(self) -> &'static str {
        match self {
            Stepping::Euler => "euler",
            Stepping::Heun => "heun",
        }
    }
}
impl_choice!(Stepping);

/// When a point force is applied.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ForceTiming {
    /// All of it at the last step (the paper's sphere example).
    #[default]
    Last,
    /// Spread evenly over the load steps.
    Ramp,
}

impl Choice for ForceTiming {
    const WHAT: &'static str = "force timing";
    const ALL: &'static [Self] = &[ForceTiming::Last, ForceTiming::Ramp];
    fn name(self) -> &'static str {
        match self {
            ForceTiming::Last => "last",
            ForceTiming::Ramp => "ramp",
        }
    }
}
impl_choice!(ForceTiming);

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
    /// Number of load steps (with `tolerance`: the first step is 1/steps of the load).
    pub steps: usize,
    /// Adaptive load steps: the largest error estimate of a step, relative to the step's
    /// displacement (`[load] tolerance`); `None`: `steps` equal steps.
    pub tolerance: Option<f64>,
    /// Step guards (`[guards]`).
    pub guards: Guards,
    /// Rigid plates (`[[plate]]`), moving along their normals over the load.
    pub plates: Vec<Plate>,
    /// Solver choices.
    pub solver: SolverOptions,
    /// How the ChainMail methods voxelize and deform the body (`[chainmail]`).
    pub chainmail: crate::chainmail_scene::ChainmailSettings,
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
            tolerance: None,
            guards: Guards::default(),
            plates: vec![],
            solver: SolverOptions::default(),
            chainmail: Default::default(),
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

    /// Reads a scene file; paths inside are relative to it. Every problem is a
    /// [`SceneError`] naming the file, the key and, where it can be found, the line.
    pub fn load(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
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
        let spec: SceneToml = toml::from_str(text).map_err(|e| {
            let (line, key, problem) = toml_problem(text, &e);
            at(key, line, problem)
        })?;
        let dir = path.parent().unwrap_or(Path::new("."));
        let name = path.file_stem().and_then(|s| s.to_str()).unwrap_or("scene").to_string();
        build(spec, dir, name, path).map_err(|Invalid { key, problem }| {
            let line = key.as_deref().and_then(|k| line_of_key(text, k));
            at(key, line, problem)
        })
    }
}

/// A problem found while building a scene, before the file is known.
pub(crate) struct Invalid {
    key: Option<String>,
    problem: SceneProblem,
}

pub(crate) fn invalid(key: impl Into<String>, problem: SceneProblem) -> Invalid {
    Invalid { key: Some(key.into()), problem }
}

pub(crate) fn range(key: impl Into<String>, rule: &'static str, value: impl std::fmt::Display) -> Invalid {
    invalid(key, SceneProblem::Range { rule, value: value.to_string() })
}

pub(crate) fn choice<T: Choice>(
    key: &str,
    value: Option<String>,
    default: T,
) -> std::result::Result<T, Invalid> {
    match value {
        None => Ok(default),
        Some(v) => T::parse_name(&v).map_err(|e| invalid(key, SceneProblem::Choice(e))),
    }
}

/// The line, key and problem of a TOML error (toml's own text is several lines with a
/// source excerpt).
fn toml_problem(text: &str, e: &toml::de::Error) -> (Option<usize>, Option<String>, SceneProblem) {
    let message = e.message().split_whitespace().collect::<Vec<_>>().join(" ");
    let Some(span) = e.span().filter(|s| !(s.start == 0 && s.end >= text.trim_end().len())) else {
        // About the whole document, e.g. a missing top-level table.
        return (None, None, SceneProblem::Toml { message, column: None });
    };
    let before = text.get(..span.start).unwrap_or(text);
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().unwrap_or("").chars().count() + 1;
    let (table, key) = key_at(text, line);
    let key = match (table, key) {
        // An unknown key is named by the message; the table is what it lacks.
        (t, _) if message.starts_with("unknown field") => t,
        (Some(t), Some(k)) => Some(format!("{t}.{k}")),
        (t, k) => t.or(k),
    };
    (Some(line), key, SceneProblem::Toml { message, column: Some(column) })
}

/// The 1-based line where `key` (`[load].steps`, `[[fix]] #2.vertices`, `[mesh]`) is
/// written, found by a light scan of the text.
fn line_of_key(text: &str, key: &str) -> Option<usize> {
    let close = key.rfind(']')?;
    let header = &key[..=close];
    let (nth, field) = match key[close + 1..].split_once('.') {
        Some((n, f)) => (n, Some(f)),
        None => (&key[close + 1..], None),
    };
    let nth = match nth.trim().strip_prefix('#') {
        Some(k) => k.parse::<usize>().ok()?,
        None => 1,
    };
    let mut seen = 0;
    let mut inside = false;
    for (i, raw) in text.lines().enumerate() {
        let l = raw.split('#').next().unwrap_or("").trim();
        if l.starts_with('[') {
            inside = l == header && {
                seen += 1;
                seen == nth
            };
            if inside && field.is_none() {
                return Some(i + 1);
            }
        } else if inside
            && let Some(f) = field
            && l.split_once('=').is_some_and(|(k, _)| k.trim() == f)
        {
            return Some(i + 1);
        }
    }
    None
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
    guards: Option<GuardsToml>,
    #[serde(default)]
    plate: Vec<PlateToml>,
    chainmail: Option<crate::chainmail_scene::ChainmailToml>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PlateToml {
    point: [f64; 3],
    normal: [f64; 3],
    #[serde(default)]
    travel: f64,
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
    tolerance: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GuardsToml {
    on_failure: Option<String>,
    volume: Option<f64>,
    increment: Option<f64>,
    inverted: Option<i64>,
    residual: Option<f64>,
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

fn axis_index(s: &str, key: &str) -> std::result::Result<usize, Invalid> {
    match s {
        "x" => Ok(0),
        "y" => Ok(1),
        "z" => Ok(2),
        other => Err(invalid(key, SceneProblem::NotAnAxis { given: other.to_string() })),
    }
}

fn build(
    spec: SceneToml,
    dir: &Path,
    name: String,
    scene_path: &Path,
) -> std::result::Result<Scene, Invalid> {
    let shape = match (spec.mesh, spec.polygon) {
        (Some(m), None) => {
            let mesh_path = dir.join(&m.path);
            if !mesh_path.exists() {
                return Err(invalid(
                    "[mesh].path",
                    SceneProblem::MeshNotFound { given: m.path.clone(), resolved: mesh_path },
                ));
            }
            if let Some(s) = m.scale
                && !(s.is_finite() && s > 0.0)
            {
                return Err(range("[mesh].scale", "positive", s));
            }
            // Scaled before validation: coordinates too large or small for f64 are checked
            // in the units the scene uses.
            let file = load_mesh_with(&mesh_path, &ReadOptions { scale: m.scale, ..Default::default() })
                .map_err(|e| invalid("[mesh].path", SceneProblem::Mesh(e)))?;
            Shape::Surface(Box::new(file))
        }
        (None, Some(p)) => Shape::Polygon(Polygon::new(p.points).ok_or_else(|| {
            invalid("[polygon].points", SceneProblem::Conflict("at least 3 finite points are needed"))
        })?),
        (Some(_), Some(_)) => {
            return Err(Invalid {
                key: None,
                problem: SceneProblem::Conflict("give either [mesh] or [polygon], not both"),
            });
        }
        (None, None) => {
            return Err(Invalid {
                key: None,
                problem: SceneProblem::Conflict("missing [mesh] (or [polygon]) table"),
            });
        }
    };
    let axes = if matches!(shape, Shape::Polygon(_)) { 2 } else { 3 };
    let young = match spec.material.young {
        Young::One(y) => [y; 3],
        Young::Three(y) => y,
    };
    for (c, y) in young.iter().enumerate().take(axes) {
        if !(y.is_finite() && *y > 0.0) {
            return Err(range("[material].young", "positive", format!("{y} along {}", ['x', 'y', 'z'][c])));
        }
    }
    let gamma = spec.material.surface_tension;
    if !(gamma.is_finite() && gamma >= 0.0) {
        return Err(range("[material].surface_tension", ">= 0", gamma));
    }
    let law = match spec.material.stiffening {
        None => StiffnessLaw::Linear,
        Some(c) if c.is_finite() && c >= 0.0 => StiffnessLaw::Quadratic { c },
        Some(c) => return Err(range("[material].stiffening", ">= 0", c)),
    };
    let density = spec.fluid.map(|f| f.density).unwrap_or(0.0);
    if !(density.is_finite() && density >= 0.0) {
        return Err(range("[fluid].density", ">= 0", density));
    }
    let (steps, tolerance) = spec.load.map(|l| (l.steps, l.tolerance)).unwrap_or((None, None));
    let steps = steps.unwrap_or(if tolerance.is_some() { 4 } else { 1 });
    if !(1..=MAX_STEPS as i64).contains(&steps) {
        return Err(range("[load].steps", "between 1 and 1000000", steps));
    }
    if let Some(t) = tolerance
        && !(t.is_finite() && t > 0.0 && t < 1.0)
    {
        return Err(range("[load].tolerance", "between 0 and 1", t));
    }
    let mut guards = Guards::default();
    if let Some(g) = spec.guards {
        guards.on_failure = choice("[guards].on_failure", g.on_failure, guards.on_failure)?;
        for (key, value) in [("volume", g.volume), ("increment", g.increment), ("residual", g.residual)] {
            if let Some(v) = value
                && !(v.is_finite() && v > 0.0)
            {
                return Err(range(format!("[guards].{key}"), "positive", v));
            }
        }
        if let Some(k) = g.inverted
            && k < 0
        {
            return Err(range("[guards].inverted", ">= 0", k));
        }
        guards.volume = g.volume;
        guards.increment = g.increment;
        guards.residual = g.residual;
        guards.inverted = g.inverted.map(|k| k as usize);
    }
    let gravity = spec.gravity.map(|g| g.acceleration).unwrap_or([0.0; 3]);
    if let Some(c) = gravity.iter().find(|c| !c.is_finite()) {
        return Err(range("[gravity].acceleration", "finite", c));
    }
    let (n, positions, file) = match &shape {
        Shape::Surface(m) => (m.mesh.n_vertices(), m.mesh.positions().to_vec(), Some(m.as_ref())),
        Shape::Polygon(p) => (p.n_vertices(), p.positions_3d(), None),
    };
    let to_mesh_index = |v: i64, key: &str| -> std::result::Result<usize, Invalid> {
        let count = file.map(|f| f.file_vertex_count()).unwrap_or(n);
        if v < 0 || v as usize >= count {
            return Err(invalid(key, SceneProblem::VertexOutOfRange { vertex: v, count }));
        }
        match file {
            Some(f) => f
                .from_file_index(v as usize)
                .ok_or_else(|| invalid(key, SceneProblem::VertexUnused { vertex: v })),
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
                    return Err(invalid(format!("{key}.dofs"), SceneProblem::Conflict("empty list")));
                }
                for d in list {
                    let c = axis_index(d, &format!("{key}.dofs"))?;
                    if c >= axes {
                        return Err(invalid(
                            format!("{key}.dofs"),
                            SceneProblem::Conflict("a 2D scene has no z axis"),
                        ));
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
            return Err(invalid(
                key,
                SceneProblem::Conflict("give exactly one of above, below, top, bottom, vertices, box"),
            ));
        }
        let need_axis = || {
            axis.ok_or_else(|| {
                invalid(key.clone(), SceneProblem::Conflict("`axis` is required with above/below/top/bottom"))
            })
        };
        let selector = if let Some(v) = fix.above {
            Selector::Above { axis: need_axis()?, value: v }
        } else if let Some(v) = fix.below {
            Selector::Below { axis: need_axis()?, value: v }
        } else if let Some(v) = fix.top {
            if v.is_nan() || v < 0.0 {
                return Err(range(format!("{key}.top"), ">= 0", v));
            }
            Selector::Top { axis: need_axis()?, within: v }
        } else if let Some(v) = fix.bottom {
            if v.is_nan() || v < 0.0 {
                return Err(range(format!("{key}.bottom"), ">= 0", v));
            }
            Selector::Bottom { axis: need_axis()?, within: v }
        } else if let Some(b) = fix.bbox {
            Selector::Box { min: b[0], max: b[1] }
        } else {
            let list = fix.vertices.as_deref().unwrap_or(&[]);
            let idx = list
                .iter()
                .map(|&v| to_mesh_index(v, &format!("{key}.vertices")))
                .collect::<std::result::Result<Vec<_>, _>>()?;
            Selector::Vertices(idx)
        };
        constraints
            .fix_selected(&selector, &positions, dofs)
            .map_err(|e| invalid(key.clone(), SceneProblem::Constraint(e)))?;
    }
    let mut forces = Vec::new();
    for (k, f) in spec.force.iter().enumerate() {
        let key = format!("[[force]] #{}", k + 1);
        let vertex = to_mesh_index(f.vertex, &format!("{key}.vertex"))?;
        if let Some(c) = f.value.iter().find(|c| !c.is_finite()) {
            return Err(range(format!("{key}.value"), "finite", c));
        }
        let timing = choice(&format!("{key}.at"), f.at.clone(), ForceTiming::Last)?;
        forces.push(PointForce { vertex, value: f.value, timing });
    }
    let mut solver = SolverOptions::default();
    if let Some(s) = spec.solver {
        solver.backend = choice("[solver].backend", s.backend, solver.backend)?;
        if let Err(e) = solver.backend.solver() {
            return Err(invalid("[solver].backend", SceneProblem::Backend(e)));
        }
        solver.mode = choice("[solver].mode", s.mode, solver.mode)?;
        solver.stepping = choice("[solver].stepping", s.stepping, solver.stepping)?;
        solver.precision = choice("[solver].precision", s.precision, solver.precision)?;
        solver.constraints = choice("[solver].constraints", s.constraints, solver.constraints)?;
        solver.penalty = s.penalty.unwrap_or(DEFAULT_PENALTY);
        if !(solver.penalty.is_finite() && solver.penalty > 0.0) {
            return Err(range("[solver].penalty", "positive", solver.penalty));
        }
    }
    for c in 0..axes {
        if constraints.count(c) == 0 {
            return Err(Invalid {
                key: Some("[[fix]]".into()),
                problem: SceneProblem::Unconstrained { axis: ['x', 'y', 'z'][c] },
            });
        }
    }
    let mut plates = Vec::with_capacity(spec.plate.len());
    for (k, p) in spec.plate.iter().enumerate() {
        let key = format!("[[plate]] #{}", k + 1);
        if p.point.iter().any(|c| !c.is_finite()) {
            return Err(range(format!("{key}.point"), "finite", format!("{:?}", p.point)));
        }
        if !p.travel.is_finite() {
            return Err(range(format!("{key}.travel"), "finite", p.travel));
        }
        let plate = Plate::new(p.point, p.normal, p.travel).ok_or_else(|| {
            range(format!("{key}.normal"), "finite and non-zero", format!("{:?}", p.normal))
        })?;
        plates.push(plate);
    }
    let (lo, hi) = fibfluid_geometry::bounding_box(&positions);
    let diagonal = fibfluid_geometry::vec3::norm(fibfluid_geometry::vec3::sub(hi, lo));
    if let Err((k, problem)) = check_plates(&plates, &positions, PLATE_REST_TOLERANCE * diagonal) {
        let key = format!("[[plate]] #{}", k + 1);
        return Err(invalid(
            key,
            match problem {
                PlateProblem::FacesAway => SceneProblem::PlateFacesAway,
                PlateProblem::CutsBody { vertex, depth } => {
                    let vertex = file.map(|f| f.to_file[vertex] as usize).unwrap_or(vertex);
                    SceneProblem::PlateCutsBody { vertex, depth }
                }
            },
        ));
    }
    let budget = fibfluid_interact::memory_budget(None);
    let chainmail = crate::chainmail_scene::parse(spec.chainmail, &positions, budget)?;
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
        tolerance,
        guards,
        plates,
        solver,
        chainmail,
    })
}

/// A plate may touch the body at rest by this fraction of the body's diagonal.
pub const PLATE_REST_TOLERANCE: f64 = 1e-6;

/// The largest number of load steps a scene may ask for.
pub const MAX_STEPS: usize = 1_000_000;
