//! Every entry of `tests/bad_inputs/` is fed to the real binary (`mesh-info` for meshes,
//! `run --out DIR` for scenes): it must exit with code 2 and print exactly one `error:`
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
    ("mesh-inconsistent-orientation.obj", "faces around edge (0, 2) are inconsistently oriented"),
    ("mesh-index-out-of-range.obj", ":9: face refers to vertex 9 but the file has 4 vertices"),
    ("mesh-index-zero.obj", ":6: face index 0 (OBJ indices start at 1)"),
    ("mesh-is-a-directory.obj", "is a directory, not a mesh file"),
    ("mesh-nan.obj", ":4: vertex 2 has a non-finite coordinate"),
    ("mesh-negative-index.obj", ":9: relative face index -5 points before the first vertex"),
    ("mesh-non-manifold-edge.obj", "edge (0, 1) is shared by 4 faces (non-manifold)"),
    ("mesh-open.obj", "the surface is open"),
    ("mesh-single-triangle.obj", "the surface is open: 3 boundary edges"),
    ("mesh-truncated-facet.stl", ":12: the last facet has fewer than 3 vertices"),
    ("mesh-two-tetrahedra.obj", "2 disconnected components"),
    ("mesh-unknown-extension.ply", "unsupported mesh format"),
    (
        "scene-backend-not-compiled.toml",
        "[solver].backend: backend `openblas-lu` is not compiled into this build; rebuild with `cargo build --features openblas` (needs the system OpenBLAS",
    ),
    ("scene-bad-mesh.toml", "[mesh].path: "),
    ("scene-fix-nothing-along-z.toml", "no vertex is fixed along z"),
    ("scene-fix-selects-nothing.toml", "[[fix]] #1: constraint `y > 5` selects no vertex"),
    ("scene-fix-vertex-out-of-range.toml", "[[fix]] #1.vertices: vertex 100 is out of range"),
    ("scene-force-vertex-out-of-range.toml", "[[force]] #1.vertex: vertex 42 is out of range"),
    ("scene-is-a-directory.toml", "is a directory, not a scene file"),
    ("scene-malformed.toml", "unclosed table, expected `]` (line 2, column 6)"),
    ("scene-mesh-is-directory.toml", "mesh-is-a-directory.obj:0: is a directory, not a mesh file"),
    ("scene-mesh-not-found.toml", "[mesh].path: `no-such-mesh.obj` does not exist"),
    ("scene-missing-mesh.toml", "missing [mesh] (or [polygon]) table"),
    ("scene-negative-density.toml", "[fluid].density: must be >= 0, got -1000"),
    ("scene-negative-surface-tension.toml", "[material].surface_tension: must be >= 0, got -1"),
    ("scene-steps-zero.toml", "[load].steps: must be between 1 and 1000000, got 0"),
    ("scene-unknown-backend.toml", "[solver].backend: unknown backend `cholmod` (compiled in: structured"),
    ("scene-unknown-key-in-table.toml", "[material]: unknown field `youngs`"),
    ("scene-unknown-key-top.toml", "unknown field `colour`"),
    ("scene-unknown-mode.toml", "[solver].mode: `implicit` is not paper, refresh or nonlinear"),
    ("scene-wrong-type-steps.toml", "[load].steps: invalid type: string \"ten\", expected i64"),
    ("scene-wrong-type-young.toml", "[material].young: expected a number or an array of three numbers"),
    ("scene-young-negative.toml", "[material].young: must be positive, got -5 along y"),
    ("scene-young-zero.toml", "[material].young: must be positive, got 0 along x"),
];

