//! The hyperelastic body: its grid, clamp, contact samples, tangent pattern and kept
//! symbolic factorization; the solution and statistics types.

use std::sync::Arc;

use faer::sparse::SparseColMat;
use fibfluid_geometry::Vec3;
use fibfluid_linalg::SparseSymbolic;
use serde::Serialize;

use super::cell::{CellMaterial, CellState, HyperCell};
use super::contact::surface_samples;
use super::dynamics::DynamicsTerm;
use super::grasp::{GRASP_PENALTY, Grasp, GraspRecord, GraspSet};
use super::linear_solve::{DirectSolver, LinearSolver, MultigridSolver};
use super::model::HyperModel;
use super::pressure::{Pressure, PressureTerm};
use super::terms::{ClampTerm, ContactTerm, ForceTerm};
use crate::assemble::{lower_pattern, lower_pattern_coupled, number_free_dofs};
use crate::body::{Loads, load_vector};
use crate::clamp::{Clamp, clamp_stiffness};
use crate::error::{FemError, Result};
use crate::grid::{FemOptions, SparseGrid};
use crate::law::{LawStates, MaterialLaw};
use crate::multigrid::GridLevels;
use crate::ordering::{Ordering, symbolic_analysis};
use crate::tissue::Tissue;

/// The grasps' compliance columns may take at most this many bytes (`8 x rows x dofs`) by
/// default ([`NewtonSettings::grasp_columns_bytes`]); larger grasps are met by Uzawa's
/// augmentations alone.
pub const GRASP_COLUMNS_BYTES: usize = 256 << 20;

/// Newton's method and its load stepping.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct NewtonSettings {
    /// Converged when `|r| <= tolerance * max(|t f|, |f_int|)` (relative residual).
    pub tolerance: f64,
    /// Newton iterations allowed per load step before the step is cut.
    pub max_iterations: usize,
    /// The first load increment (a fraction of the full load).
    pub first_increment: f64,
    /// The smallest increment before the solve gives up.
    pub min_increment: f64,
    /// The largest increment (1: none); a static plate run caps it to record each plate's
    /// force at least this often along its travel.
    pub max_increment: f64,
    /// A step that converged in at most this many iterations doubles the next increment.
    pub easy_iterations: usize,
    /// The grasps' compliance columns (`8 x 3 x grasped vertices x dofs` bytes) Newton's
    /// method on their optimality conditions may keep; above it Uzawa's augmentations
    /// alone meet the grasps.
    pub grasp_columns_bytes: usize,
    /// The linear solver of each Newton iteration (`Auto`: by the unknowns' count).
    pub solver: crate::FemSolver,
}

impl Default for NewtonSettings {
    fn default() -> Self {
        Self {
            tolerance: 1e-8,
            max_iterations: 25,
            first_increment: 1.0,
            min_increment: 1.0 / 1024.0,
            max_increment: 1.0,
            easy_iterations: 5,
            grasp_columns_bytes: GRASP_COLUMNS_BYTES,
            solver: crate::FemSolver::Auto,
        }
    }
}

/// One converged load step.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LoadStep {
    /// The load factor reached (1: the full load).
    pub load: f64,
    /// The contact augmentation this solve belongs to (0: the load stepping itself).
    pub augmentation: usize,
    /// Newton iterations (linear solves) it took.
    pub iterations: usize,
    /// The relative residual before each iteration and at convergence.
    pub residuals: Vec<f64>,
    /// Per plate, the contact force on the body along its normal at the step's end (N;
    /// empty without plates).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub plate_forces: Vec<f64>,
}

/// Cells at least this fraction inside the surface are the tissue the strain summary
/// reports on. A cell mostly outside the body is mostly the fictitious material that
/// holds its outer nodes ([`super::cell::EMPTY_STIFFNESS`]); its strain and stress can be
/// many times the tissue's without meaning anything about the tissue (their per-cell
/// values are still in `volume.vtu`, with the fill beside them).
pub const SUMMARY_FILL: f64 = 0.5;

