//! Tool paths and their replay: a path (grab displacements or push forces per frame, as a
//! scene's `PATH.csv` describes them), checked against a model, replayed on any
//! [`Interactive`] body with the latency of every frame.
//!
//! The file format is read by the scene crate; this module holds the parsed data and what
//! is done with it.

use std::path::PathBuf;
use std::time::Instant;

use fibfluid_geometry::Vec3;
use fibfluid_sim::{Method, Model, Shape};
use serde::Serialize;

use crate::chainmail_body::ChainmailBodyError;
use crate::{Grasp, InteractError, Interactive, Press, RigidMotion};

/// The largest frame number a path may use.
pub const MAX_FRAME: usize = 10_000_000;

/// A grab may move a vertex at most this many times the body's size (the diagonal of its
/// bounding box) from rest: beyond, the linear response is meaningless and its arithmetic
/// overflows.
pub const MAX_REACH: f64 = 1e3;

/// A path checked against a model: its holds grouped by frame, in the mesh's vertex order.
#[derive(Clone, Debug, PartialEq)]
pub struct CheckedPath {
    /// The path file (for messages).
    pub source: PathBuf,
    /// Grab, force, grasp or press.
    pub kind: PathKind,
    /// The holds of each frame, `0..frames` (grab, force and grasp paths).
    pub frames: Vec<Vec<PathHold>>,
    /// The tip of each frame, `0..frames` (press paths; `None`: the tip is lifted).
    pub tips: Vec<Option<TipHold>>,
    /// Mesh vertex -> file vertex.
    pub file_vertex: Vec<usize>,
    /// Displacements from rest the grasps start from (`None`: rest), for instance each
    /// method's own base state in `compare`.
    pub origin: Option<Vec<Vec3>>,
}

/// The spherical tip of one frame of a press path, in metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TipHold {
    /// Line in the path file.
    pub line: usize,
    /// Centre (absolute).
    pub centre: Vec3,
    /// Radius.
    pub radius: f64,
}

impl CheckedPath {
    /// Whether frame `k` asks exactly what frame `k - 1` asked: the same holds (vertex,
    /// value, radius, in order) or the same tip; the file lines aside. Frame 0 never does.
    pub fn repeats_previous(&self, k: usize) -> bool {
        if k == 0 {
            return false;
        }
        match self.kind {
            PathKind::Press => {
                let tip = |t: Option<TipHold>| t.map(|t| (t.centre, t.radius));
                tip(self.tips[k]) == tip(self.tips[k - 1])
            }
            _ => {
                let holds =
                    |f: &[PathHold]| f.iter().map(|h| (h.vertex, h.value, h.radius)).collect::<Vec<_>>();
                holds(&self.frames[k]) == holds(&self.frames[k - 1])
            }
        }
    }
}

