//! The assembled, constrained and factored body; loads and solutions.

use std::time::Instant;

use faer::Mat;
use faer::sparse::SparseColMat;
use fibfluid_geometry::Vec3;
use fibfluid_linalg::SparseCholesky;
use serde::Serialize;

use crate::assemble::{FIXED, add_penalty, assemble_lower, cell_matrix, number_free_dofs, symmetric_mul};
use crate::clamp::{Clamp, clamp_stiffness};
use crate::error::{FemError, Result};
use crate::grid::{Element, FemOptions, SparseGrid};
use crate::ordering::{Ordering, symbolic_analysis};
use crate::tissue::Tissue;

/// Largest accepted relative residual `|K u - f| / |f|` of a solve.
pub const RESIDUAL_LIMIT: f64 = 1e-8;

/// Static loads: a uniform acceleration acting on the tissue's mass, and point forces on
/// surface vertices.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Loads {
    /// Gravitational acceleration, m/s^2 (body force `rho g` per unit volume).
    pub gravity: Vec3,
    /// `(surface vertex, force in N)`; several forces on one vertex add up.
    pub point_forces: Vec<(usize, Vec3)>,
}

/// The static response to one [`Loads`].
#[derive(Debug, Clone, PartialEq)]
pub struct FemSolution {
    /// Displacement of every grid node (0 on fixed axes).
    pub node_displacements: Vec<Vec3>,
    /// Displacement of every surface vertex (trilinear interpolation of its cell's nodes).
    pub surface_displacements: Vec<Vec3>,
    /// The measured relative residual `|K u - f| / |f|` over the free dofs (0 when `f = 0`).
    pub residual: f64,
}

/// Sizes and timings of a body, for reports.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FemStats {
    /// Cells along the longest side.
    pub resolution: usize,
    /// Active cells.
    pub cells: usize,
    /// Grid nodes.
    pub nodes: usize,
    /// Free degrees of freedom (unknowns).
    pub dofs: usize,
    /// Stored nonzeros of K's lower triangle.
    pub nonzeros: usize,
    /// Stored values of the Cholesky factor.
    pub factor_nonzeros: usize,
    /// Seconds to build the grid's stiffness (pattern and values).
    pub assembly_seconds: f64,
    /// Seconds of the sparse Cholesky (ordering, symbolic and numeric).
    pub factor_seconds: f64,
    /// Seconds of the last [`FemBody::solve`] (0 before the first).
    pub solve_seconds: f64,
}

/// A sparse-grid body with its clamp imposed and K factored once.
///
/// The clamp acts on the fixed part of the *surface*, not on whole cells: every surface
/// triangle whose three vertices are fixed along axis `a` is sampled at most `h / 2` apart
/// ([`fixed_surface_samples`]), and each sample `p`, at trilinear weights `w` in its cell,
/// adds the penalty `beta * area_p * w w^T` on axis `a` of the cell's nodes, with
/// `beta = CLAMP_PENALTY * E / h` per unit area and `area_p` the sample's share of the
/// triangle's area ([`crate::CLAMP_PENALTY`] states the slip bound). A fixed vertex outside any
/// fully fixed triangle is one such point standing for a third of its triangles' area. A
/// point that sits on a grid node (weight 1 after snapping within [`crate::SNAP`]) fixes that
/// node's axis exactly (the dof is eliminated, see [`FemBody::is_fixed`]). Nodes outside the
/// body or a cell inside the clamp are therefore no longer held: only the embedded surface
/// is, to within the penalty's slip.
pub struct FemBody {
    pub(crate) grid: SparseGrid,
    pub(crate) tissue: Tissue,
    pub(crate) free: Vec<usize>,
    pub(crate) n_free: usize,
    pub(crate) k_lower: SparseColMat<usize, f64>,
    pub(crate) factor: SparseCholesky,
    pub(crate) stats: FemStats,
    /// Compliance columns of held vertices and the last unheld solve.
    pub(crate) held: crate::held_system::HoldCache,
}

impl std::fmt::Debug for FemBody {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FemBody").field("tissue", &self.tissue).field("stats", &self.stats).finish()
    }
}