/// Extremes of the deformed cells at least [`SUMMARY_FILL`] inside the surface (of every
/// cell when none is).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StrainSummary {
    /// Smallest `J = det F` over every cell's Gauss points.
    pub j_min: f64,
    /// Largest `J`.
    pub j_max: f64,
    /// Largest principal Green–Lagrange strain over the cells (at their centres).
    pub max_principal_strain: f64,
    /// Largest absolute principal Green–Lagrange strain over the cells (at their centres).
    pub max_strain_magnitude: f64,
    /// Largest von Mises Cauchy stress over the cells (Pa).
    pub max_von_mises: f64,
}

/// Counts and timings of a hyperelastic solve.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct HyperStats {
    /// Newton iterations in all (each one assembly, one numeric factorization, one solve).
    pub newton_iterations: usize,
    /// Load steps that converged.
    pub load_steps: usize,
    /// Load steps cut after a failed Newton solve.
    pub cut_steps: usize,
    /// Contact augmentations.
    pub augmentations: usize,
    /// Seconds assembling gradients and tangents.
    pub assembly_seconds: f64,
    /// Seconds of numeric factorizations.
    pub factor_seconds: f64,
    /// Seconds of triangular solves and line searches.
    pub solve_seconds: f64,
    /// The diagonal shift (a fraction of the largest diagonal entry) the last factored
    /// tangent needed to be positive definite, the last Newton iteration's, next to the
    /// answer: 0 at a stable equilibrium; above 0 the equilibrium found is unstable (a body
    /// pressed or hung past buckling, which would sway to another shape).
    pub final_shift: f64,
    /// Augmentations whose Newton solve failed with the contact met (at most 1: the last
    /// converged state then stands as the answer, its grasps met as far as it got).
    pub failed_augmentations: usize,
    /// Conjugate-gradient iterations of the multigrid solves (0 with the direct solver).
    pub linear_iterations: usize,
    /// Multigrid solves (steps and compliance columns; 0 with the direct solver).
    pub linear_solves: usize,
    /// The linear solver used (`direct` or `multigrid`; `auto` before a solve).
    pub solver: crate::FemSolver,
}

/// The converged large-deformation answer.
#[derive(Debug, Clone, PartialEq)]
pub struct HyperSolution {
    /// Displacement of every grid node (m).
    pub node_displacements: Vec<Vec3>,
    /// Displacement of every surface vertex (m).
    pub surface_displacements: Vec<Vec3>,
    /// The final relative residual.
    pub residual: f64,
    /// Every converged load step with its residual history.
    pub steps: Vec<LoadStep>,
    /// Per plate, the contact force it puts on the body along its normal (N).
    pub plate_forces: Vec<f64>,
    /// Per plate, the surface samples in contact.
    pub plate_contacts: Vec<usize>,
    /// Per plate, the deepest remaining penetration (m).
    pub plate_penetration: Vec<f64>,
    /// Per plate, the contact pressure at every surface vertex (Pa): each contact sample's
    /// force shared among its triangle's vertices, over the vertex's area.
    pub contact_pressure: Vec<Vec<f64>>,
    /// Per grasp, the force and moment the tissue exerts on the grasper and its largest
    /// constraint error.
    pub grasps: Vec<GraspRecord>,
    /// The total force the supports (the clamp) put on the body (N).
    pub support_force: Vec3,
    /// Each cell's strain, stress and `J`.
    pub cells: Vec<CellState>,
    /// Extremes over the cells.
    pub summary: StrainSummary,
    /// Counts and timings.
    pub stats: HyperStats,
}

