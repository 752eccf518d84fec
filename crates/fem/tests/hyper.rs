//! The hyperelastic (neo-Hookean) body: its tangent against finite differences, rigid
//! rotations, the small-load limit against the linear body, uniaxial compression against
//! the closed form, near-incompressibility and Newton's convergence.

use crate::common::*;
use fibfluid_fem::hyper::{
    CellMaterial, GRASP_TOLERANCE, Grasp, HyperBody, HyperCell, NewtonSettings, RigidPlate,
};
use fibfluid_fem::{CellFill, FemBody, FemError, FemOptions, Loads, NotConvergedWhy, Tissue, TissueModel};

/// A smooth, non-trivial displacement of a cell of edge `h` (stretch, shear and twist of
/// about 20 %).
fn sample_displacement(h: f64) -> [[f64; 3]; 8] {
    std::array::from_fn(|b| {
        let x = [(b & 1) as f64, ((b >> 1) & 1) as f64, ((b >> 2) & 1) as f64];
        [
            h * (0.15 * x[0] + 0.1 * x[1] * x[2] - 0.05 * x[2]),
            h * (-0.12 * x[1] + 0.08 * x[0] + 0.04 * x[0] * x[2]),
            h * (0.2 * x[2] - 0.07 * x[0] * x[1] + 0.03 * x[1]),
        ]
    })
}

/// The gradient and Hessian of one cell match central finite differences of the energy and
/// of the gradient to 1e-6 relative (the independent check: only the energy is trusted),
/// for a cell filled evenly and one filled unevenly by octant (a cut cell's quadrature).
#[test]
fn tangent_matches_finite_differences() {
    let uneven = CellFill { points: [1.0, 0.5, 0.25, 0.0, 0.75, 1.0, 0.125, 0.625] };
    for fill in [CellFill::uniform(0.8), uneven] {
        let (gerr, kerr, asym) = finite_difference_errors(fill);
        eprintln!("{fill:?}: gradient {gerr:.2e}, tangent {kerr:.2e}, asymmetry {asym:.2e} relative");
        assert!(gerr < 1e-6 && kerr < 1e-6, "gradient {gerr:e}, tangent {kerr:e}");
        // The Hessian of a potential is symmetric.
        assert!(asym < 1e-12, "asymmetry {asym:e}");
    }
}

/// The largest relative errors of one cell's gradient and Hessian against central
/// differences, and the Hessian's relative asymmetry.
fn finite_difference_errors(fill: CellFill) -> (f64, f64, f64) {
    let h = 0.01;
    let cell = HyperCell::new(h);
    let m = CellMaterial::new(std::sync::Arc::new(fibfluid_fem::law::NeoHookean), 1500.0, 40000.0);
    let u = sample_displacement(h);
    let t = cell.tangent(&m, &u, fill, true).unwrap();
    let k = t.hessian.unwrap();
    let eps = 1e-6 * h;
    let shifted = |l: usize, s: f64| {
        let mut v = u;
        v[l / 3][l % 3] += s;
        v
    };
    let gnorm = t.gradient.iter().map(|g| g * g).sum::<f64>().sqrt();
    let knorm = k.iter().flatten().map(|g| g * g).sum::<f64>().sqrt();
    let (mut gerr, mut kerr) = (0.0_f64, 0.0_f64);
    for l in 0..24 {
        let (plus, minus) = (shifted(l, eps), shifted(l, -eps));
        let fd =
            (cell.energy(&m, &plus, fill).unwrap() - cell.energy(&m, &minus, fill).unwrap()) / (2.0 * eps);
        gerr = gerr.max((fd - t.gradient[l]).abs() / gnorm);
        let gp = cell.tangent(&m, &plus, fill, false).unwrap().gradient;
        let gm = cell.tangent(&m, &minus, fill, false).unwrap().gradient;
        for r in 0..24 {
            kerr = kerr.max(((gp[r] - gm[r]) / (2.0 * eps) - k[r][l]).abs() / knorm);
        }
    }
    let asym = (0..24)
        .flat_map(|r| (0..24).map(move |c| (r, c)))
        .map(|(r, c)| (k[r][c] - k[c][r]).abs())
        .fold(0.0, f64::max);
    (gerr, kerr, asym / knorm)
}

