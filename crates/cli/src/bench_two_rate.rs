//! `fibfluid bench --two-rate SCENE --path PATH`: the two-rate neo-Hookean body against the
//! linear FEM body on the same path, frames paced at a haptic device's rate, in one run.
//!
//! Four bodies replay the path, each from its own equilibrium under the scene's loads
//! (as `compare` does), with a frame every [`FRAME_PERIOD`] (the time a frame does not use
//! is slept, as a haptic loop waits for its device): the linear FEM body, the two-rate body
//! with Newton refreshes only, with at most `fibfluid::interact::MAX_CHORD_REFRESHES` chord
//! refreshes on the kept factor between Newton's, and as shipped (chord refreshes balanced
//! in time against the refactorizations, `fibfluid::interact::ChordBudget`). The two-rate
//! bodies refresh on their second thread meanwhile. Reported, as ratios measured in the
//! same run: each two-rate body's frame p99 over the linear body's, and its mean refresh
//! over one iteration of the batch Newton solve of the body's own loads. Every
//! [`SAMPLE_EVERY`]-th frame each body's surface is kept; after the replays a body that
//! runs Newton to convergence at every sampled frame gives the reference, and each body's
//! tracking error is the largest difference of its tool-induced displacement (from its own
//! equilibrium) from the reference's, over the reference's largest.

use std::time::{Duration, Instant};

use fibfluid::Scene;
use fibfluid::geometry::Vec3;
use fibfluid::interact::{
    CheckedPath, Latency, LinearizationStatus, Method, MethodBody, ProbeOptions, RefreshMode, ToolPath,
    check_path, replay_observed,
};
use serde::Serialize;

use crate::Result;
use crate::compare_run::from_own_base;
use crate::probe_run::RefreshSummary;

/// The frame period the bench paces the bodies at (a 1 kHz haptic loop).
pub const FRAME_PERIOD: Duration = Duration::from_millis(1);

/// Frames between two samples of the tracking error.
pub const SAMPLE_EVERY: usize = 100;

/// A body's distance from the converged answer at the sampled frames: the largest
/// difference of its tool-induced displacement (from its first sample, the body's own
/// equilibrium) from the reference's, over the reference's largest along the samples.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Tracking {
    /// Mean over the samples.
    pub mean: f64,
    /// Largest over the samples.
    pub largest: f64,
    /// At the last sample.
    pub last: f64,
}

/// One two-rate body's replay.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TwoRateRun {
    /// The chord refreshes allowed between two refactorizations: `"none"` (Newton only),
    /// `"at most N"` or `"balanced"` (`fibfluid::interact::ChordBudget`).
    pub chords: String,
    /// Frame latency, refreshes running (us).
    pub latency_us: Latency,
    /// Frame p99 over the linear body's frame p99.
    pub frame_p99_ratio: f64,
    /// Refreshes swapped in.
    pub refreshes: u64,
    /// Those that factored the tangent (the others kept the factor: chord refreshes).
    pub refactorizations: u64,
    /// Refreshes per second over the replay (the thread idles once Newton has converged
    /// for holds that stay still).
    pub refresh_hz: f64,
    /// Refreshes per second while the thread runs them back to back (one over the mean
    /// refresh).
    pub running_hz: f64,
    /// Mean seconds of one refresh.
    pub refresh_seconds: f64,
    /// Mean seconds of one chord refresh (0: none).
    pub chord_seconds: f64,
    /// Mean seconds of one refresh that factored the tangent (0: none).
    pub refactor_seconds: f64,
    /// Mean refresh over one batch Newton iteration.
    pub refresh_ratio: f64,
    /// Refreshes that failed.
    pub failures: usize,
    /// Why the first failed refresh failed.
    pub first_failure: Option<String>,
    /// Distance from the converged answer.
    pub tracking: Tracking,
}

