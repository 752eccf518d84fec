//! The sparse voxel grid over a closed surface: active cells, their nodes and fill
//! fractions, and the trilinear embedding of the surface vertices.

use fibfluid_geometry::{PointLattice, Vec3, bounding_box, for_each_inside_line};
use serde::Serialize;

use crate::error::{FemError, Result};

/// Cells along the bounding box's longest side when nothing else is asked for: 24 is the
/// lowest tried that keeps all three test bodies within 15 % of an independent quadratic
/// tetrahedral FEM (relative L2 of the surface displacement: sphere 0.033, liver 0.017, cow
/// 0.068; at 16 and 20 the cow is at 0.154 and 0.134). The sphere (29k unknowns) factors in
/// ~0.7 s on two loaded cores with the nested-dissection ordering; see `docs/fem.md`.
pub const DEFAULT_RESOLUTION: usize = 24;

/// Largest resolution accepted.
pub const MAX_RESOLUTION: usize = 256;

/// Largest number of cells of the full grid (active or not) accepted.
pub const MAX_CELLS: usize = 1 << 22;

/// Sample points per cell and axis for the fill fraction (`SUBSAMPLES^3` per cell).
pub const SUBSAMPLES: usize = 4;

/// Fill fraction given to a cell that holds a surface vertex but none of whose sample
/// points is inside (half of one sample's share).
pub const MIN_FILL: f64 = 0.5 / (SUBSAMPLES * SUBSAMPLES * SUBSAMPLES) as f64;

/// Trilinear coordinates closer than this (in cell units) to 0 or 1 are snapped to it, so
/// a vertex on a grid plane has exactly zero weight on the nodes off the plane.
pub const SNAP: f64 = 1e-9;

/// Empirical constant of the factor size estimate `nnz(L) ~ FACTOR_NNZ_COEFF * dofs^(4/3)`
/// (faer's AMD ordering on the test bodies; an estimate, not a bound).
const FACTOR_NNZ_COEFF: f64 = 40.0;
/// Empirical constant of the factorization flop estimate `FACTOR_FLOP_COEFF * dofs^2`.
const FACTOR_FLOP_COEFF: f64 = 6.0;

/// Options of the sparse-grid FEM.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FemOptions {
    /// Cells along the bounding box's longest side (1..=[`MAX_RESOLUTION`]).
    pub resolution: usize,
    /// The element formulation.
    pub element: Element,
}

impl Default for FemOptions {
    fn default() -> Self {
        Self { resolution: DEFAULT_RESOLUTION, element: Element::BBar }
    }
}

/// The hexahedral element.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub enum Element {
    /// Trilinear (Q1) displacement, deviatoric part integrated with 2x2x2 Gauss points,
    /// volumetric part with the cell's mean dilatation (B-bar): locking-free.
    #[default]
    BBar,
    /// Plain Q1 with full 2x2x2 integration of everything. Locks as nu -> 0.5; kept only to
    /// show (in tests) what B-bar avoids.
    FullQ1,
}

/// The grid a surface would get, from its bounding box only: upper bounds of the work,
/// known before anything is allocated.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GridEstimate {
    /// The resolution.
    pub resolution: usize,
    /// Cell edge length.
    pub cell_size: f64,
    /// Cells per axis of the full grid.
    pub dims: [usize; 3],
    /// Cells of the full grid (upper bound of the active cells).
    pub cells: usize,
    /// Grid nodes of the full grid (upper bound of the nodes).
    pub nodes: usize,
    /// `3 * nodes` (upper bound of the unknowns).
    pub dofs: usize,
    /// Upper bound of the stored nonzeros of K's lower triangle (41 per dof: 27 nodes x 3,
    /// halved, plus the diagonal).
    pub nonzeros: usize,
    /// Estimated nonzeros of the Cholesky factor (empirical `~ dofs^(4/3)`).
    pub factor_nonzeros: f64,
    /// Estimated bytes of K and the factor.
    pub factor_bytes: f64,
    /// Estimated flops of the factorization (empirical `~ dofs^2`).
    pub factor_flops: f64,
    /// Estimated bytes of the multigrid solver: the tangent, its node-block copy and
    /// coarser levels, and the conjugate-gradient vectors (linear in the unknowns).
    pub multigrid_bytes: f64,
    /// Estimated flops of one multigrid-preconditioned solve ([`MULTIGRID_ITERATIONS`]
    /// iterations; linear in the unknowns).
    pub multigrid_flops: f64,
}

