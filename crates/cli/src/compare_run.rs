//! `fibfluid compare`: the same grab path replayed with every method — the fiber–fluid
//! method, TSVE-ChainMail, Generalized ChainMail and, when the scene gives `[tissue]`, the
//! finite-element method — with each method's frame cost beside its error against the
//! reference (the FEM when it runs, else FFM): accuracy against time, side by side
//! (`compare.json`, `compare.png`).
//!
//! Like is compared with like: ChainMail carries neither gravity nor point forces, so every
//! method is measured by its **tool-induced displacement**, each frame's surface minus the
//! method's own base state (the scene's loads for FFM and the FEM, rest for ChainMail), and
//! every grab is applied as a displacement from that base state (the tool moves a vertex
//! from where the scene's loads left it in that method).
//!
//! Per method (`M` in `compare.json`):
//!
//! - `setup_seconds`, `memory_bytes`, `latency_us` (frame cost: `p50`, `p99`, `max`).
//! - `carries_scene_loads`: whether the base state holds the scene's gravity and forces.
//! - `base_max_displacement`: the base state's largest displacement (m).
//! - `error_vs_reference`: relative L2 over all frames and vertices of the tool-induced
//!   displacement against the reference's, `sqrt(sum |d - d_ref|^2 / sum |d_ref|^2)`.
//! - `worst_vertex_error`: the largest `|d - d_ref|` of any vertex and frame over the
//!   reference's largest `|d_ref|`.
//! - `volume_change_max`: the largest `|V / V0 - 1|` over the frames.
//! - `rest_distance_after_release`: the largest vertex distance from the base state after the
//!   last frame, over the rest bounding-box diagonal.

use std::collections::BTreeMap;
use std::path::Path;

use fibfluid::geometry::Vec3;
use fibfluid::geometry::vec3::{dist, norm, sub};
use fibfluid::interact::RefreshMode;
use fibfluid::interact::{
    CheckedPath, Latency, Method, MethodBody, PathKind, ProbeError, ProbeOptions, ToolPath, check_method,
    check_path, replay_observed,
};
use fibfluid::{Choice, Scene, Shape, memory_budget};
use serde::Serialize;

use crate::output::write_files_atomically;
use crate::{Error, Result};

/// Names of the files [`run_compare`] writes.
pub const COMPARE_FILES: [&str; 3] = ["compare.json", "compare.png", "frame-errors.png"];

/// Paths up to this many frames get each method's error per frame in `compare.json`
/// (`frame_errors`); `frame-errors.png` charts them for any length.
pub const MAX_FRAME_ERRORS: usize = 10_000;

/// What is compared, as `compare.json` says it.
pub const COMPARED: &str = "tool-induced displacement: grabs applied from, and surfaces measured against, each method's own base state (ChainMail carries no gravity or point forces)";

/// One method's numbers in `compare.json`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MethodMetrics {
    /// Seconds of the setup.
    pub setup_seconds: f64,
    /// Bytes held by the body.
    pub memory_bytes: usize,
    /// Frame latency, microseconds.
    pub latency_us: Latency,
    /// Whether the base state carries the scene's gravity and point forces.
    pub carries_scene_loads: bool,
    /// Largest displacement of the base state (m).
    pub base_max_displacement: f64,
    /// Relative L2 of the tool-induced displacement against the reference's.
    pub error_vs_reference: f64,
    /// Largest vertex error over the reference's largest tool-induced displacement.
    pub worst_vertex_error: f64,
    /// Per frame, the L2 norm of the tool-induced displacement's difference from the
    /// reference's, over the reference's largest L2 norm along the path (so a frame where
    /// the reference is back at rest reads the error in the same units); absent above
    /// [`MAX_FRAME_ERRORS`] frames.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frame_errors: Option<Vec<f64>>,
    /// Largest `|V / V0 - 1|` over the frames.
    pub volume_change_max: f64,
    /// Largest vertex distance from the base state after the last frame, over the diagonal.
    pub rest_distance_after_release: f64,
    /// The result guards that fired on the state after the last frame
    /// ([`fibfluid::sim::result_guards`]).
    pub warnings: Vec<fibfluid::sim::result_guards::ResultWarning>,
}

