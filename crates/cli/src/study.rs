//! What accuracy costs in time: a grid of stepping modes, schemes, step counts, precisions
//! and backends, each run as a compression–decompression round trip on the same scene.

use serde::Serialize;

use fibfluid::render::log_drawable;
use fibfluid::sim::FiberModel;
use fibfluid::{Backend, Mode, Precision, RoundTrip, RunOptions, Scene, Stepping, roundtrip};

/// One configuration of the study.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Config {
    /// Stepping mode.
    pub mode: Mode,
    /// Stepping scheme.
    pub stepping: Stepping,
    /// Load steps each way (adaptive: the steps taken, both ways).
    pub steps: usize,
    /// Adaptive stepping tolerance (`None`: equal steps).
    pub tolerance: Option<f64>,
    /// Precision.
    pub precision: Precision,
    /// Backend.
    pub backend: Backend,
    /// FFM's fiber model.
    pub fibers: FiberModel,
}

impl Config {
    /// The configuration's line label (everything but the step count).
    pub fn series(&self) -> String {
        format!("{} {} {} {}", self.mode, self.stepping_label(), self.precision, self.backend)
    }

    /// `ffm` or `ffm projected`, then the mode and the stepping (a chart line's label).
    fn fibers_label(&self) -> String {
        let ffm = match self.fibers {
            FiberModel::Paper => "ffm".to_string(),
            other => format!("ffm {other}"),
        };
        format!("{ffm} {} {}", self.mode, self.stepping_label())
    }

    /// `euler`, `heun`, or `adaptive` for a tolerance point.
    pub fn stepping_label(&self) -> String {
        match self.tolerance {
            Some(_) => "adaptive".into(),
            None => self.stepping.to_string(),
        }
    }
}

/// One measured point.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Point {
    /// The configuration.
    #[serde(flatten)]
    pub config: Config,
    /// Eq. 9 round-trip error (None when the run failed).
    pub roundtrip_error: Option<f64>,
    /// |V/V0 - 1| at the end of compression.
    pub volume_drift: Option<f64>,
    /// Mean distance of the compressed shape to the reference, over N times the
    /// bounding-box diagonal (the normalization of Eq. 9).
    pub reference_distance: Option<f64>,
    /// Largest relative residual of any solve.
    pub residual_max: Option<f64>,
    /// Factorizations made.
    pub factorizations: Option<usize>,
    /// Wall-clock seconds of the round trip (setup and both ways).
    pub seconds: Option<f64>,
    /// Wall-clock seconds of the setup and the compression alone (a plain run).
    pub run_seconds: Option<f64>,
    /// Relative L2 difference of the compressed surface's displacement from the FEM
    /// reference's, no scaling (the physical axis; `None` without `[tissue]`).
    pub error_vs_fem: Option<f64>,
    /// Why the run failed, if it did.
    pub error: Option<String>,
}

/// The grid to run.
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    /// Modes.
    pub modes: Vec<Mode>,
    /// Schemes.
    pub steppings: Vec<Stepping>,
    /// Step counts.
    pub steps: Vec<usize>,
    /// Adaptive stepping tolerances (one point per mode, precision and backend each).
    pub tolerances: Vec<f64>,
    /// Precisions.
    pub precisions: Vec<Precision>,
    /// Backends.
    pub backends: Vec<Backend>,
    /// Fiber models (`projected` runs in f64 with its own coupled solver: one point per
    /// mode, stepping and step count; nonlinear mode follows the dense backends' cost rule).
    pub fibers: Vec<FiberModel>,
    /// Dense backends refactor the (3N+1)^2 matrix at every step outside paper mode (a new
    /// border or a new K); above this many vertices they are run only up to
    /// `dense_refactor_max_steps` there.
    pub dense_refactor_vertex_limit: usize,
    /// See `dense_refactor_vertex_limit`.
    pub dense_refactor_max_steps: usize,
    /// Whether the physical axis adds the grab comparison of every interactive method
    /// ([`crate::grab`]).
    pub grab: bool,
    /// Resolutions of the physical axis' FEM points.
    pub fem_resolutions: Vec<usize>,
    /// Resolution of the physical axis' FEM reference (finer than every FEM point).
    pub fem_reference: usize,
}

