//! Pressure loads on faces of the body's surface, a [`ForceTerm`].
//!
//! The faces carry their mesh orientation, which points away from the material (outward
//! on the outer surface, into the hole on a cavity), and a positive pressure `p` pushes
//! into the material: the force on the faces is `-p A` per face (area vector `A`), a third
//! on each corner.
//!
//! - **Follower** (a closed selection, a nonlinear law): the pressure acts on the deformed
//!   surface. It is then conservative, with energy `t p V(x)`, `V` the volume the
//!   selected faces enclose (`(1/6) sum x0 . (x1 x x2)`, signed by their orientation) at
//!   the deformed vertices `x = X + sum w u` (trilinear embedding): its gradient is the
//!   force above exactly, its Hessian `t p d^2V/dx^2` symmetric. The tangent's pattern
//!   gains the node pairs it couples beyond the grid's cells (two corners of a face in
//!   different cells); the multigrid solver, whose operator is the grid's, leaves those
//!   out (its Newton steps are then inexact, the answer is not).
//! - **Dead** (an open selection, e.g. by a box, or the linear law): the force of the rest
//!   surface, fixed in size and direction, scaled by the load factor (a follower pressure
//!   on an open patch is not conservative).

use fibfluid_geometry::Vec3;
use fibfluid_geometry::vec3::{cross, dot, scale, sub};

use super::model::HyperModel;
use super::terms::{Assembly, ForceTerm, LoadState};
use crate::assemble::FIXED;
use crate::error::{FemError, Result};
use crate::grid::{Embedded, SparseGrid};

/// A uniform pressure on faces of the body's surface.
#[derive(Debug, Clone, PartialEq)]
pub struct Pressure {
    /// The pressure (Pa); positive pushes into the material.
    pub value: f64,
    /// The faces it acts on (vertex indices of the body's surface, oriented away from the
    /// material).
    pub faces: Vec<[u32; 3]>,
}

impl Pressure {
    /// Whether the faces form closed surfaces: every edge shared by two of them.
    pub fn is_closed(&self) -> bool {
        let mut edges: Vec<(u32, u32)> = self
            .faces
            .iter()
            .flat_map(|t| (0..3).map(move |e| (t[e].min(t[(e + 1) % 3]), t[e].max(t[(e + 1) % 3]))))
            .collect();
        edges.sort_unstable();
        edges.chunk_by(|a, b| a == b).all(|run| run.len() == 2)
    }

    /// The resultant force of the pressure on the body (N) with the surface at `positions`:
    /// `-p sum A`, zero for a closed selection.
    pub fn resultant(&self, positions: &[Vec3]) -> Vec3 {
        let area = self.faces.iter().fold([0.0; 3], |acc, t| {
            let [a, b, c] = t.map(|v| positions[v as usize]);
            let n = scale(cross(sub(b, a), sub(c, a)), 0.5);
            [acc[0] + n[0], acc[1] + n[1], acc[2] + n[2]]
        });
        scale(area, -self.value)
    }

    /// The volume the faces enclose at `positions` (`(1/6) sum x0 . (x1 x x2)`, signed by
    /// their orientation: negative for a cavity).
    pub fn enclosed_volume(&self, positions: &[Vec3]) -> f64 {
        self.faces
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| positions[v as usize]);
                dot(a, cross(b, c))
            })
            .sum::<f64>()
            / 6.0
    }
}

/// One pressure as the solve applies it.
#[derive(Debug, Clone)]
struct Applied {
    value: f64,
    faces: Vec<[u32; 3]>,
    closed: bool,
    /// Per surface vertex, the dead force at full load.
    dead: Vec<(usize, Vec3)>,
}

impl Applied {
    /// Whether it follows the deformed surface on `model` (closed, some law nonlinear).
    fn follows(&self, model: &HyperModel) -> bool {
        self.closed && model.materials.iter().any(|m| !m.law.is_linear())
    }
}

/// The pressures on a body (see the module docs).
#[derive(Debug, Clone, Default)]
pub(crate) struct PressureTerm {
    loads: Vec<Applied>,
}

impl PressureTerm {
    /// The term of `pressures` on `grid`'s surface.
    ///
    /// Errors: a face's vertex out of range, a non-finite value.
    pub(crate) fn new(grid: &SparseGrid, pressures: &[Pressure]) -> Result<Self> {
        let rest = grid.surface_positions();
        let mut loads = Vec::with_capacity(pressures.len());
        for p in pressures {
            if !p.value.is_finite() {
                return Err(FemError::NonFinite { what: "a pressure" });
            }
            if let Some(&v) = p.faces.iter().flatten().find(|&&v| v as usize >= rest.len()) {
                return Err(FemError::VertexOutOfRange { vertex: v as usize, vertices: rest.len() });
            }
            let dead = {
                let mut force = vec![[0.0; 3]; rest.len()];
                for t in &p.faces {
                    let [a, b, c] = t.map(|v| rest[v as usize]);
                    let f = scale(cross(sub(b, a), sub(c, a)), -p.value / 6.0);
                    for &v in t {
                        let fv = &mut force[v as usize];
                        *fv = [fv[0] + f[0], fv[1] + f[1], fv[2] + f[2]];
                    }
                }
                let mut used: Vec<usize> = p.faces.iter().flatten().map(|&v| v as usize).collect();
                used.sort_unstable();
                used.dedup();
                used.into_iter().map(|v| (v, force[v])).collect()
            };
            loads.push(Applied { value: p.value, faces: p.faces.clone(), closed: p.is_closed(), dead });
        }
        Ok(Self { loads })
    }

