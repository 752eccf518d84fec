//! The fiber models (`[ffm] fibers = "paper" | "projected"`) against the independent P2
//! finite-element goldens of `crates/fem/tests/golden` (E = 50 kPa, nu = 0.45, rho = 1000,
//! g = 9.81 down): FFM in paper mode, one step, fiber modulus E, no surface tension, fluid
//! density 1000; the relative L2 shape error of the surface displacement after the best
//! single scale (`calibration::best_scale`).

use std::path::{Path, PathBuf};
use std::time::Instant;

use fibfluid::sim::Error as SimError;
use fibfluid::sim::calibration::best_scale;
use fibfluid::stages::names;
use fibfluid::{Method, Plan, RunOptions, Scene, Shape, Simulation};

type V3 = [f64; 3];

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A paper-mode gravity scene on `mesh` with the clamp `fix` (a `[[fix]]` selector line).
fn scene(dir: &Path, mesh: &Path, fix: &str, fibers: &str, extra: &str) -> Scene {
    let text = format!(
        r#"
[mesh]
path = "{}"
[ffm]
fiber_modulus = 5e4
surface_tension = 0.0
fibers = "{fibers}"
[fluid]
density = 1000.0
[gravity]
acceleration = [0.0, -9.81, 0.0]
[[fix]]
axis = "y"
{fix}
[solver]
mode = "paper"
{extra}
"#,
        mesh.display()
    );
    let path = dir.join(format!("{fibers}.toml"));
    std::fs::write(&path, text).unwrap();
    Scene::load(&path).unwrap()
}

fn golden(name: &str) -> Vec<V3> {
    std::fs::read_to_string(root().join("crates/fem/tests/golden").join(name))
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            [v[0], v[1], v[2]]
        })
        .collect()
}

/// FFM's shape error against the golden and the seconds of setup and run.
fn shape_error(scene: Scene, golden_file: &str) -> (f64, f64) {
    let Shape::Surface(file) = &scene.model.shape else { panic!("a surface") };
    let file = file.clone();
    let start = Instant::now();
    let mut sim = Simulation::new(scene).unwrap();
    sim.run(&RunOptions::default()).unwrap();
    let seconds = start.elapsed().as_secs_f64();
    let u: Vec<V3> = sim
        .positions()
        .iter()
        .zip(sim.rest_positions())
        .map(|(p, r)| [p[0] - r[0], p[1] - r[1], p[2] - r[2]])
        .collect();
    let g = golden(golden_file);
    let theirs: Vec<V3> = (0..u.len()).map(|i| g[file.from_file_index(i).unwrap()]).collect();
    (best_scale(&u, &theirs).1, seconds)
}

fn mesh(name: &str) -> PathBuf {
    root().join("fixtures/meshes").join(name)
}

/// liver2 hanging from its top swings about the small clamp: the paper's fibers resist
/// that rotation and the projected ones do not, so the projected shape is much closer to
/// the FEM's (measured 0.149 against 0.732). The sphere hanging from its cap is symmetric
/// about the clamp (no swing): there the two models are close (measured 0.200 against
/// 0.191); the projected network's own Poisson ratio (central forces) limits it.
#[test]
#[ignore = "long run: CI runs it with `cargo test --workspace -- --ignored long_`"]
fn long_projected_fibers_beat_the_papers_on_a_swinging_body() {
    let dir = tempfile::tempdir().unwrap();
    let liver = mesh("liver2.obj");
    let (paper, _) = shape_error(scene(dir.path(), &liver, "top = 0.08", "paper", ""), "liver2-hanging.txt");
    let (projected, _) =
        shape_error(scene(dir.path(), &liver, "top = 0.08", "projected", ""), "liver2-hanging.txt");
    eprintln!("liver2: paper {paper:.4}, projected {projected:.4}");
    assert!(projected < 0.7 * paper, "projected {projected} vs paper {paper}");
    let sphere = mesh("icosphere-3.obj");
    let (paper, _) =
        shape_error(scene(dir.path(), &sphere, "above = 0.8", "paper", ""), "sphere-gravity.txt");
    let (projected, _) =
        shape_error(scene(dir.path(), &sphere, "above = 0.8", "projected", ""), "sphere-gravity.txt");
    eprintln!("sphere: paper {paper:.4}, projected {projected:.4}");
    assert!(projected < 1.1 * paper, "projected {projected} vs paper {paper}");
}

