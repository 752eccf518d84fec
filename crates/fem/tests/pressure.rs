//! Pressure loads on a hollow sphere (two icospheres, the inner one reversed: a body with
//! one cavity): the work of a cavity pressure against the strain energy it stores, the
//! cavity under an outer pressure against Lamé's solution, and the inflated thick sphere
//! against the closed form of the incompressible neo-Hookean sphere.

use fibfluid_fem::hyper::{HyperBody, HyperCell, Pressure};
use fibfluid_fem::{FemOptions, Loads, Tissue, TissueModel};

type V3 = [f64; 3];

/// A hollow sphere of radii `inner` and `outer` (icospheres of `level`): positions, outer
/// faces, cavity faces (reversed: facing the hole).
fn hollow_sphere(inner: f64, outer: f64, level: u32) -> (Vec<V3>, Vec<[u32; 3]>, Vec<[u32; 3]>) {
    let a = fibfluid_geometry::icosphere(level, outer);
    let b = fibfluid_geometry::icosphere(level, inner);
    let n = a.n_vertices() as u32;
    let mut positions = a.positions().to_vec();
    positions.extend_from_slice(b.positions());
    let cavity = b.triangles().iter().map(|t| [t[0] + n, t[2] + n, t[1] + n]).collect();
    (positions, a.triangles().to_vec(), cavity)
}

/// The six outer vertices on the axes hold the two axes across them: no rigid motion,
/// nothing against a radial expansion.
fn axis_supports(positions: &[V3], outer: f64) -> Vec<[bool; 3]> {
    positions
        .iter()
        .map(|p| {
            let on = |a: usize| (p[a].abs() - outer).abs() < 1e-9 * outer;
            std::array::from_fn(|a| (0..3).any(|b| b != a && on(b)))
        })
        .collect()
}

/// A solved hollow sphere.
struct Solved {
    body: HyperBody,
    rest: Vec<V3>,
    deformed: Vec<V3>,
    cavity: Vec<[u32; 3]>,
    nodes: Vec<V3>,
}

/// Solves the hollow sphere with `pressures` (on the outer faces, on the cavity faces) at
/// `resolution`.
fn solve(
    tissue: &Tissue,
    (inner, outer, level): (f64, f64, u32),
    resolution: usize,
    [p_outer, p_cavity]: [f64; 2],
) -> Solved {
    let (positions, outer_faces, cavity_faces) = hollow_sphere(inner, outer, level);
    let mut triangles = outer_faces.clone();
    triangles.extend_from_slice(&cavity_faces);
    let fixed = axis_supports(&positions, outer);
    let options = FemOptions { resolution, ..FemOptions::default() };
    let pressures = [
        Pressure { value: p_outer, faces: outer_faces },
        Pressure { value: p_cavity, faces: cavity_faces.clone() },
    ];
    let mut body = HyperBody::from_surface(&positions, &triangles, tissue, &fixed, &options)
        .unwrap()
        .with_pressures(&pressures)
        .unwrap();
    let sol = body.solve(&Loads::default(), &[]).unwrap();
    let deformed: Vec<V3> = positions
        .iter()
        .zip(&sol.surface_displacements)
        .map(|(p, u)| std::array::from_fn(|a| p[a] + u[a]))
        .collect();
    Solved { body, rest: positions, deformed, cavity: cavity_faces, nodes: sol.node_displacements }
}

fn cavity_volume(faces: &[[u32; 3]], positions: &[V3]) -> f64 {
    -Pressure { value: 0.0, faces: faces.to_vec() }.enclosed_volume(positions)
}

/// The strain energy the body stores at node displacements `u` (J).
fn strain_energy(body: &HyperBody, u: &[V3]) -> f64 {
    let grid = body.grid();
    let cell = HyperCell::new(grid.cell_size());
    grid.cell_nodes()
        .iter()
        .enumerate()
        .map(|(c, nodes)| cell.energy(&body.materials()[c], &nodes.map(|n| u[n]), grid.fill()[c]).unwrap())
        .sum()
}