/// Files of the folder that are not bad inputs.
const NOT_CORPUS: &[&str] = &["README.md"];

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
        let output = if is_scene(&name) {
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
        let mut want: Vec<String> = fibfluid::OUTPUT_FILES.iter().map(|s| s.to_string()).collect();
        want.push(KEEP_NAME.into());
        want.sort();
        assert_eq!(listing(&out), want, "round {round}");
        for f in fibfluid::OUTPUT_FILES {
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

// ---------------------------------------------------------------------------------------
// Inputs that are not files in the corpus: special files made at test time, flags, limits.
// ---------------------------------------------------------------------------------------

/// Longest any one invocation may take: a reader blocked on a FIFO or reading /dev/zero
/// would otherwise hang the test instead of failing it.
const INVOCATION_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(60);

/// Runs `program args` in `cwd` with extra environment variables, killing it (and failing
/// the test) when it runs past [`INVOCATION_TIMEOUT`].
fn run_program(program: &Path, args: &[&std::ffi::OsStr], cwd: &Path, envs: &[(&str, &str)]) -> Output {
    let child = Command::new(program)
        .args(args)
        .current_dir(cwd)
        .envs(envs.iter().copied())
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let pid = child.id();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(child.wait_with_output());
    });
    match rx.recv_timeout(INVOCATION_TIMEOUT) {
        Ok(output) => output.unwrap(),
        Err(_) => {
            let _ = Command::new("kill").arg("-9").arg(pid.to_string()).status();
            panic!("{} {args:?} did not finish within {INVOCATION_TIMEOUT:?} (a hang)", program.display());
        }
    }
}

/// The binary with extra environment variables, under the timeout.
fn fibfluid_env(args: &[&std::ffi::OsStr], cwd: &Path, envs: &[(&str, &str)]) -> Output {
    run_program(Path::new(env!("CARGO_BIN_EXE_fibfluid")), args, cwd, envs)
}

/// Backtraces off: when an allocation that is not fallible fails under `ulimit -v`, std's
/// out-of-memory hook can deadlock while printing one; this way it aborts and the test fails.
const NO_BACKTRACE: &[(&str, &str)] = &[("RUST_BACKTRACE", "0")];

/// The binary under `ulimit -v kib` (address space), through `sh`.
fn fibfluid_ulimit(kib: u64, args: &[&std::ffi::OsStr], cwd: &Path, envs: &[(&str, &str)]) -> Output {
    let script = format!("ulimit -v {kib} && exec \"$0\" \"$@\"");
    let mut all: Vec<&std::ffi::OsStr> =
        vec!["-c".as_ref(), script.as_ref(), env!("CARGO_BIN_EXE_fibfluid").as_ref()];
    all.extend_from_slice(args);
    run_program(Path::new("sh"), &all, cwd, envs)
}

fn os(s: &str) -> &std::ffi::OsStr {
    s.as_ref()
}

fn mkfifo(path: &Path) {
    let status = Command::new("mkfifo").arg(path).status().expect("mkfifo (coreutils) must be installed");
    assert!(status.success(), "mkfifo {}", path.display());
}

/// Fails with every problem found.
fn assert_no_problems(problems: Vec<String>) {
    assert!(problems.is_empty(), "{} problems:\n{}", problems.len(), problems.join("\n"));
}

/// A scene on the 42-vertex icosphere (y up) with extra TOML appended.
fn small_scene(extra: &str) -> String {
    let mesh = fixtures_dir().join("meshes/icosphere-1.obj");
    format!(
        "[mesh]\npath = {:?}\n\n[material]\nyoung = 3000.0\nsurface_tension = 300.0\n\n[[fix]]\naxis = \"y\"\nabove = 0.8\n{extra}",
        mesh.display().to_string()
    )
}

