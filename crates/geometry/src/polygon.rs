//! The 2D variant used by the paper's worked example: a closed polygon whose edges are the
//! "faces" (REFERENCE §1).

use crate::vec3::Vec3;

/// A closed polygon in the plane (either orientation).
#[derive(Clone, Debug, PartialEq)]
pub struct Polygon {
    points: Vec<[f64; 2]>,
}

impl Polygon {
    /// A polygon from its vertices in order; at least 3.
    pub fn new(points: Vec<[f64; 2]>) -> Option<Self> {
        (points.len() >= 3 && points.iter().flatten().all(|c| c.is_finite())).then_some(Self { points })
    }

    /// Vertices.
    pub fn points(&self) -> &[[f64; 2]] {
        &self.points
    }

    /// Number of vertices.
    pub fn n_vertices(&self) -> usize {
        self.points.len()
    }

    /// Signed area (positive when counter-clockwise).
    pub fn signed_area(&self) -> f64 {
        let n = self.points.len();
        (0..n)
            .map(|i| {
                let (a, b) = (self.points[i], self.points[(i + 1) % n]);
                a[0] * b[1] - b[0] * a[1]
            })
            .sum::<f64>()
            / 2.0
    }

    /// Edge "area vectors": outward normal of edge (i, i+1) scaled by its length.
    pub fn edge_area_vectors(&self) -> Vec<[f64; 2]> {
        let n = self.points.len();
        let sign = if self.signed_area() >= 0.0 { 1.0 } else { -1.0 };
        (0..n)
            .map(|i| {
                let (a, b) = (self.points[i], self.points[(i + 1) % n]);
                let e = [b[0] - a[0], b[1] - a[1]];
                [sign * e[1], -sign * e[0]]
            })
            .collect()
    }

    /// Vertex area vectors `S_i = C (A_{i-1,i} + A_{i,i+1})`, `C = sum|A| / sum|R|`.
    pub fn vertex_area_vectors(&self) -> Vec<[f64; 2]> {
        let n = self.points.len();
        let a = self.edge_area_vectors();
        let r: Vec<[f64; 2]> = (0..n)
            .map(|i| {
                let (p, q) = (a[(i + n - 1) % n], a[i]);
                [p[0] + q[0], p[1] + q[1]]
            })
            .collect();
        let len = |v: [f64; 2]| v[0].hypot(v[1]);
        let c = a.iter().map(|v| len(*v)).sum::<f64>() / r.iter().map(|v| len(*v)).sum::<f64>();
        r.into_iter().map(|v| [c * v[0], c * v[1]]).collect()
    }

    /// Edges (i, i+1) as vertex pairs with the lower index first.
    pub fn edges(&self) -> Vec<[u32; 2]> {
        let n = self.points.len() as u32;
        (0..n)
            .map(|i| {
                let j = (i + 1) % n;
                [i.min(j), i.max(j)]
            })
            .collect()
    }

    /// Positions lifted to 3D (z = 0).
    pub fn positions_3d(&self) -> Vec<Vec3> {
        self.points.iter().map(|p| [p[0], p[1], 0.0]).collect()
    }
}
