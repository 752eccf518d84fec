//! Icosphere generator: midpoint subdivision of the icosahedron, new points pushed to the
//! sphere (the paper's sphere cases are levels 1, 2, 3 with 42, 162, 642 vertices).

use std::collections::HashMap;

use crate::mesh::TriMesh;
use crate::vec3::{Vec3, norm, scale};

/// The icosahedron (level 0) or its `level`-times subdivided sphere of radius `radius`,
/// outward oriented, vertex 0 first of the icosahedron's vertices.
///
/// # Panics
/// When `radius` is not a positive number whose squares and cubes f64 can hold (roughly
/// 1e-77 to 1e77): the validation of the result then fails. For a radius from user input,
/// build at radius 1, scale, and [`TriMesh::validate`] (which returns the error).
pub fn icosphere(level: u32, radius: f64) -> TriMesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut pos: Vec<Vec3> = vec![
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ];
    for p in &mut pos {
        *p = scale(*p, 1.0 / norm(*p));
    }
    let mut tris: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..level {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut next = Vec::with_capacity(tris.len() * 4);
        let mut midpoint = |a: u32, b: u32, pos: &mut Vec<Vec3>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let (p, q) = (pos[a as usize], pos[b as usize]);
                let m = [(p[0] + q[0]) / 2.0, (p[1] + q[1]) / 2.0, (p[2] + q[2]) / 2.0];
                pos.push(scale(m, 1.0 / norm(m)));
                (pos.len() - 1) as u32
            })
        };
        for [a, b, c] in tris {
            let ab = midpoint(a, b, &mut pos);
            let bc = midpoint(b, c, &mut pos);
            let ca = midpoint(c, a, &mut pos);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        tris = next;
    }
    let pos = pos.into_iter().map(|p| scale(p, radius)).collect();
    let mut mesh = TriMesh::new(pos, tris).expect("the icosphere is well formed");
    mesh.validate().expect("the icosphere is a closed surface");
    mesh
}

/// `n` points spread evenly over the unit sphere (Fibonacci lattice), y up.
pub fn fibonacci_sphere(n: usize) -> Vec<Vec3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - y * y).max(0.0).sqrt();
            let t = golden * i as f64;
            [r * t.cos(), y, r * t.sin()]
        })
        .collect()
}

/// A hollow sphere: icospheres (`level`) of radii `inner` and `outer`, the inner one turned
/// to face the hole (a body with one cavity). Returns the positions (the outer sphere's
/// first), the outer faces and the cavity's faces.
///
/// # Panics
/// As [`icosphere`].
pub fn hollow_icosphere(inner: f64, outer: f64, level: u32) -> (Vec<Vec3>, Vec<[u32; 3]>, Vec<[u32; 3]>) {
    let a = icosphere(level, outer);
    let b = icosphere(level, inner);
    let n = a.n_vertices() as u32;
    let mut positions = a.positions().to_vec();
    positions.extend_from_slice(b.positions());
    let cavity = b.triangles().iter().map(|t| [t[0] + n, t[2] + n, t[1] + n]).collect();
    (positions, a.triangles().to_vec(), cavity)
}
