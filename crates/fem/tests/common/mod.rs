//! Test bodies and closed-form references shared by the tests.

#![allow(dead_code)]

use fibfluid_fem::Tissue;

pub type V3 = [f64; 3];

pub use fibfluid_geometry::box_surface;

/// Tip deflection of a cantilever of length `l` with a `b x b` square section under its own
/// weight (`q = rho g b^2` per length), Timoshenko beam theory: bending `q l^4 / (8 E I)` plus
/// shear `q l^2 / (2 k G A)`, with Cowper's shear coefficient for a rectangle
/// `k = 10 (1 + nu) / (12 + 11 nu)`.
pub fn timoshenko_tip(t: &Tissue, l: f64, b: f64, g: f64) -> f64 {
    let (area, inertia) = (b * b, b.powi(4) / 12.0);
    let q = t.density() * g * area;
    let k = 10.0 * (1.0 + t.poisson()) / (12.0 + 11.0 * t.poisson());
    q * l.powi(4) / (8.0 * t.young() * inertia) + q * l * l / (2.0 * k * t.shear_modulus() * area)
}

/// Relative L2 distance `|a - b| / |b|` over the listed entries.
pub fn rel_l2(a: &[V3], b: &[V3], keep: impl Fn(usize) -> bool) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for i in 0..a.len() {
        if keep(i) {
            for c in 0..3 {
                num += (a[i][c] - b[i][c]).powi(2);
                den += b[i][c].powi(2);
            }
        }
    }
    (num / den).sqrt()
}

pub fn norm(a: V3) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

/// An icosphere of `radius` about `centre` (`fibfluid_geometry::icosphere`, moved).
pub fn sphere_surface(centre: V3, radius: f64, levels: u32) -> (Vec<V3>, Vec<[u32; 3]>) {
    let m = fibfluid_geometry::icosphere(levels, radius);
    let pos = m.positions().iter().map(|p| [p[0] + centre[0], p[1] + centre[1], p[2] + centre[2]]).collect();
    (pos, m.triangles().to_vec())
}
