//! Inside tests of the points of a regular lattice against a closed triangle surface, by
//! casting one ray per lattice line along +x.
//!
//! Each triangle is projected onto the (y, z) plane and tested against the lattice lines it
//! covers; the crossing's x comes from the barycentric coordinates. Whether a line passes
//! inside a projected triangle is decided with exact orientation predicates (Shewchuk's
//! `orient2d`) and a symbolic perturbation of the line to `(y + e^2, z + e)`, so a line
//! through a shared edge or vertex crosses exactly one of the triangles around it, and
//! edge-on triangles are never crossed. A point is inside when the signed number of
//! crossings ahead of it on its line (+1 where the surface's normal has a positive x
//! component, -1 where negative) is nonzero: this is the winding number, so either
//! orientation of the surface works. Cost: O(triangles x lines each covers + points).

use robust::{Coord, orient2d};

use crate::error::MeshError;
use crate::vec3::Vec3;

/// A regular lattice of points: point `(i, j, k)` is `origin + spacing * (i, j, k)` for
/// `i < dims[0]`, `j < dims[1]`, `k < dims[2]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointLattice {
    /// Position of point `(0, 0, 0)`.
    pub origin: Vec3,
    /// Distance between neighbouring points along each axis.
    pub spacing: f64,
    /// Points per axis.
    pub dims: [usize; 3],
}

/// One crossing of a lattice line with the surface: its x and the sign of the crossed
/// triangle's normal x component.
#[derive(Debug, Clone, Copy)]
struct LineCrossing {
    x: f64,
    sign: i32,
}

fn coord(p: Vec3) -> Coord<f64> {
    Coord { x: p[1], y: p[2] }
}

/// Whether the perturbed point `q + (e^2, e)` (in (y, z)) lies strictly left of the directed
/// edge `a -> b`, given the exact orientation `o = orient2d(a, b, q)`.
fn left_of(o: f64, a: Vec3, b: Vec3) -> bool {
    if o != 0.0 {
        return o > 0.0;
    }
    // d/de of the orientation is (b_y - a_y); d/d(e^2) is (a_z - b_z).
    b[1] > a[1] || (b[1] == a[1] && a[2] > b[2])
}

/// Calls `visit(j, k, inside)` for every lattice line `(j, k)` (in k-major, j-minor order)
/// with `inside[i]` telling whether point `(i, j, k)` lies inside the closed surface.
///
/// Errors: a triangle index out of range ([`MeshError::IndexOutOfRange`]) or a non-finite
/// vertex ([`MeshError::NonFiniteVertex`]). A non-positive or non-finite spacing gives no
/// inside point.
pub fn for_each_inside_line(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    lattice: &PointLattice,
    mut visit: impl FnMut(usize, usize, &[bool]),
) -> Result<(), MeshError> {
    check(positions, triangles)?;
    let [nx, ny, nz] = lattice.dims;
    let mut lines: Vec<Vec<LineCrossing>> = vec![Vec::new(); ny * nz];
    let h = lattice.spacing;
    if h.is_finite() && h > 0.0 && lattice.origin.iter().all(|v| v.is_finite()) {
        for t in triangles {
            let [a, b, c] = t.map(|v| positions[v as usize]);
            add_triangle_crossings(a, b, c, lattice, &mut lines);
        }
    }
    let mut inside = vec![false; nx];
    for k in 0..nz {
        for j in 0..ny {
            let line = &mut lines[j + ny * k];
            line.sort_by(|p, q| p.x.total_cmp(&q.x));
            let total: i32 = line.iter().map(|c| c.sign).sum();
            let mut passed = 0;
            let mut next = 0;
            for (i, flag) in inside.iter_mut().enumerate() {
                let x = lattice.origin[0] + i as f64 * h;
                while next < line.len() && line[next].x <= x {
                    passed += line[next].sign;
                    next += 1;
                }
                *flag = total - passed != 0;
            }
            visit(j, k, &inside);
        }
    }
    Ok(())
}

/// Inside flags of every lattice point, x fastest: index `i + dims[0] * (j + dims[1] * k)`.
/// See [`for_each_inside_line`].
pub fn inside_lattice(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    lattice: &PointLattice,
) -> Result<Vec<bool>, MeshError> {
    let mut out = Vec::with_capacity(lattice.dims.iter().product());
    for_each_inside_line(positions, triangles, lattice, |_, _, line| out.extend_from_slice(line))?;
    Ok(out)
}

fn check(positions: &[Vec3], triangles: &[[u32; 3]]) -> Result<(), MeshError> {
    if let Some(v) = positions.iter().position(|p| p.iter().any(|x| !x.is_finite())) {
        return Err(MeshError::NonFiniteVertex { vertex: v });
    }
    for (f, t) in triangles.iter().enumerate() {
        if let Some(&v) = t.iter().find(|&&v| v as usize >= positions.len()) {
            return Err(MeshError::IndexOutOfRange { face: f, index: v as i64, vertices: positions.len() });
        }
    }
    Ok(())
}

/// Adds the crossings of triangle `abc` with the lattice lines it covers in (y, z).
fn add_triangle_crossings(
    a: Vec3,
    b: Vec3,
    c: Vec3,
    lattice: &PointLattice,
    lines: &mut [Vec<LineCrossing>],
) {
    let area = orient2d(coord(a), coord(b), coord(c));
    if area == 0.0 {
        return;
    }
    // Normalize to counter-clockwise in (y, z); the sign records the original orientation.
    let (sign, [a, b, c]) = if area > 0.0 { (1, [a, b, c]) } else { (-1, [a, c, b]) };
    let [_, ny, nz] = lattice.dims;
    let h = lattice.spacing;
    let range = |axis: usize, n: usize| {
        let lo = a[axis].min(b[axis]).min(c[axis]);
        let hi = a[axis].max(b[axis]).max(c[axis]);
        let first = ((lo - lattice.origin[axis]) / h).floor().max(0.0);
        let last = ((hi - lattice.origin[axis]) / h).ceil().min(n as f64 - 1.0);
        (first as usize, last)
    };
    let (j0, j1) = range(1, ny);
    let (k0, k1) = range(2, nz);
    if j1 < 0.0 || k1 < 0.0 {
        return;
    }
    for k in k0..=k1 as usize {
        for j in j0..=j1 as usize {
            let q = [0.0, lattice.origin[1] + j as f64 * h, lattice.origin[2] + k as f64 * h];
            let (wa, wb, wc) =
                (orient2d(coord(b), coord(c), coord(q)), orient2d(coord(c), coord(a), coord(q)), {
                    orient2d(coord(a), coord(b), coord(q))
                });
            if left_of(wa, b, c) && left_of(wb, c, a) && left_of(wc, a, b) {
                let sum = wa + wb + wc;
                let x = if sum != 0.0 { (wa * a[0] + wb * b[0] + wc * c[0]) / sum } else { a[0] };
                lines[j + ny * k].push(LineCrossing { x, sign });
            }
        }
    }
}
