//! `fibfluid fit`: a column with a stiff lower half sagging under its own weight; the
//! positions of its surface vertices from a forward run at the true moduli give the moduli
//! back; bad `[fit]` input and observed files are one-line errors with exit code 2.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use fibfluid::Scene;
use fibfluid::sim::stages::StageLog;

/// Observed rows: the vertex (file order) and its deformed position (m).
type Rows = Vec<(usize, [f64; 3])>;

/// The body's tissue and region moduli (Pa) of the synthetic truth.
const TRUTH: [f64; 2] = [3000.0, 15000.0];

/// The surface of the box `[0, n_x s] x [0, n_y s] x [0, n_z s]` as OBJ text (two outward
/// triangles per square of side `s`).
pub(crate) fn box_obj(n: [usize; 3], s: f64) -> String {
    let (positions, triangles) = fibfluid::geometry::box_surface([0.0; 3], n, s);
    let vertices = positions.iter().map(|p| format!("v {} {} {}\n", p[0], p[1], p[2]));
    let faces = triangles.iter().map(|t| format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1));
    vertices.chain(faces).collect()
}

/// A 2 x 2 x 3 cm neo-Hookean column on its base, gravity down and sideways, its lower half
/// a stiff region; `young` the two moduli, `fit` an optional `[fit]` section.
fn scene_text(young: [f64; 2], fit: &str) -> String {
    column_scene("neo-hookean", young, 6, fit)
}

/// The column of [`scene_text`] with the tissue law `model` (both tissues) at `resolution`.
pub(crate) fn column_scene(model: &str, young: [f64; 2], resolution: usize, fit: &str) -> String {
    format!(
        r#"[mesh]
path = "column.obj"
[tissue]
model = "{model}"
young = {}
poisson = 0.4
density = 1000.0
[[region]]
name = "lesion"
box = {{ min = [-1.0, -1.0, -1.0], max = [1.0, 1.0, 0.015] }}
[region.tissue]
young = {}
poisson = 0.4
density = 1000.0
[gravity]
acceleration = [3.0, 0.0, -9.3]
[[fix]]
axis = "z"
below = 0.0001
[fem]
resolution = {resolution}
[solver]
method = "fem"
{fit}"#,
        young[0], young[1]
    )
}

const FIT: &str = r#"[fit]
parameters = ["tissue.young", "region.lesion.young"]
bounds = [[300.0, 3.0e5], [300.0, 3.0e6]]
observed = "observed.csv"
"#;

/// A directory with the column's mesh, `scene.toml` (moduli `start`, `[fit]`) and the
/// observed positions of 30 vertices off the base from a forward run at [`TRUTH`].
fn setup() -> (tempfile::TempDir, PathBuf, Rows) {
    setup_with(&scene_text(TRUTH, ""), &scene_text([1000.0, 1000.0], FIT))
}

/// A directory with the column's mesh, the scene `fitted` as `scene.toml` and the observed
/// positions of 30 vertices off the base from a forward run of the scene `truth`.
fn setup_with(truth: &str, fitted: &str) -> (tempfile::TempDir, PathBuf, Rows) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("column.obj"), box_obj([4, 4, 6], 0.005)).unwrap();
    let truth_path = dir.path().join("truth.toml");
    std::fs::write(&truth_path, truth).unwrap();
    let scene = Scene::load(&truth_path).unwrap();
    let tissue = scene.tissue.unwrap();
    let (_, solution, _, _) =
        fibfluid::sim::hyper_run::solve(&scene.model, &tissue, u64::MAX, &mut StageLog::default()).unwrap();
    let fibfluid::sim::Shape::Surface(file) = &scene.shape else { unreachable!() };
    let rest = scene.rest_positions();
    let off_base: Vec<(usize, usize)> = (0..file.file_vertex_count())
        .map(|v| (v, file.from_file_index(v).unwrap()))
        .filter(|&(_, m)| rest[m][2] > 0.001)
        .collect();
    let observed: Rows = off_base
        .iter()
        .step_by(off_base.len() / 30)
        .take(30)
        .map(|&(v, m)| (v, std::array::from_fn(|a| rest[m][a] + solution.surface_displacements[m][a])))
        .collect();
    let path = dir.path().join("scene.toml");
    std::fs::write(&path, fitted).unwrap();
    (dir, path, observed)
}