/// `compare.json`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CompareReport {
    /// Scene name.
    pub scene: String,
    /// The path file.
    pub path: String,
    /// Frames replayed.
    pub frames: usize,
    /// Vertices of the surface.
    pub vertices: usize,
    /// Rest bounding-box diagonal (m; the scale of the relative distances).
    pub diagonal: f64,
    /// What is compared.
    pub compared: &'static str,
    /// The body the errors are measured against: `fem` when the FEM runs (`fem-converged`,
    /// Newton to convergence at every frame, for a neo-Hookean tissue), else `ffm`.
    pub reference: &'static str,
    /// The frame shown in `compare.png`: the first frame of the path's largest grab.
    pub shown_frame: usize,
    /// Numbers per method, by method name.
    pub methods: BTreeMap<String, MethodMetrics>,
    /// Methods that did not run, with the reason.
    pub skipped: BTreeMap<String, String>,
}

/// A body a comparison replays: a method's, or one of the finite-element bodies of a
/// neo-Hookean scene.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Contender {
    /// The method's body for the scene as it is (for the FEM of a neo-Hookean tissue, the
    /// two-rate body with the probe's refresh schedule).
    Method(Method),
    /// The neo-Hookean body with Newton run to convergence at every frame: the reference.
    ConvergedHyper,
    /// The linear FEM body of the same tissue's small-strain moduli.
    LinearFem,
}

impl Contender {
    /// The name in `compare.json`.
    fn name(self) -> &'static str {
        match self {
            Contender::Method(m) => m.name(),
            Contender::ConvergedHyper => "fem-converged",
            Contender::LinearFem => "fem-linear",
        }
    }

    /// The method it runs.
    fn method(self) -> Method {
        match self {
            Contender::Method(m) => m,
            Contender::ConvergedHyper | Contender::LinearFem => Method::Fem,
        }
    }

    /// Builds its body.
    fn build(self, scene: &Scene, opts: &ProbeOptions) -> Result<MethodBody> {
        let body = match self {
            Contender::Method(m) => MethodBody::build(scene, &scene.chainmail, m, opts)?,
            Contender::ConvergedHyper => {
                let converged = ProbeOptions { refresh: RefreshMode::Converged, ..*opts };
                MethodBody::build(scene, &scene.chainmail, Method::Fem, &converged)?
            }
            Contender::LinearFem => {
                let mut linear = scene.clone();
                linear.model.tissue = linear.model.tissue.map(|t| t.linearized());
                MethodBody::build(&linear, &scene.chainmail, Method::Fem, opts)?
            }
        };
        Ok(body)
    }
}

/// One method's replay: its metrics and its tool-induced displacement at the shown frame.
struct Run {
    metrics: MethodMetrics,
    shown: Vec<Vec3>,
}

/// Bytes a comparison keeps per frame and vertex: the reference's tool-induced displacement.
const BYTES_PER_FRAME_VERTEX: u128 = 24;

/// The bodies a scene can compare, the reference first, and the methods it cannot run with
/// why. A neo-Hookean scene's reference is its converged body, beside the two-rate and the
/// linear FEM bodies.
fn methods_of(scene: &Scene) -> (Vec<Contender>, BTreeMap<String, String>) {
    let mut skipped = BTreeMap::new();
    let mut methods: Vec<Contender> = [Method::Ffm, Method::TsveChainmail, Method::GeneralizedChainmail]
        .into_iter()
        .map(Contender::Method)
        .collect();
    match scene.tissue {
        Some(t) if !t.is_linear() => {
            let fem = [Contender::ConvergedHyper, Contender::Method(Method::Fem), Contender::LinearFem];
            methods.splice(0..0, fem);
        }
        Some(_) => methods.insert(0, Contender::Method(Method::Fem)),
        None => {
            skipped.insert(
                Method::Fem.to_string(),
                "the scene has no [tissue] (E in Pa, poisson, density)".into(),
            );
        }
    }
    if !scene.ffm_material {
        methods.retain(|m| *m != Contender::Method(Method::Ffm));
        skipped.insert(Method::Ffm.to_string(), "the scene has no [material] for FFM".into());
    }
    (methods, skipped)
}

/// The most frames a comparison replays with ChainMail (its lattice updates at every frame,
/// even one that asks what the last asked; FFM and the FEM answer repeated frames for free).
pub const MAX_CHAINMAIL_FRAMES: usize = 100_000;

