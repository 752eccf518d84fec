//! The readers of untrusted input (OBJ, STL, scene TOML) never panic: random bytes, token
//! soups and random edits of valid files all come back as `Ok` or `Err`.
//!
//! 5,000 cases per property by default (a few seconds); 200,000 with
//! `cargo test --features slow-proptests --test fuzz_readers` (see tests/bad_inputs/README.md).

use std::path::{Path, PathBuf};

use fibfluid::Scene;
use fibfluid::geometry::{MeshError, icosphere, read_obj_bytes, read_stl_bytes};
use proptest::prelude::*;

/// Cases per property (`PROPTEST_CASES` overrides).
fn cases() -> u32 {
    let default = if cfg!(feature = "slow-proptests") { 200_000 } else { 5_000 };
    std::env::var("PROPTEST_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(default)
}

fn config() -> ProptestConfig {
    ProptestConfig { cases: cases(), ..ProptestConfig::default() }
}

const OBJ_TOKENS: &[&str] = &[
    "v",
    "f",
    "vt",
    "vn",
    "l",
    "p",
    "g",
    "o",
    "/",
    "//",
    "-",
    "+",
    ".",
    "0",
    "1",
    "2",
    "-1",
    "-2",
    "-9",
    "9",
    "99999999999",
    "4294967296",
    "4294967297",
    "9223372036854775807",
    "-9223372036854775808",
    "99999999999999999999",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "1e308",
    "-1e308",
    "1e-320",
    "0x10",
    " ",
    "\t",
    "\n",
    "\r\n",
    "#",
    "f 1 2 3\n",
    "f -1 -2 -3\n",
    "f 1 1 1\n",
    "v 0 0 0\n",
    "v 1e308 1e308 1e308\n",
    "l 1 2\n",
    "é",
    "\u{feff}",
    "1e300",
    "-1e300",
    "1e-300",
    "1e154",
    "1e-160",
    "v 1e300 1e300 1e300\n",
    "v 1e-300 0 1e-300\n",
];

const STL_TOKENS: &[&str] = &[
    "solid",
    "endsolid",
    "facet",
    "normal",
    "endfacet",
    "outer",
    "loop",
    "endloop",
    "vertex",
    "vertex 0 0 0\n",
    "facet normal 0 0 1\n outer loop\n",
    "nan",
    "inf",
    "1e39",
    "-1e39",
    "1e308",
    "0",
    "1",
    "-1",
    " ",
    "\n",
    "\r\n",
];

const TOML_TOKENS: &[&str] = &[
    "=",
    "[",
    "]",
    "{",
    "}",
    ",",
    ".",
    "\"",
    "'",
    "#",
    "\n",
    " ",
    "[[fix]]\n",
    "[[force]]\n",
    "[mesh]\n",
    "[polygon]\n",
    "[material]\n",
    "[fluid]\n",
    "[load]\n",
    "[gravity]\n",
    "[solver]\n",
    "path",
    "scale",
    "points",
    "young",
    "fiber_modulus",
    "surface_tension",
    "stiffening",
    "density",
    "steps",
    "acceleration",
    "axis",
    "above",
    "below",
    "top",
    "bottom",
    "vertices",
    "box",
    "dofs",
    "vertex",
    "value",
    "at",
    "backend",
    "mode",
    "stepping",
    "precision",
    "constraints",
    "penalty",
    "\"m.obj\"",
    "\"x\"",
    "\"y\"",
    "\"z\"",
    "\"ramp\"",
    "\"faer-lu\"",
    "\"nonlinear\"",
    "\"..\"",
    "\"/\"",
    "\"\"",
    "-1",
    "0",
    "1",
    "41",
    "42",
    "-0.0",
    "0.5",
    "nan",
    "-nan",
    "inf",
    "-inf",
    "1e400",
    "1e-400",
    "1e300",
    "1e-300",
    "\u{feff}",
    "\"openblas-lu\"",
    "99999999999999999999",
    "9223372036854775807",
    "true",
    "[]",
    "[1.0, 2.0]",
    "[0.0, 0.0, 0.0]",
    "[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]",
    "{}",
];

/// One random edit of a file.
#[derive(Clone, Debug)]
enum Edit {
    /// Overwrite one byte.
    Set(usize, u8),
    /// Insert bytes.
    Insert(usize, Vec<u8>),
    /// Delete up to `len` bytes.
    Delete(usize, usize),
    /// Replace up to `len` bytes.
    Replace(usize, usize, Vec<u8>),
    /// Cut the file short.
    Truncate(usize),
    /// Repeat a line (or a 50-byte record).
    Repeat(usize, usize),
}

fn snippet(tokens: &'static [&'static str]) -> impl Strategy<Value = Vec<u8>> {
    prop_oneof![
        3 => prop::sample::select(tokens).prop_map(|t| t.as_bytes().to_vec()),
        1 => prop::collection::vec(any::<u8>(), 1..8),
    ]
}

