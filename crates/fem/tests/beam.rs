//! A cantilever under its own weight against Timoshenko beam theory: convergence as the
//! resolution doubles, and no volumetric locking as nu -> 0.5.

use crate::common::*;
use fibfluid_fem::{Element, FemBody, FemOptions, Loads, Tissue};

const G: f64 = 9.81;

/// Mean vertical displacement of the tip face (x = 10) of the 10 x 1 x 1 block clamped at
/// x = 0 under gravity along -z, at `resolution` cells along the length.
fn tip_deflection(tissue: &Tissue, resolution: usize, element: Element) -> f64 {
    let (pos, tris) = box_surface([0.0; 3], [40, 4, 4], 0.25);
    let fixed: Vec<[bool; 3]> = pos.iter().map(|p| [p[0] == 0.0; 3]).collect();
    let opts = FemOptions { resolution, element };
    let mut body = FemBody::from_surface(&pos, &tris, tissue, &fixed, &opts).unwrap();
    let sol = body.solve(&Loads { gravity: [0.0, 0.0, -G], ..Default::default() }).unwrap();
    let tip: Vec<f64> = pos
        .iter()
        .zip(&sol.surface_displacements)
        .filter(|(p, _)| p[0] == 10.0)
        .map(|(_, u)| -u[2])
        .collect();
    tip.iter().sum::<f64>() / tip.len() as f64
}

/// Resolutions 20, 40, 80 (2, 4, 8 cells through the thickness). Measured: errors against
/// Timoshenko -2.6 %, -1.6 %, -1.1 %, observed order of the self-convergence
/// `log2(|d40 - d20| / |d80 - d40|)` = 0.83. Asserted: the order exceeds 0.6, the error
/// falls at each doubling, and the finest deflection is within 3 % of Timoshenko (the
/// modelling gap is the 3D clamp: beam theory lets the root section contract and warp, the
/// clamped block does not, which stiffens it by ~1 % at L/b = 10). Q1 bending alone would
/// converge at order 2; the lower order is presumably the stress singularity along the
/// clamped edges (not verified). Re-measured with the surface clamp (penalty on embedded
/// points): the same numbers, since the clamped face lies on a grid plane and its samples
/// (h / 2 apart) hit every node of it, which the clamp then fixes exactly, as the old rule
/// did. So the order is a property of the clamped-edge problem, not of the clamp rule, and
/// only what the three resolutions support is asserted.
#[test]
fn cantilever_converges_to_beam_theory() {
    let tissue = Tissue::new(1e6, 0.3, 1000.0).unwrap();
    let reference = timoshenko_tip(&tissue, 10.0, 1.0, G);
    let d: Vec<f64> = [20, 40, 80].iter().map(|&r| tip_deflection(&tissue, r, Element::BBar)).collect();
    let order = ((d[1] - d[0]).abs() / (d[2] - d[1]).abs()).log2();
    let errors: Vec<f64> = d.iter().map(|x| (x - reference) / reference).collect();
    eprintln!("cantilever: tip {d:?}, Timoshenko {reference}, errors {errors:?}, observed order {order:.2}");
    assert!(order > 0.6, "observed order {order}");
    assert!(errors[2].abs() < 0.03, "finest error {}", errors[2]);
    assert!(errors[0].abs() > errors[1].abs() && errors[1].abs() > errors[2].abs(), "{errors:?}");
}

/// nu = 0.3 and 0.499 at resolution 40 (4 cells through the thickness): B-bar stays within
/// 6 % of beam theory for both (measured 0.984 and 0.958 of it); the fully integrated Q1 at
/// nu = 0.499 deflects only 0.55 of it (volumetric locking), so the same criterion fails
/// for it, which shows the test can fail.
#[test]
fn no_locking_near_incompressibility() {
    for nu in [0.3, 0.499] {
        let tissue = Tissue::new(1e6, nu, 1000.0).unwrap();
        let reference = timoshenko_tip(&tissue, 10.0, 1.0, G);
        let bbar = tip_deflection(&tissue, 40, Element::BBar);
        let full = tip_deflection(&tissue, 40, Element::FullQ1);
        eprintln!("nu {nu}: B-bar {:.4}, full Q1 {:.4} of Timoshenko", bbar / reference, full / reference);
        assert!((bbar / reference - 1.0).abs() < 0.06, "nu {nu}: B-bar ratio {}", bbar / reference);
        if nu > 0.49 {
            assert!(full / reference < 0.7, "full Q1 ratio {}", full / reference);
        }
    }
}
