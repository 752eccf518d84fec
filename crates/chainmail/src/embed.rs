//! Embedding a triangle surface in the lattice voxelized from it (trilinear weights), so
//! that a ChainMail run deforms the same surface the other methods deform.

use fibfluid_geometry::vec3::Vec3;
use fibfluid_geometry::winding_number;

use crate::error::{ChainmailError, Result};
use crate::lattice::{Lattice, check_grid, check_spacing, check_surface};

/// Bytes per grid node of a lattice built by [`Lattice::embed_surface`]: the node-to-element
/// map (4) and the voxel mask (1).
pub const BYTES_PER_NODE: u64 = 5;

/// Upper bound of the bytes per chain element: positions (rest, current), grid coordinates
/// and neighbours (24 each), inverse mass and stiffness (8 each), six tetrahedra with their
/// rest volume and rest distances (6 × 72) and a TSVE material's per-axis alpha (24).
pub const BYTES_PER_ELEMENT: u64 = 4 * 24 + 2 * 8 + 6 * 72 + 24;

/// Bytes per embedded surface vertex: eight element indices and eight weights.
pub const BYTES_PER_VERTEX: u64 = 8 * 4 + 8 * 8;

/// The grid [`Lattice::embed_surface`] builds for a surface, known before anything is
/// allocated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EmbeddingGrid {
    /// Grid nodes per axis.
    pub dims: [usize; 3],
    /// Rest position of grid node `(0, 0, 0)`.
    pub origin: Vec3,
    /// Grid spacing.
    pub spacing: f64,
}

impl EmbeddingGrid {
    /// The grid for a surface with bounding box `lo..hi` at `spacing`: `ceil(extent /
    /// spacing) + 2` nodes per axis (at least 3), centred on the box, so that every point of
    /// the box lies in a grid cell at least half a spacing from the grid's border.
    ///
    /// Errors: a non-positive or non-finite spacing, a non-finite box, a grid over
    /// [`crate::MAX_GRID_NODES`].
    pub fn for_box(lo: Vec3, hi: Vec3, spacing: f64) -> Result<Self> {
        check_spacing(spacing)?;
        if lo.iter().chain(&hi).any(|v| !v.is_finite()) {
            return Err(ChainmailError::NonFinite { index: 0 });
        }
        let mut dims = [0usize; 3];
        let mut origin = [0.0; 3];
        for a in 0..3 {
            let cells = ((hi[a] - lo[a]) / spacing).ceil().max(1.0) + 2.0;
            if !cells.is_finite() || cells > crate::MAX_GRID_NODES as f64 {
                return Err(ChainmailError::LatticeTooLarge {
                    nodes: u128::MAX,
                    limit: crate::MAX_GRID_NODES,
                });
            }
            dims[a] = cells as usize;
            origin[a] = 0.5 * (lo[a] + hi[a]) - 0.5 * (dims[a] - 1) as f64 * spacing;
        }
        check_grid(dims)?;
        Ok(Self { dims, origin, spacing })
    }

    /// Number of grid nodes.
    pub fn nodes(&self) -> u128 {
        self.dims.iter().map(|&d| d as u128).product()
    }

    /// An upper bound of the bytes the lattice and the embedding of `vertices` surface
    /// vertices take (every node counted as an element).
    pub fn bytes_upper_bound(&self, vertices: usize) -> u128 {
        self.nodes() * (BYTES_PER_NODE + BYTES_PER_ELEMENT) as u128
            + vertices as u128 * BYTES_PER_VERTEX as u128
    }

    /// The cell holding `p` (its lowest corner node) and the trilinear coordinates of `p`
    /// in it, each in `[0, 1]`.
    fn cell_of(&self, p: Vec3) -> ([usize; 3], [f64; 3]) {
        let mut cell = [0usize; 3];
        let mut t = [0.0; 3];
        for a in 0..3 {
            let x = (p[a] - self.origin[a]) / self.spacing;
            let c = x.floor().clamp(0.0, (self.dims[a] - 2) as f64);
            cell[a] = c as usize;
            t[a] = (x - c).clamp(0.0, 1.0);
        }
        (cell, t)
    }
}

/// A surface embedded in a lattice: each vertex is the trilinear interpolation of the
/// eight elements at the corners of its grid cell.
///
/// At rest the interpolation gives back the vertex exactly (trilinear interpolation is
/// exact for the affine rest map of a regular grid); after a deformation the surface
/// follows the elements.
#[derive(Debug, Clone, PartialEq)]
pub struct Embedding {
    corners: Vec<[u32; 8]>,
    weights: Vec<[f64; 8]>,
}

impl Embedding {
    /// Number of embedded vertices.
    pub fn len(&self) -> usize {
        self.corners.len()
    }