    /// The node pairs a follower pressure's Hessian couples (both corners of each face
    /// edge, every node of one's cell with every node of the other's), sorted, each once.
    pub(crate) fn couplings(&self, grid: &SparseGrid) -> Vec<(usize, usize)> {
        let embedding = grid.embedding();
        let mut pairs = Vec::new();
        for load in self.loads.iter().filter(|l| l.closed) {
            for t in &load.faces {
                for k in 0..3 {
                    let (a, b) = (&embedding[t[k] as usize], &embedding[t[(k + 1) % 3] as usize]);
                    if a.cell == b.cell {
                        continue;
                    }
                    for &m in &a.nodes {
                        pairs.extend(b.nodes.iter().map(|&n| (m.min(n), m.max(n))));
                    }
                }
            }
        }
        pairs.sort_unstable();
        pairs.dedup();
        pairs
    }

    /// Whether there is no pressure.
    pub(crate) fn is_empty(&self) -> bool {
        self.loads.is_empty()
    }
}

/// The deformed position of an embedded surface vertex.
fn deformed(rest: Vec3, e: &Embedded, u: &[Vec3]) -> Vec3 {
    let mut x = rest;
    for b in 0..8 {
        for a in 0..3 {
            x[a] += e.weights[b] * u[e.nodes[b]][a];
        }
    }
    x
}

impl ForceTerm for PressureTerm {
    fn energy(&self, model: &HyperModel, u: &[Vec3], state: &LoadState<'_>) -> f64 {
        let (rest, embedding) = (model.grid.surface_positions(), model.grid.embedding());
        let mut e = 0.0;
        for load in &self.loads {
            if load.follows(model) {
                let mut v = 0.0;
                for t in &load.faces {
                    let [a, b, c] = t.map(|i| deformed(rest[i as usize], &embedding[i as usize], u));
                    v += dot(a, cross(b, c));
                }
                e += state.t * load.value * v / 6.0;
            } else {
                for &(i, f) in &load.dead {
                    let d = sub(deformed(rest[i], &embedding[i], u), rest[i]);
                    e -= state.t * dot(f, d);
                }
            }
        }
        e
    }

    fn add(&self, model: &HyperModel, u: &[Vec3], state: &LoadState<'_>, out: &mut Assembly<'_>) -> f64 {
        let (rest, embedding) = (model.grid.surface_positions(), model.grid.embedding());
        for load in &self.loads {
            if !load.follows(model) {
                for &(i, f) in &load.dead {
                    add_gradient(model, &embedding[i], scale(f, -state.t), out);
                }
                continue;
            }
            let coef = state.t * load.value / 6.0;
            for t in &load.faces {
                let x = t.map(|i| deformed(rest[i as usize], &embedding[i as usize], u));
                let e = t.map(|i| &embedding[i as usize]);
                for k in 0..3 {
                    let (next, prev) = ((k + 1) % 3, (k + 2) % 3);
                    add_gradient(model, e[k], scale(cross(x[next], x[prev]), coef), out);
                    // d^2V/dx_k dx_next = [eps x_prev] / 6, d^2V/dx_k dx_prev = -[eps x_next] / 6.
                    if out.tangent.is_some() {
                        add_pair(model, e[k], e[next], x[prev], coef, out);
                        add_pair(model, e[k], e[prev], x[next], -coef, out);
                    }
                }
            }
        }
        self.energy(model, u, state)
    }
}

/// Adds the force-like vector `g` at an embedded vertex to the gradient (spread by its
/// weights).
fn add_gradient(model: &HyperModel, e: &Embedded, g: Vec3, out: &mut Assembly<'_>) {
    for b in 0..8 {
        for a in 0..3 {
            if let Some(slot) = out.gradient.get_mut(model.free[3 * e.nodes[b] + a]) {
                *slot += e.weights[b] * g[a];
            }
        }
    }
}

/// Adds the block `coef [eps_rsk c_k]` coupling vertex `p` (rows) to vertex `q` (columns)
/// to the tangent's lower triangle, spread by both embeddings; the transposed block comes
/// with the pair taken the other way.
fn add_pair(model: &HyperModel, p: &Embedded, q: &Embedded, c: Vec3, coef: f64, out: &mut Assembly<'_>) {
    let Some(tangent) = out.tangent.as_deref_mut() else { return };
    // eps_rsk c_k for the off-diagonal (r, s): (0,1) = c2, (1,2) = c0, (2,0) = c1.
    let block = [[0.0, c[2], -c[1]], [-c[2], 0.0, c[0]], [c[1], -c[0], 0.0]];
    let (symbolic, values) = tangent.parts_mut();
    let (col_ptr, row_idx) = (symbolic.col_ptr(), symbolic.row_idx());
    for bp in 0..8 {
        for bq in 0..8 {
            let w = coef * p.weights[bp] * q.weights[bq];
            if w == 0.0 {
                continue;
            }
            for (r, row) in block.iter().enumerate() {
                let gr = model.free[3 * p.nodes[bp] + r];
                if gr == FIXED {
                    continue;
                }
                for (s, &m) in row.iter().enumerate() {
                    let gc = model.free[3 * q.nodes[bq] + s];
                    if m == 0.0 || gc == FIXED || gr < gc {
                        continue;
                    }
                    let col = &row_idx[col_ptr[gc]..col_ptr[gc + 1]];
                    if let Ok(pos) = col.binary_search(&gr) {
                        values[col_ptr[gc] + pos] += w * m;
                    }
                }
            }
        }
    }
}
