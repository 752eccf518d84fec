//! Probing a scene in real time: an interactive fiber–fluid body built from a [`Scene`], and
//! the replay of a tool path (`PATH.csv`) with its outputs.
//!
//! The body is the scene linearized about its rest shape (paper mode, whatever the scene's
//! own mode): the scene's gravity, hydrostatic pressure and point forces applied in full by
//! one structured solve form the base state, and the precomputed response
//! ([`fibfluid_interact::Compliance`]) adds each frame's tool forces and grabbed vertices
//! on top of it. A frame equals a full paper-mode solve with `steps = 1` and the tool's
//! forces added.
//!
//! # The path file
//!
//! ```text
//! frame,vertex,ux,uy,uz        (grab: displacement from rest)   or
//! frame,vertex,fx,fy,fz        (push: applied force)
//! 0,12,0.0,-0.01,0.0
//! 1,12,0.0,-0.02,0.0
//! 2,,,,                        (a frame with nothing applied)
//! ```
//!
//! Vertices are 0-based indices in the mesh file's order (as in a scene's `[[force]]`).
//! Frames run from 0 to the largest frame number; rows of the same frame apply together; a
//! vertex absent from a frame is released; frame numbers must not decrease. Blank lines and
//! lines starting with `#` are skipped.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use fibfluid_geometry::{MeshFile, Vec3};
use fibfluid_interact::{
    Compliance, ComplianceOptions, FfmBody, InteractError, Interactive, Storage, memory_budget,
};
use fibfluid_linalg::{Choice, Precision, impl_choice};
use serde::Serialize;

use crate::chainmail_body::{ChainmailBody, ChainmailBodyError};
use crate::chainmail_scene::Variant;
use crate::{Error, Mode, Result, RunOptions, Scene, Shape, Simulation, write_files_atomically};

pub use fibfluid_interact as interact;

/// Names of the files [`run_probe`] writes.
pub const PROBE_FILES: [&str; 4] = ["frames.csv", "final.obj", "report.json", "probe.png"];

/// The largest frame number a path may use.
pub const MAX_FRAME: usize = 10_000_000;

/// The deformation method a probe (or a comparison) runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Method {
    /// The fiber–fluid method's precomputed response (forces and grabs).
    #[default]
    Ffm,
    /// TSVE-ChainMail (grabs only).
    TsveChainmail,
    /// Generalized (traditional) ChainMail (grabs only).
    GeneralizedChainmail,
}

impl Choice for Method {
    const WHAT: &'static str = "method";
    const ALL: &'static [Self] = &[Method::Ffm, Method::TsveChainmail, Method::GeneralizedChainmail];
    fn name(self) -> &'static str {
        match self {
            Method::Ffm => "ffm",
            Method::TsveChainmail => "tsve-chainmail",
            Method::GeneralizedChainmail => "generalized-chainmail",
        }
    }
}
impl_choice!(Method);

impl Method {
    /// The ChainMail variant of a ChainMail method.
    pub fn chainmail_variant(self) -> Option<Variant> {
        match self {
            Method::Ffm => None,
            Method::TsveChainmail => Some(Variant::Tsve),
            Method::GeneralizedChainmail => Some(Variant::Generalized),
        }
    }
}

