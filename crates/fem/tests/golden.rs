//! Against an independent FEM: quadratic tetrahedra (scikit-fem on a TetGen mesh of the same
//! surface, same E, nu, rho, gravity and clamps; `tools/reference.py`, see
//! `tests/golden/README.md`). The relative L2 error of the surface displacement, no scaling.

use std::path::PathBuf;

use crate::common::*;
use fibfluid_fem::hyper::{Grasp, HyperBody, RigidPlate};
use fibfluid_fem::{DEFAULT_RESOLUTION, FemBody, FemOptions, Loads, Tissue, TissueModel};
use fibfluid_geometry::load_mesh;

struct Case {
    mesh: &'static str,
    golden: &'static str,
    /// Which vertices are fixed, from the rest positions.
    fixed: fn(&[V3]) -> Vec<[bool; 3]>,
}

const SPHERE: Case = Case {
    mesh: "icosphere-3.obj",
    golden: "sphere-gravity.txt",
    fixed: |pos| pos.iter().map(|p| [p[1] > 0.8; 3]).collect(),
};

const LIVER: Case = Case {
    mesh: "liver2.obj",
    golden: "liver2-hanging.txt",
    fixed: |pos| {
        let top = pos.iter().map(|p| p[1]).fold(f64::MIN, f64::max);
        pos.iter().map(|p| [p[1] >= top - 0.08; 3]).collect()
    },
};

const SPOT: Case = Case {
    mesh: "spot.obj",
    golden: "spot-standing.txt",
    fixed: |pos| {
        let bottom = pos.iter().map(|p| p[1]).fold(f64::MAX, f64::min);
        pos.iter().map(|p| [p[1] <= bottom + 0.08; 3]).collect()
    },
};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A golden file's surface displacements, one per file vertex (`GOLDEN_DIR` or
/// `tests/golden`).
fn golden_field(name: &str) -> Vec<V3> {
    golden_text(name)
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            [v[0], v[1], v[2]]
        })
        .collect()
}

/// A golden file's text, from `GOLDEN_DIR` when set, else `tests/golden`.
fn golden_text(name: &str) -> String {
    let dir = std::env::var("GOLDEN_DIR").map(PathBuf::from).unwrap_or_else(|_| root().join("tests/golden"));
    std::fs::read_to_string(dir.join(name)).unwrap()
}

/// The plate forces a golden's header records (N, on the body along each plate's normal,
/// in the plates' order): its first line ends `...; plate forces on the body along their
/// normals F1 F2 N`.
fn golden_plate_forces(name: &str) -> Vec<f64> {
    let text = golden_text(name);
    let header = text.lines().next().unwrap();
    let (_, tail) = header.split_once("plate forces on the body along their normals").unwrap();
    tail.split_whitespace().filter_map(|x| x.parse().ok()).collect()
}