/// What `bench --two-rate` measures.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TwoRateBench {
    /// Frames replayed per body.
    pub frames: usize,
    /// Frames sampled for the tracking error.
    pub samples: usize,
    /// The linear FEM body's frame latency (us).
    pub linear_latency_us: Latency,
    /// The linear FEM body's distance from the converged neo-Hookean answer.
    pub linear_tracking: Tracking,
    /// Seconds of one Newton iteration of the batch solve (the body's own loads).
    pub newton_iteration_seconds: f64,
    /// The two-rate body with Newton refreshes only.
    pub newton_only: TwoRateRun,
    /// The two-rate body with at most `fibfluid::interact::MAX_CHORD_REFRESHES` chord
    /// refreshes between two refactorizations.
    pub fixed_chords: TwoRateRun,
    /// The two-rate body as shipped (balanced chord refreshes).
    pub two_rate: TwoRateRun,
}

/// A replay's sampled surfaces and frame latencies.
struct Paced {
    samples: Vec<Vec<Vec3>>,
    latency_us: Vec<f64>,
    statuses: Vec<LinearizationStatus>,
    /// Wall seconds of the replay.
    seconds: f64,
}

/// Replays `path` on `scene` (a neo-Hookean tissue) with the linear and the two two-rate
/// FEM bodies, frames paced at [`FRAME_PERIOD`], and measures each against the converged
/// answer at every [`SAMPLE_EVERY`]-th frame.
pub fn bench_two_rate(scene: &Scene, path: &ToolPath, max_memory: Option<u64>) -> Result<TwoRateBench> {
    let nonlinear = scene.tissue.is_some_and(|t| !t.is_linear());
    if !nonlinear {
        return Err(fibfluid::sim::Error::MethodNeeds {
            scene: scene.display_name(),
            method: Method::Fem,
            problem: "has no two-rate body to bench: set [tissue] model = \"neo-hookean\"",
        }
        .into());
    }
    let checked = check_path(path, scene)?;
    let mut linear_scene = scene.clone();
    linear_scene.model.tissue = linear_scene.model.tissue.map(|t| t.linearized());
    let opts = |refresh, chords| ProbeOptions {
        max_memory_bytes: max_memory,
        refresh,
        chord_refreshes: chords,
        ..Default::default()
    };
    let background = |chords| opts(RefreshMode::Background, chords);
    let (linear, _) = paced_replay(&linear_scene, &checked, &background(None))?;
    let (newton_only, newton_iteration_seconds) = paced_replay(scene, &checked, &background(Some(0)))?;
    let fixed = fibfluid::interact::MAX_CHORD_REFRESHES;
    let (fixed_chords, _) = paced_replay(scene, &checked, &background(Some(fixed)))?;
    let (two_rate, _) = paced_replay(scene, &checked, &background(None))?;
    let reference = converged_samples(scene, &checked, &opts(RefreshMode::Converged, Some(0)))?;
    let linear_latency_us = Latency::of(&linear.latency_us);
    let run = |paced: &Paced, chords: String| {
        let summary = RefreshSummary::of(&paced.statuses);
        let latency_us = Latency::of(&paced.latency_us);
        TwoRateRun {
            chords,
            frame_p99_ratio: latency_us.p99 / linear_latency_us.p99,
            latency_us,
            refreshes: summary.refreshes,
            refactorizations: summary.refactorizations,
            refresh_hz: summary.refreshes as f64 / paced.seconds,
            running_hz: if summary.refresh_seconds > 0.0 { 1.0 / summary.refresh_seconds } else { 0.0 },
            refresh_seconds: summary.refresh_seconds,
            chord_seconds: summary.chord_seconds,
            refactor_seconds: summary.refactor_seconds,
            refresh_ratio: summary.refresh_seconds / newton_iteration_seconds,
            failures: summary.failures,
            first_failure: summary.first_failure,
            tracking: tracking(&paced.samples, &reference),
        }
    };
    Ok(TwoRateBench {
        frames: linear.latency_us.len(),
        samples: reference.len(),
        linear_tracking: tracking(&linear.samples, &reference),
        linear_latency_us,
        newton_iteration_seconds,
        newton_only: run(&newton_only, "none".into()),
        fixed_chords: run(&fixed_chords, format!("at most {fixed}")),
        two_rate: run(&two_rate, "balanced".into()),
    })
}

