//! Frames per second delivered to one client while it drags, at N = 10,242 (icosphere
//! level 5), and the time to the first touch after the viewer starts. Ignored by default
//! (each builds an N = 10,242 body: seconds for the base solve); they report, never
//! assert, time:
//!
//! ```text
//! cargo test -p fibfluid-viewer --test main -- --ignored frame_rate --nocapture
//! ```
//!
//! `FIBFLUID_VIEWER_LEVEL` sets another icosphere level (default 5) and
//! `FIBFLUID_VIEWER_FRAMES` the number of frames (default 600).

use std::time::Instant;

use fibfluid_interact::{Interactive, Precompute, ProbeOptions, Storage, build_body, linearized};
use fibfluid_sim::{Simulation, Stage};

use crate::common::{Client, scene_body, serve};

fn env_or(name: &str, default: usize) -> usize {
    std::env::var(name).ok().and_then(|v| v.parse().ok()).unwrap_or(default)
}

#[test]
#[ignore = "builds an N = 10,242 body (seconds); reports the frame rate"]
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

/// The time to first touch, as `fibfluid view` sees it: from the start (scene file read)
/// through the body's build, the server, a client's connection and one grab, to that grab's
/// frame; against the assembly and factorization of the same scene (a `Simulation` made
/// afterwards in this process, as `fibfluid run` times them). Ignored by default; reports,
/// never asserts:
///
/// ```text
/// FIBFLUID_VIEWER_SCENE=/tmp/s5.toml cargo test -p fibfluid-viewer --test main -- --ignored first_touch --nocapture
/// ```
///
/// Without `FIBFLUID_VIEWER_SCENE` the scene is the paper's sphere on the icosphere of
/// `FIBFLUID_VIEWER_LEVEL` (default 5); `FIBFLUID_VIEWER_PRECOMPUTE=full` times the full
/// precompute instead of the lazy columns. With `FIBFLUID_BIN` (a built `fibfluid`) the
/// server is that binary's `fibfluid view SCENE --port P --precompute ...` in a child
/// process, timed from its spawn to the frame received (the process's start included).
#[test]
#[ignore = "builds an N = 10,242 body; reports the time to the first frame after a grab"]
fn first_touch_after_start() {
    let dir = std::env::temp_dir().join(format!("fibfluid-viewer-touch-{}", std::process::id()));
    let path = match std::env::var("FIBFLUID_VIEWER_SCENE") {
        Ok(p) => std::path::PathBuf::from(p),
        Err(_) => {
            let level = env_or("FIBFLUID_VIEWER_LEVEL", 5) as u32;
            std::fs::create_dir_all(&dir).unwrap();
            let mesh = fibfluid_geometry::icosphere(level, 1.0);
            fibfluid_geometry::write_obj(dir.join("sphere.obj"), mesh.positions(), mesh.triangles()).unwrap();
            let scene_text = std::fs::read_to_string(crate::common::sphere_path())
                .unwrap()
                .replace("../meshes/icosphere-2.obj", "sphere.obj");
            std::fs::write(dir.join("sphere.toml"), scene_text).unwrap();
            dir.join("sphere.toml")
        }
    };
    let precompute: Precompute = std::env::var("FIBFLUID_VIEWER_PRECOMPUTE")
        .map_or(Precompute::Lazy, |v| v.parse().expect("full or lazy"));
    if let Ok(bin) = std::env::var("FIBFLUID_BIN") {
        return spawned_first_touch(&bin, &path, precompute);
    }
    let start = Instant::now();
    let scene = fibfluid_scene::Scene::load(&path).expect("the scene loads");
    let opts = ProbeOptions { precompute, ..Default::default() };
    let pb = build_body(&scene, &opts).expect("the body builds");
    let built = start.elapsed().as_secs_f64();
    let body = pb.body;
    let n = body.n_vertices();
    let server = serve(&scene, &body, 2);
    let rest = body.rest_positions().to_vec();
    let v = (0..n).filter(|&i| !body.is_fixed(i)).min_by(|&a, &b| rest[a][1].total_cmp(&rest[b][1])).unwrap();
    let mut c = Client::connect(server.local_addr(), "");
    let grab_sent = start.elapsed().as_secs_f64();
    c.grab(v, [rest[v][0] + 0.05, rest[v][1] - 0.1, rest[v][2]]);
    let f = c.frame();
    let first = start.elapsed().as_secs_f64();
    assert_eq!(f.reactions.len(), 1);
    c.grab(v, [rest[v][0] + 0.06, rest[v][1] - 0.1, rest[v][2]]);
    let second = c.frame().latency_us;
    drop(c);
    drop(server);
    drop(body);
    let sim = Simulation::new(linearized(&scene)).expect("the scene assembles");
    let stage =
        |name: Stage| sim.log().records().iter().filter(|r| r.name == name).map(|r| r.seconds).sum::<f64>();
    let (assembly, factorization) = (stage(Stage::Assembly), stage(Stage::Factorization));
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!(
        "first touch ({precompute}): N = {n}: start -> body built {built:.2} s (base solve {:.2} s, precompute {:.3} s) -> grab sent {grab_sent:.2} s -> its frame {first:.2} s (server latency of that frame {:.1} ms; the next frame {:.0} us); assembly + factorization of the same scene {:.2} s + {:.2} s = {:.2} s; ratio {:.2}; load average {}",
        pb.base_seconds,
        pb.precompute_seconds,
        f.latency_us / 1e3,
        second,
        assembly,
        factorization,
        assembly + factorization,
        first / (assembly + factorization),
        load.split_whitespace().take(3).collect::<Vec<_>>().join(" ")
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// [`first_touch_after_start`] against a `fibfluid view` child process.
fn spawned_first_touch(bin: &str, path: &std::path::Path, precompute: Precompute) {
    let scene = fibfluid_scene::Scene::load(path).expect("the scene loads");
    let rest = scene.rest_positions();
    let n = rest.len();
    let fixed = |v: usize| (0..3).any(|c| scene.constraints.get(v, c).is_some());
    let v = (0..n).filter(|&i| !fixed(i)).min_by(|&a, &b| rest[a][1].total_cmp(&rest[b][1])).unwrap();
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let start = Instant::now();
    let mut child = std::process::Command::new(bin)
        .args([
            "view",
            path.to_str().unwrap(),
            "--port",
            &port.to_string(),
            "--precompute",
            &precompute.to_string(),
        ])
        .stdout(std::process::Stdio::null())
        .spawn()
        .expect("fibfluid view starts");
    let addr: std::net::SocketAddr = ([127, 0, 0, 1], port).into();
    // The server binds before it builds the body; the handshake completes once it serves.
    while std::net::TcpStream::connect(addr).is_err() {
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    let mut c = Client::connect(addr, "");
    let connected = start.elapsed().as_secs_f64();
    c.grab(v, [rest[v][0] + 0.05, rest[v][1] - 0.1, rest[v][2]]);
    let f = c.frame();
    let first = start.elapsed().as_secs_f64();
    c.grab(v, [rest[v][0] + 0.06, rest[v][1] - 0.1, rest[v][2]]);
    let second = c.frame().latency_us;
    // The child's peak resident set, before it goes (`VmHWM` of its /proc status, kB).
    let peak_bytes = std::fs::read_to_string(format!("/proc/{}/status", child.id()))
        .ok()
        .and_then(|s| {
            s.lines().find(|l| l.starts_with("VmHWM:"))?.split_whitespace().nth(1)?.parse::<f64>().ok()
        })
        .map_or(0.0, |kb| kb * 1024.0);
    let _ = child.kill();
    let _ = child.wait();
    let (assembly, factorization) = run_stages(bin, path);
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!(
        "first touch ({precompute}, `fibfluid view` child): N = {n}: spawn -> handshake done {connected:.2} s -> first grab's frame {first:.2} s (server latency {:.1} ms; the next frame {second:.0} us); assembly + factorization in `fibfluid run`'s report {assembly:.2} s + {factorization:.2} s = {:.2} s; ratio {:.2}; the child's VmHWM {:.1} MiB = {:.2} x an N x N f64 factor; load average {}",
        f.latency_us / 1e3,
        assembly + factorization,
        first / (assembly + factorization),
        peak_bytes / 1048576.0,
        peak_bytes / (8.0 * (n * n) as f64),
        load.split_whitespace().take(3).collect::<Vec<_>>().join(" ")
    );
}

/// The assembly and factorization seconds of `fibfluid run` (a child process of `bin`) on
/// the scene at `path`, from its report.json's stages.
fn run_stages(bin: &str, path: &std::path::Path) -> (f64, f64) {
    let out = std::env::temp_dir().join(format!("fibfluid-touch-run-{}", std::process::id()));
    let status = std::process::Command::new(bin)
        .args(["run", path.to_str().unwrap(), "--out", out.to_str().unwrap()])
        .stdout(std::process::Stdio::null())
        .status()
        .expect("fibfluid run starts");
    assert!(status.success(), "fibfluid run failed on {}", path.display());
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).expect("report.json");
    let _ = std::fs::remove_dir_all(&out);
    let stage = |name: &str| {
        report["stages"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|s| s["name"] == name)
            .filter_map(|s| s["seconds"].as_f64())
            .sum::<f64>()
    };
    (stage("assembly"), stage("factorization"))
}