/// What can go wrong while probing: a bad tool path (file and line), a refused body.
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
    /// The body refused a request outside a path.
    #[error("{0}")]
    Body(#[from] InteractError),
    /// The body refused a frame of a path: the file, the line of the frame's hold and the
    /// frame.
    #[error("{}:{line}: frame {frame}: {source}", path.display())]
    Frame {
        /// The path file.
        path: PathBuf,
        /// The line of the hold that failed (the frame's first hold when the whole frame
        /// failed).
        line: usize,
        /// The frame.
        frame: usize,
        /// Why.
        source: InteractError,
    },
    /// The scene's body cannot be built (too large for the memory, singular).
    #[error("{scene}: {source}")]
    Build {
        /// The scene file (or the scene's name when built in code).
        scene: String,
        /// Why.
        source: InteractError,
    },
    /// The scene is a 2D polygon.
    #[error("{scene}: interactive methods need a surface mesh; this scene is a 2D polygon")]
    NotASurface {
        /// The scene file (or the scene's name when built in code).
        scene: String,
    },
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
    /// The engine refused the model (memory, a singular system).
    #[error(transparent)]
    Sim(#[from] fibfluid_sim::Error),
    /// Replaying the path would keep more than the memory budget (refused from counts,
    /// before anything is built).
    #[error(
        "{}: {what}: {frames} frames x {vertices} vertices need {bytes} bytes, but {available} bytes may be used; use fewer frames",
        path.display()
    )]
    PathTooLong {
        /// The path file.
        path: PathBuf,
        /// What is kept per frame.
        what: &'static str,
        /// Frames of the path.
        frames: usize,
        /// Vertices of the body.
        vertices: usize,
        /// Bytes needed.
        bytes: u128,
        /// Bytes that may be used.
        available: u64,
    },
    /// The path file is a directory.
    #[error("{}: is a directory, not a path file", path.display())]
    IsDirectory {
        /// The path given.
        path: PathBuf,
    },
    /// The path file cannot be read: not a regular file, or over the size limit.
    #[error("{}: {problem}", path.display())]
    Unreadable {
        /// The path given.
        path: PathBuf,
        /// Why.
        problem: fibfluid_geometry::ReadError,
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
    /// The first line is not one of the four headers.
    #[error(
        "bad header `{found}`: expected `frame,vertex,ux,uy,uz` (grab), `frame,vertex,fx,fy,fz` (force), `frame,vertex,ux,uy,uz,radius` (grasp) or `frame,x,y,z,radius` (press)"
    )]
    Header {
        /// The line found.
        found: String,
    },
    /// A row with the wrong number of fields.
    #[error("expected {expected} comma-separated fields, found {found}")]
    FieldCount {
        /// Fields expected.
        expected: usize,
        /// Fields found.
        found: usize,
    },
    /// A tool radius that is not positive.
    #[error("radius: {value} must be positive")]
    BadRadius {
        /// The value.
        value: f64,
    },
    /// Two tips in one frame of a press path.
    #[error(
        "a second tip in frame {frame} (the first is on line {first}); a press path has one tip per frame"
    )]
    TwoTips {
        /// The frame.
        frame: usize,
        /// Line of the first tip.
        first: usize,
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
    /// A grab farther from rest than [`MAX_REACH`] times the body's size.
    #[error(
        "vertex {vertex}: a displacement of {distance:e} is more than {MAX_REACH:e} times the body's size ({size:e})"
    )]
    TooFar {
        /// The vertex (file order).
        vertex: usize,
        /// The displacement's length.
        distance: f64,
        /// The diagonal of the body's bounding box.
        size: f64,
    },
    /// A tool at least as large as the body (the diagonal of its bounding box at rest),
    /// refused before the body is built.
    #[error(
        "frame {frame}: a tool of radius {radius} m is larger than the body (its bounding-box diagonal is {size} m)"
    )]
    ToolTooLarge {
        /// The frame.
        frame: usize,
        /// The radius (metres).
        radius: f64,
        /// The body's size (metres).
        size: f64,
    },
    /// Two grasps of one frame whose patches share a vertex (each patch moves rigidly with
    /// its own tool: no vertex can follow both).
    #[error(
        "frame {frame}: the grasps around vertices {first} (line {first_line}) and {second} both hold vertex {shared}; a vertex can be held by one grasp only"
    )]
    GraspsOverlap {
        /// The frame.
        frame: usize,
        /// The picked vertex of the first grasp (file order).
        first: usize,
        /// The line of the first grasp.
        first_line: usize,
        /// The picked vertex of the second grasp (file order).
        second: usize,
        /// A vertex both patches hold (file order).
        shared: usize,
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
    /// `frame,vertex,ux,uy,uz`: displacements from rest (grabs).
    Grab,
    /// `frame,vertex,fx,fy,fz`: applied forces (pushes).
    Force,
    /// `frame,vertex,ux,uy,uz,radius`: the patch of that radius around the vertex, moved by
    /// the displacement ([`crate::Grasp`]).
    Grasp,
    /// `frame,x,y,z,radius`: a spherical tip of that radius centred there ([`crate::Press`]).
    Press,
}