impl FemBody {
    /// Voxelizes, assembles and factors in one call: [`SparseGrid::from_surface`] at
    /// `options.resolution`, then [`FemBody::with_element`].
    pub fn from_surface(
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        tissue: &Tissue,
        fixed: &[[bool; 3]],
        options: &FemOptions,
    ) -> Result<Self> {
        let grid = crate::rigid::checked_grid(positions, triangles, fixed, options.resolution)?;
        Self::with_element(grid, tissue, fixed, options.element)
    }

    /// Assembles and factors the B-bar body (see [`FemBody::with_element`]).
    pub fn new(grid: SparseGrid, tissue: &Tissue, fixed: &[[bool; 3]]) -> Result<Self> {
        Self::with_element(grid, tissue, fixed, Element::BBar)
    }

    /// Assembles K over the free dofs (`fixed[v][a]`: surface vertex `v` fixed along axis
    /// `a`, see the type's docs for the rule) and factors it.
    ///
    /// Errors: `fixed` not one entry per surface vertex, every dof fixed
    /// ([`FemError::NothingFree`]), too few fixed to stop rigid motion
    /// ([`FemError::NotPositiveDefinite`]).
    pub fn with_element(
        grid: SparseGrid,
        tissue: &Tissue,
        fixed: &[[bool; 3]],
        element: Element,
    ) -> Result<Self> {
        Self::with_ordering(grid, tissue, fixed, element, Ordering::default())
    }

    /// [`FemBody::with_element`] with the fill-reducing ordering of the factorization
    /// chosen (the result is the same to rounding; only fill and time differ).
    pub fn with_ordering(
        grid: SparseGrid,
        tissue: &Tissue,
        fixed: &[[bool; 3]],
        element: Element,
        ordering: Ordering,
    ) -> Result<Self> {
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
        let start = Instant::now();
        let cell = cell_matrix(&grid, tissue, element);
        let mut k_lower = assemble_lower(&grid, &cell, &free, n_free);
        let beta = clamp_stiffness(tissue, grid.cell_size());
        add_penalty(&mut k_lower, &free, &clamp.points, |p| beta * p.area);
        let assembly_seconds = start.elapsed().as_secs_f64();
        let start = Instant::now();
        let symbolic = symbolic_analysis(&grid, &free, n_free, k_lower.symbolic(), ordering)?;
        let factor = SparseCholesky::factor(&std::sync::Arc::new(symbolic), k_lower.as_ref())?;
        let factor_seconds = start.elapsed().as_secs_f64();
        let stats = FemStats {
            resolution: grid.resolution(),
            cells: grid.n_cells(),
            nodes: grid.n_nodes(),
            dofs: n_free,
            nonzeros: k_lower.val().len(),
            factor_nonzeros: factor.nonzeros(),
            assembly_seconds,
            factor_seconds,
            solve_seconds: 0.0,
        };
        Ok(Self {
            grid,
            tissue: *tissue,
            free,
            n_free,
            k_lower,
            factor,
            stats,
            held: crate::held_system::HoldCache::default(),
        })
    }

    /// The grid.
    pub fn grid(&self) -> &SparseGrid {
        &self.grid
    }

    /// The tissue.
    pub fn tissue(&self) -> &Tissue {
        &self.tissue
    }

    /// Sizes and timings.
    pub fn stats(&self) -> FemStats {
        self.stats
    }

    /// Whether axis `a` of node `n` is fixed.
    ///
    /// # Panics
    /// When `n >= grid().n_nodes()` or `a >= 3`.
    #[track_caller]
    pub fn is_fixed(&self, n: usize, a: usize) -> bool {
        assert!(a < 3);
        self.free[3 * n + a] == FIXED
    }

    /// The static response to `loads`.
    ///
    /// Errors: a vertex index out of range, a non-finite load, a residual above
    /// [`RESIDUAL_LIMIT`].
    pub fn solve(&mut self, loads: &Loads) -> Result<FemSolution> {
        Ok(self.solve_many(std::slice::from_ref(loads))?.remove(0))
    }

