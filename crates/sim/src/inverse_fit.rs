//! The fit of `[fit]`: Levenberg–Marquardt in the parameters' logarithms, clamped to their
//! bounds, on the residual `x_model(v) - x_observed(v)` of the observed vertices; the
//! Jacobian is the forward sensitivities of each converged equilibrium
//! ([`fibfluid_fem::hyper::HyperBody::sensitivities`]): one Newton solve and one
//! sensitivity solve per parameter per iteration. The answer's uncertainty is the
//! Gauss–Newton covariance `s^2 (J^T J)^-1` with `s^2` the residual's variance
//! (`|r|^2 / (3 m - n)`); a parameter the observations cannot see (a doubling would move them
//! by less than [`IDENTIFIABLE`] of their observed displacement) is reported as not
//! identifiable, without a value.

use fibfluid_fem::Loads;
use fibfluid_fem::hyper::{HyperBody, HyperSolution, Parameter};
use fibfluid_geometry::Vec3;
use fibfluid_geometry::vec3::add;
use serde::Serialize;

use crate::fem_inputs::{full_loads, tissue_of};
use crate::inverse::{FitSpec, Observation, parameter_value, set_parameter};
use crate::model::Model;
use crate::stages::StageLog;
use crate::{Error, Result};

/// Levenberg–Marquardt iterations at most.
pub const MAX_FIT_ITERATIONS: usize = 60;
/// The fit has converged when an accepted step changes no parameter's logarithm by more.
pub const FIT_STEP_TOLERANCE: f64 = 1e-7;
/// A parameter whose doubling would move the observed vertices (RMS, linearized) by less
/// than this fraction of their observed displacement (RMS) is not identifiable.
pub const IDENTIFIABLE: f64 = 1e-3;
/// The damping's bounds (relative to the diagonal of `J^T J`).
const DAMPING: [f64; 2] = [1e-9, 1e9];

/// One iteration's state, for progress.
#[derive(Clone, Debug, PartialEq)]
pub struct FitProgress {
    /// The iteration (1-based).
    pub iteration: usize,
    /// RMS distance of the model's vertices from the observed ones (m).
    pub rms: f64,
    /// `rms` relative to the observed displacement's RMS.
    pub relative: f64,
    /// The parameters now.
    pub values: Vec<f64>,
    /// The damping of the next step.
    pub damping: f64,
}

/// One parameter's answer in `fit.json`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FittedParameter {
    /// The scene's key.
    pub key: String,
    /// The value the fit started from (the scene's).
    pub start: f64,
    /// The fitted value (`None`: not identifiable).
    pub value: Option<f64>,
    /// One standard deviation of the value (Gauss–Newton; `None`: not identifiable, or too
    /// few observations).
    pub sigma: Option<f64>,
    /// Whether the observations can see the parameter ([`IDENTIFIABLE`]).
    pub identifiable: bool,
    /// Whether the value sits on a bound (its uncertainty then understates).
    pub at_bound: bool,
    /// The bounds.
    pub bounds: [f64; 2],
}

/// One observed vertex's residual at the answer (`fit.json`'s `residuals`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct VertexResidual {
    /// The vertex as the observed file numbers it (0-based, file order).
    pub vertex: usize,
    /// Its distance from the observed position, `|x_model - x_observed|` (m).
    pub distance: f64,
}

/// The fitted model's surface at the answer.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FittedSurface {
    /// Each observed vertex's residual, in the order of the observations.
    pub residuals: Vec<VertexResidual>,
    /// Every vertex's fitted position (m, mesh order; not written to `fit.json`).
    #[serde(skip)]
    pub positions: Vec<Vec3>,
}

