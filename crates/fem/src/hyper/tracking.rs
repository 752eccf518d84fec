//! Tracking a moving tool: the hyperelastic body linearized at its latest state, answered
//! at frame rate, and Newton's iterations that move the linearization along.
//!
//! A [`Linearization`] at state `x` keeps the factor of the tangent `K(x)` and the
//! out-of-balance force `r(x) = f - grad W(x)` (the body's own loads less its internal and
//! clamp forces; the tool's forces are left out). A frame with held vertices (rows `C`,
//! targets `d` as displacements from rest) and pushed forces `p` solves
//!
//! ```text
//! K(x) du = r(x) + p + C^T lambda,     C (x + du) = d
//! ```
//!
//! by the capacitance update of the linear body (`crate::held`): one solve on the kept
//! factor, the compliance columns of the held vertices, the dense capacitance system. The
//! answer `x + du` is exactly one Newton step of the constrained equilibrium from `x`:
//! holding the tool still, each new linearization at the last answer is one more Newton
//! iteration, and the frames converge quadratically to the nonlinear equilibrium with the
//! holds met exactly. [`HyperBody::track`] is that iteration: the step of the current
//! linearization, shortened (halved) while it would invert a cell, and the body
//! linearized again there.

use std::sync::Arc;

use fibfluid_geometry::Vec3;
use fibfluid_linalg::SparseCholesky;

use super::body::HyperBody;
use super::model::{HyperModel, free_vector};
use super::terms::LoadState;
use crate::assemble::FIXED;
use crate::body::{Loads, add_point_forces};
use crate::error::{FemError, Result};
use crate::held_rows::{FemHold, Row, constraint_rows};
use crate::held_system::{HeldSystem, HoldCache, Penalty, interpolate_surface};

/// A factored tangent: the factor, the diagonal shift it needed (relative to the median
/// diagonal entry) and the holds' penalty it carries.
type Factored = (SparseCholesky, f64, Option<Penalty>);

/// Halvings of a tracking step tried while it would invert a cell or (holds met) raise
/// the energy.
pub const MAX_STEP_HALVINGS: usize = 12;

/// The hold penalties tried, in units of the tangent's median diagonal entry, when the
/// tangent alone is not positive definite.
pub const HOLD_PENALTIES: [f64; 3] = [1e2, 1e4, 1e6];

/// The diagonal shifts tried after the hold penalties, in units of the tangent's median
/// diagonal entry.
pub const SHIFTS: [f64; 6] = [1e-4, 1e-3, 1e-2, 1e-1, 1.0, 1e2];

/// A state meets its holds when the step moves no held vertex along a held direction by
/// more than this fraction of a cell.
pub const HOLD_MET: f64 = 1e-9;

/// A tracking step moves the held vertices toward their targets by at most this many
/// cells.
pub const MAX_RESTORE: f64 = 2.0;

/// The longest step (largest surface motion, in cells) a [`Tangent::Keep`] iteration takes
/// on the kept factor; a longer one is Newton's.
pub const CHORD_REACH: f64 = 1.0;

/// Below this fraction of the step, a restoring step is taken even where the tangent
/// needs a shift.
const RESTORE_FLOOR: f64 = 1.0 / 64.0;

/// Armijo's sufficient-decrease constant of the tracking step (Newton's).
const ARMIJO: f64 = 1e-4;

/// Energy changes below this fraction of the energy are rounding.
const ENERGY_ROUNDING: f64 = 1e-12;

/// Whether a tracking iteration factors the tangent at its end.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tangent {
    /// Assemble and factor the tangent at the step's end: Newton's iteration (quadratic
    /// convergence; a factorization, and the held vertices' compliance columns again).
    Refactor,
    /// Keep the factor (a tangent at an earlier state) and move only the state and its
    /// out-of-balance force: a chord iteration, the kept factor preconditioning the current
    /// tangent as in the asynchronous preconditioners of Courtecuisse et al. (2015). It
    /// costs one force evaluation and two solves, converges linearly, and keeps the held
    /// vertices' columns.
    Keep,
}