/// Conjugate-gradient iterations a multigrid solve is estimated to take (a V-cycle
/// preconditioner on the hanging bodies takes 10 to 40).
pub const MULTIGRID_ITERATIONS: f64 = 40.0;
/// Bytes per unknown of the multigrid solver: the tangent's lower triangle (41 entries of
/// 16 bytes), its node-block copy with the coarser levels (27 blocks of 76 bytes per node,
/// times 8/7) and 20 work vectors.
const MULTIGRID_BYTES_PER_DOF: f64 = 41.0 * 16.0 + 27.0 * 76.0 / 3.0 * 8.0 / 7.0 + 20.0 * 8.0;
/// Flops per unknown of one preconditioned iteration: a V-cycle's 7 block-row products
/// per level (27 blocks of 18 flops per node), times 8/7 for the coarser levels, and the
/// iteration's own product and vector updates.
const MULTIGRID_FLOPS_PER_DOF: f64 = (7.0 * 8.0 / 7.0 + 1.0) * 27.0 * 18.0 / 3.0 + 20.0;

impl GridEstimate {
    /// The grid of a surface with these vertex positions at `resolution`: cell size
    /// `h = longest extent / resolution`, `ceil(extent / h)` cells per axis, centred on the
    /// bounding box.
    ///
    /// Errors: resolution 0 or above [`MAX_RESOLUTION`], no vertex, a non-finite vertex, a
    /// body thinner than one cell along an axis ([`FemError::ThinnerThanCell`]), more than
    /// [`MAX_CELLS`] cells.
    pub fn of(positions: &[Vec3], resolution: usize) -> Result<Self> {
        if resolution == 0 || resolution > MAX_RESOLUTION {
            return Err(FemError::InvalidResolution { resolution, max: MAX_RESOLUTION });
        }
        if positions.is_empty() {
            return Err(FemError::EmptySurface { vertices: 0, triangles: 0 });
        }
        if let Some(v) = positions.iter().position(|p| p.iter().any(|x| !x.is_finite())) {
            return Err(fibfluid_geometry::MeshError::NonFiniteVertex { vertex: v }.into());
        }
        let (lo, hi) = bounding_box(positions);
        let extent = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
        let longest = extent.iter().fold(0.0_f64, |a, &b| a.max(b));
        let h = longest / resolution as f64;
        let mut dims = [0usize; 3];
        for a in 0..3 {
            if !(extent[a] >= h * (1.0 - SNAP)) || !(h > 0.0) {
                return Err(FemError::ThinnerThanCell {
                    axis: ['x', 'y', 'z'][a],
                    thickness: extent[a],
                    cell: h,
                });
            }
            dims[a] = ((extent[a] / h - SNAP).ceil() as usize).max(1);
        }
        let cells = dims.iter().map(|&d| d as u128).product::<u128>();
        if cells > MAX_CELLS as u128 {
            // Cells grow as the resolution's cube: the largest resolution below the limit.
            let mut fits = ((resolution as f64) * (MAX_CELLS as f64 / cells as f64).cbrt()) as usize;
            while fits > 1 && Self::of(positions, fits).is_err() {
                fits -= 1;
            }
            return Err(FemError::TooManyCells { cells, limit: MAX_CELLS, resolution, fits: fits.max(1) });
        }
        let nodes = (dims[0] + 1) * (dims[1] + 1) * (dims[2] + 1);
        let dofs = 3 * nodes;
        let nonzeros = 41 * dofs;
        let n = dofs as f64;
        let factor_nonzeros = (FACTOR_NNZ_COEFF * n.powf(4.0 / 3.0)).min(n * (n + 1.0) / 2.0);
        let factor_flops = (FACTOR_FLOP_COEFF * n * n).min(n * n * n / 3.0);
        let factor_bytes = 8.0 * factor_nonzeros + 16.0 * nonzeros as f64;
        Ok(Self {
            resolution,
            cell_size: h,
            dims,
            cells: cells as usize,
            nodes,
            dofs,
            nonzeros,
            factor_nonzeros,
            factor_bytes,
            factor_flops,
            multigrid_bytes: MULTIGRID_BYTES_PER_DOF * n,
            multigrid_flops: MULTIGRID_ITERATIONS * MULTIGRID_FLOPS_PER_DOF * n,
        })
    }

    /// The bytes and flops of one solve with `solver` (as [`crate::FemSolver::resolve`]
    /// picks for these unknowns): the factor's or the multigrid's.
    pub fn solver_cost(&self, solver: crate::FemSolver) -> (f64, f64) {
        match solver.resolve(self.dofs) {
            crate::FemSolver::Multigrid => (self.multigrid_bytes, self.multigrid_flops),
            _ => (self.factor_bytes, self.factor_flops),
        }
    }