/// A rigid rotation by 90 degrees about z costs the neo-Hookean cell no energy and no force;
/// the linear model (the same cell's tangent at rest, which is the linear element) gives it
/// an energy of the order of `E h^3` and forces of the order of `E h^2`.
#[test]
fn rigid_rotation_costs_nothing() {
    let (h, e, nu) = (0.02, 3000.0, 0.45);
    let tissue = Tissue::new(e, nu, 1000.0).unwrap();
    let cell = HyperCell::new(h);
    let m = CellMaterial::of(&tissue.with_model(TissueModel::NeoHookean));
    let u: [[f64; 3]; 8] = std::array::from_fn(|b| {
        let x = [(b & 1) as f64 * h, ((b >> 1) & 1) as f64 * h, ((b >> 2) & 1) as f64 * h];
        [-x[1] - x[0], x[0] - x[1], 0.0]
    });
    let energy = cell.energy(&m, &u, 1.0).unwrap();
    let force =
        cell.tangent(&m, &u, 1.0, false).unwrap().gradient.iter().fold(0.0_f64, |m, g| m.max(g.abs()));
    let k0 = cell.tangent(&m, &[[0.0; 3]; 8], 1.0, true).unwrap().hessian.unwrap();
    let flat: Vec<f64> = u.iter().flatten().copied().collect();
    let ku: Vec<f64> = (0..24).map(|r| (0..24).map(|c| k0[r][c] * flat[c]).sum()).collect();
    let linear_energy = 0.5 * flat.iter().zip(&ku).map(|(a, b)| a * b).sum::<f64>();
    let linear_force = ku.iter().fold(0.0_f64, |m, g| m.max(g.abs()));
    eprintln!(
        "90 deg rotation: neo-Hookean energy {energy:.2e} J, force {force:.2e} N; linear {linear_energy:.2e} J, {linear_force:.2e} N"
    );
    let (energy_scale, force_scale) = (e * h.powi(3), e * h * h);
    assert!(energy.abs() < 1e-12 * energy_scale && force < 1e-12 * force_scale);
    assert!(linear_energy > 0.1 * energy_scale && linear_force > 0.1 * force_scale);
}

/// The 1 m cube of `n^3` surface squares, held by frictionless symmetry planes (x on x = 0,
/// y on y = 0, z on z = 0) and pressed by a frictionless plate from z = 1 down to `stretch`.
fn compressed_cube(n: usize, resolution: usize, stretch: f64, tissue: &Tissue) -> (f64, f64, Vec<f64>) {
    let (pos, tris) = box_surface([0.0; 3], [n; 3], 1.0 / n as f64);
    let fixed: Vec<[bool; 3]> = pos.iter().map(|p| [p[0] == 0.0, p[1] == 0.0, p[2] == 0.0]).collect();
    let options = FemOptions { resolution, ..FemOptions::default() };
    let mut body = HyperBody::from_surface(&pos, &tris, tissue, &fixed, &options).unwrap();
    let plate = RigidPlate {
        force: None,
        start: [0.0, 0.0, 1.0],
        end: [0.0, 0.0, stretch],
        normal: [0.0, 0.0, -1.0],
    };
    let sol = body.solve(&Loads::default(), &[plate]).unwrap();
    let corner = pos.iter().position(|p| *p == [1.0, 1.0, 1.0]).unwrap();
    let lateral = 1.0 + sol.surface_displacements[corner][0];
    let residuals: Vec<f64> = sol.steps.iter().flat_map(|s| s.residuals.clone()).collect();
    eprintln!(
        "cube n {n} res {resolution} stretch {stretch}: iterations {}, force {:.6} N, lateral {lateral:.6}, penetration {:.2e} m, steps {:?}",
        sol.stats.newton_iterations,
        sol.plate_forces[0],
        sol.plate_penetration[0],
        sol.steps.iter().map(|s| (s.load, s.iterations)).collect::<Vec<_>>()
    );
    (sol.plate_forces[0], lateral, residuals)
}

/// The closed form of uniaxial stress for
/// `W = mu / 2 (J^(-2/3) I1 - 3) + kappa / 4 (J^2 - 1 - 2 ln J)`
/// at axial stretch `l`: the lateral stretch `s` solves `dW/ds = 0` (bisection), and the
/// nominal stress is `dW/dl`. Returns `(nominal stress, s)`.
fn uniaxial_closed_form(tissue: &Tissue, l: f64) -> (f64, f64) {
    let (mu, kappa) = (tissue.shear_modulus(), tissue.bulk_modulus());
    let dw = |s: f64| {
        let (j, i1) = (s * s * l, 2.0 * s * s + l * l);
        let ds =
            0.5 * mu * (-2.0 / 3.0 * j.powf(-5.0 / 3.0) * 2.0 * s * l * i1 + j.powf(-2.0 / 3.0) * 4.0 * s)
                + 0.5 * kappa * (j - 1.0 / j) * 2.0 * s * l;
        let dl = 0.5 * mu * (-2.0 / 3.0 * j.powf(-5.0 / 3.0) * s * s * i1 + j.powf(-2.0 / 3.0) * 2.0 * l)
            + 0.5 * kappa * (j - 1.0 / j) * s * s;
        (ds, dl)
    };
    let (mut lo, mut hi) = (0.5, 3.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if dw(mid).0 > 0.0 { hi = mid } else { lo = mid }
    }
    let s = 0.5 * (lo + hi);
    (dw(s).1, s)
}

