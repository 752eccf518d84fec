//! The volumetric lattice of chain elements, its links and its tetrahedra.

pub(crate) use fibfluid_geometry::vec3::{Vec3, cross, dot, norm, sub};

use fibfluid_geometry::winding_number;

use crate::error::{ChainmailError, Result};
use crate::material::Material;

/// Largest number of grid nodes (`nx * ny * nz`) a lattice may span.
pub const MAX_GRID_NODES: usize = 1 << 24;

const NONE: u32 = u32::MAX;

/// Lattice directions of the six face neighbours: −x, +x, −y, +y, −z, +z.
pub(crate) const DIRS: [[isize; 3]; 6] =
    [[-1, 0, 0], [1, 0, 0], [0, -1, 0], [0, 1, 0], [0, 0, -1], [0, 0, 1]];

/// Signed volume `(1/6) (p1 − p0) · ((p2 − p0) × (p3 − p0))`.
pub(crate) fn tet_volume(p: [Vec3; 4]) -> f64 {
    let a = sub(p[1], p[0]);
    let b = sub(p[2], p[0]);
    let c = sub(p[3], p[0]);
    dot(a, cross(b, c)) / 6.0
}

/// A regular 3D grid of chain elements (mass points) with 6-neighbour (face) links and a
/// tetrahedralization of the fully occupied grid cells.
///
/// Grid node `(i, j, k)` rests at `origin + spacing * (i, j, k)`. Only occupied nodes are
/// chain elements; elements are numbered in x-fastest grid order. Every pair of occupied
/// face-adjacent nodes is a link whose rest offset is `±spacing` along one axis. Every grid
/// cell whose eight corners are all occupied is split into six tetrahedra around its main
/// diagonal (Kuhn/Freudenthal split, conforming across cells), each positively oriented at
/// rest; these carry the volume and strain-energy constraints and define [`Lattice::volume`].
#[derive(Debug, Clone)]
pub struct Lattice {
    dims: [usize; 3],
    spacing: f64,
    origin: Vec3,
    node_to_element: Vec<u32>,
    coords: Vec<[usize; 3]>,
    rest: Vec<Vec3>,
    pub(crate) pos: Vec<Vec3>,
    pub(crate) neighbors: Vec<[u32; 6]>,
    pub(crate) tets: Vec<[usize; 4]>,
    pub(crate) tet_rest_volume: Vec<f64>,
    pub(crate) tet_rest_dist: Vec<[f64; 4]>,
    pub(crate) inv_mass: Vec<f64>,
    pub(crate) stiffness: Vec<f64>,
}

pub(crate) fn check_spacing(spacing: f64) -> Result<()> {
    if !(spacing.is_finite() && spacing > 0.0) {
        return Err(ChainmailError::InvalidParameter {
            name: "spacing",
            reason: format!("{spacing} is not a finite positive number"),
        });
    }
    Ok(())
}

pub(crate) fn check_grid(dims: [usize; 3]) -> Result<usize> {
    let nodes = dims.iter().map(|&d| d as u128).product::<u128>();
    if nodes > MAX_GRID_NODES as u128 {
        return Err(ChainmailError::LatticeTooLarge { nodes, limit: MAX_GRID_NODES });
    }
    if nodes == 0 {
        return Err(ChainmailError::EmptyLattice);
    }
    Ok(nodes as usize)
}

/// Checks a surface given for voxelization: a good spacing, at least one vertex and one
/// triangle, finite vertices, triangle indices in range.
pub(crate) fn check_surface(positions: &[Vec3], triangles: &[[u32; 3]], spacing: f64) -> Result<()> {
    check_spacing(spacing)?;
    if positions.is_empty() || triangles.is_empty() {
        return Err(ChainmailError::EmptyLattice);
    }
    for (i, p) in positions.iter().enumerate() {
        if p.iter().any(|v| !v.is_finite()) {
            return Err(ChainmailError::NonFinite { index: i });
        }
    }
    for t in triangles {
        for &v in t {
            if v as usize >= positions.len() {
                return Err(ChainmailError::IndexOutOfRange { index: v as usize, len: positions.len() });
            }
        }
    }
    Ok(())
}