/// Refuses, from counts, a path whose reference displacements would not fit.
fn check_size(path: &ToolPath, frames: usize, vertices: usize, opts: &ProbeOptions) -> Result<()> {
    let bytes = frames as u128 * vertices as u128 * BYTES_PER_FRAME_VERTEX;
    let available = memory_budget(opts.max_memory_bytes);
    if bytes > available as u128 {
        return Err(ProbeError::PathTooLong {
            path: path.source.clone(),
            what: "a comparison keeps the reference's displacement at every frame",
            frames,
            vertices,
            bytes,
            available,
        }
        .into());
    }
    Ok(())
}

/// Replays `path` on `scene` with every method it can run and writes [`COMPARE_FILES`] into
/// `out` (all or nothing). The path must be a grab path (ChainMail has no forces); it is
/// checked, and the memory the comparison keeps is checked against the budget from counts,
/// before any body is built.
pub fn run_compare(scene: &Scene, path: &ToolPath, out: &Path, opts: &ProbeOptions) -> Result<CompareReport> {
    let Shape::Surface(file) = &scene.shape else {
        return Err(ProbeError::NotASurface { scene: scene.display_name() }.into());
    };
    let (methods, skipped) = methods_of(scene);
    for &m in &methods {
        check_method(path, m.method())?;
    }
    let checked = check_path(path, scene)?;
    if let Some(blocked) = COMPARE_FILES.iter().map(|f| out.join(f)).find(|p| p.is_dir()) {
        return Err(Error::OutputBlocked {
            path: blocked,
            problem: "is a directory, where an output file would go (nothing was written)",
        });
    }
    let frames = checked.frames.len();
    if frames > MAX_CHAINMAIL_FRAMES && methods.iter().any(|m| m.method().is_chainmail()) {
        return Err(Error::CompareTooLong { path: path.source.clone(), frames, limit: MAX_CHAINMAIL_FRAMES });
    }
    let rest = file.mesh.positions().to_vec();
    // The reference keeps one displacement per run of frames that ask the same thing.
    let distinct = (0..checked.frames.len()).filter(|&k| !checked.repeats_previous(k)).count();
    check_size(path, distinct, rest.len(), opts)?;
    let (lo, hi) = fibfluid::geometry::bounding_box(&rest);
    let diagonal = dist(lo, hi);
    let shown = largest_grab_frame(&checked);
    let mut reference = Reference::default();
    let mut runs: Vec<(Contender, Run)> = Vec::new();
    for &method in &methods {
        let run = replay_method(scene, method, &checked, opts, &mut reference, shown, diagonal)?;
        runs.push((method, run));
    }
    let png = compare_png(&runs, &rest, file.mesh.triangles(), shown, scene)?;
    let errors_png = frame_errors_png(&runs, scene)?;
    let report = CompareReport {
        scene: scene.name.clone(),
        path: path.source.display().to_string(),
        frames: checked.frames.len(),
        vertices: rest.len(),
        diagonal,
        compared: COMPARED,
        reference: methods[0].name(),
        shown_frame: shown,
        methods: runs
            .into_iter()
            .map(|(m, mut r)| {
                if frames > MAX_FRAME_ERRORS {
                    r.metrics.frame_errors = None;
                }
                (m.name().to_string(), r.metrics)
            })
            .collect(),
        skipped,
    };
    let json = serde_json::to_string_pretty(&report)? + "\n";
    let files =
        [(COMPARE_FILES[0], json.into_bytes()), (COMPARE_FILES[1], png), (COMPARE_FILES[2], errors_png)];
    write_files_atomically(out, &files)?;
    Ok(report)
}