    /// The responses to several loads, solved in one pass over the factor.
    ///
    /// Errors: as [`FemBody::solve`].
    pub fn solve_many(&mut self, loads: &[Loads]) -> Result<Vec<FemSolution>> {
        let start = Instant::now();
        let mut rhs = Mat::<f64>::zeros(self.n_free, loads.len());
        for (j, l) in loads.iter().enumerate() {
            let f = self.load_vector(l)?;
            for (i, v) in f.into_iter().enumerate() {
                rhs[(i, j)] = v;
            }
        }
        let mut x = rhs.clone();
        self.factor.solve_in_place(x.as_mut());
        let mut out = Vec::with_capacity(loads.len());
        for j in 0..loads.len() {
            let u: Vec<f64> = (0..self.n_free).map(|i| x[(i, j)]).collect();
            let f: Vec<f64> = (0..self.n_free).map(|i| rhs[(i, j)]).collect();
            let residual = self.residual(&u, &f)?;
            let node_displacements = self.node_values(&u);
            let surface_displacements = self.grid.interpolate(&node_displacements);
            out.push(FemSolution { node_displacements, surface_displacements, residual });
        }
        self.stats.solve_seconds = start.elapsed().as_secs_f64();
        Ok(out)
    }

    /// `|K u - f| / |f|` (0 when both vanish), refused above [`RESIDUAL_LIMIT`].
    pub(crate) fn residual(&self, u: &[f64], f: &[f64]) -> Result<f64> {
        let ku = symmetric_mul(&self.k_lower, u);
        let num: f64 = ku.iter().zip(f).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt();
        let den: f64 = f.iter().map(|v| v * v).sum::<f64>().sqrt();
        let residual = if den > 0.0 { num / den } else { num };
        if !(residual <= RESIDUAL_LIMIT) {
            return Err(FemError::Residual { residual, limit: RESIDUAL_LIMIT });
        }
        Ok(residual)
    }

    /// Node displacements from the free-dof vector (0 on fixed dofs).
    pub(crate) fn node_values(&self, u: &[f64]) -> Vec<Vec3> {
        (0..self.grid.n_nodes())
            .map(|n| {
                std::array::from_fn(|a| match self.free[3 * n + a] {
                    FIXED => 0.0,
                    f => u[f],
                })
            })
            .collect()
    }

    /// The free-dof force vector of `loads` ([`load_vector`]).
    pub(crate) fn load_vector(&self, loads: &Loads) -> Result<Vec<f64>> {
        let density = self.tissue.density();
        load_vector(&self.grid, |_| density, &self.free, self.n_free, loads)
    }
}

/// The free-dof force vector of `loads`: `rho_c g fill h^3 / 8` on each node of each
/// cell `c` (`density(c)` its density), point forces spread to their cell's nodes by the trilinear weights (the
/// virtual-work-consistent loads); components on fixed dofs go to the supports.
pub(crate) fn load_vector(
    grid: &SparseGrid,
    density: impl Fn(usize) -> f64,
    free: &[usize],
    n_free: usize,
    loads: &Loads,
) -> Result<Vec<f64>> {
    if loads.gravity.iter().any(|v| !v.is_finite()) {
        return Err(FemError::NonFinite { what: "gravity" });
    }
    let mut f = vec![0.0; n_free];
    let mut add = |node: usize, axis: usize, value: f64| {
        let i = free[3 * node + axis];
        if i != FIXED {
            f[i] += value;
        }
    };
    let node_volume = grid.cell_size().powi(3) / 8.0;
    if loads.gravity != [0.0; 3] {
        for (c, (nodes, fill)) in grid.cell_nodes().iter().zip(grid.fill()).enumerate() {
            let node_mass = density(c) * node_volume;
            for &n in nodes {
                for a in 0..3 {
                    add(n, a, fill * node_mass * loads.gravity[a]);
                }
            }
        }
    }
    add_point_forces(grid.embedding(), free, &loads.point_forces, &mut f)?;
    Ok(f)
}

/// Adds point forces on surface vertices to the free-dof force vector `f`, spread to their
/// cells' nodes by the trilinear weights (components on fixed dofs go to the supports).
///
/// Errors: a vertex out of range, a non-finite force.
pub(crate) fn add_point_forces(
    embedding: &[crate::grid::Embedded],
    free: &[usize],
    forces: &[(usize, Vec3)],
    f: &mut [f64],
) -> Result<()> {
    for &(v, force) in forces {
        let e =
            embedding.get(v).ok_or(FemError::VertexOutOfRange { vertex: v, vertices: embedding.len() })?;
        if force.iter().any(|x| !x.is_finite()) {
            return Err(FemError::NonFinite { what: "point force" });
        }
        for b in 0..8 {
            for a in 0..3 {
                let i = free[3 * e.nodes[b] + a];
                if i != FIXED {
                    f[i] += e.weights[b] * force[a];
                }
            }
        }
    }
    Ok(())
}
