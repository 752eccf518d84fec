//! Regions of different tissue: two layers in series against the closed form, a surface
//! region's share against its volume, and a region outside the body refused.

use crate::common::*;
use fibfluid_fem::hyper::{HyperBody, RigidPlate};
use fibfluid_fem::{FemError, FemOptions, Loads, Region, RegionShape, SparseGrid, Tissue, blend_regions};

/// A unit column of two layers (E below z = 0.5, 4 E above, nu = 0), pressed by 1 %
/// between frictionless supports: each layer is in the same uniaxial stress, so the force is
/// `d A / (L1 / E1 + L2 / E2)` exactly (springs in series), and the top layer strains a
/// quarter as much as the bottom one.
#[test]
fn two_layers_act_as_springs_in_series() {
    let (pos, tris) = box_surface([0.0; 3], [4, 4, 4], 0.25);
    let fixed: Vec<[bool; 3]> = pos.iter().map(|p| [p[0] == 0.0, p[1] == 0.0, p[2] == 0.0]).collect();
    let soft = Tissue::new(1000.0, 0.0, 0.0).unwrap();
    let stiff = Tissue::new(4000.0, 0.0, 0.0).unwrap();
    let region =
        Region { shape: RegionShape::Box { min: [-1.0, -1.0, 0.5], max: [2.0, 2.0, 2.0] }, tissue: stiff };
    let options = FemOptions { resolution: 4, ..FemOptions::default() };
    let mut body = HyperBody::from_surface(&pos, &tris, &soft, &fixed, &options)
        .unwrap()
        .with_regions(&[region])
        .unwrap();
    assert_eq!(body.region_ids().iter().filter(|&&m| m == 1).count(), 32, "the upper half's cells");
    let d = 0.01;
    let plate = RigidPlate {
        force: None,
        start: [0.0, 0.0, 1.0],
        end: [0.0, 0.0, 1.0 - d],
        normal: [0.0, 0.0, -1.0],
    };
    let sol = body.solve(&Loads::default(), &[plate]).unwrap();
    let expected = d / (0.5 / soft.young() + 0.5 / stiff.young());
    let mid = pos.iter().position(|p| *p == [1.0, 1.0, 0.5]).unwrap();
    let lower_strain = -sol.surface_displacements[mid][2] / 0.5;
    eprintln!(
        "two layers: force {} N against {expected} N, lower strain {lower_strain}",
        sol.plate_forces[0]
    );
    assert!((sol.plate_forces[0] / expected - 1.0).abs() < 0.01);
    // The lower (soft) layer takes 4/5 of the shortening.
    assert!((lower_strain * 0.5 / d - 0.8).abs() < 0.01, "{lower_strain}");
}

/// A sphere of radius 0.3 inside the unit cube: the cells' region shares add up to the
/// sphere's volume within 3 % at resolution 16.
#[test]
fn a_surface_region_takes_its_volume() {
    let (pos, tris) = box_surface([0.0; 3], [4, 4, 4], 0.25);
    let grid = SparseGrid::from_surface(&pos, &tris, 16).unwrap();
    let (sp, st) = sphere_surface([0.5; 3], 0.3, 4);
    let base = Tissue::new(1000.0, 0.3, 0.0).unwrap();
    let lesion = Tissue::new(5000.0, 0.3, 0.0).unwrap();
    let blend = blend_regions(
        &grid,
        &base,
        &[Region {
            shape: RegionShape::Surface { positions: sp.clone(), triangles: st.clone() },
            tissue: lesion,
        }],
    )
    .unwrap();
    let h3 = grid.cell_size().powi(3);
    let share: f64 = blend
        .materials
        .iter()
        .map(|m| (m.mu - base.shear_modulus()) / (lesion.shear_modulus() - base.shear_modulus()) * h3)
        .sum();
    let volume = fibfluid_geometry::volume(&sp, &st);
    eprintln!("sphere region: {share} m^3 of cells against the surface's {volume} m^3");
    assert!((share / volume - 1.0).abs() < 0.03);
}

#[test]
fn a_region_outside_the_body_is_refused() {
    let (pos, tris) = box_surface([0.0; 3], [4, 4, 4], 0.25);
    let grid = SparseGrid::from_surface(&pos, &tris, 8).unwrap();
    let base = Tissue::new(1000.0, 0.3, 0.0).unwrap();
    let far = Region { shape: RegionShape::Box { min: [5.0; 3], max: [6.0; 3] }, tissue: base };
    let inside = Region { shape: RegionShape::Box { min: [0.2; 3], max: [0.4; 3] }, tissue: base };
    match blend_regions(&grid, &base, &[inside, far]) {
        Err(e @ FemError::RegionOutsideBody { region: 2 }) => assert!(e.to_string().contains("region 2")),
        other => panic!("{other:?}"),
    }
}