impl Default for Grid {
    fn default() -> Self {
        Self {
            modes: <Mode as fibfluid::Choice>::ALL.to_vec(),
            steppings: vec![Stepping::Euler, Stepping::Heun],
            steps: vec![1, 3, 10, 30, 100],
            tolerances: vec![1e-2, 1e-3, 1e-4],
            precisions: vec![Precision::F64, Precision::Mixed],
            backends: Backend::compiled(),
            fibers: vec![FiberModel::Paper],
            dense_refactor_vertex_limit: 500,
            dense_refactor_max_steps: 10,
            grab: true,
            fem_resolutions: FEM_STUDY_RESOLUTIONS.to_vec(),
            fem_reference: FEM_STUDY_REFERENCE,
        }
    }
}

/// The FEM at one resolution, against the study's FEM reference.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FemPoint {
    /// Cells along the longest side.
    pub resolution: usize,
    /// Unknowns.
    pub dofs: usize,
    /// Wall-clock seconds of the run (voxelization, assembly, factorization, solve).
    pub seconds: f64,
    /// Relative L2 difference of its surface displacement from the reference's.
    pub error_vs_fem: f64,
}

/// The physical axis of a study: the FEM reference and the FEM's own convergence.
#[derive(Clone, Debug, PartialEq)]
pub struct PhysicalAxis {
    /// The reference's resolution.
    pub reference_resolution: usize,
    /// The reference's surface displacement (m).
    pub reference: Vec<fibfluid::geometry::Vec3>,
    /// The FEM at coarser resolutions.
    pub fem: Vec<FemPoint>,
    /// The reference's law, by its scene name: neo-Hookean when the scene's
    /// `[tissue] model` says so.
    pub reference_law: &'static str,
    /// With a neo-Hookean reference, the linear FEM at the same resolutions against it: what
    /// the small-strain answer costs in accuracy on this scene (empty otherwise).
    pub linear_fem: Vec<FemPoint>,
    /// The calibrations made once for every point of each fiber model, when the scene gave
    /// only `[tissue]`.
    pub calibrations: Vec<fibfluid::sim::calibration::Calibration>,
    /// One grab given to every interactive method, against the FEM reference under the same
    /// grab (`None` when the grid leaves it out or the body is not a surface mesh).
    pub grab: Option<crate::grab::GrabComparison>,
}

pub use crate::study_grid::{FEM_STUDY_REFERENCE, FEM_STUDY_RESOLUTIONS, PARETO_MARGIN};

/// The study's result: every point plus the reference it was compared with.
#[derive(Clone, Debug)]
pub struct Study {
    /// The physical axis, when the scene has `[tissue]`.
    pub physical: Option<PhysicalAxis>,
    /// The reference configuration (nonlinear, Heun, the most steps, f64, structured).
    pub reference: Config,
    /// Points in grid order.
    pub points: Vec<Point>,
    /// Points skipped by the grid's cost rule, with the reason.
    pub skipped: Vec<(Config, String)>,
}

/// Runs the study. `progress(done, total)` is called after each point.
pub fn run_study(scene: &Scene, grid: &Grid, progress: &dyn Fn(usize, usize)) -> crate::Result<Study> {
    let (scene, physical) = match scene.tissue {
        Some(_) => {
            let (s, p) = physical_axis(scene, grid)?;
            (s, Some(p))
        }
        None => (scene.clone(), None),
    };
    let scene = &scene;
    let max_steps = grid.steps.iter().copied().max().unwrap_or(1);
    let mut reference_scene = scene.clone();
    reference_scene.load.steps = max_steps;
    reference_scene.load.tolerance = None;
    reference_scene.solver.mode = Mode::Nonlinear;
    reference_scene.solver.stepping = Stepping::Heun;
    reference_scene.solver.precision = Precision::F64;
    reference_scene.solver.backend = Backend::Structured;
    // Warm-up (thread pools, page faults) so the first measured point is not penalized.
    let mut warm = scene.clone();
    warm.load.steps = 1;
    warm.load.tolerance = None;
    warm.solver.backend = Backend::Structured;
    let _ = roundtrip(warm, &RunOptions::default());
    let reference_run = roundtrip(reference_scene.clone(), &RunOptions::default())?;
    let reference = config_of(&reference_scene);
    let rest = scene.rest_positions();
    let (lo, hi) = fibfluid::geometry::bounding_box(&rest);
    let diag = ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2) + (hi[2] - lo[2]).powi(2)).sqrt();
    let n = rest.len();
    let calibrations = physical.as_ref().map(|a| a.calibrations.as_slice()).unwrap_or(&[]);
    let (configs, skipped) = grid_configs(scene, grid, calibrations);
    let total = configs.len();
    let mut points = Vec::with_capacity(total);
    for (k, s) in configs.into_iter().enumerate() {
        let config = config_of(&s);
        let point = match timed_roundtrip(s) {
            Ok(rt) => {
                let mut p = point_of(config, &rt, &reference_run, n, diag);
                if p.config.fibers != reference.fibers {
                    // The converged reference is of the other fiber model.
                    p.reference_distance = None;
                }
                p.error_vs_fem = physical.as_ref().map(|a| relative_l2(&rt.compressed, &rest, &a.reference));
                p
            }
            Err(e) => Point {
                config,
                roundtrip_error: None,
                volume_drift: None,
                reference_distance: None,
                residual_max: None,
                factorizations: None,
                seconds: None,
                run_seconds: None,
                error_vs_fem: None,
                error: Some(e.to_string()),
            },
        };
        points.push(point);
        progress(k + 1, total);
    }
    Ok(Study { physical, reference, points, skipped })
}