/// A FIFO, a link to one, `/dev/zero` and a link to it, as a mesh and as a scene: each is
/// refused from its metadata before it is opened (the reader would block forever on the
/// FIFO and fill memory from /dev/zero), with one line saying what it is.
#[test]
fn special_files_are_refused_before_they_are_read() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    mkfifo(&d.join("pipe.obj"));
    mkfifo(&d.join("pipe.toml"));
    std::os::unix::fs::symlink(d.join("pipe.obj"), d.join("link-to-pipe.obj")).unwrap();
    std::os::unix::fs::symlink("/dev/zero", d.join("zero.obj")).unwrap();
    let scene = small_scene("").replace(
        &format!("{:?}", fixtures_dir().join("meshes/icosphere-1.obj").display().to_string()),
        "\"zero.obj\"",
    );
    assert!(scene.contains("path = \"zero.obj\""), "{scene}");
    std::fs::write(d.join("zero-mesh.toml"), scene).unwrap();

    let fifo = "is a FIFO (named pipe), not a regular file";
    let device = "is a character device, not a regular file";
    let mut problems = Vec::new();
    for (file, fragment) in
        [("pipe.obj", fifo), ("link-to-pipe.obj", fifo), ("zero.obj", device), ("/dev/zero", device)]
    {
        let output = fibfluid_env(&[os("mesh-info"), os(file)], d, &[]);
        problems.extend(check_failure(file, &format!("{file}: {fragment}"), &output));
    }
    for (file, fragment) in [
        ("pipe.toml", format!("pipe.toml: {fifo}")),
        ("zero-mesh.toml", format!("[mesh].path: {}: {device}", d.join("zero.obj").display())),
    ] {
        let (parent, out) = out_with_user_file();
        let output =
            fibfluid_env(&[os("run"), d.join(file).as_os_str(), os("--out"), out.as_os_str()], d, &[]);
        problems.extend(check_failure(file, &fragment, &output));
        problems.extend(check_untouched(file, parent.path(), &out));
    }
    assert_no_problems(problems);
}

/// The size limit is stated in the error with how to raise it; the flag beats the variable.
#[test]
fn the_file_size_limit_is_stated_and_can_be_raised() {
    let mesh = fixtures_dir().join("meshes/icosphere-1.obj");
    let scene = fixtures_dir().join("scenes/sphere.toml");
    let (mesh_len, scene_len) =
        (std::fs::metadata(&mesh).unwrap().len(), std::fs::metadata(&scene).unwrap().len());
    assert!(mesh_len > 2048 && scene_len > 100, "the cases below assume these sizes");
    let cwd = tempfile::tempdir().unwrap();
    let raise = "raise it with --max-file-bytes or FIBFLUID_MAX_FILE_BYTES";
    let mut problems = Vec::new();
    // (flags, environment, expected fragment)
    type Case<'a> = (&'a [&'a str], &'a [(&'a str, &'a str)], String);
    let cases: [Case; 3] = [
        (
            &["--max-file-bytes", "1K"],
            &[],
            format!("is {mesh_len} bytes, more than the limit of 1 KiB; {raise}"),
        ),
        (
            &[],
            &[("FIBFLUID_MAX_FILE_BYTES", "2000")],
            format!("is {mesh_len} bytes, more than the limit of 2000 bytes"),
        ),
        (
            &[],
            &[("FIBFLUID_MAX_FILE_BYTES", "lots")],
            "FIBFLUID_MAX_FILE_BYTES = `lots` is not a byte count".into(),
        ),
    ];
    for (flags, envs, fragment) in &cases {
        let mut args: Vec<&std::ffi::OsStr> = flags.iter().map(|f| os(f)).collect();
        args.extend([os("mesh-info"), mesh.as_os_str()]);
        problems.extend(check_failure("icosphere-1.obj", fragment, &fibfluid_env(&args, cwd.path(), envs)));
    }
    // The scene file itself is under the limit too.
    let (parent, out) = out_with_user_file();
    let output = fibfluid_env(
        &[os("run"), scene.as_os_str(), os("--out"), out.as_os_str(), os("--max-file-bytes"), os("100")],
        parent.path(),
        &[],
    );
    problems.extend(check_failure(
        "sphere.toml",
        &format!("is {scene_len} bytes, more than the limit of 100 bytes"),
        &output,
    ));
    problems.extend(check_untouched("sphere.toml", parent.path(), &out));
    // The flag overrides the variable.
    let output = fibfluid_env(
        &[os("--max-file-bytes"), os("1M"), os("mesh-info"), mesh.as_os_str()],
        cwd.path(),
        &[("FIBFLUID_MAX_FILE_BYTES", "100")],
    );
    if !output.status.success() {
        problems.push(format!(
            "--max-file-bytes 1M did not override the variable: {}",
            String::from_utf8_lossy(&output.stderr)
        ));
    }
    assert_no_problems(problems);
}

