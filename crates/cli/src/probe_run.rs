//! `fibfluid probe`'s outputs: a tool path replayed on a scene's body for one method, with
//! `frames.csv`, `final.obj`, `report.json` and `probe.png`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use fibfluid::fem::FemStats;
use fibfluid::geometry::{Boundary, MeshFile, Vec3};
use fibfluid::interact::{
    FrameRow, Latency, LinearizationStatus, Method, MethodBody, PathKind, ProbeError, ProbeOptions, Storage,
    ToolPath, check_method, check_path, replay_observed,
};
use fibfluid::sim::result_guards::{ESTIMATE_LIMIT, ResultChecks, ResultGuard, ResultWarning, check_answer};
use fibfluid::{ConstraintKind, Scene, Shape};
use serde::Serialize;

use crate::output::write_files_atomically;
use crate::{Error, Result};

/// Names of the files [`run_probe`] writes.
pub const PROBE_FILES: [&str; 4] = ["frames.csv", "final.obj", "report.json", "probe.png"];

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
    /// Frames the body computed; a frame that asks exactly what the last one asked costs
    /// none on a body whose answer depends only on its holds (FFM, the FEM).
    pub updates: u64,
    /// The neo-Hookean body's refreshes (absent for the bodies that have none).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refresh: Option<RefreshStats>,
}

/// The `probe.refresh` section of `report.json`: the two-rate neo-Hookean body's linearizations
/// along the path, and what a refresh thread beside the frames would have kept up with.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RefreshStats {
    /// Frames between refreshes (each one Newton iteration, in the frame loop).
    pub every: u64,
    /// Linearizations made along the path.
    pub refreshes: u64,
    /// Those that factored the tangent (the others kept the factor: chord refreshes).
    pub refactorizations: u64,
    /// Mean seconds of one refresh.
    pub refresh_seconds: f64,
    /// Refreshes per second a second thread would run back to back.
    pub refresh_hz: f64,
    /// Frames a refresh thread would let pass per refresh (mean refresh over mean frame
    /// seconds): the age of its linearizations, against `every` here.
    pub frames_per_refresh: f64,
    /// The oldest linearization a frame used, in frames.
    pub largest_age_frames: u64,
    /// The oldest linearization a frame used, in milliseconds since it was swapped in.
    pub largest_age_ms: f64,
    /// The largest estimated distance of a frame from the converged answer for its holds
    /// (m; Newton's next correction).
    pub largest_estimated_error: f64,
    /// The last frame's estimated distance from the converged answer (m).
    pub final_estimated_error: f64,
    /// Refreshes that failed (the frames kept the last good linearization).
    pub failures: usize,
}

/// `report.json` of a probe run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ProbeReport {
    /// Scene name.
    pub scene: String,
    /// The path file.
    pub path: String,
    /// `ffm`, `tsve-chainmail` or `generalized-chainmail`.
    pub method: Method,
    /// `grab` or `force`.
    pub kind: PathKind,
    /// Storage of the response.
    pub precision: Storage,
    /// How FFM imposes the fixed vertices (`null` for ChainMail: its fixed vertices fix
    /// the lattice elements that carry them).
    pub constraints: Option<ConstraintKind>,
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
    /// The ChainMail lattice (absent for the other methods).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub chainmail: Option<ChainmailStats>,
    /// The finite-element grid (absent for the other methods).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fem: Option<FemStats>,
    /// The result guards that fired on the state after the last frame
    /// ([`fibfluid::sim::result_guards`]).
    pub warnings: Vec<ResultWarning>,
    /// Wall-clock seconds of the whole probe run.
    pub seconds_total: f64,
}

