//! Sparse-grid finite elements: static linear elasticity of a body bounded by a closed
//! triangle surface, the project's reference ("yardstick") method.
//!
//! # The problem
//! Find the displacement `u` with `div sigma + rho g = 0`, `sigma = lambda tr(eps) I +
//! 2 mu eps`, `eps = (grad u + grad u^T) / 2`, zero displacement on the fixed axes and point
//! forces on surface vertices. Equivalently minimize
//! `integral of mu |dev eps|^2 + kappa/2 (tr eps)^2 - rho g . u` minus the point forces' work,
//! with `mu = E / (2 (1 + nu))`, `kappa = E / (3 (1 - 2 nu))`.
//!
//! # Discretization (SOFA's sparse grid)
//! - [`SparseGrid`]: a regular grid of cubes of edge `h = longest bounding-box side /
//!   resolution`, centred on the box; the active cells are those holding a surface vertex or
//!   an inside sample point. Each cell's fill fraction `phi` (the share of its 4^3 sub-cell
//!   centres inside the surface, by exact ray crossings, [`fibfluid_geometry::inside_lattice`])
//!   scales its stiffness and its mass, so partly filled boundary cells carry only the
//!   material they contain.
//! - Each cell is a trilinear (Q1, 8-node) hexahedron. **Locking**: the volumetric energy
//!   `kappa (tr eps)^2` uses the cell's mean dilatation (B-bar, Hughes 1980), which on a cube
//!   equals selective reduced integration of that term at the cell centre; the deviatoric
//!   energy `2 mu |dev eps|^2` is integrated with 2x2x2 Gauss points. As nu -> 0.5 only one
//!   volumetric constraint per cell remains, so the element does not lock
//!   ([`Element::FullQ1`] integrates everything fully and does lock, for comparison).
//! - The surface is embedded: vertex `v` in cell `c` moves with the trilinear interpolation
//!   `u(v) = sum_b w_b u_b` of the cell's 8 nodes; a point force `F` on `v` puts `w_b F` on
//!   node `b` (virtual work). Gravity puts `phi rho g h^3 / 8` on each node of each cell.
//! - Fixed vertices: the fixed part of the surface (triangles whose three vertices are fixed,
//!   and isolated fixed vertices) is held by an area-weighted penalty on its embedded points,
//!   `beta = CLAMP_PENALTY * E / h` per unit area (see [`FemBody`], [`CLAMP_PENALTY`]); a
//!   point on a grid node fixes that node exactly.
//!
//! # Linear algebra
//! K (symmetric positive definite once rigid motions are fixed) is stored as its lower
//! triangle in compressed columns and factored once by faer's sparse Cholesky (supernodal
//! when it pays, through `fibfluid_linalg::SparseCholesky`), ordered by nested dissection along grid planes ([`Ordering`]; faer's AMD
//! on request, [`FemBody::with_ordering`]). [`FemBody::solve_many`] solves several loads in one pass over
//! the factor; [`FemBody::respond_held`] holds surface vertices at given displacements by a
//! capacitance update of the same factor, with compliance columns cached per held vertex.
//!
//! # Entry points
//! [`Tissue`], [`GridEstimate::of`] (sizes before any allocation), [`SparseGrid`],
//! [`FemBody`], [`Loads`], [`FemSolution`], [`HeldResponse`], [`FemStats`], [`FemError`].

mod assemble;
mod body;
mod clamp;
mod element;
mod error;
mod grid;
mod held;
mod held_affine;
mod held_basis;
mod held_rows;
mod held_system;
pub mod hyper;
pub mod law;
mod multigrid;
mod ordering;
mod region;
mod rigid;
mod tissue;

pub use body::{FemBody, FemSolution, FemStats, Loads, RESIDUAL_LIMIT};
pub use clamp::CLAMP_PENALTY;
pub use clamp::fixed_surface_samples;
pub use error::{FemError, NotConvergedWhy, Result};
pub use grid::{
    CellFill, DEFAULT_RESOLUTION, Element, Embedded, FemOptions, GridEstimate, MAX_CELLS, MAX_RESOLUTION,
    MIN_FILL, MULTIGRID_ITERATIONS, SNAP, SUBSAMPLES, SparseGrid,
};
pub use held_rows::FemHold;
pub use held_system::HeldResponse;
pub use multigrid::{COARSEST_NODES, FemSolver, MAX_PCG_ITERATIONS, MULTIGRID_CROSSOVER_DOFS};
pub use ordering::{ND_LEAF, Ordering};
pub use region::{CellBlend, Region, RegionShape, blend_regions};
pub use rigid::{RIGID_MODE_TOLERANCE, RigidMode, check_rigid_modes, free_rigid_modes};
pub use tissue::{MAX_PRONY_TERMS, Relaxation, Tissue, TissueModel, TissueParameter};