/// What can go wrong while probing.
#[derive(Debug, thiserror::Error)]
pub enum ProbeError {
    /// A line of the path file is wrong.
    #[error("{}:{line}: {problem}", path.display())]
    Path {
        /// The path file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        problem: PathProblem,
    },
    /// The path file has a header but no row.
    #[error("{}: the path is empty (a header and at least one row are needed)", path.display())]
    EmptyPath {
        /// The path file.
        path: PathBuf,
    },
    /// The body refused a request.
    #[error("probe: {0}")]
    Body(#[from] InteractError),
    /// The scene's body cannot be built (too large for the memory, singular).
    #[error("{scene}: {source}")]
    Build {
        /// The scene file (or the scene's name when built in code).
        scene: String,
        /// Why.
        source: InteractError,
    },
    /// The scene is a 2D polygon.
    #[error("probe needs a surface mesh; this scene is a 2D polygon")]
    NotASurface,
    /// The scene's ChainMail body cannot be built.
    #[error("{scene}: {source}")]
    Chainmail {
        /// The scene file (or the scene's name when built in code).
        scene: String,
        /// Why.
        source: ChainmailBodyError,
    },
    /// A force path given to a displacement-driven method.
    #[error("{}: {method} is displacement-driven: it needs a grab path (frame,vertex,ux,uy,uz), not a force path", path.display())]
    ForcePath {
        /// The path file.
        path: PathBuf,
        /// The method.
        method: Method,
    },
    /// The path file is a directory.
    #[error("{}: is a directory, not a path file", path.display())]
    IsDirectory {
        /// The path given.
        path: PathBuf,
    },
    /// The path file is not text.
    #[error("{}: not a text file (invalid UTF-8)", path.display())]
    NotUtf8 {
        /// The path given.
        path: PathBuf,
    },
}

/// What is wrong with one line of a path file.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PathProblem {
    /// The first line is not one of the two headers.
    #[error(
        "bad header `{found}`: expected `frame,vertex,ux,uy,uz` (grab) or `frame,vertex,fx,fy,fz` (force)"
    )]
    Header {
        /// The line found.
        found: String,
    },
    /// A row without five fields.
    #[error("expected 5 comma-separated fields, found {found}")]
    FieldCount {
        /// Fields found.
        found: usize,
    },
    /// A frame field that is not a non-negative integer.
    #[error("frame: `{value}` is not a frame number (0, 1, 2, ...)")]
    BadFrame {
        /// The text.
        value: String,
    },
    /// A frame number beyond [`MAX_FRAME`].
    #[error("frame {frame} is beyond the largest allowed frame number {MAX_FRAME}")]
    FrameTooLarge {
        /// The frame.
        frame: usize,
    },
    /// A frame number smaller than the previous row's.
    #[error("frame {frame} comes after frame {previous}: frame numbers must not decrease")]
    DecreasingFrame {
        /// This row's frame.
        frame: usize,
        /// The previous row's frame.
        previous: usize,
    },
    /// A vertex field that is not a non-negative integer.
    #[error("vertex: `{value}` is not a vertex index (0-based)")]
    BadVertex {
        /// The text.
        value: String,
    },
    /// A value field that is not a number.
    #[error("{column}: `{value}` is not a number")]
    NotANumber {
        /// The column name.
        column: &'static str,
        /// The text.
        value: String,
    },
    /// A value that is NaN or infinite.
    #[error("{column}: {value} is not finite")]
    NonFinite {
        /// The column name.
        column: &'static str,
        /// The value.
        value: f64,
    },
    /// An empty vertex field with values.
    #[error("a row without a vertex (an empty frame) must have no values")]
    ValuesWithoutVertex,
    /// A vertex beyond the mesh file.
    #[error("vertex {vertex} does not exist (the mesh file has {count} vertices, 0-based)")]
    UnknownVertex {
        /// The vertex (file order).
        vertex: usize,
        /// Vertices in the file.
        count: usize,
    },
    /// A vertex of the file that no face uses.
    #[error("vertex {vertex} is not used by any face of the mesh")]
    UnusedVertex {
        /// The vertex (file order).
        vertex: usize,
    },
    /// A grab on a vertex the scene fixes (or a push on a vertex fixed along every axis).
    #[error("vertex {vertex} is fixed along {axis} by the scene and cannot be {action}")]
    FixedVertex {
        /// The vertex (file order).
        vertex: usize,
        /// The first fixed axis.
        axis: char,
        /// `grabbed` or `pushed`.
        action: &'static str,
    },
    /// The same vertex twice in one frame.
    #[error("vertex {vertex} appears twice in frame {frame} (first on line {first})")]
    Duplicate {
        /// The vertex (file order).
        vertex: usize,
        /// The frame.
        frame: usize,
        /// Line of the first occurrence.
        first: usize,
    },
}

/// What the rows of a path prescribe.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PathKind {
    /// `ux,uy,uz`: displacements from rest (grabs).
    Grab,
    /// `fx,fy,fz`: applied forces (pushes).
    Force,
}

impl PathKind {
    /// `grab` or `force`.
    pub fn name(self) -> &'static str {
        match self {
            PathKind::Grab => "grab",
            PathKind::Force => "force",
        }
    }
}

/// One row of a path.
#[derive(Clone, Debug, PartialEq)]
pub struct PathRow {
    /// 1-based line in the file.
    pub line: usize,
    /// Frame number.
    pub frame: usize,
    /// Vertex in the mesh file's order; `None` declares an empty frame.
    pub vertex: Option<usize>,
    /// Displacement or force.
    pub value: Vec3,
}

/// A parsed tool path.
#[derive(Clone, Debug, PartialEq)]
pub struct ToolPath {
    /// The file it came from (for messages).
    pub source: PathBuf,
    /// Grab or force.
    pub kind: PathKind,
    /// Rows in file order (frames non-decreasing).
    pub rows: Vec<PathRow>,
}