/// The scenes of every grid point (and the points skipped, with why).
fn grid_configs(
    scene: &Scene,
    grid: &Grid,
    calibrations: &[fibfluid::sim::calibration::Calibration],
) -> (Vec<Scene>, Vec<(Config, String)>) {
    let n = scene.n_vertices();
    let mut configs = Vec::new();
    let mut skipped = Vec::new();
    for &fibers in &grid.fibers {
        for &mode in &grid.modes {
            for &stepping in &grid.steppings {
                for &precision in &grid.precisions {
                    for &backend in &grid.backends {
                        let fixed = grid.steps.iter().map(|&n| (n, None));
                        let adaptive = grid
                            .tolerances
                            .iter()
                            .filter(|_| stepping == Stepping::Heun)
                            .map(|&t| (4, Some(t)));
                        for (steps, tolerance) in fixed.chain(adaptive) {
                            let mut s = scene.clone();
                            s.load.steps = steps;
                            s.load.tolerance = tolerance;
                            s.solver.mode = mode;
                            s.solver.stepping = stepping;
                            s.solver.precision = precision;
                            s.solver.backend = backend;
                            s.ffm.fibers = fibers;
                            apply_calibration(&mut s, calibrations);
                            match skip_reason(&s, grid, n) {
                                Some(why) => skipped.push((config_of(&s), why)),
                                None => configs.push(s),
                            }
                        }
                    }
                }
            }
        }
    }
    (configs, skipped)
}

/// Why a grid point is not run, if it is not.
fn skip_reason(s: &Scene, grid: &Grid, n: usize) -> Option<String> {
    let (mode, backend) = (s.solver.mode, s.solver.backend);
    let costly = s.load.tolerance.is_some() || s.load.steps > grid.dense_refactor_max_steps;
    if s.ffm.fibers == FiberModel::Projected {
        if s.solver.precision != Precision::F64 {
            return Some("projected fibers factor in f64 only".into());
        }
        if backend != grid.backends[0] {
            return Some("projected fibers have their own coupled solver (one backend's row)".into());
        }
        if mode == Mode::Nonlinear && n > grid.dense_refactor_vertex_limit && costly {
            return Some(format!(
                "a dense 3N x 3N refactorization per step at N = {n} costs too much beyond {} steps",
                grid.dense_refactor_max_steps
            ));
        }
        return None;
    }
    if backend.is_dense() && mode != Mode::Paper && n > grid.dense_refactor_vertex_limit && costly {
        return Some(format!(
            "a dense refactorization per step at N = {n} costs too much beyond {} steps",
            grid.dense_refactor_max_steps
        ));
    }
    None
}

