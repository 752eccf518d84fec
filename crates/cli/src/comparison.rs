//! `fibfluid compare`: the same tool path replayed with the fiber–fluid method,
//! TSVE-ChainMail and Generalized ChainMail, with the numbers a user comparing the methods
//! asks for (`compare.json`) and the three surfaces side by side (`compare.png`).
//!
//! Per method (`M` in `compare.json`):
//!
//! - `setup_seconds`: FFM base solve and precompute; ChainMail voxelization and embedding.
//! - `memory_bytes`: the body's [`Interactive::memory_bytes`](fibfluid::interact::Interactive::memory_bytes).
//! - `latency_us`: frame latency percentiles (`p50`, `p99`, `max`, nearest rank).
//! - `volume_change_max`: the largest `|V / V0 - 1|` of the deformed surface over the
//!   frames (`V0` the rest surface's volume).
//! - `rest_distance_after_release`: the largest vertex distance from rest after the last
//!   frame, over the rest bounding-box diagonal (a path ends with frames holding nothing;
//!   relaxation runs there). FFM's includes its base state (the scene's loads), to which it
//!   returns.
//! - `surface_rms_vs_ffm`: the RMS vertex distance to FFM's surface over all frames and
//!   vertices, over the diagonal (0 for FFM itself).

use std::collections::BTreeMap;
use std::path::Path;

use fibfluid::geometry::Vec3;
use fibfluid::geometry::vec3::{dist, norm};
use fibfluid::interact::{
    CheckedPath, Latency, Method, MethodBody, ProbeError, ProbeOptions, ToolPath, check_method, check_path,
    replay_observed,
};
use fibfluid::{Choice, Scene, Shape, memory_budget};
use serde::Serialize;

use crate::output::write_files_atomically;
use crate::{Error, Result};

/// Names of the files [`run_compare`] writes.
pub const COMPARE_FILES: [&str; 2] = ["compare.json", "compare.png"];

/// One method's numbers in `compare.json`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MethodMetrics {
    /// Seconds of the setup.
    pub setup_seconds: f64,
    /// Bytes held by the body.
    pub memory_bytes: usize,
    /// Frame latency, microseconds.
    pub latency_us: Latency,
    /// Largest `|V / V0 - 1|` over the frames.
    pub volume_change_max: f64,
    /// Largest vertex distance from rest after the last frame, over the diagonal.
    pub rest_distance_after_release: f64,
    /// RMS vertex distance to FFM's surface over all frames, over the diagonal.
    pub surface_rms_vs_ffm: f64,
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
    /// Rest bounding-box diagonal (the scale of the relative distances).
    pub diagonal: f64,
    /// The frame shown in `compare.png`: the first frame of the path's largest grab.
    pub shown_frame: usize,
    /// Numbers per method, by method name.
    pub methods: BTreeMap<String, MethodMetrics>,
}

/// One method's replay: its metrics and its surface at the shown frame.
struct Run {
    metrics: MethodMetrics,
    shown: Vec<Vec3>,
}

/// Bytes a comparison keeps per frame and vertex: FFM's surface (the reference of the
/// others' distances).
const BYTES_PER_FRAME_VERTEX: u128 = 24;