/// Uniaxial compression of the unit cube between frictionless plates to stretch 0.9, 0.7
/// and 0.5: the plate force (the nominal stress on 1 m^2) and the lateral stretch within 1 %
/// of the closed form. The deformation is homogeneous, so a coarse grid is exact up to the
/// contact's remaining penetration; the top face has 9 x 9 vertices over 4 x 4 cells, so
/// most of them sit between nodes.
#[test]
fn uniaxial_compression_matches_closed_form() {
    let tissue = Tissue::new(5000.0, 0.45, 0.0).unwrap().with_model(TissueModel::NeoHookean);
    for stretch in [0.9, 0.7, 0.5] {
        let (force, lateral, _) = compressed_cube(8, 4, stretch, &tissue);
        let (stress, s) = uniaxial_closed_form(&tissue, stretch);
        eprintln!("  closed form: nominal stress {stress:.6} Pa, lateral {s:.6}");
        assert!(((-force) / stress - 1.0).abs() < 0.01, "stretch {stretch}: force {force} against {stress}");
        assert!((lateral / s - 1.0).abs() < 0.01, "stretch {stretch}: lateral {lateral} against {s}");
    }
}

/// The contact pressure the solution reports per surface vertex: compressing the unit cube
/// (12 x 12 squares a face, resolution 6) to stretch 0.7 between frictionless plates is
/// homogeneous, so every vertex inside the top face carries the closed-form nominal stress (within 2 %), the vertices off it none
/// (up to the contact law's smoothing),
/// and each load step's plate force grows with the load up to the final force.
#[test]
fn contact_pressure_on_the_top_face_is_the_closed_form_stress() {
    let tissue = Tissue::new(5000.0, 0.45, 0.0).unwrap().with_model(TissueModel::NeoHookean);
    let (pos, tris) = box_surface([0.0; 3], [12; 3], 1.0 / 12.0);
    let fixed: Vec<[bool; 3]> = pos.iter().map(|p| [p[0] == 0.0, p[1] == 0.0, p[2] == 0.0]).collect();
    let options = FemOptions { resolution: 6, ..FemOptions::default() };
    let mut body = HyperBody::from_surface(&pos, &tris, &tissue, &fixed, &options).unwrap();
    let plate =
        RigidPlate { force: None, start: [0.0, 0.0, 1.0], end: [0.0, 0.0, 0.7], normal: [0.0, 0.0, -1.0] };
    let sol = body.solve(&Loads::default(), &[plate]).unwrap();
    let (stress, _) = uniaxial_closed_form(&tissue, 0.7);
    // Within three vertex spacings of the free edges (x = 1, y = 1) the samples' pressures
    // are not unique (more samples than the cells' nodes see: 0.8 to 1.09 of the stress
    // there), so the check stays inside.
    let inside = |p: &[f64; 3]| p[2] == 1.0 && p[0] > 0.0 && p[0] < 0.7 && p[1] > 0.0 && p[1] < 0.7;
    for (p, &pressure) in pos.iter().zip(&sol.contact_pressure[0]) {
        if inside(p) {
            assert!((pressure / -stress - 1.0).abs() < 0.02, "{p:?}: {pressure} Pa against {}", -stress);
        } else if p[2] < 0.99 {
            // The smoothed contact law lets a sample just out of contact carry at most
            // CONTACT_SMOOTHING E / 4 (12.5 Pa here, 0.7 % of the stress).
            assert!(pressure.abs() < 0.01 * stress.abs(), "{p:?} is off the top face: {pressure} Pa");
        }
    }
    let forces: Vec<f64> = sol.steps.iter().map(|s| s.plate_forces[0]).collect();
    assert!(forces.windows(2).all(|w| w[1] >= w[0] - 1e-9 * stress.abs()), "{forces:?}");
    assert!((forces.last().unwrap() - sol.plate_forces[0]).abs() <= 1e-9 * stress.abs());
}

/// Newton converges quadratically near the solution: in the last load step, each residual
/// below 1e-3 is followed by one below 100 times its square (or by rounding, 1e-13).
#[test]
fn newton_converges_quadratically() {
    let tissue = Tissue::new(5000.0, 0.45, 0.0).unwrap().with_model(TissueModel::NeoHookean);
    let (_, _, residuals) = compressed_cube(4, 4, 0.7, &tissue);
    let mut checked = 0;
    for w in residuals.windows(2) {
        if w[0] < 1e-3 && w[0] > 1e-12 && w[1] < w[0] {
            assert!(w[1] < 100.0 * w[0] * w[0] || w[1] < 1e-13, "{residuals:?}");
            checked += 1;
        }
    }
    eprintln!("residuals {residuals:?}");
    assert!(checked >= 1, "no pair near the solution: {residuals:?}");
}