/// Newton's scratch: the tangent's values on its fixed pattern, the pattern's symbolic
/// analysis (made at the first direct solve, then kept: numeric factorizations reuse it)
/// and the grid's multigrid levels (made at the first multigrid solve).
pub(crate) struct NewtonStage {
    pub(crate) tangent: SparseColMat<usize, f64>,
    symbolic: Option<Arc<SparseSymbolic>>,
    levels: Option<Arc<GridLevels>>,
    ordering: Ordering,
}

impl NewtonStage {
    /// The tangent's symbolic analysis (made on first use).
    ///
    /// Errors: the analysis's (out of memory, index overflow).
    pub(crate) fn symbolic(&mut self, model: &HyperModel) -> Result<Arc<SparseSymbolic>> {
        if self.symbolic.is_none() {
            let pattern = self.tangent.symbolic();
            let analysis = symbolic_analysis(&model.grid, &model.free, model.n_free, pattern, self.ordering)?;
            self.symbolic = Some(Arc::new(analysis));
        }
        Ok(self.symbolic.clone().expect("made above"))
    }

    /// The linear solver `solver` resolves to on this model's grid (by its
    /// [`crate::GridEstimate::dofs`], as the plan decides).
    ///
    /// Errors: those of [`NewtonStage::symbolic`].
    pub(crate) fn linear_solver(
        &mut self,
        model: &HyperModel,
        solver: crate::FemSolver,
    ) -> Result<LinearSolver> {
        Ok(match solver.resolve(model.grid.estimate().dofs) {
            crate::FemSolver::Multigrid => {
                let levels =
                    self.levels.get_or_insert_with(|| Arc::new(GridLevels::new(&model.grid, &model.free)));
                LinearSolver::Multigrid(MultigridSolver::new(levels.clone()))
            }
            _ => LinearSolver::Direct(DirectSolver::new(self.symbolic(model)?)),
        })
    }
}

/// A sparse-grid body of hyperelastic tissue (see the module docs): the model (shared,
/// immutable), the force terms besides the tissue (clamp, contact, grasps), Newton's
/// scratch, the laws' per-point state and the settings.
pub struct HyperBody {
    pub(crate) model: Arc<HyperModel>,
    pub(crate) terms: ForceTerms,
    pub(crate) stage: NewtonStage,
    /// The laws' per-point state (empty when every law is stateless).
    pub(crate) states: LawStates,
    pub(crate) settings: NewtonSettings,
}

impl std::fmt::Debug for HyperBody {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HyperBody")
            .field("tissue", &self.model.tissue)
            .field("dofs", &self.model.n_free)
            .finish()
    }
}

impl HyperBody {
    /// Voxelizes the surface at `options.resolution` and prepares the body: the clamp of
    /// `fixed` (as [`crate::FemBody`]'s), the tangent's pattern and its symbolic
    /// factorization. Nothing is factored numerically until a solve.
    ///
    /// Errors: those of [`crate::FemBody::from_surface`] that come from the input.
    pub fn from_surface(
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        tissue: &Tissue,
        fixed: &[[bool; 3]],
        options: &FemOptions,
    ) -> Result<Self> {
        Self::from_surface_grasped(positions, triangles, tissue, fixed, &[], options)
    }

    /// [`HyperBody::from_surface`] with `grasps` moving patches of the surface rigidly
    /// ([`HyperBody::with_grasps`]); a grasped vertex counts as held on every axis when the
    /// constraints are checked for free rigid motions.
    ///
    /// Errors: those of [`HyperBody::from_surface`] and of [`HyperBody::with_grasps`].
    pub fn from_surface_grasped(
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        tissue: &Tissue,
        fixed: &[[bool; 3]],
        grasps: &[Grasp],
        options: &FemOptions,
    ) -> Result<Self> {
        let mut held = fixed.to_vec();
        for v in grasps.iter().flat_map(|g| &g.vertices) {
            if let Some(h) = held.get_mut(*v) {
                *h = [true; 3];
            }
        }
        let grid = crate::rigid::checked_grid(positions, triangles, &held, options.resolution)?;
        Self::new(grid, tissue, fixed, Ordering::default())?.with_grasps(grasps)
    }