/// What a fit found (`fit.json`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FitReport {
    /// The scene.
    pub scene: String,
    /// Each parameter, in the scene's order.
    pub parameters: Vec<FittedParameter>,
    /// The parameters' correlation (Gauss–Newton; `None` where either is not identifiable).
    pub correlation: Vec<Vec<Option<f64>>>,
    /// RMS distance of the fitted model's observed vertices from the observations (m).
    pub residual_rms: f64,
    /// `residual_rms` over the observed displacement's RMS.
    pub residual_relative: f64,
    /// The observed displacement's RMS (m).
    pub observed_rms: f64,
    /// The residual's standard deviation per coordinate the uncertainties use (m).
    pub noise_sigma: f64,
    /// Observed vertices.
    pub observations: usize,
    /// Levenberg–Marquardt iterations.
    pub iterations: usize,
    /// Newton solves (one per trial).
    pub newton_solves: usize,
    /// Sensitivity solves (one per parameter per accepted iteration).
    pub sensitivity_solves: usize,
    /// Whether the steps shrank below [`FIT_STEP_TOLERANCE`] (`false`: the iteration limit).
    pub converged: bool,
    /// The RMS residual after each iteration (m).
    pub history: Vec<f64>,
    /// The residual of each observed vertex and the fitted surface (`residuals` in
    /// `fit.json`).
    #[serde(flatten)]
    pub surface: FittedSurface,
}

/// A converged equilibrium at one set of parameters: its residual and Jacobian.
struct Point {
    /// Log-parameters.
    logs: Vec<f64>,
    residual: Vec<f64>,
    cost: f64,
    /// `d r / d ln theta`, `jacobian[j]` a column (`None` until asked).
    jacobian: Option<Vec<Vec<f64>>>,
    body: HyperBody,
    solution: HyperSolution,
    loads: Loads,
}

/// What a fit solves with: the template model, the parameters and the observations.
struct Problem<'a> {
    model: &'a Model,
    spec: &'a FitSpec,
    observed: &'a [Observation],
    limit: u64,
    newton_solves: usize,
    sensitivity_solves: usize,
}

impl Problem<'_> {
    fn parameters(&self) -> Vec<Parameter> {
        self.spec.parameters.iter().map(|p| p.parameter).collect()
    }

    /// The equilibrium at `logs` (`Ok(None)`: Newton failed there).
    fn solve(&mut self, logs: &[f64]) -> Result<Option<Point>> {
        let mut model = self.model.clone();
        for (p, l) in self.parameters().into_iter().zip(logs) {
            set_parameter(&mut model, p, l.exp())?;
        }
        let tissue = tissue_of(&model)?;
        let mut body = crate::hyper_run::build(&model, &tissue, &[], self.limit, &mut StageLog::default())?;
        let loads = full_loads(&model);
        self.newton_solves += 1;
        let solution = match body.solve(&loads, &[]) {
            Ok(s) => s,
            Err(fibfluid_fem::FemError::NotConverged { .. }) => return Ok(None),
            Err(source) => return Err(Error::Fem { scene: model.display_name(), source }),
        };
        let rest = &model.rest_positions();
        let residual: Vec<f64> = self
            .observed
            .iter()
            .flat_map(|o| {
                let u = solution.surface_displacements[o.vertex];
                (0..3).map(move |a| rest[o.vertex][a] + u[a] - o.position[a])
            })
            .collect();
        let cost = residual.iter().map(|r| r * r).sum();
        Ok(Some(Point { logs: logs.to_vec(), residual, cost, jacobian: None, body, solution, loads }))
    }

    /// Fills `point`'s Jacobian from the forward sensitivities.
    fn jacobian(&mut self, point: &mut Point) -> Result<()> {
        if point.jacobian.is_some() {
            return Ok(());
        }
        let parameters = self.parameters();
        let sens = point
            .body
            .sensitivities(&point.solution, &point.loads, &parameters)
            .map_err(|source| Error::Fem { scene: self.model.display_name(), source })?;
        self.sensitivity_solves += parameters.len();
        let columns = (0..parameters.len())
            .map(|j| {
                let theta = point.logs[j].exp();
                self.observed.iter().flat_map(|o| sens.surface[j][o.vertex].map(|d| theta * d)).collect()
            })
            .collect();
        point.jacobian = Some(columns);
        Ok(())
    }
}

