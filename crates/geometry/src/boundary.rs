//! The boundary of a body as one type for its two forms: a closed triangle surface (3D)
//! or a closed polygon (the paper's 2D example), with the shape functions a simulation
//! needs on any positions: vertex area vectors, enclosed volume and its exact gradient.

use crate::vec3::scale;
use crate::{Polygon, Vec3, raw_vertex_vectors, vertex_area_vectors, volume};

/// The connectivity of a body's boundary; positions are passed to each query, so one
/// boundary serves the rest shape and every deformed shape.
#[derive(Clone, Debug, PartialEq)]
pub enum Boundary {
    /// A closed, outward-oriented triangle surface.
    Surface {
        /// Triangles (vertex indices).
        triangles: Vec<[u32; 3]>,
    },
    /// A closed polygon in the xy plane (vertices in order; z ignored).
    Polygon,
}

impl Boundary {
    /// Number of axes the body moves along (3, or 2 for a polygon).
    pub fn axes(&self) -> usize {
        match self {
            Boundary::Surface { .. } => 3,
            Boundary::Polygon => 2,
        }
    }

    /// Vertex area vectors `S_i` (Eq. 2) of the shape `positions` (z = 0 in 2D). A
    /// degenerate polygon (fewer than 3 finite points) has zero vectors.
    pub fn vertex_area_vectors(&self, positions: &[Vec3]) -> Vec<Vec3> {
        match self {
            Boundary::Surface { triangles } => vertex_area_vectors(positions, triangles),
            Boundary::Polygon => match polygon_at(positions) {
                Some(p) => p.vertex_area_vectors().into_iter().map(|v| [v[0], v[1], 0.0]).collect(),
                None => vec![[0.0; 3]; positions.len()],
            },
        }
    }

    /// Enclosed volume (area for a polygon) of the shape `positions`.
    pub fn volume(&self, positions: &[Vec3]) -> f64 {
        match self {
            Boundary::Surface { triangles } => volume(positions, triangles),
            Boundary::Polygon => polygon_at(positions).map(|p| p.signed_area().abs()).unwrap_or(0.0),
        }
    }

    /// Exact gradient of [`volume`](Self::volume) with respect to each vertex: `R_i / 3`
    /// on a surface, `perp(s_{i+1} - s_{i-1}) / 2` on a counter-clockwise polygon.
    pub fn volume_gradient(&self, positions: &[Vec3]) -> Vec<Vec3> {
        match self {
            Boundary::Surface { triangles } => {
                raw_vertex_vectors(positions, triangles).into_iter().map(|r| scale(r, 1.0 / 3.0)).collect()
            }
            Boundary::Polygon => {
                let n = positions.len();
                let sign = polygon_at(positions).map(|p| p.signed_area().signum()).unwrap_or(1.0);
                (0..n)
                    .map(|i| {
                        let (a, b) = (positions[(i + n - 1) % n], positions[(i + 1) % n]);
                        [0.5 * sign * (b[1] - a[1]), -0.5 * sign * (b[0] - a[0]), 0.0]
                    })
                    .collect()
            }
        }
    }
}

fn polygon_at(positions: &[Vec3]) -> Option<Polygon> {
    Polygon::new(positions.iter().map(|p| [p[0], p[1]]).collect())
}