/// Relative L2 error of our surface displacement at `resolution` against the golden file.
fn error(case: &Case, resolution: usize) -> f64 {
    let file = load_mesh(root().join("../../fixtures/meshes").join(case.mesh)).unwrap();
    assert_eq!(file.file_vertex_count(), file.mesh.n_vertices(), "every file vertex is used");
    let golden = golden_field(case.golden);
    let pos = file.mesh.positions();
    assert_eq!(golden.len(), pos.len());
    let tissue = Tissue::new(5e4, 0.45, 1000.0).unwrap();
    let opts = FemOptions { resolution, ..Default::default() };
    let mut body =
        FemBody::from_surface(pos, file.mesh.triangles(), &tissue, &(case.fixed)(pos), &opts).unwrap();
    let s = body.solve(&Loads { gravity: [0.0, -9.81, 0.0], ..Default::default() }).unwrap();
    // Our vertex i is file vertex from_file_index(i).
    let ours: Vec<V3> = (0..pos.len()).map(|i| s.surface_displacements[i]).collect();
    let theirs: Vec<V3> = (0..pos.len()).map(|i| golden[file.from_file_index(i).unwrap()]).collect();
    if let Ok(dir) = std::env::var("FEM_DUMP") {
        // Ours in the golden's layout (file order), for comparing fields outside the test.
        let by_file = file.file_to_mesh().into_iter().map(|m| ours[m.unwrap()]);
        let text: String = by_file.map(|u| format!("{:.12e} {:.12e} {:.12e}\n", u[0], u[1], u[2])).collect();
        std::fs::write(PathBuf::from(dir).join(format!("{}-{resolution}.txt", case.mesh)), text).unwrap();
    }
    let e = rel_l2(&ours, &theirs, |_| true);
    let mean = |u: &[V3]| u.iter().map(|x| x[1]).sum::<f64>() / u.len() as f64;
    let st = body.stats();
    let tris = file.mesh.triangles();
    let volume: f64 = tris
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| pos[v as usize]);
            let cross = [b[1] * c[2] - b[2] * c[1], b[2] * c[0] - b[0] * c[2], b[0] * c[1] - b[1] * c[0]];
            (a[0] * cross[0] + a[1] * cross[1] + a[2] * cross[2]) / 6.0
        })
        .sum();
    eprintln!(
        "{}: resolution {resolution}: relative L2 error {e:.4}, mean u_y ratio {:.3}, dofs {} factor {:.2}s, \
         filled / enclosed volume {:.4}",
        case.mesh,
        mean(&ours) / mean(&theirs),
        st.dofs,
        st.factor_seconds,
        body.grid().filled_volume() / volume.abs()
    );
    e
}

/// The measurements behind `docs/fem.md` (slow: run with `--ignored --nocapture`).
/// `FEM_CASES` and `FEM_RES` choose bodies and resolutions, `GOLDEN_DIR` other reference
/// files, and `FEM_DUMP=DIR` writes our surface displacements there (`MESH-RES.txt`, one
/// `ux uy uz` line per file vertex).
#[test]
#[ignore]
fn measure_errors_against_reference() {
    let res: Vec<usize> = std::env::var("FEM_RES")
        .unwrap_or_else(|_| "8,12,16,20,24,32,40,48".into())
        .split(',')
        .map(|x| x.parse().unwrap())
        .collect();
    let which = std::env::var("FEM_CASES").unwrap_or_else(|_| "sphere,liver2,spot".into());
    for case in [&SPHERE, &LIVER, &SPOT] {
        if !which.contains(case.golden.split('-').next().unwrap()) {
            continue;
        }
        for &r in &res {
            error(case, r);
        }
    }
}

/// The sphere under gravity at resolutions 8, 16 and 24: the error against the reference
/// falls at each step (measured 0.056, 0.039, 0.033).
#[test]
#[ignore = "long run: CI runs it with `cargo test --workspace -- --ignored long_`"]
fn long_sphere_error_falls_with_resolution() {
    let e: Vec<f64> = [8, 16, 24].iter().map(|&r| error(&SPHERE, r)).collect();
    assert!(e[1] < e[0] && e[2] < e[1], "{e:?}");
}

/// The acceptance target: at the default resolution every body is within 15 % of the
/// independent P2 reference (measured: sphere 0.033, liver 0.041, spot 0.068).
#[test]
#[ignore = "long run: CI runs it with `cargo test --workspace -- --ignored long_`"]
fn long_default_resolution_meets_the_target() {
    assert_eq!(DEFAULT_RESOLUTION, 24);
    for case in [&SPHERE, &LIVER, &SPOT] {
        let e = error(case, DEFAULT_RESOLUTION);
        assert!(e < 0.15, "{}: {e}", case.mesh);
    }
}