/// The state, out-of-balance force and tangent factor of one linearization.
struct Core {
    model: Arc<HyperModel>,
    x: Vec<f64>,
    force: Vec<f64>,
    /// Shared by the chord iterations made from it ([`Tangent::Keep`]).
    factor: Arc<SparseCholesky>,
    /// Chord iterations since the factor was made (0: factored at `x`).
    chord_steps: usize,
    /// The shift added to the tangent's diagonal to factor it (0: the exact tangent).
    shift: f64,
    /// Displacement of every surface vertex at `x` (m).
    surface: Vec<Vec3>,
    /// The hold rows penalized to factor it (an augmented Lagrangian on the holds it was
    /// made for, when the tangent alone is not positive definite).
    penalty: Option<Penalty>,
}

impl Core {
    /// The held system of this linearization's factor.
    fn system(&self) -> HeldSystem<'_> {
        HeldSystem {
            factor: &self.factor,
            embedding: self.model.grid.embedding(),
            free: &self.model.free,
            rest: self.model.grid.surface_positions(),
        }
    }

    /// The surface displaced by `step_field` from this state, and the step's largest
    /// surface motion (m).
    fn stepped(&self, step_field: &[Vec3]) -> (Vec<Vec3>, f64) {
        let step = step_field.iter().map(|d| fibfluid_geometry::vec3::norm(*d)).fold(0.0, f64::max);
        let surface = self.surface.iter().zip(step_field).map(|(p, d)| fibfluid_geometry::vec3::add(*p, *d));
        (surface.collect(), step)
    }
}

/// The body linearized at one state (see the module docs). Cheap to clone: the factor
/// is shared, the compliance columns cached for held vertices are copied.
#[derive(Clone)]
pub struct Linearization {
    core: Arc<Core>,
    cache: HoldCache,
}

impl std::fmt::Debug for Linearization {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Linearization")
            .field("dofs", &self.core.x.len())
            .field("shift", &self.core.shift)
            .finish()
    }
}

/// A frame answered on a linearization.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackedResponse {
    /// The answer's free-dof state (the linearization's state plus the step).
    pub state: Vec<f64>,
    /// Displacement of every surface vertex (m).
    pub surface_displacements: Vec<Vec3>,
    /// Per hold (in the order given), the force its holder puts on the body (N).
    pub reactions: Vec<Vec3>,
    /// The largest distance a surface vertex moved from the linearization's state (m):
    /// the Newton step this frame took.
    pub step: f64,
    /// Whether the answer keeps springs on vertices the linearization was made holding
    /// and this frame does not hold (its tangent needed them; the next linearization for
    /// these holds drops them).
    pub approximate: bool,
}

impl Linearization {
    /// The free-dof state it was made at.
    pub fn state(&self) -> &[f64] {
        &self.core.x
    }

    /// Chord iterations ([`Tangent::Keep`]) since its factor was made at a state of its
    /// own (0: the factor is the tangent at [`Linearization::state`]).
    pub fn chord_steps(&self) -> usize {
        self.core.chord_steps
    }

    /// The shift added to the tangent's diagonal to factor it (relative to its median
    /// diagonal entry; 0 when the tangent, or the tangent with its holds penalized, was
    /// positive definite).
    pub fn shift(&self) -> f64 {
        self.core.shift
    }

    /// The stiffness of the penalty on the holds it was made for (N/m; 0: none, the
    /// tangent alone was positive definite).
    pub fn hold_penalty(&self) -> f64 {
        self.core.penalty.as_ref().map_or(0.0, |p| p.stiffness)
    }