impl ToolPath {
    /// Reads and parses a path file.
    pub fn load(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        if path.is_dir() {
            return Err(ProbeError::IsDirectory { path: path.to_path_buf() }.into());
        }
        let bytes = std::fs::read(path).map_err(|source| Error::Io { path: path.to_path_buf(), source })?;
        let text = String::from_utf8(bytes).map_err(|_| ProbeError::NotUtf8 { path: path.to_path_buf() })?;
        Ok(Self::parse(path, &text)?)
    }

    /// Parses the text of a path file; `source` names it in errors.
    pub fn parse(source: impl Into<PathBuf>, text: &str) -> std::result::Result<Self, ProbeError> {
        let source = source.into();
        let err =
            |line: usize, problem: PathProblem| ProbeError::Path { path: source.clone(), line, problem };
        let mut lines = text
            .lines()
            .enumerate()
            .map(|(i, l)| (i + 1, l.trim_start_matches('\u{feff}').trim()))
            .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
        let Some((hline, header)) = lines.next() else {
            return Err(ProbeError::EmptyPath { path: source });
        };
        let names: Vec<String> = header.split(',').map(|f| f.trim().to_ascii_lowercase()).collect();
        let kind = match names.iter().map(String::as_str).collect::<Vec<_>>().as_slice() {
            ["frame", "vertex", "ux", "uy", "uz"] => PathKind::Grab,
            ["frame", "vertex", "fx", "fy", "fz"] => PathKind::Force,
            _ => return Err(err(hline, PathProblem::Header { found: header.to_string() })),
        };
        let columns: [&'static str; 3] = match kind {
            PathKind::Grab => ["ux", "uy", "uz"],
            PathKind::Force => ["fx", "fy", "fz"],
        };
        let mut rows: Vec<PathRow> = Vec::new();
        for (line, text) in lines {
            let fields: Vec<&str> = text.split(',').map(str::trim).collect();
            // `12` alone declares an empty frame as `12,,,,` does.
            let fields: Vec<&str> = if fields.len() == 1 { vec![fields[0], "", "", "", ""] } else { fields };
            if fields.len() != 5 {
                return Err(err(line, PathProblem::FieldCount { found: fields.len() }));
            }
            let frame: usize = fields[0]
                .parse()
                .map_err(|_| err(line, PathProblem::BadFrame { value: fields[0].to_string() }))?;
            if frame > MAX_FRAME {
                return Err(err(line, PathProblem::FrameTooLarge { frame }));
            }
            if let Some(prev) = rows.last()
                && frame < prev.frame
            {
                return Err(err(line, PathProblem::DecreasingFrame { frame, previous: prev.frame }));
            }
            let vertex = if fields[1].is_empty() {
                if fields[2..].iter().any(|f| !f.is_empty()) {
                    return Err(err(line, PathProblem::ValuesWithoutVertex));
                }
                None
            } else {
                Some(
                    fields[1]
                        .parse::<usize>()
                        .map_err(|_| err(line, PathProblem::BadVertex { value: fields[1].to_string() }))?,
                )
            };
            let mut value = [0.0; 3];
            if vertex.is_some() {
                for c in 0..3 {
                    let f = fields[2 + c];
                    let v: f64 = f.parse().map_err(|_| {
                        err(line, PathProblem::NotANumber { column: columns[c], value: f.to_string() })
                    })?;
                    if !v.is_finite() {
                        return Err(err(line, PathProblem::NonFinite { column: columns[c], value: v }));
                    }
                    value[c] = v;
                }
            }
            rows.push(PathRow { line, frame, vertex, value });
        }
        if rows.is_empty() {
            return Err(ProbeError::EmptyPath { path: source });
        }
        Ok(Self { source, kind, rows })
    }

    /// Number of frames: the largest frame number plus one.
    pub fn frames(&self) -> usize {
        self.rows.last().map(|r| r.frame + 1).unwrap_or(0)
    }
}

/// One hold of a checked path: the vertex in the mesh's order and in the file's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathHold {
    /// Line in the path file.
    pub line: usize,
    /// Vertex in the mesh's (compacted) order.
    pub vertex: usize,
    /// Vertex in the mesh file's order.
    pub file_vertex: usize,
    /// Displacement or force.
    pub value: Vec3,
}