impl PathKind {
    /// `grab`, `force`, `grasp` or `press`.
    pub fn name(self) -> &'static str {
        match self {
            PathKind::Grab => "grab",
            PathKind::Force => "force",
            PathKind::Grasp => "grasp",
            PathKind::Press => "press",
        }
    }

    /// The header line of a path of this kind.
    pub fn header(self) -> &'static str {
        match self {
            PathKind::Grab => "frame,vertex,ux,uy,uz",
            PathKind::Force => "frame,vertex,fx,fy,fz",
            PathKind::Grasp => "frame,vertex,ux,uy,uz,radius",
            PathKind::Press => "frame,x,y,z,radius",
        }
    }

    /// Every kind.
    pub const ALL: [PathKind; 4] = [PathKind::Grab, PathKind::Force, PathKind::Grasp, PathKind::Press];
}

/// One row of a path.
#[derive(Clone, Debug, PartialEq)]
pub struct PathRow {
    /// 1-based line in the file.
    pub line: usize,
    /// Frame number.
    pub frame: usize,
    /// Vertex in the mesh file's order; `None` declares an empty frame, or is a press row.
    pub vertex: Option<usize>,
    /// Displacement, force or tip centre.
    pub value: Vec3,
    /// The tool's radius (grasp and press rows); `None` in an empty frame.
    pub radius: Option<f64>,
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
    /// The grasp's radius in metres (0 for a grab or a push).
    pub radius: f64,
}

/// Checks a path against a model (vertices exist, are used, are not fixed, appear once per
/// frame, grabs stay within [`MAX_REACH`] of the body's size, tools are smaller than the
/// body, the grasps of a frame share no vertex, one tip per frame) and groups
/// its rows by frame. Lengths (displacements, centres, radii) are in the mesh's unit in the
/// file and in metres in the result.
pub fn check_path(path: &ToolPath, scene: &Model) -> std::result::Result<CheckedPath, ProbeError> {
    let Shape::Surface(file) = &scene.shape else {
        return Err(ProbeError::NotASurface { scene: scene.display_name() });
    };
    let mut file_vertex = vec![0; file.mesh.n_vertices()];
    for (fv, v) in file.file_to_mesh().iter().enumerate() {
        if let Some(v) = v {
            file_vertex[*v] = fv;
        }
    }
    let mut checked = CheckedPath {
        source: path.source.clone(),
        kind: path.kind,
        frames: vec![Vec::new(); path.frames()],
        tips: vec![None; path.frames()],
        file_vertex,
        origin: None,
    };
    let metres = scene.unit.metres();
    let rest = file.mesh.positions();
    let (lo, hi) = fibfluid_geometry::bounding_box(rest);
    let size = fibfluid_geometry::vec3::dist(lo, hi);
    let mut patches = PatchCache::default();
    for row in &path.rows {
        if path.kind == PathKind::Press {
            let Some(radius) = row.radius else { continue };
            let tip =
                TipHold { line: row.line, centre: row.value.map(|c| c * metres), radius: radius * metres };
            check_tool(path, row, rest, tip.radius)?;
            match &checked.tips[row.frame] {
                Some(first) => {
                    let problem = PathProblem::TwoTips { frame: row.frame, first: first.line };
                    return Err(ProbeError::Path { path: path.source.clone(), line: row.line, problem });
                }
                None => checked.tips[row.frame] = Some(tip),
            }
        } else if let Some(hold) = check_row(path, row, scene, size)? {
            let frame = &mut checked.frames[row.frame];
            if let Some(first) = frame.iter().find(|h| h.vertex == hold.vertex) {
                let problem =
                    PathProblem::Duplicate { vertex: hold.file_vertex, frame: row.frame, first: first.line };
                return Err(ProbeError::Path { path: path.source.clone(), line: row.line, problem });
            }
            if path.kind == PathKind::Grasp {
                check_tool(path, row, rest, hold.radius)?;
                patches.check_apart(path, row, rest, &hold, frame, &checked.file_vertex)?;
            }
            frame.push(hold);
        }
    }
    Ok(checked)
}