/// What projected fibers do not run (plates, mixed precision) is refused in one line,
/// before any work; the plan counts the coupled matrix and its factor; several paper-mode
/// steps run.
#[test]
fn projected_fibers_refuse_what_is_not_built() {
    let dir = tempfile::tempdir().unwrap();
    let sphere = mesh("icosphere-2.obj");
    let plate = "[[plate]]\npoint = [0.0, -1.0, 0.0]\nnormal = [0.0, 1.0, 0.0]\ntravel = 0.1\n";
    for (extra, says) in [(plate, "plates"), ("precision = \"mixed\"", "mixed")] {
        let s = scene(dir.path(), &sphere, "above = 0.8", "projected", extra);
        let e = Simulation::new(s).err().expect("refused");
        let text = e.to_string();
        assert!(matches!(e, SimError::MethodNeeds { method: Method::Ffm, .. }), "{e:?}");
        assert!(text.contains(says) && !text.contains('\n'), "{text}");
    }
    let s = scene(dir.path(), &sphere, "above = 0.8", "projected", "");
    let paper = scene(dir.path(), &sphere, "above = 0.8", "paper", "");
    let m = 3 * 162u64;
    let (ours, theirs) = (Plan::from_scene(&s.model), Plan::from_scene(&paper.model));
    assert_eq!(ours.memory_bytes - theirs.memory_bytes, 2 * m * m * 8);
    let mut two = s.clone();
    two.model.load.steps = 2;
    let mut sim = Simulation::new(two).unwrap();
    sim.run(&RunOptions::default()).unwrap();
    assert_eq!(sim.step_stats().taken, 2);
    assert!(sim.counters().residual_max < 1e-12);
    assert!(sim.positions().iter().zip(sim.rest_positions()).any(|(p, r)| p[1] < r[1] - 1e-6));
    let e = sim.respond(&[(0, [0.0, 1.0, 0.0])]).unwrap_err();
    assert!(e.to_string().contains("interactive"), "{e}");
    // The interactive body (probe, view, compare, Python) refuses too, in one line.
    let e = fibfluid::interact::build_body(&s, &fibfluid::interact::ProbeOptions::default()).unwrap_err();
    assert!(e.to_string().contains("projected") && !e.to_string().contains('\n'), "{e}");
}

/// Largest distance of the run's vertices from where the rotation by `angle` about z takes
/// their rest positions (the unit sphere: relative to its radius).
fn rotation_miss(sim: &Simulation, angle: f64) -> f64 {
    let (c, s) = (angle.cos(), angle.sin());
    sim.positions()
        .iter()
        .zip(sim.rest_positions())
        .map(|(p, r)| {
            let q = [c * r[0] - s * r[1], s * r[0] + c * r[1], r[2]];
            ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
        })
        .fold(0.0, f64::max)
}

/// Projected fibers cost nothing under a rigid rotation: with the cap turned 0.5 rad about
/// z (prescribed displacements `R p - p`, no load) and the operator re-assembled on the
/// current shape at each of 20 steps (nonlinear mode), the whole unit sphere follows the
/// rotation (the exact answer is the rotated rest shape; each linearized step misses by
/// about (0.5 / 20)^2, so 20 of them by about 0.0125). Operators kept from the rest shape
/// (paper and refresh modes) only know infinitesimal rotations and miss by about
/// 0.5^2 / 2; the paper's fibers (a Laplacian per axis) drag the body along without turning
/// it and miss by most of the radius. Volume: refresh and nonlinear keep it (1e-9).
#[test]
fn projected_fibers_follow_a_rigid_rotation_in_nonlinear_mode() {
    let dir = tempfile::tempdir().unwrap();
    let sphere = mesh("icosphere-2.obj");
    let angle: f64 = 0.5;
    let (c, s) = (angle.cos(), angle.sin());
    let run = |fibers: &str, mode: fibfluid::Mode| {
        let mut sc = scene(dir.path(), &sphere, "above = 0.8", fibers, "");
        sc.model.load.gravity = [0.0; 3];
        sc.model.material.set_density(0.0).unwrap();
        sc.model.load.steps = 20;
        sc.model.solver.mode = mode;
        let rest = sc.rest_positions();
        for (v, p) in rest.iter().enumerate().filter(|(_, p)| p[1] > 0.8) {
            let q = [c * p[0] - s * p[1], s * p[0] + c * p[1], p[2]];
            for a in 0..3 {
                sc.model.constraints.prescribe(v, a, q[a] - p[a]).unwrap();
            }
        }
        let mut sim = Simulation::new(sc).unwrap();
        sim.run(&RunOptions::default()).unwrap();
        assert!(sim.counters().residual_max < 1e-10, "{fibers} {mode}");
        if mode != fibfluid::Mode::Paper {
            assert!((sim.volume() / sim.volume_initial() - 1.0).abs() < 1e-9, "{fibers} {mode}: volume");
        }
        rotation_miss(&sim, angle)
    };
    let nonlinear = run("projected", fibfluid::Mode::Nonlinear);
    let kept = run("projected", fibfluid::Mode::Paper);
    let refresh = run("projected", fibfluid::Mode::Refresh);
    let laplacian = run("paper", fibfluid::Mode::Nonlinear);
    eprintln!(
        "rotation miss: projected nonlinear {nonlinear:.4}, paper mode {kept:.4}, refresh {refresh:.4}; paper fibers nonlinear {laplacian:.4}"
    );
    assert!(nonlinear < 0.03, "projected, nonlinear: misses the rotation by {nonlinear}");
    assert!(kept > 0.06 && refresh > 0.06, "kept operators: {kept}, {refresh}");
    assert!(nonlinear < 0.3 * kept.min(refresh), "{nonlinear} vs {kept}, {refresh}");
    assert!(laplacian > 0.3, "the paper's fibers miss by {laplacian}");
}