/// Checks a path against a scene (vertices exist, are used, are not fixed, appear once per
/// frame) and groups its rows by frame (`0..path.frames()`).
pub fn check_path(path: &ToolPath, scene: &Scene) -> std::result::Result<Vec<Vec<PathHold>>, ProbeError> {
    let Shape::Surface(file) = &scene.shape else { return Err(ProbeError::NotASurface) };
    let to_mesh: HashMap<usize, usize> =
        file.to_file.iter().enumerate().map(|(m, &f)| (f as usize, m)).collect();
    let count = file.file_vertex_count();
    let err =
        |line: usize, problem: PathProblem| ProbeError::Path { path: path.source.clone(), line, problem };
    let mut frames: Vec<Vec<PathHold>> = vec![Vec::new(); path.frames()];
    for row in &path.rows {
        let Some(fv) = row.vertex else { continue };
        if fv >= count {
            return Err(err(row.line, PathProblem::UnknownVertex { vertex: fv, count }));
        }
        let v = *to_mesh.get(&fv).ok_or_else(|| err(row.line, PathProblem::UnusedVertex { vertex: fv }))?;
        let fixed: Vec<usize> = (0..3).filter(|&c| scene.constraints.get(v, c).is_some()).collect();
        let refused = match path.kind {
            PathKind::Grab => !fixed.is_empty(),
            PathKind::Force => fixed.len() == 3,
        };
        if refused {
            let action = if path.kind == PathKind::Grab { "grabbed" } else { "pushed" };
            let axis = fibfluid_assembly::AXES[fixed[0]];
            return Err(err(row.line, PathProblem::FixedVertex { vertex: fv, axis, action }));
        }
        let frame = &mut frames[row.frame];
        if let Some(first) = frame.iter().find(|h| h.vertex == v) {
            return Err(err(
                row.line,
                PathProblem::Duplicate { vertex: fv, frame: row.frame, first: first.line },
            ));
        }
        frame.push(PathHold { line: row.line, vertex: v, file_vertex: fv, value: row.value });
    }
    Ok(frames)
}

/// Options of [`build_body`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ProbeOptions {
    /// Storage of the precomputed response.
    pub storage: Storage,
    /// Memory budget (see [`fibfluid_interact::memory_budget`]).
    pub max_memory_bytes: Option<u64>,
}

/// A scene's interactive body and what building it cost.
#[derive(Debug)]
pub struct ProbeBody {
    /// The body (base state applied).
    pub body: FfmBody,
    /// Seconds of the base solve (assembly, factorization and one solve).
    pub base_seconds: f64,
    /// Seconds of the precompute of the response.
    pub precompute_seconds: f64,
}

/// The scene as the probe solves it: paper mode, one step (loads in full), structured
/// backend, f64.
pub fn linearized_scene(scene: &Scene) -> Scene {
    let mut s = scene.clone();
    s.solver.mode = Mode::Paper;
    s.steps = 1;
    s.solver.backend = fibfluid_linalg::Backend::Structured;
    s.solver.precision = Precision::F64;
    s
}

/// Builds the interactive body of a scene: one full solve of the scene's loads (the base
/// state) and the precomputed response of the same assembled system.
///
/// Refuses before assembling anything when the assembled system, its factorization and the
/// precompute's peak would exceed the memory budget, naming the bytes.
pub fn build_body(scene: &Scene, opts: &ProbeOptions) -> Result<ProbeBody> {
    if !matches!(scene.shape, Shape::Surface(_)) {
        return Err(ProbeError::NotASurface.into());
    }
    let n = scene.n_vertices();
    let nblocks = if scene.material.is_isotropic() && scene.constraints.is_uniform(3) { 1 } else { 3 };
    let est = Compliance::estimate_for(n, nblocks, opts.storage);
    // The assembled blocks and their factorization stay alive during the precompute.
    let system_bytes = 2 * (nblocks * n * n * 8) as u64;
    let need = est.peak + system_bytes;
    let budget = memory_budget(opts.max_memory_bytes);
    let scene_name =
        scene.source.as_ref().map(|p| p.display().to_string()).unwrap_or_else(|| scene.name.clone());
    let build = |source: InteractError| ProbeError::Build { scene: scene_name.clone(), source };
    if need > budget {
        return Err(build(InteractError::OutOfMemory { bytes: need, available: budget }).into());
    }
    let start = Instant::now();
    let mut sim = Simulation::new(linearized_scene(scene))?;
    sim.run(&RunOptions::default())?;
    let base: Vec<Vec3> = sim
        .positions()
        .iter()
        .zip(sim.rest_positions())
        .map(|(p, r)| [p[0] - r[0], p[1] - r[1], p[2] - r[2]])
        .collect();
    let base_pressure = sim.pressure();
    let base_seconds = start.elapsed().as_secs_f64();
    let copts = ComplianceOptions { storage: opts.storage, max_memory_bytes: Some(budget - system_bytes) };
    let compliance = Compliance::from_system(sim.system(), &copts).map_err(build)?;
    let precompute_seconds = compliance.seconds();
    let rest = sim.rest_positions().to_vec();
    drop(sim);
    let mut body = FfmBody::new(compliance, rest).map_err(build)?;
    body.set_base(base, base_pressure).map_err(build)?;
    Ok(ProbeBody { body, base_seconds, precompute_seconds })
}

