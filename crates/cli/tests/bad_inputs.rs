//! Every entry of `tests/bad_inputs/` is fed to the real binary (`mesh-info` for meshes,
//! `run --out DIR` for scenes, `probe --method tsve-chainmail` for the `[chainmail]` ones): it must exit with code 2 and print exactly one `error:`
//! line that names the file and its problem, never panic, and leave `--out` as it was.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Each corpus entry and a fragment its error line must contain (README.md there says why).
const EXPECTED: &[(&str, &str)] = &[
    (
        "mesh-coordinates-1e-300.obj",
        "face 0: the coordinates are too small, its area underflows to 0e0 (vertex 2 has |coordinate| = 1e-300); scale the mesh up, e.g. `[mesh].scale = 1e300`",
    ),
    (
        "mesh-coordinates-1e300.obj",
        "face 0: the coordinates overflow f64 when multiplied (vertex 2 has |coordinate| = 1e300); scale the mesh down, e.g. `[mesh].scale = 1e-300`",
    ),
    ("mesh-duplicate-faces.obj", "faces 0 and 4 are duplicates"),
    ("mesh-empty.obj", "no vertices"),
    ("mesh-garbage.obj", "not a text OBJ file (invalid UTF-8)"),
    ("mesh-garbage.stl", "but the file has 301 bytes"),
    ("mesh-huge-header.stl", "header claims 4000000 triangles (200000084 bytes) but the file has 134 bytes"),
    (
        "mesh-huge-header.ply",
        ":4: the header claims 1000000000000 vertex elements (at least 6000000000000 bytes with those before them) but only 56 bytes follow the header",
    ),
    ("mesh-index-out-of-range.off", ":11: face refers to vertex 4 but the file has 4 vertices (0-based)"),
    ("mesh-point-cloud.ply", ":0: the header has no `element face` (a point cloud, not a surface)"),
    ("mesh-truncated.ply", ":0: binary face 3 at byte 359: the file ends inside it"),
    ("mesh-wrong-magic.ply", ":1: not a PLY file (the first line is not `ply`)"),
    ("mesh-inconsistent-orientation.obj", "faces around edge (0, 2) are inconsistently oriented"),
    ("mesh-index-out-of-range.obj", ":9: face refers to vertex 9 but the file has 4 vertices"),
    ("mesh-index-zero.obj", ":6: face index 0 (OBJ indices start at 1)"),
    ("mesh-is-a-directory.obj", "is a directory, not a mesh file"),
    ("mesh-nan.obj", ":4: vertex 2 has a non-finite coordinate"),
    (
        "mesh-near-duplicate-vertices.obj",
        "vertices 0 and 12 are 1.00e-12 apart, 2.89e-13 of the body's size: a near-duplicate vertex",
    ),
    ("mesh-negative-index.obj", ":9: relative face index -5 points before the first vertex"),
    ("mesh-non-manifold-edge.obj", "edge (0, 1) is shared by 4 faces (non-manifold)"),
    ("mesh-open.obj", "the surface is open"),
    ("mesh-single-triangle.obj", "the surface is open: 3 boundary edges"),
    ("mesh-truncated-facet.stl", ":12: the last facet has fewer than 3 vertices"),
    ("mesh-two-tetrahedra.obj", "component 1 lies outside the outer surface: two disjoint bodies"),
    ("mesh-cavity-crosses.obj", "cavity 1 crosses the outer surface"),
    (
        "scene-image-truncated.toml",
        "image-truncated.nii: is truncated: the voxels need 11872 bytes, only 400 present",
    ),
    ("scene-image-label-missing.toml", "phantom.nii.gz: the image has no voxel of label 7"),
    ("mesh-unknown-extension.xyz", "unsupported mesh format (expected .obj, .stl, .ply or .off)"),
    (
        "scene-backend-not-compiled.toml",
        "[solver].backend: backend `openblas-lu` is not compiled into this build; rebuild with `cargo build --features openblas` (needs the system OpenBLAS",
    ),
    ("scene-bad-mesh.toml", "scene-bad-mesh.toml:3: [mesh].path: "),
    (
        "scene-fix-nothing-along-z.toml",
        "scene-fix-nothing-along-z.toml:10: [[fix]]: no vertex is fixed along z",
    ),
    (
        "scene-fix-selects-nothing.toml",
        "scene-fix-selects-nothing.toml:9: [[fix]] #1: constraint `y > 5` selects no vertex",
    ),
    (
        "scene-fix-vertex-out-of-range.toml",
        "scene-fix-vertex-out-of-range.toml:10: [[fix]] #1.vertices: vertex 100 is out of range",
    ),
    (
        "scene-grasp-radius-zero.toml",
        "scene-grasp-radius-zero.toml:15: [[grasp]] #1.radius: must be positive (in the mesh's unit), got 0",
    ),
    (
        "scene-grasp-vertex-out-of-range.toml",
        "scene-grasp-vertex-out-of-range.toml:14: [[grasp]] #1.vertex: vertex 42 is out of range",
    ),
    (
        "scene-grasp-on-fixed.toml",
        "scene-grasp-on-fixed.toml:15: [[grasp]] #1.radius: the patch holds a vertex that a [[fix]] fixes",
    ),
    (
        "scene-force-vertex-out-of-range.toml",
        "scene-force-vertex-out-of-range.toml:14: [[force]] #1.vertex: vertex 42 is out of range",
    ),
    (
        "scene-fem-unknown-model.toml",
        "scene-fem-unknown-model.toml:6: [tissue].model: `mooney` is not a tissue model (expected one of: linear, neo-hookean, auto)",
    ),
    (
        "scene-fem-region-outside.toml",
        "scene-fem-region-outside.toml: fem: region 1 (box) lies outside the body",
    ),
    ("scene-fem-region-model.toml", "[[region]] #1 tissue.model: a region takes the body's [tissue] model"),
    (
        "scene-fem-newton-fails.toml",
        "scene-fem-newton-fails.toml: fem: Newton's method did not converge at load step",
    ),
    (
        "scene-fem-poisson-half.toml",
        "scene-fem-poisson-half.toml:7: [tissue].poisson: must be in (-1, 0.5): 0.5 is the incompressible limit",
    ),
    (
        "scene-fem-resolution-zero.toml",
        "scene-fem-resolution-zero.toml:18: [fem].resolution: must be between 1 and 256",
    ),
    (
        "scene-fem-thin-body.toml",
        "scene-fem-thin-body.toml: fem: the body is 2.000e-2 m thick along z, thinner than a cell (4.167e-2 m)",
    ),
    (
        "scene-fem-young-zero.toml",
        "scene-fem-young-zero.toml:6: [tissue].young: must be finite and > 0 (Pa), got 0",
    ),
    ("scene-is-a-directory.toml", "is a directory, not a scene file"),
    ("scene-malformed.toml", "scene-malformed.toml:2: unclosed table, expected `]` (column 6)"),
    ("scene-mesh-is-directory.toml", "mesh-is-a-directory.obj:0: is a directory, not a mesh file"),
    (
        "scene-mesh-not-found.toml",
        "scene-mesh-not-found.toml:3: [mesh].path: `no-such-mesh.obj` does not exist",
    ),
    ("scene-missing-mesh.toml", "missing [mesh] (or [polygon]) table"),
    (
        "scene-negative-density.toml",
        "scene-negative-density.toml:10: [fluid].density: must be >= 0, got -1000",
    ),
    (
        "scene-kernel-exponent-zero.toml",
        "scene-kernel-exponent-zero.toml:7: [ffm].kernel_exponent: must be in [0.5, 6], got 0",
    ),
    (
        "scene-negative-surface-tension.toml",
        "scene-negative-surface-tension.toml:7: [material].surface_tension: must be >= 0, got -1",
    ),
    (
        "scene-plate-cuts-body.toml",
        "scene-plate-cuts-body.toml:12: [[plate]] #1: the plate already cuts the body at rest: vertex 36 is 5e-1 through it",
    ),
    (
        "scene-plate-faces-away.toml",
        "scene-plate-faces-away.toml:12: [[plate]] #1: the plate faces away from the body",
    ),
    (
        "scene-plates-cross.toml",
        "scene-plates-cross.toml: [[plate]] #1 and [[plate]] #2 meet at load factor 0.7500: they face each other",
    ),
    (
        "scene-plate-zero-normal.toml",
        "scene-plate-zero-normal.toml:14: [[plate]] #1.normal: must be finite and non-zero",
    ),
    ("scene-pressure-missing-cavity.toml", "[[pressure]] #1.surface: the body has no cavity 2 (it has 1"),
    ("scene-pressure-empty-box.toml", "[[pressure]] #1.box: selects no face"),
    ("scene-pressure-nan.toml", "[[pressure]] #1.value: must be finite"),
    ("scene-pressure-ffm.toml", "[[pressure]]: a pressure is a load of the finite-element method only"),
    (
        "scene-fem-fixed-on-a-line.toml",
        "scene-fem-fixed-on-a-line.toml: fem: the fixed vertices (2 of them) leave the body free to move: a rotation about the axis",
    ),
    (
        "scene-tissue-young-1e-300.toml",
        "scene-tissue-young-1e-300.toml: fem: the answer is not finite at vertex",
    ),
    ("scene-steps-zero.toml", "scene-steps-zero.toml:10: [load].steps: must be between 1 and 1000000, got 0"),
    (
        "scene-unknown-backend.toml",
        "scene-unknown-backend.toml:14: [solver].backend: `cholmod` is not a backend (expected one of: structured, faer-lu, nalgebra-lu, openblas-lu)",
    ),
    (
        "scene-unknown-key-in-table.toml",
        "scene-unknown-key-in-table.toml:6: [material]: unknown field `youngs`",
    ),
    ("scene-unknown-key-top.toml", "scene-unknown-key-top.toml:2: unknown field `colour`"),
    (
        "scene-unknown-mode.toml",
        "scene-unknown-mode.toml:14: [solver].mode: `implicit` is not a mode (expected one of: paper, refresh, nonlinear)",
    ),
    (
        "scene-wrong-type-steps.toml",
        "scene-wrong-type-steps.toml:10: [load].steps: invalid type: string \"ten\", expected i64",
    ),
    (
        "scene-wrong-type-young.toml",
        "scene-wrong-type-young.toml:6: [material].young: expected a number or an array of three numbers",
    ),
    (
        "scene-young-negative.toml",
        "scene-young-negative.toml:6: [material].young: must be positive, got -5 along y",
    ),
    ("scene-young-zero.toml", "scene-young-zero.toml:6: [material].young: must be positive, got 0 along x"),
    (
        "scene-chainmail-spacing-zero.toml",
        "scene-chainmail-spacing-zero.toml:13: [chainmail].spacing: must be positive, got 0",
    ),
    (
        "scene-chainmail-alpha-order.toml",
        "scene-chainmail-alpha-order.toml:13: [chainmail].alpha_min: must be in (0, 1], got 1.3 along y",
    ),
    (
        "scene-chainmail-nan.toml",
        "scene-chainmail-nan.toml:13: [chainmail].alpha_max: must be >= 1 and finite, got NaN along x",
    ),
    (
        "scene-chainmail-too-fine.toml",
        "scene-chainmail-too-fine.toml: the ChainMail lattice at spacing 0.0001 needs up to 4585375337524584 bytes",
    ),
    (
        "scene-chainmail-unknown-variant.toml",
        "scene-chainmail-unknown-variant.toml:13: [chainmail].variant: `gibson` is not a ChainMail variant (expected one of: tsve, generalized)",
    ),
];