/// Mean tip deflection of the 4 x 1 x 1 cantilever (clamped at x = 0) under gravity `g`.
fn cantilever(tissue: &Tissue, g: f64, linear: bool) -> Vec<[f64; 3]> {
    let (pos, tris) = box_surface([0.0; 3], [16, 4, 4], 0.25);
    let fixed: Vec<[bool; 3]> = pos.iter().map(|p| [p[0] == 0.0; 3]).collect();
    let options = FemOptions { resolution: 16, ..FemOptions::default() };
    let loads = Loads { gravity: [0.0, 0.0, -g], ..Default::default() };
    if linear {
        let mut body = FemBody::from_surface(&pos, &tris, tissue, &fixed, &options).unwrap();
        body.solve(&loads).unwrap().surface_displacements
    } else {
        let tissue = tissue.with_model(TissueModel::NeoHookean);
        let mut body = HyperBody::from_surface(&pos, &tris, &tissue, &fixed, &options).unwrap();
        body.solve(&loads, &[]).unwrap().surface_displacements
    }
}

fn relative_l2(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    let d: f64 = a.iter().zip(b).flat_map(|(x, y)| (0..3).map(move |k| (x[k] - y[k]).powi(2))).sum();
    let n: f64 = b.iter().flat_map(|y| y.iter().map(|v| v * v)).sum();
    (d / n).sqrt()
}

/// Small load (tip sag ~1e-4 of the length): the neo-Hookean answer equals the linear
/// body's within 0.5 %, at nu = 0.3 and at nu = 0.49 (where a locking element would differ
/// from the B-bar linear body, itself checked against beam theory in `beam.rs`). A large
/// load (sag ~ a quarter of the length) separates them by more than 0.5 %.
#[test]
fn small_load_matches_linear_and_does_not_lock() {
    for nu in [0.3, 0.49] {
        let tissue = Tissue::new(1e6, nu, 1000.0).unwrap();
        let small = relative_l2(&cantilever(&tissue, 0.01, false), &cantilever(&tissue, 0.01, true));
        eprintln!("nu {nu}: small load, neo-Hookean against linear {small:.2e}");
        assert!(small < 0.005, "nu {nu}: {small}");
    }
    let tissue = Tissue::new(1e6, 0.45, 1000.0).unwrap();
    let large = relative_l2(&cantilever(&tissue, 300.0, false), &cantilever(&tissue, 300.0, true));
    eprintln!("large load, neo-Hookean against linear {large:.2e}");
    assert!(large > 0.005, "{large}");
}

/// A load that cannot be reached within the allowed increments fails with the step, the
/// load factor and the residual, never an answer.
#[test]
fn unreachable_load_is_an_error() {
    let (pos, tris) = box_surface([0.0; 3], [4, 4, 4], 0.25);
    let fixed: Vec<[bool; 3]> = pos.iter().map(|p| [p[0] == 0.0, p[1] == 0.0, p[2] == 0.0]).collect();
    let tissue = Tissue::new(5000.0, 0.45, 0.0).unwrap().with_model(TissueModel::NeoHookean);
    let options = FemOptions { resolution: 4, ..FemOptions::default() };
    let settings = NewtonSettings { max_iterations: 1, min_increment: 0.5, ..NewtonSettings::default() };
    let mut body =
        HyperBody::from_surface(&pos, &tris, &tissue, &fixed, &options).unwrap().with_settings(settings);
    let plate =
        RigidPlate { force: None, start: [0.0, 0.0, 1.0], end: [0.0, 0.0, 0.4], normal: [0.0, 0.0, -1.0] };
    match body.solve(&Loads::default(), &[plate]) {
        Err(e @ FemError::NotConverged { step: 1, .. }) => {
            let text = e.to_string();
            assert!(text.contains("load step 1") && text.contains("residual"), "{text}");
        }
        other => panic!("{:?}", other.map(|s| s.steps.len())),
    }
}

/// A slender column (1 x 1 x 8) clamped at its foot and pressed down by a plate to half
/// its height buckles (Euler's load of this column is reached at about 1 % strain): the
/// straight equilibrium Newton aims for is unstable, its tangent indefinite, and the error
/// says so rather than "too large a load".
#[test]
fn buckling_is_reported_as_an_unstable_equilibrium() {
    let (pos, tris) = box_surface([0.0; 3], [2, 2, 16], 0.5);
    let fixed: Vec<[bool; 3]> = pos.iter().map(|p| [p[2] == 0.0; 3]).collect();
    let tissue = Tissue::new(5000.0, 0.3, 0.0).unwrap().with_model(TissueModel::NeoHookean);
    let options = FemOptions { resolution: 16, ..FemOptions::default() };
    let settings = NewtonSettings { min_increment: 1.0 / 64.0, ..NewtonSettings::default() };
    let mut body =
        HyperBody::from_surface(&pos, &tris, &tissue, &fixed, &options).unwrap().with_settings(settings);
    let plate =
        RigidPlate { force: None, start: [0.0, 0.0, 8.0], end: [0.0, 0.0, 4.0], normal: [0.0, 0.0, -1.0] };
    match body.solve(&Loads::default(), &[plate]) {
        Err(e @ FemError::NotConverged { why: NotConvergedWhy::Indefinite, .. }) => {
            assert!(e.to_string().contains("unstable equilibrium"), "{e}");
        }
        other => panic!("{:?}", other.map(|s| s.steps.len())),
    }
}