/// One probed vertex in one frame (a row of `frames.csv`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameRow {
    /// Frame number.
    pub frame: usize,
    /// Vertex in the mesh file's order.
    pub file_vertex: usize,
    /// Force on the body there (reaction of a grab, or the pushed force).
    pub force: Vec3,
    /// Displacement from rest there.
    pub displacement: Vec3,
}

/// What a replay produced.
#[derive(Clone, Debug, PartialEq)]
pub struct Replay {
    /// One row per probed vertex and frame.
    pub rows: Vec<FrameRow>,
    /// Microseconds of each frame (hold edits and the full-field update).
    pub latency_us: Vec<f64>,
    /// Frames replayed.
    pub frames: usize,
}

/// Replays checked frames (from [`check_path`]) on a body: in each frame every vertex is
/// released, the frame's holds are applied and the frame is updated.
pub fn replay(
    body: &mut dyn Interactive,
    kind: PathKind,
    frames: &[Vec<PathHold>],
) -> std::result::Result<Replay, ProbeError> {
    replay_observed(body, kind, frames, |_, _| {})
}

/// [`replay`], calling `observe(frame, body)` after each frame's update (outside the timed
/// part), for instance to record the surfaces.
pub fn replay_observed(
    body: &mut dyn Interactive,
    kind: PathKind,
    frames: &[Vec<PathHold>],
    mut observe: impl FnMut(usize, &dyn Interactive),
) -> std::result::Result<Replay, ProbeError> {
    let mut rows = Vec::new();
    let mut latency_us = Vec::with_capacity(frames.len());
    for (k, holds) in frames.iter().enumerate() {
        let start = Instant::now();
        body.release_all();
        for h in holds {
            match kind {
                PathKind::Grab => body.grab(h.vertex, h.value)?,
                PathKind::Force => body.push(h.vertex, h.value)?,
            }
        }
        body.update()?;
        latency_us.push(start.elapsed().as_secs_f64() * 1e6);
        let reactions = body.reactions();
        for h in holds {
            let force = reactions.iter().find(|(v, _)| *v == h.vertex).map(|(_, f)| *f).unwrap_or([0.0; 3]);
            rows.push(FrameRow {
                frame: k,
                file_vertex: h.file_vertex,
                force,
                displacement: body.field()[h.vertex],
            });
        }
        observe(k, &*body);
    }
    Ok(Replay { rows, latency_us, frames: frames.len() })
}

/// Frame latency percentiles, microseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Latency {
    /// Median.
    pub p50: f64,
    /// 99th percentile (nearest rank).
    pub p99: f64,
    /// Largest.
    pub max: f64,
}

impl Latency {
    /// Nearest-rank percentiles of the samples (zeros when there are none).
    pub fn of(samples: &[f64]) -> Self {
        let mut s: Vec<f64> = samples.iter().copied().filter(|v| v.is_finite()).collect();
        if s.is_empty() {
            return Self::default();
        }
        s.sort_by(f64::total_cmp);
        let rank = |p: f64| s[((p * s.len() as f64).ceil() as usize).clamp(1, s.len()) - 1];
        Self { p50: rank(0.5), p99: rank(0.99), max: s[s.len() - 1] }
    }
}

/// The `probe` section of `report.json`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ProbeStats {
    /// Frames replayed.
    pub frames: usize,
    /// Vertices of the body.
    pub vertices: usize,
    /// Distinct vertices the path probes.
    pub probed_vertices: usize,
    /// Seconds of the precompute of the response.
    pub precompute_seconds: f64,
    /// Bytes held by the body (the response dominates).
    pub memory_bytes: usize,
    /// Latency of the full-field frame update.
    pub latency_us: Latency,
}

