//! `[time]` and `[load] curve`: a run through time (the finite-element method only).

use fibfluid_fem::hyper::{LoadCurve, TimeSettings};
use fibfluid_sim::TimedRun;

use crate::error::SceneProblem;
use crate::invalid::{Invalid, invalid};
use crate::spec::TimeToml;

/// Outputs a run writes at most by default: `output_every` defaults to the end over this
/// (and at least the step).
const DEFAULT_OUTPUTS: f64 = 100.0;

/// `[time]` with `[load] curve`: `None` without `[time]`; a curve without `[time]` is
/// refused (it would do nothing).
pub(crate) fn timed_run(
    time: Option<TimeToml>,
    curve: Option<Vec<[f64; 2]>>,
) -> Result<Option<TimedRun>, Invalid> {
    let Some(t) = time else {
        return match curve {
            Some(_) => Err(invalid(
                "[load].curve",
                SceneProblem::Conflict("a load curve acts through time: add a [time] table (end, step)"),
            )),
            None => Ok(None),
        };
    };
    let settings = TimeSettings {
        end: t.end,
        step: t.step,
        inertia: t.inertia.unwrap_or(false),
        damping: t.damping.unwrap_or([0.0; 2]),
        output_every: t.output_every.unwrap_or((t.end / DEFAULT_OUTPUTS).max(t.step)),
    };
    settings.validate().map_err(|e| invalid("[time]", SceneProblem::Tissue(e)))?;
    let curve = match curve {
        Some(points) => LoadCurve::new(points.iter().map(|p| (p[0], p[1])).collect()),
        None => LoadCurve::ramp(settings.end),
    }
    .map_err(|e| invalid("[load].curve", SceneProblem::Tissue(e)))?;
    Ok(Some(TimedRun { settings, curve }))
}