/// A UTF-8 byte-order mark before the first line of an OBJ or a scene is skipped, and that
/// line is still line 1.
#[test]
fn a_byte_order_mark_is_not_part_of_the_first_line() {
    const BOM: &[u8] = b"\xEF\xBB\xBF";
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let text = std::fs::read(fixtures_dir().join("meshes/icosphere-1.obj")).unwrap();
    // The premise: the mark lands in front of vertex 0 (the old reader lost that vertex).
    assert!(text.starts_with(b"v "), "icosphere-1.obj should start with a vertex line");
    std::fs::write(d.join("bom.obj"), [BOM, &text].concat()).unwrap();
    let output = fibfluid_env(&[os("mesh-info"), os("bom.obj"), os("--json")], d, &[]);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let v: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    // The level-1 icosphere: 12 + 30 edge midpoints = 42 vertices, 80 faces.
    assert_eq!(
        (v["vertices"].as_u64(), v["file_vertices"].as_u64(), v["faces"].as_u64()),
        (Some(42), Some(42), Some(80))
    );

    // An error on the first line is reported on line 1.
    std::fs::write(d.join("bom-bad.obj"), [BOM, b"v 0 0\n".as_slice()].concat()).unwrap();
    let output = fibfluid_env(&[os("mesh-info"), os("bom-bad.obj")], d, &[]);
    let mut problems =
        check_failure("bom-bad.obj", "bom-bad.obj:1: vertex has 2 coordinates, 3 expected", &output);

    // Scenes: a good one runs, a bad first line is line 1.
    std::fs::write(d.join("bom.toml"), [BOM, small_scene("").as_bytes()].concat()).unwrap();
    let output = fibfluid_env(&[os("roundtrip"), os("bom.toml"), os("--json")], d, &[]);
    if !output.status.success() {
        problems.push(format!("bom.toml: {}", String::from_utf8_lossy(&output.stderr)));
    }
    std::fs::write(d.join("bom-bad.toml"), [BOM, b"[mesh\n".as_slice()].concat()).unwrap();
    let (parent, out) = out_with_user_file();
    let output =
        fibfluid_env(&[os("run"), d.join("bom-bad.toml").as_os_str(), os("--out"), out.as_os_str()], d, &[]);
    problems.extend(check_failure("bom-bad.toml", "(line 1, column 6)", &output));
    problems.extend(check_untouched("bom-bad.toml", parent.path(), &out));
    assert_no_problems(problems);
}