/// A 10 cm sphere (`icosphere-3.obj`, E = 3 kPa, resolution 10) glued at its bottom and
/// pressed from above by a frictionless plate to 70 % of its height: on a base 1 cm deep
/// (a cap 6 cm across) the straight-down answer Newton converges to is unstable (the body
/// would sway on its narrow base; its last tangent factors only shifted, `final_shift` > 0,
/// which the `unstable` result guard reads); on a base 3 cm deep it is stable (no shift).
/// (Which branch Newton reaches past a buckling load depends on its path: at resolution 12
/// it ends on a stable one, unshifted.)
#[test]
#[ignore = "long run: CI runs it with `cargo test --workspace -- --ignored long_`"]
fn long_an_unstable_equilibrium_is_told_by_its_tangent() {
    let file = fibfluid_geometry::load_mesh(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/meshes/icosphere-3.obj"),
    )
    .unwrap();
    let pos: Vec<[f64; 3]> = file.mesh.positions().iter().map(|p| p.map(|x| 0.05 * x)).collect();
    let tissue = Tissue::new(3000.0, 0.45, 1000.0).unwrap().with_model(TissueModel::NeoHookean);
    let options = FemOptions { resolution: 10, ..FemOptions::default() };
    let plates = [
        RigidPlate { force: None, start: [0.0, -0.05, 0.0], end: [0.0, -0.05, 0.0], normal: [0.0, 1.0, 0.0] },
        RigidPlate { force: None, start: [0.0, 0.05, 0.0], end: [0.0, 0.02, 0.0], normal: [0.0, -1.0, 0.0] },
    ];
    let shift = |depth: f64| {
        let bottom = pos.iter().map(|p| p[1]).fold(f64::MAX, f64::min);
        let fixed: Vec<[bool; 3]> = pos.iter().map(|p| [p[1] <= bottom + depth; 3]).collect();
        let mut body =
            HyperBody::from_surface(&pos, file.mesh.triangles(), &tissue, &fixed, &options).unwrap();
        let s = body.solve(&Loads::default(), &plates).unwrap();
        eprintln!("base {depth} m deep: final shift {}", s.stats.final_shift);
        s.stats.final_shift
    };
    assert!(shift(0.01) > 0.0);
    assert_eq!(shift(0.03), 0.0);
}

/// The linear law through the same contact: a plate pressing the unit cube (top face 9 x 9
/// vertices over 4 x 4 cells, so most vertices sit between nodes) by 1 % gives E A d / L
/// within 2 % (uniaxial stress is homogeneous, so the linear answer is exact on any grid);
/// contact at the vertices alone gave 0.65 of it.
#[test]
fn linear_plate_force_matches_uniaxial_stiffness() {
    let tissue = Tissue::new(5000.0, 0.45, 0.0).unwrap();
    let (force, lateral, _) = compressed_cube(8, 4, 0.99, &tissue);
    let expected = tissue.young() * 1.0 * 0.01 / 1.0;
    eprintln!("linear: force {force:.6} N against E A d / L = {expected:.6} N, lateral {lateral:.6}");
    assert!((force / expected - 1.0).abs() < 0.02, "{force} against {expected}");
    assert!((lateral - (1.0 + tissue.poisson() * 0.01)).abs() < 0.02 * tissue.poisson() * 0.01);
}

/// The unit cube of 8 x 8 x 8 surface squares over 4 x 4 x 4 cells, its top face (z = 1,
/// 81 vertices, most between nodes) grasped and moved by `translation` and `rotation`;
/// clamped at its bottom face (z = 0) when `clamped`. Returns the solution and the surface.
fn grasped_cube(
    tissue: &Tissue,
    clamped: bool,
    translation: [f64; 3],
    rotation: [f64; 3],
    gravity: [f64; 3],
) -> (fibfluid_fem::hyper::HyperSolution, Vec<[f64; 3]>, Vec<usize>) {
    let (pos, tris) = box_surface([0.0; 3], [8; 3], 1.0 / 8.0);
    let fixed: Vec<[bool; 3]> = pos.iter().map(|p| [clamped && p[2] == 0.0; 3]).collect();
    let top: Vec<usize> = (0..pos.len()).filter(|&v| pos[v][2] == 1.0).collect();
    let grasp = Grasp { vertices: top.clone(), translation, rotation };
    let options = FemOptions { resolution: 4, ..FemOptions::default() };
    let mut body = HyperBody::from_surface_grasped(&pos, &tris, tissue, &fixed, &[grasp], &options).unwrap();
    let sol = body.solve(&Loads { gravity, ..Default::default() }, &[]).unwrap();
    let g = sol.grasps[0];
    eprintln!(
        "grasped cube ({:?}, clamped {clamped}): force {:?} N, moment {:?} N m, error {:.2e} m, support {:?} N, iterations {}, augmentations {}, largest strain {:.2e}, J {:.8}..{:.8}",
        tissue.model(),
        g.force,
        g.moment,
        g.error,
        sol.support_force,
        sol.stats.newton_iterations,
        sol.stats.augmentations,
        sol.summary.max_strain_magnitude,
        sol.summary.j_min,
        sol.summary.j_max
    );
    (sol, pos, top)
}