/// A cavity pressure's work `W = int p dV` (by parts, `P dV(P) - int dV dp`, Simpson over
/// 0, P/2 and P) equals the strain energy stored at the full pressure within 1 % (measured
/// 7.5e-4; 5e-5 with five pressures): the follower pressure is conservative and its volume
/// is the cavity's.
#[test]
fn cavity_pressure_work_is_the_stored_energy() {
    let tissue = Tissue::new(5000.0, 0.45, 0.0).unwrap().with_model(TissueModel::NeoHookean);
    let shape = (1.0, 2.0, 2);
    let p = 600.0;
    let mut dv = vec![0.0];
    let mut stored = 0.0;
    for k in 1..=2 {
        let Solved { body, rest, deformed, cavity, nodes } =
            solve(&tissue, shape, 8, [0.0, p * k as f64 / 2.0]);
        dv.push(cavity_volume(&cavity, &deformed) - cavity_volume(&cavity, &rest));
        stored = strain_energy(&body, &nodes);
    }
    let integral = p / 6.0 * (dv[0] + 4.0 * dv[1] + dv[2]);
    let work = p * dv[2] - integral;
    eprintln!("cavity dV {dv:?} m^3; work {work:.6e} J, stored {stored:.6e} J");
    assert!(dv[2] > 0.05, "the cavity grows: {dv:?}");
    assert!((work / stored - 1.0).abs() < 0.01, "work {work} against stored {stored}");
}

/// A cavity with no pressure keeps its shape while an outer pressure (small, the linear
/// law: a dead load) squeezes the body: every cavity vertex moves radially, by Lamé's
/// `u(a) = A a (1 + 3K / 4mu)`, `A = -p / (3K (1 - a^3 / b^3))`, within 6 % on average at
/// resolution 16 (measured: 9 % at 12, 3.8 % at 16, 2.2 % at 24: the cut cells converge
/// from the stiff side), the spread over the vertices within 10 % of it, and the
/// tangential motion below 5 % of it.
#[test]
fn unpressed_cavity_keeps_its_shape_under_outer_pressure() {
    let tissue = Tissue::new(5000.0, 0.3, 0.0).unwrap();
    let (a, b, p) = (1.0, 2.0, 10.0);
    let Solved { rest, deformed, cavity, .. } = solve(&tissue, (a, b, 3), 16, [p, 0.0]);
    let (k, mu) = (tissue.bulk_modulus(), tissue.shear_modulus());
    let lame = -p / (3.0 * k * (1.0 - (a / b).powi(3))) * a * (1.0 + 3.0 * k / (4.0 * mu));
    let mut vertices: Vec<u32> = cavity.iter().flatten().copied().collect();
    vertices.sort_unstable();
    vertices.dedup();
    let (mut radial, mut tangential) = (Vec::new(), 0.0f64);
    for &v in &vertices {
        let (x, d) = (
            rest[v as usize],
            std::array::from_fn::<f64, 3, _>(|i| deformed[v as usize][i] - rest[v as usize][i]),
        );
        let r = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt();
        let ur = (x[0] * d[0] + x[1] * d[1] + x[2] * d[2]) / r;
        let t: f64 = (0..3).map(|i| (d[i] - ur * x[i] / r).powi(2)).sum::<f64>().sqrt();
        radial.push(ur);
        tangential = tangential.max(t);
    }
    let mean = radial.iter().sum::<f64>() / radial.len() as f64;
    let spread = radial.iter().fold(0.0f64, |m, u| m.max((u - mean).abs()));
    eprintln!("u(a): mean {mean:.4e}, Lamé {lame:.4e}, spread {spread:.2e}, tangential {tangential:.2e}");
    assert!((mean / lame - 1.0).abs() < 0.06, "mean {mean} against {lame}");
    assert!(spread < 0.1 * lame.abs() && tangential < 0.05 * lame.abs());
}

