//! Tool-path files: the four headers, their rows and their errors (parsed by the scene
//! crate), and grasp and press paths replayed end to end on the paper's sphere.

use fibfluid::interact::{PathKind, ProbeError, check_path, replay};
use fibfluid::parse_tool_path;

#[test]
fn path_rows_group_and_empty_frames() {
    let p = parse_tool_path("p.csv", "frame,vertex,ux,uy,uz\n0,1,0,0,0.1\n0,2,0,0,0\n3,,,,\n").unwrap();
    assert_eq!(p.kind, PathKind::Grab);
    assert_eq!(p.frames(), 4);
    assert_eq!(p.rows[2].vertex, None);
    let e = parse_tool_path("p.csv", "frame,vertex,ux,uy,uz\n2,1,0,0,0\n1,1,0,0,0\n").unwrap_err();
    assert_eq!(e.to_string(), "p.csv:3: frame 1 comes after frame 2: frame numbers must not decrease");
    let e = parse_tool_path("p.csv", "frame,vertex,ux,uy,uz\n0,1,0,NaN,0\n").unwrap_err();
    assert_eq!(e.to_string(), "p.csv:2: uy: NaN is not finite");
    let e = parse_tool_path("p.csv", "frame,vertex,ux,uy,uz\n").unwrap_err();
    assert!(matches!(e, ProbeError::EmptyPath { .. }));
}

#[test]
fn grasp_and_press_rows_carry_a_positive_radius() {
    let p = parse_tool_path("p.csv", "frame,vertex,ux,uy,uz,radius\n0,4,0,-0.01,0,0.02\n1\n").unwrap();
    assert_eq!((p.kind, p.rows[0].vertex, p.rows[0].radius), (PathKind::Grasp, Some(4), Some(0.02)));
    assert_eq!((p.rows[1].vertex, p.rows[1].radius), (None, None));
    let p = parse_tool_path("p.csv", "frame,x,y,z,radius\n0,0.1,-1.2,0,0.3\n2,,,,\n").unwrap();
    assert_eq!((p.kind, p.rows[0].value, p.rows[0].radius), (PathKind::Press, [0.1, -1.2, 0.0], Some(0.3)));
    assert_eq!(p.frames(), 3);
    let e = parse_tool_path("p.csv", "frame,x,y,z,radius\n0,0,0,0,0\n").unwrap_err();
    assert_eq!(e.to_string(), "p.csv:2: radius: 0 must be positive");
    let e = parse_tool_path("p.csv", "frame,vertex,ux,uy,uz,radius\n0,1,0,0,0\n").unwrap_err();
    assert_eq!(e.to_string(), "p.csv:2: expected 6 comma-separated fields, found 5");
}

fn sphere() -> fibfluid::Scene {
    fibfluid::Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/fixtures/scenes/sphere.toml")).unwrap()
}

/// The file vertex of the sphere's lowest point (far from the fixed cap).
fn lowest_file_vertex(scene: &fibfluid::Scene) -> usize {
    let rest = scene.rest_positions();
    let v = (0..rest.len()).min_by(|&a, &b| rest[a][1].total_cmp(&rest[b][1])).unwrap();
    match &scene.shape {
        fibfluid::sim::Shape::Surface(f) => {
            (0..f.file_vertex_count()).find(|&fv| f.from_file_index(fv) == Some(v)).unwrap()
        }
        _ => unreachable!("the sphere is a surface"),
    }
}

fn ffm_body(scene: &fibfluid::Scene) -> fibfluid::interact::MethodBody {
    let opts = fibfluid::interact::ProbeOptions::default();
    fibfluid::interact::MethodBody::build(scene, &scene.chainmail, fibfluid::sim::Method::Ffm, &opts).unwrap()
}

