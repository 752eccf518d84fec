//! Helpers shared by the acceptance tests of the geometry crate. Everything here is written
//! independently of the crate's own implementation (plain loops over the triangles), so that
//! the tests compare the crate against a second computation rather than against itself.

#![allow(dead_code)]

use std::path::PathBuf;

use fibfluid_geometry::{MeshFile, TriMesh, load_mesh};

/// Every mesh file of the fixture folder, with the topology it is known to have
/// (genus 0 for the sphere-like bodies, genus 1 for the torus).
pub const FIXTURES: &[(&str, i64)] = &[
    ("Bunny.stl", 0),
    ("cube.obj", 0),
    ("dome.obj", 0),
    ("hollow-sphere.obj", 0),
    ("icosahedron.obj", 0),
    ("icosphere-1.obj", 0),
    ("icosphere-2.obj", 0),
    ("icosphere-3.obj", 0),
    ("lesion.obj", 0),
    ("liver-smooth.obj", 0),
    ("liver.obj", 0),
    ("liver2.obj", 0),
    ("slab.obj", 0),
    ("spot.obj", 0),
    ("tongue.obj", 0),
    ("torus2_for_collision.obj", 1),
];

/// Path of a file in `fixtures/meshes`.
pub fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/meshes").join(name)
}

/// Loads a fixture through the crate's reader, panicking with the error on failure.
pub fn load(name: &str) -> MeshFile {
    load_mesh(fixture(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

pub type V3 = [f64; 3];

pub fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

pub fn mul(a: V3, s: f64) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}

pub fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub fn cross(a: V3, b: V3) -> V3 {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

pub fn norm(a: V3) -> f64 {
    dot(a, a).sqrt()
}

/// Face area vector exactly as REFERENCE §1 writes it, `A = (v1 - v2) x (v2 - v3) / 2`,
/// evaluated in that order so that tolerance decisions made on it (the exit test) are
/// bit-for-bit reproducible.
pub fn face_vector(v1: V3, v2: V3, v3: V3) -> V3 {
    mul(cross(sub(v1, v2), sub(v2, v3)), 0.5)
}

/// Face area vectors of a mesh by the formula above.
pub fn face_vectors(m: &TriMesh) -> Vec<V3> {
    let p = m.positions();
    m.triangles().iter().map(|t| face_vector(p[t[0] as usize], p[t[1] as usize], p[t[2] as usize])).collect()
}

/// Sum of face areas, computed with a different (but equivalent) cross product,
/// `(v2 - v1) x (v3 - v1) / 2`, so that it is a second computation of the same number.
pub fn area_independent(positions: &[V3], triangles: &[[u32; 3]]) -> f64 {
    triangles
        .iter()
        .map(|t| {
            let (a, b, c) = (positions[t[0] as usize], positions[t[1] as usize], positions[t[2] as usize]);
            0.5 * norm(cross(sub(b, a), sub(c, a)))
        })
        .sum()
}

/// Enclosed volume as a sum of signed tetrahedra against the vertex centroid (a different
/// apex than the crate's origin; the result is the same in exact arithmetic).
pub fn volume_independent(positions: &[V3], triangles: &[[u32; 3]]) -> f64 {
    let n = positions.len() as f64;
    let c = positions.iter().fold([0.0; 3], |s, p| add(s, *p));
    let c = mul(c, 1.0 / n);
    triangles
        .iter()
        .map(|t| {
            let a = sub(positions[t[0] as usize], c);
            let b = sub(positions[t[1] as usize], c);
            let d = sub(positions[t[2] as usize], c);
            dot(a, cross(b, d))
        })
        .sum::<f64>()
        / 6.0
}

/// Raw vertex vectors `R_i = sum of A_k over the faces touching i`, by a plain loop.
pub fn raw_vectors(m: &TriMesh) -> Vec<V3> {
    let mut r = vec![[0.0; 3]; m.n_vertices()];
    for (t, a) in m.triangles().iter().zip(face_vectors(m)) {
        for &v in t {
            r[v as usize] = add(r[v as usize], a);
        }
    }
    r
}

/// Rotation matrix of the unit quaternion `q / |q|` (w, x, y, z).
pub fn rotation(q: [f64; 4]) -> [V3; 3] {
    let l = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    let [w, x, y, z] = q.map(|c| c / l);
    [
        [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)],
        [2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x)],
        [2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)],
    ]
}

/// Matrix times vector.
pub fn apply(r: &[V3; 3], v: V3) -> V3 {
    [dot(r[0], v), dot(r[1], v), dot(r[2], v)]
}

/// Exit test of REFERENCE §2 written out over the triangle list: does fiber (i, j) leave the
/// body at its end i? Uses the crate's published tolerance constant.
pub fn exits_at(m: &TriMesh, faces: &[V3], i: usize, j: usize, tol: f64) -> bool {
    let p = m.positions();
    let d = sub(p[j], p[i]);
    let ld = norm(d);
    m.triangles().iter().zip(faces).any(|(t, a)| t.contains(&(i as u32)) && dot(*a, d) > tol * norm(*a) * ld)
}

/// OBJ text of a mesh (1-based faces), for tests that feed hand-built meshes to the reader.
pub fn obj_text(positions: &[V3], triangles: &[[u32; 3]]) -> String {
    let mut s = String::new();
    for p in positions {
        s.push_str(&format!("v {:?} {:?} {:?}\n", p[0], p[1], p[2]));
    }
    for t in triangles {
        s.push_str(&format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1));
    }
    s
}

/// The regular octahedron with circumradius 1, outward faces.
pub fn octahedron() -> (Vec<V3>, Vec<[u32; 3]>) {
    let p = vec![
        [1.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
    ];
    // Upper faces (x, y, +z) counter-clockwise seen from outside, lower ones reversed.
    let t = vec![[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]];
    (p, t)
}

/// A tetrahedron with small-integer corners, outward faces.
pub fn tetrahedron() -> (Vec<V3>, Vec<[u32; 3]>) {
    let p = vec![[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.0]];
    let t = vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    (p, t)
}