    /// The compliance columns the last [`Linearization::respond_at_surface`] read: a
    /// frame's cost is `3 x surface vertices x` this. A patch held at the targets of one
    /// rigid (or affine) motion, a grasp, reads at most 12 whatever its size; other holds
    /// read `min(3 x held vertices, free dofs their rows touch)` (0 before any frame).
    pub fn frame_columns(&self) -> usize {
        self.cache.frame_columns()
    }

    /// Whether a frame holding `vertex` reads compliance columns already made on this
    /// linearization (by an earlier frame, or by the refresh that made it): a vertex not
    /// yet held here costs its columns' triangular solves first, `3` per vertex at most.
    pub fn has_columns_for(&self, vertex: usize) -> bool {
        self.cache.answers(vertex)
    }

    /// Whether `other` is this linearization (the same state and factor), whatever columns
    /// either has cached since.
    pub fn same_state(&self, other: &Linearization) -> bool {
        Arc::ptr_eq(&self.core, &other.core)
    }

    /// Bytes of the factor and the cached columns.
    pub fn memory_bytes(&self) -> usize {
        let n = self.core.x.len();
        8 * (self.core.factor.nonzeros() + 3 * n) + self.cache.bytes()
    }

    /// The out-of-balance force at the state with `pushes` added (free dofs).
    fn respond_force(&self, pushes: &[(usize, Vec3)]) -> Result<Vec<f64>> {
        let mut f = self.core.force.clone();
        add_point_forces(self.core.model.grid.embedding(), &self.core.model.free, pushes, &mut f)?;
        Ok(f)
    }

    /// Displacement of every surface vertex at the linearization's own state (m).
    pub fn surface_displacements(&self) -> Vec<Vec3> {
        self.core.surface.clone()
    }

    /// The response to `pushes` (point forces on surface vertices, N) and `holds`
    /// (targets as displacements from the rest shape) on this linearization.
    ///
    /// Errors: a vertex out of range, a non-finite force or target, dependent holds, a
    /// target on an axis only fixed nodes carry.
    pub fn respond(
        &mut self,
        pushes: &[(usize, Vec3)],
        holds: &[(usize, FemHold)],
    ) -> Result<TrackedResponse> {
        let f = self.respond_force(pushes)?;
        let solved = self.core.system().solve(
            &mut self.cache,
            f,
            holds,
            Some(&self.core.x),
            self.core.penalty.as_ref(),
        )?;
        let (surface_displacements, step) = self.core.stepped(&interpolate(&self.core.model, &solved.u));
        let state: Vec<f64> = self.core.x.iter().zip(&solved.u).map(|(a, b)| a + b).collect();
        Ok(TrackedResponse {
            surface_displacements,
            state,
            reactions: solved.reactions,
            step,
            approximate: solved.uncovered > 0,
        })
    }
}

impl Linearization {
    /// What a frame needs of [`Linearization::respond`]: the same surface, reactions and
    /// step, without the state inside the body. It costs `3 x surface vertices x` the
    /// columns it reads ([`Linearization::frame_columns`]) while the held rows and the
    /// pushes stay the same (the columns are projected onto the surface once, on the first
    /// such frame), whatever the number of unknowns.
    ///
    /// Errors: those of [`Linearization::respond`].
    pub fn respond_at_surface(
        &mut self,
        pushes: &[(usize, Vec3)],
        holds: &[(usize, FemHold)],
    ) -> Result<SurfaceResponse> {
        let f = self.respond_force(pushes)?;
        let solved = self.core.system().solve_surface(
            &mut self.cache,
            &f,
            holds,
            Some(&self.core.x),
            self.core.penalty.as_ref(),
        )?;
        let (surface_displacements, step) = self.core.stepped(&solved.surface);
        Ok(SurfaceResponse {
            surface_displacements,
            reactions: solved.reactions,
            step,
            approximate: solved.uncovered > 0,
        })
    }
}