#[test]
fn a_grasp_path_moves_the_patch_and_reports_its_total_force() {
    let scene = sphere();
    let v = lowest_file_vertex(&scene);
    let text = format!("frame,vertex,ux,uy,uz,radius\n0,{v},0,-0.05,0,0.45\n1,{v},0,-0.1,0,0.45\n2\n");
    let path = check_path(&parse_tool_path("g.csv", &text).unwrap(), &scene).unwrap();
    let mut body = ffm_body(&scene);
    let mut patch_moved = Vec::new();
    let r = fibfluid::interact::replay_observed(body.interactive(), &path, |k, b| {
        if k < 2 {
            // Every reaction is a patch vertex's, and every patch vertex moved by the tool.
            let held: Vec<usize> = b.reactions().iter().map(|r| r.0).collect();
            let dy = -0.05 * (k + 1) as f64;
            patch_moved.push(held.iter().all(|&u| (b.field()[u][1] - dy).abs() < 1e-9) && held.len() > 3);
        }
    })
    .unwrap();
    assert_eq!(patch_moved, [true, true]);
    assert_eq!((r.frames, r.rows.len()), (3, 2), "one row per grasp and frame");
    // The tool holds the patch above where gravity sags it: pulling it lower takes less lift.
    assert!(r.rows[1].force[1] < r.rows[0].force[1], "{:?}", r.rows);
}

#[test]
fn a_press_path_pushes_harder_as_it_goes_deeper() {
    let scene = sphere();
    let mut body = ffm_body(&scene);
    let bottom = body.interactive_ref().positions().iter().map(|p| p[1]).fold(f64::MAX, f64::min);
    let mut text = String::from("frame,x,y,z,radius\n");
    for k in 0..5 {
        text.push_str(&format!("{k},0,{},0,0.5\n", bottom - 0.5 + 0.06 * (k + 1) as f64));
    }
    text.push_str("5\n");
    let path = check_path(&parse_tool_path("p.csv", &text).unwrap(), &scene).unwrap();
    let r = replay(body.interactive(), &path).unwrap();
    let up: Vec<f64> = r.rows.iter().map(|row| row.force[1]).collect();
    assert_eq!(up.len(), 5, "one row per frame with a tip");
    assert!(up[0] > 0.0 && up.windows(2).all(|w| w[1] >= w[0]), "{up:?}");
    assert!(body.interactive_ref().reactions().is_empty(), "the lifted tip holds nothing");
}

#[test]
fn bad_tool_paths_name_the_line_and_frame() {
    let scene = sphere();
    let top = {
        let rest = scene.rest_positions();
        let v = (0..rest.len()).find(|&u| rest[u][1] < 0.8 && rest[u][1] > 0.6).unwrap();
        match &scene.shape {
            fibfluid::sim::Shape::Surface(f) => {
                (0..f.file_vertex_count()).find(|&fv| f.from_file_index(fv) == Some(v)).unwrap()
            }
            _ => unreachable!(),
        }
    };
    let text = format!("frame,vertex,ux,uy,uz,radius\n0,{top},0,-0.05,0,0.4\n");
    let path = check_path(&parse_tool_path("g.csv", &text).unwrap(), &scene).unwrap();
    let e = replay(ffm_body(&scene).interactive(), &path).unwrap_err().to_string();
    assert!(e.starts_with("g.csv:2: frame 0: the grasp of radius 0.4 m"), "{e}");
    assert!(e.contains("the scene fixes"), "{e}");
    let e = check_path(
        &parse_tool_path("p.csv", "frame,x,y,z,radius\n0,0,0,0,0.1\n0,1,1,1,0.1\n").unwrap(),
        &scene,
    )
    .unwrap_err();
    assert_eq!(
        e.to_string(),
        "p.csv:3: a second tip in frame 0 (the first is on line 2); a press path has one tip per frame"
    );
    // A tool larger than the body is refused by the check, from the rest shape.
    let e = check_path(&parse_tool_path("p.csv", "frame,x,y,z,radius\n0,0,0,0,9\n").unwrap(), &scene)
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("p.csv:2: frame 0: a tool of radius 9 m is larger than the body"), "{e}");
}
