//! Right-hand sides: point forces and hydrostatic pressure — the one load path every
//! run, step and probe goes through.

use fibfluid_geometry::Vec3;
use fibfluid_geometry::vec3::{dot, norm, scale};

use crate::{AssemblyError, Result};

/// Depth of each vertex below the body's current top along `down`:
/// `h_i = max_j (s_j . e) - s_i . e`, with `e = -down / |down|` ("up"). Zero when
/// `down = 0`.
pub fn depths(positions: &[Vec3], down: Vec3) -> Vec<f64> {
    let mag = norm(down);
    if mag == 0.0 {
        return vec![0.0; positions.len()];
    }
    let up = scale(down, -1.0 / mag);
    let height: Vec<f64> = positions.iter().map(|p| dot(*p, up)).collect();
    let top = height.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    height.into_iter().map(|h| top - h).collect()
}

/// The loads acting on a body (or their increment over one load step).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Loads<'a> {
    /// The acceleration acting on the fluid (the increment of it, for a load step).
    pub acceleration: Vec3,
    /// The direction depths are measured along ("down"), when it differs from
    /// `acceleration`: an unloading step has the opposite increment but the same "down".
    /// `None`: along `acceleration`.
    pub down: Option<Vec3>,
    /// Fluid density; the hydrostatic load is zero without it.
    pub density: f64,
    /// Point forces (vertex, force).
    pub forces: &'a [(usize, Vec3)],
}

impl Loads<'_> {
    /// Whether the hydrostatic term acts (an acceleration and a fluid density).
    pub fn has_hydrostatic(&self) -> bool {
        self.density != 0.0 && norm(self.acceleration) > 0.0
    }
}

/// The load part of the right-hand side, length `axes * N` in the paper's layout
/// (all x, all y, all z): `b_i = F_i + rho (a . e_down) h_i S_i`, with `h_i` the depth
/// of vertex i below the top of `positions` along "down" (REFERENCE §3).
///
/// `positions` and `vertex_areas` are of the shape the load acts on (the current shape in
/// the paper's stepping). A force on a vertex the body does not have is an error.
pub fn load_vector(
    axes: usize,
    positions: &[Vec3],
    vertex_areas: &[Vec3],
    loads: &Loads,
) -> Result<Vec<f64>> {
    let n = positions.len();
    let mut b = vec![0.0; axes * n];
    let down = loads.down.unwrap_or(loads.acceleration);
    if loads.has_hydrostatic() && norm(down) > 0.0 {
        let e = scale(down, 1.0 / norm(down));
        let h = depths(positions, down);
        let pressure_per_depth = loads.density * dot(loads.acceleration, e);
        for i in 0..n {
            let w = pressure_per_depth * h[i];
            for c in 0..axes {
                b[c * n + i] += w * vertex_areas[i][c];
            }
        }
    }
    for &(v, f) in loads.forces {
        if v >= n {
            return Err(AssemblyError::VertexOutOfRange { vertex: v, vertices: n });
        }
        for c in 0..axes {
            b[c * n + v] += f[c];
        }
    }
    Ok(b)
}
