//! The result guards of an interactive body's frames: the batch answers' guards and limits
//! (`fibfluid_sim::result_guards`), set up once per surface and measured per frame in one
//! pass over the vertices and a few over the faces.

use fibfluid_geometry::Vec3;
use fibfluid_geometry::vec3::{cross, dist, dot, norm, sub};
use fibfluid_sim::result_guards::{Measures, ResultChecks, ResultWarning};

#[cfg(doc)]
use fibfluid_sim::result_guards::check_answer;

/// Why [`FrameGuards`] cannot be set up or cannot check a frame.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum FrameGuardError {
    /// A face refers to a vertex beyond the rest shape.
    #[error("face {face} refers to vertex {vertex}, beyond the {count} vertices of the rest shape")]
    FaceVertex {
        /// The face.
        face: usize,
        /// The vertex it names.
        vertex: u32,
        /// Vertices of the rest shape.
        count: usize,
    },
    /// A frame with another number of positions than the rest shape has vertices.
    #[error("the frame has {found} positions for a rest shape of {count} vertices")]
    Count {
        /// Positions of the frame.
        found: usize,
        /// Vertices of the rest shape.
        count: usize,
    },
    /// A position, a displacement or the volume is not finite: the frame is an error, never
    /// a warning.
    #[error(
        "the answer is not finite at vertex {vertex}: the tissue is far too soft for the load, or the constraints do not hold the body"
    )]
    NonFinite {
        /// The first vertex whose position or displacement is not finite (0 when only the
        /// volume overflows).
        vertex: usize,
    },
}

/// The result guards of every frame of a triangle surface: [`check_answer`]'s guards and
/// limits, set up once (the rest volume, the body's size, the angle between each face's
/// normal and its neighbourhood's at rest) so that a frame costs one pass over the vertices
/// (finiteness, the largest displacement) and three over the faces (the volume by the
/// divergence theorem; the faces turned inside out: the raw vertex vectors, then each
/// face's angle to its neighbourhood), and allocates one vector of the vertices' raw
/// vectors.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameGuards {
    rest: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
    /// Per face, the angle between its normal and its neighbourhood's at rest
    /// ([`fibfluid_geometry::neighbourhood_angles`]).
    rest_angles: Vec<f64>,
    rest_volume: f64,
    size: f64,
}

impl FrameGuards {
    /// The guards of the surface `triangles` over the rest shape `rest` (vertices no face
    /// uses are allowed: they count for the displacement only).
    pub fn new(rest: &[Vec3], triangles: &[[u32; 3]]) -> Result<Self, FrameGuardError> {
        let count = rest.len();
        for (face, t) in triangles.iter().enumerate() {
            if let Some(&vertex) = t.iter().find(|&&v| v as usize >= count) {
                return Err(FrameGuardError::FaceVertex { face, vertex, count });
            }
        }
        let (lo, hi) = fibfluid_geometry::bounding_box(rest);
        Ok(Self {
            rest: rest.to_vec(),
            triangles: triangles.to_vec(),
            rest_angles: fibfluid_geometry::neighbourhood_angles(triangles, rest),
            rest_volume: fibfluid_geometry::volume(rest, triangles),
            size: dist(lo, hi),
        })
    }

    /// The warnings of the frame `positions` (one per rest vertex, in the same order);
    /// empty when every guard holds. A non-finite position, displacement or volume is
    /// [`FrameGuardError::NonFinite`].
    pub fn check(
        &self,
        positions: &[Vec3],
        checks: ResultChecks,
    ) -> Result<Vec<ResultWarning>, FrameGuardError> {
        let count = self.rest.len();
        if positions.len() != count {
            return Err(FrameGuardError::Count { found: positions.len(), count });
        }
        let mut largest = 0.0_f64;
        for (vertex, (p, r)) in positions.iter().zip(&self.rest).enumerate() {
            let length = norm(sub(*p, *r));
            if !(p.iter().all(|x| x.is_finite()) && length.is_finite()) {
                return Err(FrameGuardError::NonFinite { vertex });
            }
            largest = largest.max(length);
        }
        let six_volume: f64 = self
            .triangles
            .iter()
            .map(|t| dot(positions[t[0] as usize], cross(positions[t[1] as usize], positions[t[2] as usize])))
            .sum();
        let inverted = fibfluid_geometry::faces_turned_given(&self.rest_angles, &self.triangles, positions);
        let volume = six_volume / 6.0;
        if !volume.is_finite() {
            return Err(FrameGuardError::NonFinite { vertex: 0 });
        }

        let measures = Measures { rest_volume: self.rest_volume, volume, largest, size: self.size, inverted };
        Ok(measures.judge(checks))
    }

    /// Vertices of the rest shape (the length [`check`](Self::check) expects).
    pub fn n_vertices(&self) -> usize {
        self.rest.len()
    }
}