/// `fit.json` in `out`, parsed.
fn fit_json(out: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(out.join("fit.json")).unwrap()).unwrap()
}

fn write_observed(dir: &Path, rows: &[(usize, [f64; 3])]) {
    let mut text = String::from("vertex,x,y,z\n");
    for (v, p) in rows {
        text.push_str(&format!("{v},{},{},{}\n", p[0], p[1], p[2]));
    }
    std::fs::write(dir.join("observed.csv"), text).unwrap();
}

fn fit(scene: &Path, out: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_fibfluid")).arg("fit").arg(scene).arg("--out").arg(out).output().unwrap()
}

/// Noise-free positions of 30 vertices from a forward run at 3 and 15 kPa give both moduli
/// back within 1 % from a start of 1 kPa each.
#[test]
fn fit_recovers_the_moduli_of_a_synthetic_truth() {
    let (dir, scene, observed) = setup();
    write_observed(dir.path(), &observed);
    let out = dir.path().join("out");
    let run = fit(&scene, &out);
    let stderr = String::from_utf8_lossy(&run.stderr);
    eprintln!("{stderr}{}", String::from_utf8_lossy(&run.stdout));
    assert!(run.status.success());
    assert!(stderr.contains("fit: iteration 1:"), "a progress line per iteration");
    let report: serde_json::Value = fit_json(&out);
    for (j, truth) in TRUTH.iter().enumerate() {
        let p = &report["parameters"][j];
        let value = p["value"].as_f64().unwrap();
        assert!((value / truth - 1.0).abs() < 0.01, "{}: {value} against {truth}", p["key"]);
        assert_eq!(p["identifiable"], true);
    }
    assert!(report["residual_relative"].as_f64().unwrap() < 1e-3, "{}", report["residual_relative"]);
    assert_eq!(report["observations"], 30);
    assert!(report["correlation"][0][1].as_f64().unwrap().abs() <= 1.0);
    let png = std::fs::read(out.join("fit.png")).unwrap();
    assert!(png.starts_with(b"\x89PNG\r\n\x1a\n"), "fit.png is a PNG");
    // The header's width and height: the surface and the chart side by side.
    assert_eq!((be32(&png[16..20]), be32(&png[20..24])), (1600, 640));
    // Noise-free: every observed vertex lands on its observation, to well under its
    // displacement (the vertices in the observed file's order).
    let residuals = report["residuals"].as_array().unwrap();
    assert_eq!(residuals.len(), 30);
    let rest = Scene::load(&scene).unwrap().rest_positions();
    for ((r, (v, p)), m) in residuals.iter().zip(&observed).zip(mesh_indices(&scene, &observed)) {
        assert_eq!(r["vertex"].as_u64(), Some(*v as u64));
        let moved = (0..3).map(|a| (p[a] - rest[m][a]).powi(2)).sum::<f64>().sqrt();
        assert!(r["distance"].as_f64().unwrap() < 1e-6 * moved, "{r} against a displacement of {moved} m");
    }
}

fn be32(b: &[u8]) -> u32 {
    u32::from_be_bytes([b[0], b[1], b[2], b[3]])
}

/// The mesh index of each observed vertex (the rows are in file order).
fn mesh_indices(scene: &Path, rows: &Rows) -> Vec<usize> {
    let scene = Scene::load(scene).unwrap();
    let fibfluid::sim::Shape::Surface(file) = &scene.shape else { unreachable!() };
    rows.iter().map(|(v, _)| file.from_file_index(*v).unwrap()).collect()
}