/// `--threads 0` is an error, a huge count is lowered with a one-line note (it used to
/// panic or spend minutes creating threads), and a pool whose threads cannot start is a
/// clean error.
#[test]
fn thread_counts_are_checked_clamped_or_refused_cleanly() {
    let mesh = fixtures_dir().join("meshes/icosphere-1.obj");
    let cwd = tempfile::tempdir().unwrap();
    let mut problems = Vec::new();
    let output =
        fibfluid_env(&[os("--threads"), os("0"), os("mesh-info"), mesh.as_os_str()], cwd.path(), &[]);
    problems.extend(check_failure(
        "--threads 0",
        "--threads 0: the thread count must be at least 1",
        &output,
    ));

    let cap = (std::thread::available_parallelism().unwrap().get() * 4).min(1024);
    let output =
        fibfluid_env(&[os("--threads"), os("100000"), os("mesh-info"), mesh.as_os_str()], cwd.path(), &[]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    let note = format!("note: --threads 100000 lowered to {cap} (4 per available core, at most 1024)");
    if !output.status.success() || stderr.trim() != note {
        problems.push(format!(
            "--threads 100000: status {:?}, stderr {stderr:?}, expected {note:?}",
            output.status.code()
        ));
    }

    // Each rayon thread asks for a 4 GiB stack (RUST_MIN_STACK) under a 1 GiB address-space
    // limit: the system refuses the thread.
    let output = fibfluid_ulimit(
        1 << 20,
        &[os("--threads"), os("2"), os("mesh-info"), mesh.as_os_str()],
        cwd.path(),
        &[("RUST_MIN_STACK", "4294967296"), NO_BACKTRACE[0]],
    );
    problems.extend(check_failure("--threads 2", "--threads 2: cannot start a pool of 2 threads: ", &output));
    assert_no_problems(problems);
}

/// An `--out` that cannot be created is named as the user gave it, never as the temporary
/// directory beside it.
#[test]
fn an_unwritable_out_is_named_as_given() {
    let scene = fixtures_dir().join("scenes/sphere.toml");
    let cwd = tempfile::tempdir().unwrap();
    let mut problems = Vec::new();
    for out in ["/proc/fibfluid-out", "/proc/fibfluid-out/deeper"] {
        let output = fibfluid_env(&[os("run"), scene.as_os_str(), os("--out"), os(out)], cwd.path(), &[]);
        problems.extend(check_failure(
            out,
            &format!("error: {out}: cannot write the outputs here: "),
            &output,
        ));
        if String::from_utf8_lossy(&output.stderr).contains("fibfluid-tmp") {
            problems.push(format!("{out}: the error names the temporary directory"));
        }
    }
    assert_no_problems(problems);
}

/// A known backend left out of this build says which feature builds it; an unknown name
/// says it is unknown. Both on the command line and in a scene.
#[test]
fn a_backend_left_out_of_the_build_says_how_to_enable_it() {
    let scene = fixtures_dir().join("scenes/sphere.toml");
    let compiled = fibfluid::linalg::backend_names();
    let mut problems = Vec::new();
    let mut cases: Vec<(String, String)> = fibfluid::linalg::KNOWN_BACKENDS
        .iter()
        .filter(|(name, _, _)| !compiled.contains(name))
        .map(|(name, feature, _)| {
            (
                name.to_string(),
                format!(
                    "--backend: backend `{name}` is not compiled into this build; rebuild with `cargo build --features {feature}`"
                ),
            )
        })
        .collect();
    // The default build leaves OpenBLAS out: at least that case runs there.
    assert!(cfg!(feature = "openblas") || !cases.is_empty());
    cases.push(("cholmod".into(), "--backend: unknown backend `cholmod` (compiled in: structured".into()));
    for (name, fragment) in cases {
        let (parent, out) = out_with_user_file();
        let output = fibfluid_env(
            &[os("run"), scene.as_os_str(), os("--out"), out.as_os_str(), os("--backend"), os(&name)],
            parent.path(),
            &[],
        );
        problems.extend(check_failure(&name, &fragment, &output));
        problems.extend(check_untouched(&name, parent.path(), &out));
    }
    assert_no_problems(problems);
}

/// A dense backend whose matrix cannot be allocated (an address-space limit) gives a clean
/// error naming the bytes, not an abort (exit 134); under the same limit the structured
/// backend, which never forms the dense matrix, runs.
#[test]
fn a_dense_matrix_that_cannot_be_allocated_is_an_error_not_an_abort() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let made = fibfluid_env(&[os("icosphere"), os("--level"), os("4"), os("--out"), os("ico4.obj")], d, &[]);
    assert!(made.status.success(), "{}", String::from_utf8_lossy(&made.stderr));
    // 10 * 4^4 + 2 = 2562 vertices: the dense system is (3 * 2562 + 1)^2 f64 values.
    let dim: u64 = 3 * 2562 + 1;
    let bytes = dim * dim * 8;
    // Enough for the structured run, not for `bytes` more (OpenBLAS, when linked, reserves
    // its own buffers at start-up). Measured: the structured run needs under 400 MiB (under
    // 500 MiB with OpenBLAS); a dense one at least 170 MiB before the matrix.
    let limit_kib = if cfg!(feature = "openblas") { 550 } else { 450 } * 1024;
    assert!(limit_kib < 170 * 1024 + bytes / 1024, "the limit must leave no room for the matrix");
    let scene = |backend: &str| {
        format!(
            "[mesh]\npath = \"ico4.obj\"\n[material]\nyoung = 3000.0\n[[fix]]\naxis = \"y\"\nabove = 0.9\n[[force]]\nvertex = 3\nvalue = [0.0, -1.0, 0.0]\n[solver]\nbackend = \"{backend}\"\n"
        )
    };
    let mut problems = Vec::new();
    let dense: Vec<&str> =
        fibfluid::linalg::backend_names().into_iter().filter(|b| *b != "structured").collect();
    for backend in dense {
        let file = format!("dense-{backend}.toml");
        std::fs::write(d.join(&file), scene(backend)).unwrap();
        let (parent, out) = out_with_user_file();
        let output = fibfluid_ulimit(
            limit_kib,
            &[os("--threads"), os("1"), os("run"), d.join(&file).as_os_str(), os("--out"), out.as_os_str()],
            d,
            NO_BACKTRACE,
        );
        // Refused up front when the machine's free memory is below twice the matrix; else
        // the allocation itself fails under the limit.
        let free = fibfluid::linalg::available_memory_bytes().unwrap_or(0) as f64;
        let fragment = if free * fibfluid::linalg::DENSE_MEMORY_FRACTION > 2.0 * bytes as f64 {
            format!("linear solver: cannot allocate {bytes} bytes")
        } else {
            "use the `structured` backend".to_string()
        };
        // A solver error names the stage (`linear solver`), not the scene file.
        problems.extend(check_failure("linear solver", &fragment, &output));
        problems.extend(check_untouched(&file, parent.path(), &out));
    }
    std::fs::write(d.join("structured.toml"), scene("structured")).unwrap();
    let output = fibfluid_ulimit(
        limit_kib,
        &[os("--threads"), os("1"), os("run"), os("structured.toml"), os("--out"), os("out-structured")],
        d,
        NO_BACKTRACE,
    );
    if !output.status.success() {
        problems.push(format!(
            "the structured run does not fit the limit, so the test proves nothing: {}",
            String::from_utf8_lossy(&output.stderr)
        ));
    }
    assert_no_problems(problems);
}

