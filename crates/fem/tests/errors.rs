//! Bad input gives the typed errors, never a panic.

use crate::common::*;
use fibfluid_fem::{FemBody, FemError, FemOptions, GridEstimate, Loads, SparseGrid, Tissue};
use fibfluid_geometry::vec3::{cross, sub};

#[test]
fn bad_tissue_is_refused() {
    for (e, nu, rho, name) in [
        (0.0, 0.3, 1.0, "young"),
        (-1.0, 0.3, 1.0, "young"),
        (f64::NAN, 0.3, 1.0, "young"),
        (1.0, 0.5, 1.0, "poisson"),
        (1.0, 0.7, 1.0, "poisson"),
        (1.0, -1.0, 1.0, "poisson"),
        (1.0, f64::NAN, 1.0, "poisson"),
        (1.0, 0.3, -1.0, "density"),
    ] {
        match Tissue::new(e, nu, rho) {
            Err(FemError::InvalidTissue { name: n, .. }) => assert_eq!(n.key(), name),
            other => panic!("({e}, {nu}, {rho}): {other:?}"),
        }
    }
    assert!(Tissue::new(1.0, 0.499, 0.0).is_ok());
}

#[test]
fn bad_grids_are_refused() {
    let (pos, tris) = box_surface([0.0; 3], [8, 2, 1], 0.25);
    assert!(matches!(GridEstimate::of(&pos, 0), Err(FemError::InvalidResolution { resolution: 0, .. })));
    assert!(matches!(SparseGrid::from_surface(&pos, &tris, 0), Err(FemError::InvalidResolution { .. })));
    // 2 x 0.5 x 0.25: at resolution 4 a cell is 0.5, thicker than the body along z.
    match GridEstimate::of(&pos, 4) {
        Err(e @ FemError::ThinnerThanCell { axis: 'z', .. }) => {
            let text = e.to_string();
            assert!(text.contains("2.500e-1 m") && text.contains("(5.000e-1 m)"), "{text}");
        }
        other => panic!("{other:?}"),
    }
    assert!(GridEstimate::of(&pos, 8).is_ok());
    assert!(matches!(GridEstimate::of(&[], 8), Err(FemError::EmptySurface { .. })));
    let mut bad = tris.clone();
    bad[0][0] = 10_000;
    assert!(matches!(SparseGrid::from_surface(&pos, &bad, 8), Err(FemError::Mesh(_))));
}

/// A resolution whose grid has too many cells is refused naming the key and the largest
/// resolution that fits (which does fit, and one more does not).
#[test]
fn a_grid_with_too_many_cells_names_the_key_and_the_resolution_that_fits() {
    let (pos, _) = box_surface([0.0; 3], [2, 2, 2], 0.5);
    let text = GridEstimate::of(&pos, 256).expect_err("256^3 cells").to_string();
    assert!(text.contains("[fem] resolution 256"), "{text}");
    let fits: usize = text
        .split("to ")
        .last()
        .and_then(|t| t.split_whitespace().next())
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("no resolution to use: {text}"));
    assert!(GridEstimate::of(&pos, fits).is_ok() && GridEstimate::of(&pos, fits + 1).is_err(), "{text}");
}