/// Doubling the default resolution is no worse, for the liver (0.041 -> 0.012) and the cow
/// (0.068 -> 0.018), ~5 s. Against the reference whose mesh was refined only in the volume
/// the liver got worse (0.017 -> 0.047): that reference was too stiff at the clamp's edge
/// (see `tests/golden/README.md`). The sphere is `sphere_doubling_is_no_worse`.
#[test]
#[ignore = "long run: CI runs it with `cargo test --workspace -- --ignored long_`"]
fn long_doubling_the_default_resolution_is_no_worse() {
    for case in [&LIVER, &SPOT] {
        let e = [error(case, DEFAULT_RESOLUTION), error(case, 2 * DEFAULT_RESOLUTION)];
        assert!(e[1] <= e[0], "{}: {e:?}", case.mesh);
    }
}

/// The sphere at twice the default resolution (48: 200k unknowns, ~20 s to factor; run
/// with `--ignored`): no worse than at the default (measured 0.0325 -> 0.0290).
#[test]
#[ignore]
fn sphere_doubling_is_no_worse() {
    let e = [error(&SPHERE, DEFAULT_RESOLUTION), error(&SPHERE, 2 * DEFAULT_RESOLUTION)];
    assert!(e[1] <= e[0], "{e:?}");
}

/// A body of neo-Hookean tissue under gravity, a grasp or plates, with its independent
/// reference.
struct HyperCase {
    mesh: &'static str,
    golden: &'static str,
    /// The mesh file's coordinates times this are metres.
    scale: f64,
    young: f64,
    /// kg/m^3.
    density: f64,
    gravity: V3,
    /// Which vertices are fixed, from the scaled rest positions.
    fixed: fn(&[V3]) -> Vec<[bool; 3]>,
    /// A grasp: the centre vertex (file order), the patch's radius (m) and its translation
    /// at the full load (m).
    grasp: Option<(usize, f64, V3)>,
    /// Frictionless rigid plates.
    plates: &'static [RigidPlate],
}

/// `tongue.obj` at 2 cm per unit (3.6 x 2.7 x 6.2 cm), E = 2 kPa, hanging along z from its
/// top 5 mm (as `[[fix]] axis = "z" top = 0.005`: 174 vertices).
const TONGUE_NH: HyperCase = HyperCase {
    mesh: "tongue.obj",
    golden: "tongue-hanging-nh.txt",
    scale: 0.02,
    young: 2000.0,
    density: 1000.0,
    gravity: [0.0, 0.0, -9.81],
    fixed: |pos| {
        let top = pos.iter().map(|p| p[2]).fold(f64::MIN, f64::max);
        pos.iter().map(|p| [p[2] >= top - 0.005; 3]).collect()
    },
    grasp: None,
    plates: &[],
};

/// `icosphere-3.obj` 10 cm across, E = 3 kPa, hanging from its cap above 4 cm (as
/// `[[fix]] axis = "y" above = 0.04`).
const SPHERE_NH: HyperCase = HyperCase {
    mesh: "icosphere-3.obj",
    golden: "sphere-gravity-nh.txt",
    scale: 0.05,
    young: 3000.0,
    density: 1000.0,
    gravity: [0.0, -9.81, 0.0],
    fixed: |pos| pos.iter().map(|p| [p[1] > 0.04; 3]).collect(),
    grasp: None,
    plates: &[],
};

/// The bundled liver-hanging scene: `liver2.obj` at 10 cm per unit (21.5 cm across),
/// E = 5 kPa, density 1060, hanging along y from its top 8 mm (as `[[fix]] axis = "y"
/// top = 0.008`: 39 vertices).
const LIVER_NH: HyperCase = HyperCase {
    mesh: "liver2.obj",
    golden: "liver-hanging-nh.txt",
    scale: 0.1,
    young: 5000.0,
    density: 1060.0,
    gravity: [0.0, -9.81, 0.0],
    fixed: |pos| {
        let top = pos.iter().map(|p| p[1]).fold(f64::MIN, f64::max);
        pos.iter().map(|p| [p[1] >= top - 0.008; 3]).collect()
    },
    grasp: None,
    plates: &[],
};
/// The tongue of `TONGUE_NH` hanging, grasped 6 mm around vertex 2543 (near its tip, 72
/// vertices) and pulled 2 cm along +y and 2 cm down, as `[[grasp]] vertex = 2543
/// radius = 0.006 translation = [0.0, 0.02, -0.02]` (the grasp pulled far: 2.8 cm on a
/// 6.2 cm body).
const TONGUE_GRASP_NH: HyperCase =
    HyperCase { golden: "tongue-grasp-nh.txt", grasp: Some((2543, 0.006, [0.0, 0.02, -0.02])), ..TONGUE_NH };