impl Lattice {
    /// A full box of `dims[0] * dims[1] * dims[2]` elements, node `(0,0,0)` at `origin`.
    ///
    /// Errors: a zero dimension ([`ChainmailError::EmptyLattice`]), a non-positive or
    /// non-finite spacing, a non-finite origin, or more than [`MAX_GRID_NODES`] nodes.
    pub fn new_box(dims: [usize; 3], spacing: f64, origin: Vec3) -> Result<Self> {
        check_spacing(spacing)?;
        if origin.iter().any(|v| !v.is_finite()) {
            return Err(ChainmailError::InvalidParameter {
                name: "origin",
                reason: "non-finite coordinate".into(),
            });
        }
        let n = check_grid(dims)?;
        Self::from_mask(dims, spacing, origin, vec![true; n])
    }

    /// Voxelizes the interior of a closed triangle surface.
    ///
    /// The grid covers the surface's bounding box with `ceil(extent / spacing)` cells per
    /// axis (at least one), centred on the box; a chain element sits at the centre of each
    /// cell whose centre is inside the surface, decided by the generalized winding number
    /// (`|w| > 1/2`, so either triangle orientation works and small gaps are tolerated).
    /// Cost is O(cells × triangles).
    ///
    /// Errors: no vertex or triangle, a non-finite vertex, a triangle index out of range,
    /// a bad spacing, a grid over [`MAX_GRID_NODES`], or no cell centre inside
    /// ([`ChainmailError::EmptyLattice`]).
    pub fn from_surface(positions: &[Vec3], triangles: &[[u32; 3]], spacing: f64) -> Result<Self> {
        check_surface(positions, triangles, spacing)?;
        let (lo, hi) = fibfluid_geometry::bounding_box(positions);
        let mut dims = [0usize; 3];
        let mut origin = [0.0; 3];
        for a in 0..3 {
            let cells = ((hi[a] - lo[a]) / spacing).ceil().max(1.0);
            if !cells.is_finite() || cells > MAX_GRID_NODES as f64 {
                return Err(ChainmailError::LatticeTooLarge { nodes: u128::MAX, limit: MAX_GRID_NODES });
            }
            dims[a] = cells as usize;
            let centre = 0.5 * (lo[a] + hi[a]);
            origin[a] = centre - 0.5 * dims[a] as f64 * spacing + 0.5 * spacing;
        }
        let n = check_grid(dims)?;
        let mut mask = vec![false; n];
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let p = [
                        origin[0] + i as f64 * spacing,
                        origin[1] + j as f64 * spacing,
                        origin[2] + k as f64 * spacing,
                    ];
                    if winding_number(p, positions, triangles).abs() > 0.5 {
                        mask[i + dims[0] * (j + dims[1] * k)] = true;
                    }
                }
            }
        }
        Self::from_mask(dims, spacing, origin, mask)
    }

    pub(crate) fn from_mask(dims: [usize; 3], spacing: f64, origin: Vec3, mask: Vec<bool>) -> Result<Self> {
        let count = mask.iter().filter(|&&m| m).count();
        if count == 0 {
            return Err(ChainmailError::EmptyLattice);
        }
        if count >= NONE as usize {
            return Err(ChainmailError::LatticeTooLarge { nodes: count as u128, limit: MAX_GRID_NODES });
        }
        let mut node_to_element = vec![NONE; mask.len()];
        let mut coords = Vec::with_capacity(count);
        let mut rest = Vec::with_capacity(count);
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let node = i + dims[0] * (j + dims[1] * k);
                    if mask[node] {
                        node_to_element[node] = coords.len() as u32;
                        coords.push([i, j, k]);
                        rest.push([
                            origin[0] + i as f64 * spacing,
                            origin[1] + j as f64 * spacing,
                            origin[2] + k as f64 * spacing,
                        ]);
                    }
                }
            }
        }
        let grid = GridLookup { dims, node_to_element: &node_to_element };
        let neighbors: Vec<[u32; 6]> = coords
            .iter()
            .map(|c| {
                let mut nb = [NONE; 6];
                for (d, dir) in DIRS.iter().enumerate() {
                    nb[d] = grid.element(*c, *dir);
                }
                nb
            })
            .collect();
        let tets = kuhn_tets(&grid, &coords, &rest);
        let (tet_rest_volume, tet_rest_dist) = tet_rest_shapes(&tets, &rest);
        Ok(Self {
            dims,
            spacing,
            origin,
            node_to_element,
            coords,
            pos: rest.clone(),
            rest,
            neighbors,
            tets,
            tet_rest_volume,
            tet_rest_dist,
            inv_mass: vec![1.0; count],
            stiffness: vec![1.0; count],
        })
    }

    /// Number of chain elements.
    pub fn len(&self) -> usize {
        self.rest.len()
    }

    /// Always false: a lattice is never built empty. Present for API convention.
    pub fn is_empty(&self) -> bool {
        self.rest.is_empty()
    }

    /// Grid nodes per axis `[nx, ny, nz]`.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// Grid spacing (rest length of every link).
    pub fn spacing(&self) -> f64 {
        self.spacing
    }

    /// Rest position of grid node `(0, 0, 0)`.
    pub fn origin(&self) -> Vec3 {
        self.origin
    }

    /// Current positions of the elements.
    pub fn positions(&self) -> &[Vec3] {
        &self.pos
    }

    /// Rest positions of the elements.
    pub fn rest_positions(&self) -> &[Vec3] {
        &self.rest
    }

    /// Grid coordinates `(i, j, k)` of element `e`.
    pub fn grid_coords(&self, e: usize) -> Result<[usize; 3]> {
        self.check_index(e)?;
        Ok(self.coords[e])
    }

    /// The element at grid node `(i, j, k)`, if that node is occupied.
    pub fn element_at(&self, ijk: [usize; 3]) -> Option<usize> {
        if (0..3).any(|a| ijk[a] >= self.dims[a]) {
            return None;
        }
        let e = self.node_to_element[ijk[0] + self.dims[0] * (ijk[1] + self.dims[1] * ijk[2])];
        (e != NONE).then_some(e as usize)
    }

    /// Face neighbours of element `e` (at most six).
    pub fn neighbors(&self, e: usize) -> Result<Vec<usize>> {
        self.check_index(e)?;
        Ok(self.neighbors[e].iter().filter(|&&n| n != NONE).map(|&n| n as usize).collect())
    }

    /// Every link once, as `(a, b)` with `a < b`.
    pub fn links(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        self.neighbors.iter().enumerate().flat_map(|(a, nb)| {
            nb.iter().filter(move |&&b| b != NONE && (b as usize) > a).map(move |&b| (a, b as usize))
        })
    }

    /// Tetrahedra (element indices, positively oriented at rest).
    pub fn tets(&self) -> &[[usize; 4]] {
        &self.tets
    }

    /// Sets the current positions of every element (for instance to restore a saved state).
    ///
    /// Errors: a length other than [`Lattice::len`], a non-finite coordinate.
    pub fn set_positions(&mut self, positions: &[Vec3]) -> Result<()> {
        if positions.len() != self.len() {
            return Err(ChainmailError::LengthMismatch { expected: self.len(), found: positions.len() });
        }
        if let Some(i) = positions.iter().position(|p| p.iter().any(|v| !v.is_finite())) {
            return Err(ChainmailError::NonFinite { index: i });
        }
        self.pos.copy_from_slice(positions);
        Ok(())
    }

    /// Puts every element back at its rest position.
    pub fn reset(&mut self) {
        self.pos.clone_from(&self.rest);
    }

    /// Inverse mass `w_i` of element `e` (default 1; 0 means fixed).
    pub fn inverse_mass(&self, e: usize) -> Result<f64> {
        self.check_index(e)?;
        Ok(self.inv_mass[e])
    }

    /// Sets the inverse mass `w_i` (finite, `>= 0`). An element with `w_i = 0` is a
    /// boundary condition: propagation and relaxation never move it (only an explicit move
    /// in [`Lattice::propagate`] does).
    pub fn set_inverse_mass(&mut self, e: usize, w: f64) -> Result<()> {
        self.check_index(e)?;
        if !(w.is_finite() && w >= 0.0) {
            return Err(ChainmailError::InvalidParameter {
                name: "inverse_mass",
                reason: format!("{w} is not finite and >= 0"),
            });
        }
        self.inv_mass[e] = w;
        Ok(())
    }

    /// Sets the strain-energy stiffness `k_i` of Eq. 17 (finite, `>= 0`; default 1).
    pub fn set_stiffness(&mut self, e: usize, k: f64) -> Result<()> {
        self.check_index(e)?;
        if !(k.is_finite() && k >= 0.0) {
            return Err(ChainmailError::InvalidParameter {
                name: "stiffness",
                reason: format!("{k} is not finite and >= 0"),
            });
        }
        self.stiffness[e] = k;
        Ok(())
    }

    /// Current volume: sum of the signed volumes of the tetrahedra.
    pub fn volume(&self) -> f64 {
        self.tets
            .iter()
            .map(|t| tet_volume([self.pos[t[0]], self.pos[t[1]], self.pos[t[2]], self.pos[t[3]]]))
            .sum()
    }

    /// Rest volume: `(number of full cells) * spacing^3`.
    pub fn rest_volume(&self) -> f64 {
        self.tet_rest_volume.iter().sum()
    }

    /// `|volume − rest_volume| / rest_volume` (0 when there is no full cell).
    pub fn relative_volume_change(&self) -> f64 {
        let v0 = self.rest_volume();
        if v0 > 0.0 { (self.volume() - v0).abs() / v0 } else { 0.0 }
    }

    /// Root-mean-square distance of the elements from their rest positions.
    pub fn rms_displacement(&self) -> f64 {
        let s: f64 = self.pos.iter().zip(&self.rest).map(|(p, r)| dot(sub(*p, *r), sub(*p, *r))).sum();
        (s / self.len() as f64).sqrt()
    }

    /// The largest distance by which any link violates its CBR under `material`
    /// (0 when every link is satisfied). Checks both `P_j` in `CBR_{j,i}` and `P_i` in
    /// `CBR_{i,j}`.
    pub fn max_cbr_violation<M: Material + ?Sized>(&self, material: &M) -> Result<f64> {
        material.validate(self.len())?;
        let mut worst = 0.0_f64;
        for (a, b) in self.links() {
            for (i, j) in [(a, b), (b, a)] {
                let cbr = material.cbr(i, j, sub(self.rest[j], self.rest[i]))?;
                worst = worst.max(cbr.violation(sub(self.pos[j], self.pos[i])));
            }
        }
        Ok(worst)
    }

    pub(crate) fn check_index(&self, e: usize) -> Result<()> {
        if e < self.len() {
            Ok(())
        } else {
            Err(ChainmailError::IndexOutOfRange { index: e, len: self.len() })
        }
    }

    pub(crate) fn rest_offset(&self, i: usize, j: usize) -> Vec3 {
        sub(self.rest[j], self.rest[i])
    }
}