/// Replays `path` on `scene` with the three methods and writes [`COMPARE_FILES`] into `out`
/// (all or nothing). The path must be a grab path (ChainMail has no forces); it is checked,
/// and the memory the comparison keeps is checked against the budget from counts, before
/// any body is built.
pub fn run_compare(scene: &Scene, path: &ToolPath, out: &Path, opts: &ProbeOptions) -> Result<CompareReport> {
    let Shape::Surface(file) = &scene.shape else {
        return Err(ProbeError::NotASurface { scene: scene.display_name() }.into());
    };
    for &m in Method::ALL {
        check_method(path, m)?;
    }
    let checked = check_path(path, scene)?;
    if let Some(blocked) = COMPARE_FILES.iter().map(|f| out.join(f)).find(|p| p.is_dir()) {
        return Err(Error::OutputBlocked {
            path: blocked,
            problem: "is a directory, where an output file would go (nothing was written)",
        });
    }
    let rest = file.mesh.positions().to_vec();
    let frames = checked.frames.len();
    let bytes = frames as u128 * rest.len() as u128 * BYTES_PER_FRAME_VERTEX;
    let available = memory_budget(opts.max_memory_bytes);
    if bytes > available as u128 {
        return Err(ProbeError::PathTooLong {
            path: path.source.clone(),
            what: "a comparison keeps FFM's surface at every frame",
            frames,
            vertices: rest.len(),
            bytes,
            available,
        }
        .into());
    }
    let triangles = file.mesh.triangles();
    let (lo, hi) = fibfluid::geometry::bounding_box(&rest);
    let diagonal = dist(lo, hi);
    let shown = largest_grab_frame(&checked);
    let mut reference: Vec<Vec<Vec3>> = Vec::with_capacity(frames);
    let mut runs: Vec<(Method, Run)> = Vec::new();
    for &method in Method::ALL {
        let mut body = MethodBody::build(scene, &scene.chainmail, method, opts)?;
        let setup_seconds = body.setup_seconds();
        let mut tally = Tally::new(fibfluid::geometry::volume(&rest, triangles));
        let replay = replay_observed(body.interactive(), &checked, |k, b| {
            let p = b.positions();
            tally.volume(fibfluid::geometry::volume(p, triangles));
            match reference.get(k) {
                Some(r) => tally.distance(p, r),
                None => reference.push(p.to_vec()),
            }
            if k == shown {
                tally.shown = p.to_vec();
            }
        })?;
        let b = body.interactive_ref();
        let after = b.positions().iter().zip(&rest).map(|(p, r)| dist(*p, *r)).fold(0.0, f64::max);
        let metrics = MethodMetrics {
            setup_seconds,
            memory_bytes: b.memory_bytes(),
            latency_us: Latency::of(&replay.latency_us),
            volume_change_max: tally.volume_change_max,
            rest_distance_after_release: after / diagonal,
            surface_rms_vs_ffm: tally.rms() / diagonal,
        };
        runs.push((method, Run { metrics, shown: std::mem::take(&mut tally.shown) }));
    }
    let png = compare_png(&runs, &rest, triangles, shown)?;
    let report = CompareReport {
        scene: scene.name.clone(),
        path: path.source.display().to_string(),
        frames,
        vertices: rest.len(),
        diagonal,
        shown_frame: shown,
        methods: runs.into_iter().map(|(m, r)| (m.name().to_string(), r.metrics)).collect(),
    };
    let json = serde_json::to_string_pretty(&report)? + "\n";
    write_files_atomically(out, &[(COMPARE_FILES[0], json.into_bytes()), (COMPARE_FILES[1], png)])?;
    Ok(report)
}

/// The frame of largest displacement: where the tool's largest grab is (the first such
/// frame); the scene's own loads (FFM's base state) do not count.
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
    sum_sq: f64,
    count: usize,
    shown: Vec<Vec3>,
}

impl Tally {
    fn new(v0: f64) -> Self {
        Self { v0, volume_change_max: 0.0, sum_sq: 0.0, count: 0, shown: Vec::new() }
    }

    fn volume(&mut self, v: f64) {
        self.volume_change_max = self.volume_change_max.max((v / self.v0 - 1.0).abs());
    }

    fn distance(&mut self, surface: &[Vec3], reference: &[Vec3]) {
        for (p, q) in surface.iter().zip(reference) {
            let d = dist(*p, *q);
            self.sum_sq += d * d;
            self.count += 1;
        }
    }

    fn rms(&self) -> f64 {
        if self.count > 0 { (self.sum_sq / self.count as f64).sqrt() } else { 0.0 }
    }
}

/// The three surfaces at frame `k`, side by side, colored by `|u|` on one scale.
fn compare_png(runs: &[(Method, Run)], rest: &[Vec3], triangles: &[[u32; 3]], k: usize) -> Result<Vec<u8>> {
    let mags: Vec<Vec<f64>> =
        runs.iter().map(|(_, r)| r.shown.iter().zip(rest).map(|(p, q)| dist(*p, *q)).collect()).collect();
    let top = mags.iter().flatten().copied().fold(0.0, f64::max);
    let range = (0.0, if top > 0.0 { top } else { 1.0 });
    let panels: Vec<fibfluid::render::Surface<'_>> = runs
        .iter()
        .zip(&mags)
        .map(|((m, r), mag)| fibfluid::render::Surface {
            positions: &r.shown,
            triangles,
            scalar: mag,
            title: format!("{m}, frame {k}"),
        })
        .collect();
    let opts = fibfluid::render::ViewOptions { scalar_label: "|u|".into(), ..Default::default() };
    Ok(fibfluid::render::render_surfaces(&panels, Some(range), &opts)?)
}