/// A frame answered on a linearization at the surface only
/// ([`Linearization::respond_at_surface`]): a [`TrackedResponse`] without the state.
#[derive(Debug, Clone, PartialEq)]
pub struct SurfaceResponse {
    /// Displacement of every surface vertex (m).
    pub surface_displacements: Vec<Vec3>,
    /// Per hold (in the order given), the force its holder puts on the body (N).
    pub reactions: Vec<Vec3>,
    /// The largest distance a surface vertex moved from the linearization's state (m).
    pub step: f64,
    /// As [`TrackedResponse::approximate`].
    pub approximate: bool,
}

/// The full dead load `external` alone: no plates, no grasps.
fn dead_loads(external: &[f64]) -> LoadState<'_> {
    LoadState { t: 1.0, external, plates: &[], multipliers: &[], grasp_multipliers: &[] }
}

/// Surface displacements of a free-dof vector.
fn interpolate(model: &HyperModel, x: &[f64]) -> Vec<Vec3> {
    interpolate_surface(model.grid.embedding(), &model.free, x)
}

/// One tracking iteration's outcome.
#[derive(Debug, Clone)]
pub struct TrackStep {
    /// The new linearization, at the step's end.
    pub linearization: Linearization,
    /// The fraction of the Newton step taken (1: the full step).
    pub fraction: f64,
    /// Whether the tangent was factored at the step's end ([`Tangent::Refactor`], or a
    /// [`Tangent::Keep`] step the kept factor could not take).
    pub refactored: bool,
    /// The largest surface motion of the full step (m): the distance to the equilibrium
    /// of the holds, to first order, before this iteration.
    pub step: f64,
}

impl HyperBody {
    /// Linearizes the body (without plates or grasps) at the free-dof state `x` under
    /// `loads`: assembles the tangent and factors it (shifting the diagonal by the first of
    /// [`SHIFTS`] that makes it positive definite when it is not).
    ///
    /// Errors: a non-finite load, a vertex out of range, an inverted cell at `x`, a tangent
    /// that no shift makes positive definite.
    pub fn linearize(&mut self, x: Vec<f64>, loads: &Loads) -> Result<Linearization> {
        self.linearize_holding(x, loads, &[])
    }

    /// [`HyperBody::linearize`] for frames that hold `holds`: a tangent that is not
    /// positive definite on its own (a compressed or unloaded body may buckle freely, held
    /// it does not) is factored with `beta C^T C` added on the holds' rows, `beta` the
    /// smallest of [`HOLD_PENALTIES`] times the tangent's median diagonal entry that makes it
    /// positive definite: an augmented Lagrangian that leaves the held answer unchanged.
    /// Only when that fails is the diagonal shifted.
    ///
    /// Errors: as [`HyperBody::linearize`], and those of the holds' rows.
    pub fn linearize_holding(
        &mut self,
        x: Vec<f64>,
        loads: &Loads,
        holds: &[(usize, FemHold)],
    ) -> Result<Linearization> {
        self.linearize_if(x, loads, holds, true)?.ok_or(FemError::NotPositiveDefinite)
    }

    /// [`HyperBody::linearize_holding`]; without `shift_allowed`, `None` where the tangent
    /// would need a diagonal shift (no shifted factorization is tried: a tracking step
    /// halves instead, and each try is a factorization).
    fn linearize_if(
        &mut self,
        x: Vec<f64>,
        loads: &Loads,
        holds: &[(usize, FemHold)],
        shift_allowed: bool,
    ) -> Result<Option<Linearization>> {
        if x.len() != self.model.n_free {
            return Err(FemError::LengthMismatch {
                what: "state",
                expected: self.model.n_free,
                found: x.len(),
            });
        }
        let external = self.external_loads(loads)?;
        let eval = self.evaluate(&x, &dead_loads(&external), true).ok_or(FemError::Inverted)?;
        let rows = constraint_rows(self.model.grid.embedding(), &self.model.free, holds)?;
        let Some((factor, shift, penalty)) = self.factor_holding(&rows, shift_allowed)? else {
            return Ok(None);
        };
        let model = Arc::clone(&self.model);
        let force = eval.gradient.iter().map(|g| -g).collect();
        let surface = interpolate(&model, &x);
        let factor = Arc::new(factor);
        let core = Core { model, x, force, factor, chord_steps: 0, shift, surface, penalty };
        Ok(Some(Linearization { core: Arc::new(core), cache: HoldCache::default() }))
    }