/// Fits `spec`'s parameters of `model` to `observed` (see the module docs), telling
/// `progress` each iteration; `limit` is the memory limit of each solve (bytes).
///
/// Errors: a model without `[tissue]`, with plates, grasps or a timed run; the start's
/// Newton solve failing; a solve's error.
pub fn fit(
    model: &Model,
    spec: &FitSpec,
    observed: &[Observation],
    limit: u64,
    progress: &mut dyn FnMut(&FitProgress),
) -> Result<FitReport> {
    let refuse = |problem| Err(crate::fem_inputs::needs(model, problem));
    if !model.plates.is_empty() || !model.fem.grasps.is_empty() || model.fem.time.is_some() {
        return refuse("fits a static solve without [[plate]], [[grasp]] or [time]");
    }
    let mut problem = Problem { model, spec, observed, limit, newton_solves: 0, sensitivity_solves: 0 };
    let start: Vec<f64> =
        problem.parameters().iter().map(|&p| parameter_value(model, p).unwrap_or(f64::NAN)).collect();
    let logs: Vec<f64> = start.iter().map(|v| v.ln()).collect();
    let Some(mut point) = problem.solve(&logs)? else {
        return refuse("the start's Newton solve did not converge: start from other values");
    };
    let rest = &model.rest_positions();
    let observed_rms = rms(&observed
        .iter()
        .flat_map(|o| (0..3).map(move |a| o.position[a] - rest[o.vertex][a]))
        .collect::<Vec<_>>());
    let lower: Vec<f64> = spec.bounds.iter().map(|b| b[0].ln()).collect();
    let upper: Vec<f64> = spec.bounds.iter().map(|b| b[1].ln()).collect();
    let (mut damping, mut converged, mut history) = (1e-3, false, Vec::new());
    let mut iterations = 0;
    while iterations < MAX_FIT_ITERATIONS && !converged && point.cost > 0.0 {
        iterations += 1;
        problem.jacobian(&mut point)?;
        let columns = point.jacobian.as_ref().expect("filled above");
        let step = damped_step(columns, &point.residual, damping);
        let trial: Vec<f64> =
            (0..step.len()).map(|j| (point.logs[j] + step[j]).clamp(lower[j], upper[j])).collect();
        let moved = trial.iter().zip(&point.logs).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        match problem.solve(&trial)? {
            Some(next) if next.cost <= point.cost => {
                point = next;
                damping = (damping / 3.0).max(DAMPING[0]);
                converged = moved < FIT_STEP_TOLERANCE;
            }
            _ => {
                damping *= 4.0;
                converged = moved < FIT_STEP_TOLERANCE || damping > DAMPING[1];
            }
        }
        let now = rms(&point.residual);
        history.push(now);
        progress(&FitProgress {
            iteration: iterations,
            rms: now,
            relative: now / observed_rms,
            values: point.logs.iter().map(|l| l.exp()).collect(),
            damping,
        });
    }
    problem.jacobian(&mut point)?;
    let surface = FittedSurface {
        residuals: observed
            .iter()
            .zip(point.residual.chunks_exact(3))
            .map(|(o, r)| VertexResidual { vertex: o.file_vertex, distance: dot(r, r).sqrt() })
            .collect(),
        positions: rest.iter().zip(&point.solution.surface_displacements).map(|(x, u)| add(*x, *u)).collect(),
    };
    let residual_rms = rms(&point.residual);
    let stats = Statistics::of(point.jacobian.as_ref().expect("filled above"), point.cost, observed_rms);
    let parameters = spec
        .parameters
        .iter()
        .enumerate()
        .map(|(j, p)| {
            let value = point.logs[j].exp();
            let identifiable = stats.identifiable[j];
            FittedParameter {
                key: p.key.clone(),
                start: start[j],
                value: identifiable.then_some(value),
                sigma: stats.log_sigma[j].map(|s| s * value),
                identifiable,
                at_bound: point.logs[j] <= lower[j] || point.logs[j] >= upper[j],
                bounds: spec.bounds[j],
            }
        })
        .collect();
    Ok(FitReport {
        scene: model.display_name(),
        parameters,
        correlation: stats.correlation,
        residual_rms,
        residual_relative: residual_rms / observed_rms,
        observed_rms,
        noise_sigma: stats.noise_sigma,
        observations: observed.len(),
        iterations,
        newton_solves: problem.newton_solves,
        sensitivity_solves: problem.sensitivity_solves,
        converged: converged || point.cost == 0.0,
        history,
        surface,
    })
}