/// Clamped at the bottom, the top face grasped and pulled up by 1 %, the linear law at
/// nu = 0: no lateral strain, so clamping the faces changes nothing and the closed form is
/// uniaxial stress, `F = E A d / L` (the exact answer is linear in z, inside the element's
/// space: only the grasp's remaining error separates them). The tissue pulls the grasper
/// down with it; the grasped vertices sit where they are told within `GRASP_TOLERANCE h`.
#[test]
fn grasp_pull_matches_uniaxial_stiffness() {
    let tissue = Tissue::new(5000.0, 0.0, 0.0).unwrap();
    let d = 0.01;
    let (sol, _, top) = grasped_cube(&tissue, true, [0.0, 0.0, d], [0.0; 3], [0.0; 3]);
    let expected = -tissue.young() * 1.0 * d / 1.0;
    let f = sol.grasps[0].force;
    assert!((f[2] / expected - 1.0).abs() < 1e-3, "{f:?} against {expected}");
    assert!(f[0].abs() < 1e-6 * expected.abs() && f[1].abs() < 1e-6 * expected.abs(), "{f:?}");
    assert!(sol.grasps[0].error <= GRASP_TOLERANCE * 0.25, "{}", sol.grasps[0].error);
    for &v in &top {
        let u = sol.surface_displacements[v];
        assert!(norm([u[0], u[1], u[2] - d]) <= GRASP_TOLERANCE * 0.25, "vertex {v}: {u:?}");
    }
}

/// The same pull to stretch 1.3, neo-Hookean (nu = 0.45) under gravity: a clamped top and
/// bottom is not uniaxial, so there is no closed form; the check is equilibrium. The force
/// the tissue puts on the grasper equals the force the supports put on the body (the
/// clamp's penalty and its eliminated nodes, computed from the cells' internal forces)
/// plus the body's weight (`rho g` times the unit volume), to 1e-6 of the force; the
/// grasped vertices are where they are told within `GRASP_TOLERANCE h`.
#[test]
fn grasp_pull_is_in_equilibrium_with_the_clamp() {
    let tissue = Tissue::new(5000.0, 0.45, 1000.0).unwrap().with_model(TissueModel::NeoHookean);
    let (d, g) = (0.3, [0.0, 0.0, -9.81]);
    let (sol, _, top) = grasped_cube(&tissue, true, [0.0, 0.0, d], [0.0; 3], g);
    let f = sol.grasps[0].force;
    let weight = g.map(|a| tissue.density() * 1.0 * a);
    let balance: [f64; 3] = std::array::from_fn(|a| f[a] - sol.support_force[a] - weight[a]);
    eprintln!("force balance {balance:?} N");
    assert!(norm(balance) < 1e-6 * norm(f), "{balance:?} against {f:?}");
    for &v in &top {
        let u = sol.surface_displacements[v];
        assert!(norm([u[0], u[1], u[2] - d]) <= GRASP_TOLERANCE * 0.25, "vertex {v}: {u:?}");
    }
}

/// A free body (no clamp, no gravity) whose top face is grasped and translated by
/// (0.3, -0.2, 0.5) m: the neo-Hookean body translates with it, every vertex by the
/// translation, with zero strain and zero force on the grasper.
#[test]
fn grasp_translates_a_free_body_rigidly() {
    let tissue = Tissue::new(5000.0, 0.45, 0.0).unwrap().with_model(TissueModel::NeoHookean);
    let t = [0.3, -0.2, 0.5];
    let (sol, _, _) = grasped_cube(&tissue, false, t, [0.0; 3], [0.0; 3]);
    let scale = tissue.young() * 1.0;
    assert!(norm(sol.grasps[0].force) < 1e-6 * scale, "{:?}", sol.grasps[0].force);
    assert!(sol.summary.max_strain_magnitude < 1e-6, "{}", sol.summary.max_strain_magnitude);
    for u in &sol.surface_displacements {
        assert!(norm([u[0] - t[0], u[1] - t[1], u[2] - t[2]]) < GRASP_TOLERANCE * 0.25, "{u:?}");
    }
}