/// Gravity without a fluid density does nothing (it acts through the hydrostatic pressure
/// only): the run says so on stderr and in report.json, and the premise holds (nothing
/// moved). With a density, no warning and the body sags.
#[test]
fn a_setting_that_cannot_act_is_warned_about() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let gravity = "[gravity]\nacceleration = [0.0, -9.81, 0.0]\n";
    std::fs::write(d.join("no-density.toml"), small_scene(gravity)).unwrap();
    std::fs::write(d.join("density.toml"), small_scene(&format!("{gravity}[fluid]\ndensity = 1000.0\n")))
        .unwrap();
    let warning = "warning: [gravity] acceleration = [0, -9.81, 0] has no effect: the fluid density is 0";
    let mut problems = Vec::new();
    for (file, warned) in [("no-density.toml", true), ("density.toml", false)] {
        let out = d.join(format!("out-{file}"));
        let output = fibfluid_env(&[os("run"), os(file), os("--out"), out.as_os_str()], d, &[]);
        let stderr = String::from_utf8_lossy(&output.stderr);
        if !output.status.success() {
            problems.push(format!("{file}: {stderr}"));
            continue;
        }
        let warnings: Vec<&str> = stderr.lines().filter(|l| l.starts_with("warning: ")).collect();
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
        let listed: Vec<&str> = report["warnings"]
            .as_array()
            .map(|a| a.iter().filter_map(|w| w.as_str()).collect())
            .unwrap_or_default();
        let printed: Vec<&str> = warnings.iter().map(|w| w.trim_start_matches("warning: ")).collect();
        if listed != printed {
            problems
                .push(format!("{file}: report.json warnings {listed:?} differ from stderr's {printed:?}"));
        }
        let moved = report["max_displacement"].as_f64().unwrap();
        if warned {
            if warnings.len() != 1 || !warnings[0].starts_with(warning) {
                problems.push(format!("{file}: expected one `{warning}`, stderr: {stderr}"));
            }
            if moved != 0.0 {
                problems.push(format!("{file}: the warning is wrong, the body moved by {moved}"));
            }
        } else {
            if !warnings.is_empty() || !listed.is_empty() {
                problems.push(format!("{file}: unexpected warnings: {warnings:?} / {listed:?}"));
            }
            if !(moved > 0.0) {
                problems.push(format!("{file}: with a density the body should sag, moved {moved}"));
            }
        }
    }
    // The round trip warns too.
    let output = fibfluid_env(&[os("roundtrip"), os("no-density.toml")], d, &[]);
    if !String::from_utf8_lossy(&output.stderr).contains(warning) {
        problems.push(format!("roundtrip: no warning: {}", String::from_utf8_lossy(&output.stderr)));
    }
    assert_no_problems(problems);
}

