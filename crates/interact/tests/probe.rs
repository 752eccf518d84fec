//! Probe frames against independent full solves.
//!
//! The reference is the engine's `Simulation` on the same scene in paper mode with
//! `steps = 1` (its own assembly, structured Cholesky factorization and refined solve),
//! with the probe's forces added as scene point forces: a probe frame must be that solve,
//! not an approximation of it. The scene is the paper's sphere (fixtures/scenes/sphere.toml,
//! built here in code from its mesh: icosphere level 2, N = 162, gravity, a point force and
//! the top cap fixed), once with its penalty constraints as published and once with
//! elimination.

use fibfluid_assembly::{Material, Selector};
use fibfluid_geometry::{Vec3, load_mesh};
use fibfluid_interact::{
    Compliance, ComplianceOptions, FfmBody, Hold, InteractError, Interactive, Precompute, ProbeOptions,
    Storage, build_body, linearized,
};
use fibfluid_linalg::{Backend, Choice};
use fibfluid_sim::ConstraintKind as ConstraintMethod;
use fibfluid_sim::{ForceTiming, Mode, Model, PointForce, RunOptions, Shape, Simulation};

/// A force on the body matches the full solve to this, relative to the largest displacement
/// (the bound for a pushed force).
const PUSH_TOLERANCE: f64 = 1e-9;
/// A grab's reaction, applied as a force in a full solve, gives the same surface to this.
const GRAB_TOLERANCE: f64 = 1e-7;
/// f32 storage: each compliance entry is rounded once (relative error <= 2^-24 = 6e-8); the
/// field sums a few columns and the capacitance solve of a grab amplifies the rounding by
/// its (small) condition number: 8 f32 epsilons (9.5e-7) of the largest displacement
/// (measured on this case: 5.8e-9).
const F32_TOLERANCE: f64 = 8.0 * f32::EPSILON as f64;

#[path = "probe/custom_tool.rs"]
mod custom_tool;
#[path = "probe/guards.rs"]
mod guards;
#[path = "probe/tools.rs"]
mod tools;
#[path = "probe/two_rate.rs"]
mod two_rate;

/// fixtures/scenes/sphere.toml, in code.
fn sphere(method: ConstraintMethod) -> Model {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meshes/icosphere-2.obj");
    let file = load_mesh(path).expect("the sphere mesh loads");
    let material = Material::new([3000.0; 3], 3000.0, 1000.0).unwrap();
    let mut scene = Model::from_mesh("sphere", file, material);
    let rest = scene.rest_positions();
    scene.constraints.fix_selected(&Selector::Above { axis: 1, value: 0.8 }, &rest, [true; 3]).unwrap();
    scene.load.gravity = [0.0, -10.0, 0.0];
    let vertex = mesh_index(&scene, 3);
    scene.load.forces.push(PointForce { vertex, value: [-300.0; 3], timing: ForceTiming::Last });
    scene.load.steps = 10;
    scene.solver.backend = Backend::Structured;
    scene.solver.mode = Mode::Paper;
    scene.solver.constraints = method;
    scene
}

fn methods() -> [ConstraintMethod; 2] {
    [ConstraintMethod::Penalty, ConstraintMethod::Eliminate]
}

/// Every constraint method with every precompute: the exactness tests run on each pair.
fn cases() -> Vec<(ConstraintMethod, Precompute)> {
    methods().into_iter().flat_map(|m| Precompute::ALL.iter().map(move |&p| (m, p))).collect()
}

/// Mesh index of a vertex of the mesh file.
fn mesh_index(scene: &Model, file_vertex: usize) -> usize {
    match &scene.shape {
        Shape::Surface(f) => f.from_file_index(file_vertex).expect("a used vertex"),
        Shape::Polygon(_) => file_vertex,
    }
}

/// Positions of an independent full solve: the scene's loads plus `extra` point forces, in
/// paper mode with one step.
fn full_solve(scene: &Model, extra: &[(usize, Vec3)]) -> Vec<Vec3> {
    let mut s = linearized(scene);
    for &(vertex, value) in extra {
        s.load.forces.push(PointForce { vertex, value, timing: ForceTiming::Last });
    }
    let mut sim = Simulation::new(s).expect("the sphere assembles");
    sim.run(&RunOptions::default()).expect("the full solve succeeds");
    sim.positions().to_vec()
}

/// Largest vertex distance between two surfaces over the largest displacement of `b`.
fn relative_difference(a: &[Vec3], b: &[Vec3], rest: &[Vec3]) -> f64 {
    let dist =
        |p: Vec3, q: Vec3| ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt();
    let diff = a.iter().zip(b).map(|(p, q)| dist(*p, *q)).fold(0.0, f64::max);
    let scale = b.iter().zip(rest).map(|(p, q)| dist(*p, *q)).fold(0.0, f64::max);
    diff / scale
}