/// `[ffm] kernel_exponent = 3` (bulk weights falling as `1 / d^3`) against the independent P2
/// golden of the sphere hanging from its cap: measured 0.063 for the paper's fibers (0.191
/// with the paper's `1 / d`) and 0.132 for projected fibers (0.200); the test asks for
/// less than half and less than 0.8 of the `1 / d` error. The kernel's length scale is the
/// bounding-box diagonal, so the same body declared in mm moves exactly as in m (1e-9).
#[test]
fn a_steeper_kernel_brings_the_fibers_closer_to_the_fem() {
    let dir = tempfile::tempdir().unwrap();
    let sphere = mesh("icosphere-3.obj");
    let error = |fibers: &str, p: f64| {
        let mut s = scene(dir.path(), &sphere, "above = 0.8", fibers, "");
        s.model.material.set_kernel_exponent(p).unwrap();
        shape_error(s, "sphere-gravity.txt").0
    };
    let (paper1, paper3) = (error("paper", 1.0), error("paper", 3.0));
    let (proj1, proj3) = (error("projected", 1.0), error("projected", 3.0));
    eprintln!(
        "kernel 1/d vs 1/d^3: paper fibers {paper1:.3} -> {paper3:.3}, projected {proj1:.3} -> {proj3:.3}"
    );
    assert!(paper3 < 0.5 * paper1, "paper fibers: {paper1} -> {paper3}");
    assert!(proj3 < 0.8 * proj1, "projected fibers: {proj1} -> {proj3}");

    // The same body in mm: coordinates x 1000, `unit = "mm"`, the clamp in mm.
    let text = std::fs::read_to_string(mesh("icosphere-2.obj")).unwrap();
    let scaled: String = text
        .lines()
        .map(|l| match l.strip_prefix("v ") {
            Some(rest) => {
                let v: Vec<f64> =
                    rest.split_whitespace().map(|x| x.parse::<f64>().unwrap() * 1000.0).collect();
                format!("v {} {} {}\n", v[0], v[1], v[2])
            }
            None => format!("{l}\n"),
        })
        .collect();
    let mm_mesh = dir.path().join("sphere-mm.obj");
    std::fs::write(&mm_mesh, scaled).unwrap();
    let run = |mesh: &Path, unit: &str, above: f64| {
        let text = format!(
            "[mesh]\npath = \"{}\"\nunit = \"{unit}\"\n[ffm]\nfiber_modulus = 5e4\nsurface_tension = 30.0\nkernel_exponent = 3.0\n\
             [fluid]\ndensity = 1000.0\n[gravity]\nacceleration = [0.0, -9.81, 0.0]\n\
             [[fix]]\naxis = \"y\"\nabove = {above}\n[solver]\nmode = \"refresh\"\n",
            mesh.display()
        );
        let path = dir.path().join(format!("kernel-{unit}.toml"));
        std::fs::write(&path, text).unwrap();
        let mut sim = Simulation::new(Scene::load(&path).unwrap()).unwrap();
        sim.run(&RunOptions::default()).unwrap();
        sim.positions()
            .iter()
            .zip(sim.rest_positions())
            .map(|(p, r)| [p[0] - r[0], p[1] - r[1], p[2] - r[2]])
            .collect::<Vec<V3>>()
    };
    let (m, mm) = (run(&mesh("icosphere-2.obj"), "m", 0.8), run(&mm_mesh, "mm", 800.0));
    let largest = m.iter().flatten().fold(0.0f64, |a, v| a.max(v.abs()));
    assert!(largest > 1e-3, "the body must move: {largest}");
    for (a, b) in m.iter().zip(&mm) {
        assert!((0..3).all(|c| (a[c] - b[c]).abs() <= 1e-9 * largest), "{a:?} in m, {b:?} in mm");
    }
}