/// A free body whose top face is grasped and turned by 90 degrees about x (through the
/// face's centre): the neo-Hookean body turns with it, with no force or moment on the
/// grasper, no strain and no change of volume (every cell's `J` is 1); the linear law
/// through the same solve cannot represent the rotation and strains the body (largest
/// Green–Lagrange strain above 0.1).
#[test]
fn grasp_rotates_a_free_body_rigidly_only_large_deformation() {
    let quarter = [std::f64::consts::FRAC_PI_2, 0.0, 0.0];
    let tissue = Tissue::new(5000.0, 0.45, 0.0).unwrap();
    let (sol, pos, _) =
        grasped_cube(&tissue.with_model(TissueModel::NeoHookean), false, [0.0; 3], quarter, [0.0; 3]);
    let scale = tissue.young() * 1.0;
    let g = sol.grasps[0];
    assert!(norm(g.force) < 1e-6 * scale && norm(g.moment) < 1e-6 * scale, "{g:?}");
    assert!(sol.summary.max_strain_magnitude < 1e-6, "{}", sol.summary.max_strain_magnitude);
    assert!((sol.summary.j_min - 1.0).abs() < 1e-6 && (sol.summary.j_max - 1.0).abs() < 1e-6);
    // The rotation about x through (0.5, 0.5, 1): (y, z) - c -> (-(z - cz), y - cy) + c.
    for (p, u) in pos.iter().zip(&sol.surface_displacements) {
        let want = [p[0], 0.5 - (p[2] - 1.0), 1.0 + (p[1] - 0.5)];
        let got = [p[0] + u[0], p[1] + u[1], p[2] + u[2]];
        assert!(norm([got[0] - want[0], got[1] - want[1], got[2] - want[2]]) < 1e-3, "{p:?}: {got:?}");
    }
    let (linear, _, _) = grasped_cube(&tissue, false, [0.0; 3], quarter, [0.0; 3]);
    assert!(linear.summary.max_strain_magnitude > 0.1, "{}", linear.summary.max_strain_magnitude);
}

/// The liver of `liver-grasp.toml` (liver2.obj in metres, held within 8 mm of its top,
/// under gravity, E = 5 kPa, nu = 0.45, 1060 kg/m^3, resolution 16), the 10 vertices within
/// 2 cm of vertex 570 lifted by (-3.3, 3.2, -0.6) cm: the patch lies in few cells, so its
/// rows are nearly dependent and Uzawa's augmentations crept (12 of them, error 5.6e-8 m).
/// Newton's method on the grasp's optimality conditions meets it in one augmentation to
/// the tolerance, its residuals falling quadratically (each below 100 times the square of
/// the one before once under 1e-2: measured constants about 50), and the grasper's force balances the weight and
/// the supports (an independent check: the same equilibrium as
/// `grasp_pull_is_in_equilibrium_with_the_clamp`).
#[test]
#[ignore = "long run: CI runs it with `cargo test --workspace -- --ignored long_`"]
fn long_newton_meets_a_grasp_uzawa_crept_on() {
    let file = fibfluid_geometry::load_mesh(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/meshes/liver2.obj"),
    )
    .unwrap();
    let pos: Vec<[f64; 3]> = file.mesh.positions().iter().map(|p| p.map(|x| 0.1 * x)).collect();
    let top = pos.iter().map(|p| p[1]).fold(f64::MIN, f64::max);
    let fixed: Vec<[bool; 3]> = pos.iter().map(|p| [p[1] >= top - 0.008; 3]).collect();
    let tissue = Tissue::new(5000.0, 0.45, 1060.0).unwrap().with_model(TissueModel::NeoHookean);
    let grasp = Grasp {
        vertices: Grasp::patch(&pos, 570, 0.02),
        translation: [-0.033, 0.032, -0.006],
        rotation: [0.0; 3],
    };
    let options = FemOptions { resolution: 16, ..FemOptions::default() };
    let mut body =
        HyperBody::from_surface_grasped(&pos, file.mesh.triangles(), &tissue, &fixed, &[grasp], &options)
            .unwrap();
    let gravity = [0.0, -9.81, 0.0];
    let sol = body.solve(&Loads { gravity, ..Default::default() }, &[]).unwrap();
    let h = body.grid().cell_size();
    let last = sol.steps.last().unwrap();
    eprintln!(
        "liver grasp: error {:.2e} m, {} augmentations, {} Newton iterations, last step {:?}",
        sol.grasps[0].error, sol.stats.augmentations, sol.stats.newton_iterations, last.residuals
    );
    assert!(sol.grasps[0].error <= GRASP_TOLERANCE * h, "{}", sol.grasps[0].error);
    assert_eq!((sol.stats.augmentations, last.augmentation), (1, 1));
    let small: Vec<f64> = last.residuals.iter().copied().skip(1).filter(|&r| r < 1e-2).collect();
    assert!(
        small.len() >= 2 && small.windows(2).all(|w| w[1] <= 100.0 * w[0] * w[0]),
        "{:?}",
        last.residuals
    );
    let weight = 9.81 * 1060.0 * body.grid().fill().iter().sum::<f64>() * h.powi(3);
    let balance: Vec<f64> = (0..3).map(|a| sol.grasps[0].force[a] - sol.support_force[a]).collect();
    let expected = [0.0, -weight, 0.0];
    let off = (0..3).map(|a| (balance[a] - expected[a]).abs()).fold(0.0, f64::max);
    assert!(off < 1e-6 * weight, "grasper minus supports {balance:?} against the weight {weight}");
}

