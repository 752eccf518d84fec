//! Sensitivities of a converged equilibrium to the tissues' moduli, densities and gravity:
//! the forward and the adjoint forms against central differences of full solves.

use crate::common::*;
use fibfluid_fem::hyper::{HyperBody, NewtonSettings, Parameter, RigidPlate};
use fibfluid_fem::{FemOptions, Loads, Region, RegionShape, Tissue, TissueModel};

/// A 4 x 2 x 2 cm block clamped at x = 0, sagging under sideways gravity, its far half
/// `stiff` times stiffer: `tissue` with the region's Young's modulus scaled, Poisson's ratio
/// 0.4 and density 1100 there.
struct Case {
    pos: Vec<V3>,
    tris: Vec<[u32; 3]>,
    fixed: Vec<[bool; 3]>,
}

impl Case {
    fn new() -> Self {
        let (pos, tris) = box_surface([0.0; 3], [4, 2, 2], 0.01);
        let fixed = pos.iter().map(|p| [p[0] == 0.0; 3]).collect();
        Self { pos, tris, fixed }
    }

    /// The body with the parameters `theta` = [E0, E1, nu0, nu1, rho0, rho1, g] solved.
    fn solve(
        &self,
        model: TissueModel,
        theta: &[f64; 7],
    ) -> (HyperBody, fibfluid_fem::hyper::HyperSolution, Loads) {
        let base = Tissue::new(theta[0], theta[2], theta[4]).unwrap().with_model(model);
        let region = Region {
            shape: RegionShape::Box { min: [0.02, -1.0, -1.0], max: [1.0, 1.0, 1.0] },
            tissue: Tissue::new(theta[1], theta[3], theta[5]).unwrap().with_model(model),
        };
        let options = FemOptions { resolution: 4, ..FemOptions::default() };
        let settings = NewtonSettings { tolerance: 1e-12, ..NewtonSettings::default() };
        let mut body = HyperBody::from_surface(&self.pos, &self.tris, &base, &self.fixed, &options)
            .unwrap()
            .with_regions(&[region])
            .unwrap()
            .with_settings(settings);
        let loads = Loads { gravity: [0.0, 0.0, -theta[6]], point_forces: vec![] };
        let solution = body.solve(&loads, &[]).unwrap();
        (body, solution, loads)
    }
}

const PARAMETERS: [Parameter; 7] = [
    Parameter::Young(0),
    Parameter::Young(1),
    Parameter::Poisson(0),
    Parameter::Poisson(1),
    Parameter::Density(0),
    Parameter::Density(1),
    Parameter::Gravity,
];

/// Every parameter's forward sensitivity of the surface equals the central difference of two
/// full solves (relative step 1e-4, Newton to 1e-12) to 1e-5 of its largest entry, and the
/// adjoint gradient of a weighted sum of the surface displacements equals the forward one.
fn check(model: TissueModel) {
    let case = Case::new();
    let theta = [3000.0, 15000.0, 0.3, 0.4, 1000.0, 1100.0, 9.81];
    let (mut body, solution, loads) = case.solve(model, &theta);
    let sens = body.sensitivities(&solution, &loads, &PARAMETERS).unwrap();
    let sag = solution.surface_displacements.iter().map(|u| norm(*u)).fold(0.0, f64::max);
    eprintln!("{model:?}: largest displacement {sag:.3e} m");
    for (j, p) in PARAMETERS.iter().enumerate() {
        assert_eq!(sens.values[j], theta[j], "{p:?}'s value");
        let h = 1e-4 * theta[j];
        let (mut plus, mut minus) = (theta, theta);
        plus[j] += h;
        minus[j] -= h;
        let up = case.solve(model, &plus).1.surface_displacements;
        let down = case.solve(model, &minus).1.surface_displacements;
        let (mut err, mut size) = (0.0_f64, 0.0_f64);
        for v in 0..up.len() {
            for a in 0..3 {
                let fd = (up[v][a] - down[v][a]) / (2.0 * h);
                err = err.max((fd - sens.surface[j][v][a]).abs());
                size = size.max(fd.abs());
            }
        }
        eprintln!("{p:?}: largest du/dtheta {size:.3e}, error {:.2e} relative", err / size);
        assert!(size > 0.0 && err < 1e-5 * size, "{p:?}: {err:e} against {size:e}");
    }
    // J = sum_v w_v . u_v with fixed, varied weights.
    let weights: Vec<V3> =
        (0..case.pos.len()).map(|v| [(v % 7) as f64 - 3.0, (v % 3) as f64, 1.0 + (v % 5) as f64]).collect();
    let adjoint = body.objective_gradient(&solution, &loads, &PARAMETERS, &weights).unwrap();
    for j in 0..PARAMETERS.len() {
        let forward: f64 =
            sens.surface[j].iter().zip(&weights).map(|(d, w)| (0..3).map(|a| d[a] * w[a]).sum::<f64>()).sum();
        eprintln!("{:?}: adjoint {:.6e}, forward {forward:.6e}", PARAMETERS[j], adjoint[j]);
        assert!((adjoint[j] - forward).abs() <= 1e-8 * forward.abs(), "{:?}", PARAMETERS[j]);
    }
}

#[test]
fn neo_hookean_sensitivities_match_central_differences() {
    check(TissueModel::NeoHookean);
}

#[test]
fn linear_sensitivities_match_central_differences() {
    check(TissueModel::Linear);
}

/// A tissue index past the regions and a solve with plates are refused with typed errors,
/// not a panic.
#[test]
fn unknown_tissues_and_plates_are_refused() {
    let case = Case::new();
    let (mut body, solution, loads) =
        case.solve(TissueModel::Linear, &[3000.0, 15000.0, 0.3, 0.4, 1000.0, 1100.0, 9.81]);
    let e = body.sensitivities(&solution, &loads, &[Parameter::Young(2)]).unwrap_err();
    assert!(e.to_string().contains("tissue 2 does not exist"), "{e}");
    // A solve with a plate (here one that never touches) is not covered.
    let plate =
        RigidPlate { force: None, start: [0.0, 0.0, 1.0], end: [0.0, 0.0, 1.0], normal: [0.0, 0.0, -1.0] };
    let pressed = body.solve(&loads, &[plate]).unwrap();
    let e = body.sensitivities(&pressed, &loads, &[Parameter::Young(0)]).unwrap_err();
    assert!(e.to_string().contains("plates are not covered"), "{e}");
}
