//! Sensitivities of a converged static equilibrium `R(u, theta) = 0` to the body's
//! parameters `theta` (each tissue's Young's modulus, Poisson's ratio and density, and the
//! size of gravity).
//!
//! - Forward: `du/dtheta = -K^-1 dR/dtheta`, one solve per parameter with the tangent `K`
//!   factored once at the answer ([`HyperBody::sensitivities`]).
//! - Adjoint: for a scalar objective `J(u)`, `dJ/dtheta = -lambda^T dR/dtheta` with
//!   `K lambda = dJ/du`, one solve in all (the tangent is an energy's Hessian, symmetric:
//!   the same factor serves) ([`HyperBody::objective_gradient`]).
//! - `dR/dtheta` is a central difference of the residual's assembly in `theta` at the
//!   answer (assemblies only, no solve): exact to rounding for the moduli, the densities and
//!   gravity (the residual is linear in each: the laws in `mu` and `kappa`, the clamp's
//!   penalty in the body's modulus, the loads in `rho g`), second order in Poisson's ratio.
//!
//! Plates and grasps are not covered (their augmented multipliers are not differentiated):
//! the answer must be a solve without plates, and a grasped body is refused.

use faer::Mat;
use fibfluid_geometry::Vec3;
use serde::Serialize;

use super::body::{HyperBody, HyperSolution};
use super::cell::CellMaterial;
use super::linear_solve::TangentSolver;
use super::model::{HyperModel, free_vector};
use super::newton::add_tissue;
use super::terms::{Assembly, ClampTerm, ForceTerm, LoadState};
use crate::body::{Loads, load_vector};
use crate::clamp::clamp_stiffness;
use crate::error::{FemError, Result};

/// Relative step of the residual's central difference in a modulus, density or gravity.
const RELATIVE_STEP: f64 = 1e-4;
/// Step of the residual's central difference in Poisson's ratio.
const POISSON_STEP: f64 = 1e-5;
/// Relative residual of a multigrid sensitivity solve.
const SOLVE_TOLERANCE: f64 = 1e-11;

/// A parameter of the body a sensitivity is taken to. The tissue index is 0 for the body's
/// tissue and `k` for the `k`-th region ([`HyperBody::with_regions`]'s order).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Parameter {
    /// A tissue's Young's modulus (Pa).
    Young(usize),
    /// A tissue's Poisson's ratio.
    Poisson(usize),
    /// A tissue's density (kg/m^3).
    Density(usize),
    /// The size of gravity (m/s^2), its direction kept.
    Gravity,
}

/// Forward sensitivities of an answer (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Sensitivities {
    /// The parameters, in the order asked.
    pub parameters: Vec<Parameter>,
    /// Each parameter's value at the answer.
    pub values: Vec<f64>,
    /// Per parameter, each grid node's `du/dtheta` (m per unit of the parameter).
    pub nodes: Vec<Vec<Vec3>>,
    /// Per parameter, each surface vertex's `du/dtheta` (m per unit of the parameter).
    pub surface: Vec<Vec<Vec3>>,
}

impl HyperBody {
    /// The value of `parameter` on this body under `loads`.
    ///
    /// Errors: a tissue index past the regions ([`FemError::Sensitivity`]).
    pub fn parameter_value(&self, parameter: Parameter, loads: &Loads) -> Result<f64> {
        let tissue = |k: usize| {
            self.model.tissues.get(k).copied().ok_or_else(|| FemError::Sensitivity {
                reason: format!("tissue {k} does not exist ({} regions)", self.model.tissues.len() - 1),
            })
        };
        Ok(match parameter {
            Parameter::Young(k) => tissue(k)?.young(),
            Parameter::Poisson(k) => tissue(k)?.poisson(),
            Parameter::Density(k) => tissue(k)?.density(),
            Parameter::Gravity => loads.gravity.iter().map(|g| g * g).sum::<f64>().sqrt(),
        })
    }