    /// The same body with `grasps` (replacing any it had): each moves its patch rigidly
    /// with the load factor (see [`super::grasp`]'s module docs).
    ///
    /// Errors: a vertex out of range, an empty patch, a non-finite motion.
    pub fn with_grasps(mut self, grasps: &[Grasp]) -> Result<Self> {
        let beta = GRASP_PENALTY * self.model.tissue.young() / self.model.grid.cell_size();
        self.terms.grasps = GraspSet::new(&self.model.grid, grasps, beta)?;
        Ok(self)
    }

    /// The same body with `pressures` (replacing any it had) on faces of its surface,
    /// ramped with the load factor ([`super::pressure`]'s module docs: a closed selection
    /// follows the deformed surface under a nonlinear law; an open one, or any under the
    /// linear law, is a dead load on the rest surface).
    ///
    /// Errors: a face's vertex out of range, a non-finite value.
    pub fn with_pressures(mut self, pressures: &[Pressure]) -> Result<Self> {
        self.terms.pressures = PressureTerm::new(&self.model.grid, pressures)?;
        let pairs = self.terms.pressures.couplings(&self.model.grid);
        if !pairs.is_empty() {
            let model = &*self.model;
            let pattern = lower_pattern_coupled(&model.grid, &model.free, model.n_free, &pairs);
            let nnz = pattern.row_idx().len();
            self.stage.tangent = SparseColMat::new(pattern, vec![0.0; nnz]);
            self.stage.symbolic = None;
        }
        Ok(self)
    }

    /// Prepares the body on a grid (see [`HyperBody::from_surface`]).
    pub fn new(grid: SparseGrid, tissue: &Tissue, fixed: &[[bool; 3]], ordering: Ordering) -> Result<Self> {
        if fixed.len() != grid.n_vertices() {
            return Err(FemError::LengthMismatch {
                what: "fixed",
                expected: grid.n_vertices(),
                found: fixed.len(),
            });
        }
        let clamp = Clamp::new(&grid, fixed);
        let (free, n_free) = number_free_dofs(&clamp.eliminated);
        if n_free == 0 {
            return Err(FemError::NothingFree);
        }
        let pattern = lower_pattern(&grid, &free, n_free);
        let nnz = pattern.row_idx().len();
        let tangent = SparseColMat::new(pattern, vec![0.0; nnz]);
        let h = grid.cell_size();
        let terms = ForceTerms {
            clamp: ClampTerm { points: clamp.points, beta: clamp_stiffness(tissue, h) },
            contact: ContactTerm { samples: surface_samples(&grid, fixed) },
            grasps: GraspSet::default(),
            dynamics: None,
            pressures: PressureTerm::default(),
        };
        let materials = vec![CellMaterial::of(tissue); grid.n_cells()];
        let states = LawStates::new(&materials);
        let model = HyperModel {
            cell: HyperCell::new(h),
            materials,
            densities: vec![tissue.density(); grid.n_cells()],
            region_ids: vec![0; grid.n_cells()],
            tissues: vec![*tissue],
            shares: vec![1.0; grid.n_cells()],
            grid,
            tissue: *tissue,
            free,
            n_free,
        };
        Ok(Self {
            model: Arc::new(model),
            terms,
            stage: NewtonStage { tangent, symbolic: None, levels: None, ordering },
            states,
            settings: NewtonSettings::default(),
        })
    }

    /// The same body with regions of other tissues ([`crate::blend_regions`]: each cell's
    /// moduli and density blended from the tissues its samples fall in).
    ///
    /// Errors: a region outside the body, a malformed region surface.
    pub fn with_regions(mut self, regions: &[crate::Region]) -> Result<Self> {
        if regions.is_empty() {
            return Ok(self);
        }
        let blend = crate::blend_regions(&self.model.grid, &self.model.tissue, regions)?;
        let model = Arc::make_mut(&mut self.model);
        model.materials = blend.materials;
        model.densities = blend.densities;
        model.region_ids = blend.region_ids;
        model.shares = blend.shares;
        model.tissues = std::iter::once(model.tissue).chain(regions.iter().map(|r| r.tissue)).collect();
        self.states = LawStates::new(&self.model.materials);
        Ok(self)
    }