    /// Factors the assembled tangent as [`HyperBody::linearize_holding`] says; `None`
    /// when it needs a shift that is not `shift_allowed`.
    fn factor_holding(&mut self, rows: &[Row], shift_allowed: bool) -> Result<Option<Factored>> {
        let symbolic = self.stage.symbolic(&self.model)?;
        if rows.is_empty() {
            match SparseCholesky::factor(&symbolic, self.stage.tangent.as_ref()) {
                Ok(f) => return Ok(Some((f, 0.0, None))),
                Err(fibfluid_linalg::LinalgError::SparseNotPositiveDefinite { .. }) => {}
                Err(e) => return Err(e.into()),
            }
        }
        let mut diagonal: Vec<f64> = (0..self.model.n_free)
            .map(|j| self.stage.tangent.val()[self.stage.tangent.symbolic().col_ptr()[j]].abs())
            .collect();
        diagonal.sort_by(f64::total_cmp);
        let median = diagonal[diagonal.len() / 2];
        let plain = self.stage.tangent.clone();
        let diagonal_at: Vec<usize> = (0..self.model.n_free).map(|j| plain.symbolic().col_ptr()[j]).collect();
        // First the holds' penalty (exact for frames that hold them), then a shift of the
        // diagonal (a damped step, exact nowhere: the refreshes converge linearly then).
        let penalties = if rows.is_empty() { &[][..] } else { &HOLD_PENALTIES[..] };
        let shifts = if shift_allowed { &SHIFTS[..] } else { &[][..] };
        let attempts = penalties.iter().map(|&p| (p, 0.0)).chain(shifts.iter().map(|&s| (0.0, s)));
        for (penalty, shift) in attempts {
            let stiffness = penalty * median;
            for row in rows.iter().filter(|_| penalty > 0.0) {
                self.add_row_penalty(row, stiffness);
            }
            diagonal_at.iter().for_each(|&p| self.stage.tangent.val_mut()[p] += shift * median);
            let made = SparseCholesky::factor(&symbolic, self.stage.tangent.as_ref());
            self.stage.tangent = plain.clone();
            match made {
                Ok(f) if penalty > 0.0 => {
                    let keys = rows.iter().map(Row::key).collect();
                    return Ok(Some((f, 0.0, Some(Penalty { keys, stiffness }))));
                }
                Ok(f) => return Ok(Some((f, shift, None))),
                Err(fibfluid_linalg::LinalgError::SparseNotPositiveDefinite { .. }) => {}
                Err(e) => return Err(e.into()),
            }
        }
        if shift_allowed { Err(FemError::NotPositiveDefinite) } else { Ok(None) }
    }

    /// Adds `stiffness r r^T` of a hold row `r` to the tangent's lower triangle.
    fn add_row_penalty(&mut self, row: &Row, stiffness: f64) {
        let (symbolic, values) = self.stage.tangent.parts_mut();
        let (col_ptr, row_idx) = (symbolic.col_ptr(), symbolic.row_idx());
        for &(c, wc) in &row.entries {
            let col = &row_idx[col_ptr[c]..col_ptr[c + 1]];
            for &(r, wr) in row.entries.iter().filter(|e| e.0 >= c) {
                if let Ok(pos) = col.binary_search(&r) {
                    values[col_ptr[c] + pos] += stiffness * wr * wc;
                }
            }
        }
    }

    /// The rest state (every displacement 0) linearized under `loads`.
    ///
    /// Errors: as [`HyperBody::linearize`].
    pub fn linearize_at_rest(&mut self, loads: &Loads) -> Result<Linearization> {
        self.linearize(vec![0.0; self.model.n_free], loads)
    }

