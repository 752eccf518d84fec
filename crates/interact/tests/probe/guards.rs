//! The promises of the tools that a refusal must not break: a refused request changes
//! nothing.

use fibfluid_geometry::Vec3;
use fibfluid_geometry::vec3::dist;
use fibfluid_interact::{InteractError, Interactive, Storage, ToolLoad, ToolSet};
use fibfluid_sim::ConstraintKind;

use super::{body, sphere};

/// The lowest vertex of the sphere (far from the fixed cap y > 0.8).
fn lowest(b: &dyn Interactive) -> usize {
    let r = b.rest_positions();
    (0..r.len()).min_by(|&a, &c| r[a][1].total_cmp(&r[c][1])).unwrap()
}

/// The identity map of body to file vertices (the sphere has no unused vertex).
fn identity(b: &dyn Interactive) -> Vec<u32> {
    (0..b.n_vertices() as u32).collect()
}

/// The tip's load in a frame's loads.
fn tip_load(loads: &[ToolLoad]) -> Option<(Vec3, f64, usize)> {
    loads.iter().find_map(|l| match l {
        ToolLoad::Press { press, radius, contacts, .. } => Some((*press, *radius, *contacts)),
        _ => None,
    })
}

#[test]
fn a_refused_press_keeps_the_working_tip() {
    let scene = sphere(ConstraintKind::Eliminate);
    let mut b = body(&scene, Storage::F64);
    let to_file = identity(&b);
    let bottom = b.rest_positions()[lowest(&b)];
    let centre = [bottom[0], bottom[1] - 0.6 + 0.1, bottom[2]];
    let mut tools = ToolSet::default();
    tools.press(&mut b, centre, 0.6).unwrap();
    let before = tools.frame(&mut b, &to_file).unwrap();
    let (_, _, contacts) = tip_load(&before).expect("the tip is placed");
    assert!(contacts > 0, "the tip touches the body");
    let positions = b.positions().to_vec();
    for (c, r) in [(centre, 50.0), (centre, 1e308), (centre, -1.0), ([0.0, f64::NAN, 0.0], 0.6)] {
        let e = tools.press(&mut b, c, r).unwrap_err();
        assert!(!e.to_string().contains('\n'), "{e}");
    }
    let after = tools.frame(&mut b, &to_file).unwrap();
    assert_eq!(tip_load(&after), Some((centre, 0.6, contacts)), "the refused presses changed the tip");
    let moved = positions.iter().zip(b.positions()).map(|(p, q)| dist(*p, *q)).fold(0.0, f64::max);
    assert!(moved <= 1e-9 * 2.0, "the surface moved by {moved:e} after refused presses");
}

#[test]
fn a_non_finite_tip_centre_names_the_centre() {
    let scene = sphere(ConstraintKind::Eliminate);
    let mut b = body(&scene, Storage::F64);
    let mut tools = ToolSet::default();
    let e = tools.press(&mut b, [0.0, f64::NAN, 0.0], 0.3).unwrap_err();
    assert!(matches!(e, InteractError::NonFiniteCentre { .. }), "{e}");
    assert!(e.to_string().contains("the tip's centre"), "{e}");
}