/// Builds `scene`'s FEM body with `opts` and replays `checked` from the body's own
/// equilibrium, paced; returns the replay and the body's batch Newton iteration (s; 0 for
/// the linear body).
fn paced_replay(scene: &Scene, checked: &CheckedPath, opts: &ProbeOptions) -> Result<(Paced, f64)> {
    let mut body = MethodBody::build(scene, &scene.chainmail, Method::Fem, opts)?;
    let newton_iteration_seconds = match &body {
        MethodBody::Hyper(b) => b.newton_iteration_seconds(),
        _ => 0.0,
    };
    let own = own_base(&body, checked);
    let (mut samples, mut statuses) = (Vec::new(), Vec::new());
    let start = Instant::now();
    let replay = replay_observed(body.interactive(), &own, |k, b| {
        statuses.extend(b.linearization());
        if k % SAMPLE_EVERY == 0 {
            samples.push(b.positions().to_vec());
        }
        if let Some(wait) = (FRAME_PERIOD * (k as u32 + 1)).checked_sub(start.elapsed()) {
            std::thread::sleep(wait);
        }
    })?;
    let seconds = start.elapsed().as_secs_f64();
    Ok((Paced { samples, latency_us: replay.latency_us, statuses, seconds }, newton_iteration_seconds))
}

/// `checked` taken from `body`'s own equilibrium (the grasps' origin, the grabs' offsets).
fn own_base(body: &MethodBody, checked: &CheckedPath) -> CheckedPath {
    let b = body.interactive_ref();
    from_own_base(checked, b.positions(), b.rest_positions())
}

/// The converged answer's surface at every [`SAMPLE_EVERY`]-th frame of `checked`: a body
/// that runs Newton to convergence at every frame, replaying those frames only (the
/// converged answer depends on the frame's holds alone).
fn converged_samples(scene: &Scene, checked: &CheckedPath, opts: &ProbeOptions) -> Result<Vec<Vec<Vec3>>> {
    let mut body = MethodBody::build(scene, &scene.chainmail, Method::Fem, opts)?;
    let mut sampled = own_base(&body, checked);
    sampled.frames = sampled.frames.into_iter().step_by(SAMPLE_EVERY).collect();
    sampled.tips = sampled.tips.into_iter().step_by(SAMPLE_EVERY).collect();
    let mut samples = Vec::new();
    replay_observed(body.interactive(), &sampled, |_, b| samples.push(b.positions().to_vec()))?;
    Ok(samples)
}

/// `samples`' distance from `reference` (see [`Tracking`]).
fn tracking(samples: &[Vec<Vec3>], reference: &[Vec<Vec3>]) -> Tracking {
    use fibfluid::geometry::vec3::{norm, sub};
    let (Some(own), Some(base)) = (samples.first(), reference.first()) else { return Tracking::default() };
    let tool =
        |s: &[Vec3], at: &[Vec3]| -> Vec<Vec3> { s.iter().zip(at).map(|(p, q)| sub(*p, *q)).collect() };
    let largest =
        |a: &[Vec3], b: &[Vec3]| a.iter().zip(b).map(|(p, q)| norm(sub(*p, *q))).fold(0.0, f64::max);
    let scale = reference.iter().map(|r| largest(r, base)).fold(0.0, f64::max).max(f64::MIN_POSITIVE);
    let errors: Vec<f64> =
        samples.iter().zip(reference).map(|(s, r)| largest(&tool(s, own), &tool(r, base)) / scale).collect();
    Tracking {
        mean: errors.iter().sum::<f64>() / errors.len().max(1) as f64,
        largest: errors.iter().copied().fold(0.0, f64::max),
        last: errors.last().copied().unwrap_or(0.0),
    }
}