/// Replays the path with one method; the first method fills `reference` with its
/// tool-induced displacements, the others are measured against it.
fn replay_method(
    scene: &Scene,
    contender: Contender,
    checked: &CheckedPath,
    opts: &ProbeOptions,
    reference: &mut Reference,
    shown: usize,
    diagonal: f64,
) -> Result<Run> {
    let Shape::Surface(file) = &scene.shape else { unreachable!("checked by run_compare") };
    let triangles = file.mesh.triangles();
    let method = contender.method();
    let mut body = contender.build(scene, opts)?;
    let setup_seconds = body.setup_seconds();
    let base = body.interactive_ref().positions().to_vec();
    let rest = body.interactive_ref().rest_positions().to_vec();
    let base_max = base.iter().zip(&rest).map(|(p, r)| dist(*p, *r)).fold(0.0, f64::max);
    let mut tally = Tally::new(fibfluid::geometry::volume(&rest, triangles));
    let is_reference = reference.slots.is_empty();
    let from_base = from_own_base(checked, &base, &rest);
    let replay = replay_observed(body.interactive(), &from_base, |k, b| {
        let p = b.positions();
        tally.volume(fibfluid::geometry::volume(p, triangles));
        let d: Vec<Vec3> = p.iter().zip(&base).map(|(p, q)| sub(*p, *q)).collect();
        if is_reference {
            reference.record(k, checked.repeats_previous(k) && b.answers_from_holds(), &d);
        }
        tally.against(&d, reference.at(k));
        if k == shown {
            tally.shown = d;
        }
    })?;
    let b = body.interactive_ref();
    let after = b.positions().iter().zip(&base).map(|(p, r)| dist(*p, *r)).fold(0.0, f64::max);
    let metrics = MethodMetrics {
        setup_seconds,
        memory_bytes: b.memory_bytes(),
        latency_us: Latency::of(&replay.latency_us),
        carries_scene_loads: !method.is_chainmail(),
        base_max_displacement: base_max,
        error_vs_reference: tally.relative_l2(),
        worst_vertex_error: tally.worst(),
        frame_errors: Some(tally.frame_errors()),
        volume_change_max: tally.volume_change_max,
        rest_distance_after_release: after / diagonal,
        warnings: crate::probe_run::final_state_guards(scene, file, b.field(), method)?,
    };
    Ok(Run { metrics, shown: std::mem::take(&mut tally.shown) })
}

/// The reference method's tool-induced displacement at every frame, kept once per run of
/// frames that ask the same thing (a path that declares frame 1,000,000 keeps two, not a
/// million): `slots[k]` indexes `fields`.
#[derive(Default)]
struct Reference {
    fields: Vec<Vec<Vec3>>,
    slots: Vec<usize>,
}

impl Reference {
    /// Frame `k`'s displacement `d`; `repeats`: frame `k` asks what frame `k - 1` asked, so
    /// its field is the last one kept.
    fn record(&mut self, k: usize, repeats: bool, d: &[Vec3]) {
        debug_assert_eq!(k, self.slots.len(), "frames come in order");
        if !repeats || self.fields.is_empty() {
            self.fields.push(d.to_vec());
        }
        self.slots.push(self.fields.len() - 1);
    }

    /// Frame `k`'s displacement.
    fn at(&self, k: usize) -> &[Vec3] {
        &self.fields[self.slots[k]]
    }
}

/// The path with every grab and grasp taken from the method's own base state: the tool
/// moves a vertex by the path's displacement from where the scene's loads left it, so a
/// method that carries gravity and one that does not (ChainMail) are pulled by the same
/// tool. A press's tip is placed in absolute coordinates.
pub(crate) fn from_own_base(checked: &CheckedPath, base: &[Vec3], rest: &[Vec3]) -> CheckedPath {
    let mut shifted = checked.clone();
    match checked.kind {
        PathKind::Grab => {
            for h in shifted.frames.iter_mut().flatten() {
                let u = sub(base[h.vertex], rest[h.vertex]);
                h.value = [h.value[0] + u[0], h.value[1] + u[1], h.value[2] + u[2]];
            }
        }
        PathKind::Grasp => shifted.origin = Some(base.iter().zip(rest).map(|(p, r)| sub(*p, *r)).collect()),
        PathKind::Force | PathKind::Press => {}
    }
    shifted
}

/// The frame of largest displacement: where the tool's largest grab is (the first such
/// frame); the scene's own loads (the base state) do not count.
fn largest_grab_frame(path: &CheckedPath) -> usize {
    let tool = |k: usize| path.frames[k].iter().map(|h| norm(h.value)).fold(0.0, f64::max);
    let mut shown = 0;
    for k in 0..path.frames.len() {
        if tool(k) > tool(shown) {
            shown = k;
        }
    }
    shown
}

/// What a replay accumulates frame by frame.
struct Tally {
    v0: f64,
    volume_change_max: f64,
    diff_sq: f64,
    reference_sq: f64,
    worst_diff: f64,
    reference_max: f64,
    /// Per frame, the L2 norm of the difference from the reference (m).
    frame_errors: Vec<f64>,
    /// Per frame, the L2 norm of the reference's tool-induced displacement (m).
    frame_reference: Vec<f64>,
    shown: Vec<Vec3>,
}

