//! Volume-preserving edge-collapse decimation of a closed triangle surface.
//!
//! Edges are collapsed one at a time, cheapest first, until the surface has the target
//! number of vertices. An edge `(a, b)` collapses to one new vertex `v`:
//!
//! - **Placement** (Lindstrom & Turk, "Fast and memory efficient polygonal simplification",
//!   IEEE Visualization 1998): the enclosed volume after the collapse is linear in `v`, so
//!   "the volume does not change" is a plane `N . v = d`. `v` minimises the quadric error on
//!   that plane. Every collapse keeps the volume exactly (up to rounding), so the decimated
//!   surface encloses the input's volume.
//! - **Cost** (Garland & Heckbert, "Surface simplification using quadric error metrics",
//!   SIGGRAPH 1997): each vertex carries the sum of the quadrics of the planes of its
//!   original faces (a collapse adds the two); the cost is that quadric at `v`. A small
//!   Lindstrom–Turk shape term, the sum of squared distances from `v` to the ring's vertices
//!   ([`SHAPE_WEIGHT`] of it), keeps the system well posed on flat patches and favours short
//!   edges there.
//! - **Refused collapses**: the link condition (the two rings share exactly the two vertices
//!   opposite the edge; Dey, Edelsbrunner, Guha & Nekhayev 1999), which keeps a closed
//!   2-manifold; none below 4 vertices (the tetrahedron); no face whose normal turns by more
//!   than 90 degrees; no new face thinner than [`MIN_QUALITY`] unless the faces it replaces
//!   had one as thin already. Faces keep their vertex order, so the orientation is kept.
//!
//! Collapses come from a priority queue with lazy invalidation: an entry is stale when one of
//! its vertices was removed or moved since it was queued, and its cost is recomputed when it
//! comes out (and the entry queued again when the cost grew). An edge refused once may become
//! possible after its neighbours changed: when the queue runs dry above the target, a new pass
//! queues every edge again, at most [`MAX_PASSES`] passes.
//!
//! The work is done on coordinates centred on the bounding box and divided by its diagonal,
//! so the tolerances do not depend on the units.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use crate::error::MeshError;
use crate::mesh::TriMesh;
use crate::vec3::{Vec3, add, cross, dot, norm, scale, sub};

/// Weight of the shape term (squared distances to the ring) against the quadric error.
pub const SHAPE_WEIGHT: f64 = 1e-3;

/// Smallest quality `4 sqrt(3) area / (sum of squared edges)` (1 for an equilateral
/// triangle) a collapse may create, unless a face it replaces was already worse.
pub const MIN_QUALITY: f64 = 0.1;

/// Most passes over the whole edge set (see the module documentation).
pub const MAX_PASSES: usize = 16;

/// Why a surface could not be decimated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DecimateError {
    /// The input is not one valid closed surface.
    #[error("the surface to decimate is not one valid closed body: {0}")]
    Mesh(#[from] MeshError),
    /// No allowed collapse was left above the target.
    #[error("decimation cannot bring the surface to {target} vertices (it stopped at {reached})")]
    TargetTooSmall {
        /// The target.
        target: usize,
        /// The vertices of the surface where decimation stopped.
        reached: usize,
    },
}

/// Decimates a closed surface to at most `target_vertices` vertices, keeping its volume,
/// its topology and its orientation (see the module documentation).
///
/// The mesh is validated first ([`TriMesh::validate`] on a copy). A mesh with no more
/// vertices than the target comes back unchanged; otherwise unused vertices are dropped and
/// the vertices keep their relative order. Returns positions and triangles for
/// [`TriMesh::new`].
pub fn decimate(mesh: &TriMesh, target_vertices: usize) -> Result<(Vec<Vec3>, Vec<[u32; 3]>), DecimateError> {
    mesh.clone().validate()?;
    decimate_valid(mesh.positions(), mesh.triangles(), target_vertices)
}

/// [`decimate`] on a surface already known to pass validation.
pub(crate) fn decimate_valid(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    target: usize,
) -> Result<(Vec<Vec3>, Vec<[u32; 3]>), DecimateError> {
    if positions.len() <= target {
        return Ok((positions.to_vec(), triangles.to_vec()));
    }
    let mut work = Collapser::new(positions, triangles);
    for _ in 0..MAX_PASSES {
        if work.alive <= target || !work.pass(target) {
            break;
        }
    }
    if work.alive > target {
        return Err(DecimateError::TargetTooSmall { target, reached: work.alive });
    }
    Ok(work.finish())
}

