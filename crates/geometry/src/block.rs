//! Test and benchmark bodies: the triangulated surface of an axis-aligned box.

use std::collections::HashMap;

use crate::Vec3;

/// The surface of the box `lo + [0, n_x s] x [0, n_y s] x [0, n_z s]`, triangulated on a
/// grid of spacing `s` (two triangles per square), outward.
pub fn box_surface(lo: Vec3, n: [usize; 3], s: f64) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut index: HashMap<[usize; 3], u32> = HashMap::new();
    let mut pos = Vec::new();
    let mut tris = Vec::new();
    let mut vertex = |g: [usize; 3], pos: &mut Vec<Vec3>| {
        *index.entry(g).or_insert_with(|| {
            pos.push([lo[0] + g[0] as f64 * s, lo[1] + g[1] as f64 * s, lo[2] + g[2] as f64 * s]);
            (pos.len() - 1) as u32
        })
    };
    for a in 0..3 {
        let (b, c) = ((a + 1) % 3, (a + 2) % 3);
        for side in [0, n[a]] {
            for i in 0..n[b] {
                for j in 0..n[c] {
                    let g = |di: usize, dj: usize| {
                        let mut g = [0; 3];
                        g[a] = side;
                        g[b] = i + di;
                        g[c] = j + dj;
                        g
                    };
                    let q = [g(0, 0), g(1, 0), g(1, 1), g(0, 1)].map(|g| vertex(g, &mut pos));
                    // e_b x e_c = e_a: counter-clockwise in (b, c) points along +a.
                    if side == n[a] {
                        tris.push([q[0], q[1], q[2]]);
                        tris.push([q[0], q[2], q[3]]);
                    } else {
                        tris.push([q[0], q[2], q[1]]);
                        tris.push([q[0], q[3], q[2]]);
                    }
                }
            }
        }
    }
    (pos, tris)
}