/// The scene with its fibers calibrated once (when it gave only `[tissue]`), the FEM
/// reference at `grid.fem_reference`, the FEM at `grid.fem_resolutions` and, with
/// `grab`, the grab comparison (the paper's fibers are then calibrated too, for its FFM body).
fn physical_axis(scene: &Scene, grid: &Grid) -> crate::Result<(Scene, PhysicalAxis)> {
    let (fibers, grab) = (&grid.fibers, grid.grab);
    let mut calibrated = scene.clone();
    let mut calibrations = Vec::new();
    let grab = grab && crate::grab::applies(scene);
    if scene.ffm.calibrate {
        let paper = grab.then_some(&FiberModel::Paper);
        for &f in fibers.iter().chain([&scene.ffm.fibers]).chain(paper) {
            if calibrations.iter().any(|c: &fibfluid::sim::calibration::Calibration| c.fibers == f) {
                continue;
            }
            let mut m = scene.clone();
            m.ffm.fibers = f;
            calibrations.push(fibfluid::sim::calibration::calibrate(&m, None)?);
        }
        calibrated.ffm.calibrate = false;
        apply_calibration(&mut calibrated, &calibrations);
    }
    // `linearized`: the small-strain law in place of the scene's.
    let fem_run = |resolution: usize, linearized: bool| -> crate::Result<fibfluid::sim::fem_run::FemRun> {
        let mut m: fibfluid::sim::Model = scene.model.clone();
        m.solver.method = fibfluid::Method::Fem;
        m.fem.resolution = resolution;
        if linearized {
            m.tissue = m.tissue.map(|t| t.linearized());
            m.fem.auto_model = false;
        }
        Ok(fibfluid::sim::fem_run::FemRun::new(m, None)?)
    };
    let reference_run = fem_run(grid.fem_reference, false)?;
    let reference_law = reference_run.tissue.law().name();
    let reference: Vec<_> =
        fibfluid::sim::calibration::displacements(&reference_run.positions, &reference_run.rest);
    let point = |linearized: bool, r: usize| -> crate::Result<FemPoint> {
        let run = fem_run(r, linearized)?;
        Ok(FemPoint {
            resolution: r,
            dofs: run.stats.dofs,
            seconds: run.seconds,
            error_vs_fem: relative_l2(&run.positions, &run.rest, &reference),
        })
    };
    let fem = grid.fem_resolutions.iter().map(|&r| point(false, r)).collect::<crate::Result<Vec<_>>>()?;
    let linear_fem = if !reference_run.tissue.is_linear() {
        grid.fem_resolutions.iter().map(|&r| point(true, r)).collect::<crate::Result<_>>()?
    } else {
        Vec::new()
    };
    let grab = if grab { Some(crate::grab::grab_comparison(scene, &calibrations)?) } else { None };
    Ok((
        calibrated,
        PhysicalAxis {
            reference_resolution: grid.fem_reference,
            reference,
            fem,
            reference_law,
            linear_fem,
            calibrations,
            grab,
        },
    ))
}

/// Sets the scene's fiber modulus from the calibration of its fiber model, if any.
fn apply_calibration(s: &mut Scene, calibrations: &[fibfluid::sim::calibration::Calibration]) {
    if let Some(c) = calibrations.iter().find(|c| c.fibers == s.ffm.fibers) {
        c.apply(&mut s.material).expect("a calibration's fibers are in range (positive modulus)");
    }
}

/// `|(positions - rest) - reference| / |reference|` over the surface vertices.
fn relative_l2(positions: &[[f64; 3]], rest: &[[f64; 3]], reference: &[[f64; 3]]) -> f64 {
    let u = fibfluid::sim::calibration::displacements(positions, rest);
    fibfluid::sim::calibration::relative_l2(&u, reference)
}

/// A round trip timed as the fastest of a few repeats (at most [`MAX_REPEATS`], until
/// [`REPEAT_BUDGET`] seconds were spent), so that millisecond runs are not dominated by
/// scheduler noise.
fn timed_roundtrip(scene: Scene) -> crate::Result<RoundTrip> {
    let mut best = roundtrip(scene.clone(), &RunOptions::default())?;
    let mut spent = best.seconds;
    let mut repeats = 1;
    while repeats < MAX_REPEATS && spent < REPEAT_BUDGET {
        let again = roundtrip(scene.clone(), &RunOptions::default())?;
        spent += again.seconds;
        repeats += 1;
        if again.seconds < best.seconds {
            best.seconds = again.seconds;
        }
        best.compress_seconds = best.compress_seconds.min(again.compress_seconds);
    }
    Ok(best)
}

/// Most repeats of one configuration.
pub const MAX_REPEATS: usize = 5;
/// Repeats stop once this many seconds were spent on a configuration.
pub const REPEAT_BUDGET: f64 = 0.2;

fn config_of(s: &Scene) -> Config {
    Config {
        mode: s.solver.mode,
        stepping: s.solver.stepping,
        steps: s.load.steps,
        tolerance: s.load.tolerance,
        precision: s.solver.precision,
        backend: s.solver.backend,
        fibers: s.ffm.fibers,
    }
}