/// `report.json` of a probe run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ProbeReport {
    /// Scene name.
    pub scene: String,
    /// The path file.
    pub path: String,
    /// `ffm`, `tsve-chainmail` or `generalized-chainmail`.
    pub method: String,
    /// `grab` or `force`.
    pub kind: PathKind,
    /// Storage of the response (`f64`, `f32`).
    pub precision: String,
    /// Constraint method (`penalty` or `eliminate`).
    pub constraints: String,
    /// Probe statistics.
    pub probe: ProbeStats,
    /// Seconds of the base solve (the scene's loads in full).
    pub base_seconds: f64,
    /// Largest displacement of the base state.
    pub base_max_displacement: f64,
    /// Largest displacement after the last frame.
    pub final_max_displacement: f64,
    /// Pressure change after the last frame (`null` for ChainMail, which has no pressure).
    pub final_pressure: Option<f64>,
    /// The ChainMail lattice (absent for FFM).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub chainmail: Option<ChainmailStats>,
    /// Wall-clock seconds of the whole probe run.
    pub seconds_total: f64,
}

fn max_norm(v: &[Vec3]) -> f64 {
    v.iter().map(|u| (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt()).fold(0.0, f64::max)
}

/// `frames.csv`: `frame,vertex,fx,fy,fz,ux,uy,uz`, every value in shortest round-trip
/// scientific notation.
pub fn frames_csv(rows: &[FrameRow]) -> String {
    frames_csv_with(rows, true)
}

/// [`frames_csv`]; with `forces` false (a method without forces, such as ChainMail) the
/// force fields are left empty (the header stays the same).
pub fn frames_csv_with(rows: &[FrameRow], forces: bool) -> String {
    let mut s = String::from("frame,vertex,fx,fy,fz,ux,uy,uz\n");
    for r in rows {
        let (f, u) = (r.force, r.displacement);
        if forces {
            s.push_str(&format!(
                "{},{},{:e},{:e},{:e},{:e},{:e},{:e}\n",
                r.frame, r.file_vertex, f[0], f[1], f[2], u[0], u[1], u[2]
            ));
        } else {
            s.push_str(&format!("{},{},,,,{:e},{:e},{:e}\n", r.frame, r.file_vertex, u[0], u[1], u[2]));
        }
    }
    s
}

/// `probe.png`: the force magnitude at each probed vertex per frame (0 while it is not
/// held); with more than eight probed vertices, the sum of the magnitudes.
pub fn probe_chart(title: &str, frames: usize, rows: &[FrameRow]) -> Result<Vec<u8>> {
    probe_chart_by(title, frames, rows, "|force| on the body", |r| r.force)
}

/// The chart of [`probe_chart`] for any vector of a row (`value`), labelled `y_label`; a
/// method without forces charts the displacement of the probed vertices.
pub fn probe_chart_by(
    title: &str,
    frames: usize,
    rows: &[FrameRow],
    y_label: &str,
    value: impl Fn(&FrameRow) -> Vec3,
) -> Result<Vec<u8>> {
    let mut vertices: Vec<usize> = rows.iter().map(|r| r.file_vertex).collect();
    vertices.sort_unstable();
    vertices.dedup();
    let norm = |f: Vec3| (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
    let series: Vec<fibfluid_render::Series> = if vertices.len() <= 8 && !vertices.is_empty() {
        vertices
            .iter()
            .map(|&v| {
                let mut y = vec![0.0; frames];
                for r in rows.iter().filter(|r| r.file_vertex == v) {
                    y[r.frame] = norm(value(r));
                }
                fibfluid_render::Series {
                    label: format!("vertex {v}"),
                    points: y.into_iter().enumerate().map(|(k, y)| (k as f64, y)).collect(),
                }
            })
            .collect()
    } else {
        let mut y = vec![0.0; frames];
        for r in rows {
            y[r.frame] += norm(value(r));
        }
        vec![fibfluid_render::Series {
            label: "sum over probed vertices".into(),
            points: y.into_iter().enumerate().map(|(k, y)| (k as f64, y)).collect(),
        }]
    };
    Ok(fibfluid_render::line_chart(title, "frame", y_label, &series, 900, 520)?)
}

pub(crate) fn final_obj(file: &MeshFile, positions: &[Vec3]) -> Result<Vec<u8>> {
    let mut obj = Vec::new();
    fibfluid_geometry::write_obj_to(
        &mut obj,
        &file.positions_in_file_order(positions),
        &file.triangles_in_file_order(),
    )
    .map_err(|source| Error::Io { path: PathBuf::from("final.obj"), source })?;
    Ok(obj)
}

/// A scene's body for one [`Method`], with what building it cost.
#[derive(Debug)]
pub enum MethodBody {
    /// The fiber–fluid method's body.
    Ffm(Box<ProbeBody>),
    /// A ChainMail body.
    Chainmail(Box<ChainmailBody>),
}

impl MethodBody {
    /// Builds the body of `scene` for `method`, within the memory budget of `opts`.
    pub fn build(scene: &Scene, method: Method, opts: &ProbeOptions) -> Result<Self> {
        match method.chainmail_variant() {
            None => Ok(MethodBody::Ffm(Box::new(build_body(scene, opts)?))),
            Some(variant) => {
                let budget = memory_budget(opts.max_memory_bytes);
                let body = ChainmailBody::from_scene(scene, variant, budget)
                    .map_err(|source| ProbeError::Chainmail { scene: scene_name(scene), source })?;
                Ok(MethodBody::Chainmail(Box::new(body)))
            }
        }
    }

    /// The body behind the method-neutral trait.
    pub fn interactive(&mut self) -> &mut dyn Interactive {
        match self {
            MethodBody::Ffm(b) => &mut b.body,
            MethodBody::Chainmail(b) => b.as_mut(),
        }
    }

    /// The body behind the method-neutral trait, read only.
    pub fn interactive_ref(&self) -> &dyn Interactive {
        match self {
            MethodBody::Ffm(b) => &b.body,
            MethodBody::Chainmail(b) => b.as_ref(),
        }
    }

    /// Seconds of the setup: base solve and precompute (FFM), voxelization and embedding
    /// (ChainMail).
    pub fn setup_seconds(&self) -> f64 {
        match self {
            MethodBody::Ffm(b) => b.base_seconds + b.precompute_seconds,
            MethodBody::Chainmail(b) => b.setup_seconds(),
        }
    }
}

fn scene_name(scene: &Scene) -> String {
    scene.source.as_ref().map(|p| p.display().to_string()).unwrap_or_else(|| scene.name.clone())
}

/// The ChainMail section of a probe's `report.json`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ChainmailStats {
    /// Lattice spacing.
    pub spacing: f64,
    /// Chain elements.
    pub elements: usize,
    /// Tetrahedra (volume and strain-energy constraints).
    pub tetrahedra: usize,
    /// Whether the time-saving scheme is allowed (`[chainmail].tss`).
    pub tss: bool,
    /// Relaxation sweeps per frame (TSVE).
    pub relaxation: usize,
    /// Seconds of the voxelization and embedding.
    pub setup_seconds: f64,
}

/// Checks that `method` can replay a path of this kind (ChainMail needs grabs).
pub fn check_method(path: &ToolPath, method: Method) -> std::result::Result<(), ProbeError> {
    if path.kind == PathKind::Force && method != Method::Ffm {
        return Err(ProbeError::ForcePath { path: path.source.clone(), method });
    }
    Ok(())
}

/// Probes a scene along a path with the fiber–fluid method and writes [`PROBE_FILES`] into
/// `out` (all or nothing). See [`run_probe_with`].
pub fn run_probe(scene: &Scene, path: &ToolPath, out: &Path, opts: &ProbeOptions) -> Result<ProbeReport> {
    run_probe_with(scene, path, out, opts, Method::Ffm)
}

/// Probes a scene along a path with `method` and writes [`PROBE_FILES`] into `out` (all or
/// nothing). The path is checked against the scene before anything is assembled. A method
/// without forces (ChainMail) leaves the force fields of `frames.csv` empty, and its
/// `probe.png` charts the displacement of the probed vertices instead of the force.
pub fn run_probe_with(
    scene: &Scene,
    path: &ToolPath,
    out: &Path,
    opts: &ProbeOptions,
    method: Method,
) -> Result<ProbeReport> {
    let start = Instant::now();
    let Shape::Surface(file) = &scene.shape else { return Err(ProbeError::NotASurface.into()) };
    check_method(path, method)?;
    let frames = check_path(path, scene)?;
    if let Some(blocked) = PROBE_FILES.iter().map(|f| out.join(f)).find(|p| p.is_dir()) {
        return Err(Error::OutputBlocked {
            path: blocked,
            problem: "is a directory, where an output file would go (nothing was written)",
        });
    }
    let mut mb = MethodBody::build(scene, method, opts)?;
    let base_max = match &mb {
        MethodBody::Ffm(pb) => max_norm(pb.body.base_field()),
        MethodBody::Chainmail(_) => 0.0,
    };
    let replay = replay(mb.interactive(), path.kind, &frames)?;
    let mut probed: Vec<usize> = replay.rows.iter().map(|r| r.file_vertex).collect();
    probed.sort_unstable();
    probed.dedup();
    let body = mb.interactive_ref();
    let forces = body.supports_forces();
    let (precision, constraints, base_seconds, precompute_seconds, final_pressure, chainmail) = match &mb {
        MethodBody::Ffm(pb) => (
            opts.storage.to_string(),
            scene.solver.constraints.to_string(),
            pb.base_seconds,
            pb.precompute_seconds,
            Some(pb.body.pressure()),
            None,
        ),
        MethodBody::Chainmail(cb) => (
            "f64".to_string(),
            "fixed-elements".to_string(),
            0.0,
            cb.setup_seconds(),
            None,
            Some(ChainmailStats {
                spacing: cb.lattice().spacing(),
                elements: cb.lattice().len(),
                tetrahedra: cb.lattice().tets().len(),
                tss: scene.chainmail.tss,
                relaxation: scene.chainmail.relaxation,
                setup_seconds: cb.setup_seconds(),
            }),
        ),
    };
    let mut report = ProbeReport {
        scene: scene.name.clone(),
        path: path.source.display().to_string(),
        method: method.to_string(),
        kind: path.kind,
        precision,
        constraints,
        probe: ProbeStats {
            frames: replay.frames,
            vertices: body.n_vertices(),
            probed_vertices: probed.len(),
            precompute_seconds,
            memory_bytes: body.memory_bytes(),
            latency_us: Latency::of(&replay.latency_us),
        },
        base_seconds,
        base_max_displacement: base_max,
        final_max_displacement: max_norm(body.field()),
        final_pressure,
        chainmail,
        seconds_total: 0.0,
    };
    let png = if forces {
        let title = format!(
            "{}: force at the probed vertices ({} path, {method}, {})",
            scene.name,
            path.kind.name(),
            opts.storage
        );
        probe_chart(&title, replay.frames, &replay.rows)?
    } else {
        let title = format!(
            "{}: displacement of the probed vertices ({} path, {method})",
            scene.name,
            path.kind.name()
        );
        probe_chart_by(&title, replay.frames, &replay.rows, "|u| at the probed vertex", |r| r.displacement)?
    };
    let obj = final_obj(file, body.positions())?;
    report.seconds_total = start.elapsed().as_secs_f64();
    let json = serde_json::to_string_pretty(&report)? + "\n";
    let files = [
        (PROBE_FILES[0], frames_csv_with(&replay.rows, forces).into_bytes()),
        (PROBE_FILES[1], obj),
        (PROBE_FILES[2], json.into_bytes()),
        (PROBE_FILES[3], png),
    ];
    write_files_atomically(out, &files)?;
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn latency_percentiles_by_nearest_rank() {
        let s: Vec<f64> = (1..=100).map(f64::from).collect();
        assert_eq!(Latency::of(&s), Latency { p50: 50.0, p99: 99.0, max: 100.0 });
        assert_eq!(Latency::of(&[3.0]), Latency { p50: 3.0, p99: 3.0, max: 3.0 });
        assert_eq!(Latency::of(&[]), Latency::default());
    }

    #[test]
    fn path_rows_group_and_empty_frames() {
        let p = ToolPath::parse("p.csv", "frame,vertex,ux,uy,uz\n0,1,0,0,0.1\n0,2,0,0,0\n3,,,,\n").unwrap();
        assert_eq!(p.kind, PathKind::Grab);
        assert_eq!(p.frames(), 4);
        assert_eq!(p.rows[2].vertex, None);
        let e = ToolPath::parse("p.csv", "frame,vertex,ux,uy,uz\n2,1,0,0,0\n1,1,0,0,0\n").unwrap_err();
        assert_eq!(e.to_string(), "p.csv:3: frame 1 comes after frame 2: frame numbers must not decrease");
        let e = ToolPath::parse("p.csv", "frame,vertex,ux,uy,uz\n0,1,0,NaN,0\n").unwrap_err();
        assert_eq!(e.to_string(), "p.csv:2: uy: NaN is not finite");
        let e = ToolPath::parse("p.csv", "frame,vertex,ux,uy,uz\n").unwrap_err();
        assert!(matches!(e, ProbeError::EmptyPath { .. }));
    }
}