fn body(scene: &Model, storage: Storage) -> FfmBody {
    body_with(scene, storage, Precompute::Full)
}

fn body_with(scene: &Model, storage: Storage, precompute: Precompute) -> FfmBody {
    let opts = ProbeOptions { storage, precompute, max_memory_bytes: None, ..Default::default() };
    let b = build_body(scene, &opts).expect("the probe body builds").body;
    assert_eq!(b.compliance().precompute(), precompute);
    b
}

#[test]
fn a_pushed_force_is_the_full_solve_with_that_force() {
    for (method, precompute) in cases() {
        let scene = sphere(method);
        let mut b = body_with(&scene, Storage::F64, precompute);
        let v = mesh_index(&scene, 36);
        let w = mesh_index(&scene, 100);
        let pushes = [(v, [40.0, 150.0, -30.0]), (w, [-60.0, 20.0, 90.0])];
        for &(vertex, f) in &pushes {
            b.push(vertex, f).unwrap();
        }
        let reactions = b.update().unwrap().to_vec();
        assert_eq!(reactions.len(), 2, "pushed forces are reported as the forces on the body");
        let reference = full_solve(&scene, &pushes);
        let d = relative_difference(b.positions(), &reference, b.rest_positions());
        println!("{method:?}, {precompute}: two pushes vs the full solve {d:e}");
        assert!(d <= PUSH_TOLERANCE, "{method:?}, {precompute}: probe vs full solve {d:e}");
        // Without any hold the frame is the base state, which is the full solve of the
        // scene's own loads.
        b.release_all();
        b.update().unwrap();
        let d = relative_difference(b.positions(), &full_solve(&scene, &[]), b.rest_positions());
        assert!(d <= PUSH_TOLERANCE, "{method:?}, {precompute}: base state vs full solve {d:e}");
    }
}

#[test]
fn a_grabbed_vertex_stays_put_and_its_reaction_reproduces_the_surface() {
    for (method, precompute) in cases() {
        let scene = sphere(method);
        let mut b = body_with(&scene, Storage::F64, precompute);
        let v = mesh_index(&scene, 36);
        let d = [0.1, -0.9, 0.05];
        b.grab(v, d).unwrap();
        let r = b.update().unwrap().to_vec();
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].0, v);
        let p = b.positions()[v];
        let rest = b.rest_positions()[v];
        for c in 0..3 {
            assert!(
                (p[c] - (rest[c] + d[c])).abs() <= 1e-12,
                "{method:?}, {precompute}: grabbed vertex at {p:?}"
            );
        }
        let reference = full_solve(&scene, &r);
        let diff = relative_difference(b.positions(), &reference, b.rest_positions());
        println!("{method:?}, {precompute}: one grab vs the full solve with its reaction {diff:e}");
        assert!(
            diff <= GRAB_TOLERANCE,
            "{method:?}, {precompute}: grab vs full solve with its reaction {diff:e}"
        );
    }
}

#[test]
fn three_grabbed_vertices_and_a_push_reproduce_the_full_solve() {
    for (method, precompute) in cases() {
        let scene = sphere(method);
        let mut b = body_with(&scene, Storage::F64, precompute);
        let grabs = [(36, [0.05, -0.95, 0.0]), (122, [0.0, -0.8, 0.1]), (9, [-0.02, -0.3, 0.03])];
        let push = (mesh_index(&scene, 100), [10.0, -50.0, 25.0]);
        for &(fv, d) in &grabs {
            b.grab(mesh_index(&scene, fv), d).unwrap();
        }
        b.push(push.0, push.1).unwrap();
        let forces = b.update().unwrap().to_vec();
        assert_eq!(forces.len(), 4);
        for &(fv, d) in &grabs {
            let v = mesh_index(&scene, fv);
            let (p, r) = (b.positions()[v], b.rest_positions()[v]);
            for c in 0..3 {
                assert!(
                    (p[c] - r[c] - d[c]).abs() <= 1e-12,
                    "{method:?}, {precompute}: vertex {fv} at {p:?}"
                );
            }
        }
        let reference = full_solve(&scene, &forces);
        let diff = relative_difference(b.positions(), &reference, b.rest_positions());
        println!("{method:?}, {precompute}: three grabs and a push vs the full solve {diff:e}");
        assert!(diff <= GRAB_TOLERANCE, "{method:?}, {precompute}: {diff:e}");
        // The reaction-only query gives the same reactions without touching the field.
        let field = b.field().to_vec();
        let quick = b.update_reactions().unwrap().to_vec();
        assert_eq!(quick, forces);
        assert!(!b.field_is_current());
        assert_eq!(b.field(), &field[..]);
    }
}

