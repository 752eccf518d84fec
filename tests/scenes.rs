//! Scenes end to end through the library: the paper's sphere and rectangle, the round
//! trip's 1/n behaviour (REFERENCE §4), and the plan (only the stages a scene needs).

use fibfluid::linalg::backend_names;
use fibfluid::stages::names;
use fibfluid::{Direction, Mode, Report, RunOptions, Scene, Simulation, Stepping, roundtrip};

fn sphere() -> Scene {
    Scene::load("fixtures/scenes/sphere.toml").expect("bundled sphere scene")
}

fn run(scene: Scene) -> Simulation {
    let mut sim = Simulation::new(scene).expect("setup");
    sim.run(&RunOptions::default()).expect("run");
    sim
}

/// Relative agreement asked of different backends on the same scene (issue: 1e-8).
const BACKEND_AGREEMENT: f64 = 1e-8;

#[test]
fn sphere_scene_agrees_across_backends_and_behaves_physically() {
    let mut results = Vec::new();
    for backend in backend_names() {
        let mut scene = sphere();
        scene.solver.backend = backend.into();
        let sim = run(scene);
        results.push((backend, sim.positions().to_vec(), sim.pressure()));
        let rest = sim.rest_positions();
        let n = rest.len() as f64;
        let centroid_dy: f64 = sim.positions().iter().zip(rest).map(|(p, r)| p[1] - r[1]).sum::<f64>() / n;
        assert!(centroid_dy < -1e-3, "{backend}: gravity must pull the centroid down, moved {centroid_dy}");
        let report = Report::of(&sim, &[], vec![]);
        // The paper's penalty keeps the row's off-diagonal entries, so a "fixed" vertex moves
        // by about (K row sum * |u| + load) / big: the penalty's own bound, ~1e-5 here.
        let k = sim.system().matrix.block(0);
        let diag_max = (0..k.nrows()).map(|i| k[(i, i)]).filter(|d| *d < 1e8).fold(0.0, f64::max);
        let penalty_bound = 2.0 * diag_max * report.max_displacement / 1e9;
        assert!(
            report.fixed_max_displacement < penalty_bound,
            "{backend}: cap moved {}",
            report.fixed_max_displacement
        );
        assert!(
            report.volume_initial > 3.9 && report.volume_initial < 4.19,
            "icosphere-2 volume below 4/3 pi"
        );
        assert!(report.volume_final.is_finite());
    }
    let (_, reference, p_ref) = &results[0];
    let scale = reference.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    for (backend, pos, p) in &results[1..] {
        let diff = pos
            .iter()
            .flatten()
            .zip(reference.iter().flatten())
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(diff <= BACKEND_AGREEMENT * scale, "{backend} differs from {} by {diff:e}", results[0].0);
        assert!((p - p_ref).abs() <= BACKEND_AGREEMENT * p_ref.abs(), "{backend}: pressure {p} vs {p_ref}");
    }
}

#[test]
fn eliminated_constraints_hold_the_cap_exactly() {
    let mut scene = sphere();
    scene.solver.constraints = fibfluid::assembly::ConstraintMethod::Eliminate;
    let sim = run(scene);
    let report = Report::of(&sim, &[], vec![]);
    assert_eq!(report.fixed_max_displacement, 0.0);
    assert!(report.max_displacement > 0.1);
}

#[test]
fn rectangle_scene_reproduces_the_papers_worked_example() {
    let sim = run(Scene::load("fixtures/scenes/rectangle.toml").unwrap());
    let u: Vec<[f64; 3]> = sim
        .positions()
        .iter()
        .zip(sim.rest_positions())
        .map(|(p, r)| [p[0] - r[0], p[1] - r[1], 0.0])
        .collect();
    // Paper: u_x = -4 (right corners), u_y = 16/3 (upper corners), P = 32; the penalty
    // leaves O(F / 1e9) at the fixed degrees of freedom.
    let tol = 1e-5;
    assert!((u[0][0] + 4.0).abs() < tol && (u[1][0] + 4.0).abs() < tol);
    assert!((u[0][1] - 16.0 / 3.0).abs() < tol && (u[3][1] - 16.0 / 3.0).abs() < tol);
    assert!((sim.pressure() - 32.0).abs() < 1e-4);
}