/// Bodies as stiff as cortical bone and stiffer (E = 1.5e10 to 1e12 Pa) hanging under their
/// own weight strain by 1e-9 to 1e-11, where the neo-Hookean stress is computed to its
/// rounding: Newton's tolerance scales with that rounding, so the solves converge, and
/// their answers equal the linear body's (the independent reference at such strains) to
/// 1e-6 of the sag.
#[test]
fn a_body_as_stiff_as_bone_converges_to_the_linear_answer() {
    let (pos, tris) = box_surface([0.0; 3], [4, 4, 4], 0.025);
    let fixed: Vec<[bool; 3]> = pos.iter().map(|p| [p[2] == 0.0; 3]).collect();
    let options = FemOptions { resolution: 12, ..FemOptions::default() };
    let loads = Loads { gravity: [0.0, 0.0, -9.81], ..Default::default() };
    for young in [1.5e10, 1e11, 1e12] {
        let bone = Tissue::new(young, 0.3, 1900.0).unwrap();
        let linear =
            FemBody::from_surface(&pos, &tris, &bone, &fixed, &options).unwrap().solve(&loads).unwrap();
        let mut body = HyperBody::from_surface(&pos, &tris, &bone.nonlinear(), &fixed, &options).unwrap();
        let sol = body.solve(&loads, &[]);
        let sag = linear.surface_displacements.iter().map(|u| u[2].abs()).fold(0.0, f64::max);
        let sol = sol.unwrap_or_else(|e| panic!("E = {young:e} Pa: {e}"));
        let diff = sol
            .surface_displacements
            .iter()
            .zip(&linear.surface_displacements)
            .flat_map(|(a, b)| (0..3).map(move |k| (a[k] - b[k]).abs()))
            .fold(0.0, f64::max);
        eprintln!(
            "E {young:e} Pa: sag {sag:.3e} m, neo-Hookean against linear {diff:.2e} m, {} iterations",
            sol.stats.newton_iterations
        );
        assert!(diff <= 1e-6 * sag, "E = {young:e} Pa: {diff} against the sag {sag}");
    }
}

/// The surface's enclosed volume change of a nearly incompressible sphere (nu = 0.4999,
/// 10 cm, E = 3 kPa) hanging from its cap at resolution `resolution`, relative: the FEM's
/// own surface, its clamped cap where the clamp's penalty left it.
fn hanging_sphere_volume_change(resolution: usize) -> f64 {
    let mesh = fibfluid_geometry::icosphere(3, 0.05);
    let fixed: Vec<[bool; 3]> = mesh.positions().iter().map(|p| [p[1] > 0.04; 3]).collect();
    let tissue = Tissue::new(3000.0, 0.4999, 1000.0).unwrap().with_model(TissueModel::NeoHookean);
    let options = FemOptions { resolution, ..FemOptions::default() };
    let mut body =
        HyperBody::from_surface(mesh.positions(), mesh.triangles(), &tissue, &fixed, &options).unwrap();
    let sol = body.solve(&Loads { gravity: [0.0, -9.81, 0.0], ..Default::default() }, &[]).unwrap();
    let deformed: Vec<[f64; 3]> = mesh
        .positions()
        .iter()
        .zip(&sol.surface_displacements)
        .map(|(p, u)| std::array::from_fn(|a| p[a] + u[a]))
        .collect();
    let rest = fibfluid_geometry::volume(mesh.positions(), mesh.triangles());
    fibfluid_geometry::volume(&deformed, mesh.triangles()) / rest - 1.0
}

/// A nearly incompressible body keeps its surface's volume: the sphere, sagging 2 cm, changes
/// its enclosed volume by less than 0.2 % at resolutions 8 and 16 (measured +0.076 and
/// +0.078 %). A run writes this surface, the clamp's slip (up to 2.7 mm here) included
/// (`a_near_incompressible_run_writes_a_surface_that_keeps_its_volume` in the facade's
/// tests): putting the clamped vertices back at rest added +1 % at resolution 8.
#[test]
#[ignore = "long run: CI runs it with `cargo test --workspace -- --ignored long_`"]
fn long_near_incompressible_surface_keeps_its_volume() {
    for resolution in [8, 16] {
        let change = hanging_sphere_volume_change(resolution);
        eprintln!("resolution {resolution}: enclosed volume change {:.3} %", 100.0 * change);
        assert!(change.abs() < 2e-3, "resolution {resolution}: {change}");
    }
}