/// The bundled breast-compression scene: `dome.obj` (a 6 cm hemisphere on the chest plane
/// y = 0), E = 3.25 kPa, glued within 1 mm of the chest plane, the paddle coming up 3 cm
/// from the apex (half the thickness), the chest wall a fixed plate; no gravity.
const DOME_NH: HyperCase = HyperCase {
    mesh: "dome.obj",
    golden: "dome-half-nh.txt",
    scale: 1.0,
    young: 3250.0,
    density: 930.0,
    gravity: [0.0; 3],
    fixed: |pos| {
        let top = pos.iter().map(|p| p[1]).fold(f64::MIN, f64::max);
        pos.iter().map(|p| [p[1] >= top - 0.001; 3]).collect()
    },
    grasp: None,
    plates: &[
        RigidPlate { force: None, start: [0.0; 3], end: [0.0; 3], normal: [0.0, -1.0, 0.0] },
        RigidPlate { force: None, start: [0.0, -0.06, 0.0], end: [0.0, -0.03, 0.0], normal: [0.0, 1.0, 0.0] },
    ],
};

/// Relative L2 error of the neo-Hookean FEM's surface displacement at `resolution` against
/// the case's independent neo-Hookean reference (nu = 0.45).
fn hyper_error(case: &HyperCase, resolution: usize) -> f64 {
    hyper_solve(case, resolution).0
}

/// [`hyper_error`] and the plates' forces on the body (N).
fn hyper_solve(case: &HyperCase, resolution: usize) -> (f64, Vec<f64>) {
    let file = load_mesh(root().join("../../fixtures/meshes").join(case.mesh)).unwrap();
    let golden = golden_field(case.golden);
    let pos: Vec<V3> = file.mesh.positions().iter().map(|p| p.map(|x| x * case.scale)).collect();
    assert_eq!(golden.len(), pos.len());
    let tissue = Tissue::new(case.young, 0.45, case.density).unwrap().with_model(TissueModel::NeoHookean);
    let opts = FemOptions { resolution, ..Default::default() };
    let fixed = (case.fixed)(&pos);
    let grasps: Vec<Grasp> = case
        .grasp
        .iter()
        .map(|&(vertex, radius, translation)| Grasp {
            vertices: Grasp::patch(&pos, file.from_file_index(vertex).unwrap(), radius),
            translation,
            rotation: [0.0; 3],
        })
        .collect();
    let mut body =
        HyperBody::from_surface_grasped(&pos, file.mesh.triangles(), &tissue, &fixed, &grasps, &opts)
            .unwrap();
    let s = body.solve(&Loads { gravity: case.gravity, ..Default::default() }, case.plates).unwrap();
    let theirs: Vec<V3> = (0..pos.len()).map(|i| golden[file.from_file_index(i).unwrap()]).collect();
    // As the command line reports it: a fixed axis of a fixed vertex is exactly at rest
    // (the clamp's penalty slip is an error inside the body).
    let ours: Vec<V3> = s
        .surface_displacements
        .iter()
        .zip(&fixed)
        .map(|(u, f)| std::array::from_fn(|a| if f[a] { 0.0 } else { u[a] }))
        .collect();
    let e = rel_l2(&ours, &theirs, |_| true);
    let fixed_count = fixed.iter().filter(|f| f[0]).count();
    eprintln!(
        "{} (neo-Hookean, {}), resolution {resolution}: relative L2 error {e:.4} ({fixed_count} fixed), plate forces {:?} N",
        case.mesh, case.golden, s.plate_forces
    );
    (e, s.plate_forces)
}

