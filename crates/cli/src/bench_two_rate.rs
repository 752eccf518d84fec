//! `fibfluid bench --two-rate SCENE --path PATH`: the two-rate neo-Hookean body against the
//! linear FEM body on the same path, frames paced at a haptic device's rate, in one run.
//!
//! Both bodies replay the path with a frame every [`FRAME_PERIOD`] (the time a frame does
//! not use is slept, as a haptic loop waits for its device). The two-rate body refreshes
//! on its second thread meanwhile. Reported, as ratios measured in the same run: the
//! frame p99 of the two-rate body over the linear body's, and the mean refresh (one
//! Newton iteration: the step, the tangent's assembly and factorization, the held
//! vertices' columns) over one iteration of the batch Newton solve of the body's own loads.

use std::time::{Duration, Instant};

use fibfluid::Scene;
use fibfluid::fem::TissueModel;
use fibfluid::interact::{
    Latency, LinearizationStatus, Method, MethodBody, ProbeOptions, RefreshMode, ToolPath, check_path,
    replay_observed,
};
use serde::Serialize;

use crate::Result;
use crate::probe_run::RefreshSummary;

/// The frame period the bench paces both bodies at (a 1 kHz haptic loop).
pub const FRAME_PERIOD: Duration = Duration::from_millis(1);

/// What `bench --two-rate` measures.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TwoRateBench {
    /// Frames replayed per body.
    pub frames: usize,
    /// The linear FEM body's frame latency (us).
    pub linear_latency_us: Latency,
    /// The two-rate body's frame latency, refreshes running (us).
    pub two_rate_latency_us: Latency,
    /// Two-rate frame p99 over the linear frame p99.
    pub frame_p99_ratio: f64,
    /// Refreshes the two-rate body swapped in.
    pub refreshes: u64,
    /// Refreshes per second over the two-rate replay.
    pub refresh_hz: f64,
    /// Mean seconds of one refresh.
    pub refresh_seconds: f64,
    /// Seconds of one Newton iteration of the batch solve (the body's own loads).
    pub newton_iteration_seconds: f64,
    /// Mean refresh over one batch Newton iteration.
    pub refresh_ratio: f64,
    /// Refreshes that failed.
    pub failures: usize,
    /// Why the first failed refresh failed.
    pub first_failure: Option<String>,
}

/// Replays `path` on `scene` (a neo-Hookean tissue) with the linear and the two-rate FEM
/// bodies, frames paced at [`FRAME_PERIOD`].
pub fn bench_two_rate(scene: &Scene, path: &ToolPath, max_memory: Option<u64>) -> Result<TwoRateBench> {
    let nonlinear = scene.tissue.is_some_and(|t| t.model() == TissueModel::NeoHookean);
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
    linear_scene.model.tissue = linear_scene.model.tissue.map(|t| t.with_model(TissueModel::Linear));
    let opts =
        ProbeOptions { max_memory_bytes: max_memory, refresh: RefreshMode::Background, ..Default::default() };
    let mut linear = MethodBody::build(&linear_scene, &scene.chainmail, Method::Fem, &opts)?;
    let linear_replay = replay_observed(linear.interactive(), &checked, pace())?;
    let mut two_rate = MethodBody::build(scene, &scene.chainmail, Method::Fem, &opts)?;
    let MethodBody::Hyper(body) = &two_rate else {
        unreachable!("a neo-Hookean tissue builds the two-rate body")
    };
    let newton_iteration_seconds = body.newton_iteration_seconds();
    let start = Instant::now();
    let mut statuses: Vec<LinearizationStatus> = Vec::new();
    let mut paced = pace();
    let replay = replay_observed(two_rate.interactive(), &checked, |k, b| {
        statuses.extend(b.linearization());
        paced(k, b);
    })?;
    let wall = start.elapsed().as_secs_f64();
    let RefreshSummary { refreshes, refresh_seconds, failures, first_failure } =
        RefreshSummary::of(&statuses);
    let (linear_latency_us, two_rate_latency_us) =
        (Latency::of(&linear_replay.latency_us), Latency::of(&replay.latency_us));
    Ok(TwoRateBench {
        frames: replay.frames,
        frame_p99_ratio: two_rate_latency_us.p99 / linear_latency_us.p99,
        linear_latency_us,
        two_rate_latency_us,
        refreshes,
        refresh_hz: refreshes as f64 / wall,
        refresh_seconds,
        newton_iteration_seconds,
        refresh_ratio: refresh_seconds / newton_iteration_seconds,
        failures,
        first_failure,
    })
}

/// An observer that sleeps each frame out to the next [`FRAME_PERIOD`] boundary.
fn pace() -> impl FnMut(usize, &dyn fibfluid::interact::Interactive) {
    let start = Instant::now();
    move |k, _| {
        let next = FRAME_PERIOD * (k as u32 + 1);
        if let Some(wait) = next.checked_sub(start.elapsed()) {
            std::thread::sleep(wait);
        }
    }
}
