//! Grasps: a prescribed rigid motion of a patch of surface vertices, imposed inside the
//! Newton loop by an augmented Lagrangian (as the plates' contact, [`super::contact`]).
//!
//! A grasp moves its patch rigidly: at load factor `t` each patch vertex `p` (rest position
//! `X_p`, embedded in its cell with trilinear weights `w`) is asked to be at
//! `y_p(t) = c + t T + R(t theta) (X_p - c)`, with `c` the patch's rest centroid (the mean of
//! its vertices), `T` the translation and `theta` the rotation vector (radians) at the full
//! load, so load stepping ramps the grasp with the loads and plates. The error
//! `g_p = x_p - y_p` (`x_p = X_p + sum_b w_b u_b`) enters the energy as
//! `lambda_p . g_p + k_p / 2 |g_p|^2`, with `k_p = GRASP_PENALTY * E / h * a_p` (`a_p` a third
//! of the area of the vertex's triangles) and `lambda_p` the force kept from the previous
//! augmentation (0 during the load steps: a penalty). After the full load converges, Uzawa's
//! update `lambda_p <- lambda_p + k_p g_p` repeats until the largest `|g_p|` is below
//! `GRASP_TOLERANCE * h`. The constraint is an equality, so its tangent `k_p w w^T` (per
//! axis) is constant.

use fibfluid_geometry::Vec3;
use fibfluid_geometry::vec3::{add, cross, norm, scale, sub};
use serde::Serialize;

use crate::error::{FemError, Result};
use crate::grid::SparseGrid;

/// The grasp's penalty, in units of `E / h` per unit area of the grasped surface (the
/// contact's, [`super::CONTACT_PENALTY`]); the augmentations remove the error it leaves.
pub const GRASP_PENALTY: f64 = 100.0;

/// Augmentations stop when every grasped vertex is within this fraction of a cell of its
/// prescribed position. (1e-3, the contact's, left 0.3 % of the force of a 1 % pull on
/// the unit cube at 4 cells: a grasp's motion can be much smaller than a cell; 1e-5 left
/// the surface 2.4e-6 from the answer with the patch held exactly.)
pub const GRASP_TOLERANCE: f64 = 1e-7;

/// A rigid motion prescribed to a patch of surface vertices (a grasper's jaws holding it).
#[derive(Debug, Clone, PartialEq)]
pub struct Grasp {
    /// The grasped surface vertices (indices into the body's surface positions).
    pub vertices: Vec<usize>,
    /// The patch's translation at the full load (m).
    pub translation: Vec3,
    /// The patch's rotation vector at the full load (radians, about its rest centroid).
    pub rotation: Vec3,
}

impl Grasp {
    /// The vertices whose rest position lies within `radius` of vertex `centre`'s (the
    /// interactive grasp's patch); `centre` itself is always one. Empty when `centre` is
    /// out of range.
    pub fn patch(positions: &[Vec3], centre: usize, radius: f64) -> Vec<usize> {
        let Some(&c) = positions.get(centre) else { return Vec::new() };
        (0..positions.len())
            .filter(|&v| v == centre || fibfluid_geometry::vec3::dist(positions[v], c) <= radius)
            .collect()
    }
}

/// What a grasp does at the end of a solve.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GraspRecord {
    /// Vertices in the patch.
    pub vertices: usize,
    /// The force the tissue exerts on the grasper (N).
    pub force: Vec3,
    /// The moment the tissue exerts on the grasper about the patch's prescribed centroid
    /// `c + T` (N m).
    pub moment: Vec3,
    /// The largest distance of a grasped vertex from its prescribed position (m).
    pub error: f64,
}

/// One grasped vertex: its rest position, embedding and penalty.
#[derive(Debug, Clone, Copy)]
pub(crate) struct GraspPoint {
    pub(crate) grasp: usize,
    pub(crate) rest: Vec3,
    pub(crate) nodes: [usize; 8],
    pub(crate) weights: [f64; 8],
    /// `k_p` (N/m).
    pub(crate) stiffness: f64,
}

impl GraspPoint {
    fn position(&self, u: &[Vec3]) -> Vec3 {
        let mut x = self.rest;
        for b in 0..8 {
            for a in 0..3 {
                x[a] += self.weights[b] * u[self.nodes[b]][a];
            }
        }
        x
    }
}

/// The grasps of a body: their motions, rest centroids and points.
#[derive(Debug, Clone, Default)]
pub(crate) struct GraspSet {
    pub(crate) motions: Vec<(Vec3, Vec3)>,
    pub(crate) centroids: Vec<Vec3>,
    pub(crate) counts: Vec<usize>,
    pub(crate) points: Vec<GraspPoint>,
}

/// The rotation matrix of rotation vector `w` (Rodrigues).
fn rotation_matrix(w: Vec3) -> [Vec3; 3] {
    let angle = norm(w);
    if angle == 0.0 {
        return [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    }
    let k = scale(w, 1.0 / angle);
    let (s, c) = angle.sin_cos();
    std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            let kron = if i == j { 1.0 } else { 0.0 };
            let skew = match (i, j) {
                (0, 1) => -k[2],
                (0, 2) => k[1],
                (1, 0) => k[2],
                (1, 2) => -k[0],
                (2, 0) => -k[1],
                (2, 1) => k[0],
                _ => 0.0,
            };
            c * kron + s * skew + (1.0 - c) * k[i] * k[j]
        })
    })
}

