//! The mesh reader: agreement with `tobj` on the OBJ fixtures, the map back to the file's
//! vertex order, flipping of inward files, OBJ write/read round trip, binary and ASCII STL,
//! and a typed error for every kind of broken input.

use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use crate::common::*;
use fibfluid_geometry::{
    FileKind, GeometryError, MeshError, MeshFile, ReadError, ReadOptions, ScaleSite, TriMesh, icosphere,
    load_mesh, load_mesh_with, parse_byte_count, read_file_limited, read_obj_bytes, read_stl_bytes,
    write_obj,
};

/// Volume from tobj's f32 positions against ours from f64: f32 rounding of the coordinates.
const F32_VOLUME_REL_TOL: f64 = 1e-5;

/// A file in the system temp folder, removed on drop.
struct TempFile(PathBuf);

impl TempFile {
    fn new(stem: &str, ext: &str, bytes: &[u8]) -> Self {
        let nanos = SystemTime::now().duration_since(UNIX_EPOCH).unwrap().as_nanos();
        let name = format!("fibfluid-geometry-{stem}-{}-{nanos}.{ext}", std::process::id());
        let path = std::env::temp_dir().join(name);
        std::fs::write(&path, bytes).unwrap();
        Self(path)
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

type Key = [[u32; 3]; 3];

/// A corner as the bits of its f32 coordinates (-0 folded onto +0).
fn key32(p: [f32; 3]) -> [u32; 3] {
    p.map(|c| if c == 0.0 { 0 } else { c.to_bits() })
}

/// Rotates a triangle so that its smallest corner comes first (orientation kept).
fn canonical(mut t: Key) -> Key {
    let first = (0..3).min_by_key(|&i| t[i]).unwrap();
    t.rotate_left(first);
    t
}

fn triangles_by_tobj(path: &Path) -> Vec<Key> {
    let opts = tobj::LoadOptions { triangulate: true, single_index: false, ..Default::default() };
    let (models, _materials) = tobj::load_obj(path, &opts).unwrap();
    let mut out = Vec::new();
    for model in models {
        let m = model.mesh;
        let corner = |i: u32| {
            let i = 3 * i as usize;
            key32([m.positions[i], m.positions[i + 1], m.positions[i + 2]])
        };
        for t in m.indices.chunks(3) {
            out.push(canonical([corner(t[0]), corner(t[1]), corner(t[2])]));
        }
    }
    out.sort_unstable();
    out
}

fn triangles_by_us(m: &TriMesh) -> Vec<Key> {
    let mut out: Vec<Key> =
        (0..m.n_faces()).map(|k| canonical(m.corners(k).map(|p| key32(p.map(|c| c as f32))))).collect();
    out.sort_unstable();
    out
}

fn volume_of_keys(tris: &[Key]) -> f64 {
    let p = |k: [u32; 3]| k.map(|b| f32::from_bits(b) as f64);
    tris.iter().map(|t| dot(p(t[0]), cross(p(t[1]), p(t[2])))).sum::<f64>() / 6.0
}

/// Our reader and `tobj` (triangulating, merged over all models) give the same triangles,
/// compared as position triples with orientation, on liver.obj (plain `f a b c`), spot.obj
/// (`v/vt`), tongue.obj (mostly quads, fan-triangulated by both) and icosahedron.obj
/// (`v/vt/vn`). The volume from tobj's data is positive (the files are outward) and matches.
#[test]
fn same_triangles_as_tobj() {
    for name in ["liver.obj", "spot.obj", "tongue.obj", "icosahedron.obj"] {
        let file = load(name);
        assert!(!file.validation.flipped, "{name} is outward in the file");
        let theirs = triangles_by_tobj(&fixture(name));
        let ours = triangles_by_us(&file.mesh);
        assert_eq!(ours.len(), theirs.len(), "{name}: triangle count");
        let first_diff = ours.iter().zip(&theirs).position(|(a, b)| a != b);
        assert_eq!(first_diff, None, "{name}: triangle sets differ");
        let v = volume_of_keys(&theirs);
        assert!(v > 0.0, "{name}");
        assert!(
            (v - file.mesh.volume()).abs() <= F32_VOLUME_REL_TOL * v,
            "{name}: {v} vs {}",
            file.mesh.volume()
        );
    }
}

/// A plain OBJ reading written here: (positions, 0-based faces) in file order.
fn parse_plain_obj(text: &str) -> (Vec<V3>, Vec<[u32; 3]>) {
    let mut v = Vec::new();
    let mut f = Vec::new();
    for line in text.lines() {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => v.push([0, 1, 2].map(|_| it.next().unwrap().parse::<f64>().unwrap())),
            Some("f") => {
                let idx: Vec<u32> =
                    it.map(|t| t.split('/').next().unwrap().parse::<u32>().unwrap() - 1).collect();
                assert_eq!(idx.len(), 3, "this helper reads triangles only");
                f.push([idx[0], idx[1], idx[2]]);
            }
            _ => {}
        }
    }
    (v, f)
}

fn rotate_min_first(t: [u32; 3]) -> [u32; 3] {
    let mut t = t;
    let first = (0..3).min_by_key(|&i| t[i]).unwrap();
    t.rotate_left(first);
    t
}

/// liver.obj has 181 `v` lines of which 42 are used by no face (counted here by reading the
/// file independently). They are dropped from the mesh, and the maps lead back to the file:
/// `to_file` lists the referenced file indices in order, `from_file_index` inverts it (None
/// for the unreferenced), `triangles_in_file_order` gives the file's faces, and
/// `positions_in_file_order` puts moved mesh vertices back at their file index while the
/// unreferenced ones keep the file's coordinates.
#[test]
fn liver_unreferenced_vertices_map_back_to_the_file() {
    let text = std::fs::read_to_string(fixture("liver.obj")).unwrap();
    let (v, f) = parse_plain_obj(&text);
    let mut used = vec![false; v.len()];
    for t in &f {
        for &i in t {
            used[i as usize] = true;
        }
    }
    let referenced: Vec<u32> = (0..v.len() as u32).filter(|&i| used[i as usize]).collect();
    assert_eq!((v.len(), v.len() - referenced.len()), (181, 42));

    let file = load("liver.obj");
    assert_eq!(file.file_vertex_count(), 181);
    assert_eq!(file.mesh.n_vertices(), 139);
    assert_eq!(file.to_file, referenced);
    assert_eq!(file.file_positions, v);
    assert!(file.notes.iter().any(|n| n.contains("42 unreferenced")), "{:?}", file.notes);
    for (m, &fi) in file.to_file.iter().enumerate() {
        assert_eq!(file.from_file_index(fi as usize), Some(m));
        assert_eq!(file.mesh.positions()[m], v[fi as usize]);
    }
    for i in (0..v.len()).filter(|&i| !used[i]) {
        assert_eq!(file.from_file_index(i), None, "file vertex {i} is unreferenced");
    }
    assert_eq!(file.from_file_index(181), None);
    let mut ours: Vec<[u32; 3]> = file.triangles_in_file_order().into_iter().map(rotate_min_first).collect();
    let mut theirs: Vec<[u32; 3]> = f.iter().map(|t| rotate_min_first(*t)).collect();
    ours.sort_unstable();
    theirs.sort_unstable();
    assert_eq!(ours, theirs);

    let shift = [1.0, -2.0, 0.5];
    let moved: Vec<V3> = file.mesh.positions().iter().map(|p| add(*p, shift)).collect();
    let back = file.positions_in_file_order(&moved);
    assert_eq!(back.len(), 181);
    for i in 0..181 {
        let want = if used[i] { add(v[i], shift) } else { v[i] };
        assert_eq!(back[i], want, "file vertex {i}");
    }
}

fn reverse_faces(text: &str) -> String {
    text.lines()
        .map(|l| {
            let t: Vec<&str> = l.split_whitespace().collect();
            if t.first() == Some(&"f") { format!("f {} {} {}", t[1], t[3], t[2]) } else { l.to_string() }
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// An inward-oriented copy of liver.obj (every face reversed) is flipped with a warning
/// and gives the positive volume of the original (computed here from the original file),
/// with the original's faces. Read both from a temp file and from memory.
#[test]
fn inward_file_is_flipped_with_a_warning() {
    let text = std::fs::read_to_string(fixture("liver.obj")).unwrap();
    let (v, f) = parse_plain_obj(&text);
    let want_volume = volume_independent(&v, &f);
    let inward = reverse_faces(&text);
    let (_, fr) = parse_plain_obj(&inward);
    assert!(volume_independent(&v, &fr) < 0.0, "the reversed copy encloses a negative volume");

    let tmp = TempFile::new("liver-inward", "obj", inward.as_bytes());
    let from_disk = load_mesh(&tmp.0).unwrap();
    let from_memory = read_obj_bytes("liver-inward.obj", inward.as_bytes()).unwrap();
    let original = load("liver.obj");
    for file in [&from_disk, &from_memory] {
        assert!(file.validation.flipped);
        assert!(!file.validation.warnings.is_empty());
        assert!(file.notes.iter().any(|n| n.contains("flipped")), "{:?}", file.notes);
        let vol = file.mesh.volume();
        assert!(vol > 0.0);
        assert!((vol - want_volume).abs() <= 1e-12 * want_volume, "{vol} vs {want_volume}");
        let mut a: Vec<[u32; 3]> = file.mesh.triangles().iter().map(|t| rotate_min_first(*t)).collect();
        let mut b: Vec<[u32; 3]> = original.mesh.triangles().iter().map(|t| rotate_min_first(*t)).collect();
        a.sort_unstable();
        b.sort_unstable();
        assert_eq!(a, b, "flipped faces are the original ones");
    }
    assert_eq!(from_disk.mesh, from_memory.mesh);
    assert_eq!(from_disk.path, tmp.0);
}

/// `write_obj` keeps every bit of the f64 positions: writing a mesh and reading it back
/// gives an identical mesh (a level-2 icosphere, whose coordinates are not short decimals,
/// and liver2).
#[test]
fn obj_write_read_round_trip_is_exact() {
    for (name, m) in [("icosphere", icosphere(2, 0.37)), ("liver2", load("liver2.obj").mesh)] {
        let tmp = TempFile::new(name, "obj", b"");
        write_obj(&tmp.0, m.positions(), m.triangles()).unwrap();
        let back = load_mesh(&tmp.0).unwrap();
        assert_eq!(back.mesh, m, "{name}");
    }
}

/// Negative (relative) face indices name the same vertices as positive ones.
#[test]
fn relative_indices_read_like_absolute_ones() {
    let (p, t) = tetrahedron();
    let absolute = obj_text(&p, &t);
    let mut relative = String::new();
    for q in &p {
        relative.push_str(&format!("v {} {} {}\n", q[0], q[1], q[2]));
    }
    for tri in &t {
        let r = tri.map(|i| i as i64 - p.len() as i64);
        relative.push_str(&format!("f {} {} {}\n", r[0], r[1], r[2]));
    }
    let a = read_obj_bytes("a.obj", absolute.as_bytes()).unwrap();
    let b = read_obj_bytes("b.obj", relative.as_bytes()).unwrap();
    assert_eq!(a.mesh, b.mesh);
    assert_eq!(a.mesh.triangles(), &t[..]);
}

fn stl_binary(header: &[u8; 80], positions: &[V3], triangles: &[[u32; 3]]) -> Vec<u8> {
    let mut out = header.to_vec();
    out.extend((triangles.len() as u32).to_le_bytes());
    for t in triangles {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        let n = cross(sub(b, a), sub(c, a));
        let n = mul(n, 1.0 / norm(n));
        for v in [n, a, b, c] {
            for x in v {
                out.extend((x as f32).to_le_bytes());
            }
        }
        out.extend(0u16.to_le_bytes());
    }
    out
}

/// ASCII STL text; with `negative_zeros`, zero coordinates of every other facet are written
/// as `-0.0` (they must weld with `0.0`).
fn stl_ascii(positions: &[V3], triangles: &[[u32; 3]], negative_zeros: bool) -> String {
    let mut s = String::from("solid test\n");
    for (k, t) in triangles.iter().enumerate() {
        s.push_str("  facet normal 0 0 0\n    outer loop\n");
        for i in t {
            let mut p = positions[*i as usize];
            if negative_zeros && k % 2 == 1 {
                p = p.map(|c| if c == 0.0 { -0.0 } else { c });
            }
            // `{:?}` of an f64 round-trips exactly; the values are f32-exact already.
            s.push_str(&format!("      vertex {:?} {:?} {:?}\n", p[0], p[1], p[2]));
        }
        s.push_str("    endloop\n  endfacet\n");
    }
    s.push_str("endsolid test\n");
    s
}

/// Binary and ASCII STL of the same mesh (a level-1 icosphere with f32-exact coordinates)
/// read to the same mesh, whose triangles are the source triangles (vertices welded in
/// order of first appearance, `-0.0` with `0.0`). A binary file whose header starts with "solid" (as some
/// exporters write) is still read as binary.
#[test]
fn binary_and_ascii_stl_agree() {
    let src = icosphere(1, 2.0);
    let pos: Vec<V3> = src.positions().iter().map(|p| p.map(|c| c as f32 as f64)).collect();
    let tris = src.triangles().to_vec();
    let mut header = [b' '; 80];
    let bin = read_stl_bytes("b.stl", &stl_binary(&header, &pos, &tris)).unwrap();
    let ascii = read_stl_bytes("a.stl", stl_ascii(&pos, &tris, false).as_bytes()).unwrap();
    let text = stl_ascii(&pos, &tris, true);
    assert!(text.contains("-0.0"));
    let signed_zeros = read_stl_bytes("z.stl", text.as_bytes()).unwrap();
    header[..5].copy_from_slice(b"solid");
    let solid = read_stl_bytes("s.stl", &stl_binary(&header, &pos, &tris)).unwrap();
    assert_eq!(bin.mesh, ascii.mesh);
    assert_eq!(bin.mesh, solid.mesh);
    assert_eq!(bin.mesh, signed_zeros.mesh, "-0.0 and 0.0 are one vertex");
    assert_eq!((bin.mesh.n_vertices(), bin.mesh.n_faces()), (42, 80));
    for k in 0..tris.len() {
        assert_eq!(bin.mesh.corners(k), tris[k].map(|i| pos[i as usize]), "face {k}");
    }
    // Through the file path as well.
    let tmp = TempFile::new("ico", "stl", &stl_binary(&[b'x'; 80], &pos, &tris));
    assert_eq!(load_mesh(&tmp.0).unwrap().mesh, bin.mesh);
}

fn mesh_error(r: fibfluid_geometry::Result<MeshFile>) -> MeshError {
    match r {
        Err(GeometryError::Mesh { source, .. }) => source,
        Err(e) => panic!("expected a mesh error, got {e}"),
        Ok(_) => panic!("expected a mesh error, the file was accepted"),
    }
}

fn parse_error(r: fibfluid_geometry::Result<MeshFile>) -> (usize, String) {
    match r {
        Err(GeometryError::Parse { line, message, .. }) => (line, message),
        Err(e) => panic!("expected a parse error, got {e}"),
        Ok(_) => panic!("expected a parse error, the file was accepted"),
    }
}

const TETRA: &str = "v 0 0 0\nv 2 0 0\nv 0 2 0\nv 0 0 2\nf 1 3 2\nf 1 2 4\nf 1 4 3\n";

/// Text problems are parse errors naming the line (0 when not tied to one line).
#[test]
fn parse_errors_name_the_line() {
    let obj = |s: &str| read_obj_bytes("t.obj", s.as_bytes());
    // The tetrahedron itself reads (guard for the cases below, which each break one thing).
    obj(&format!("{TETRA}f 2 3 4\n")).unwrap();

    let (line, msg) = parse_error(obj(""));
    assert_eq!(line, 0);
    assert!(msg.contains("no vertices"), "{msg}");
    let (line, msg) = parse_error(obj("# nothing but a comment\n\n"));
    assert_eq!(line, 0, "{msg}");
    let empty = TempFile::new("empty", "obj", b"");
    match load_mesh(&empty.0) {
        Err(GeometryError::Parse { path, line: 0, .. }) => assert_eq!(path, empty.0),
        other => panic!("{other:?}"),
    }

    let (line, msg) = parse_error(obj("v 0 0 0\nv 1 0 0\nv 0 1 0\n"));
    assert_eq!(line, 0);
    assert!(msg.contains("no faces"), "{msg}");

    let (line, msg) = parse_error(obj(&format!("{TETRA}f 2 3 9\n")));
    assert_eq!(line, 8, "{msg}");
    assert!(msg.contains('9') && msg.contains("4 vertices"), "{msg}");

    let (line, msg) = parse_error(obj(&format!("{TETRA}f 2 3 -5\n")));
    assert_eq!(line, 8, "{msg}");

    let (line, msg) = parse_error(obj(&format!("{TETRA}f 2 0 4\n")));
    assert_eq!(line, 8);
    assert!(msg.contains("index 0"), "{msg}");

    for bad in ["nan", "NaN", "inf", "-inf"] {
        let text = TETRA.replace("v 0 2 0", &format!("v 0 {bad} 0"));
        let (line, msg) = parse_error(obj(&format!("{text}f 2 3 4\n")));
        assert_eq!(line, 3, "{bad}: {msg}");
    }

    let (line, _) = parse_error(obj("v 0 0 0\nv 1 0\n"));
    assert_eq!(line, 2);
    let (line, _) = parse_error(obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n"));
    assert_eq!(line, 4);
}

/// Topology problems are typed mesh errors, with vertex indices of the file (0-based).
#[test]
fn topology_errors_are_typed() {
    let (p, t) = tetrahedron();
    let read = |p: &[V3], t: &[[u32; 3]]| read_obj_bytes("t.obj", obj_text(p, t).as_bytes());
    read(&p, &t).unwrap();

    // Open surface: one face missing leaves its three edges on the boundary.
    match mesh_error(read(&p, &t[..3])) {
        MeshError::OpenBoundary { count, a, b } => {
            assert_eq!(count, 3);
            assert!([(1, 2), (2, 3), (1, 3)].contains(&(a, b)), "({a}, {b})");
        }
        e => panic!("{e:?}"),
    }

    // Two tetrahedra sharing the edge (0, 1): four faces on one edge.
    let mut p2 = p.clone();
    p2.extend([[0.0, -2.0, 0.0], [0.0, 0.0, -2.0]]);
    let mut t2 = t.clone();
    t2.extend([[0, 4, 1], [0, 1, 5], [0, 5, 4], [1, 4, 5]]);
    assert_eq!(mesh_error(read(&p2, &t2)), MeshError::NonManifoldEdge { a: 0, b: 1, faces: 4 });

    // A face given twice.
    let mut t3 = t.clone();
    t3.push(t[0]);
    assert_eq!(mesh_error(read(&p, &t3)), MeshError::DuplicateFace { first: 0, second: 4 });

    // One face reversed.
    let mut t4 = t.clone();
    t4[3] = [1, 3, 2];
    match mesh_error(read(&p, &t4)) {
        MeshError::InconsistentOrientation { a, b } => {
            assert!([(1, 2), (2, 3), (1, 3)].contains(&(a, b)), "({a}, {b})");
        }
        e => panic!("{e:?}"),
    }

    // Two separate tetrahedra.
    let mut p5 = p.clone();
    p5.extend(p.iter().map(|q| add(*q, [10.0, 0.0, 0.0])));
    let mut t5 = t.clone();
    t5.extend(t.iter().map(|f| f.map(|i| i + 4)));
    assert_eq!(mesh_error(read(&p5, &t5)), MeshError::DisjointBodies { component: 1 });

    // A face using one vertex twice.
    let mut t6 = t.clone();
    t6[0] = [0, 0, 1];
    assert!(matches!(mesh_error(read(&p, &t6)), MeshError::DegenerateFace { face: 0, .. }));

    // Error indices are the file's: with an unused vertex first, the open boundary of the
    // same surface names vertices shifted by one.
    let mut p7 = vec![[5.0, 5.0, 5.0]];
    p7.extend(&p);
    let t7: Vec<[u32; 3]> = t[..3].iter().map(|f| f.map(|i| i + 1)).collect();
    match mesh_error(read(&p7, &t7)) {
        MeshError::OpenBoundary { a, b, .. } => {
            assert!([(2, 3), (3, 4), (2, 4)].contains(&(a, b)), "({a}, {b})");
        }
        e => panic!("{e:?}"),
    }
}

/// STL problems: empty bytes, a binary header that claims far more triangles than the file
/// holds, an ASCII facet cut short; and file-level errors (missing file, unknown extension)
/// name the path.
#[test]
fn stl_and_file_errors() {
    let (line, msg) = parse_error(read_stl_bytes("e.stl", b""));
    assert_eq!(line, 0);
    assert!(msg.contains("not an STL"), "{msg}");

    let (p, t) = tetrahedron();
    let mut bytes = stl_binary(&[b' '; 80], &p, &t);
    read_stl_bytes("ok.stl", &bytes).unwrap();
    bytes[80..84].copy_from_slice(&1_000_000u32.to_le_bytes());
    let (_, msg) = parse_error(read_stl_bytes("big.stl", &bytes));
    assert!(msg.contains("claims 1000000 triangles"), "{msg}");
    bytes[..5].copy_from_slice(b"solid");
    let (_, msg) = parse_error(read_stl_bytes("big-solid.stl", &bytes));
    assert!(msg.contains("claims 1000000 triangles"), "header starting with solid: {msg}");

    let ascii = stl_ascii(&p, &t, false);
    let cut = &ascii[..ascii.rfind("vertex").unwrap()];
    parse_error(read_stl_bytes("cut.stl", cut.as_bytes()));

    let missing = std::env::temp_dir().join("fibfluid-geometry-no-such-file.obj");
    match load_mesh(&missing) {
        Err(GeometryError::Io { path, .. }) => assert_eq!(path, missing),
        other => panic!("{other:?}"),
    }
    let tmp = TempFile::new("tetra", "xyz", TETRA.as_bytes());
    match load_mesh(&tmp.0) {
        Err(GeometryError::UnsupportedFormat { path }) => assert_eq!(path, tmp.0),
        other => panic!("{other:?}"),
    }
    let tmp = TempFile::new("open", "obj", TETRA.as_bytes());
    match load_mesh(&tmp.0) {
        Err(GeometryError::Mesh { path, source: MeshError::OpenBoundary { .. } }) => assert_eq!(path, tmp.0),
        other => panic!("{other:?}"),
    }
}

const BOM: &[u8] = b"\xEF\xBB\xBF";

/// A UTF-8 byte-order mark before the first line is skipped: the mesh is the same as
/// without it (the old reader lost the first vertex line), and the first line is line 1.
#[test]
fn a_byte_order_mark_is_skipped() {
    let (p, t) = tetrahedron();
    let text = obj_text(&p, &t);
    let plain = read_obj_bytes("t.obj", text.as_bytes()).unwrap();
    let marked = read_obj_bytes("t.obj", &[BOM, text.as_bytes()].concat()).unwrap();
    assert_eq!(marked.file_vertex_count(), 4);
    assert_eq!(marked.mesh, plain.mesh);
    let (line, msg) = parse_error(read_obj_bytes("t.obj", &[BOM, b"v 0 0\n".as_slice()].concat()));
    assert_eq!((line, msg.as_str()), (1, "vertex has 2 coordinates, 3 expected"));
    // ASCII STL too (a binary STL's header is left as it is).
    let ascii = stl_ascii(&p, &t, false);
    let marked = read_stl_bytes("t.stl", &[BOM, ascii.as_bytes()].concat()).unwrap();
    assert_eq!(marked.mesh, read_stl_bytes("t.stl", ascii.as_bytes()).unwrap().mesh);
}

/// Coordinates whose products overflow or underflow f64 are said to be so, with the vertex
/// and a scale that fixes them, instead of "degenerate (area NaN)"; a truly degenerate face
/// stays degenerate at any scale. Expected values worked out by hand from the tetrahedron
/// (edge 2, face 0 = [0, 2, 1]: its largest coordinate is vertex 2's y).
#[test]
fn coordinate_scale_errors_are_typed_and_the_suggested_scale_works() {
    let (p, t) = tetrahedron();
    let scaled = |s: f64| p.iter().map(|q| mul(*q, s)).collect::<Vec<_>>();
    let huge = obj_text(&scaled(1e300), &t);
    assert_eq!(
        mesh_error(read_obj_bytes("huge.obj", huge.as_bytes())),
        MeshError::CoordinateOverflow {
            site: ScaleSite::Face(0),
            vertex: 2,
            magnitude: 2e300,
            suggested_scale: 1e-300
        }
    );
    let tiny = obj_text(&scaled(1e-300), &t);
    assert_eq!(
        mesh_error(read_obj_bytes("tiny.obj", tiny.as_bytes())),
        MeshError::CoordinateUnderflow {
            site: ScaleSite::Face(0),
            vertex: 2,
            magnitude: 2e-300,
            value: 0.0,
            suggested_scale: 1e300
        }
    );
    let msg = mesh_error(read_obj_bytes("huge.obj", huge.as_bytes())).to_string();
    assert!(msg.contains("overflow f64 when multiplied") && msg.contains("`[mesh].scale = 1e-300`"), "{msg}");

    // The suggested scale, applied before validation, loads the file: the tetrahedron with
    // edge 2 has volume 2^3 / 6.
    let tmp = TempFile::new("huge", "obj", huge.as_bytes());
    let file = load_mesh_with(&tmp.0, &ReadOptions { scale: Some(1e-300), ..Default::default() }).unwrap();
    assert!((file.mesh.volume() - 8.0 / 6.0).abs() < 1e-12, "{}", file.mesh.volume());
    // A scale that is not enough is reported in the file's units: the total scale to use.
    match load_mesh_with(&tmp.0, &ReadOptions { scale: Some(1e-200), ..Default::default() }) {
        Err(GeometryError::Mesh {
            source: MeshError::CoordinateOverflow { magnitude, suggested_scale, .. },
            ..
        }) => {
            assert!((magnitude / 2e300 - 1.0).abs() < 1e-12, "{magnitude}");
            assert_eq!(suggested_scale, 1e-300);
        }
        other => panic!("{other:?}"),
    }

    // A collinear face (vertex 4 is the midpoint of edge (0, 1)) in a closed surface, listed
    // first: degenerate at scale 1 and at 1e-300 alike.
    let mut p5 = p.clone();
    p5.push([1.0, 0.0, 0.0]);
    let t5 = vec![[0, 1, 4], [0, 2, 1], [0, 4, 3], [4, 1, 3], [0, 3, 2], [1, 2, 3]];
    for s in [1.0, 1e-300] {
        let q: Vec<_> = p5.iter().map(|v| mul(*v, s)).collect();
        let e = mesh_error(read_obj_bytes("sliver.obj", obj_text(&q, &t5).as_bytes()));
        assert!(matches!(e, MeshError::DegenerateFace { face: 0, .. }), "scale {s}: {e:?}");
    }
}

/// Only regular files are read, and no more than the limit: a FIFO, a device and a
/// directory are refused from their metadata; a file over the limit before it is read;
/// a file that is longer than its reported size (a `/proc` file reports 0) while it is read.
#[test]
fn the_bounded_reader_refuses_special_and_oversized_files() {
    let dir = std::env::temp_dir().join(format!("fibfluid-geometry-special-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let fifo = dir.join("pipe.obj");
    let _ = std::fs::remove_file(&fifo);
    assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let kind = |r: Result<Vec<u8>, ReadError>| match r {
        Err(ReadError::NotARegularFile { kind }) => kind,
        other => panic!("{other:?}"),
    };
    assert_eq!(kind(read_file_limited(&fifo, None)), FileKind::Fifo);
    assert_eq!(kind(read_file_limited("/dev/zero", Some(10))), FileKind::CharDevice);
    assert_eq!(kind(read_file_limited(&dir, None)), FileKind::Directory);
    match load_mesh(&fifo) {
        Err(GeometryError::Read { path, source: ReadError::NotARegularFile { kind: FileKind::Fifo } }) => {
            assert_eq!(path, fifo)
        }
        other => panic!("{other:?}"),
    }
    let zero = dir.join("zero.obj");
    let _ = std::fs::remove_file(&zero);
    std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
    assert!(matches!(
        load_mesh(&zero),
        Err(GeometryError::Read { source: ReadError::NotARegularFile { kind: FileKind::CharDevice }, .. })
    ));
    std::fs::remove_dir_all(&dir).unwrap();

    let tmp = TempFile::new("hundred", "obj", &[b'#'; 100]);
    assert!(matches!(read_file_limited(&tmp.0, Some(50)), Err(ReadError::TooLarge { size: 100, limit: 50 })));
    assert_eq!(read_file_limited(&tmp.0, Some(100)).unwrap().len(), 100);
    match load_mesh_with(&tmp.0, &ReadOptions { max_bytes: Some(99), ..Default::default() }) {
        Err(e @ GeometryError::Read { source: ReadError::TooLarge { .. }, .. }) => {
            assert!(e.to_string().contains("is 100 bytes, more than the limit of 99 bytes; raise it"), "{e}")
        }
        other => panic!("{other:?}"),
    }
    // /proc/self/status is a regular file of reported size 0 and a few hundred bytes.
    assert_eq!(std::fs::metadata("/proc/self/status").unwrap().len(), 0);
    assert!(matches!(
        read_file_limited("/proc/self/status", Some(10)),
        Err(ReadError::GrewPastLimit { limit: 10 })
    ));
}

/// Byte counts: digits with an optional binary suffix.
#[test]
fn byte_counts_parse() {
    assert_eq!(parse_byte_count("4G"), Some(4 << 30));
    assert_eq!(parse_byte_count("512M"), Some(512 << 20));
    assert_eq!(parse_byte_count("1kib"), Some(1024));
    assert_eq!(parse_byte_count(" 12 "), Some(12));
    assert_eq!(parse_byte_count("12B"), Some(12));
    for bad in ["0", "", "x", "-5", "1.5G", "1Q", "99999999999T", "18446744073709551616"] {
        assert_eq!(parse_byte_count(bad), None, "{bad}");
    }
}