fn max_norm(v: &[Vec3]) -> f64 {
    v.iter().map(|u| (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt()).fold(0.0, f64::max)
}

/// The result guards of the state after the last frame (every method; a non-finite state is
/// an error naming the scene, before anything is written).
pub(crate) fn final_state_guards(
    scene: &Scene,
    file: &MeshFile,
    field: &[Vec3],
    method: Method,
) -> Result<Vec<ResultWarning>> {
    let rest = file.mesh.positions();
    let positions: Vec<Vec3> =
        rest.iter().zip(field).map(|(r, u)| std::array::from_fn(|a| r[a] + u[a])).collect();
    let boundary = Boundary::Surface { triangles: file.mesh.triangles().to_vec() };
    // The small-strain validity check is the linear law's: a neo-Hookean body is valid at
    // any strain.
    let linear_law = scene.model.tissue.is_none_or(|t| t.is_linear());
    let checks = ResultChecks { inverted: true, residual: None, linear: method == Method::Fem && linear_law };
    check_answer(&boundary, rest, &positions, checks).map_err(|e| {
        Error::Fibfluid(
            fibfluid::sim::Error::NonFiniteAnswer { scene: scene.display_name(), method, vertex: e.vertex }
                .into(),
        )
    })
}

/// The `estimate` guard: the largest estimated error of the frames (two-rate bodies) over
/// the body's size `diagonal` (m), past [`ESTIMATE_LIMIT`].
fn estimate_warning(refresh: Option<&RefreshStats>, diagonal: f64) -> Option<ResultWarning> {
    let ratio = refresh?.largest_estimated_error / diagonal.max(f64::MIN_POSITIVE);
    (ratio > ESTIMATE_LIMIT).then_some(ResultWarning {
        guard: ResultGuard::Estimate,
        value: ratio,
        limit: ESTIMATE_LIMIT,
    })
}

/// `frames.csv`: `frame,vertex,fx,fy,fz,ux,uy,uz`, every value in shortest round-trip
/// scientific notation.
pub fn frames_csv(rows: &[FrameRow]) -> String {
    frames_csv_with(rows, true)
}

/// [`frames_csv`]; with `forces` false (a method without forces, such as ChainMail) the
/// force fields are left empty (the header stays the same).
pub fn frames_csv_with(rows: &[FrameRow], forces: bool) -> String {
    frames_csv_linearized(rows, forces, &[])
}

/// The columns `frames.csv` adds for a body answered on linearizations (the two-rate
/// neo-Hookean FEM body): the age of the frame's linearization and its estimated error.
pub const LINEARIZATION_COLUMNS: &str = "linearization_age_ms,linearization_age_frames,estimated_error_m";

/// [`frames_csv_with`], and with `statuses` (one per frame, in frame order; empty for a body
/// without linearizations) the [`LINEARIZATION_COLUMNS`] of each row's frame.
pub fn frames_csv_linearized(rows: &[FrameRow], forces: bool, statuses: &[LinearizationStatus]) -> String {
    let mut s = String::from("frame,vertex,fx,fy,fz,ux,uy,uz");
    if !statuses.is_empty() {
        s.push(',');
        s.push_str(LINEARIZATION_COLUMNS);
    }
    s.push('\n');
    for r in rows {
        let (f, u) = (r.force, r.displacement);
        if forces {
            s.push_str(&format!(
                "{},{},{:e},{:e},{:e},{:e},{:e},{:e}",
                r.frame, r.file_vertex, f[0], f[1], f[2], u[0], u[1], u[2]
            ));
        } else {
            s.push_str(&format!("{},{},,,,{:e},{:e},{:e}", r.frame, r.file_vertex, u[0], u[1], u[2]));
        }
        if !statuses.is_empty() {
            match statuses.get(r.frame) {
                Some(l) => s.push_str(&format!(
                    ",{:e},{},{:e}",
                    l.age_seconds * 1e3,
                    l.age_frames,
                    l.estimated_error
                )),
                None => s.push_str(",,,"),
            }
        }
        s.push('\n');
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
    let series: Vec<fibfluid::render::Series> = if vertices.len() <= 8 && !vertices.is_empty() {
        vertices
            .iter()
            .map(|&v| {
                let mut y = vec![0.0; frames];
                for r in rows.iter().filter(|r| r.file_vertex == v) {
                    y[r.frame] = norm(value(r));
                }
                fibfluid::render::Series {
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
        vec![fibfluid::render::Series {
            label: "sum over probed vertices".into(),
            points: y.into_iter().enumerate().map(|(k, y)| (k as f64, y)).collect(),
        }]
    };
    Ok(fibfluid::render::line_chart(title, "frame", y_label, &series, 900, 520)?)
}

/// `final.obj`: the surface at `positions` (m), written in the mesh file's vertex order and
/// unit (`to_unit` file units per metre).
pub fn final_obj(file: &MeshFile, positions: &[Vec3], to_unit: f64) -> Result<Vec<u8>> {
    let mut obj = Vec::new();
    let ordered: Vec<Vec3> =
        file.positions_in_file_order(positions).into_iter().map(|p| p.map(|c| c * to_unit)).collect();
    fibfluid::geometry::write_obj_to(&mut obj, &ordered, &file.triangles_in_file_order())
        .map_err(|source| Error::Io { path: PathBuf::from("final.obj"), source })?;
    Ok(obj)
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

/// Probes a scene along a path with the fiber–fluid method and writes [`PROBE_FILES`] into
/// `out` (all or nothing). See [`run_probe_with`].
pub fn run_probe(scene: &Scene, path: &ToolPath, out: &Path, opts: &ProbeOptions) -> Result<ProbeReport> {
    run_probe_with(scene, path, out, opts, Method::Ffm, None)
}

/// Probes a scene along a path with `method` and writes [`PROBE_FILES`] into `out` (all or
/// nothing). The path is checked against the scene before anything is assembled. A method
/// without forces (ChainMail) leaves the force fields of `frames.csv` empty, and its
/// `probe.png` charts the displacement of the probed vertices instead of the force.
/// `progress(frame, frames)` is called after each frame.
pub fn run_probe_with(
    scene: &Scene,
    path: &ToolPath,
    out: &Path,
    opts: &ProbeOptions,
    method: Method,
    progress: Option<&(dyn Fn(usize, usize) + Send + Sync)>,
) -> Result<ProbeReport> {
    let start = Instant::now();
    let Shape::Surface(file) = &scene.shape else {
        return Err(ProbeError::NotASurface { scene: scene.display_name() }.into());
    };
    check_method(path, method)?;
    let checked = check_path(path, scene)?;
    if let Some(blocked) = PROBE_FILES.iter().map(|f| out.join(f)).find(|p| p.is_dir()) {
        return Err(Error::OutputBlocked {
            path: blocked,
            problem: "is a directory, where an output file would go (nothing was written)",
        });
    }
    let mut mb = MethodBody::build(scene, &scene.chainmail, method, opts)?;
    let base_max = match &mb {
        MethodBody::Ffm(pb) => max_norm(pb.body.base_field()),
        MethodBody::Chainmail(_) => 0.0,
        MethodBody::Fem(b) => max_norm(fibfluid::interact::Interactive::field(b.as_ref())),
        MethodBody::Hyper(b) => max_norm(fibfluid::interact::Interactive::field(b.as_ref())),
    };
    let frames = checked.frames.len().max(checked.tips.len());
    let mut statuses = Vec::new();
    let mut replay = replay_observed(mb.interactive(), &checked, |k, body| {
        statuses.extend(body.linearization());
        if let Some(p) = progress {
            p(k + 1, frames);
        }
    })?;
    // Displacements go out in the mesh's unit, like the mesh (forces stay in newtons).
    let to_unit = 1.0 / scene.unit.metres();
    replay.rows.iter_mut().for_each(|r| r.displacement = r.displacement.map(|c| c * to_unit));
    let mut probed: Vec<usize> = replay.rows.iter().map(|r| r.file_vertex).collect();
    probed.sort_unstable();
    probed.dedup();
    let body = mb.interactive_ref();
    let forces = body.supports_forces();
    let d = MethodDetails::of(&mb, scene);
    let mut report = ProbeReport {
        scene: scene.name.clone(),
        path: path.source.display().to_string(),
        method,
        kind: path.kind,
        precision: d.precision,
        constraints: d.constraints,
        probe: ProbeStats {
            frames: replay.frames,
            vertices: body.n_vertices(),
            probed_vertices: probed.len(),
            precompute_seconds: d.precompute_seconds,
            memory_bytes: body.memory_bytes(),
            latency_us: Latency::of(&replay.latency_us),
            updates: body.frame(),
            refresh: refresh_stats(&mb, &statuses, &replay.latency_us),
        },
        base_seconds: d.base_seconds,
        base_max_displacement: base_max,
        final_max_displacement: max_norm(body.field()),
        final_pressure: d.final_pressure,
        chainmail: d.chainmail,
        fem: d.fem,
        warnings: final_state_guards(scene, file, body.field(), method)?,
        seconds_total: 0.0,
    };
    report.warnings.extend(estimate_warning(report.probe.refresh.as_ref(), file.mesh.diagonal()));
    let png = if forces {
        let title = format!(
            "{}: force at the probed vertices ({} path, {method}, {})",
            scene.name,
            path.kind.name(),
            report.precision
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
    let obj = final_obj(file, body.positions(), to_unit)?;
    report.seconds_total = start.elapsed().as_secs_f64();
    let json = serde_json::to_string_pretty(&report)? + "\n";
    let files = [
        (PROBE_FILES[0], frames_csv_linearized(&replay.rows, forces, &statuses).into_bytes()),
        (PROBE_FILES[1], obj),
        (PROBE_FILES[2], json.into_bytes()),
        (PROBE_FILES[3], png),
    ];
    write_files_atomically(out, &files)?;
    Ok(report)
}

/// What a probe report says of the method's body.
struct MethodDetails {
    precision: Storage,
    constraints: Option<ConstraintKind>,
    base_seconds: f64,
    precompute_seconds: f64,
    final_pressure: Option<f64>,
    chainmail: Option<ChainmailStats>,
    fem: Option<FemStats>,
}

impl MethodDetails {
    fn of(mb: &MethodBody, scene: &Scene) -> Self {
        let none = Self {
            precision: Storage::F64,
            constraints: None,
            base_seconds: 0.0,
            precompute_seconds: 0.0,
            final_pressure: None,
            chainmail: None,
            fem: None,
        };
        match mb {
            MethodBody::Ffm(pb) => Self {
                precision: pb.body.compliance().storage(),
                constraints: Some(scene.solver.constraints),
                base_seconds: pb.base_seconds,
                precompute_seconds: pb.precompute_seconds,
                final_pressure: Some(pb.body.pressure()),
                ..none
            },
            MethodBody::Chainmail(cb) => Self {
                precompute_seconds: cb.setup_seconds(),
                chainmail: Some(ChainmailStats {
                    spacing: cb.lattice().spacing(),
                    elements: cb.lattice().len(),
                    tetrahedra: cb.lattice().tets().len(),
                    tss: scene.chainmail.tss,
                    relaxation: scene.chainmail.relaxation,
                    setup_seconds: cb.setup_seconds(),
                }),
                ..none
            },
            MethodBody::Fem(b) => Self { base_seconds: b.setup_seconds(), fem: Some(b.stats()), ..none },
            MethodBody::Hyper(b) => Self { base_seconds: b.setup_seconds(), fem: Some(b.stats()), ..none },
        }
    }
}

/// The refresh section of a two-rate body's probe from its frames' statuses.
/// What a two-rate body's frames say of its refreshes along a replay.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RefreshSummary {
    /// Linearizations made by the last frame.
    pub refreshes: u64,
    /// Those that factored the tangent (the others kept the factor: chord refreshes).
    pub refactorizations: u64,
    /// Mean seconds of the refreshes swapped in (0 when none was).
    pub refresh_seconds: f64,
    /// Mean seconds of the chord refreshes (0 when none).
    pub chord_seconds: f64,
    /// Mean seconds of the refreshes that factored the tangent (0 when none).
    pub refactor_seconds: f64,
    /// Refreshes that failed (a new failure message in a frame).
    pub failures: usize,
    /// Why the first failed refresh failed.
    pub first_failure: Option<String>,
}

impl RefreshSummary {
    /// The summary of the frames' statuses, in frame order.
    pub fn of(statuses: &[LinearizationStatus]) -> Self {
        let (mut seconds, mut chords, mut refactors) = (Vec::new(), Vec::new(), Vec::new());
        let mut failures = 0;
        for w in statuses.windows(2) {
            if w[1].refreshes > w[0].refreshes {
                seconds.push(w[1].refresh_seconds);
                let refactored = w[1].refactorizations > w[0].refactorizations;
                if refactored { &mut refactors } else { &mut chords }.push(w[1].refresh_seconds);
            }
            failures += usize::from(w[1].failure.is_some() && w[1].failure != w[0].failure);
        }
        Self {
            refreshes: statuses.last().map_or(0, |s| s.refreshes),
            refactorizations: statuses.last().map_or(0, |s| s.refactorizations),
            refresh_seconds: mean(&seconds),
            chord_seconds: mean(&chords),
            refactor_seconds: mean(&refactors),
            failures,
            first_failure: statuses.iter().find_map(|s| s.failure.clone()),
        }
    }
}

/// The mean of `v` (0 when empty).
fn mean(v: &[f64]) -> f64 {
    if v.is_empty() { 0.0 } else { v.iter().sum::<f64>() / v.len() as f64 }
}

fn refresh_stats(
    mb: &MethodBody,
    statuses: &[LinearizationStatus],
    latency_us: &[f64],
) -> Option<RefreshStats> {
    let MethodBody::Hyper(b) = mb else { return None };
    let last = statuses.last().cloned().unwrap_or_default();
    let RefreshSummary { refresh_seconds, failures, .. } = RefreshSummary::of(statuses);
    let frame_seconds = mean(latency_us) * 1e-6;
    Some(RefreshStats {
        every: b.refresh_every().unwrap_or(1),
        refreshes: last.refreshes,
        refactorizations: last.refactorizations,
        refresh_seconds,
        refresh_hz: if refresh_seconds > 0.0 { 1.0 / refresh_seconds } else { 0.0 },
        frames_per_refresh: if frame_seconds > 0.0 { refresh_seconds / frame_seconds } else { 0.0 },
        largest_age_frames: statuses.iter().map(|s| s.age_frames).max().unwrap_or(0),
        largest_age_ms: statuses.iter().map(|s| s.age_seconds * 1e3).fold(0.0, f64::max),
        largest_estimated_error: statuses.iter().map(|s| s.estimated_error).fold(0.0, f64::max),
        final_estimated_error: last.estimated_error,
        failures,
    })
}