impl Tally {
    fn new(v0: f64) -> Self {
        Self {
            v0,
            volume_change_max: 0.0,
            diff_sq: 0.0,
            reference_sq: 0.0,
            worst_diff: 0.0,
            reference_max: 0.0,
            frame_errors: Vec::new(),
            frame_reference: Vec::new(),
            shown: Vec::new(),
        }
    }

    fn volume(&mut self, v: f64) {
        self.volume_change_max = self.volume_change_max.max((v / self.v0 - 1.0).abs());
    }

    fn against(&mut self, d: &[Vec3], reference: &[Vec3]) {
        let (mut diff_sq, mut reference_sq) = (0.0, 0.0);
        for (p, q) in d.iter().zip(reference) {
            let e = dist(*p, *q);
            diff_sq += e * e;
            self.worst_diff = self.worst_diff.max(e);
            let r = norm(*q);
            reference_sq += r * r;
            self.reference_max = self.reference_max.max(r);
        }
        self.diff_sq += diff_sq;
        self.reference_sq += reference_sq;
        self.frame_errors.push(diff_sq.sqrt());
        self.frame_reference.push(reference_sq.sqrt());
    }

    fn relative_l2(&self) -> f64 {
        if self.reference_sq > 0.0 { (self.diff_sq / self.reference_sq).sqrt() } else { 0.0 }
    }

    /// Each frame's error over the reference's largest (over the frames) L2 norm: a
    /// frame where the reference is back at its base state reads its absolute error.
    fn frame_errors(&self) -> Vec<f64> {
        let peak = self.frame_reference.iter().copied().fold(0.0, f64::max);
        self.frame_errors.iter().map(|e| if peak > 0.0 { e / peak } else { 0.0 }).collect()
    }

    fn worst(&self) -> f64 {
        if self.reference_max > 0.0 { self.worst_diff / self.reference_max } else { 0.0 }
    }
}

/// Each method's tool-induced displacement at frame `k`, on the rest shape, side by side on
/// one color scale.
fn compare_png(
    runs: &[(Contender, Run)],
    rest: &[Vec3],
    triangles: &[[u32; 3]],
    k: usize,
    scene: &Scene,
) -> Result<Vec<u8>> {
    let to_unit = 1.0 / scene.unit.metres();
    let mags: Vec<Vec<f64>> =
        runs.iter().map(|(_, r)| r.shown.iter().map(|d| to_unit * norm(*d)).collect()).collect();
    let shapes: Vec<Vec<Vec3>> = runs
        .iter()
        .map(|(_, r)| {
            rest.iter().zip(&r.shown).map(|(p, d)| [p[0] + d[0], p[1] + d[1], p[2] + d[2]]).collect()
        })
        .collect();
    let top = mags.iter().flatten().copied().fold(0.0, f64::max);
    let range = (0.0, if top > 0.0 { top } else { 1.0 });
    let reference = runs.first().map(|(m, _)| *m);
    let panels: Vec<fibfluid::render::Surface<'_>> = runs
        .iter()
        .zip(&mags)
        .zip(&shapes)
        .map(|(((m, r), mag), shape)| fibfluid::render::Surface {
            positions: shape,
            triangles,
            scalar: mag,
            title: if Some(*m) == reference {
                format!("{} (reference), frame {k}", m.name())
            } else {
                format!("{}, frame {k}: error {:.0} %", m.name(), 100.0 * r.metrics.error_vs_reference)
            },
        })
        .collect();
    let label = format!("tool-induced |u| ({})", scene.unit);
    let opts = fibfluid::render::ViewOptions { scalar_label: label, ..Default::default() };
    Ok(fibfluid::render::render_surfaces(&panels, Some(range), &opts)?)
}

/// Each compared body's error per frame against the reference, one line each (the
/// reference itself left out).
fn frame_errors_png(runs: &[(Contender, Run)], scene: &Scene) -> Result<Vec<u8>> {
    let series: Vec<fibfluid::render::Series> = runs
        .iter()
        .skip(1)
        .map(|(m, r)| fibfluid::render::Series {
            label: m.name().to_string(),
            points: r
                .metrics
                .frame_errors
                .iter()
                .flatten()
                .enumerate()
                .map(|(k, &e)| (k as f64, e))
                .collect(),
        })
        .collect();
    let reference = runs.first().map_or("the reference", |(m, _)| m.name());
    let title = format!("{}: error per frame against {reference}", scene.name);
    let y = "L2 error / the reference's largest L2";
    Ok(fibfluid::render::line_chart(&title, "frame", y, &series, 900, 520)?)
}