/// The root mean square of `v`.
fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

/// Marquardt's step: `(J^T J + damping diag(J^T J)) d = -J^T r`.
fn damped_step(columns: &[Vec<f64>], residual: &[f64], damping: f64) -> Vec<f64> {
    let n = columns.len();
    let mut a = normal_matrix(columns);
    let largest = (0..n).map(|j| a[j][j]).fold(0.0, f64::max);
    for (j, row) in a.iter_mut().enumerate() {
        row[j] += damping * row[j] + 1e-14 * largest;
    }
    let b: Vec<f64> = columns.iter().map(|c| -dot(c, residual)).collect();
    solve_dense(a, b).unwrap_or_else(|| vec![0.0; n])
}

/// `J^T J` of the columns.
fn normal_matrix(columns: &[Vec<f64>]) -> Vec<Vec<f64>> {
    columns.iter().map(|ci| columns.iter().map(|cj| dot(ci, cj)).collect()).collect()
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Solves the small system `a x = b` by Gaussian elimination with partial pivoting
/// (`None`: singular).
fn solve_dense(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Option<Vec<f64>> {
    let n = b.len();
    for k in 0..n {
        let p = (k..n).max_by(|&i, &j| a[i][k].abs().total_cmp(&a[j][k].abs()))?;
        if !(a[p][k].abs() > 0.0) {
            return None;
        }
        a.swap(k, p);
        b.swap(k, p);
        for i in k + 1..n {
            let f = a[i][k] / a[k][k];
            for j in k..n {
                a[i][j] -= f * a[k][j];
            }
            b[i] -= f * b[k];
        }
    }
    let mut x = vec![0.0; n];
    for k in (0..n).rev() {
        x[k] = (b[k] - (k + 1..n).map(|j| a[k][j] * x[j]).sum::<f64>()) / a[k][k];
    }
    Some(x)
}

/// The Gauss–Newton statistics of an answer.
struct Statistics {
    identifiable: Vec<bool>,
    /// Per parameter, one standard deviation of its logarithm.
    log_sigma: Vec<Option<f64>>,
    correlation: Vec<Vec<Option<f64>>>,
    noise_sigma: f64,
}

impl Statistics {
    /// From the Jacobian's `columns` (in log-parameters), the residual's `cost` (`|r|^2`)
    /// and the observed displacement's RMS.
    fn of(columns: &[Vec<f64>], cost: f64, observed_rms: f64) -> Self {
        let n = columns.len();
        let m = columns.first().map_or(0, Vec::len);
        let identifiable: Vec<bool> = columns
            .iter()
            .map(|c| {
                dot(c, c).sqrt() * std::f64::consts::LN_2 / (m.max(1) as f64).sqrt()
                    >= IDENTIFIABLE * observed_rms
            })
            .collect();
        let kept: Vec<usize> = (0..n).filter(|&j| identifiable[j]).collect();
        let dof = m.saturating_sub(kept.len());
        let noise_sigma = if dof > 0 { (cost / dof as f64).sqrt() } else { f64::NAN };
        let sub: Vec<Vec<f64>> = kept.iter().map(|&j| columns[j].clone()).collect();
        let a = normal_matrix(&sub);
        let k = kept.len();
        // The covariance's columns: (J^T J)^-1 e_i, scaled by s^2.
        let inverse: Option<Vec<Vec<f64>>> = (0..k)
            .map(|i| solve_dense(a.clone(), (0..k).map(|r| f64::from(u8::from(r == i))).collect()))
            .collect();
        let mut log_sigma = vec![None; n];
        let mut correlation = vec![vec![None; n]; n];
        if let (Some(inv), true) = (inverse, dof > 0) {
            for (ii, &i) in kept.iter().enumerate() {
                log_sigma[i] = Some(noise_sigma * inv[ii][ii].max(0.0).sqrt());
                for (jj, &j) in kept.iter().enumerate() {
                    correlation[i][j] = Some(inv[ii][jj] / (inv[ii][ii] * inv[jj][jj]).sqrt());
                }
            }
        }
        Self { identifiable, log_sigma, correlation, noise_sigma }
    }
}