    /// One Newton iteration of the equilibrium with `pushes` and `holds` from
    /// `current`'s state: its step (see the module docs), halved while it would invert a
    /// cell, then the body linearized at the step's end. The returned linearization has
    /// the columns of `holds` cached, and their projection onto the surface.
    ///
    /// Errors: those of [`Linearization::respond`] and [`HyperBody::linearize`];
    /// [`FemError::Inverted`] when even the step halved [`MAX_STEP_HALVINGS`] times
    /// inverts a cell.
    pub fn track(
        &mut self,
        current: &mut Linearization,
        loads: &Loads,
        pushes: &[(usize, Vec3)],
        holds: &[(usize, FemHold)],
    ) -> Result<TrackStep> {
        self.track_with(current, loads, pushes, holds, Tangent::Refactor)
    }

    /// [`HyperBody::track`] with the tangent as `tangent` says: [`Tangent::Keep`] moves
    /// the state along the step of the kept factor when the held vertices are within
    /// reach (the step is not cut to restore them) and its first trial is accepted (no
    /// assembly, no factorization, no new compliance columns: the held vertices' columns
    /// stay valid), and falls back to [`Tangent::Refactor`] (halving the same step) when
    /// not.
    ///
    /// Errors: as [`HyperBody::track`].
    pub fn track_with(
        &mut self,
        current: &mut Linearization,
        loads: &Loads,
        pushes: &[(usize, Vec3)],
        holds: &[(usize, FemHold)],
        tangent: Tangent,
    ) -> Result<TrackStep> {
        let mut keep = tangent == Tangent::Keep;
        let answer = current.respond(pushes, holds)?;
        let x0 = current.state().to_vec();
        let direction: Vec<f64> = answer.state.iter().zip(&x0).map(|(a, b)| a - b).collect();
        // The holds are linear in the state: when the start already meets them, every point
        // of the step does, and the energy is the merit of the step (Armijo's backtracking);
        // otherwise the step first restores them, shortened only while it would invert.
        let h = self.model.grid.cell_size();
        let held_motion = self.held_motion(current, &direction, holds);
        let merit = if held_motion <= HOLD_MET * h {
            let mut all = loads.clone();
            all.point_forces.extend_from_slice(pushes);
            Some(self.external_loads(&all)?)
        } else {
            None
        };
        let start = merit.as_ref().and_then(|e| self.energy(&x0, &dead_loads(e)));
        // The slope of the energy along the step: the gradient is the negated out-of-balance
        // force with the pushes (the holds' reactions do no work along it).
        let pushed = current.respond_force(pushes)?;
        let slope: f64 = -pushed.iter().zip(&direction).map(|(f, d)| f * d).sum::<f64>();
        // Restoring the holds moves them at most MAX_RESTORE cells per iteration: a tool
        // that ran far ahead is caught up over several, each from a state it can trust.
        let mut fraction = if merit.is_some() { 1.0 } else { (MAX_RESTORE * h / held_motion).min(1.0) };
        // The kept factor steers near its own state only: a tool far ahead is caught up
        // by Newton's steps, and so is a step long against a cell.
        keep &= fraction == 1.0 && answer.step <= CHORD_REACH * h;
        for _ in 0..=MAX_STEP_HALVINGS {
            let trial: Vec<f64> = x0.iter().zip(&direction).map(|(a, d)| a + fraction * d).collect();
            let accepted = match (&merit, start) {
                (Some(external), Some(e0)) => self.energy(&trial, &dead_loads(external)).is_some_and(|e| {
                    let rounding = ENERGY_ROUNDING * e0.abs().max(e.abs());
                    e <= e0 + ARMIJO * fraction * slope.min(0.0) + rounding
                }),
                _ => self.cell_states_valid(&trial),
            };
            // A step that restores holds must also land where the held tangent is positive
            // definite (its penalty suffices, no shift): a state reached by a long stride
            // can be wildly unstable without inverting a cell.
            let shift_allowed = merit.is_some() || fraction < RESTORE_FLOOR;
            if accepted && keep {
                let mut linearization = self.restate(current, trial, loads)?;
                linearization.respond_at_surface(pushes, holds)?;
                return Ok(TrackStep { linearization, fraction, step: answer.step, refactored: false });
            }
            keep = false;
            if accepted
                && let Some(mut linearization) = self.linearize_if(trial, loads, holds, shift_allowed)?
            {
                // The frames' projection is made here, off the frame thread.
                linearization.respond_at_surface(pushes, holds)?;
                return Ok(TrackStep { linearization, fraction, step: answer.step, refactored: true });
            }
            fraction *= 0.5;
        }
        Err(FemError::Inverted)
    }