fn point_of(mut config: Config, rt: &RoundTrip, reference: &RoundTrip, n: usize, diag: f64) -> Point {
    if config.tolerance.is_some() {
        config.steps = rt.steps_taken;
    }
    let dist: f64 = rt
        .compressed
        .iter()
        .zip(&reference.compressed)
        .map(|(a, b)| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt())
        .sum();
    Point {
        config,
        roundtrip_error: Some(rt.roundtrip_error),
        volume_drift: Some(rt.volume_drift),
        reference_distance: Some(dist / (n as f64 * diag)),
        residual_max: Some(rt.residual_max),
        factorizations: Some(rt.factorizations),
        seconds: Some(rt.seconds),
        run_seconds: Some(rt.compress_seconds),
        error_vs_fem: None,
        error: None,
    }
}

/// The measured columns of a point, formatted by `num` (missing values by `missing`).
fn measured_cells(p: &Point, num: impl Fn(f64) -> String, missing: &str) -> Vec<String> {
    let f = |v: Option<f64>| v.map(&num).unwrap_or_else(|| missing.to_string());
    let c = &p.config;
    vec![
        c.mode.to_string(),
        c.stepping_label(),
        c.steps.to_string(),
        c.tolerance.map(|t| format!("{t:e}")).unwrap_or_default(),
        c.precision.to_string(),
        c.backend.to_string(),
        f(p.roundtrip_error),
        f(p.volume_drift),
        f(p.reference_distance),
        f(p.residual_max),
        p.factorizations.map(|v| v.to_string()).unwrap_or_else(|| missing.to_string()),
    ]
}

/// A sentence naming the points whose round-trip error, distance to the reference or
/// difference from the FEM cannot be drawn on the log charts (not finite, or beyond 1e100:
/// the run diverged); empty when every point can.
fn off_chart_note(study: &Study) -> String {
    let off: Vec<String> = study
        .points
        .iter()
        .filter(|p| {
            [p.roundtrip_error, p.reference_distance, p.error_vs_fem]
                .iter()
                .flatten()
                .any(|&e| !log_drawable(e) && e != 0.0)
        })
        .map(|p| format!("{} {} steps {}", p.config.fibers_label(), p.config.steps, p.config.precision))
        .collect();
    if off.is_empty() {
        return String::new();
    }
    format!(
        "Off the charts (an error not finite or beyond 1e100: the run diverged; its numbers are in the tables): {}.\n\n",
        off.join("; ")
    )
}

/// The study as CSV (one row per point).
pub fn to_csv(study: &Study) -> String {
    let mut out = String::from(
        "fibers,mode,stepping,steps,tolerance,precision,backend,roundtrip_error,volume_drift,reference_distance,residual_max,factorizations,seconds,run_seconds,error_vs_fem,error\n",
    );
    for p in &study.points {
        let mut cells = vec![p.config.fibers.to_string()];
        cells.extend(measured_cells(p, |x| format!("{x:e}"), ""));
        cells.push(p.seconds.map(|x| format!("{x:e}")).unwrap_or_default());
        cells.push(p.run_seconds.map(|x| format!("{x:e}")).unwrap_or_default());
        cells.push(p.error_vs_fem.map(|x| format!("{x:e}")).unwrap_or_default());
        cells.push(p.error.as_deref().unwrap_or("").replace(',', ";").replace('\n', " "));
        out.push_str(&cells.join(","));
        out.push('\n');
    }
    out
}

/// Indices of the points on the Pareto front of (seconds, error) for an error measure
/// (failed points and zero errors left out; see [`PARETO_MARGIN`]).
pub fn pareto(study: &Study, error: impl Fn(&Point) -> Option<f64>) -> Vec<usize> {
    let idx: Vec<usize> = (0..study.points.len())
        .filter(|&i| study.points[i].seconds.is_some() && error(&study.points[i]).is_some_and(log_drawable))
        .collect();
    let xy: Vec<(f64, f64)> = idx
        .iter()
        .map(|&i| (study.points[i].seconds.unwrap_or(0.0), error(&study.points[i]).unwrap_or(f64::INFINITY)))
        .collect();
    fibfluid::render::pareto_front_with_margin(&xy, PARETO_MARGIN).into_iter().map(|k| idx[k]).collect()
}