/// Checks a tool's radius (metres) on a row against the rest shape: a tool at least as
/// large as the body is refused here, before anything is built.
fn check_tool(
    path: &ToolPath,
    row: &PathRow,
    rest: &[Vec3],
    radius: f64,
) -> std::result::Result<(), ProbeError> {
    let problem = match crate::tools::check_tool_radius(rest, radius) {
        Ok(_) => return Ok(()),
        Err(InteractError::ToolTooLarge { radius, size }) => {
            PathProblem::ToolTooLarge { frame: row.frame, radius, size }
        }
        Err(_) => PathProblem::BadRadius { value: radius },
    };
    Err(ProbeError::Path { path: path.source.clone(), line: row.line, problem })
}

/// The patches of a grasp path's grasps, by picked vertex and radius (computed from the rest
/// shape once each).
#[derive(Default)]
struct PatchCache(std::collections::HashMap<(usize, u64), Vec<usize>>);

impl PatchCache {
    fn patch(&mut self, rest: &[Vec3], vertex: usize, radius: f64) -> &[usize] {
        self.0
            .entry((vertex, radius.to_bits()))
            .or_insert_with(|| crate::tools::patch_around(rest, vertex, radius))
    }

    /// Refuses a grasp whose patch shares a vertex with a grasp already in its frame.
    fn check_apart(
        &mut self,
        path: &ToolPath,
        row: &PathRow,
        rest: &[Vec3],
        hold: &PathHold,
        frame: &[PathHold],
        file_vertex: &[usize],
    ) -> std::result::Result<(), ProbeError> {
        if frame.is_empty() {
            return Ok(());
        }
        let patch = self.patch(rest, hold.vertex, hold.radius).to_vec();
        for first in frame {
            let other = self.patch(rest, first.vertex, first.radius);
            if let Some(shared) = crate::tools::shared_vertex(other, &patch) {
                let problem = PathProblem::GraspsOverlap {
                    frame: row.frame,
                    first: first.file_vertex,
                    first_line: first.line,
                    second: hold.file_vertex,
                    shared: file_vertex[shared],
                };
                return Err(ProbeError::Path { path: path.source.clone(), line: row.line, problem });
            }
        }
        Ok(())
    }
}