/// Files of the folder that are not bad inputs.
/// (`image-truncated.nii` is the data of `scene-image-truncated.toml`: `mesh-info` reads
/// meshes, not images.)
const NOT_CORPUS: &[&str] = &["README.md", "image-truncated.nii"];

/// Entries that are bad only in a build without a Cargo feature (name, feature compiled in).
/// With the feature they are valid scenes, so the failure is not asked of them.
const BAD_WITHOUT_FEATURE: &[(&str, bool)] =
    &[("scene-backend-not-compiled.toml", cfg!(feature = "openblas"))];

/// What the user had in `--out` before a run.
const KEEP_NAME: &str = "keep.txt";
const KEEP_TEXT: &str = "the user's own notes; no run may touch them\n";

fn corpus_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/bad_inputs").canonicalize().unwrap()
}

fn fixtures_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures").canonicalize().unwrap()
}

/// The corpus entries (files and directories), by name.
fn corpus() -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(corpus_dir())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| !NOT_CORPUS.contains(&n.as_str()))
        .collect();
    names.sort();
    names
}

fn is_scene(name: &str) -> bool {
    name.ends_with(".toml")
}

fn is_chainmail_scene(name: &str) -> bool {
    name.starts_with("scene-chainmail-")
}

/// Runs the binary in `cwd` (a scratch directory, so a stray file would not land in the tree).
fn fibfluid(args: &[&std::ffi::OsStr], cwd: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_fibfluid")).args(args).current_dir(cwd).output().unwrap()
}

