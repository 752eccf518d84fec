//! The promises of the tools that a refusal or a second tool must not break: a refused
//! request changes nothing, and a tip leaves alone what it cannot move (fixed vertices, a
//! grasp's patch) and says so.

use fibfluid_geometry::Vec3;
use fibfluid_geometry::vec3::{add, dist};
use fibfluid_interact::{Grasp, InteractError, Interactive, Press, RigidMotion, Storage, ToolLoad, ToolSet};
use fibfluid_sim::ConstraintKind;

use super::{body, sphere};

/// A patch vertex is at its target to this, times the body's size (as in the tools tests).
const PATCH_TOLERANCE: f64 = 1e-9;

/// The diagonal of the bounding box of the rest shape.
fn size(b: &dyn Interactive) -> f64 {
    let (lo, hi) = fibfluid_geometry::bounding_box(b.rest_positions());
    dist(lo, hi)
}

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

#[test]
fn a_tip_in_the_fixed_cap_names_the_fixed_vertices_it_cannot_move() {
    let scene = sphere(ConstraintKind::Eliminate);
    let mut b = body(&scene, Storage::F64);
    let (centre, radius) = ([0.0, 1.0, 0.0], 0.3);
    // The scene fixes the cap y > 0.8: the fixed vertices inside the tip, from the rest shape.
    let rest = b.rest_positions().to_vec();
    let inside: Vec<usize> =
        (0..rest.len()).filter(|&v| rest[v][1] > 0.8 && dist(rest[v], centre) < radius).collect();
    assert!(!inside.is_empty(), "the tip reaches into the cap");
    let mut tip = Press::new(&b, radius).unwrap();
    let e = tip.place(&mut b, centre).unwrap_err();
    match &e {
        InteractError::TipReachesFixed { fixed, count, .. } => {
            assert_eq!((*fixed, *count), (inside[0], inside.len()), "{e}");
        }
        other => panic!("expected the fixed vertices named, got: {other}"),
    }
    let text = e.to_string();
    assert!(text.contains(&format!(
        "{} vertices the scene fixes (vertex {} first)",
        inside.len(),
        inside[0]
    )));
    assert!(!text.contains('\n'), "{text}");
    // Through a tool set (the viewer, Python): the same error, when the tip is pressed,
    // and the tip is not kept.
    let mut tools = ToolSet::default();
    let e = tools.press(&mut b, centre, radius).unwrap_err();
    assert!(matches!(e, InteractError::TipReachesFixed { count, .. } if count == inside.len()), "{e}");
    let to_file = identity(&b);
    let loads = tools.frame(&mut b, &to_file).unwrap();
    assert!(tip_load(&loads).is_none(), "{loads:?}");
}

/// Every patch vertex is at the target the grasp's motion gives it.
fn assert_patch_held(b: &dyn Interactive, g: &Grasp, m: &RigidMotion, when: &str) {
    let rest = b.rest_positions();
    let tolerance = PATCH_TOLERANCE * size(b);
    for &v in g.patch() {
        let e = dist(b.positions()[v], m.apply(rest[g.vertex()], rest[v]));
        assert!(e <= tolerance, "{when}: patch vertex {v} is {e:e} off its grasp target");
    }
}

#[test]
fn lifting_a_tip_leaves_the_grasp_holding_its_patch() {
    let scene = sphere(ConstraintKind::Eliminate);
    let base = body(&scene, Storage::F64);
    let to_file = identity(&base);
    let v = lowest(&base);
    let (g_radius, t_radius) = (0.4, 0.3);
    let g = Grasp::new(&base, v, g_radius).unwrap();
    let m = RigidMotion::translation([0.0, -0.1, 0.0]);
    // A tip beside the picked vertex, over the side of the patch and the free surface next
    // to it.
    let rest = base.rest_positions().to_vec();
    let centre = add(rest[v], [0.35, -0.1 - t_radius + 0.05, 0.0]);
    let covered = g.patch().iter().filter(|&&u| dist(m.apply(rest[v], rest[u]), centre) < t_radius).count();
    assert!(covered > 0 && covered < g.patch().len(), "the tip covers part of the patch ({covered})");
    for tip_first in [false, true] {
        let mut b = base.clone();
        let mut tools = ToolSet::default();
        if tip_first {
            tools.press(&mut b, centre, t_radius).unwrap();
            tools.frame(&mut b, &to_file).unwrap();
        }
        tools.grasp(&mut b, v, g_radius, m).unwrap();
        tools.press(&mut b, centre, t_radius).unwrap();
        let loads = tools.frame(&mut b, &to_file).unwrap();
        let (_, _, contacts) = tip_load(&loads).unwrap();
        assert!(contacts > 0, "tip first: {tip_first}: the tip touches the free surface");
        assert_patch_held(&b, &g, &m, &format!("tip first: {tip_first}: with the tip"));
        tools.lift(&mut b).unwrap();
        tools.frame(&mut b, &to_file).unwrap();
        assert_patch_held(&b, &g, &m, &format!("tip first: {tip_first}: after the lift"));
        let held: Vec<usize> = b.holds().iter().map(|h| h.0).collect();
        assert_eq!(held, g.patch(), "tip first: {tip_first}: the body holds the patch and nothing else");
    }
}