    /// The derivative of every node's and surface vertex's displacement in `solution` (a
    /// static solve of this body under `loads`, without plates) with respect to each of
    /// `parameters`: one factorization of the tangent at the answer, one solve per parameter.
    ///
    /// Errors: a grasped body, a solution with plates, an unknown tissue, zero gravity asked as a parameter
    /// ([`FemError::Sensitivity`]); a tangent that is not positive definite at the answer.
    pub fn sensitivities(
        &mut self,
        solution: &HyperSolution,
        loads: &Loads,
        parameters: &[Parameter],
    ) -> Result<Sensitivities> {
        let x = self.answer(solution)?;
        let n = self.model.n_free;
        let mut rhs = Mat::<f64>::zeros(n, parameters.len());
        let mut values = Vec::with_capacity(parameters.len());
        for (j, &p) in parameters.iter().enumerate() {
            values.push(self.parameter_value(p, loads)?);
            let d = self.residual_derivative(&x, loads, p)?;
            for (i, v) in d.into_iter().enumerate() {
                rhs[(i, j)] = -v;
            }
        }
        self.solve_at(&x, loads, &mut rhs)?;
        let nodes: Vec<Vec<Vec3>> = (0..parameters.len())
            .map(|j| self.node_field(&(0..n).map(|i| rhs[(i, j)]).collect::<Vec<_>>()))
            .collect();
        let surface = nodes.iter().map(|u| self.model.grid.interpolate(u)).collect();
        Ok(Sensitivities { parameters: parameters.to_vec(), values, nodes, surface })
    }

    /// The gradient of an objective `J` of the surface displacements with respect to
    /// `parameters` by the adjoint (one solve in all): `surface_gradient` is `dJ/du` at each
    /// surface vertex of `solution` (a static solve of this body under `loads`, without
    /// plates).
    ///
    /// Errors: those of [`HyperBody::sensitivities`]; `surface_gradient` without one entry
    /// per surface vertex ([`FemError::LengthMismatch`]).
    pub fn objective_gradient(
        &mut self,
        solution: &HyperSolution,
        loads: &Loads,
        parameters: &[Parameter],
        surface_gradient: &[Vec3],
    ) -> Result<Vec<f64>> {
        let embedding = self.model.grid.embedding();
        if surface_gradient.len() != embedding.len() {
            return Err(FemError::LengthMismatch {
                what: "the objective's gradient",
                expected: embedding.len(),
                found: surface_gradient.len(),
            });
        }
        let x = self.answer(solution)?;
        let mut lambda = Mat::<f64>::zeros(self.model.n_free, 1);
        for (e, g) in embedding.iter().zip(surface_gradient) {
            for b in 0..8 {
                for (a, ga) in g.iter().enumerate() {
                    if let Some(&i) =
                        self.model.free.get(3 * e.nodes[b] + a).filter(|&&i| i < self.model.n_free)
                    {
                        lambda[(i, 0)] += e.weights[b] * ga;
                    }
                }
            }
        }
        self.solve_at(&x, loads, &mut lambda)?;
        parameters
            .iter()
            .map(|&p| {
                let d = self.residual_derivative(&x, loads, p)?;
                Ok(-d.iter().enumerate().map(|(i, v)| lambda[(i, 0)] * v).sum::<f64>())
            })
            .collect()
    }

    /// The free-dof vector of `solution`, refused for a grasped body or a solve with plates.
    fn answer(&self, solution: &HyperSolution) -> Result<Vec<f64>> {
        if !self.terms.grasps.points.is_empty() {
            return Err(FemError::Sensitivity { reason: "grasps are not covered".into() });
        }
        if !solution.plate_forces.is_empty() {
            return Err(FemError::Sensitivity { reason: "plates are not covered".into() });
        }
        if solution.node_displacements.len() != self.model.grid.n_nodes() {
            return Err(FemError::LengthMismatch {
                what: "the solution's node displacements",
                expected: self.model.grid.n_nodes(),
                found: solution.node_displacements.len(),
            });
        }
        Ok(free_vector(&self.model.free, self.model.n_free, &solution.node_displacements))
    }