/// A `--out` directory inside a fresh parent, holding the user's `keep.txt`.
fn out_with_user_file() -> (tempfile::TempDir, PathBuf) {
    let parent = tempfile::tempdir().unwrap();
    let out = parent.path().join("out");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join(KEEP_NAME), KEEP_TEXT).unwrap();
    (parent, out)
}

/// Names in a directory, sorted.
fn listing(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
    v.sort();
    v
}

/// Problems with a failed run's output: code 2, one `error:` line naming `name` and holding
/// `fragment`, no panic, nothing on stdout.
fn check_failure(name: &str, fragment: &str, out: &Output) -> Vec<String> {
    let mut problems = Vec::new();
    let stderr = String::from_utf8_lossy(&out.stderr);
    let stdout = String::from_utf8_lossy(&out.stdout);
    if out.status.code() != Some(2) {
        problems.push(format!("{name}: exit status {:?}, expected 2", out.status.code()));
    }
    if stderr.contains("panicked") || stdout.contains("panicked") {
        problems.push(format!("{name}: panicked: {stderr}"));
    }
    if !stdout.trim().is_empty() {
        problems.push(format!("{name}: printed on stdout: {stdout}"));
    }
    let lines: Vec<&str> = stderr.lines().collect();
    match lines.as_slice() {
        [line] => {
            if !line.starts_with("error: ") {
                problems.push(format!("{name}: stderr line does not start with `error: `: {line}"));
            }
            if !line.contains(name) {
                problems.push(format!("{name}: the error does not name the file: {line}"));
            }
            if !line.contains(fragment) {
                problems.push(format!("{name}: the error lacks `{fragment}`: {line}"));
            }
        }
        _ => {
            problems.push(format!("{name}: expected exactly one stderr line, got {}: {stderr}", lines.len()))
        }
    }
    problems
}