    /// Whether `solver` resolves to the direct solver on this grid.
    pub fn uses_direct_solver(&self, solver: crate::FemSolver) -> bool {
        solver.resolve(self.dofs) == crate::FemSolver::Direct
    }

    /// Position of grid node `(0, 0, 0)` for the bounding box `lo..hi`: the grid is centred on
    /// the box.
    fn origin(&self, lo: Vec3, hi: Vec3) -> Vec3 {
        std::array::from_fn(|a| 0.5 * (lo[a] + hi[a]) - 0.5 * self.dims[a] as f64 * self.cell_size)
    }
}

/// Where a surface vertex sits in the grid: its cell and the trilinear weights of the
/// cell's eight nodes (corner `b` at grid offset `(b & 1, (b >> 1) & 1, (b >> 2) & 1)`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Embedded {
    /// Index of the active cell holding the vertex.
    pub cell: usize,
    /// Node indices of the cell's corners.
    pub nodes: [usize; 8],
    /// Trilinear weights (non-negative, summing to 1).
    pub weights: [f64; 8],
}

/// The fill of one cell by octant: `points[p]` is the share of tissue in the octant of
/// the cell around Gauss point `p` (corner order as in [`Embedded`]). The hyperelastic cell
/// weights each Gauss point's energy by it and takes its mean dilatation over the tissue
/// only, so a cut cell's tissue stores its energy where it is rather than spread evenly
/// over the cell (the spread stiffened a thick sphere under pressure by 4 % of its stretch
/// at 6 cells through the wall).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CellFill {
    /// Tissue share of each octant, in `[0, 1]`.
    pub points: [f64; 8],
}

impl CellFill {
    /// `fill` in every octant.
    pub fn uniform(fill: f64) -> Self {
        Self { points: [fill; 8] }
    }

    /// The cell's fill fraction (the octants' mean).
    pub fn mean(&self) -> f64 {
        self.points.iter().sum::<f64>() / 8.0
    }
}

impl From<f64> for CellFill {
    fn from(fill: f64) -> Self {
        Self::uniform(fill)
    }
}

/// The active cells of a regular grid over a closed surface, their nodes and fill
/// fractions, and the embedding of every surface vertex.
#[derive(Debug, Clone)]
pub struct SparseGrid {
    estimate: GridEstimate,
    origin: Vec3,
    cell_coords: Vec<[usize; 3]>,
    cell_nodes: Vec<[usize; 8]>,
    fill: Vec<f64>,
    octants: Vec<[u8; 8]>,
    node_coords: Vec<[usize; 3]>,
    cell_id: Vec<usize>,
    embedding: Vec<Embedded>,
    positions: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
}