/// One observed vertex moved 3 mm sideways: `fit.json`'s residuals are the distances of a
/// separate forward run at the fitted moduli from the observations, and the moved vertex's
/// is the largest, most of the 3 mm (the two moduli cannot follow one vertex).
#[test]
fn fit_json_residuals_are_those_of_a_forward_run_at_the_fitted_moduli() {
    let (dir, scene, mut observed) = setup();
    let moved = 7;
    observed[moved].1[0] += 3e-3;
    write_observed(dir.path(), &observed);
    let out = dir.path().join("out");
    let run = fit(&scene, &out);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let report: serde_json::Value = fit_json(&out);
    let fitted: Vec<f64> = (0..2).map(|j| report["parameters"][j]["value"].as_f64().unwrap()).collect();
    let forward = dir.path().join("forward.toml");
    std::fs::write(&forward, scene_text([fitted[0], fitted[1]], "")).unwrap();
    let model = Scene::load(&forward).unwrap();
    let (_, solution, _, _) = fibfluid::sim::hyper_run::solve(
        &model.model,
        &model.tissue.unwrap(),
        u64::MAX,
        &mut StageLog::default(),
    )
    .unwrap();
    let rest = model.rest_positions();
    let residuals = report["residuals"].as_array().unwrap();
    let mut largest = (0, 0.0);
    for (k, ((r, (v, p)), m)) in
        residuals.iter().zip(&observed).zip(mesh_indices(&forward, &observed)).enumerate()
    {
        let x: [f64; 3] = std::array::from_fn(|a| rest[m][a] + solution.surface_displacements[m][a]);
        let distance = (0..3).map(|a| (x[a] - p[a]).powi(2)).sum::<f64>().sqrt();
        let reported = r["distance"].as_f64().unwrap();
        assert_eq!(r["vertex"].as_u64(), Some(*v as u64));
        assert!((reported - distance).abs() < 1e-9, "vertex {v}: {reported} against {distance} m");
        if reported > largest.1 {
            largest = (k, reported);
        }
    }
    assert_eq!(largest.0, moved, "{residuals:?}");
    assert!(largest.1 > 0.5 * 3e-3 && largest.1 < 1.05 * 3e-3, "{}", largest.1);
}

/// Without gravity, pressed by a point force, the column's density does nothing: fitted with
/// its Young's modulus, it is reported as not identifiable (no value) and the modulus is found.
#[test]
fn a_parameter_the_observations_cannot_see_is_not_identifiable() {
    // The vertex at the middle of the top face.
    let top = box_obj([4, 4, 6], 0.005)
        .lines()
        .filter(|l| l.starts_with("v "))
        .position(|l| {
            let p: Vec<f64> = l.split_whitespace().skip(1).map(|t| t.parse().unwrap()).collect();
            (p[0] - 0.01).abs() < 1e-9 && (p[1] - 0.01).abs() < 1e-9 && (p[2] - 0.03).abs() < 1e-9
        })
        .unwrap();
    let force = format!("[[force]]\nvertex = {top}\nvalue = [0.004, 0.002, -0.01]");
    let pressed = |young: f64, fit: &str| {
        scene_text([young, TRUTH[0]], fit).replace("[gravity]\nacceleration = [3.0, 0.0, -9.3]", &force)
    };
    let fit_text = FIT
        .replace("\"region.lesion.young\"", "\"tissue.density\"")
        .replace("[300.0, 3.0e6]", "[100.0, 3000.0]");
    let (dir, scene, observed) = setup_with(&pressed(TRUTH[0], ""), &pressed(1000.0, &fit_text));
    write_observed(dir.path(), &observed);
    let out = dir.path().join("out");
    let run = fit(&scene, &out);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let report: serde_json::Value = fit_json(&out);
    let (young, density) = (&report["parameters"][0], &report["parameters"][1]);
    assert!((young["value"].as_f64().unwrap() / TRUTH[0] - 1.0).abs() < 0.01, "{young}");
    assert_eq!(density["identifiable"], false);
    assert!(density["value"].is_null() && density["sigma"].is_null(), "{density}");
    assert!(String::from_utf8_lossy(&run.stdout).contains("tissue.density"));
}

