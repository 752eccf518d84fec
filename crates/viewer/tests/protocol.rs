//! The protocol over real sockets: the served mesh, grabs compared with the same scene's
//! body driven directly, bad messages, coalescing, several clients, refusals.
//!
//! The reference for every frame is an [`FfmBody`] built from the same scene by
//! `fibfluid_interact::build_body` and driven through the `Interactive` trait in this
//! process (the body's own exactness against full solves is tested in crates/interact).
//! The mesh is checked against the OBJ file read independently and the scene's fixing rule.

use fibfluid_geometry::{Vec3, load_mesh};
use fibfluid_interact::{Grasp, Interactive, Press, RigidMotion, Storage};

use crate::common::{
    Client, Reply, http_get, max_dist, scene_body, serve, sphere_path, sphere_with_unused_first_vertex,
};

/// Positions travel as f32: each coordinate is rounded once (relative 2^-24); the sphere's
/// coordinates are at most ~1.2, so 4 f32 epsilons of that bound the difference.
const F32_POSITION_TOLERANCE: f64 = 4.0 * f32::EPSILON as f64 * 1.2;
/// Reactions travel as JSON f64 (shortest round trip) and are computed with the same
/// arithmetic as the direct body: equal up to a few ulps.
const REACTION_TOLERANCE: f64 = 1e-12;
/// The rest shape the body uses against the OBJ file read independently (coordinates of
/// order 1; a few ulps).
const REST_TOLERANCE: f64 = 1e-14;
/// A free vertex of the sphere (y = -0.85, the bottom; the cap y > 0.8 is fixed).
const FREE: usize = 3;
/// Another free vertex.
const FREE2: usize = 100;

fn fixed_by_rule(positions: &[Vec3]) -> Vec<u32> {
    // The scene fixes every vertex with y > 0.8 (fixtures/scenes/sphere.toml).
    (0..positions.len() as u32).filter(|&i| positions[i as usize][1] > 0.8).collect()
}

fn rel(a: Vec3, b: Vec3) -> f64 {
    let d = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
    d / (b[0] * b[0] + b[1] * b[1] + b[2] * b[2]).sqrt().max(f64::MIN_POSITIVE)
}

