//! A flag overrides only its own key: `--method ffm` on a scene whose `[solver] method`
//! says `fem` runs what `method = "ffm"` in the file runs.

use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A `[tissue]`-only scene (the 162-vertex icosphere of radius 1 cm, E = 5 kPa, hanging
/// from its cap under gravity; the FEM on a coarse grid) with `[solver] method = method`,
/// written in `dir`.
fn tissue_scene(dir: &Path, method: &str) -> PathBuf {
    let mesh = root().join("fixtures/meshes/icosphere-2.obj");
    let text = format!(
        "[mesh]\npath = {:?}\nunit = \"cm\"\n[tissue]\nyoung = 5000.0\npoisson = 0.45\ndensity = 1000.0\n\
         [gravity]\nacceleration = [0.0, -9.81, 0.0]\n[[fix]]\naxis = \"y\"\nabove = 0.8\n\
         [fem]\nresolution = 8\n[solver]\nmode = \"paper\"\nmethod = \"{method}\"\n",
        mesh.to_str().unwrap()
    );
    let path = dir.join(format!("{method}.toml"));
    std::fs::write(&path, text).unwrap();
    path
}

/// Runs `fibfluid run scene args --out dir/out` and returns report.json's largest
/// displacement (m) and the run's stderr.
fn run(scene: &Path, args: &[&str], out: &Path) -> (f64, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_fibfluid"))
        .arg("run")
        .arg(scene)
        .args(args)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(o.status.success(), "{stderr}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let u = report["max_displacement"].as_f64().unwrap_or_else(|| panic!("no max_displacement: {report}"));
    (u, stderr)
}

/// `--method ffm` on a scene that says `fem` calibrates the fibers on the tissue and takes
/// its density, as `method = "ffm"` does: the two runs give the same largest displacement,
/// gravity moves the body, and by about what the FEM (the calibration's reference, run
/// here separately) finds; neither run asks for a fluid density the tissue already gives.
#[test]
fn the_method_flag_runs_what_the_method_key_runs() {
    let tmp = tempfile::tempdir().unwrap();
    let fem_scene = tissue_scene(tmp.path(), "fem");
    let ffm_scene = tissue_scene(tmp.path(), "ffm");
    let (flag, flag_err) = run(&fem_scene, &["--method", "ffm"], &tmp.path().join("flag"));
    let (key, key_err) = run(&ffm_scene, &[], &tmp.path().join("key"));
    let (fem, _) = run(&fem_scene, &[], &tmp.path().join("fem"));
    assert!((flag - key).abs() <= 1e-12 * key, "--method ffm {flag:e} m, method = \"ffm\" {key:e} m");
    // Gravity moves the body, by the FEM's order of magnitude (the calibration fits the
    // FEM's displacement field: its scale is the FEM's to within the shape's error).
    assert!(fem > 1e-5, "the FEM's sag {fem:e} m");
    assert!(flag > 0.5 * fem && flag < 2.0 * fem, "calibrated FFM {flag:e} m against the FEM's {fem:e} m");
    for err in [&flag_err, &key_err] {
        assert!(!err.contains("[fluid] density"), "{err}");
    }
}