fn edit(tokens: &'static [&'static str]) -> impl Strategy<Value = Edit> {
    prop_oneof![
        (any::<usize>(), any::<u8>()).prop_map(|(i, b)| Edit::Set(i, b)),
        (any::<usize>(), snippet(tokens)).prop_map(|(i, s)| Edit::Insert(i, s)),
        (any::<usize>(), 1usize..24).prop_map(|(i, n)| Edit::Delete(i, n)),
        (any::<usize>(), 1usize..8, snippet(tokens)).prop_map(|(i, n, s)| Edit::Replace(i, n, s)),
        any::<usize>().prop_map(Edit::Truncate),
        (any::<usize>(), 50usize..200).prop_map(|(i, n)| Edit::Repeat(i, n)),
    ]
}

fn edits(tokens: &'static [&'static str]) -> impl Strategy<Value = Vec<Edit>> {
    prop::collection::vec(edit(tokens), 1..6)
}

fn apply(base: &[u8], edits: &[Edit]) -> Vec<u8> {
    let mut b = base.to_vec();
    for e in edits {
        let at = |i: usize, len: usize| if len == 0 { 0 } else { i % (len + 1) };
        match e {
            Edit::Set(i, v) => {
                if !b.is_empty() {
                    let i = i % b.len();
                    b[i] = *v;
                }
            }
            Edit::Insert(i, s) => {
                let i = at(*i, b.len());
                b.splice(i..i, s.iter().copied());
            }
            Edit::Delete(i, n) => {
                let i = at(*i, b.len());
                let end = (i + n).min(b.len());
                b.drain(i..end);
            }
            Edit::Replace(i, n, s) => {
                let i = at(*i, b.len());
                let end = (i + n).min(b.len());
                b.splice(i..end, s.iter().copied());
            }
            Edit::Truncate(i) => {
                let i = at(*i, b.len());
                b.truncate(i);
            }
            Edit::Repeat(i, n) => {
                // Repeat the line starting after position i, or n bytes when there is none.
                let i = at(*i, b.len());
                let start = b[..i].iter().rposition(|&c| c == b'\n').map(|p| p + 1).unwrap_or(0);
                let end = b[i..].iter().position(|&c| c == b'\n').map(|p| i + p + 1).unwrap_or(b.len());
                let end = if end - start > *n { start + n } else { end };
                let piece = b[start..end].to_vec();
                b.splice(end..end, piece);
            }
        }
    }
    b
}

fn fixture(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures").join(rel)
}

fn valid_obj() -> Vec<u8> {
    std::fs::read(fixture("meshes/icosphere-1.obj")).unwrap()
}

fn binary_stl() -> Vec<u8> {
    let m = icosphere(1, 1.0);
    let mut b = b"fuzz base: a level-1 icosphere".to_vec();
    b.resize(80, b' ');
    b.extend((m.n_faces() as u32).to_le_bytes());
    for t in m.triangles() {
        b.extend([0u8; 12]); // normal (ignored)
        for &v in t {
            for c in m.positions()[v as usize] {
                b.extend((c as f32).to_le_bytes());
            }
        }
        b.extend([0u8; 2]);
    }
    b
}

fn ascii_stl() -> Vec<u8> {
    let m = icosphere(1, 1.0);
    let mut s = String::from("solid fuzz\n");
    for t in m.triangles() {
        s.push_str("  facet normal 0 0 0\n    outer loop\n");
        for &v in t {
            let p = m.positions()[v as usize];
            s.push_str(&format!("      vertex {:?} {:?} {:?}\n", p[0] as f32, p[1] as f32, p[2] as f32));
        }
        s.push_str("    endloop\n  endfacet\n");
    }
    s.push_str("endsolid fuzz\n");
    s.into_bytes()
}

/// A scene using every table; its mesh is `m.obj` beside it (see [`SceneDir`]).
const VALID_SCENE: &str = r#"# fuzz base
[mesh]
path = "m.obj"
scale = 1.0

[material]
young = [3000.0, 2000.0, 1000.0]
surface_tension = 300.0
stiffening = 0.5

[fluid]
density = 1000.0

[load]
steps = 3

[gravity]
acceleration = [0.0, -9.81, 0.0]

[[fix]]
axis = "y"
above = 0.8
dofs = ["x", "y", "z"]

[[fix]]
vertices = [0, 1]
dofs = ["x"]

[[fix]]
box = [[-2.0, -2.0, -2.0], [2.0, -0.8, 2.0]]

[[force]]
vertex = 5
value = [0.0, -1.0, 0.0]
at = "ramp"

[solver]
backend = "structured"
mode = "refresh"
stepping = "heun"
precision = "f64"
constraints = "penalty"
penalty = 1e9
"#;