#[test]
fn f32_storage_stays_within_its_tolerance() {
    let scene = sphere(ConstraintMethod::Eliminate);
    let v = mesh_index(&scene, 36);
    let w = mesh_index(&scene, 122);
    let mut b64 = body(&scene, Storage::F64);
    let mut b32 = body(&scene, Storage::F32);
    assert_eq!(b32.compliance().storage(), Storage::F32);
    assert!(b32.memory_bytes() < b64.memory_bytes());
    for b in [&mut b64, &mut b32] {
        b.grab(v, [0.1, -0.9, 0.05]).unwrap();
        b.push(w, [20.0, 30.0, -10.0]).unwrap();
        b.update().unwrap();
    }
    let diff = relative_difference(b32.positions(), b64.positions(), b64.rest_positions());
    assert!(diff <= F32_TOLERANCE, "f32 vs f64 storage: {diff:e}");
    assert!(diff > 0.0, "f32 storage must differ from f64 somewhere (else it is not f32)");
    // The grabbed vertex is exactly where the tool holds it even in f32 (the capacitance
    // and the field use the same stored entries).
    let (p, r) = (b32.positions()[v], b32.rest_positions()[v]);
    assert!((p[0] - r[0] - 0.1).abs() <= 1e-12 && (p[1] - r[1] + 0.9).abs() <= 1e-12);
    let (r32, r64) = (b32.reactions()[0].1, b64.reactions()[0].1);
    let rel = (0..3).map(|c| (r32[c] - r64[c]).abs()).fold(0.0, f64::max)
        / (0..3).map(|c| r64[c].abs()).fold(0.0, f64::max);
    assert!(rel <= F32_TOLERANCE, "f32 reaction {r32:?} vs {r64:?}");
}

#[test]
fn bad_requests_are_typed_errors_and_change_nothing() {
    let scene = sphere(ConstraintMethod::Eliminate);
    let mut b: Box<dyn Interactive> = Box::new(body(&scene, Storage::F64));
    let n = b.n_vertices();
    let fixed = (0..n).find(|&v| b.is_fixed(v)).expect("the top cap is fixed");
    let free = mesh_index(&scene, 36);
    assert_eq!(b.grab(n, [0.0; 3]), Err(InteractError::UnknownVertex { vertex: n, vertices: n }));
    assert!(matches!(
        b.grab(fixed, [0.0, 0.1, 0.0]),
        Err(InteractError::FixedVertex { action: "grabbed", .. })
    ));
    assert!(matches!(b.push(fixed, [1.0; 3]), Err(InteractError::FixedVertex { action: "pushed", .. })));
    assert!(matches!(b.grab(free, [0.0, f64::NAN, 0.0]), Err(InteractError::NonFinite { .. })));
    assert!(matches!(b.push(free, [f64::INFINITY, 0.0, 0.0]), Err(InteractError::NonFinite { .. })));
    assert_eq!(b.release(n + 5), Err(InteractError::UnknownVertex { vertex: n + 5, vertices: n }));
    assert!(b.holds().is_empty(), "refused requests leave no hold");
    // The last call for a vertex wins; releasing an unheld vertex is no error.
    b.grab(free, [0.0, -0.5, 0.0]).unwrap();
    b.push(free, [0.0, 5.0, 0.0]).unwrap();
    assert_eq!(b.holds().to_vec(), vec![(free, Hold::Push { force: [0.0, 5.0, 0.0] })]);
    b.release(free).unwrap();
    b.release(free).unwrap();
    assert!(b.holds().is_empty());
}

#[test]
fn grabbing_every_free_vertex_is_singular_and_keeps_the_last_frame() {
    // With elimination S vanishes on the fixed cap, so holding every free vertex leaves the
    // volume row nothing to move: the capacitance matrix is singular (its null vector is S).
    for precompute in Precompute::ALL.iter().copied() {
        grabbing_every_free_vertex_is_singular_with(precompute);
    }
}