    /// The same body with every cell's law replaced by `law` (each cell keeps its moduli);
    /// the laws' state starts at rest. A law defined outside this crate enters here.
    pub fn with_law(mut self, law: Arc<dyn MaterialLaw>) -> Self {
        for m in &mut Arc::make_mut(&mut self.model).materials {
            m.law = law.clone();
        }
        self.states = LawStates::new(&self.model.materials);
        self
    }

    /// The laws' per-point state.
    pub fn law_states(&self) -> &LawStates {
        &self.states
    }

    /// Commits every Gauss point's law state at the node displacements `u` (one per grid
    /// node, m: a [`HyperSolution`]'s) after a converged step of `dt` seconds
    /// ([`MaterialLaw::commit_state`]); nothing for stateless laws.
    ///
    /// # Panics
    /// When `u` does not have one entry per grid node.
    #[track_caller]
    pub fn commit_law_states(&mut self, u: &[Vec3], dt: f64) {
        assert_eq!(u.len(), self.model.grid.n_nodes(), "one displacement per node");
        if self.states.is_empty() {
            return;
        }
        for (c, nodes) in self.model.grid.cell_nodes().iter().enumerate() {
            let m = &self.model.materials[c];
            let len = m.law.state_len();
            if len == 0 {
                continue;
            }
            let local = nodes.map(|n| u[n]);
            let fs = self.model.cell.deformation_gradients(&local);
            let theta = fs.iter().map(crate::law::det).sum::<f64>() / 8.0;
            let cell = self.states.cell_mut(c);
            if let Some(first) = cell.get_mut(..len) {
                m.law.commit_volumetric(theta, &m.moduli(), first, dt);
            }
            for (p, state) in cell.chunks_mut(len).enumerate() {
                m.law.commit_state(&fs[p], &m.moduli(), state, dt);
            }
        }
    }

    /// Each cell's region id (0: the body's tissue, `k`: the `k`-th region).
    pub fn region_ids(&self) -> &[u16] {
        &self.model.region_ids
    }

    /// The same body with other Newton settings.
    pub fn with_settings(mut self, settings: NewtonSettings) -> Self {
        self.settings = settings;
        self
    }

    /// The grid.
    pub fn grid(&self) -> &SparseGrid {
        &self.model.grid
    }

    /// The free-dof vector of `loads` (gravity by each cell's density, point forces) on
    /// this body.
    pub(crate) fn external_loads(&self, loads: &Loads) -> Result<Vec<f64>> {
        load_vector(&self.model.grid, |c| self.model.densities[c], &self.model.free, self.model.n_free, loads)
    }

    /// The tissue.
    pub fn tissue(&self) -> &Tissue {
        &self.model.tissue
    }

    /// Unknowns (free degrees of freedom).
    pub fn dofs(&self) -> usize {
        self.model.n_free
    }

    /// Stored nonzeros of the tangent's lower triangle.
    pub fn nonzeros(&self) -> usize {
        self.stage.tangent.val().len()
    }

    /// Stored values of the tangent's Cholesky factor (0 before a direct solve: the
    /// multigrid solver makes none).
    pub fn factor_nonzeros(&self) -> usize {
        self.stage.symbolic.as_ref().map_or(0, |s| s.factor_len())
    }

    /// Node displacements from a free-dof vector (0 on fixed dofs).
    pub(crate) fn node_field(&self, x: &[f64]) -> Vec<Vec3> {
        (0..self.model.grid.n_nodes())
            .map(|n| {
                std::array::from_fn(|a| match self.model.free[3 * n + a] {
                    crate::assemble::FIXED => 0.0,
                    f => x[f],
                })
            })
            .collect()
    }

