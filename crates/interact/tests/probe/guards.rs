//! The promises of the tools that a refusal or a second tool must not break: a refused
//! request changes nothing, a tip leaves alone what it cannot move (fixed vertices, a
//! grasp's patch) and says so, two grasps never share a vertex, and a path's tools are
//! checked against the body's size before anything is built.

use std::path::PathBuf;

use fibfluid_geometry::Vec3;
use fibfluid_geometry::vec3::{add, dist};
use fibfluid_interact::{
    Grasp, InteractError, Interactive, PathKind, PathProblem, PathRow, Press, ProbeError, RigidMotion,
    Storage, ToolLoad, ToolPath, ToolSet, check_path,
};
use fibfluid_sim::{ConstraintKind, Model, Shape};

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

#[test]
fn overlapping_grasps_are_refused_and_change_nothing() {
    let scene = sphere(ConstraintKind::Eliminate);
    let mut b = body(&scene, Storage::F64);
    let to_file = identity(&b);
    let rest = b.rest_positions().to_vec();
    let v = lowest(&b);
    // A free neighbour 0.2 to 0.5 away: patches of radius 0.3 around both share vertices.
    let u = (0..rest.len())
        .find(|&u| !b.is_fixed(u) && (0.2..0.5).contains(&dist(rest[u], rest[v])))
        .expect("a neighbour");
    let first = Grasp::new(&b, v, 0.3).unwrap();
    let second = Grasp::new(&b, u, 0.3).unwrap();
    let common: Vec<usize> = first.patch().iter().copied().filter(|w| second.patch().contains(w)).collect();
    assert!(!common.is_empty());
    let m = RigidMotion::translation([0.0, -0.05, 0.0]);
    let mut tools = ToolSet::default();
    tools.grasp(&mut b, v, 0.3, m).unwrap();
    let e = tools.grasp(&mut b, u, 0.3, RigidMotion::translation([0.05, 0.0, 0.0])).unwrap_err();
    match &e {
        InteractError::GraspsOverlap { first, second, shared } => {
            assert_eq!((*first, *second), (v, u), "{e}");
            assert!(common.contains(shared), "{e}");
        }
        other => panic!("expected the overlap named, got: {other}"),
    }
    assert!(!e.to_string().contains('\n'));
    let loads = tools.frame(&mut b, &to_file).unwrap();
    assert_eq!(loads.len(), 1, "only the first grasp: {loads:?}");
    assert_patch_held(&b, &first, &m, "after the refused grasp");
}

/// The mesh vertex -> file vertex map of a surface model.
fn file_vertices(scene: &Model) -> Vec<usize> {
    let Shape::Surface(file) = &scene.shape else { panic!("a surface") };
    let mut to_file = vec![0; file.mesh.n_vertices()];
    for (fv, v) in file.file_to_mesh().iter().enumerate() {
        if let Some(v) = v {
            to_file[*v] = fv;
        }
    }
    to_file
}

fn grasp_row(line: usize, vertex: usize, radius: f64) -> PathRow {
    PathRow { line, frame: 0, vertex: Some(vertex), value: [0.0, -0.05, 0.0], radius: Some(radius) }
}

#[test]
fn overlapping_grasps_in_a_frame_of_a_path_are_refused() {
    let scene = sphere(ConstraintKind::Eliminate);
    let Shape::Surface(file) = &scene.shape else { panic!("a surface") };
    let rest = file.mesh.positions().to_vec();
    let to_file = file_vertices(&scene);
    let v = (0..rest.len()).min_by(|&a, &c| rest[a][1].total_cmp(&rest[c][1])).unwrap();
    let u = (0..rest.len()).find(|&u| (0.2..0.5).contains(&dist(rest[u], rest[v]))).unwrap();
    let overlapping = ToolPath {
        source: PathBuf::from("tool.csv"),
        kind: PathKind::Grasp,
        rows: vec![grasp_row(2, to_file[v], 0.3), grasp_row(3, to_file[u], 0.3)],
    };
    match check_path(&overlapping, &scene) {
        Err(ProbeError::Path {
            line: 3,
            problem: PathProblem::GraspsOverlap { frame, first, first_line, second, shared },
            ..
        }) => {
            assert_eq!((frame, first, first_line, second), (0, to_file[v], 2, to_file[u]));
            let m = (0..rest.len()).find(|&m| to_file[m] == shared).unwrap();
            assert!(
                dist(rest[m], rest[v]) <= 0.3 && dist(rest[m], rest[u]) <= 0.3,
                "vertex {shared} is in both patches"
            );
        }
        other => panic!("expected the overlap refused, got {other:?}"),
    }
}

#[test]
fn a_tool_larger_than_the_body_is_refused_from_the_rest_shape() {
    // check_path sees the model only (no assembly, no factorization): a refusal there comes
    // before anything is built.
    let scene = sphere(ConstraintKind::Eliminate);
    let Shape::Surface(file) = &scene.shape else { panic!("a surface") };
    let rest = file.mesh.positions().to_vec();
    let (lo, hi) = fibfluid_geometry::bounding_box(&rest);
    let body_size = dist(lo, hi);
    let to_file = file_vertices(&scene);
    let v = (0..rest.len()).min_by(|&a, &c| rest[a][1].total_cmp(&rest[c][1])).unwrap();
    let source = PathBuf::from("tool.csv");
    let press = PathRow { line: 2, frame: 0, vertex: None, value: [0.0, -1.5, 0.0], radius: Some(5.0) };
    let too_large = [
        ToolPath { source: source.clone(), kind: PathKind::Grasp, rows: vec![grasp_row(2, to_file[v], 5.0)] },
        ToolPath { source, kind: PathKind::Press, rows: vec![press] },
    ];
    for path in &too_large {
        match check_path(path, &scene) {
            Err(ProbeError::Path {
                line: 2,
                problem: PathProblem::ToolTooLarge { frame: 0, radius, size },
                ..
            }) => {
                assert_eq!(radius, 5.0);
                assert!((size - body_size).abs() <= 1e-12 * body_size, "{size} vs {body_size}");
            }
            other => panic!("{:?}: expected the tool refused as too large, got {other:?}", path.kind),
        }
        let text = check_path(path, &scene).unwrap_err().to_string();
        assert!(
            text.starts_with("tool.csv:2: frame 0: a tool of radius 5 m is larger than the body"),
            "{text}"
        );
    }
}