/// Writes the icosphere of `level` subdivisions as an OBJ file.
fn icosphere_obj(dir: &Path, level: u32) -> PathBuf {
    let m = fibfluid::geometry::icosphere(level, 1.0);
    let mut text = String::new();
    for p in m.positions() {
        text += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    for t in m.triangles() {
        text += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    let path = dir.join(format!("icosphere-{level}.obj"));
    std::fs::write(&path, text).unwrap();
    path
}

/// The table and times of docs/method.md, "Fiber models" (slow: `--ignored --nocapture`).
#[test]
#[ignore]
fn measure_fiber_models_against_the_fem() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        ("sphere (icosphere-3, N = 642)", "icosphere-3.obj", "above = 0.8", "sphere-gravity.txt"),
        ("liver2 (N = 1170)", "liver2.obj", "top = 0.08", "liver2-hanging.txt"),
        ("spot (N = 2930)", "spot.obj", "bottom = 0.08", "spot-standing.txt"),
    ];
    println!("| body | paper | projected | paper s | projected s |");
    println!("|---|---|---|---|---|");
    for (name, file, fix, g) in cases {
        let (ep, sp) = shape_error(scene(dir.path(), &mesh(file), fix, "paper", ""), g);
        let (eq, sq) = shape_error(scene(dir.path(), &mesh(file), fix, "projected", ""), g);
        println!("| {name} | {ep:.3} | {eq:.3} | {sp:.2} | {sq:.2} |");
    }
    println!("| p | paper: sphere / liver2 / spot | projected: sphere / liver2 / spot |");
    println!("|---|---|---|");
    for p in [1.0, 2.0, 2.5, 3.0, 4.0] {
        let errors = |fibers: &str| -> Vec<String> {
            cases
                .iter()
                .map(|(_, file, fix, g)| {
                    let mut s = scene(dir.path(), &mesh(file), fix, fibers, "");
                    s.model.material.set_kernel_exponent(p).unwrap();
                    format!("{:.3}", shape_error(s, g).0)
                })
                .collect()
        };
        println!("| {p} | {} | {} |", errors("paper").join(" / "), errors("projected").join(" / "));
    }
    for fibers in ["paper", "projected"] {
        let text = format!(
            "[mesh]\npath = \"{}\"\nunit = \"cm\"\n[tissue]\nyoung = 5000.0\npoisson = 0.45\ndensity = 1000.0\n\
             [ffm]\nfibers = \"{fibers}\"\n[gravity]\nacceleration = [0.0, -9.81, 0.0]\n\
             [[fix]]\naxis = \"y\"\nabove = 0.8\n[solver]\nmode = \"paper\"\n",
            mesh("icosphere-3.obj").display()
        );
        let path = dir.path().join(format!("tissue-{fibers}.toml"));
        std::fs::write(&path, text).unwrap();
        let sim = Simulation::new(Scene::load(&path).unwrap()).unwrap();
        let c = sim.calibration().expect("a tissue-only scene calibrates");
        println!(
            "calibration, sphere-tissue, fibers = {fibers}: error_vs_fem {:.4}, scale {:.3}, {:.2} s",
            c.error_vs_fem, c.scale, c.seconds
        );
    }
    for level in [3, 4] {
        let obj = icosphere_obj(dir.path(), level);
        for fibers in ["paper", "projected"] {
            let mut sim = Simulation::new(scene(dir.path(), &obj, "above = 0.8", fibers, "")).unwrap();
            let t = Instant::now();
            sim.run(&RunOptions::default()).unwrap();
            let solve = t.elapsed().as_secs_f64();
            let stage =
                |s| sim.log().records().iter().filter(|r| r.name == s).map(|r| r.seconds).sum::<f64>();
            println!(
                "icosphere-{level} N = {}: {fibers}: assembly {:.3} s, factorization {:.3} s, run {solve:.3} s",
                sim.positions().len(),
                stage(names::ASSEMBLY),
                stage(names::FACTORIZATION),
            );
        }
    }
}
