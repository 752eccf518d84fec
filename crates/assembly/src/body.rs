//! The body as the assembly sees it.

use fibfluid_geometry::{FiberSet, Vec3};

/// The body as the assembly sees it (a triangle mesh or the paper's 2D polygon).
#[derive(Clone, Copy, Debug)]
pub struct Body<'a> {
    /// 2 (polygon) or 3 (surface).
    pub axes: usize,
    /// Positions the stiffness is computed on.
    pub positions: &'a [Vec3],
    /// Vertex area vectors S of that shape.
    pub vertex_areas: &'a [Vec3],
    /// Surface edges (surface fibers), each once.
    pub edges: &'a [[u32; 2]],
    /// Kept bulk fibers.
    pub fibers: &'a FiberSet,
    /// Rest positions, for strain-dependent materials (None = `positions`).
    pub rest_positions: Option<&'a [Vec3]>,
}