/// A plane quadric sum: `E(v) = v' A v - 2 b' v + c`, `A` symmetric (xx, xy, xz, yy, yz, zz).
#[derive(Clone, Copy, Default)]
struct Quadric {
    a: [f64; 6],
    b: Vec3,
    c: f64,
}

impl Quadric {
    /// The squared distance to the plane through `p` with unit normal `n`.
    fn plane(n: Vec3, p: Vec3) -> Self {
        let d = dot(n, p);
        Self {
            a: [n[0] * n[0], n[0] * n[1], n[0] * n[2], n[1] * n[1], n[1] * n[2], n[2] * n[2]],
            b: scale(n, d),
            c: d * d,
        }
    }

    fn add(&self, o: &Self) -> Self {
        Self { a: std::array::from_fn(|i| self.a[i] + o.a[i]), b: add(self.b, o.b), c: self.c + o.c }
    }

    fn eval(&self, v: Vec3) -> f64 {
        (dot(v, mul(&self.a, v)) - 2.0 * dot(self.b, v) + self.c).max(0.0)
    }
}

/// A queued collapse: the edge, its cost and the vertices' versions when it was queued.
#[derive(Clone, Copy)]
struct Entry {
    cost: f64,
    a: u32,
    b: u32,
    stamp: [u32; 2],
}

impl PartialEq for Entry {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl Eq for Entry {}

impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Entry {
    /// Reversed, so the max-heap pops the cheapest first (ties: the smaller vertices).
    fn cmp(&self, other: &Self) -> Ordering {
        other.cost.total_cmp(&self.cost).then_with(|| (other.a, other.b).cmp(&(self.a, self.b)))
    }
}

/// The surface being decimated, in normalised coordinates.
struct Collapser {
    pos: Vec<Vec3>,
    tris: Vec<[u32; 3]>,
    face_alive: Vec<bool>,
    /// The live faces around each vertex (empty once removed).
    faces: Vec<Vec<u32>>,
    quadric: Vec<Quadric>,
    version: Vec<u32>,
    vertex_alive: Vec<bool>,
    alive: usize,
    centre: Vec3,
    size: f64,
}

impl Collapser {
    fn new(positions: &[Vec3], triangles: &[[u32; 3]]) -> Self {
        let (lo, hi) = crate::mesh::bounding_box(positions);
        let centre = scale(add(lo, hi), 0.5);
        let size = norm(sub(hi, lo)).max(f64::MIN_POSITIVE);
        let pos: Vec<Vec3> = positions.iter().map(|&p| scale(sub(p, centre), 1.0 / size)).collect();
        let n = pos.len();
        let mut faces = vec![Vec::new(); n];
        let mut quadric = vec![Quadric::default(); n];
        for (f, t) in triangles.iter().enumerate() {
            let normal = cross(
                sub(pos[t[1] as usize], pos[t[0] as usize]),
                sub(pos[t[2] as usize], pos[t[0] as usize]),
            );
            let len = norm(normal);
            let q = if len > 0.0 {
                Quadric::plane(scale(normal, 1.0 / len), pos[t[0] as usize])
            } else {
                Quadric::default()
            };
            for &v in t {
                faces[v as usize].push(f as u32);
                quadric[v as usize] = quadric[v as usize].add(&q);
            }
        }
        let vertex_alive: Vec<bool> = faces.iter().map(|f| !f.is_empty()).collect();
        let alive = vertex_alive.iter().filter(|&&x| x).count();
        Self {
            pos,
            tris: triangles.to_vec(),
            face_alive: vec![true; triangles.len()],
            faces,
            quadric,
            version: vec![0; n],
            vertex_alive,
            alive,
            centre,
            size,
        }
    }

    /// One pass: queue every edge, collapse until the target or an empty queue. Returns
    /// whether anything collapsed.
    fn pass(&mut self, target: usize) -> bool {
        let mut heap = BinaryHeap::new();
        for (f, t) in self.tris.iter().enumerate() {
            if !self.face_alive[f] {
                continue;
            }
            for e in 0..3 {
                let (a, b) = (t[e], t[(e + 1) % 3]);
                if a < b {
                    self.push(&mut heap, a, b);
                }
            }
        }
        let mut collapsed = false;
        while self.alive > target {
            let Some(entry) = heap.pop() else { break };
            let (a, b) = (entry.a as usize, entry.b as usize);
            if !self.vertex_alive[a]
                || !self.vertex_alive[b]
                || entry.stamp != [self.version[a], self.version[b]]
            {
                continue;
            }
            let Some((v, cost)) = self.placement(a, b) else { continue };
            if cost > entry.cost * (1.0 + 1e-9) + 1e-300 {
                heap.push(Entry { cost, ..entry });
                continue;
            }
            if !self.allowed(a, b, v) {
                continue;
            }
            self.collapse(a, b, v);
            collapsed = true;
            for n in self.ring(a) {
                self.push(&mut heap, a as u32, n);
            }
        }
        collapsed
    }