    /// Each cell's state and their extremes for node displacements `u`.
    pub(crate) fn cell_states(&self, u: &[Vec3]) -> (Vec<CellState>, StrainSummary) {
        let cells = self.model.grid.cell_nodes().iter().enumerate();
        let states = cells.map(|(c, nodes)| {
            self.model.cell.state_with(&self.model.materials[c], &nodes.map(|n| u[n]), self.states.cell(c))
        });
        summarize(&self.model.grid, states.collect())
    }

    /// Each cell's law and moduli.
    pub fn materials(&self) -> &[CellMaterial] {
        &self.model.materials
    }
}

/// Each cell's strain, `J` and stress (of its own law) for node displacements `u` on `grid`,
/// and their extremes over the cells at least [`SUMMARY_FILL`] inside: the large-strain
/// measures of any answer, a linear one included (whose Green–Lagrange strain then shows
/// the rotations it cannot represent).
///
/// # Panics
/// When `u` does not have one entry per grid node or `materials` one per cell.
#[track_caller]
pub fn cell_states(
    grid: &SparseGrid,
    materials: &[CellMaterial],
    u: &[Vec3],
) -> (Vec<CellState>, StrainSummary) {
    assert_eq!(u.len(), grid.n_nodes(), "one displacement per node");
    assert_eq!(materials.len(), grid.n_cells(), "one material per cell");
    let cell = HyperCell::new(grid.cell_size());
    let cells: Vec<CellState> = grid
        .cell_nodes()
        .iter()
        .zip(materials)
        .map(|(nodes, m)| cell.state(m, &nodes.map(|n| u[n])))
        .collect();
    summarize(grid, cells)
}

/// The cells' states and their extremes over the cells at least [`SUMMARY_FILL`] inside.
fn summarize(grid: &SparseGrid, cells: Vec<CellState>) -> (Vec<CellState>, StrainSummary) {
    let mut s = StrainSummary {
        j_min: f64::INFINITY,
        j_max: f64::NEG_INFINITY,
        max_principal_strain: f64::NEG_INFINITY,
        max_strain_magnitude: 0.0,
        max_von_mises: 0.0,
    };
    let tissue =
        |c: &(&CellState, &f64)| *c.1 >= SUMMARY_FILL || grid.fill().iter().all(|&f| f < SUMMARY_FILL);
    for (c, _) in cells.iter().zip(grid.fill()).filter(tissue) {
        s.j_min = s.j_min.min(c.j_min);
        s.j_max = s.j_max.max(c.j_max);
        s.max_principal_strain = s.max_principal_strain.max(c.max_principal_strain);
        s.max_strain_magnitude = s.max_strain_magnitude.max(c.strain_magnitude);
        s.max_von_mises = s.max_von_mises.max(c.von_mises);
    }
    (cells, s)
}

/// Every force term of a body besides its tissue.
pub(crate) struct ForceTerms {
    pub(crate) clamp: ClampTerm,
    pub(crate) contact: ContactTerm,
    pub(crate) grasps: GraspSet,
    /// Inertia and damping over a time step (a timed solve with `inertia` or damping only).
    pub(crate) dynamics: Option<DynamicsTerm>,
    /// Pressures on faces of the surface.
    pub(crate) pressures: PressureTerm,
}

impl ForceTerms {
    /// The terms, in the order their energies are summed.
    pub(crate) fn each(&self) -> Vec<&dyn ForceTerm> {
        let mut terms: Vec<&dyn ForceTerm> = vec![&self.clamp, &self.contact, &self.grasps];
        if let Some(d) = &self.dynamics {
            terms.push(d);
        }
        if !self.pressures.is_empty() {
            terms.push(&self.pressures);
        }
        terms
    }
}