/// The study as a Markdown table, Pareto points marked.
pub fn to_markdown(study: &Study, title: &str) -> String {
    let front = pareto(study, |p| p.roundtrip_error);
    let mut out = format!(
        "### {title}\n\nReference: {} {} {} steps {} {}. `*` marks the Pareto front of round-trip error against time.\n\n",
        study.reference.mode,
        study.reference.stepping,
        study.reference.steps,
        study.reference.precision,
        study.reference.backend
    );
    out.push_str(&off_chart_note(study));
    out.push_str("| fibers | mode | stepping | steps | tolerance | precision | backend | round-trip error | volume drift | distance to reference | residual | factorizations | seconds | |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (i, p) in study.points.iter().enumerate() {
        let mut cells = vec![p.config.fibers.to_string()];
        cells.extend(measured_cells(p, |x| format!("{x:.2e}"), "—"));
        cells.push(p.seconds.map(|s| format!("{s:.4}")).unwrap_or_else(|| "—".into()));
        cells.push(if front.contains(&i) {
            "*".to_string()
        } else {
            p.error.clone().map(|e| format!("failed: {e}")).unwrap_or_default()
        });
        out.push_str(&format!("| {} |\n", cells.join(" | ")));
    }
    for (c, why) in &study.skipped {
        out.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {} | skipped: {why} |||||||\n",
            c.fibers,
            c.mode,
            c.stepping_label(),
            c.steps,
            c.tolerance.map(|t| format!("{t:e}")).unwrap_or_default(),
            c.precision,
            c.backend
        ));
    }
    // After the skipped rows, which belong to the table above.
    if let Some(axis) = &study.physical {
        out.push_str(&physical_markdown(study, axis));
        if let Some(g) = &axis.grab {
            out.push_str(&crate::grab::to_markdown(g));
        }
    }
    out
}

/// Log–log chart of an error measure against seconds: one line per (mode, stepping) with
/// the given precision and backend, across step counts; the Pareto front of *all* points
/// of the study marked. Returns PNG bytes.
pub fn chart(
    study: &Study,
    title: &str,
    y_label: &str,
    error: impl Fn(&Point) -> Option<f64> + Copy,
    precision: Precision,
    backend: Backend,
) -> crate::Result<Vec<u8>> {
    let mut series: Vec<fibfluid::render::Series> = Vec::new();
    for p in study.points.iter().filter(|p| p.config.precision == precision && p.config.backend == backend) {
        let (Some(t), Some(e)) = (p.seconds, error(p)) else { continue };
        if !(log_drawable(e) && log_drawable(t)) {
            continue;
        }
        let label = format!("{} ({precision}, {backend})", p.config.fibers_label());
        match series.iter_mut().find(|s| s.label == label) {
            Some(s) => s.points.push((t, e)),
            None => series.push(fibfluid::render::Series { label, points: vec![(t, e)] }),
        }
    }
    let front: Vec<(f64, f64)> = pareto(study, error)
        .into_iter()
        .map(|i| (study.points[i].seconds.unwrap_or(0.0), error(&study.points[i]).unwrap_or(0.0)))
        .collect();
    for s in &mut series {
        s.points.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
    Ok(fibfluid::render::loglog_chart(
        title,
        "seconds (round trip, fastest of repeats)",
        y_label,
        &series,
        &front,
        1200,
        800,
    )?)
}

/// The physical axis as Markdown: the FEM's convergence, then each FFM configuration's
/// difference from the FEM reference beside the time of a plain run, Pareto points marked.
fn physical_markdown(study: &Study, axis: &PhysicalAxis) -> String {
    let mut out = format!(
        "\n#### Against the FEM (reference: {} FEM, resolution {})\n\n",
        axis.reference_law, axis.reference_resolution
    );
    for c in &axis.calibrations {
        out.push_str(&format!(
            "The scene gives only `[tissue]`: {} fibers' modulus calibrated once against the FEM at resolution {} (scale {:.3}, fiber modulus {:.4e}, shape error {:.3}).\n\n",
            c.fibers, c.fem_resolution, c.scale, c.fiber_modulus, c.error_vs_fem
        ));
    }
    out.push_str(
        "| FEM resolution | unknowns | seconds | difference from the reference |\n|---|---|---|---|\n",
    );
    for f in &axis.fem {
        out.push_str(&format!(
            "| {} | {} | {:.3} | {:.3} |\n",
            f.resolution, f.dofs, f.seconds, f.error_vs_fem
        ));
    }
    if !axis.linear_fem.is_empty() {
        out.push_str(
            "\nThe linear (small-strain) FEM against the same neo-Hookean reference:\n\n| FEM resolution | seconds | difference from the reference |\n|---|---|---|\n",
        );
        for f in &axis.linear_fem {
            out.push_str(&format!("| {} | {:.3} | {:.3} |\n", f.resolution, f.seconds, f.error_vs_fem));
        }
    }
    let front = physical_front(study);
    out.push_str("\n| fibers | mode | stepping | steps | precision | backend | seconds (one run) | difference from the FEM | |\n|---|---|---|---|---|---|---|---|---|\n");
    for (i, p) in study.points.iter().enumerate() {
        let (Some(t), Some(e)) = (p.run_seconds, p.error_vs_fem) else { continue };
        let c = &p.config;
        let mark = if front.contains(&i) { "*" } else { "" };
        out.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {t:.4} | {e:.3} | {mark} |\n",
            c.fibers,
            c.mode,
            c.stepping_label(),
            c.steps,
            c.precision,
            c.backend
        ));
    }
    out
}

