//! A material law defined outside the crate: a neo-Hookean solid with the logarithmic
//! volumetric energy `kappa / 2 (ln J)^2` and a Mullins-like softening kept as per-point
//! state. It enters the body through `HyperBody::with_law` alone; the uniaxial compression
//! of the unit cube (homogeneous, so a coarse grid is exact up to the contact's
//! penetration) is checked against this law's closed form, before and after the state is
//! committed.

use std::sync::Arc;

use crate::common::*;
use fibfluid_fem::hyper::{HyperBody, RigidPlate};
use fibfluid_fem::law::{M3, MaterialLaw, Moduli, NeoHookean, PointState, Tangent9, det};
use fibfluid_fem::{FemOptions, Loads, Tissue};

/// `W = mu_eff / 2 (J^(-2/3) I1 - 3) + kappa / 2 (ln J)^2`, `mu_eff = mu / (1 + d)`, with
/// `d` the largest `J^(-2/3) I1 - 3` a point has been committed at (its one state value).
#[derive(Debug)]
struct SofteningLogVolume;

impl SofteningLogVolume {
    fn effective(moduli: &Moduli, state: PointState<'_>) -> Moduli {
        let softening = state.values.first().copied().unwrap_or(0.0);
        Moduli { mu: moduli.mu / (1.0 + softening), kappa: moduli.kappa }
    }
}

impl MaterialLaw for SofteningLogVolume {
    fn name(&self) -> &'static str {
        "softening log-volume neo-Hookean"
    }
    fn state_len(&self) -> usize {
        1
    }
    fn isochoric_energy(&self, f: &M3, moduli: &Moduli, state: PointState<'_>) -> Option<f64> {
        NeoHookean.isochoric_energy(f, &Self::effective(moduli, state), PointState::ELASTIC)
    }
    fn isochoric_stress(&self, f: &M3, moduli: &Moduli, state: PointState<'_>) -> (M3, Tangent9) {
        NeoHookean.isochoric_stress(f, &Self::effective(moduli, state), PointState::ELASTIC)
    }
    fn volumetric(&self, theta: f64, moduli: &Moduli, _state: PointState<'_>) -> Option<[f64; 3]> {
        if !(theta > 0.0) {
            return None;
        }
        let (k, l) = (moduli.kappa, theta.ln());
        Some([0.5 * k * l * l, k * l / theta, k * (1.0 - l) / (theta * theta)])
    }
    fn commit_state(&self, f: &M3, _moduli: &Moduli, state: &mut [f64], _dt: f64) {
        let i1: f64 = f.iter().flatten().map(|x| x * x).sum();
        state[0] = state[0].max(det(f).powf(-2.0 / 3.0) * i1 - 3.0);
    }
}

/// This law's uniaxial stress at axial stretch `l` with shear modulus `mu`: the lateral
/// stretch `s` solves `dW/ds = 0` (bisection on the derivative written out by hand), the
/// nominal stress is `dW/dl`. Returns `(nominal stress, s, J^(-2/3) I1 - 3)`.
fn closed_form(mu: f64, kappa: f64, l: f64) -> (f64, f64, f64) {
    let dw = |s: f64| {
        let (j, i1) = (s * s * l, 2.0 * s * s + l * l);
        let vol = kappa * j.ln() / j;
        let ds =
            0.5 * mu * (-2.0 / 3.0 * j.powf(-5.0 / 3.0) * 2.0 * s * l * i1 + j.powf(-2.0 / 3.0) * 4.0 * s)
                + vol * 2.0 * s * l;
        let dl = 0.5 * mu * (-2.0 / 3.0 * j.powf(-5.0 / 3.0) * s * s * i1 + j.powf(-2.0 / 3.0) * 2.0 * l)
            + vol * s * s;
        (ds, dl)
    };
    let (mut lo, mut hi) = (0.5, 3.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if dw(mid).0 > 0.0 { hi = mid } else { lo = mid }
    }
    let s = 0.5 * (lo + hi);
    let (j, i1) = (s * s * l, 2.0 * s * s + l * l);
    (dw(s).1, s, j.powf(-2.0 / 3.0) * i1 - 3.0)
}

/// The plate's force on the cube pressed to `stretch`, the lateral stretch at a top corner
/// and the node displacements.
fn press(body: &mut HyperBody, pos: &[[f64; 3]], stretch: f64) -> (f64, f64, Vec<[f64; 3]>) {
    let plate = RigidPlate {
        force: None,
        start: [0.0, 0.0, 1.0],
        end: [0.0, 0.0, stretch],
        normal: [0.0, 0.0, -1.0],
    };
    let sol = body.solve(&Loads::default(), &[plate]).unwrap();
    let corner = pos.iter().position(|p| *p == [1.0, 1.0, 1.0]).unwrap();
    (-sol.plate_forces[0], 1.0 + sol.surface_displacements[corner][0], sol.node_displacements)
}

/// The law of a test file drives the whole Newton solve: stress and lateral stretch within
/// 1 % of its closed form; its per-point state, committed at the answer, holds the closed
/// form's `J^(-2/3) I1 - 3` at every point; pressed again, the softened body meets the
/// closed form with `mu / (1 + d)`.
#[test]
fn a_law_defined_outside_the_crate_meets_its_closed_form() {
    let (pos, tris) = box_surface([0.0; 3], [8, 8, 8], 1.0 / 8.0);
    let fixed: Vec<[bool; 3]> = pos.iter().map(|p| [p[0] == 0.0, p[1] == 0.0, p[2] == 0.0]).collect();
    let tissue = Tissue::new(5000.0, 0.45, 0.0).unwrap();
    let options = FemOptions { resolution: 4, ..FemOptions::default() };
    let mut body = HyperBody::from_surface(&pos, &tris, &tissue, &fixed, &options)
        .unwrap()
        .with_law(Arc::new(SofteningLogVolume));
    assert_eq!(body.law_states().len(), 8 * body.grid().n_cells(), "one value per Gauss point");
    let (mu, kappa) = (tissue.shear_modulus(), tissue.bulk_modulus());
    let stretch = 0.7;
    let (force, lateral, nodes) = press(&mut body, &pos, stretch);
    let (stress, s, d) = closed_form(mu, kappa, stretch);
    eprintln!(
        "log-volume law at {stretch}: force {force:.6} N against {stress:.6}, lateral {lateral:.6} against {s:.6}"
    );
    assert!((force / stress - 1.0).abs() < 0.01 && (lateral / s - 1.0).abs() < 0.01);

    body.commit_law_states(&nodes, 1.0);
    let cell = body.law_states().cell(0).values.to_vec();
    eprintln!("committed state {:?} against {d:.6}", &cell[..2]);
    assert!(cell.iter().all(|v| (v / d - 1.0).abs() < 0.01), "{cell:?} against {d}");
    let (force, lateral, _) = press(&mut body, &pos, stretch);
    let (stress, s, _) = closed_form(mu / (1.0 + d), kappa, stretch);
    eprintln!("softened: force {force:.6} N against {stress:.6}, lateral {lateral:.6} against {s:.6}");
    assert!((force / stress - 1.0).abs() < 0.01 && (lateral / s - 1.0).abs() < 0.01);
}
