//! The closed surfaces a body's mesh is made of: the outer surface and its cavities.
//!
//! A mesh of several closed components is one body when every other component lies inside
//! the outer one (the component of largest |volume|): each is a cavity, faced so that the
//! material is on its outside (its signed volume negative when the outer's is positive).
//! The checks are by the generalized winding number of each component's vertices with
//! respect to the others: a component outside the outer surface is a second body, one
//! partly outside it (or partly inside another cavity) crosses it, one inside another
//! cavity is a body floating in a hole. A crossing whose vertices all lie on the right
//! side (an edge through a thin wall) is not detected.

use crate::error::MeshError;
use crate::mesh::{TriMesh, UnionFind, volume};
use crate::vec3::{Vec3, cross, dot, norm, sub};

/// One closed surface of a mesh: its faces (indices into the mesh's triangles) and its
/// signed volume.
#[derive(Clone, Debug, PartialEq)]
pub struct Shell {
    /// The faces of this surface.
    pub faces: Vec<usize>,
    /// Its signed enclosed volume (positive when its faces point away from the inside).
    pub volume: f64,
}

/// Largest number of vertex-face pairs the winding tests evaluate per pair of shells; above
/// it, every `k`-th vertex is tested.
const WINDING_WORK: usize = 1 << 25;

impl TriMesh {
    /// The closed surfaces of the mesh: the outer one (largest |volume|) first, then the
    /// cavities in the order of their first face (cavity `K` is entry `K`).
    pub fn shells(&self) -> Vec<Shell> {
        let mut uf = UnionFind::new(self.n_vertices());
        for t in self.triangles() {
            uf.union(t[0] as usize, t[1] as usize);
            uf.union(t[1] as usize, t[2] as usize);
        }
        let mut label = vec![usize::MAX; self.n_vertices()];
        let mut shells: Vec<Shell> = Vec::new();
        for (k, t) in self.triangles().iter().enumerate() {
            let root = uf.find(t[0] as usize);
            if label[root] == usize::MAX {
                label[root] = shells.len();
                shells.push(Shell { faces: Vec::new(), volume: 0.0 });
            }
            shells[label[root]].faces.push(k);
        }
        for s in &mut shells {
            let tris: Vec<[u32; 3]> = s.faces.iter().map(|&f| self.triangles()[f]).collect();
            s.volume = volume(self.positions(), &tris);
        }
        let outer = (0..shells.len())
            .max_by(|&a, &b| shells[a].volume.abs().total_cmp(&shells[b].volume.abs()))
            .unwrap_or(0);
        let first = shells.remove(outer);
        shells.insert(0, first);
        shells
    }

    /// The volumes (m^3 in a metre mesh, positive) of the cavities, in cavity order.
    pub fn cavity_volumes(&self) -> Vec<f64> {
        self.shells().iter().skip(1).map(|s| s.volume.abs()).collect()
    }

    /// Checks that every shell after the first lies inside the first and outside every
    /// other, and faces them: the outer outward, each cavity with the material outside it.
    /// Returns the warnings of what was flipped (the outer's first when it was).
    pub(crate) fn orient_shells(&mut self, shells: &[Shell]) -> Result<Vec<String>, MeshError> {
        let tri_of =
            |m: &TriMesh, s: &Shell| -> Vec<[u32; 3]> { s.faces.iter().map(|&f| m.triangles()[f]).collect() };
        let vertices = |m: &TriMesh, s: &Shell| -> Vec<usize> {
            let mut v: Vec<usize> =
                s.faces.iter().flat_map(|&f| m.triangles()[f]).map(|v| v as usize).collect();
            v.sort_unstable();
            v.dedup();
            v
        };
        let outer = tri_of(self, &shells[0]);
        for (k, cavity) in shells.iter().enumerate().skip(1) {
            let inside = self.inside_fraction(&vertices(self, cavity), &outer);
            if inside == 0.0 {
                return Err(MeshError::DisjointBodies { component: k });
            }
            if inside < 1.0 {
                return Err(MeshError::CavityCrossesOuter { cavity: k });
            }
        }
        for (a, ca) in shells.iter().enumerate().skip(1) {
            let va = vertices(self, ca);
            for (b, cb) in shells.iter().enumerate().skip(1).filter(|(b, _)| *b != a) {
                let inside = self.inside_fraction(&va, &tri_of(self, cb));
                if inside == 1.0 {
                    return Err(MeshError::CavityInCavity { inner: a, outer: b });
                }
                if inside > 0.0 {
                    return Err(MeshError::CavitiesCross { a: a.min(b), b: a.max(b) });
                }
            }
        }
        let mut warnings = Vec::new();
        for (k, s) in shells.iter().enumerate() {
            let wrong = if k == 0 { s.volume < 0.0 } else { s.volume > 0.0 };
            if !wrong {
                continue;
            }
            for &f in &s.faces {
                self.flip_face(f);
            }
            warnings.push(if k == 0 {
                "faces pointed inward (negative volume); flipped to outward".to_string()
            } else {
                format!("cavity {k} faced into the material (positive volume); flipped to face its hole")
            });
        }
        Ok(warnings)
    }

    /// The fraction of `vertices` (every `k`-th when they are many) that lie inside the
    /// closed surface `triangles`, by the generalized winding number.
    fn inside_fraction(&self, vertices: &[usize], triangles: &[[u32; 3]]) -> f64 {
        let stride = (vertices.len() * triangles.len()).div_ceil(WINDING_WORK).max(1);
        let tested: Vec<usize> = vertices.iter().step_by(stride).copied().collect();
        let inside = tested
            .iter()
            .filter(|&&v| winding_number(self.positions()[v], self.positions(), triangles).abs() > 0.5)
            .count();
        inside as f64 / tested.len().max(1) as f64
    }
}

/// Generalized winding number of a closed triangle surface around `p` (solid angles by
/// Van Oosterom & Strackee): ±1 inside, 0 outside.
pub fn winding_number(p: Vec3, positions: &[Vec3], triangles: &[[u32; 3]]) -> f64 {
    let mut total = 0.0;
    for t in triangles {
        let a = sub(positions[t[0] as usize], p);
        let b = sub(positions[t[1] as usize], p);
        let c = sub(positions[t[2] as usize], p);
        let (la, lb, lc) = (norm(a), norm(b), norm(c));
        let num = dot(a, cross(b, c));
        let den = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb;
        total += 2.0 * num.atan2(den);
    }
    total / (4.0 * std::f64::consts::PI)
}