/// Indices of the FFM points on the Pareto front of (one run's seconds, difference from the
/// FEM).
pub fn physical_front(study: &Study) -> Vec<usize> {
    let idx: Vec<usize> = (0..study.points.len())
        .filter(|&i| {
            study.points[i].run_seconds.is_some() && study.points[i].error_vs_fem.is_some_and(log_drawable)
        })
        .collect();
    let xy: Vec<(f64, f64)> = idx
        .iter()
        .map(|&i| {
            (
                study.points[i].run_seconds.unwrap_or(0.0),
                study.points[i].error_vs_fem.unwrap_or(f64::INFINITY),
            )
        })
        .collect();
    fibfluid::render::pareto_front_with_margin(&xy, PARETO_MARGIN).into_iter().map(|k| idx[k]).collect()
}

/// Log-log chart of the difference from the FEM against the time of one run: one line per
/// (mode, stepping) of the structured f64 FFM points across step counts, one line for the
/// FEM across resolutions; the Pareto front of every point (FFM and FEM) marked. `None`
/// without a physical axis.
pub fn physical_chart(study: &Study, title: &str) -> crate::Result<Option<Vec<u8>>> {
    let Some(axis) = &study.physical else { return Ok(None) };
    let mut series: Vec<fibfluid::render::Series> = Vec::new();
    let mut all: Vec<(f64, f64)> = Vec::new();
    for p in &study.points {
        let (Some(t), Some(e)) = (p.run_seconds, p.error_vs_fem) else { continue };
        if !(log_drawable(t) && log_drawable(e)) {
            continue;
        }
        all.push((t, e));
        if p.config.precision != Precision::F64 || p.config.backend != Backend::Structured {
            continue;
        }
        let label = p.config.fibers_label();
        match series.iter_mut().find(|s| s.label == label) {
            Some(s) => s.points.push((t, e)),
            None => series.push(fibfluid::render::Series { label, points: vec![(t, e)] }),
        }
    }
    let fem: Vec<(f64, f64)> = axis
        .fem
        .iter()
        .filter(|f| log_drawable(f.seconds) && log_drawable(f.error_vs_fem))
        .map(|f| (f.seconds, f.error_vs_fem))
        .collect();
    all.extend(&fem);
    let resolutions: Vec<usize> = axis.fem.iter().map(|f| f.resolution).collect();
    series.push(fibfluid::render::Series {
        label: format!("fem {}, resolution {resolutions:?}", axis.reference_law),
        points: fem,
    });
    let linear: Vec<(f64, f64)> = axis
        .linear_fem
        .iter()
        .filter(|f| log_drawable(f.seconds) && log_drawable(f.error_vs_fem))
        .map(|f| (f.seconds, f.error_vs_fem))
        .collect();
    if !linear.is_empty() {
        all.extend(&linear);
        series
            .push(fibfluid::render::Series { label: "fem linear, same resolutions".into(), points: linear });
    }
    for s in &mut series {
        s.points.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
    let front: Vec<(f64, f64)> =
        fibfluid::render::pareto_front_with_margin(&all, PARETO_MARGIN).into_iter().map(|k| all[k]).collect();
    Ok(Some(fibfluid::render::loglog_chart(
        title,
        "seconds (one run: setup and solve)",
        &format!("relative L2 difference from the FEM at resolution {}", axis.reference_resolution),
        &series,
        &front,
        1200,
        800,
    )?))
}