/// A tiny deterministic generator (SplitMix64) for the argument fuzzing below.
struct SplitMix(u64);

impl SplitMix {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn pick<'a>(&mut self, items: &[&'a str]) -> &'a str {
        items[(self.next() % items.len() as u64) as usize]
    }
}

/// Random command lines (seeded) over the global flags (`--threads`, `--max-file-bytes`)
/// and each command's numeric and named options: every one exits with 0 or 2 within the
/// timeout and never panics.
#[test]
fn fuzzed_arguments_never_panic() {
    const THREADS: &[&str] = &[
        "0",
        "1",
        "2",
        "3",
        "8",
        "9",
        "1024",
        "1025",
        "100000",
        "4294967297",
        "18446744073709551615",
        "18446744073709551616",
        "-1",
        "abc",
        "",
        "0x10",
        "1e3",
        " 2",
    ];
    const BYTES: &[&str] = &["0", "1", "100", "1K", "1k", "2G", "16T", "99999999T", "1Q", "-5", "", "4096B"];
    const LEVELS: &[&str] = &["0", "1", "2", "8", "-1", "99999999999", "x"];
    const RADII: &[&str] = &["1", "0", "-1", "nan", "inf", "1e308", "1e-320", "x"];
    const STEPS: &[&str] = &["0", "1", "2", "-1", "x", ""];
    const BACKENDS: &[&str] = &["structured", "faer-lu", "nalgebra-lu", "openblas-lu", "cholmod", ""];
    const MODES: &[&str] = &["paper", "refresh", "nonlinear", "implicit"];
    const SIZES: &[&str] = &["0", "3", "4", "5", "20001", "abc", "4,5"];
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("s.toml"), small_scene("[[force]]\nvertex = 3\nvalue = [0.0, -1.0, 0.0]\n"))
        .unwrap();
    let mesh = fixtures_dir().join("meshes/icosphere-1.obj").display().to_string();
    let mut rng = SplitMix(0x5EED_F1BF_1D00_0016);
    let mut problems = Vec::new();
    for case in 0..60 {
        let mut args: Vec<String> = Vec::new();
        if !rng.next().is_multiple_of(4) {
            args.extend(["--threads".into(), rng.pick(THREADS).into()]);
        }
        if rng.next().is_multiple_of(3) {
            args.extend(["--max-file-bytes".into(), rng.pick(BYTES).into()]);
        }
        match rng.next() % 4 {
            0 => {
                args.extend(["mesh-info".into(), mesh.clone()]);
                if rng.next().is_multiple_of(2) {
                    args.push("--json".into());
                }
            }
            1 => args.extend([
                "icosphere".into(),
                "--level".into(),
                rng.pick(LEVELS).into(),
                "--radius".into(),
                rng.pick(RADII).into(),
                "--out".into(),
                format!("ico-{case}.obj"),
            ]),
            2 => args.extend([
                "roundtrip".into(),
                "s.toml".into(),
                "--steps".into(),
                rng.pick(STEPS).into(),
                "--backend".into(),
                rng.pick(BACKENDS).into(),
                "--mode".into(),
                rng.pick(MODES).into(),
            ]),
            _ => args.extend(["bench".into(), "--sizes".into(), rng.pick(SIZES).into()]),
        }
        let argv: Vec<&std::ffi::OsStr> = args.iter().map(|a| os(a)).collect();
        let output = fibfluid_env(&argv, d, &[]);
        let stderr = String::from_utf8_lossy(&output.stderr);
        if !matches!(output.status.code(), Some(0) | Some(2)) {
            problems.push(format!("{args:?}: exit status {:?}: {stderr}", output.status.code()));
        }
        if stderr.contains("panicked") || stderr.contains("RUST_BACKTRACE") {
            problems.push(format!("{args:?}: panicked: {stderr}"));
        }
    }
    assert_no_problems(problems);
}