/// A scratch directory holding `m.obj` (a valid mesh) and the scene file under test.
struct SceneDir {
    dir: tempfile::TempDir,
    count: std::cell::Cell<u64>,
}

impl SceneDir {
    fn new() -> Self {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("m.obj"), valid_obj()).unwrap();
        Self { dir, count: Default::default() }
    }

    /// Writes `bytes` as a new scene file and loads it; a panic fails the property.
    fn load(&self, bytes: &[u8]) -> fibfluid::Result<Scene> {
        // A fresh name each time: rewriting one file in place makes some file systems flush it.
        let k = self.count.replace(self.count.get() + 1);
        let path = self.dir.path().join(format!("scene-{k}.toml"));
        std::fs::write(&path, bytes).unwrap();
        let result = Scene::load(&path);
        std::fs::remove_file(&path).unwrap();
        result
    }
}

thread_local! {
    static SCENE_DIR: SceneDir = SceneDir::new();
}

fn load_scene(bytes: &[u8]) -> fibfluid::Result<Scene> {
    SCENE_DIR.with(|d| d.load(bytes))
}

#[test]
fn the_fuzz_bases_are_valid() {
    read_obj_bytes("base.obj", &valid_obj()).unwrap();
    read_stl_bytes("base.stl", &binary_stl()).unwrap();
    read_stl_bytes("base.stl", &ascii_stl()).unwrap();
    let scene = load_scene(VALID_SCENE.as_bytes()).unwrap();
    assert_eq!(scene.n_vertices(), 42);
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn random_bytes_never_panic_any_reader(bytes in prop::collection::vec(any::<u8>(), 0..2048)) {
        let _ = read_obj_bytes("fuzz.obj", &bytes);
        let _ = read_stl_bytes("fuzz.stl", &bytes);
        let _ = load_scene(&bytes);
    }

    #[test]
    fn token_soups_never_panic_the_obj_reader(tokens in prop::collection::vec(prop::sample::select(OBJ_TOKENS), 0..80)) {
        let _ = read_obj_bytes("fuzz.obj", tokens.concat().as_bytes());
    }

    #[test]
    fn token_soups_never_panic_the_scene_parser(tokens in prop::collection::vec(prop::sample::select(TOML_TOKENS), 0..60)) {
        let _ = load_scene(tokens.concat().as_bytes());
    }

    #[test]
    fn edits_of_a_valid_obj_never_panic(e in edits(OBJ_TOKENS)) {
        let _ = read_obj_bytes("fuzz.obj", &apply(&valid_obj(), &e));
    }

    /// The valid OBJ in units of 10^k (coordinates stay normal f64), with or without a
    /// byte-order mark: it reads with all 42 vertices, or the error blames the scale (never
    /// "degenerate" or "flat": the shape is fine).
    #[test]
    fn a_valid_obj_at_any_scale_reads_or_blames_its_scale(k in -300i32..=300, bom in any::<bool>()) {
        let factor: f64 = format!("1e{k}").parse().unwrap();
        let m = icosphere(1, 1.0);
        let mut text = if bom { "\u{feff}".to_string() } else { String::new() };
        for p in m.positions() {
            text.push_str(&format!("v {:e} {:e} {:e}\n", p[0] * factor, p[1] * factor, p[2] * factor));
        }
        for t in m.triangles() {
            text.push_str(&format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1));
        }
        match read_obj_bytes("scaled.obj", text.as_bytes()) {
            Ok(f) => prop_assert_eq!(f.file_vertex_count(), 42),
            Err(fibfluid::geometry::GeometryError::Mesh {
                source: MeshError::CoordinateOverflow { .. } | MeshError::CoordinateUnderflow { .. },
                ..
            }) => {}
            Err(e) => prop_assert!(false, "10^{}: {}", k, e),
        }
    }

    #[test]
    fn edits_of_a_valid_binary_stl_never_panic(
        e in edits(STL_TOKENS),
        count in prop_oneof![Just(None), any::<u32>().prop_map(Some), (0u32..200).prop_map(Some)],
    ) {
        let mut base = binary_stl();
        if let Some(c) = count {
            base[80..84].copy_from_slice(&c.to_le_bytes());
        }
        let _ = read_stl_bytes("fuzz.stl", &base);
        let _ = read_stl_bytes("fuzz.stl", &apply(&base, &e));
    }

    #[test]
    fn edits_of_a_valid_ascii_stl_never_panic(e in edits(STL_TOKENS)) {
        let _ = read_stl_bytes("fuzz.stl", &apply(&ascii_stl(), &e));
    }

    #[test]
    fn edits_of_a_valid_scene_never_panic(e in edits(TOML_TOKENS)) {
        let _ = load_scene(&apply(VALID_SCENE.as_bytes(), &e));
    }
}