#[test]
fn roundtrip_error_falls_as_one_over_n() {
    let errors: Vec<f64> = [1, 10, 100]
        .iter()
        .map(|&n| {
            let mut s = sphere();
            s.steps = n;
            roundtrip(s, &RunOptions::default()).unwrap().roundtrip_error
        })
        .collect();
    for w in errors.windows(2) {
        let ratio = w[0] / w[1];
        assert!((5.0..=20.0).contains(&ratio), "errors {errors:?}: ratio {ratio} not ~10 (first order)");
    }
}

#[test]
fn refresh_mode_keeps_the_volume_and_paper_mode_drifts() {
    let drift = |mode| {
        let mut s = sphere();
        s.solver.mode = mode;
        let sim = run(s);
        (sim.volume() / sim.volume_initial() - 1.0).abs()
    };
    let (paper, refresh) = (drift(Mode::Paper), drift(Mode::Refresh));
    // REFERENCE §5: the frozen border drifts by several percent over the 10-step ramp.
    assert!(paper > 1e-2, "paper drift {paper}");
    assert!(refresh < 1e-4, "refresh drift {refresh}");
}

#[test]
fn heun_beats_euler_by_twenty_at_ten_steps() {
    let err = |stepping| {
        let mut s = sphere();
        s.solver.stepping = stepping;
        roundtrip(s, &RunOptions::default()).unwrap().roundtrip_error
    };
    let (euler, heun) = (err(Stepping::Euler), err(Stepping::Heun));
    assert!(heun * 20.0 <= euler, "heun {heun:e} vs euler {euler:e}");
}

#[test]
fn unloading_with_the_paper_stepping_returns_near_the_start() {
    // A sanity check of Direction::Unload independent of roundtrip(): one step each way
    // with a point force alone is linear in paper mode and returns exactly.
    let mut s = Scene::load("fixtures/scenes/rectangle.toml").unwrap();
    s.steps = 1;
    let mut sim = Simulation::new(s).unwrap();
    sim.step(0, 1, Direction::Load).unwrap();
    sim.step(0, 1, Direction::Unload).unwrap();
    let back = sim
        .positions()
        .iter()
        .zip(sim.rest_positions())
        .map(|(p, r)| (p[0] - r[0]).hypot(p[1] - r[1]))
        .fold(0.0, f64::max);
    // Paper mode keeps K and S: load and unload cancel up to rounding.
    assert!(back < 1e-9, "{back}");
}

#[test]
fn the_plan_runs_only_the_stages_a_scene_needs() {
    // The convex sphere: no visibility tests; isotropic with identical constraints: one block.
    let sim = run(sphere());
    let log = sim.log();
    assert!(log.ran(names::CONVEXITY));
    assert!(!log.ran(names::VISIBILITY) && log.skipped.iter().any(|s| s.name == names::VISIBILITY));
    assert_eq!(sim.system().stats.blocks, 1);
    assert!(log.ran(names::DEPTHS));
    // The bunny pulled by a force: no gravity, so no depth is ever computed; concave, so
    // the visibility tests run.
    let mut bunny = Scene::load("fixtures/scenes/bunny-pull.toml").unwrap();
    bunny.steps = 1;
    let sim = run(bunny);
    let log = sim.log();
    assert!(!log.ran(names::DEPTHS) && !log.ran(names::HYDROSTATIC));
    assert!(log.skipped.iter().any(|s| s.name == names::DEPTHS && s.reason.contains("gravity")));
    assert!(log.ran(names::VISIBILITY));
    assert!(sim.fibers().kept() < sim.fibers().total());
    // Anisotropic material: three blocks.
    let mut aniso = sphere();
    aniso.material.young = [3000.0, 4000.0, 5000.0];
    aniso.steps = 1;
    let sim = run(aniso);
    assert_eq!(sim.system().stats.blocks, 3);
    // Paper mode factors once; nonlinear mode once per step (plus the first).
    let mut nl = sphere();
    nl.solver.mode = Mode::Nonlinear;
    nl.steps = 4;
    let sim = run(nl);
    assert_eq!(sim.factorizations(), 5);
    assert!(sim.log().ran(names::REASSEMBLY));
}