    fn push(&self, heap: &mut BinaryHeap<Entry>, a: u32, b: u32) {
        let (i, j) = (a as usize, b as usize);
        if let Some((_, cost)) = self.placement(i, j) {
            heap.push(Entry { cost, a, b, stamp: [self.version[i], self.version[j]] });
        }
    }

    /// The vertices sharing a face with `v`, each once.
    fn ring(&self, v: usize) -> Vec<u32> {
        let mut ring: Vec<u32> =
            self.faces[v].iter().flat_map(|&f| self.tris[f as usize]).filter(|&w| w as usize != v).collect();
        ring.sort_unstable();
        ring.dedup();
        ring
    }

    /// The faces around `a` or `b`, each once, with whether they contain both.
    fn star(&self, a: usize, b: usize) -> impl Iterator<Item = (u32, bool)> + '_ {
        let has = |f: u32, v: usize| self.tris[f as usize].contains(&(v as u32));
        let around_a = self.faces[a].iter().map(move |&f| (f, has(f, b)));
        around_a.chain(self.faces[b].iter().filter(move |&&f| !has(f, a)).map(|&f| (f, false)))
    }

    /// The corners of face `f`, with `a` and `b` moved to `v` when given.
    fn corners(&self, f: u32, moved: Option<(usize, usize, Vec3)>) -> [Vec3; 3] {
        self.tris[f as usize].map(|w| match moved {
            Some((a, b, v)) if w as usize == a || w as usize == b => v,
            _ => self.pos[w as usize],
        })
    }

    /// Where `(a, b)` collapses to and the cost: the quadric (plus the shape term) minimised
    /// on the plane that keeps the volume. `None` when that plane is undefined.
    fn placement(&self, a: usize, b: usize) -> Option<(Vec3, f64)> {
        let m = scale(add(self.pos[a], self.pos[b]), 0.5);
        // Relative to m: the star's volume before, its gradient in v after, and the ring
        // (each ring vertex is in two of the new faces: counted twice, weighted by 1/2).
        let (mut grad, mut before) = ([0.0; 3], 0.0);
        let (mut count, mut ring_sum, mut ring_sq) = (0.0, [0.0; 3], 0.0);
        for (f, both) in self.star(a, b) {
            let t = self.tris[f as usize];
            let k = t.iter().position(|&w| w as usize == a || w as usize == b)?;
            let [p0, p1, p2] = [0, 1, 2].map(|i| sub(self.pos[t[(k + i) % 3] as usize], m));
            let c = cross(p1, p2);
            before += dot(p0, c) / 6.0;
            if both {
                continue;
            }
            grad = add(grad, scale(c, 1.0 / 6.0));
            count += 1.0;
            ring_sum = add(ring_sum, scale(add(p1, p2), 0.5));
            ring_sq += 0.5 * (dot(p1, p1) + dot(p2, p2));
        }
        let edge = norm(sub(self.pos[a], self.pos[b]));
        if !(norm(grad) > 1e-9 * edge * edge) {
            return None;
        }
        // Quadric plus shape term, relative to m: E(m + x) = x' A x - 2 g' x + const.
        let q = self.quadric[a].add(&self.quadric[b]);
        let k = SHAPE_WEIGHT * count;
        let mat = [q.a[0] + k, q.a[1], q.a[2], q.a[3] + k, q.a[4], q.a[5] + k];
        let g = add(sub(q.b, mul(&q.a, m)), scale(ring_sum, SHAPE_WEIGHT));
        // Minimum of x' A x - 2 g' x subject to grad . x = before.
        let inv = inverse(mat)?;
        let x0 = mul(&inv, g);
        let d = mul(&inv, grad);
        let denom = dot(grad, d);
        if !(denom > 0.0) {
            return None;
        }
        let x = add(x0, scale(d, (before - dot(grad, x0)) / denom));
        let v = add(m, x);
        if !v.iter().all(|c| c.is_finite()) {
            return None;
        }
        let spread = count * dot(x, x) - 2.0 * dot(x, ring_sum) + ring_sq;
        Some((v, q.eval(v) + SHAPE_WEIGHT * spread.max(0.0)))
    }

