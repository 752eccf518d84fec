//! Frames per second delivered to one client while it drags, at N = 10,242 (icosphere
//! level 5). Ignored by default (the precompute takes about a minute); it reports, never
//! asserts, time:
//!
//! ```text
//! cargo test -p fibfluid-viewer --test main -- --ignored frame_rate --nocapture
//! ```
//!
//! `FIBFLUID_VIEWER_LEVEL` sets another icosphere level (default 5) and
//! `FIBFLUID_VIEWER_FRAMES` the number of frames (default 600).

use std::time::Instant;

use fibfluid_interact::{Interactive, Storage};

use crate::common::{Client, scene_body, serve};

fn env_or(name: &str, default: usize) -> usize {
    std::env::var(name).ok().and_then(|v| v.parse().ok()).unwrap_or(default)
}

#[test]
#[ignore = "builds an N = 10,242 body (about a minute); reports the frame rate"]
fn frame_rate_while_dragging() {
    let level = env_or("FIBFLUID_VIEWER_LEVEL", 5) as u32;
    let frames = env_or("FIBFLUID_VIEWER_FRAMES", 600);
    let dir = std::env::temp_dir().join(format!("fibfluid-viewer-rate-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mesh = fibfluid_geometry::icosphere(level, 1.0);
    fibfluid_geometry::write_obj(dir.join("sphere.obj"), mesh.positions(), mesh.triangles()).unwrap();
    // The paper's sphere scene (fixtures/scenes/sphere.toml) on the finer mesh.
    let scene_text = std::fs::read_to_string(crate::common::sphere_path())
        .unwrap()
        .replace("../meshes/icosphere-2.obj", "sphere.obj");
    std::fs::write(dir.join("sphere.toml"), scene_text).unwrap();
    let start = Instant::now();
    let (scene, body) = scene_body(dir.join("sphere.toml").to_str().unwrap(), Storage::F64);
    let build = start.elapsed().as_secs_f64();
    let n = body.n_vertices();
    let server = serve(&scene, &body, 2);
    let rest = body.rest_positions().to_vec();
    // The free vertex nearest the bottom.
    let v = (0..n).filter(|&i| !body.is_fixed(i)).min_by(|&a, &b| rest[a][1].total_cmp(&rest[b][1])).unwrap();
    let mut c = Client::connect(server.local_addr(), "");
    c.send(r#"{"reset": true}"#);
    c.frame();
    let mut server_us = Vec::with_capacity(frames);
    let mut round_trip_us = Vec::with_capacity(frames);
    let t0 = Instant::now();
    for k in 0..frames {
        // A drag: down and sideways, up to 0.2 (a fifth of the radius).
        let s = 0.2 * (k as f64 / frames as f64);
        let to = [rest[v][0] + 0.5 * s, rest[v][1] - s, rest[v][2]];
        let t = Instant::now();
        c.grab(v, to);
        let f = c.frame();
        round_trip_us.push(t.elapsed().as_secs_f64() * 1e6);
        server_us.push(f.latency_us);
        assert_eq!(f.positions.len(), n);
    }
    let secs = t0.elapsed().as_secs_f64();
    let pct = |xs: &mut Vec<f64>, p: f64| {
        xs.sort_by(f64::total_cmp);
        xs[((p * xs.len() as f64).ceil() as usize).clamp(1, xs.len()) - 1]
    };
    println!(
        "viewer frame rate: N = {n}, body built in {build:.1} s; one client dragging one vertex, lockstep: {frames} frames in {secs:.3} s = {:.0} frames/s; server latency p50 {:.0} us, p99 {:.0} us; round trip (send, frame text + {} KiB positions back) p50 {:.0} us, p99 {:.0} us",
        frames as f64 / secs,
        pct(&mut server_us, 0.5),
        pct(&mut server_us, 0.99),
        12 * n / 1024,
        pct(&mut round_trip_us, 0.5),
        pct(&mut round_trip_us, 0.99),
    );
    let _ = std::fs::remove_dir_all(&dir);
}