impl SparseGrid {
    /// Voxelizes a closed surface at `resolution` (see [`GridEstimate::of`] for the grid).
    ///
    /// A cell is active when one of its `SUBSAMPLES^3` sample points (the centres of its
    /// sub-cells) is inside the surface, or when it holds a surface vertex. Its fill fraction
    /// is the share of inside samples ([`MIN_FILL`] if none); stiffness and body force are
    /// scaled by it. Each vertex is embedded in the cell that contains it (lower cell on a
    /// shared face) with trilinear weights.
    ///
    /// Errors: those of [`GridEstimate::of`], no triangle, a triangle index out of range.
    pub fn from_surface(positions: &[Vec3], triangles: &[[u32; 3]], resolution: usize) -> Result<Self> {
        let estimate = GridEstimate::of(positions, resolution)?;
        if triangles.is_empty() {
            return Err(FemError::EmptySurface { vertices: positions.len(), triangles: 0 });
        }
        let (lo, hi) = bounding_box(positions);
        let origin = estimate.origin(lo, hi);
        let [nx, ny, nz] = estimate.dims;
        let h = estimate.cell_size;
        let cell_index = |c: [usize; 3]| c[0] + nx * (c[1] + ny * c[2]);
        let mut inside_count = vec![0u16; estimate.cells];
        let mut octant_count = vec![[0u8; 8]; estimate.cells];
        let s = SUBSAMPLES;
        let samples = PointLattice {
            origin: origin.map(|o| o + 0.5 * h / s as f64),
            spacing: h / s as f64,
            dims: [nx * s, ny * s, nz * s],
        };
        for_each_inside_line(positions, triangles, &samples, |j, k, line| {
            let row = nx * (j / s + ny * (k / s));
            let half = |x: usize| usize::from(x % s >= s / 2);
            let octant_jk = 2 * half(j) + 4 * half(k);
            for (i, &inside) in line.iter().enumerate() {
                inside_count[row + i / s] += inside as u16;
                octant_count[row + i / s][octant_jk + half(i)] += inside as u8;
            }
        })?;
        let located: Vec<([usize; 3], [f64; 3])> =
            positions.iter().map(|&p| locate(p, origin, h, estimate.dims)).collect();
        let mut holds_vertex = vec![false; estimate.cells];
        for (c, _) in &located {
            holds_vertex[cell_index(*c)] = true;
        }
        let mut cell_id = vec![usize::MAX; estimate.cells];
        let mut cell_coords = Vec::new();
        let mut fill = Vec::new();
        let mut octants = Vec::new();
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let g = cell_index([i, j, k]);
                    if inside_count[g] > 0 || holds_vertex[g] {
                        cell_id[g] = cell_coords.len();
                        cell_coords.push([i, j, k]);
                        fill.push((inside_count[g] as f64 / (s * s * s) as f64).max(MIN_FILL));
                        octants.push(octant_count[g]);
                    }
                }
            }
        }
        let (node_coords, cell_nodes) = number_nodes(&cell_coords, estimate.dims);
        let embedding = located
            .iter()
            .map(|(c, t)| {
                let cell = cell_id[cell_index(*c)];
                Embedded { cell, nodes: cell_nodes[cell], weights: trilinear_weights(*t) }
            })
            .collect();
        Ok(Self {
            estimate,
            origin,
            cell_coords,
            cell_nodes,
            fill,
            octants,
            node_coords,
            cell_id,
            embedding,
            positions: positions.to_vec(),
            triangles: triangles.to_vec(),
        })
    }

    /// The grid's sizes (the full grid's counts; see [`SparseGrid::n_cells`] for the active
    /// ones).
    pub fn estimate(&self) -> &GridEstimate {
        &self.estimate
    }

    /// The resolution the grid was built at.
    pub fn resolution(&self) -> usize {
        self.estimate.resolution
    }

    /// Cell edge length.
    pub fn cell_size(&self) -> f64 {
        self.estimate.cell_size
    }

    /// Position of grid node `(0, 0, 0)`.
    pub fn origin(&self) -> Vec3 {
        self.origin
    }

    /// Number of active cells.
    pub fn n_cells(&self) -> usize {
        self.cell_coords.len()
    }

    /// Number of nodes (corners of active cells).
    pub fn n_nodes(&self) -> usize {
        self.node_coords.len()
    }

    /// Number of embedded surface vertices.
    pub fn n_vertices(&self) -> usize {
        self.embedding.len()
    }

    /// Grid coordinates `(i, j, k)` of every active cell.
    pub fn cell_coords(&self) -> &[[usize; 3]] {
        &self.cell_coords
    }

    /// Grid coordinates `(i, j, k)` of every node (node `(0, 0, 0)` at [`SparseGrid::origin`]).
    pub fn node_coords(&self) -> &[[usize; 3]] {
        &self.node_coords
    }

    /// The eight node indices of every active cell (corner order as in [`Embedded`]).
    pub fn cell_nodes(&self) -> &[[usize; 8]] {
        &self.cell_nodes
    }

    /// Fill fraction of every active cell, in `(0, 1]`.
    pub fn fill(&self) -> &[f64] {
        &self.fill
    }

    /// The fill of active cell `c` by octant: where in the cell its tissue is, for the
    /// hyperelastic cell's quadrature ([`CellFill`]).
    pub fn cell_fill(&self, c: usize) -> CellFill {
        let counts = self.octants[c];
        let per_octant = (SUBSAMPLES / 2).pow(3) as f64;
        if counts.iter().all(|&n| n == 0) {
            return CellFill::uniform(self.fill[c]);
        }
        CellFill { points: counts.map(|n| n as f64 / per_octant) }
    }

    /// Filled volume: `sum fill * h^3`.
    pub fn filled_volume(&self) -> f64 {
        self.fill.iter().sum::<f64>() * self.cell_size().powi(3)
    }

    /// Rest position of node `n`.
    ///
    /// # Panics
    /// When `n >= n_nodes()`.
    #[track_caller]
    pub fn node_position(&self, n: usize) -> Vec3 {
        let c = self.node_coords[n];
        std::array::from_fn(|a| self.origin[a] + c[a] as f64 * self.cell_size())
    }

    /// Rest positions of every node.
    pub fn node_positions(&self) -> Vec<Vec3> {
        (0..self.n_nodes()).map(|n| self.node_position(n)).collect()
    }

    /// The embedding of every surface vertex.
    pub fn embedding(&self) -> &[Embedded] {
        &self.embedding
    }

    /// The rest positions of the surface vertices.
    pub fn surface_positions(&self) -> &[Vec3] {
        &self.positions
    }

    /// The surface triangles.
    pub fn surface_triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// The active cell holding point `p` and its trilinear weights there (as a surface
    /// vertex is embedded), or `None` when that cell is not active or `p` is off the grid by
    /// more than [`SNAP`] cells.
    pub fn locate(&self, p: Vec3) -> Option<Embedded> {
        let h = self.cell_size();
        for a in 0..3 {
            let x = (p[a] - self.origin[a]) / h;
            if !(x >= -SNAP && x <= self.estimate.dims[a] as f64 + SNAP) {
                return None;
            }
        }
        let (c, t) = locate(p, self.origin, h, self.estimate.dims);
        let [nx, ny, _] = self.estimate.dims;
        let cell = self.cell_id[c[0] + nx * (c[1] + ny * c[2])];
        (cell != usize::MAX).then(|| Embedded {
            cell,
            nodes: self.cell_nodes[cell],
            weights: trilinear_weights(t),
        })
    }

    /// Trilinear interpolation of node values at every surface vertex.
    ///
    /// # Panics
    /// When `node_values.len() != n_nodes()`.
    #[track_caller]
    pub fn interpolate(&self, node_values: &[Vec3]) -> Vec<Vec3> {
        assert_eq!(node_values.len(), self.n_nodes(), "one value per node");
        self.embedding
            .iter()
            .map(|e| {
                let mut p = [0.0; 3];
                for b in 0..8 {
                    for a in 0..3 {
                        p[a] += e.weights[b] * node_values[e.nodes[b]][a];
                    }
                }
                p
            })
            .collect()
    }
}

