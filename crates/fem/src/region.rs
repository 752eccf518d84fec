//! Regions of different tissue inside the body: a lesion, glandular tissue inside fat.
//!
//! A region is a closed surface or a box with its own [`Tissue`]. Each active cell's
//! `SUBSAMPLES^3` sample points (the same sub-cell centres that give its fill fraction) are
//! tested against the body's surface and every region's shape; a sample inside the body and
//! inside region `r` (the last listed region wins where regions overlap) counts for `r`,
//! one inside the body only for the base tissue. The cell's moduli `mu`, `kappa` and its
//! density are the sample-weighted means of its tissues (Voigt's bound: the cell's
//! materials strained alike), and its material id is the tissue with the most samples.
//! A cell takes the law of the tissue it holds most of (the body's elastic law, viscoelastic
//! where that tissue relaxes).

use std::sync::Arc;

use fibfluid_geometry::{PointLattice, Vec3, for_each_inside_line};

use crate::error::{FemError, Result};
use crate::grid::{SUBSAMPLES, SparseGrid};
use crate::hyper::CellMaterial;
use crate::law::MaterialLaw;
use crate::tissue::Tissue;

/// Where a region is.
#[derive(Debug, Clone, PartialEq)]
pub enum RegionShape {
    /// The axis-aligned box `[min, max]` (m).
    Box {
        /// The lower corner.
        min: Vec3,
        /// The upper corner.
        max: Vec3,
    },
    /// The inside of a closed triangle surface (m).
    Surface {
        /// Vertex positions.
        positions: Vec<Vec3>,
        /// Triangles (vertex indices).
        triangles: Vec<[u32; 3]>,
    },
}

/// A region of the body made of another tissue.
#[derive(Debug, Clone, PartialEq)]
pub struct Region {
    /// Its shape.
    pub shape: RegionShape,
    /// Its tissue (the body's law applies; only the moduli and density are the region's).
    pub tissue: Tissue,
}

/// Per active cell: its blended material, density and dominant material id.
#[derive(Debug, Clone, PartialEq)]
pub struct CellBlend {
    /// The cell's law and moduli.
    pub materials: Vec<CellMaterial>,
    /// The cell's mass density (kg/m^3).
    pub densities: Vec<f64>,
    /// 0: the base tissue; `k`: the `k`-th region (1-based), the one with most samples.
    pub region_ids: Vec<u16>,
    /// Per region, the cells it holds most of.
    pub region_cells: Vec<usize>,
    /// Per cell, the share of its samples in each tissue (the base first, then the regions):
    /// `regions + 1` values per cell, summing to 1 (what its moduli and density are the
    /// weighted means by).
    pub shares: Vec<f64>,
}

/// The inside flags of every sample point of the grid's box for one shape (x fastest).
fn inside_flags(lattice: &PointLattice, shape: &RegionShape) -> Result<Vec<bool>> {
    let [nx, ny, nz] = lattice.dims;
    let mut flags = vec![false; nx * ny * nz];
    match shape {
        RegionShape::Box { min, max } => {
            for (i, f) in flags.iter_mut().enumerate() {
                let g = [i % nx, (i / nx) % ny, i / (nx * ny)];
                let p: Vec3 = std::array::from_fn(|a| lattice.origin[a] + g[a] as f64 * lattice.spacing);
                *f = (0..3).all(|a| p[a] >= min[a] && p[a] <= max[a]);
            }
        }
        RegionShape::Surface { positions, triangles } => {
            for_each_inside_line(positions, triangles, lattice, |j, k, line| {
                flags[nx * (j + ny * k)..nx * (j + ny * k) + nx].copy_from_slice(line);
            })?;
        }
    }
    Ok(flags)
}

/// The cells' blended materials for a body of `base` tissue with `regions` (see the module
/// docs).
///
/// Errors: a region with no sample inside the body ([`FemError::RegionOutsideBody`]), a
/// malformed region surface.
pub fn blend_regions(grid: &SparseGrid, base: &Tissue, regions: &[Region]) -> Result<CellBlend> {
    let h = grid.cell_size();
    let s = SUBSAMPLES;
    let dims = grid.estimate().dims;
    let lattice = PointLattice {
        origin: grid.origin().map(|o| o + 0.5 * h / s as f64),
        spacing: h / s as f64,
        dims: [dims[0] * s, dims[1] * s, dims[2] * s],
    };
    let body = RegionShape::Surface {
        positions: grid.surface_positions().to_vec(),
        triangles: grid.surface_triangles().to_vec(),
    };
    let inside_body = inside_flags(&lattice, &body)?;
    let inside: Vec<Vec<bool>> =
        regions.iter().map(|r| inside_flags(&lattice, &r.shape)).collect::<Result<_>>()?;
    let tissues: Vec<Tissue> = std::iter::once(*base).chain(regions.iter().map(|r| r.tissue)).collect();
    let [lx, ly, _] = lattice.dims;
    let mut blend = CellBlend {
        materials: Vec::new(),
        densities: Vec::new(),
        region_ids: Vec::new(),
        region_cells: vec![0; regions.len()],
        shares: Vec::new(),
    };
    let mut samples_in = vec![0usize; regions.len()];
    let laws: Vec<Arc<dyn MaterialLaw>> = tissues.iter().map(Tissue::law).collect();
    for c in grid.cell_coords() {
        let mut counts = vec![0usize; tissues.len()];
        for k in 0..s * s * s {
            let g = [c[0] * s + k % s, c[1] * s + (k / s) % s, c[2] * s + k / (s * s)];
            let i = g[0] + lx * (g[1] + ly * g[2]);
            if !inside_body[i] {
                continue;
            }
            let owner = (0..regions.len()).rev().find(|&r| inside[r][i]).map_or(0, |r| r + 1);
            counts[owner] += 1;
        }
        if counts.iter().sum::<usize>() == 0 {
            counts[0] = 1;
        }
        for r in 0..regions.len() {
            samples_in[r] += counts[r + 1];
        }
        push_cell(&mut blend, &laws, &tissues, &counts);
    }
    if let Some(r) = samples_in.iter().position(|&n| n == 0) {
        return Err(FemError::RegionOutsideBody { region: r + 1 });
    }
    Ok(blend)
}

/// Appends one cell's sample-weighted material.
fn push_cell(blend: &mut CellBlend, laws: &[Arc<dyn MaterialLaw>], tissues: &[Tissue], counts: &[usize]) {
    let total = counts.iter().sum::<usize>() as f64;
    let mean = |f: &dyn Fn(&Tissue) -> f64| {
        tissues.iter().zip(counts).map(|(t, &n)| f(t) * n as f64).sum::<f64>() / total
    };
    blend.densities.push(mean(&|t| t.density()));
    blend.shares.extend(counts.iter().map(|&n| n as f64 / total));
    let id = (0..counts.len()).max_by_key(|&k| (counts[k], std::cmp::Reverse(k))).unwrap_or(0);
    blend.materials.push(CellMaterial::new(
        laws[id].clone(),
        mean(&|t| t.shear_modulus()),
        mean(&|t| t.bulk_modulus()),
    ));
    blend.region_ids.push(id as u16);
    if id > 0 {
        blend.region_cells[id - 1] += 1;
    }
}