    /// `current`'s factor (and its held vertices' columns) at the free-dof state `x`:
    /// the out-of-balance force evaluated there, no tangent assembled.
    fn restate(&mut self, current: &Linearization, x: Vec<f64>, loads: &Loads) -> Result<Linearization> {
        let external = self.external_loads(loads)?;
        let eval = self.evaluate(&x, &dead_loads(&external), false).ok_or(FemError::Inverted)?;
        let kept = &current.core;
        let core = Core {
            model: Arc::clone(&kept.model),
            force: eval.gradient.iter().map(|g| -g).collect(),
            surface: interpolate(&kept.model, &x),
            x,
            factor: Arc::clone(&kept.factor),
            chord_steps: kept.chord_steps + 1,
            shift: kept.shift,
            penalty: kept.penalty.clone(),
        };
        Ok(Linearization { core: Arc::new(core), cache: current.cache.clone() })
    }

    /// How far the step moves the held vertices along their held directions (m, the
    /// largest): 0 when `current`'s state already meets `holds`.
    fn held_motion(&self, current: &Linearization, direction: &[f64], holds: &[(usize, FemHold)]) -> f64 {
        let model = &current.core.model;
        holds
            .iter()
            .map(|&(v, hold)| {
                let Some(e) = model.grid.embedding().get(v) else { return 0.0 };
                let moved: Vec3 = std::array::from_fn(|a| {
                    (0..8)
                        .map(|b| match model.free[3 * e.nodes[b] + a] {
                            FIXED => 0.0,
                            i => e.weights[b] * direction[i],
                        })
                        .sum()
                });
                match hold {
                    FemHold::At(_) => fibfluid_geometry::vec3::norm(moved),
                    FemHold::Along { normal, .. } => fibfluid_geometry::vec3::dot(moved, normal).abs(),
                }
            })
            .fold(0.0, f64::max)
    }

    /// Whether no cell is inverted at the free-dof state `x`.
    fn cell_states_valid(&self, x: &[f64]) -> bool {
        let u = self.node_field(x);
        let cells = self.model.grid.cell_nodes().iter().enumerate();
        cells.into_iter().all(|(c, nodes)| {
            let fill = self.model.grid.cell_fill(c);
            self.model
                .cell
                .energy_with(&self.model.materials[c], &nodes.map(|n| u[n]), fill, self.states.cell(c))
                .is_some()
        })
    }
}

impl HyperBody {
    /// The free-dof state of node displacements `u` (one per grid node; fixed dofs are
    /// dropped): the state a batch [`HyperBody::solve`] ends at, to start tracking from.
    ///
    /// Errors: `u` not one entry per grid node.
    pub fn state_of(&self, u: &[Vec3]) -> Result<Vec<f64>> {
        if u.len() != self.model.grid.n_nodes() {
            return Err(FemError::LengthMismatch {
                what: "node field",
                expected: self.model.grid.n_nodes(),
                found: u.len(),
            });
        }
        Ok(free_vector(&self.model.free, self.model.n_free, u))
    }
}