/// The cell holding `p` (clamped to the grid) and the trilinear coordinates of `p` in it,
/// snapped to 0 or 1 within [`SNAP`].
fn locate(p: Vec3, origin: Vec3, h: f64, dims: [usize; 3]) -> ([usize; 3], [f64; 3]) {
    let mut cell = [0usize; 3];
    let mut t = [0.0; 3];
    for a in 0..3 {
        let x = (p[a] - origin[a]) / h;
        let c = x.floor().clamp(0.0, (dims[a] - 1) as f64);
        let mut f = (x - c).clamp(0.0, 1.0);
        if f < SNAP {
            f = 0.0;
        } else if f > 1.0 - SNAP {
            f = 1.0;
        }
        cell[a] = c as usize;
        t[a] = f;
    }
    (cell, t)
}

/// Weights of the eight corners for trilinear coordinates `t`.
fn trilinear_weights(t: [f64; 3]) -> [f64; 8] {
    std::array::from_fn(|b| {
        let f = |a: usize| if (b >> a) & 1 == 1 { t[a] } else { 1.0 - t[a] };
        f(0) * f(1) * f(2)
    })
}

/// Numbers the corners of the active cells in grid order (x fastest); returns each node's
/// grid coordinates and each cell's eight node indices.
fn number_nodes(cell_coords: &[[usize; 3]], dims: [usize; 3]) -> (Vec<[usize; 3]>, Vec<[usize; 8]>) {
    let nd = [dims[0] + 1, dims[1] + 1, dims[2] + 1];
    let node_index = |c: [usize; 3]| c[0] + nd[0] * (c[1] + nd[1] * c[2]);
    let corner = |c: [usize; 3], b: usize| [c[0] + (b & 1), c[1] + ((b >> 1) & 1), c[2] + ((b >> 2) & 1)];
    let mut used = vec![false; nd[0] * nd[1] * nd[2]];
    for &c in cell_coords {
        for b in 0..8 {
            used[node_index(corner(c, b))] = true;
        }
    }
    let mut id = vec![usize::MAX; used.len()];
    let mut node_coords = Vec::new();
    for k in 0..nd[2] {
        for j in 0..nd[1] {
            for i in 0..nd[0] {
                if used[node_index([i, j, k])] {
                    id[node_index([i, j, k])] = node_coords.len();
                    node_coords.push([i, j, k]);
                }
            }
        }
    }
    let cell_nodes =
        cell_coords.iter().map(|&c| std::array::from_fn(|b| id[node_index(corner(c, b))])).collect();
    (node_coords, cell_nodes)
}