#[test]
fn bad_constraints_and_loads_are_refused() {
    let (pos, tris) = box_surface([0.0; 3], [4, 2, 2], 0.5);
    let tissue = Tissue::new(1e4, 0.45, 1000.0).unwrap();
    let opts = FemOptions { resolution: 4, ..Default::default() };
    let none = vec![[false; 3]; pos.len()];
    // Nothing fixed: refused from the constraints, before the (singular) factorization.
    assert!(matches!(
        FemBody::from_surface(&pos, &tris, &tissue, &none, &opts),
        Err(FemError::RigidModeFree { fixed_vertices: 0, .. })
    ));
    assert!(matches!(
        FemBody::from_surface(&pos, &tris, &tissue, &none[1..], &opts),
        Err(FemError::LengthMismatch { .. })
    ));
    // At resolution 2 (2 x 1 x 1 cells) every node is on the surface.
    let all = vec![[true; 3]; pos.len()];
    let coarse = FemOptions { resolution: 2, ..Default::default() };
    assert!(matches!(FemBody::from_surface(&pos, &tris, &tissue, &all, &coarse), Err(FemError::NothingFree)));
    let fixed: Vec<[bool; 3]> = pos.iter().map(|p| [p[0] == 0.0; 3]).collect();
    let mut body = FemBody::from_surface(&pos, &tris, &tissue, &fixed, &opts).unwrap();
    let far = Loads { point_forces: vec![(pos.len(), [1.0, 0.0, 0.0])], ..Default::default() };
    assert!(matches!(body.solve(&far), Err(FemError::VertexOutOfRange { .. })));
    let nan = Loads { gravity: [0.0, f64::NAN, 0.0], ..Default::default() };
    assert!(matches!(body.solve(&nan), Err(FemError::NonFinite { .. })));
    let v = pos.iter().position(|p| p[0] == 2.0).unwrap();
    assert!(matches!(
        body.respond_held(&Loads::default(), &[(v, [0.1; 3]), (v, [0.1; 3])]),
        Err(FemError::DependentHolds { .. })
    ));
    let clamped = fixed.iter().position(|f| f[0]).unwrap();
    assert!(matches!(
        body.respond_held(&Loads::default(), &[(clamped, [0.1, 0.0, 0.0])]),
        Err(FemError::HeldOnFixed { axis: 0, .. })
    ));
}

/// Constraints that leave a rigid motion free are refused before anything is built, with
/// the motion named: two fixed vertices leave the rotation about the line through them
/// (the direction checked against the line, an independent computation), one vertex all
/// three rotations, nothing at all every motion. A fixed face, or rollers that stop each
/// motion, hold the body.
#[test]
fn constraints_that_leave_a_rigid_motion_free_are_refused() {
    let (pos, tris) = box_surface([0.0; 3], [4, 2, 2], 0.25);
    let tissue = Tissue::new(5e4, 0.45, 1000.0).unwrap();
    let far = (0..pos.len())
        .max_by(|&a, &b| norm(sub(pos[a], pos[0])).total_cmp(&norm(sub(pos[b], pos[0]))))
        .unwrap();
    let mut two = vec![[false; 3]; pos.len()];
    two[0] = [true; 3];
    two[far] = [true; 3];
    let modes = fibfluid_fem::free_rigid_modes(&pos, &two);
    assert_eq!(modes.len(), 1, "{modes:?}");
    let line = sub(pos[far], pos[0]);
    match modes[0] {
        fibfluid_fem::RigidMode::Rotation { axis, through } => {
            // Parallel to the line, and the line passes through `through`.
            assert!(norm(cross(axis, line)) < 1e-9 * norm(line), "{axis:?} against {line:?}");
            assert!(norm(cross(sub(through, pos[0]), line)) < 1e-9 * norm(line) * norm(line), "{through:?}");
        }
        other => panic!("{other:?}"),
    }
    let options = FemOptions::default();
    match FemBody::from_surface(&pos, &tris, &tissue, &two, &options) {
        Err(FemError::RigidModeFree { fixed_vertices: 2, .. }) => {}
        other => panic!("{:?}", other.map(|_| ())),
    }
    let mut one = vec![[false; 3]; pos.len()];
    one[0] = [true; 3];
    assert_eq!(fibfluid_fem::free_rigid_modes(&pos, &one).len(), 3);
    assert_eq!(fibfluid_fem::free_rigid_modes(&pos, &vec![[false; 3]; pos.len()]).len(), 6);
    // The face x = 0 fixed: held.
    let face: Vec<[bool; 3]> = pos.iter().map(|p| [p[0] == 0.0; 3]).collect();
    assert!(fibfluid_fem::free_rigid_modes(&pos, &face).is_empty());
    // Rollers: y fixed on the face y = 0, x on its edge z = 0, z on two of its corners.
    let rollers: Vec<[bool; 3]> = pos
        .iter()
        .map(|p| {
            let bottom = p[1] == 0.0;
            [bottom && p[2] == 0.0, bottom, bottom && p[2] == 0.0 && (p[0] == 0.0 || p[0] == 1.0)]
        })
        .collect();
    assert!(fibfluid_fem::free_rigid_modes(&pos, &rollers).is_empty());
}
