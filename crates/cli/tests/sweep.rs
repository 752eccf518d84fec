//! `fibfluid sweep`: every combination of the `--set` values runs into its own directory,
//! `sweep.csv` lists them in order, and a linear body's sag scales as 1/E; bad `--set`
//! values are one-line errors with exit code 2 before anything runs.

use std::path::Path;
use std::process::{Command, Output};

fn setup() -> (tempfile::TempDir, std::path::PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("column.obj"), crate::fit::box_obj([2, 2, 3], 0.01)).unwrap();
    let scene = dir.path().join("scene.toml");
    // The fit's column with the linear law (its sag scales exactly as 1/E), coarser.
    let text = crate::fit::column_scene("linear", [3000.0, 15000.0], 4, "");
    std::fs::write(&scene, text).unwrap();
    (dir, scene)
}

fn sweep(scene: &Path, out: &Path, sets: &[&str]) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_fibfluid"));
    c.arg("sweep").arg(scene).arg("--out").arg(out).args(["--jobs", "2"]);
    for s in sets {
        c.arg("--set").arg(s);
    }
    c.output().unwrap()
}

/// A 2 x 2 sweep: four run directories with each run's outputs, four rows in order; a
/// stiffer tissue sags less, and doubling both moduli halves the sag (linear elasticity:
/// u scales as 1/E when every modulus scales together).
#[test]
fn sweep_runs_every_combination_in_order() {
    let (dir, scene) = setup();
    let out = dir.path().join("out");
    let run = sweep(&scene, &out, &["tissue.young=1000,2000", "region.lesion.young=15000,30000"]);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    for k in 1..=4 {
        let d = out.join(format!("run-00{k}"));
        for f in ["report.json", "deformed.obj", "volume.vtu"] {
            assert!(d.join(f).is_file(), "{}/{f}", d.display());
        }
    }
    let csv = std::fs::read_to_string(out.join("sweep.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines[0], "run,tissue.young,region.lesion.young,status,max_displacement_m,seconds");
    assert_eq!(lines.len(), 5, "{csv}");
    let rows: Vec<Vec<&str>> = lines[1..].iter().map(|l| l.split(',').collect()).collect();
    let expected =
        [("1000.0", "15000.0"), ("1000.0", "30000.0"), ("2000.0", "15000.0"), ("2000.0", "30000.0")];
    for (k, (r, (e, l))) in rows.iter().zip(expected).enumerate() {
        assert_eq!((r[0], r[1], r[2], r[3]), (format!("run-00{}", k + 1).as_str(), e, l, "ok"), "{csv}");
    }
    let u: Vec<f64> = rows.iter().map(|r| r[4].parse().unwrap()).collect();
    assert!(u[2] < u[0] && u[1] < u[0], "{u:?}");
    assert!((u[0] / u[3] / 2.0 - 1.0).abs() < 1e-6, "{u:?}");
    // The row's value is the run's own: its report's largest displacement.
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("run-004/report.json")).unwrap()).unwrap();
    assert_eq!(report["max_displacement"].as_f64().unwrap(), u[3]);
}

/// An unknown key, an empty list, a value that is not a number, a modulus the tissue refuses:
/// one `error:` line naming the `--set` value, exit code 2, nothing written.
#[test]
fn bad_sweep_sets_are_one_line_errors() {
    let (dir, scene) = setup();
    let out = dir.path().join("out");
    for (set, says) in [
        ("tissue.yung=1000", "tissue.yung"),
        ("region.tumor.young=1000", "no [[region]] of that name"),
        ("tissue.young=", "no value"),
        ("tissue.young=1000,abc", "`abc` is not a finite number"),
        ("tissue.young=-5", "tissue.young"),
        ("tissue.young", "KEY=VALUE"),
    ] {
        let run = sweep(&scene, &out, &[set]);
        let err = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{set}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{set}: {err}");
        assert!(err.starts_with(&format!("error: --set {set}: ")) && err.contains(says), "{set}: {err}");
        assert!(!out.exists(), "{set}: nothing written");
    }
}

/// `run --set` changes the run as the scene would: the tissue's modulus in the report.
#[test]
fn run_set_overrides_the_scene() {
    let (dir, scene) = setup();
    let out = dir.path().join("out");
    let run = Command::new(env!("CARGO_BIN_EXE_fibfluid"))
        .arg("run")
        .arg(&scene)
        .arg("--out")
        .arg(&out)
        .args(["--set", "tissue.young=4321"])
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    assert!(
        String::from_utf8_lossy(&run.stdout).contains("E = 4321.00 Pa"),
        "{}",
        String::from_utf8_lossy(&run.stdout)
    );
}
