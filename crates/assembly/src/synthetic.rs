//! A synthetic fiber–fluid system for benches and tests: a convex body of any size.

use fibfluid_geometry::{FiberSet, Vec3, fibonacci_sphere};

use crate::{
    AssemblyOptions, Body, ConstraintMethod, Constraints, Material, PressureScaling, Result, System, assemble,
};

/// The FFM system of a sphere sampled at `n` points: every pair a fiber (convex), vertex
/// area vectors `4 pi / n` along the normal, no surface fibers, the top 10 % fixed, with
/// the paper's material. Its K blocks are as dense and as conditioned as a real convex
/// body's, without needing a mesh of exactly `n` vertices.
pub fn synthetic_system(n: usize, method: ConstraintMethod) -> Result<System> {
    let pos = fibonacci_sphere(n);
    let w = 4.0 * std::f64::consts::PI / n as f64;
    let areas: Vec<Vec3> = pos.iter().map(|p| p.map(|c| c * w)).collect();
    let fibers = FiberSet::all(n);
    let body = Body {
        axes: 3,
        positions: &pos,
        vertex_areas: &areas,
        edges: &[],
        fibers: &fibers,
        rest_positions: None,
    };
    let mut material = Material::default();
    material.set_surface_tension(0.0).expect("0 is a surface tension");
    let mut c = Constraints::new(n);
    for (i, p) in pos.iter().enumerate() {
        if p[1] > 0.8 {
            c.fix(i, [true; 3])?;
        }
    }
    let scaling =
        if method == ConstraintMethod::Eliminate { PressureScaling::Auto } else { PressureScaling::None };
    assemble(&body, &material, &c, &AssemblyOptions { method, pressure_scaling: scaling })
}