/// Each bad input is one `error:` line naming the file (and line or key), exit code 2.
#[test]
fn bad_fit_inputs_are_one_line_errors() {
    let (dir, scene, observed) = setup();
    let text = std::fs::read_to_string(&scene).unwrap();
    let cases: Vec<(String, Rows, String, &str)> = vec![
        (
            text.replace("\"tissue.young\"", "\"tissue.stiffness\""),
            observed.clone(),
            String::new(),
            "[fit].parameters",
        ),
        (
            text.replace("\"region.lesion.young\"", "\"region.tumour.young\""),
            observed.clone(),
            String::new(),
            "no [[region]] of that name",
        ),
        (text.replace("[300.0, 3.0e5], ", ""), observed.clone(), String::new(), "1 bounds for 2 parameters"),
        (
            text.replace("[300.0, 3.0e5]", "[2000.0, 3.0e5]"),
            observed.clone(),
            String::new(),
            "lies outside [2000, 300000]",
        ),
        (
            text.clone(),
            vec![(100_000, [0.0; 3])],
            String::new(),
            "observed.csv:2: vertex 100000 is not a vertex of the mesh",
        ),
        (
            text.clone(),
            observed.clone(),
            "7,0.1,zero,0.2\n".into(),
            "observed.csv:32: `zero` is not a finite number",
        ),
    ];
    for (scene_text, rows, extra, fragment) in cases {
        std::fs::write(&scene, &scene_text).unwrap();
        write_observed(dir.path(), &rows);
        if !extra.is_empty() {
            let path = dir.path().join("observed.csv");
            let csv = std::fs::read_to_string(&path).unwrap() + &extra;
            std::fs::write(&path, csv).unwrap();
        }
        let run = fit(&scene, &dir.path().join("out"));
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{fragment}: {stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(stderr.starts_with("error: ") && stderr.contains(fragment), "{fragment}: {stderr}");
    }
}

/// With 0.2 mm of Gaussian noise on every coordinate (about half the observed displacement),
/// over 20 draws the truth lies within the reported 1-sigma of each modulus about as often as
/// a Gaussian's 68 % (between 8 and 19 draws) and within 2 sigma in at least 16.
#[test]
#[ignore = "long run: CI runs it with `cargo test --workspace -- --ignored long_`"]
fn long_noisy_fits_bracket_the_truth_at_the_stated_rate() {
    let (dir, scene, observed) = setup();
    let mut seed = 0x2545_f491_4f6c_dd1d_u64;
    let mut uniform = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut gauss = move || {
        let (u, v) = (uniform().max(1e-300), uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    };
    let (draws, mut within, mut within2) = (20, [0; 2], [0; 2]);
    for draw in 0..draws {
        let noisy: Rows = observed.iter().map(|(v, p)| (*v, p.map(|x| x + 2e-4 * gauss()))).collect();
        write_observed(dir.path(), &noisy);
        let out = dir.path().join(format!("out{draw}"));
        assert!(fit(&scene, &out).status.success());
        let report: serde_json::Value = fit_json(&out);
        for (j, truth) in TRUTH.iter().enumerate() {
            let p = &report["parameters"][j];
            let (value, sigma) = (p["value"].as_f64().unwrap(), p["sigma"].as_f64().unwrap());
            eprintln!("draw {draw}: {} {value:.1} +- {sigma:.1} (truth {truth})", p["key"]);
            within[j] += usize::from((value - truth).abs() <= sigma);
            within2[j] += usize::from((value - truth).abs() <= 2.0 * sigma);
        }
    }
    eprintln!("within 1 sigma: {within:?}, within 2 sigma: {within2:?} of {draws}");
    for j in 0..2 {
        assert!((8..=19).contains(&within[j]) && within2[j] >= 16, "{within:?} {within2:?}");
    }
}