    /// True when no vertex is embedded.
    pub fn is_empty(&self) -> bool {
        self.corners.is_empty()
    }

    /// The eight elements carrying vertex `v` (corner `b` at grid offset
    /// `(b & 1, (b >> 1) & 1, (b >> 2) & 1)`), or `None` for an unknown vertex.
    pub fn elements(&self, v: usize) -> Option<[usize; 8]> {
        self.corners.get(v).map(|c| c.map(|e| e as usize))
    }

    /// The trilinear weights of vertex `v` (summing to 1), or `None` for an unknown vertex.
    pub fn weights(&self, v: usize) -> Option<[f64; 8]> {
        self.weights.get(v).copied()
    }

    /// The surface positions for the lattice's current element positions.
    pub fn positions(&self, lattice: &Lattice) -> Vec<Vec3> {
        let mut out = vec![[0.0; 3]; self.len()];
        self.positions_into(lattice, &mut out);
        out
    }

    /// Writes the surface positions into `out` (one per embedded vertex; extra entries are
    /// left alone).
    pub fn positions_into(&self, lattice: &Lattice, out: &mut [Vec3]) {
        let pos = lattice.positions();
        for ((c, w), o) in self.corners.iter().zip(&self.weights).zip(out.iter_mut()) {
            let mut p = [0.0; 3];
            for b in 0..8 {
                let q = pos[c[b] as usize];
                for a in 0..3 {
                    p[a] += w[b] * q[a];
                }
            }
            *o = p;
        }
    }

    /// Bytes held by the embedding.
    pub fn memory_bytes(&self) -> usize {
        self.len() * BYTES_PER_VERTEX as usize
    }
}

impl Lattice {
    /// Voxelizes a closed triangle surface and embeds its vertices.
    ///
    /// The grid is [`EmbeddingGrid::for_box`] of the surface's bounding box. A grid node is
    /// a chain element when it lies inside the surface (generalized winding number
    /// `|w| > 1/2`) or when it is a corner of a cell that holds a surface vertex, so that
    /// every vertex has all eight corners of its cell as elements and a thin part of the
    /// body thinner than a spacing still has elements. Each vertex gets the trilinear
    /// weights of its position in its cell. Cost is O(nodes × triangles) for the
    /// voxelization.
    ///
    /// Errors: as [`Lattice::from_surface`].
    pub fn embed_surface(
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        spacing: f64,
    ) -> Result<(Self, Embedding)> {
        check_surface(positions, triangles, spacing)?;
        let (lo, hi) = fibfluid_geometry::bounding_box(positions);
        let grid = EmbeddingGrid::for_box(lo, hi, spacing)?;
        let dims = grid.dims;
        let node = |i: [usize; 3]| i[0] + dims[0] * (i[1] + dims[1] * i[2]);
        let mut mask = vec![false; grid.nodes() as usize];
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let p = [
                        grid.origin[0] + i as f64 * spacing,
                        grid.origin[1] + j as f64 * spacing,
                        grid.origin[2] + k as f64 * spacing,
                    ];
                    if winding_number(p, positions, triangles).abs() > 0.5 {
                        mask[node([i, j, k])] = true;
                    }
                }
            }
        }
        let cells: Vec<([usize; 3], [f64; 3])> = positions.iter().map(|&p| grid.cell_of(p)).collect();
        let corner = |c: [usize; 3], b: usize| [c[0] + (b & 1), c[1] + ((b >> 1) & 1), c[2] + ((b >> 2) & 1)];
        for (c, _) in &cells {
            for b in 0..8 {
                mask[node(corner(*c, b))] = true;
            }
        }
        let lattice = Self::from_mask(dims, spacing, grid.origin, mask)?;
        let mut corners = Vec::with_capacity(positions.len());
        let mut weights = Vec::with_capacity(positions.len());
        for (c, t) in cells {
            let mut ids = [0u32; 8];
            let mut w = [0.0; 8];
            for b in 0..8 {
                // Every corner was put in the mask above.
                let e = lattice.element_at(corner(c, b)).ok_or(ChainmailError::EmptyLattice)?;
                ids[b] = e as u32;
                let f = |a: usize, bit: usize| if bit == 1 { t[a] } else { 1.0 - t[a] };
                w[b] = f(0, b & 1) * f(1, (b >> 1) & 1) * f(2, (b >> 2) & 1);
            }
            corners.push(ids);
            weights.push(w);
        }
        Ok((lattice, Embedding { corners, weights }))
    }

    /// Bytes held by the lattice's arrays (grid map, element data, tetrahedra).
    pub fn memory_bytes(&self) -> usize {
        let nodes: usize = self.dims().iter().product();
        nodes * 4 + self.len() * (4 * 24 + 2 * 8) + self.tets.len() * 72
    }
}