/// One row of a grab, force or grasp path as a hold (`None` for an empty frame).
/// `size` is the diagonal of the body's bounding box.
fn check_row(
    path: &ToolPath,
    row: &PathRow,
    scene: &Model,
    size: f64,
) -> std::result::Result<Option<PathHold>, ProbeError> {
    let Shape::Surface(file) = &scene.shape else {
        return Err(ProbeError::NotASurface { scene: scene.display_name() });
    };
    let err = |problem: PathProblem| ProbeError::Path { path: path.source.clone(), line: row.line, problem };
    let Some(fv) = row.vertex else { return Ok(None) };
    let count = file.file_vertex_count();
    if fv >= count {
        return Err(err(PathProblem::UnknownVertex { vertex: fv, count }));
    }
    let v = file.file_to_mesh()[fv].ok_or_else(|| err(PathProblem::UnusedVertex { vertex: fv }))?;
    let fixed: Vec<usize> = (0..3).filter(|&c| scene.constraints.get(v, c).is_some()).collect();
    let moved = path.kind != PathKind::Force;
    if (moved && !fixed.is_empty()) || fixed.len() == 3 {
        let action = if moved { "grabbed" } else { "pushed" };
        let axis = fibfluid_geometry::AXES[fixed[0]];
        return Err(err(PathProblem::FixedVertex { vertex: fv, axis, action }));
    }
    // Displacements are written in the mesh's unit, like the mesh; forces in newtons.
    let metres = scene.unit.metres();
    let value = if moved { row.value.map(|c| c * metres) } else { row.value };
    let distance = fibfluid_geometry::vec3::norm(value);
    if moved && !(distance <= MAX_REACH * size) {
        return Err(err(PathProblem::TooFar { vertex: fv, distance, size }));
    }
    Ok(Some(PathHold {
        line: row.line,
        vertex: v,
        file_vertex: fv,
        value,
        radius: row.radius.unwrap_or(0.0) * metres,
    }))
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

/// Replays a checked path on a body: in each frame every vertex is released, the frame's
/// holds are applied and the frame is updated. A frame that asks exactly what the last one
/// asked ([`CheckedPath::repeats_previous`]) on a body whose answer depends only on its
/// holds ([`Interactive::answers_from_holds`]) costs no update: its rows repeat the last
/// frame's. A refused hold or frame names the path file, the line and the frame.
pub fn replay(body: &mut dyn Interactive, path: &CheckedPath) -> std::result::Result<Replay, ProbeError> {
    replay_observed(body, path, |_, _| {})
}

/// [`replay`], calling `observe(frame, body)` after each frame's update (outside the timed
/// part), for instance to record the surfaces.
pub fn replay_observed(
    body: &mut dyn Interactive,
    path: &CheckedPath,
    mut observe: impl FnMut(usize, &dyn Interactive),
) -> std::result::Result<Replay, ProbeError> {
    let mut rows = Vec::new();
    let frames = path.frames.len().max(path.tips.len());
    let mut latency_us = Vec::with_capacity(frames);
    let mut tools = ToolCache::default();
    for k in 0..frames {
        let start = Instant::now();
        if body.answers_from_holds() && path.repeats_previous(k) {
            // The same question as the last frame: the same answer, without an update.
            repeat_last_frame(&mut rows, k);
            latency_us.push(start.elapsed().as_secs_f64() * 1e6);
            observe(k, &*body);
            continue;
        }
        let line = match path.kind {
            PathKind::Press => path.tips[k].map(|t| t.line),
            _ => path.frames[k].first().map(|h| h.line),
        };
        let at = |source: InteractError| ProbeError::Frame {
            path: path.source.clone(),
            line: line.unwrap_or(0),
            frame: k,
            source,
        };
        match path.kind {
            PathKind::Grab | PathKind::Force => vertex_frame(body, path, k, &mut rows)?,
            PathKind::Grasp => grasp_frame(body, path, k, &mut tools, &mut rows)?,
            PathKind::Press => press_frame(body, path, k, &mut tools, &mut rows).map_err(at)?,
        }
        latency_us.push(start.elapsed().as_secs_f64() * 1e6);
        observe(k, &*body);
    }
    Ok(Replay { rows, latency_us, frames })
}

/// Appends frame `k`'s rows as a copy of frame `k - 1`'s (the rows of a frame are
/// contiguous, at the end).
fn repeat_last_frame(rows: &mut Vec<FrameRow>, k: usize) {
    let from = rows.iter().rposition(|r| r.frame != k - 1).map_or(0, |i| i + 1);
    let last: Vec<FrameRow> = rows[from..].iter().filter(|r| r.frame == k - 1).cloned().collect();
    rows.extend(last.into_iter().map(|r| FrameRow { frame: k, ..r }));
}

/// The tools of a replay, kept from frame to frame.
#[derive(Default)]
struct ToolCache {
    /// Grasp patches by (vertex, radius bits).
    grasps: std::collections::HashMap<(usize, u64), Grasp>,
    /// The tip and its radius.
    press: Option<Press>,
}

fn frame_error(path: &CheckedPath, frame: usize, line: usize) -> impl Fn(InteractError) -> ProbeError + '_ {
    move |source| ProbeError::Frame { path: path.source.clone(), line, frame, source }
}

