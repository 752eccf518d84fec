//! The segment–triangle crossing test (Chirkov's structure, exact predicates).
//!
//! Chirkov's fast test first compares the signed distances of the two segment endpoints to
//! the triangle's plane, then checks the plane crossing against the three edges. Here both
//! stages use Shewchuk's exact `orient3d` (crate `robust`), so the classification is exact
//! for f64 input and the grazing cases follow an explicit policy instead of rounding:
//!
//! | configuration | [`Crossing`] | removes a fiber? |
//! |---|---|---|
//! | the open segment passes through the triangle's interior | `Interior` | yes |
//! | ... through an edge (not a vertex) | `Edge` | yes |
//! | ... through a vertex | `Vertex` | yes |
//! | segment and triangle coplanar | `Coplanar` | no (the fiber runs along the surface) |
//! | an endpoint lies on the plane, the other off it | `None` (the open segment misses) | no |
//!
//! Faces incident to a fiber's own end vertices are excluded by topology before this test.

use robust::{Coord3D, orient3d};

use crate::vec3::Vec3;

/// How a segment meets a triangle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Crossing {
    /// They do not meet (the open segment).
    None,
    /// The segment crosses the triangle's interior.
    Interior,
    /// The segment passes exactly through an edge.
    Edge,
    /// The segment passes exactly through a vertex.
    Vertex,
    /// The segment lies in the triangle's plane.
    Coplanar,
}

impl Crossing {
    /// Whether the policy counts this as the fiber leaving the body.
    pub fn removes_fiber(self) -> bool {
        matches!(self, Crossing::Interior | Crossing::Edge | Crossing::Vertex)
    }
}

#[inline]
fn c(p: Vec3) -> Coord3D<f64> {
    Coord3D { x: p[0], y: p[1], z: p[2] }
}

/// Classifies the open segment (p, q) against triangle (a, b, c) exactly.
pub fn segment_triangle(p: Vec3, q: Vec3, a: Vec3, b: Vec3, tc: Vec3) -> Crossing {
    let op = orient3d(c(a), c(b), c(tc), c(p));
    let oq = orient3d(c(a), c(b), c(tc), c(q));
    if op == 0.0 && oq == 0.0 {
        return Crossing::Coplanar;
    }
    if op == 0.0 || oq == 0.0 || (op > 0.0) == (oq > 0.0) {
        return Crossing::None;
    }
    let e1 = orient3d(c(p), c(q), c(a), c(b));
    let e2 = orient3d(c(p), c(q), c(b), c(tc));
    let e3 = orient3d(c(p), c(q), c(tc), c(a));
    let pos = (e1 > 0.0) as u8 + (e2 > 0.0) as u8 + (e3 > 0.0) as u8;
    let neg = (e1 < 0.0) as u8 + (e2 < 0.0) as u8 + (e3 < 0.0) as u8;
    if pos > 0 && neg > 0 {
        return Crossing::None;
    }
    match 3 - pos - neg {
        0 => Crossing::Interior,
        1 => Crossing::Edge,
        _ => Crossing::Vertex,
    }
}