/// Problems with `--out` after a run: it must hold exactly the user's file, unchanged, and no
/// temporary directory may be left beside it.
fn check_untouched(name: &str, parent: &Path, out: &Path) -> Vec<String> {
    let mut problems = Vec::new();
    if !out.is_dir() {
        return vec![format!("{name}: --out is gone")];
    }
    let inside = listing(out);
    if inside != [KEEP_NAME] {
        problems.push(format!("{name}: --out holds {inside:?}, expected only {KEEP_NAME}"));
    }
    match std::fs::read_to_string(out.join(KEEP_NAME)) {
        Ok(text) if text == KEEP_TEXT => {}
        other => problems.push(format!("{name}: {KEEP_NAME} changed: {other:?}")),
    }
    let beside = listing(parent);
    if beside != ["out"] {
        problems.push(format!("{name}: beside --out: {beside:?} (a temporary directory left behind?)"));
    }
    problems
}

#[test]
fn every_corpus_entry_has_an_expected_message_and_every_expectation_an_entry() {
    let expected: BTreeMap<&str, &str> = EXPECTED.iter().copied().collect();
    assert_eq!(expected.len(), EXPECTED.len(), "a name is listed twice in EXPECTED");
    let names = corpus();
    let missing: Vec<&String> = names.iter().filter(|n| !expected.contains_key(n.as_str())).collect();
    assert!(missing.is_empty(), "corpus entries without an expected message in EXPECTED: {missing:?}");
    let stale: Vec<&&str> = expected.keys().filter(|k| !names.iter().any(|n| n == *k)).collect();
    assert!(stale.is_empty(), "EXPECTED lists entries that are not in tests/bad_inputs/: {stale:?}");
    assert!(names.iter().any(|n| is_scene(n)) && names.iter().any(|n| !is_scene(n)));
    // The README documents every entry too.
    let readme = std::fs::read_to_string(corpus_dir().join("README.md")).unwrap();
    let undocumented: Vec<&String> = names.iter().filter(|n| !readme.contains(&format!("`{n}`"))).collect();
    assert!(undocumented.is_empty(), "entries missing from tests/bad_inputs/README.md: {undocumented:?}");
}

#[test]
fn every_bad_input_gives_one_clean_error_and_writes_nothing() {
    let dir = corpus_dir();
    let expected: BTreeMap<&str, &str> = EXPECTED.iter().copied().collect();
    let mut problems = Vec::new();
    for name in corpus() {
        let Some(fragment) = expected.get(name.as_str()) else {
            problems.push(format!("{name}: no expected message in EXPECTED"));
            continue;
        };
        if BAD_WITHOUT_FEATURE.iter().any(|(n, compiled)| *n == name && *compiled) {
            continue;
        }
        let path = dir.join(&name);
        let (parent, out) = out_with_user_file();
        let output = if is_chainmail_scene(&name) {
            // ChainMail's settings act (and its lattice is sized) only when a ChainMail body
            // is built: probed with a one-frame grab of a free vertex.
            let grab_dir = tempfile::tempdir().unwrap();
            let grab = grab_dir.path().join("grab.csv");
            std::fs::write(&grab, "frame,vertex,ux,uy,uz\n0,2,0,-0.01,0\n").unwrap();
            let args: [&std::ffi::OsStr; 8] = [
                "probe".as_ref(),
                path.as_os_str(),
                "--method".as_ref(),
                "tsve-chainmail".as_ref(),
                "--path".as_ref(),
                grab.as_os_str(),
                "--out".as_ref(),
                out.as_os_str(),
            ];
            fibfluid(&args, parent.path())
        } else if is_scene(&name) {
            fibfluid(&["run".as_ref(), path.as_os_str(), "--out".as_ref(), out.as_os_str()], parent.path())
        } else {
            fibfluid(&["mesh-info".as_ref(), path.as_os_str()], parent.path())
        };
        problems.extend(check_failure(&name, fragment, &output));
        problems.extend(check_untouched(&name, parent.path(), &out));
    }
    assert!(problems.is_empty(), "{} problems:\n{}", problems.len(), problems.join("\n"));
}