    /// Solves `K y = rhs` (each column, in place) with the tangent assembled at `x`.
    fn solve_at(&mut self, x: &[f64], loads: &Loads, rhs: &mut Mat<f64>) -> Result<()> {
        let external = self.external_loads(loads)?;
        let (multipliers, grasps) = (Vec::new(), Vec::new());
        let state = LoadState {
            t: 1.0,
            external: &external,
            plates: &[],
            multipliers: &multipliers,
            grasp_multipliers: &grasps,
        };
        self.evaluate(x, &state, true).ok_or(FemError::Inverted)?;
        let mut solver = self.stage.linear_solver(&self.model, self.settings.solver)?;
        if solver.prepare(&self.stage.tangent)? > 0.0 {
            return Err(FemError::NotPositiveDefinite);
        }
        solver.set_tolerance(SOLVE_TOLERANCE);
        solver.solve_in_place(rhs.as_mut());
        Ok(())
    }

    /// `dR/dtheta` at `x` (free dofs) by a central difference of the residual's assembly.
    fn residual_derivative(&self, x: &[f64], loads: &Loads, parameter: Parameter) -> Result<Vec<f64>> {
        let value = self.parameter_value(parameter, loads)?;
        let step = match parameter {
            Parameter::Poisson(_) => POISSON_STEP,
            _ => RELATIVE_STEP * value.abs(),
        };
        if !(step > 0.0) {
            return Err(FemError::Sensitivity {
                reason: format!("{parameter:?} is 0: its relative step is none"),
            });
        }
        let plus = self.residual_with(x, loads, parameter, value + step)?;
        let minus = self.residual_with(x, loads, parameter, value - step)?;
        Ok(plus.iter().zip(&minus).map(|(p, m)| (p - m) / (2.0 * step)).collect())
    }

    /// The residual (tissue, clamp, loads) at `x` with `parameter` set to `value`.
    fn residual_with(&self, x: &[f64], loads: &Loads, parameter: Parameter, value: f64) -> Result<Vec<f64>> {
        let mut model = (*self.model).clone();
        let mut loads = loads.clone();
        let mut clamp = self.terms.clamp.clone();
        match parameter {
            Parameter::Gravity => {
                let size = self.parameter_value(parameter, &loads)?;
                loads.gravity = loads.gravity.map(|g| g * value / size);
            }
            Parameter::Young(k) | Parameter::Poisson(k) | Parameter::Density(k) => {
                let t = model.tissues[k];
                model.tissues[k] = match parameter {
                    Parameter::Young(_) => t.with_elastic(value, t.poisson())?,
                    Parameter::Poisson(_) => t.with_elastic(t.young(), value)?,
                    _ => t.with_density(value)?,
                };
                reblend(&mut model);
                if k == 0 {
                    model.tissue = model.tissues[0];
                    clamp.beta = clamp_stiffness(&model.tissue, model.grid.cell_size());
                }
            }
        }
        let u = self.node_field(x);
        let mut r = vec![0.0; model.n_free];
        add_tissue(&model, &self.states, &u, &mut r, None).ok_or(FemError::Inverted)?;
        let (multipliers, grasps) = (Vec::new(), Vec::new());
        let state = LoadState {
            t: 1.0,
            external: &[],
            plates: &[],
            multipliers: &multipliers,
            grasp_multipliers: &grasps,
        };
        clamp_residual(&clamp, &model, &u, &state, &mut r);
        let f = load_vector(&model.grid, |c| model.densities[c], &model.free, model.n_free, &loads)?;
        r.iter_mut().zip(&f).for_each(|(ri, fi)| *ri -= fi);
        Ok(r)
    }
}

/// Adds the clamp's forces at `u` to `r`.
fn clamp_residual(clamp: &ClampTerm, model: &HyperModel, u: &[Vec3], state: &LoadState<'_>, r: &mut [f64]) {
    let mut out = Assembly { gradient: r, tangent: None };
    clamp.add(model, u, state, &mut out);
}

/// Each cell's moduli and density again from its tissues' shares (each cell keeps its law).
fn reblend(model: &mut HyperModel) {
    let k = model.tissues.len();
    for (c, m) in model.materials.iter_mut().enumerate() {
        let shares = &model.shares[k * c..k * (c + 1)];
        let mean =
            |f: &dyn Fn(&crate::Tissue) -> f64| model.tissues.iter().zip(shares).map(|(t, s)| f(t) * s).sum();
        *m = CellMaterial::new(m.law.clone(), mean(&|t| t.shear_modulus()), mean(&|t| t.bulk_modulus()));
        model.densities[c] = mean(&|t| t.density());
    }
}