/// Against the independent neo-Hookean references (P2 tetrahedra, `tools/reference_nh.py`,
/// `tests/golden/NEO_HOOKEAN.md`), at the default resolution: the tongue hanging from its
/// top within 3 % (measured 0.0187; 0.0093 at resolution 48), the 10 cm sphere within
/// 5 % (measured 0.0366; 0.0083 at resolution 48), where the issue asks 10 %, and the
/// bundled liver-hanging scene within 3 % (measured 0.0116; its reference is not refined
/// at the clamp, and at resolution 48 fibfluid hangs the liver 3 % further: 0.0392).
#[test]
#[ignore = "long run: CI runs it with `cargo test --workspace -- --ignored long_`"]
fn long_neo_hookean_bodies_match_an_independent_reference() {
    let tongue = hyper_error(&TONGUE_NH, DEFAULT_RESOLUTION);
    assert!(tongue < 0.03, "tongue: {tongue}");
    let sphere = hyper_error(&SPHERE_NH, DEFAULT_RESOLUTION);
    assert!(sphere < 0.05, "sphere: {sphere}");
    let liver = hyper_error(&LIVER_NH, DEFAULT_RESOLUTION);
    assert!(liver < 0.03, "liver: {liver}");
}

/// A grasp pulled far and a compression between plates against independent neo-Hookean
/// references (P2 tetrahedra, `tools/reference_nh.py`: the grasp's patch held by
/// prescribed displacements, the plates as an active set of nodes held on their planes;
/// `tests/golden/NEO_HOOKEAN.md`), at the default resolution: the tongue grasped near its
/// tip and pulled 2.8 cm within 4 % (measured 0.0235), the dome pressed to half its
/// thickness within 5 % (measured 0.0292; 0.0125 at resolution 48) and its paddle force
/// within 5 % of the reference's 24.86 N (measured 24.23 N, -2.5 %; 24.51 N at 48), where the
/// issue asks 10 % of both.
#[test]
#[ignore = "long run: CI runs it with `cargo test --workspace -- --ignored long_`"]
fn long_neo_hookean_grasp_and_plates_match_an_independent_reference() {
    let tongue = hyper_error(&TONGUE_GRASP_NH, DEFAULT_RESOLUTION);
    assert!(tongue < 0.04, "tongue grasped: {tongue}");
    let (dome, forces) = hyper_solve(&DOME_NH, DEFAULT_RESOLUTION);
    assert!(dome < 0.05, "dome: {dome}");
    let paddle = forces[1] / golden_plate_forces(DOME_NH.golden)[1];
    assert!((paddle - 1.0).abs() < 0.05, "paddle force {} N: {paddle} of the reference", forces[1]);
}

/// Doubling the resolution is no worse against the neo-Hookean references (slow: the
/// sphere at 48 has about 200,000 unknowns and takes half an hour; run with `--ignored
/// --nocapture`). Measured: sphere 0.0366 then 0.0083, tongue 0.0187 then 0.0093, the
/// grasped tongue 0.0235 then 0.0103. (The dome between plates, 0.0292 then 0.0125, takes
/// 27 minutes at 48 and is measured from the command line: NEO_HOOKEAN.md.)
#[test]
#[ignore]
fn neo_hookean_doubling_is_no_worse() {
    for case in [&TONGUE_NH, &SPHERE_NH, &TONGUE_GRASP_NH] {
        let (coarse, fine) = (hyper_error(case, 24), hyper_error(case, 48));
        assert!(fine <= coarse * 1.05, "{}: {coarse} then {fine}", case.mesh);
    }
}