/// Finds the elements of occupied grid nodes while a lattice is being built.
struct GridLookup<'a> {
    dims: [usize; 3],
    node_to_element: &'a [u32],
}

impl GridLookup<'_> {
    /// The element at grid node `c + offset`, or `NONE` if that node is outside the grid or
    /// not occupied.
    fn element(&self, c: [usize; 3], offset: [isize; 3]) -> u32 {
        let c: [isize; 3] = std::array::from_fn(|a| c[a] as isize + offset[a]);
        if (0..3).any(|a| c[a] < 0 || c[a] as usize >= self.dims[a]) {
            NONE
        } else {
            let [i, j, k] = c.map(|v| v as usize);
            self.node_to_element[i + self.dims[0] * (j + self.dims[1] * k)]
        }
    }
}

/// Kuhn split of each full grid cell (all eight corners occupied, the cell's lowest corner
/// at one of `coords`): six tetrahedra, one per axis permutation, each oriented positively
/// at the `rest` positions.
fn kuhn_tets(grid: &GridLookup<'_>, coords: &[[usize; 3]], rest: &[Vec3]) -> Vec<[usize; 4]> {
    const PERMS: [[usize; 3]; 6] = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
    let mut tets = Vec::new();
    for &c in coords {
        let mut corners = [NONE; 8];
        for (b, corner) in corners.iter_mut().enumerate() {
            *corner = grid.element(c, [(b & 1) as isize, ((b >> 1) & 1) as isize, ((b >> 2) & 1) as isize]);
        }
        if corners.contains(&NONE) {
            continue;
        }
        for p in PERMS {
            let b1 = 1 << p[0];
            let b2 = b1 | (1 << p[1]);
            let mut t =
                [corners[0] as usize, corners[b1] as usize, corners[b2] as usize, corners[7] as usize];
            if tet_volume([rest[t[0]], rest[t[1]], rest[t[2]], rest[t[3]]]) < 0.0 {
                t.swap(2, 3);
            }
            tets.push(t);
        }
    }
    tets
}

/// Rest volume of each tetrahedron and the rest distances of its four vertices from its
/// barycenter.
fn tet_rest_shapes(tets: &[[usize; 4]], rest: &[Vec3]) -> (Vec<f64>, Vec<[f64; 4]>) {
    let mut volumes = Vec::with_capacity(tets.len());
    let mut dists = Vec::with_capacity(tets.len());
    for t in tets {
        let p = [rest[t[0]], rest[t[1]], rest[t[2]], rest[t[3]]];
        volumes.push(tet_volume(p));
        let mut c = [0.0; 3];
        for q in &p {
            for a in 0..3 {
                c[a] += 0.25 * q[a];
            }
        }
        dists.push([norm(sub(p[0], c)), norm(sub(p[1], c)), norm(sub(p[2], c)), norm(sub(p[3], c))]);
    }
    (volumes, dists)
}
