//! Right-hand sides: point forces and hydrostatic pressure.

use fibfluid_geometry::Vec3;

/// Depth of each vertex below the body's current top along the acceleration:
/// `h_i = max_j (s_j . e) - s_i . e`, with `e = -a / |a|` ("up"). Zero when `a = 0`.
pub fn depths(positions: &[Vec3], acceleration: Vec3) -> Vec<f64> {
    let mag = (acceleration[0].powi(2) + acceleration[1].powi(2) + acceleration[2].powi(2)).sqrt();
    if mag == 0.0 {
        return vec![0.0; positions.len()];
    }
    let e = [-acceleration[0] / mag, -acceleration[1] / mag, -acceleration[2] / mag];
    let height: Vec<f64> = positions.iter().map(|p| p[0] * e[0] + p[1] * e[1] + p[2] * e[2]).collect();
    let top = height.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    height.into_iter().map(|h| top - h).collect()
}

/// The load part of the right-hand side, length `axes * N` in the paper's layout
/// (all x, all y, all z): `b_i = F_i + rho |a| h_i S_i`.
///
/// `positions` and `vertex_areas` are of the shape the load acts on (the current shape in
/// the paper's stepping). `depth` may be passed in when already computed.
pub fn load_vector(
    axes: usize,
    positions: &[Vec3],
    vertex_areas: &[Vec3],
    forces: &[(usize, Vec3)],
    acceleration: Vec3,
    density: f64,
) -> Vec<f64> {
    let n = positions.len();
    let mut b = vec![0.0; axes * n];
    let mag = (acceleration[0].powi(2) + acceleration[1].powi(2) + acceleration[2].powi(2)).sqrt();
    if mag > 0.0 && density != 0.0 {
        let h = depths(positions, acceleration);
        for i in 0..n {
            let w = density * mag * h[i];
            for c in 0..axes {
                b[c * n + i] += w * vertex_areas[i][c];
            }
        }
    }
    for &(v, f) in forces {
        for c in 0..axes {
            b[c * n + v] += f[c];
        }
    }
    b
}