/// A frame of grabs or pushes: one row per held vertex.
fn vertex_frame(
    body: &mut dyn Interactive,
    path: &CheckedPath,
    k: usize,
    rows: &mut Vec<FrameRow>,
) -> std::result::Result<(), ProbeError> {
    let holds = &path.frames[k];
    body.release_all();
    for h in holds {
        match path.kind {
            PathKind::Force => body.push(h.vertex, h.value),
            _ => body.grab(h.vertex, h.value),
        }
        .map_err(frame_error(path, k, h.line))?;
    }
    let line = holds.first().map(|h| h.line).unwrap_or(0);
    body.update().map_err(frame_error(path, k, line))?;
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
    Ok(())
}

/// A frame of grasps: one row per grasp, with the total force on its patch.
fn grasp_frame(
    body: &mut dyn Interactive,
    path: &CheckedPath,
    k: usize,
    tools: &mut ToolCache,
    rows: &mut Vec<FrameRow>,
) -> std::result::Result<(), ProbeError> {
    let holds = &path.frames[k];
    body.release_all();
    let mut grasps = Vec::with_capacity(holds.len());
    for h in holds {
        let err = frame_error(path, k, h.line);
        let key = (h.vertex, h.radius.to_bits());
        let grasp = match tools.grasps.get(&key) {
            Some(g) => g.clone(),
            None => Grasp::new(&*body, h.vertex, h.radius).map_err(&err)?,
        };
        tools.grasps.entry(key).or_insert_with(|| grasp.clone());
        let motion = RigidMotion::translation(h.value);
        match &path.origin {
            Some(origin) => grasp.hold_from(body, &motion, origin),
            None => grasp.hold(body, &motion),
        }
        .map_err(&err)?;
        grasps.push((grasp, motion));
    }
    let line = holds.first().map(|h| h.line).unwrap_or(0);
    body.update().map_err(frame_error(path, k, line))?;
    for ((g, motion), h) in grasps.iter().zip(holds) {
        let force = g.wrench(&*body, motion).force;
        rows.push(FrameRow {
            frame: k,
            file_vertex: h.file_vertex,
            force,
            displacement: body.field()[h.vertex],
        });
    }
    Ok(())
}

/// A frame of a press path: the tip placed (or lifted), one row with the total force and
/// the vertex nearest the tip's centre.
fn press_frame(
    body: &mut dyn Interactive,
    path: &CheckedPath,
    k: usize,
    tools: &mut ToolCache,
    rows: &mut Vec<FrameRow>,
) -> crate::Result<()> {
    let Some(tip) = path.tips[k] else {
        if let Some(mut press) = tools.press.take() {
            press.lift(body)?;
        }
        body.update()?;
        return Ok(());
    };
    if tools.press.as_ref().is_some_and(|p| p.radius() != tip.radius) {
        tools.press.take().map(|mut p| p.lift(body)).transpose()?;
    }
    let press = match &mut tools.press {
        Some(p) => p,
        None => tools.press.insert(Press::new(&*body, tip.radius)?),
    };
    let report = press.place(body, tip.centre)?;
    let positions = body.positions();
    let near = |v: &usize| fibfluid_geometry::vec3::dist(positions[*v], tip.centre);
    let nearest = report
        .contacts
        .iter()
        .copied()
        .min_by(|a, b| near(a).total_cmp(&near(b)))
        .or_else(|| (0..positions.len()).min_by(|a, b| near(a).total_cmp(&near(b))))
        .unwrap_or(0);
    rows.push(FrameRow {
        frame: k,
        file_vertex: path.file_vertex[nearest],
        force: report.force,
        displacement: body.field()[nearest],
    });
    Ok(())
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

/// Checks that `method` can replay a path of this kind (forces need the fiber–fluid method).
pub fn check_method(path: &ToolPath, method: Method) -> std::result::Result<(), ProbeError> {
    if path.kind == PathKind::Force && method != Method::Ffm {
        return Err(ProbeError::ForcePath { path: path.source.clone(), method });
    }
    Ok(())
}