/// The incompressible neo-Hookean thick sphere (inner radius A, outer B) under an inner
/// pressure p, from the radial equilibrium `dsigma_rr/dr = 2 (sigma_tt - sigma_rr) / r`
/// with `sigma_tt - sigma_rr = mu (l^2 - l^-4)`, `l = r / R` (Ogden, Non-linear Elastic
/// Deformations, §5.3): `p = mu (2/lb + 1/(2 lb^4) - 2/la - 1/(2 la^4))` with the inner
/// stretch `la` and the outer one `lb^3 = 1 + (la^3 - 1) A^3 / B^3`.
fn thick_sphere_pressure(mu: f64, la: f64, a: f64, b: f64) -> f64 {
    let lb = (1.0 + (la.powi(3) - 1.0) * (a / b).powi(3)).cbrt();
    mu * (2.0 / lb + 0.5 / lb.powi(4) - 2.0 / la - 0.5 / la.powi(4))
}

/// The inner stretch the closed form gives at pressure `p` (bisection below the limit
/// point).
fn thick_sphere_stretch(mu: f64, p: f64, a: f64, b: f64) -> f64 {
    let (mut lo, mut hi) = (1.0, 1.8);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if thick_sphere_pressure(mu, mid, a, b) < p { lo = mid } else { hi = mid }
    }
    0.5 * (lo + hi)
}

/// The mean inner stretch (deformed over rest radius of the cavity's vertices).
fn inner_stretch(rest: &[V3], deformed: &[V3], cavity: &[[u32; 3]]) -> f64 {
    let r = |p: V3| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
    let vs: Vec<usize> = cavity.iter().flatten().map(|&v| v as usize).collect();
    vs.iter().map(|&v| r(deformed[v]) / r(rest[v])).sum::<f64>() / vs.len() as f64
}

/// Runs the thick sphere (1, 2) at `resolution` for target inner stretches; returns the
/// largest relative error of the stretch over the closed form's.
fn thick_sphere_error(nu: f64, resolution: usize, level: u32, stretches: &[f64]) -> f64 {
    let tissue = Tissue::new(5000.0, nu, 0.0).unwrap().with_model(TissueModel::NeoHookean);
    let mu = tissue.shear_modulus();
    let mut worst = 0.0f64;
    for &target in stretches {
        let p = thick_sphere_pressure(mu, target, 1.0, 2.0);
        let Solved { rest, deformed, cavity, .. } = solve(&tissue, (1.0, 2.0, level), resolution, [0.0, p]);
        let la = inner_stretch(&rest, &deformed, &cavity);
        let exact = thick_sphere_stretch(mu, p, 1.0, 2.0);
        let err = ((la - 1.0) / (exact - 1.0) - 1.0).abs();
        let rel = (la / exact - 1.0).abs();
        eprintln!(
            "nu {nu}, resolution {resolution}: p/mu {:.4}, inner stretch {la:.5}, closed form {exact:.5}, error {:.3} % (of the stretch - 1: {:.2} %)",
            p / mu,
            100.0 * rel,
            100.0 * err
        );
        worst = worst.max(rel);
    }
    worst
}

/// Quick: the thick sphere at resolution 10 (2.5 cells through the wall), nu = 0.49, at
/// an inner stretch of 1.1: the stretch within 4 % of the closed form (measured 1.8 %; at
/// 1.2, 2.7 % at resolution 12, 1.2 % at 16, 0.6 % at 24).
#[test]
fn thick_sphere_coarse_matches_closed_form() {
    let worst = thick_sphere_error(0.49, 10, 2, &[1.1]);
    assert!(worst < 0.04, "{worst}");
}

/// The thick sphere at resolution 24 (six cells through the wall), nu = 0.499, five
/// pressures up to an inner stretch of 1.5: each stretch within 3 % of the closed form.
/// Measured (200 s on two loaded cores): 0.45, 0.84, 1.27, 1.84 and 2.68 % at the closed
/// form's 1.1 to 1.5, always short (the cut cells are stiff), 5 to 8 % of the stretch
/// minus one; 1 % holds up to 1.2 at this resolution.
#[test]
#[ignore = "long run: CI runs it with `cargo test --workspace -- --ignored long_`"]
fn long_thick_sphere_matches_closed_form() {
    let worst = thick_sphere_error(0.499, 24, 3, &[1.1, 1.2, 1.3, 1.4, 1.5]);
    assert!(worst < 0.03, "{worst}");
}