#[test]
fn the_report_lists_stages_and_skips() {
    let sim = run(sphere());
    let report = Report::of(&sim, &[], vec![]);
    let json = serde_json::to_value(&report).unwrap();
    for key in [
        "backend",
        "mode",
        "vertices",
        "faces",
        "fibers_kept",
        "steps",
        "volume_initial",
        "volume_final",
        "max_displacement",
        "mean_displacement",
        "pressure",
        "residual_max",
        "stages",
        "seconds_total",
    ] {
        assert!(json.get(key).is_some(), "report lacks {key}");
    }
    assert!(report.residual_max < 1e-10);
    assert_eq!(report.fibers_kept, 162 * 161 / 2);
    assert!(report.stages.iter().all(|s| s.seconds >= 0.0 && s.count >= 1));
}

/// `ineffective` names each setting that cannot act, and each finding is true: the run with
/// the setting equals (bit for bit) the run without it. The bundled scenes have none, and a
/// setting that does act (stiffening in nonlinear mode) is not reported and changes the run.
#[test]
fn settings_that_cannot_act_are_found_and_really_do_nothing() {
    use fibfluid::assembly::{ConstraintMethod, StiffnessLaw};
    use fibfluid::{Ineffective, ineffective};
    for entry in std::fs::read_dir("fixtures/scenes").unwrap() {
        let path = entry.unwrap().path();
        let scene = Scene::load(&path).unwrap();
        assert_eq!(ineffective(&scene), vec![], "{}", path.display());
    }
    let same = |a: Scene, b: Scene, what: &str| {
        let (pa, pb) = (run(a).positions().to_vec(), run(b).positions().to_vec());
        assert_eq!(pa, pb, "{what}: the setting changed the run");
    };
    // sphere.toml: gravity [0, -10, 0], density 1000, a force on vertex 3, paper mode.
    let mut s = sphere();
    s.material.density = 0.0;
    assert_eq!(ineffective(&s), vec![Ineffective::GravityWithoutDensity { acceleration: [0.0, -10.0, 0.0] }]);
    let mut without = s.clone();
    without.gravity = [0.0; 3];
    same(s, without, "gravity without density");

    let mut s = sphere();
    s.gravity = [0.0; 3];
    assert_eq!(ineffective(&s), vec![Ineffective::DensityWithoutGravity { density: 1000.0 }]);
    let mut without = s.clone();
    without.material.density = 0.0;
    same(s, without, "density without gravity");

    let mut s = sphere();
    s.material.law = StiffnessLaw::Quadratic { c: 50.0 };
    s.solver.mode = Mode::Refresh;
    assert_eq!(ineffective(&s), vec![Ineffective::StiffeningOutsideNonlinear { mode: Mode::Refresh }]);
    let mut linear = s.clone();
    linear.material.law = StiffnessLaw::Linear;
    same(s.clone(), linear.clone(), "stiffening in refresh mode");
    // In nonlinear mode it acts: not reported, and the run differs.
    s.solver.mode = Mode::Nonlinear;
    linear.solver.mode = Mode::Nonlinear;
    assert_eq!(ineffective(&s), vec![]);
    assert_ne!(run(s).positions(), run(linear).positions(), "stiffening must act in nonlinear mode");

    let mut s = sphere();
    s.forces[0].value = [0.0; 3];
    assert_eq!(ineffective(&s), vec![Ineffective::ZeroForce { index: 1, vertex: 3 }]);
    let mut without = s.clone();
    without.forces.clear();
    same(s, without, "a zero force");

    // A force on a vertex of the fixed cap (held exactly by elimination).
    let mut s = sphere();
    s.solver.constraints = ConstraintMethod::Eliminate;
    let held = (0..s.n_vertices()).find(|&v| (0..3).all(|c| s.constraints.get(v, c).is_some())).unwrap();
    s.forces[0].vertex = held;
    assert_eq!(ineffective(&s), vec![Ineffective::ForceOnFixedVertex { index: 1, vertex: held }]);
    let mut without = s.clone();
    without.forces.clear();
    same(s, without, "a force on a fixed vertex");
}