#[test]
fn page_mesh_and_info_are_served() {
    let (scene, body) = scene_body(sphere_path(), Storage::F64);
    let server = serve(&scene, &body, 4);
    let addr = server.local_addr();

    let (status, headers, page) = http_get(addr, "/");
    assert_eq!(status, "HTTP/1.1 200 OK");
    assert!(headers.to_ascii_lowercase().contains("content-type: text/html"));
    let page = String::from_utf8(page).unwrap();
    assert!(page.contains("<canvas"));
    assert!(!page.contains("http://") && !page.contains("https://"), "no external URL in the page");

    let (status, _, json) = http_get(addr, "/mesh");
    assert_eq!(status, "HTTP/1.1 200 OK");
    let v: serde_json::Value = serde_json::from_slice(&json).unwrap();
    let file =
        load_mesh(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meshes/icosphere-2.obj")).unwrap();
    let positions: Vec<f64> =
        v["positions"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    let expected: Vec<f64> = file.file_positions.iter().flatten().copied().collect();
    // The body's rest shape is the file's up to the rounding of the scene's loading (the
    // last bit of a few coordinates).
    assert_eq!(positions.len(), expected.len());
    let worst = positions.iter().zip(&expected).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    assert!(worst <= REST_TOLERANCE, "rest positions in the file's order (off by {worst:e})");
    let triangles: Vec<u32> =
        v["triangles"].as_array().unwrap().iter().map(|x| x.as_u64().unwrap() as u32).collect();
    assert_eq!(triangles.len(), 3 * 320);
    let fixed: Vec<u32> = v["fixed"].as_array().unwrap().iter().map(|x| x.as_u64().unwrap() as u32).collect();
    assert_eq!(fixed, fixed_by_rule(&file.file_positions));
    assert!(!fixed.is_empty());

    let (_, _, info) = http_get(addr, "/info");
    let info: serde_json::Value = serde_json::from_slice(&info).unwrap();
    assert_eq!(info["methods"][0], "ffm");

    assert_eq!(http_get(addr, "/nope").0, "HTTP/1.1 404 Not Found");
    assert_eq!(http_get(addr, "/ws").0, "HTTP/1.1 400 Bad Request");
}

#[test]
fn grab_matches_the_body_driven_directly() {
    let (scene, body) = scene_body(sphere_path(), Storage::F64);
    let server = serve(&scene, &body, 4);
    let mut direct = body.clone();
    let rest = direct.rest_positions().to_vec();
    let mut c = Client::connect(server.local_addr(), "");

    // The base state (the scene's gravity and point force), no hold.
    c.send(r#"{"reset": true}"#);
    let f0 = c.frame();
    direct.release_all();
    direct.update().unwrap();
    assert!(f0.reactions.is_empty());
    assert!(max_dist(&f0.positions, direct.positions()) <= F32_POSITION_TOLERANCE);

    // Grab: `to` is a target position, the displacement is to - rest.
    for (k, step) in [0.05, 0.1, 0.15].into_iter().enumerate() {
        let to = [rest[FREE][0] + step, rest[FREE][1] - 0.5 * step, rest[FREE][2] + 0.2 * step];
        c.grab(FREE, to);
        let f = c.frame();
        direct.grab(FREE, [to[0] - rest[FREE][0], to[1] - rest[FREE][1], to[2] - rest[FREE][2]]).unwrap();
        direct.update().unwrap();
        assert_eq!(f.frame, f0.frame + 1 + k as u64);
        assert!(max_dist(&f.positions, direct.positions()) <= F32_POSITION_TOLERANCE);
        // The grabbed vertex sits at the target.
        assert!(max_dist(&f.positions[FREE..=FREE], &[to]) <= F32_POSITION_TOLERANCE);
        assert_eq!(f.reactions.len(), 1);
        assert_eq!(f.reactions[0].0, FREE);
        let r = direct.reactions()[0].1;
        assert!(rel(f.reactions[0].1, r) <= REACTION_TOLERANCE, "{:?} vs {r:?}", f.reactions[0].1);
        assert!(r.iter().any(|x| x.abs() > 0.0), "a displaced vertex needs a force");
        assert!(f.latency_us >= 0.0 && f.latency_us.is_finite());
    }

    // Two holds, then release one.
    let to2 = [rest[FREE2][0] * 1.1, rest[FREE2][1] * 1.1, rest[FREE2][2] * 1.1];
    c.grab(FREE2, to2);
    let f = c.frame();
    direct.grab(FREE2, [0.1 * rest[FREE2][0], 0.1 * rest[FREE2][1], 0.1 * rest[FREE2][2]]).unwrap();
    direct.update().unwrap();
    assert_eq!(f.reactions.iter().map(|r| r.0).collect::<Vec<_>>(), vec![FREE, FREE2]);
    assert!(max_dist(&f.positions, direct.positions()) <= F32_POSITION_TOLERANCE);
    c.send(&format!("{{\"release\": {FREE}}}"));
    let f = c.frame();
    direct.release(FREE).unwrap();
    direct.update().unwrap();
    assert_eq!(f.reactions.len(), 1);
    assert!(max_dist(&f.positions, direct.positions()) <= F32_POSITION_TOLERANCE);

    // Reset: back to the base state.
    c.send(r#"{"reset": true}"#);
    let f = c.frame();
    assert!(f.reactions.is_empty());
    assert!(max_dist(&f.positions, &f0.positions) == 0.0);
}

#[test]
fn bad_messages_get_errors_and_the_connection_stays_open() {
    let (scene, body) = scene_body(sphere_path(), Storage::F64);
    let server = serve(&scene, &body, 4);
    let rest = body.rest_positions().to_vec();
    let fixed = fixed_by_rule(&rest)[0] as usize;
    let mut c = Client::connect(server.local_addr(), "");

    let cases: Vec<(String, &str)> = vec![
        ("grab 3".into(), "malformed message: not JSON"),
        (r#"{"grab": 3}"#.into(), "malformed message: unknown keys"),
        (r#"{"grab": "3", "to": [0, 0, 0]}"#.into(), "malformed message: `grab` must be a vertex index"),
        (r#"{"reset": false}"#.into(), "malformed message: `reset` must be true"),
        (
            r#"{"grab": 9999, "to": [0, 0, 0]}"#.into(),
            "vertex 9999 does not exist (the mesh has 162 vertices, 0-based)",
        ),
        (r#"{"release": 162}"#.into(), "vertex 162 does not exist"),
        (format!(r#"{{"grab": {fixed}, "to": [0, 1, 0]}}"#), "is fixed by the scene; it cannot be grabbed"),
        (
            r#"{"grab": 3, "to": [null, 0, 0]}"#.into(),
            "vertex 3: the target position has a non-finite component (null)",
        ),
        (r#"{"grab": 3, "to": [0, "NaN", 0]}"#.into(), "non-finite component"),
        (r#"{"grab": 3, "to": [1e400, 0, 0]}"#.into(), "malformed message"),
    ];
    for (msg, expected) in &cases {
        c.send(msg);
        let e = c.error();
        assert!(e.contains(expected), "{msg}: got `{e}`, expected `{expected}`");
    }
    c.ws.send(tungstenite::Message::binary(vec![1u8, 2, 3])).unwrap();
    assert!(c.error().contains("binary messages are not part of the protocol"));

    // Still open, and no hold was left behind by the refused messages.
    let to = [rest[FREE][0], rest[FREE][1] - 0.1, rest[FREE][2]];
    c.grab(FREE, to);
    let f = c.frame();
    assert_eq!(f.reactions.iter().map(|r| r.0).collect::<Vec<_>>(), vec![FREE]);
    assert!(max_dist(&f.positions[FREE..=FREE], &[to]) <= F32_POSITION_TOLERANCE);
}

#[test]
fn bursts_coalesce_and_the_last_state_wins() {
    let (scene, body) = scene_body(sphere_path(), Storage::F64);
    let server = serve(&scene, &body, 4);
    let rest = body.rest_positions().to_vec();
    let mut c = Client::connect(server.local_addr(), "");
    let burst = 200;
    let target = |k: usize| [rest[FREE][0], rest[FREE][1] - 0.001 * k as f64, rest[FREE][2]];
    for k in 1..=burst {
        let to = target(k);
        c.ws.write(tungstenite::Message::text(format!(
            "{{\"grab\": {FREE}, \"to\": [{:e}, {:e}, {:e}]}}",
            to[0], to[1], to[2]
        )))
        .unwrap();
    }
    c.ws.flush().unwrap();
    let mut frames = 0;
    loop {
        let f = c.frame();
        frames += 1;
        assert!(frames <= burst, "more frames than messages");
        if max_dist(&f.positions[FREE..=FREE], &[target(burst)]) <= F32_POSITION_TOLERANCE {
            break;
        }
    }
    eprintln!("{burst} grabs sent at once were answered by {frames} frames");
}

#[test]
fn two_clients_have_their_own_bodies_and_a_third_is_refused() {
    let (scene, body) = scene_body(sphere_path(), Storage::F64);
    let server = serve(&scene, &body, 2);
    let rest = body.rest_positions().to_vec();
    let mut a = Client::connect(server.local_addr(), "?method=ffm");
    let mut b = Client::connect(server.local_addr(), "");
    b.send(r#"{"reset": true}"#);
    let base = b.frame();
    let to = [rest[FREE][0] + 0.2, rest[FREE][1], rest[FREE][2]];
    a.grab(FREE, to);
    let fa = a.frame();
    b.send(r#"{"reset": true}"#);
    let fb = b.frame();
    assert_eq!(fa.reactions.len(), 1);
    assert!(fb.reactions.is_empty(), "b's body has no hold of a's");
    assert_eq!(max_dist(&fb.positions, &base.positions), 0.0);
    assert!(max_dist(&fa.positions, &fb.positions) > 0.1);

    let mut c = Client::connect(server.local_addr(), "");
    assert!(c.error().contains("the viewer is full (2 clients at most)"));
    drop(c);

    // When a leaves, a new client is served.
    a.ws.close(None).unwrap();
    while a.ws.read().is_ok() {}
    std::thread::sleep(std::time::Duration::from_millis(50));
    let mut d = Client::connect(server.local_addr(), "");
    let mut served = false;
    for _ in 0..50 {
        d.send(r#"{"reset": true}"#);
        match d.reply() {
            Reply::Frame(_) => {
                served = true;
                break;
            }
            Reply::Error(_) => {
                std::thread::sleep(std::time::Duration::from_millis(20));
                d = Client::connect(server.local_addr(), "");
            }
        }
    }
    assert!(served, "a client slot frees when a client leaves");
}

#[test]
fn unsupported_method_is_refused_with_a_message() {
    let (scene, body) = scene_body(sphere_path(), Storage::F64);
    let server = serve(&scene, &body, 2);
    let mut c = Client::connect(server.local_addr(), "?method=tsve-chainmail");
    let e = c.error();
    assert_eq!(e, "method `tsve-chainmail` is not available in this viewer (available: ffm)");
}

#[test]
fn vertices_are_in_the_file_order_with_an_unused_vertex() {
    let dir = std::env::temp_dir().join(format!("fibfluid-viewer-order-{}", std::process::id()));
    let (scene, body) = scene_body(&sphere_with_unused_first_vertex(&dir, [5.0, 5.0, 5.0]), Storage::F64);
    let (_, reference) = scene_body(sphere_path(), Storage::F64);
    let _ = std::fs::remove_dir_all(&dir);
    let server = serve(&scene, &body, 2);
    let (_, _, json) = http_get(server.local_addr(), "/mesh");
    let v: serde_json::Value = serde_json::from_slice(&json).unwrap();
    assert_eq!(v["positions"].as_array().unwrap().len(), 3 * 163);
    assert_eq!(&v["positions"].as_array().unwrap()[..3], &[5.0, 5.0, 5.0]);
    let fixed: Vec<u64> = v["fixed"].as_array().unwrap().iter().map(|x| x.as_u64().unwrap()).collect();
    let expected: Vec<u64> =
        fixed_by_rule(reference.rest_positions()).iter().map(|&i| i as u64 + 1).collect();
    assert_eq!(fixed, expected);

    let mut c = Client::connect(server.local_addr(), "");
    c.send(r#"{"grab": 0, "to": [5, 5, 5]}"#);
    assert_eq!(c.error(), "vertex 0 is not used by any face of the mesh");
    // File vertex FREE + 1 is the reference sphere's vertex FREE.
    let rest = reference.rest_positions()[FREE];
    let to = [rest[0] + 0.1, rest[1], rest[2] - 0.05];
    c.grab(FREE + 1, to);
    let f = c.frame();
    let mut direct = reference.clone();
    direct.grab(FREE, [0.1, 0.0, -0.05]).unwrap();
    direct.update().unwrap();
    assert_eq!(f.positions.len(), 163);
    assert_eq!(f.positions[0], [5.0, 5.0, 5.0], "the unused vertex stays at its rest position");
    assert!(max_dist(&f.positions[1..], direct.positions()) <= F32_POSITION_TOLERANCE);
    assert_eq!(f.reactions.len(), 1);
    assert_eq!(f.reactions[0].0, FREE + 1);
    // The reference is a different scene file (same body); its reaction agrees to rounding.
    assert!(rel(f.reactions[0].1, direct.reactions()[0].1) <= 1e-9);
}

fn vec3(v: &serde_json::Value) -> Vec3 {
    let a = v.as_array().expect("[x, y, z]");
    [0, 1, 2].map(|i| a[i].as_f64().expect("a number"))
}

#[test]
fn grasp_and_press_match_the_tools_driven_directly() {
    let (scene, body) = scene_body(sphere_path(), Storage::F64);
    let server = serve(&scene, &body, 4);
    let mut direct = body.clone();
    let rest = direct.rest_positions().to_vec();
    let mut c = Client::connect(server.local_addr(), "");
    c.send(r#"{"reset": true}"#);
    c.frame();

    // A grasp: the patch moves with the picked vertex; the tool's force is the patch total.
    let to = [rest[FREE][0] + 0.05, rest[FREE][1] - 0.1, rest[FREE][2]];
    c.send(&format!(r#"{{"grasp": {FREE}, "radius": 0.45, "to": [{:e}, {:e}, {:e}]}}"#, to[0], to[1], to[2]));
    let f = c.frame();
    let g = Grasp::new(&direct, FREE, 0.45).unwrap();
    let m = RigidMotion::translation([0.05, -0.1, 0.0]);
    g.hold(&mut direct, &m).unwrap();
    direct.update().unwrap();
    assert!(max_dist(&f.positions, direct.positions()) <= F32_POSITION_TOLERANCE);
    assert_eq!(f.tools.len(), 1, "{:?}", f.tools);
    assert_eq!(f.tools[0]["vertices"].as_u64(), Some(g.patch().len() as u64));
    assert!(rel(vec3(&f.tools[0]["force"]), g.wrench(&direct, &m).force) <= REACTION_TOLERANCE);
    c.send(&format!(r#"{{"release": {FREE}}}"#));
    assert!(c.frame().tools.is_empty());
    g.release(&mut direct).unwrap();
    direct.update().unwrap();

    // A press from below: the same contacts and force as the tip driven directly.
    let base = direct.positions()[FREE];
    let centre = [base[0], base[1] - 0.5 + 0.1, base[2]];
    c.send(&format!(r#"{{"press": [{:e}, {:e}, {:e}], "radius": 0.5}}"#, centre[0], centre[1], centre[2]));
    let f = c.frame();
    let mut tip = Press::new(&direct, 0.5).unwrap();
    let r = tip.place(&mut direct, centre).unwrap();
    assert!(max_dist(&f.positions, direct.positions()) <= F32_POSITION_TOLERANCE);
    assert_eq!(f.tools[0]["contacts"].as_u64(), Some(r.contacts.len() as u64));
    assert!(rel(vec3(&f.tools[0]["force"]), r.force) <= REACTION_TOLERANCE && r.force[1] > 0.0);
    c.send(r#"{"lift": true}"#);
    assert!(c.frame().tools.is_empty());

    // Bad tools: an error each, the connection stays open.
    for bad in [
        r#"{"grasp": 3, "radius": -1, "to": [0, 0, 0]}"#.to_string(),
        r#"{"press": [0, 0, 0], "radius": 0}"#.to_string(),
        format!(r#"{{"grasp": {FREE}, "radius": 50, "to": [0, 0, 0]}}"#),
    ] {
        c.send(&bad);
        match c.reply() {
            Reply::Error(e) => assert!(e.contains("radius"), "{bad}: {e}"),
            other => panic!("{bad}: {other:?}"),
        }
    }
    c.send(r#"{"reset": true}"#);
    assert!(c.frame().tools.is_empty());
}
