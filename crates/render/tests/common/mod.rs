//! Test meshes shared by the integration tests and the samples example.
#![allow(dead_code)]

/// A regular icosahedron of circumradius ~1.9 centered at the origin.
pub fn icosahedron() -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let positions = vec![
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
    let triangles = vec![
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
    (positions, triangles)
}

/// Unit cube `[0,1]^3` whose six faces do not share vertices (4 vertices
/// and 2 triangles per face), so a per-vertex scalar can single out one face.
/// Face order: -x, +x, -y, +y, -z, +z; face `f` owns vertices `4f..4f+4`.
pub fn split_cube() -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for axis in 0..3 {
        for side in [0.0, 1.0] {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let base = positions.len() as u32;
            for (a, b) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
                let mut p = [0.0; 3];
                p[axis] = side;
                p[u] = a;
                p[v] = b;
                positions.push(p);
            }
            triangles.push([base, base + 1, base + 2]);
            triangles.push([base, base + 2, base + 3]);
        }
    }
    (positions, triangles)
}

/// A bumpy closed sphere with `2 * n_theta * (n_phi - 1)` triangles
/// (poles are single vertices).
pub fn bumpy_sphere(n_theta: usize, n_phi: usize) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    use std::f64::consts::PI;
    let mut positions = vec![[0.0, 1.0, 0.0]];
    for j in 1..n_phi {
        let phi = PI * j as f64 / n_phi as f64;
        for i in 0..n_theta {
            let theta = 2.0 * PI * i as f64 / n_theta as f64;
            let r = 1.0 + 0.08 * (5.0 * theta).sin() * (4.0 * phi).sin();
            positions.push([r * phi.sin() * theta.cos(), r * phi.cos(), r * phi.sin() * theta.sin()]);
        }
    }
    positions.push([0.0, -1.0, 0.0]);
    let south = (positions.len() - 1) as u32;
    let ring = |j: usize, i: usize| (1 + (j - 1) * n_theta + i % n_theta) as u32;
    let mut triangles = Vec::new();
    for i in 0..n_theta {
        triangles.push([0, ring(1, i + 1), ring(1, i)]);
        triangles.push([south, ring(n_phi - 1, i), ring(n_phi - 1, i + 1)]);
    }
    for j in 1..n_phi - 1 {
        for i in 0..n_theta {
            let (a, b) = (ring(j, i), ring(j, i + 1));
            let (c, d) = (ring(j + 1, i), ring(j + 1, i + 1));
            triangles.push([a, b, d]);
            triangles.push([a, d, c]);
        }
    }
    (positions, triangles)
}

/// Decodes PNG bytes into (width, height, RGB pixels row by row).
pub fn decode(png: &[u8]) -> (u32, u32, Vec<[u8; 3]>) {
    let pixmap = tiny_skia::Pixmap::decode_png(png).expect("valid PNG");
    let pixels = pixmap
        .pixels()
        .iter()
        .map(|p| {
            let c = p.demultiply();
            [c.red(), c.green(), c.blue()]
        })
        .collect();
    (pixmap.width(), pixmap.height(), pixels)
}
