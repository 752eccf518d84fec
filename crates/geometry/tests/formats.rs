//! PLY (ASCII, binary little- and big-endian) and OFF: bundled OBJ meshes written in each
//! format and read back equal the OBJ reading bit for bit; a hand-written PLY with extra
//! properties of every PLY type, quads, a skipped element and comments reads as the same
//! OBJ; every malformed input is a parse error that names its line or byte offset; and no
//! truncation or corrupted byte makes a reader panic.

use proptest::prelude::*;
use proptest::test_runner::RngSeed;

use crate::common::*;
use fibfluid_geometry::{
    GeometryError, MeshFile, PlyFormat, icosphere, load_mesh, read_obj_bytes, read_off_bytes, read_ply_bytes,
    write_off, write_off_to, write_ply, write_ply_to,
};

const PLY_FORMATS: [PlyFormat; 3] =
    [PlyFormat::Ascii, PlyFormat::BinaryLittleEndian, PlyFormat::BinaryBigEndian];

/// A fresh temporary directory, removed on drop.
struct TempDir(std::path::PathBuf);

impl TempDir {
    fn new(stem: &str) -> Self {
        let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap().as_nanos();
        let dir =
            std::env::temp_dir().join(format!("fibfluid-formats-{stem}-{}-{nanos}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        Self(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn bits(p: &[V3]) -> Vec<[u64; 3]> {
    p.iter().map(|q| q.map(f64::to_bits)).collect()
}

/// The first index where `a` and `b` differ (a length difference counts), or None.
fn first_difference<T: PartialEq>(a: &[T], b: &[T]) -> Option<usize> {
    a.iter().zip(b).position(|(x, y)| x != y).or((a.len() != b.len()).then(|| a.len().min(b.len())))
}

/// `back` is `want` bit for bit: every file position, the map to the file, the mesh's
/// positions and triangles, and the validation's outcome.
fn assert_same_reading(back: &MeshFile, want: &MeshFile, what: &str) {
    let d = first_difference(&bits(&back.file_positions), &bits(&want.file_positions));
    assert_eq!(d, None, "{what}: file positions differ at vertex {d:?}");
    assert_eq!(first_difference(&back.to_file, &want.to_file), None, "{what}: map to the file");
    let d = first_difference(&bits(back.mesh.positions()), &bits(want.mesh.positions()));
    assert_eq!(d, None, "{what}: mesh positions differ at vertex {d:?}");
    let d = first_difference(back.mesh.triangles(), want.mesh.triangles());
    assert_eq!(d, None, "{what}: triangles differ at face {d:?}");
    assert_eq!(back.validation, want.validation, "{what}: validation");
}

/// The sphere, the breast (dome), the liver with its 42 unreferenced vertices and the tongue
/// (quads, triangulated by the OBJ reader), plus an icosphere whose coordinates are no short
/// decimals, scaled to 1e-7 (exponent notation): written as PLY in all three encodings and as
/// OFF (to memory and through a file), read back, and compared with the OBJ reading bit for
/// bit. A writer that rounds (f32, `{:.6}`) fails here.
#[test]
fn bundled_meshes_round_trip_through_ply_and_off_bit_for_bit() {
    let dir = TempDir::new("round-trip");
    let mut cases: Vec<(String, MeshFile)> = ["icosphere-2.obj", "dome.obj", "liver.obj", "tongue.obj"]
        .iter()
        .map(|n| (n.to_string(), load(n)))
        .collect();
    let m = icosphere(2, 0.37);
    let tiny: Vec<V3> = m.positions().iter().map(|p| mul(*p, 1e-7)).collect();
    let text = obj_text(&tiny, m.triangles());
    assert!(text.contains("e-8"), "the case exercises exponent notation");
    cases.push(("icosphere-1e-7".into(), read_obj_bytes("tiny.obj", text.as_bytes()).unwrap()));
    for (name, obj) in &cases {
        let (p, t) = (&obj.file_positions, obj.triangles_in_file_order());
        for format in PLY_FORMATS {
            let what = format!("{name} as {format:?} PLY");
            let mut bytes = Vec::new();
            write_ply_to(&mut bytes, p, &t, format).unwrap();
            assert_same_reading(&read_ply_bytes("m.ply", &bytes).unwrap(), obj, &what);
            let path = dir.0.join(format!("{}-{}.ply", name, format.header_name()));
            write_ply(&path, p, &t, format).unwrap();
            assert_eq!(std::fs::read(&path).unwrap(), bytes, "{what}: the file is what the writer wrote");
            assert_same_reading(&load_mesh(&path).unwrap(), obj, &format!("{what}, from the file"));
        }
        let mut bytes = Vec::new();
        write_off_to(&mut bytes, p, &t).unwrap();
        assert_same_reading(&read_off_bytes("m.off", &bytes).unwrap(), obj, &format!("{name} as OFF"));
        let path = dir.0.join(format!("{name}.OFF"));
        write_off(&path, p, &t).unwrap();
        assert_same_reading(&load_mesh(&path).unwrap(), obj, &format!("{name} as OFF, from the file"));
    }
}

/// The unit cube as six quads (outward), and its OBJ.
fn cube() -> (Vec<V3>, Vec<[u32; 4]>, String) {
    let p: Vec<V3> = (0..8).map(|i| [(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64]).collect();
    let q = vec![[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
    let mut obj = String::new();
    for v in &p {
        obj.push_str(&format!("v {} {} {}\n", v[0], v[1], v[2]));
    }
    for f in &q {
        obj.push_str(&format!("f {} {} {} {}\n", f[0] + 1, f[1] + 1, f[2] + 1, f[3] + 1));
    }
    (p, q, obj)
}

/// A property of the hand-written PLY: its header text and the value of element `k`
/// (a list: its values).
struct Prop {
    decl: &'static str,
    value: fn(usize) -> Vec<f64>,
}

/// The encoding of `v` as PLY type `ty`, in either byte order.
fn encode(ty: &str, v: f64, big: bool) -> Vec<u8> {
    macro_rules! e {
        ($t:ty) => {{
            let x = v as $t;
            if big { x.to_be_bytes().to_vec() } else { x.to_le_bytes().to_vec() }
        }};
    }
    match ty {
        "char" | "int8" => e!(i8),
        "uchar" | "uint8" => e!(u8),
        "short" | "int16" => e!(i16),
        "ushort" | "uint16" => e!(u16),
        "int" | "int32" => e!(i32),
        "uint" | "uint32" => e!(u32),
        "float" | "float32" => e!(f32),
        "double" | "float64" => e!(f64),
        _ => panic!("no type {ty}"),
    }
}

/// A PLY file with the elements `(name, count, properties)`, in `format`, with comments.
fn ply_file(format: PlyFormat, elements: &[(&str, usize, &[Prop])]) -> Vec<u8> {
    let mut out = format!("ply\nformat {} 1.0\ncomment a hand-written cube\n", format.header_name());
    for (name, count, props) in elements {
        out.push_str(&format!("element {name} {count}\n"));
        for p in *props {
            out.push_str(&format!("property {}\n", p.decl));
        }
    }
    out.push_str("obj_info made for a test\nend_header\n");
    let mut bytes = out.into_bytes();
    let big = format == PlyFormat::BinaryBigEndian;
    for (_, count, props) in elements {
        for k in 0..*count {
            let mut line = Vec::new();
            for p in *props {
                let words: Vec<&str> = p.decl.split_whitespace().collect();
                let values = (p.value)(k);
                match (format, words.as_slice()) {
                    (PlyFormat::Ascii, ["list", ..]) => {
                        line.push(values.len().to_string());
                        line.extend(values.iter().map(|v| v.to_string()));
                    }
                    (PlyFormat::Ascii, _) => line.push(values[0].to_string()),
                    (_, ["list", count, item, _]) => {
                        bytes.extend(encode(count, values.len() as f64, big));
                        values.iter().for_each(|v| bytes.extend(encode(item, *v, big)));
                    }
                    (_, [ty, _]) => bytes.extend(encode(ty, values[0], big)),
                    _ => panic!("bad declaration {}", p.decl),
                }
            }
            if format == PlyFormat::Ascii {
                bytes.extend(format!("{}\n", line.join(" ")).into_bytes());
            }
        }
    }
    bytes
}

/// The cube with the extra vertex properties of every PLY type name (both spellings, signed
/// values negative) around x, y, z, lists before and after a face's `vertex_indices` (or
/// `vertex_index`), and an `edge` element: reads as the cube's OBJ (fan triangulation of its
/// quads, file order) in all three encodings.
fn hand_written_cube(format: PlyFormat, index_name: &'static str) -> Vec<u8> {
    let vertex: Vec<Prop> = vec![
        Prop { decl: "char a", value: |k| vec![-(k as f64)] },
        Prop { decl: "float x", value: |k| vec![cube().0[k][0]] },
        Prop { decl: "uchar red", value: |k| vec![200.0 + k as f64] },
        Prop { decl: "int16 c", value: |_| vec![-300.0] },
        Prop { decl: "double y", value: |k| vec![cube().0[k][1]] },
        Prop { decl: "ushort d", value: |_| vec![60000.0] },
        Prop { decl: "int e", value: |_| vec![-70000.0] },
        Prop { decl: "uint32 f", value: |_| vec![4.0e9] },
        Prop { decl: "float64 z", value: |k| vec![cube().0[k][2]] },
        Prop { decl: "int8 g", value: |_| vec![-5.0] },
        Prop { decl: "float32 nx", value: |_| vec![0.25] },
        Prop { decl: "list uint16 short texture", value: |k| (0..k % 3).map(|i| -(i as f64)).collect() },
        Prop { decl: "uint h", value: |_| vec![7.0] },
        Prop { decl: "uint8 i", value: |_| vec![8.0] },
        Prop { decl: "int32 j", value: |_| vec![-9.0] },
        Prop { decl: "short k", value: |_| vec![-10.0] },
        Prop { decl: "uint16 l", value: |_| vec![11.0] },
    ];
    let face: Vec<Prop> = vec![
        Prop { decl: "uchar flags", value: |_| vec![1.0] },
        Prop {
            decl: if index_name == "vertex_indices" {
                "list uchar int vertex_indices"
            } else {
                "list uint8 uint32 vertex_index"
            },
            value: |k| cube().1[k].iter().map(|&i| i as f64).collect(),
        },
        Prop { decl: "list int8 float texcoord", value: |_| vec![0.5, 0.25, 1.0, 0.0] },
        Prop { decl: "double quality", value: |k| vec![k as f64 / 3.0] },
    ];
    let edge: Vec<Prop> = vec![
        Prop { decl: "int vertex1", value: |k| vec![k as f64] },
        Prop { decl: "uint vertex2", value: |k| vec![((k + 1) % 8) as f64] },
    ];
    ply_file(format, &[("vertex", 8, &vertex), ("edge", 12, &edge), ("face", 6, &face)])
}

#[test]
fn hand_written_ply_with_extra_properties_and_quads_reads_as_its_obj() {
    let (_, _, obj_text) = cube();
    let obj = read_obj_bytes("cube.obj", obj_text.as_bytes()).unwrap();
    assert_eq!(obj.mesh.n_faces(), 12);
    for format in PLY_FORMATS {
        for index_name in ["vertex_indices", "vertex_index"] {
            let bytes = hand_written_cube(format, index_name);
            let what = format!("{format:?}, {index_name}");
            let ply = read_ply_bytes("cube.ply", &bytes).unwrap_or_else(|e| panic!("{what}: {e}"));
            assert_same_reading(&ply, &obj, &what);
            assert!(
                ply.notes.contains(&"6 polygons with more than 3 vertices triangulated as fans".into()),
                "{what}: {:?}",
                ply.notes
            );
            assert!(ply.notes.contains(&"PLY elements ignored: edge (12)".into()), "{what}: {:?}", ply.notes);
        }
    }
    // Windows line ends in the header and the body read the same.
    let crlf = String::from_utf8(hand_written_cube(PlyFormat::Ascii, "vertex_indices"))
        .unwrap()
        .replace('\n', "\r\n");
    assert_same_reading(&read_ply_bytes("crlf.ply", crlf.as_bytes()).unwrap(), &obj, "CRLF");
}

/// OFF with a comment, blank lines, the counts on the keyword's line, colours after the
/// face indices and normals after the coordinates (`NOFF`): the cube's OBJ.
#[test]
fn off_with_comments_counts_on_the_keyword_line_and_colours_reads_as_its_obj() {
    let (p, q, obj_text) = cube();
    let obj = read_obj_bytes("cube.obj", obj_text.as_bytes()).unwrap();
    let mut off = String::from("NOFF 8 6 12  # vertices faces edges\n# the unit cube\n\n");
    for v in &p {
        off.push_str(&format!("{} {} {} 0 0 1\n", v[0], v[1], v[2]));
    }
    for f in &q {
        off.push_str(&format!("4 {} {} {} {} 255 0 0\n\n", f[0], f[1], f[2], f[3]));
    }
    let file = read_off_bytes("cube.off", off.as_bytes()).unwrap();
    assert_same_reading(&file, &obj, "NOFF");
    assert!(file.notes.contains(&"6 polygons with more than 3 vertices triangulated as fans".into()));
    // The counts on their own line, plain `OFF`.
    let plain = off.replacen("NOFF 8 6 12", "OFF\n8 6 12", 1);
    assert_same_reading(&read_off_bytes("cube.off", plain.as_bytes()).unwrap(), &obj, "OFF");
}

fn parse_error(r: fibfluid_geometry::Result<MeshFile>) -> (usize, String) {
    match r {
        Err(GeometryError::Parse { line, message, .. }) => (line, message),
        Err(e) => panic!("expected a parse error, got {e}"),
        Ok(_) => panic!("expected a parse error, the file was accepted"),
    }
}

#[test]
fn malformed_ply_is_a_parse_error_naming_the_line_or_byte() {
    let (p, t) = tetrahedron();
    let mut ascii = Vec::new();
    write_ply_to(&mut ascii, &p, &t, PlyFormat::Ascii).unwrap();
    let ascii = String::from_utf8(ascii).unwrap();
    let ply = |s: &str| parse_error(read_ply_bytes("t.ply", s.as_bytes()));
    read_ply_bytes("t.ply", ascii.as_bytes()).unwrap();
    assert_eq!(ascii.lines().nth(10), Some("0.0 0.0 0.0"), "the first vertex is line 11");
    let cases: Vec<(String, usize, &str)> = vec![
        (ascii.replacen("ply", "plx", 1), 1, "not a PLY file (the first line is not `ply`)"),
        (String::new(), 1, "not a PLY file (no `ply` line)"),
        (ascii.split("end_header").next().unwrap().to_string(), 10, "the header has no `end_header` line"),
        (ascii.replace("format ascii 1.0", "format utf8 1.0"), 2, "unknown PLY format `utf8`"),
        (ascii.replace("format ascii 1.0\n", ""), 0, "the header has no `format` line"),
        (ascii.replace("double y", "float128 y"), 6, "unknown property type `float128`"),
        (ascii.replace("double z", "double w"), 4, "the vertex element has no `z` property"),
        (ascii.replace("vertex_indices", "corners"), 8, "the face element has no `vertex_indices`"),
        (ascii.replace("list uchar int", "list float int"), 9, "it must be an integer type"),
        (ascii.replace("list uchar int", "list uchar float"), 8, "must be a list of integers"),
        (ascii.replace("element face 4", "element polygon 4"), 0, "no `element face` (a point cloud"),
        (ascii.replace("element vertex 4", "element point 4"), 0, "no `element vertex`"),
        (ascii.replace("comment", "remark"), 3, "unknown header line `remark`"),
        (ascii.replace("format ascii 1.0", "format ascii"), 2, "a format line is `format ascii 1.0`"),
        (ascii.replace("element face 4", "element face"), 8, "an element line is `element NAME COUNT`"),
        (ascii.replace("element face 4", "element face four"), 8, "element `face` has a bad count `four`"),
        (ascii.replace("0.0 2.0 0.0", "0.0 NaN 0.0"), 13, "vertex 2: a non-finite coordinate"),
        (ascii.replace("0.0 2.0 0.0", "0.0 2.0"), 13, "vertex 2: fewer values than the header's properties"),
        (
            ascii.replace("0.0 2.0 0.0", "0.0 2.0 0.0 1.0"),
            13,
            "vertex 2: 1 values more than the header's properties",
        ),
        (ascii.replace("0.0 2.0 0.0", "0.0 2,0 0.0"), 13, "vertex 2: bad number `2,0`"),
        (
            ascii.replace("3 0 2 1", "3 0 2 9"),
            15,
            "face 0: face refers to vertex 9 but the file has 4 vertices",
        ),
        (ascii.replace("3 0 2 1", "3 0 -2 1"), 15, "face 0: face refers to vertex -2"),
        (ascii.replace("3 0 2 1", "2 0 2"), 15, "face 0: a face with 2 vertices (at least 3 needed)"),
        (
            ascii.replace("3 0 2 1", "300 0 2 1"),
            15,
            "face 0: 300 does not fit the property's type (0 to 255)",
        ),
        (ascii.replace("3 1 2 3\n", ""), 0, "the file ends before face 3"),
        (
            ascii.replace("element face 4", "element face 40"),
            8,
            "the header claims 40 face elements (at least 104 bytes with those before them) but only 80 bytes follow the header",
        ),
    ];
    for (text, line, fragment) in &cases {
        let (got_line, msg) = ply(text);
        assert!(msg.contains(fragment), "`{fragment}` not in `{msg}`");
        assert_eq!(got_line, *line, "{msg}");
    }
    let (line, msg) = parse_error(read_ply_bytes("t.ply", &[ascii.as_bytes(), b"\xff\n"].concat()));
    assert_eq!(
        (line, msg.as_str()),
        (19, "an ASCII PLY body that is not text (a binary file labelled ascii?)")
    );
    // An open surface reads but is a mesh error, as for OBJ.
    let open = ascii.replace("element face 4", "element face 3").replace("3 1 2 3\n", "");
    assert!(matches!(read_ply_bytes("o.ply", open.as_bytes()), Err(GeometryError::Mesh { .. })));

    // Binary: the element and its byte offset. The header is as long as the ASCII one with
    // a longer format name; vertices take 24 bytes, faces 13.
    for format in [PlyFormat::BinaryLittleEndian, PlyFormat::BinaryBigEndian] {
        let mut bin = Vec::new();
        write_ply_to(&mut bin, &p, &t, format).unwrap();
        let body = bin.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
        read_ply_bytes("t.ply", &bin).unwrap();
        let mut nan = bin.clone();
        let o = body + 2 * 24 + 8;
        let y = if format == PlyFormat::BinaryBigEndian {
            f64::NAN.to_be_bytes()
        } else {
            f64::NAN.to_le_bytes()
        };
        nan[o..o + 8].copy_from_slice(&y);
        let (line, msg) = parse_error(read_ply_bytes("n.ply", &nan));
        assert_eq!(
            (line, msg),
            (0, format!("binary vertex 2 at byte {}: a non-finite coordinate", body + 48))
        );
        let cut = &bin[..bin.len() - 5];
        let (line, msg) = parse_error(read_ply_bytes("c.ply", cut));
        let face3 = body + 4 * 24 + 3 * 13;
        assert_eq!(line, 0);
        assert!(msg.starts_with(&format!("binary face 3 at byte {face3}: the file ends inside it")), "{msg}");
        let mut bad = bin.clone();
        bad[body + 4 * 24 + 1..body + 4 * 24 + 5].copy_from_slice(&if format == PlyFormat::BinaryBigEndian {
            7i32.to_be_bytes()
        } else {
            7i32.to_le_bytes()
        });
        let (_, msg) = parse_error(read_ply_bytes("b.ply", &bad));
        assert_eq!(
            msg,
            format!(
                "binary face 0 at byte {}: face refers to vertex 7 but the file has 4 vertices (0-based)",
                body + 96
            )
        );
    }
}

/// A header that claims 10^12 vertices (or faces, or a skipped element) is refused from its
/// counts and the file's size, at once, before anything is allocated.
#[test]
fn huge_counts_are_refused_before_allocating() {
    let (p, t) = tetrahedron();
    for format in PLY_FORMATS {
        let mut bytes = Vec::new();
        write_ply_to(&mut bytes, &p, &t, format).unwrap();
        for (from, to, what) in [
            ("element vertex 4", "element vertex 1000000000000", "1000000000000 vertex elements"),
            ("element face 4", "element face 1000000000000", "1000000000000 face elements"),
            (
                "element face 4",
                "element edge 1000000000000\nproperty int a\nelement face 4",
                "1000000000000 edge",
            ),
        ] {
            // The body stays as it is: only the header changes.
            let huge = splice_header(&bytes, from, to);
            let (line, msg) = parse_error(read_ply_bytes("huge.ply", &huge));
            assert!(
                msg.contains(&format!("the header claims {what}")) && msg.contains("bytes follow the header"),
                "{msg}"
            );
            assert!(line > 0, "{msg}");
        }
    }
    let (line, msg) = parse_error(read_off_bytes("huge.off", b"OFF\n1000000000000 1 0\n0 0 0\n3 0 0 0\n"));
    assert_eq!(line, 2);
    assert!(msg.starts_with("the header claims 1000000000000 vertices and 1 faces"), "{msg}");
}

/// `bytes` with `from` replaced by `to` in the header only.
fn splice_header(bytes: &[u8], from: &str, to: &str) -> Vec<u8> {
    let end = bytes.windows(11).position(|w| w == b"end_header\n").unwrap();
    let header = String::from_utf8(bytes[..end].to_vec()).unwrap().replacen(from, to, 1);
    [header.as_bytes(), &bytes[end..]].concat()
}

#[test]
fn malformed_off_is_a_parse_error_naming_the_line() {
    let (p, t) = tetrahedron();
    let mut off = Vec::new();
    write_off_to(&mut off, &p, &t).unwrap();
    let off = String::from_utf8(off).unwrap();
    read_off_bytes("t.off", off.as_bytes()).unwrap();
    assert_eq!(off.lines().nth(4), Some("0.0 2.0 0.0"), "vertex 2 is line 5");
    let cases: Vec<(String, usize, &str)> = vec![
        (String::new(), 0, "not an OFF file (it is empty)"),
        (off.replacen("OFF", "PLY", 1), 1, "not an OFF file (it starts with `PLY`, not `OFF`)"),
        (off.replacen("OFF", "4OFF", 1), 1, "(4D or n-dimensional OFF) are not read"),
        (off.replacen("OFF\n", "OFF BINARY\n", 1), 1, "binary OFF is not read"),
        (off.replacen("4 4 0", "4", 1), 2, "expected the counts `vertices faces edges`, found 1 values"),
        (off.replacen("4 4 0", "4 x 0", 1), 2, "bad face count `x`"),
        (off.replacen("0.0 2.0 0.0", "0.0 inf 0.0", 1), 5, "vertex 2 has a non-finite coordinate"),
        (off.replacen("0.0 2.0 0.0", "0.0 2.0", 1), 5, "vertex 2 has 2 coordinates, 3 expected"),
        (off.replacen("0.0 2.0 0.0", "0.0 two 0.0", 1), 5, "bad coordinate `two`"),
        (
            off.replacen("3 0 2 1", "3 0 2 4", 1),
            7,
            "face refers to vertex 4 but the file has 4 vertices (0-based)",
        ),
        (off.replacen("3 0 2 1", "3 0 2 -1", 1), 7, "face refers to vertex -1"),
        (off.replacen("3 0 2 1", "2 0 2", 1), 7, "face 0 has 2 vertices (at least 3 needed)"),
        (off.replacen("3 0 2 1", "4 0 2 1", 1), 7, "face 0 announces 4 vertices but lists 3"),
        (
            off.replacen("3 0 2 1", "18446744073709551615 0 2 1", 1),
            7,
            "face 0 announces 18446744073709551615",
        ),
        (off.replacen("3 1 2 3\n", "", 1), 0, "the file ends after 3 of 4 faces"),
        (off.replacen("4 4 0", "9 4 0", 1), 0, "the file ends after 8 of 9 vertices"),
        (off.replacen("3 1 2 3", "3 1 2 \u{1}", 1), 10, "bad face index"),
    ];
    for (text, line, fragment) in &cases {
        let (got_line, msg) = parse_error(read_off_bytes("t.off", text.as_bytes()));
        assert!(msg.contains(fragment), "`{fragment}` not in `{msg}`");
        assert_eq!(got_line, *line, "{msg}");
    }
    let (line, msg) = parse_error(read_off_bytes("t.off", b"OFF\n3 1 0\n0 0 0\n\xff\n"));
    assert_eq!((line, msg.as_str()), (4, "not a text OFF file (invalid UTF-8)"));
}

fn config(cases: u32) -> ProptestConfig {
    ProptestConfig {
        cases,
        rng_seed: RngSeed::Fixed(0x0ff_91e5),
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

type Reader = fn(&str, &[u8]) -> fibfluid_geometry::Result<MeshFile>;

/// The octahedron in every format this crate writes, and the hand-written binary cube:
/// (name, bytes, reader).
fn octahedron_files() -> Vec<(String, Vec<u8>, Reader)> {
    let (p, t) = octahedron();
    let mut out: Vec<(String, Vec<u8>, Reader)> = Vec::new();
    for format in PLY_FORMATS {
        let mut b = Vec::new();
        write_ply_to(&mut b, &p, &t, format).unwrap();
        out.push((format!("{format:?}"), b, |n, b| read_ply_bytes(n, b)));
    }
    let mut b = Vec::new();
    write_off_to(&mut b, &p, &t).unwrap();
    out.push(("OFF".into(), b, |n, b| read_off_bytes(n, b)));
    out.push((
        "cube PLY LE".into(),
        hand_written_cube(PlyFormat::BinaryLittleEndian, "vertex_index"),
        |n, b| read_ply_bytes(n, b),
    ));
    out
}

proptest! {
    #![proptest_config(config(2_000))]

    /// Any truncation of a good file is an error (never a panic), but for the ASCII files'
    /// final line end; a binary file cut anywhere is an error.
    #[test]
    fn truncation_never_panics(which in 0usize..5, cut in 0.0f64..1.0) {
        let (name, bytes, read) = &octahedron_files()[which];
        let n = (cut * bytes.len() as f64) as usize;
        let result = read(name, &bytes[..n]);
        if n + 1 < bytes.len() {
            prop_assert!(result.is_err(), "{name} cut to {n} of {} bytes was accepted", bytes.len());
        }
        if let Err(e) = result {
            prop_assert!(!e.to_string().contains('\n'), "one line: {e}");
        }
    }

    /// A corrupted byte anywhere gives `Ok` or `Err`, never a panic.
    #[test]
    fn a_corrupted_byte_never_panics(which in 0usize..5, at in 0.0f64..1.0, byte in any::<u8>()) {
        let (name, mut bytes, read) = octahedron_files().swap_remove(which);
        let i = ((at * bytes.len() as f64) as usize).min(bytes.len() - 1);
        bytes[i] = byte;
        let _ = read(&name, &bytes);
    }
}