#[test]
fn a_good_run_adds_its_outputs_and_keeps_the_users_file() {
    let scene = fixtures_dir().join("scenes/sphere.toml");
    let (parent, out) = out_with_user_file();
    for round in 0..2 {
        // The second round replaces the first round's outputs.
        let output =
            fibfluid(&["run".as_ref(), scene.as_os_str(), "--out".as_ref(), out.as_os_str()], parent.path());
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(output.status.success(), "round {round}: {stderr}");
        let mut want: Vec<String> = fibfluid_cli::OUTPUT_FILES.iter().map(|s| s.to_string()).collect();
        want.push(KEEP_NAME.into());
        want.sort();
        assert_eq!(listing(&out), want, "round {round}");
        for f in fibfluid_cli::OUTPUT_FILES {
            assert!(std::fs::metadata(out.join(f)).unwrap().len() > 0, "round {round}: {f} is empty");
        }
        assert_eq!(std::fs::read_to_string(out.join(KEEP_NAME)).unwrap(), KEEP_TEXT, "round {round}");
        assert_eq!(listing(parent.path()), ["out"], "round {round}: a temporary directory was left");
    }
}

#[test]
fn a_run_that_cannot_place_an_output_moves_none_of_them() {
    // The user has a directory where render.png would go: the run fails, and the outputs
    // written before it must not be left in --out either.
    let scene = fixtures_dir().join("scenes/sphere.toml");
    let (parent, out) = out_with_user_file();
    let blocker = out.join("render.png");
    std::fs::create_dir(&blocker).unwrap();
    std::fs::write(blocker.join("inside.txt"), "x").unwrap();
    let output =
        fibfluid(&["run".as_ref(), scene.as_os_str(), "--out".as_ref(), out.as_os_str()], parent.path());
    let mut problems = check_failure("render.png", "is a directory, where an output file would go", &output);
    if listing(&out) != [KEEP_NAME, "render.png"] {
        problems.push(format!("--out holds {:?}: outputs were moved in part", listing(&out)));
    }
    if listing(&blocker) != ["inside.txt"] {
        problems.push(format!("the user's render.png directory changed: {:?}", listing(&blocker)));
    }
    if std::fs::read_to_string(out.join(KEEP_NAME)).unwrap() != KEEP_TEXT {
        problems.push(format!("{KEEP_NAME} changed"));
    }
    if listing(parent.path()) != ["out"] {
        problems
            .push(format!("beside --out: {:?} (a temporary directory left behind?)", listing(parent.path())));
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// Bad tool paths for `fibfluid probe` on the sphere scene, written on the fly: name,
/// content, and a fragment the one error line must hold (besides the file's name).
const BAD_PATHS: &[(&str, &str, &str)] = &[
    ("path-empty.csv", "frame,vertex,ux,uy,uz\n", "the path is empty"),
    ("path-blank.csv", "", "the path is empty"),
    ("path-bad-header.csv", "time,vertex,ux,uy,uz\n0,36,0,0,0\n", ":1: bad header `time,vertex,ux,uy,uz`"),
    ("path-unknown-vertex.csv", "frame,vertex,ux,uy,uz\n0,500,0,0,0\n", ":2: vertex 500 does not exist"),
    (
        "path-fixed-vertex.csv",
        "frame,vertex,ux,uy,uz\n0,36,0,0,0\n1,0,0,0.1,0\n",
        ":3: vertex 0 is fixed along x by the scene and cannot be grabbed",
    ),
    (
        "path-force-on-fixed.csv",
        "frame,vertex,fx,fy,fz\n0,0,1,1,1\n",
        ":2: vertex 0 is fixed along x by the scene and cannot be pushed",
    ),
    ("path-not-a-number.csv", "frame,vertex,ux,uy,uz\n0,36,abc,0,0\n", ":2: ux: `abc` is not a number"),
    ("path-nan.csv", "frame,vertex,ux,uy,uz\n0,36,0,NaN,0\n", ":2: uy: NaN is not finite"),
    ("path-infinite.csv", "frame,vertex,fx,fy,fz\n0,36,0,0,inf\n", ":2: fz: inf is not finite"),
    (
        "path-decreasing-frames.csv",
        "frame,vertex,ux,uy,uz\n0,36,0,0,0\n2,36,0,0,0\n1,36,0,0,0\n",
        ":4: frame 1 comes after frame 2",
    ),
    (
        "path-negative-frame.csv",
        "frame,vertex,ux,uy,uz\n-1,36,0,0,0\n",
        ":2: frame: `-1` is not a frame number",
    ),
    (
        "path-negative-vertex.csv",
        "frame,vertex,ux,uy,uz\n0,-3,0,0,0\n",
        ":2: vertex: `-3` is not a vertex index",
    ),
    (
        "path-field-count.csv",
        "frame,vertex,ux,uy,uz\n0,36,0,0\n",
        ":2: expected 5 comma-separated fields, found 4",
    ),
    (
        "path-duplicate-vertex.csv",
        "frame,vertex,ux,uy,uz\n0,36,0,0,0\n0,36,0,0.1,0\n",
        ":3: vertex 36 appears twice in frame 0 (first on line 2)",
    ),
    ("path-values-without-vertex.csv", "frame,vertex,ux,uy,uz\n0,,1,0,0\n", ":2: a row without a vertex"),
    (
        "path-grasp-larger-than-the-body.csv",
        "frame,vertex,ux,uy,uz,radius\n0,36,0,-0.1,0,0.1\n1,36,0,-0.1,0,5\n",
        ":3: frame 1: a tool of radius 5 m is larger than the body (its bounding-box diagonal is",
    ),
    (
        "path-press-larger-than-the-body.csv",
        "frame,x,y,z,radius\n0,0,-1.5,0,5\n",
        ":2: frame 0: a tool of radius 5 m is larger than the body (its bounding-box diagonal is",
    ),
    (
        "path-overlapping-grasps.csv",
        "frame,vertex,ux,uy,uz,radius\n0,36,0,-0.1,0,0.3\n0,122,0,-0.1,0,0.3\n",
        ":3: frame 0: the grasps around vertices 36 (line 2) and 122 both hold vertex",
    ),
    (
        "path-huge-frame.csv",
        "frame,vertex,ux,uy,uz\n99999999999,36,0,0,0\n",
        ":2: frame 99999999999 is beyond the largest allowed frame number",
    ),
];

#[test]
fn every_bad_probe_path_gives_one_clean_error_and_writes_nothing() {
    let scene = fixtures_dir().join("scenes/sphere.toml");
    let dir = tempfile::tempdir().unwrap();
    let mut problems = Vec::new();
    for (name, content, fragment) in BAD_PATHS {
        let path = dir.path().join(name);
        std::fs::write(&path, content).unwrap();
        let (parent, out) = out_with_user_file();
        let output = fibfluid(
            &[
                "probe".as_ref(),
                scene.as_os_str(),
                "--path".as_ref(),
                path.as_os_str(),
                "--out".as_ref(),
                out.as_os_str(),
            ],
            parent.path(),
        );
        problems.extend(check_failure(name, fragment, &output));
        problems.extend(check_untouched(name, parent.path(), &out));
    }
    // A precompute over the memory budget is refused with the bytes it needs; a bad
    // --precision, --precompute or --method names the flag.
    let good = fixtures_dir().join("paths/sphere-poke.csv");
    for (flag, value, name, fragment) in [
        ("--max-memory", "1000", "sphere.toml", "bytes (0.00 GiB) at its peak, but only 1000 bytes"),
        ("--precision", "f16", "--precision", "`f16` is not a storage precision (expected one of: f64, f32)"),
        (
            "--precompute",
            "eager",
            "--precompute",
            "`eager` is not a precompute (expected one of: full, lazy)",
        ),
        (
            "--method",
            "gibson",
            "--method",
            "`gibson` is not a method (expected one of: ffm, tsve-chainmail, generalized-chainmail, fem)",
        ),
    ] {
        let (parent, out) = out_with_user_file();
        let output = fibfluid(
            &[
                "probe".as_ref(),
                scene.as_os_str(),
                "--path".as_ref(),
                good.as_os_str(),
                "--out".as_ref(),
                out.as_os_str(),
                flag.as_ref(),
                value.as_ref(),
            ],
            parent.path(),
        );
        problems.extend(check_failure(name, fragment, &output));
        problems.extend(check_untouched(name, parent.path(), &out));
    }
    assert!(problems.is_empty(), "{} problems:\n{}", problems.len(), problems.join("\n"));
}

/// One run of the binary and the problems with its failure: exit 2, one `error:` line that
/// contains every fragment, no panic.
fn one_line_failure(args: &[&std::ffi::OsStr], fragments: &[&str]) -> Vec<String> {
    let dir = tempfile::tempdir().unwrap();
    let out = fibfluid(args, dir.path());
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    let mut problems = Vec::new();
    let what = format!("{:?}", args);
    if out.status.code() != Some(2) {
        problems.push(format!("{what}: exit {:?}, expected 2: {stderr}", out.status.code()));
    }
    let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error: ")).collect();
    if errors.len() != 1 || stderr.contains("panicked") {
        problems.push(format!("{what}: expected one error line, got: {stderr}"));
    }
    for f in fragments {
        if !stderr.contains(f) {
            problems.push(format!("{what}: the error lacks `{f}`: {stderr}"));
        }
    }
    if stderr.len() > 600 {
        problems.push(format!("{what}: a {}-byte error is not one line a user can read", stderr.len()));
    }
    problems
}

#[test]
fn a_closed_stdout_is_a_normal_end() {
    let scene = fixtures_dir().join("scenes/sphere.toml");
    let mesh = fixtures_dir().join("meshes/liver2.obj");
    let runs: [Vec<&std::ffi::OsStr>; 3] = [
        vec!["plan".as_ref(), scene.as_os_str()],
        vec!["mesh-info".as_ref(), mesh.as_os_str()],
        vec!["icosphere".as_ref(), "--level".as_ref(), "9".as_ref()],
    ];
    for args in runs {
        let (reader, writer) = std::io::pipe().unwrap();
        drop(reader);
        let out = Command::new(env!("CARGO_BIN_EXE_fibfluid"))
            .args(&args)
            .stdout(writer)
            .stderr(std::process::Stdio::piped())
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
        assert!(matches!(out.status.code(), Some(0) | Some(2)), "{args:?}: {:?} {stderr}", out.status.code());
    }
}

#[test]
fn hostile_path_files_and_flags_get_one_line() {
    let scene = fixtures_dir().join("scenes/sphere.toml");
    let rectangle = fixtures_dir().join("scenes/rectangle.toml");
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("fifo.csv");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let long_header = dir.path().join("long-header.csv");
    std::fs::write(&long_header, "x".repeat(200_000) + "\n0,1,0,0,0\n").unwrap();
    let far = dir.path().join("far.csv");
    std::fs::write(&far, "frame,vertex,ux,uy,uz\n0,36,0,1e308,0\n").unwrap();
    let many = dir.path().join("many-frames.csv");
    std::fs::write(&many, "frame,vertex,ux,uy,uz\n0,36,0,-0.1,0\n1000000,,,,\n").unwrap();
    let big = dir.path().join("big.csv");
    std::fs::write(&big, "frame,vertex,ux,uy,uz\n".to_string() + &"0,36,0,-0.1,0\n".repeat(2000)).unwrap();
    let out = dir.path().join("out");
    let probe = |path: &Path| -> Vec<&std::ffi::OsStr> {
        let mut v: Vec<&std::ffi::OsStr> = vec!["probe".as_ref(), scene.as_os_str(), "--path".as_ref()];
        v.push(path.as_os_str().to_owned().leak());
        v.extend(["--out".as_ref(), out.as_os_str()]);
        v
    };
    let mut problems = Vec::new();
    problems.extend(one_line_failure(&probe(Path::new("/dev/zero")), &["/dev/zero", "not a regular file"]));
    problems.extend(one_line_failure(&probe(&fifo), &["fifo.csv", "not a regular file"]));
    problems.extend(one_line_failure(&probe(&long_header), &["long-header.csv:1", "bad header"]));
    problems.extend(one_line_failure(&probe(&far), &["far.csv:2", "more than"]));
    let mut capped = vec!["--max-file-bytes".as_ref(), "20000".as_ref()];
    capped.extend(probe(&big));
    problems.extend(one_line_failure(&capped, &["big.csv"]));
    let compare: Vec<&std::ffi::OsStr> = vec![
        "compare".as_ref(),
        scene.as_os_str(),
        "--path".as_ref(),
        many.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
        "--max-memory".as_ref(),
        "100000000".as_ref(),
    ];
    problems.extend(one_line_failure(&compare, &["many-frames.csv", "1000001 frames", "use fewer frames"]));
    problems.extend(one_line_failure(
        &["view".as_ref(), rectangle.as_os_str()],
        &["rectangle.toml", "2D polygon"],
    ));
    problems.extend(one_line_failure(
        &["icosphere".as_ref(), "--level".as_ref(), "9".as_ref(), "--out".as_ref(), out.as_os_str()],
        &["at most 7 (163842 vertices"],
    ));
    assert!(problems.is_empty(), "{} problems:\n{}", problems.len(), problems.join("\n"));
    assert!(!out.exists(), "a refused command wrote {}", out.display());
}

/// The seconds a refusal from the rest shape may take, process start included: far less than
/// building the body of [`a_tool_larger_than_the_body_is_refused_before_the_body_is_built`]
/// (a probe with the FEM at resolution 40 on the sphere took 14 s on a busy 2-core machine).
const REFUSED_BEFORE_BUILD_SECONDS: f64 = 2.0;

#[test]
fn a_tool_larger_than_the_body_is_refused_before_the_body_is_built() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = fixtures_dir().join("meshes/icosphere-2.obj");
    let scene = dir.path().join("sphere-fem.toml");
    let toml = format!(
        "[mesh]\npath = {:?}\n[tissue]\nyoung = 5000.0\npoisson = 0.45\ndensity = 1000.0\n[[fix]]\naxis = \"y\"\nabove = 0.8\n[fem]\nresolution = 40\n[solver]\nmode = \"paper\"\n",
        mesh.display().to_string()
    );
    std::fs::write(&scene, toml).unwrap();
    let mut problems = Vec::new();
    for (name, content) in [
        ("grasp-5m.csv", "frame,vertex,ux,uy,uz,radius\n0,36,0,-0.1,0,5\n"),
        ("press-5m.csv", "frame,x,y,z,radius\n0,0,-1.5,0,5\n"),
    ] {
        let path = dir.path().join(name);
        std::fs::write(&path, content).unwrap();
        let (parent, out) = out_with_user_file();
        let start = std::time::Instant::now();
        let output = fibfluid(
            &[
                "probe".as_ref(),
                scene.as_os_str(),
                "--path".as_ref(),
                path.as_os_str(),
                "--out".as_ref(),
                out.as_os_str(),
                "--method".as_ref(),
                "fem".as_ref(),
            ],
            parent.path(),
        );
        let seconds = start.elapsed().as_secs_f64();
        problems.extend(check_failure(
            name,
            ":2: frame 0: a tool of radius 5 m is larger than the body",
            &output,
        ));
        problems.extend(check_untouched(name, parent.path(), &out));
        if seconds > REFUSED_BEFORE_BUILD_SECONDS {
            problems.push(format!("{name}: refused after {seconds:.2} s: the body was built first"));
        }
    }
    assert!(problems.is_empty(), "{} problems:\n{}", problems.len(), problems.join("\n"));
}

#[test]
fn an_output_path_that_is_a_file_is_refused_before_the_run() {
    // Both runs fail in the engine (the FEM on its constraints, FFM on a memory budget of one
    // byte): the output path must be refused first, so the message is about the file.
    let scenes = [
        (corpus_dir().join("scene-fem-fixed-on-a-line.toml"), None),
        (fixtures_dir().join("scenes/sphere.toml"), Some("1")),
    ];
    for (scene, budget) in scenes {
        let parent = tempfile::tempdir().unwrap();
        let out = parent.path().join("results.txt");
        std::fs::write(&out, KEEP_TEXT).unwrap();
        let mut args: Vec<&std::ffi::OsStr> =
            vec!["run".as_ref(), scene.as_os_str(), "--out".as_ref(), out.as_os_str()];
        if let Some(b) = budget {
            args.push("--max-memory".as_ref());
            args.push(b.as_ref());
        }
        let output = fibfluid(&args, parent.path());
        let problems = check_failure("results.txt", "exists and is not a directory", &output);
        let name = scene.display();
        assert!(problems.is_empty(), "{name}: {}", problems.join("\n"));
        assert_eq!(std::fs::read_to_string(&out).unwrap(), KEEP_TEXT, "{name}: the user's file changed");
        assert_eq!(listing(parent.path()), ["results.txt"], "{name}: something was left beside it");
    }
}

/// `bench --two-rate` and `--path` go together: either alone gets one line naming the flag
/// that is missing (not clap's empty or repeated list of required arguments).
#[test]
fn bench_two_rate_without_its_pair_names_the_missing_flag() {
    let problems: Vec<String> = [
        (["bench", "--path", "grab.csv"], ["--path grab.csv", "needs --two-rate SCENE"]),
        (["bench", "--two-rate", "scene.toml"], ["--two-rate scene.toml", "needs --path FILE"]),
    ]
    .iter()
    .flat_map(|(args, fragments)| {
        let args: Vec<&std::ffi::OsStr> = args.iter().map(|a| a.as_ref()).collect();
        let mut p = one_line_failure(&args, fragments);
        let out = fibfluid(&args, &std::env::temp_dir());
        let stderr = String::from_utf8_lossy(&out.stderr).to_string();
        if stderr.lines().count() != 1 {
            p.push(format!("{args:?}: more than one line: {stderr}"));
        }
        p
    })
    .collect();
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// A `[[region]]` mesh entirely outside the body is refused naming the scene file and the
/// region's mesh file (a cube from 5 to 6 beside a unit sphere).
#[test]
fn a_region_mesh_outside_the_body_is_refused_naming_its_file() {
    let dir = tempfile::tempdir().unwrap();
    let mut cube = String::new();
    for k in 0..8 {
        let c = |bit: usize| if k & bit == 0 { 5.0 } else { 6.0 };
        cube.push_str(&format!("v {} {} {}\n", c(1), c(2), c(4)));
    }
    for f in [
        [1, 3, 4],
        [1, 4, 2],
        [5, 6, 8],
        [5, 8, 7],
        [1, 2, 6],
        [1, 6, 5],
        [3, 7, 8],
        [3, 8, 4],
        [1, 5, 7],
        [1, 7, 3],
        [2, 4, 8],
        [2, 8, 6],
    ] {
        cube.push_str(&format!("f {} {} {}\n", f[0], f[1], f[2]));
    }
    std::fs::write(dir.path().join("far-lesion.obj"), cube).unwrap();
    let sphere = fixtures_dir().join("meshes/icosphere-2.obj");
    let scene = dir.path().join("far-region.toml");
    std::fs::write(
        &scene,
        format!(
            "[mesh]\npath = \"{}\"\n\n[tissue]\nyoung = 5000.0\npoisson = 0.45\ndensity = 1000.0\n\n\
             [fem]\nresolution = 8\n\n[[region]]\nmesh = \"far-lesion.obj\"\n\n[region.tissue]\n\
             young = 20000.0\npoisson = 0.45\n\n[[fix]]\naxis = \"y\"\nbelow = 0.01\n\n\
             [solver]\nmethod = \"fem\"\n",
            sphere.display()
        ),
    )
    .unwrap();
    let out = dir.path().join("out");
    let problems = one_line_failure(
        &["run".as_ref(), scene.as_os_str(), "--out".as_ref(), out.as_os_str()],
        &["far-region.toml", "region 1 (mesh far-lesion.obj) lies outside the body"],
    );
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}