impl GraspSet {
    /// The grasps on `grid`'s surface, with the penalty `beta` per unit area.
    ///
    /// Errors: a vertex out of range, an empty patch, a non-finite motion.
    pub(crate) fn new(grid: &SparseGrid, grasps: &[Grasp], beta: f64) -> Result<Self> {
        let pos = grid.surface_positions();
        let mut share = vec![0.0; pos.len()];
        for t in grid.surface_triangles() {
            let c = t.map(|v| pos[v as usize]);
            let area = 0.5 * norm(cross(sub(c[1], c[0]), sub(c[2], c[0])));
            t.iter().for_each(|&v| share[v as usize] += area / 3.0);
        }
        let floor = 1e-3 * grid.cell_size().powi(2);
        let mut set = GraspSet::default();
        for (k, g) in grasps.iter().enumerate() {
            if g.translation.iter().chain(&g.rotation).any(|v| !v.is_finite()) {
                return Err(FemError::NonFinite { what: "grasp" });
            }
            if g.vertices.is_empty() {
                return Err(FemError::EmptyGrasp { grasp: k });
            }
            let mut centroid = [0.0; 3];
            for &v in &g.vertices {
                let e = grid
                    .embedding()
                    .get(v)
                    .ok_or(FemError::VertexOutOfRange { vertex: v, vertices: pos.len() })?;
                centroid = add(centroid, pos[v]);
                set.points.push(GraspPoint {
                    grasp: k,
                    rest: pos[v],
                    nodes: e.nodes,
                    weights: e.weights,
                    stiffness: beta * share[v].max(floor),
                });
            }
            set.centroids.push(scale(centroid, 1.0 / g.vertices.len() as f64));
            set.motions.push((g.translation, g.rotation));
            set.counts.push(g.vertices.len());
        }
        Ok(set)
    }

    /// Per grasp, the rotation matrix at load factor `t`.
    pub(crate) fn rotations(&self, t: f64) -> Vec<[Vec3; 3]> {
        self.motions.iter().map(|(_, w)| rotation_matrix(scale(*w, t))).collect()
    }

    /// The prescribed position of `p` at load factor `t` (`rotations` of that `t`).
    pub(crate) fn target(&self, p: &GraspPoint, t: f64, rotations: &[[Vec3; 3]]) -> Vec3 {
        let c = self.centroids[p.grasp];
        let r = &rotations[p.grasp];
        let d = sub(p.rest, c);
        let turned: Vec3 = std::array::from_fn(|i| (0..3).map(|j| r[i][j] * d[j]).sum());
        add(add(c, scale(self.motions[p.grasp].0, t)), turned)
    }

    /// Per point, the error `g = x - y(t)` for node displacements `u`.
    pub(crate) fn errors(&self, u: &[Vec3], t: f64) -> Vec<Vec3> {
        let rotations = self.rotations(t);
        self.points.iter().map(|p| sub(p.position(u), self.target(p, t, &rotations))).collect()
    }

    /// The largest distance of a prescribed position from its rest position at load
    /// factor `t` (m; 0 without grasps).
    pub(crate) fn largest_motion(&self, t: f64) -> f64 {
        let rotations = self.rotations(t);
        self.points.iter().map(|p| norm(sub(self.target(p, t, &rotations), p.rest))).fold(0.0, f64::max)
    }

    /// Per point, the force it puts on the grasper, `lambda + k g`.
    pub(crate) fn forces(&self, u: &[Vec3], t: f64, multipliers: &[Vec3]) -> Vec<Vec3> {
        self.errors(u, t)
            .iter()
            .zip(&self.points)
            .zip(multipliers)
            .map(|((g, p), l)| add(*l, scale(*g, p.stiffness)))
            .collect()
    }

    /// The energy `sum lambda . g + k / 2 |g|^2`.
    pub(crate) fn energy(&self, u: &[Vec3], t: f64, multipliers: &[Vec3]) -> f64 {
        self.errors(u, t)
            .iter()
            .zip(&self.points)
            .zip(multipliers)
            .map(|((g, p), l)| (0..3).map(|a| l[a] * g[a] + 0.5 * p.stiffness * g[a] * g[a]).sum::<f64>())
            .sum()
    }

    /// Uzawa's update at the full load: `lambda <- lambda + k g`.
    pub(crate) fn augment(&self, u: &[Vec3], t: f64, multipliers: &mut [Vec3]) {
        let forces = self.forces(u, t, multipliers);
        multipliers.copy_from_slice(&forces);
    }

    /// The largest `|g|` at the full load (m; 0 without grasps).
    pub(crate) fn largest_error(&self, u: &[Vec3], t: f64) -> f64 {
        self.errors(u, t).iter().map(|g| norm(*g)).fold(0.0, f64::max)
    }

    /// Per grasp, its force, moment and largest error at the full load.
    pub(crate) fn records(&self, u: &[Vec3], t: f64, multipliers: &[Vec3]) -> Vec<GraspRecord> {
        let rotations = self.rotations(t);
        let errors = self.errors(u, t);
        let forces = self.forces(u, t, multipliers);
        let mut out: Vec<GraspRecord> = self
            .counts
            .iter()
            .map(|&vertices| GraspRecord { vertices, force: [0.0; 3], moment: [0.0; 3], error: 0.0 })
            .collect();
        for ((p, g), f) in self.points.iter().zip(&errors).zip(&forces) {
            let r = &mut out[p.grasp];
            let about = add(self.centroids[p.grasp], self.motions[p.grasp].0);
            r.force = add(r.force, *f);
            r.moment = add(r.moment, cross(sub(self.target(p, t, &rotations), about), *f));
            r.error = r.error.max(norm(*g));
        }
        out
    }
}