    /// Whether collapsing `(a, b)` to `v` keeps a closed 2-manifold with no turned-over or
    /// thin faces (see the module documentation).
    fn allowed(&self, a: usize, b: usize, v: Vec3) -> bool {
        if self.alive <= 4 {
            return false;
        }
        let (ra, rb) = (self.ring(a), self.ring(b));
        if ra.iter().filter(|w| rb.binary_search(w).is_ok()).count() != 2 {
            return false;
        }
        let (mut worst_old, mut worst_new) = (1.0f64, 1.0f64);
        for (f, both) in self.star(a, b) {
            let old = self.corners(f, None);
            worst_old = worst_old.min(quality(old));
            if both {
                continue;
            }
            let new = self.corners(f, Some((a, b, v)));
            let (n_old, n_new) = (normal(old), normal(new));
            if !(dot(n_old, n_new) > 0.0) || !(norm(n_new) > 1e-14) {
                return false;
            }
            worst_new = worst_new.min(quality(new));
        }
        worst_new >= worst_old.min(MIN_QUALITY)
    }

    /// Collapses `b` into `a`, which moves to `v`.
    fn collapse(&mut self, a: usize, b: usize, v: Vec3) {
        let around_b = std::mem::take(&mut self.faces[b]);
        for f in around_b {
            let t = &mut self.tris[f as usize];
            if t.contains(&(a as u32)) {
                self.face_alive[f as usize] = false;
                for w in *t {
                    self.faces[w as usize].retain(|&g| g != f);
                }
            } else {
                for w in t.iter_mut() {
                    if *w as usize == b {
                        *w = a as u32;
                    }
                }
                self.faces[a].push(f);
            }
        }
        self.pos[a] = v;
        self.quadric[a] = self.quadric[a].add(&self.quadric[b]);
        self.version[a] += 1;
        self.vertex_alive[b] = false;
        self.alive -= 1;
    }

    /// The live vertices (in their order, back in the input's coordinates) and faces.
    fn finish(self) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut index = vec![u32::MAX; self.pos.len()];
        let mut positions = Vec::with_capacity(self.alive);
        for (v, p) in self.pos.iter().enumerate() {
            if self.vertex_alive[v] {
                index[v] = positions.len() as u32;
                positions.push(add(scale(*p, self.size), self.centre));
            }
        }
        let triangles = self
            .tris
            .iter()
            .zip(&self.face_alive)
            .filter(|(_, alive)| **alive)
            .map(|(t, _)| t.map(|w| index[w as usize]))
            .collect();
        (positions, triangles)
    }
}

/// `(p1 - p0) x (p2 - p0)`.
fn normal(p: [Vec3; 3]) -> Vec3 {
    cross(sub(p[1], p[0]), sub(p[2], p[0]))
}

/// `4 sqrt(3) area / (sum of squared edges)`: 1 for an equilateral triangle, 0 for a flat one.
fn quality(p: [Vec3; 3]) -> f64 {
    let edges: f64 = (0..3).map(|i| norm(sub(p[(i + 1) % 3], p[i])).powi(2)).sum();
    if !(edges > 0.0) {
        return 0.0;
    }
    2.0 * 3f64.sqrt() * norm(normal(p)) / edges
}

/// Inverse of a symmetric 3x3 matrix (xx, xy, xz, yy, yz, zz); `None` when singular.
fn inverse(m: [f64; 6]) -> Option<[f64; 6]> {
    let [a, b, c, d, e, f] = m;
    let co = [d * f - e * e, c * e - b * f, b * e - c * d, a * f - c * c, b * c - a * e, a * d - b * b];
    let det = a * co[0] + b * co[1] + c * co[2];
    if !(det.abs() > 1e-300) || !det.is_finite() {
        return None;
    }
    Some(co.map(|x| x / det))
}

/// A symmetric 3x3 matrix (xx, xy, xz, yy, yz, zz) times a vector.
fn mul(m: &[f64; 6], v: Vec3) -> Vec3 {
    [
        m[0] * v[0] + m[1] * v[1] + m[2] * v[2],
        m[1] * v[0] + m[3] * v[1] + m[4] * v[2],
        m[2] * v[0] + m[4] * v[1] + m[5] * v[2],
    ]
}