fn grabbing_every_free_vertex_is_singular_with(precompute: Precompute) {
    let scene = sphere(ConstraintMethod::Eliminate);
    let mut b = body_with(&scene, Storage::F64, precompute);
    let v = mesh_index(&scene, 36);
    b.grab(v, [0.0, -0.9, 0.0]).unwrap();
    b.update().unwrap();
    let before = b.positions().to_vec();
    let frame = b.frame();
    for u in 0..b.n_vertices() {
        if !b.is_fixed(u) {
            b.grab(u, [0.0; 3]).unwrap();
        }
    }
    assert!(matches!(b.update(), Err(InteractError::Singular { .. })));
    assert_eq!(b.positions(), &before[..], "a failed update keeps the last frame");
    assert_eq!(b.frame(), frame);
    // Releasing one vertex makes it solvable again.
    b.release(v).unwrap();
    b.update().unwrap();
}

#[test]
fn memory_is_refused_before_allocating_with_the_bytes() {
    let scene = sphere(ConstraintMethod::Eliminate);
    let full =
        ProbeOptions { precompute: Precompute::Full, max_memory_bytes: Some(100_000), ..Default::default() };
    let err = build_body(&scene, &full).unwrap_err().to_string();
    // N = 162, one shared block: the compliance (8 N^2 = 209,952 bytes, plus one working
    // column block) and the system with its factor (2 x 209,952) exceed 100 kB.
    assert!(err.contains("bytes") && err.contains("100000"), "{err}");
    let sim = Simulation::new(linearized(&scene)).unwrap();
    let opts = ComplianceOptions { storage: Storage::F32, max_memory_bytes: Some(1000) };
    match Compliance::from_system(sim.system(), &opts) {
        Err(InteractError::OutOfMemory { bytes, available: 1000 }) => {
            let n = 162u64;
            assert_eq!(bytes, Compliance::estimate(sim.system(), Storage::F32).peak);
            assert!(bytes >= n * n * (4 + 8), "f32 storage plus the f64 working block: {bytes}");
        }
        other => panic!("expected OutOfMemory, got {other:?}"),
    }
}

#[test]
fn storage_names_round_trip() {
    for &s in Storage::ALL {
        assert_eq!(s.name().parse::<Storage>(), Ok(s));
        assert_eq!(s.to_string(), s.name());
    }
    assert!("f16".parse::<Storage>().is_err());
    for &p in Precompute::ALL {
        assert_eq!(p.name().parse::<Precompute>(), Ok(p));
    }
    assert_eq!(Precompute::default(), Precompute::Lazy);
    assert!("eager".parse::<Precompute>().is_err());
}

/// The lazy response keeps the base solve's factorization (no second one) and computes the
/// columns of a vertex once, when it is first touched: a drag of the same vertices adds
/// none, and a frame equals the full precompute's frame.
#[test]
fn lazy_columns_are_computed_once_per_touched_vertex() {
    let scene = sphere(ConstraintMethod::Eliminate);
    let mut lazy = body_with(&scene, Storage::F64, Precompute::Lazy);
    let mut full = body_with(&scene, Storage::F64, Precompute::Full);
    let (v, w) = (mesh_index(&scene, 36), mesh_index(&scene, 122));
    let mem0 = lazy.memory_bytes();
    for t in 0..5 {
        let d = [0.01 * t as f64, -0.5, 0.0];
        for b in [&mut lazy, &mut full] {
            b.grab(v, d).unwrap();
            b.push(w, [0.0, 10.0, 0.0]).unwrap();
            b.update().unwrap();
        }
        let diff = relative_difference(lazy.positions(), full.positions(), lazy.rest_positions());
        assert!(diff <= 1e-10, "frame {t}: lazy vs full {diff:e}");
    }
    // Two vertices touched: two columns of N values (one shared block) and nothing else.
    let n = lazy.n_vertices();
    assert_eq!(lazy.memory_bytes() - mem0, 2 * n * 8 + 9 * 8, "two cached columns and G (3 x 3)");
    // A clone carries the cache: touching the same vertices computes nothing new.
    let mut c = lazy.clone();
    let before = c.memory_bytes();
    c.release_all();
    c.grab(v, [0.0, -0.4, 0.0]).unwrap();
    c.update().unwrap();
    assert_eq!(c.memory_bytes(), before);
}

/// Nearest-rank percentiles, by hand: of 1..=100 the 50th and 99th values; one sample is
/// every percentile; no sample gives zeros.
#[test]
fn latency_percentiles_by_nearest_rank() {
    use fibfluid_interact::Latency;
    let s: Vec<f64> = (1..=100).map(f64::from).collect();
    assert_eq!(Latency::of(&s), Latency { p50: 50.0, p99: 99.0, max: 100.0 });
    assert_eq!(Latency::of(&[3.0]), Latency { p50: 3.0, p99: 3.0, max: 3.0 });
    assert_eq!(Latency::of(&[]), Latency::default());
}
