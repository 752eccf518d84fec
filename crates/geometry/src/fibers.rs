//! Which bulk fibers stay inside the body (REFERENCE §2).
//!
//! Every vertex pair (i, j) is a candidate fiber. A convex body keeps all of them, and
//! convexity is detected first so that no test runs. Otherwise a fiber is removed when
//! 1. it leaves the body at one of its ends: some face k touching the end vertex i has
//!    `A_k . (s_j - s_i) > EXIT_TOLERANCE |A_k| |s_j - s_i|` (and the same at j); or
//! 2. the open segment crosses a face that touches neither end ([`crate::crossing`]),
//!    found through a [`TriangleBvh`] so the cost stays far below the O(N^2 N') loop.

use std::time::Instant;

use rayon::prelude::*;

use crate::bvh::TriangleBvh;
use crate::crossing::segment_triangle;
use crate::mesh::TriMesh;
use crate::vec3::{dot, norm, sub};

/// Relative tolerance of the exit test (see the module docs).
pub const EXIT_TOLERANCE: f64 = 1e-9;

/// The kept fibers: a bitset over the vertex pairs i < j.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FiberSet {
    n: usize,
    bits: Vec<u64>,
    kept: usize,
    per_vertex: Vec<u32>,
}

impl FiberSet {
    /// Every pair kept (a convex body).
    pub fn all(n: usize) -> Self {
        let total = n * n.saturating_sub(1) / 2;
        let mut bits = vec![u64::MAX; total.div_ceil(64)];
        if !total.is_multiple_of(64)
            && let Some(last) = bits.last_mut()
        {
            *last = (1u64 << (total % 64)) - 1;
        }
        Self { n, bits, kept: total, per_vertex: vec![n.saturating_sub(1) as u32; n] }
    }

    /// Builds the set from the kept pairs of each row i (j > i).
    pub fn from_rows(n: usize, rows: &[Vec<u32>]) -> Self {
        let total = n * n.saturating_sub(1) / 2;
        let mut bits = vec![0u64; total.div_ceil(64)];
        let mut per_vertex = vec![0u32; n];
        let mut kept = 0;
        for (i, row) in rows.iter().enumerate() {
            for &j in row {
                let idx = pair_index(n, i, j as usize);
                bits[idx / 64] |= 1 << (idx % 64);
                per_vertex[i] += 1;
                per_vertex[j as usize] += 1;
                kept += 1;
            }
        }
        Self { n, bits, kept, per_vertex }
    }

    /// Number of vertices.
    pub fn n_vertices(&self) -> usize {
        self.n
    }

    /// Whether fiber (i, j) is kept (i != j, any order).
    #[inline]
    pub fn contains(&self, i: usize, j: usize) -> bool {
        if i == j {
            return false;
        }
        let idx = pair_index(self.n, i.min(j), i.max(j));
        self.bits[idx / 64] >> (idx % 64) & 1 == 1
    }

    /// Number of kept fibers.
    pub fn kept(&self) -> usize {
        self.kept
    }

    /// Number of candidate fibers, N(N-1)/2.
    pub fn total(&self) -> usize {
        self.n * self.n.saturating_sub(1) / 2
    }

    /// Kept fibers per vertex.
    pub fn per_vertex(&self) -> &[u32] {
        &self.per_vertex
    }

    /// Mean kept fibers per vertex, `2 F_kept / N` (N - 1 for a convex body): the
    /// effective connection count that replaces (N - 1) in Eq. 6.
    pub fn mean_connections(&self) -> f64 {
        if self.n == 0 { 0.0 } else { 2.0 * self.kept as f64 / self.n as f64 }
    }

    /// Iterates over the kept pairs (i, j), i < j.
    pub fn pairs(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        (0..self.n)
            .flat_map(move |i| (i + 1..self.n).filter(move |&j| self.contains(i, j)).map(move |j| (i, j)))
    }
}

#[inline]
fn pair_index(n: usize, i: usize, j: usize) -> usize {
    i * n - i * (i + 1) / 2 + (j - i - 1)
}

/// Options of [`cull_fibers`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VisibilityOptions {
    /// Relative tolerance of the convexity check.
    pub convexity_tolerance: f64,
    /// Relative tolerance of the exit test.
    pub exit_tolerance: f64,
    /// Skip the convexity shortcut and always run both tests (for testing).
    pub force_tests: bool,
}

impl Default for VisibilityOptions {
    fn default() -> Self {
        Self {
            convexity_tolerance: crate::mesh::CONVEXITY_TOLERANCE,
            exit_tolerance: EXIT_TOLERANCE,
            force_tests: false,
        }
    }
}

/// What [`cull_fibers`] did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VisibilityReport {
    /// The body was found convex (no test ran).
    pub convex: bool,
    /// Fibers removed by the exit test.
    pub removed_by_exit: usize,
    /// Fibers removed by the crossing test.
    pub removed_by_crossing: usize,
    /// Seconds spent.
    pub seconds: f64,
}

/// Finds the fibers that stay inside the body.
pub fn cull_fibers(mesh: &TriMesh, opts: &VisibilityOptions) -> (FiberSet, VisibilityReport) {
    let start = Instant::now();
    let n = mesh.n_vertices();
    if !opts.force_tests && mesh.is_convex_eps(opts.convexity_tolerance) {
        let report =
            VisibilityReport { convex: true, seconds: start.elapsed().as_secs_f64(), ..Default::default() };
        return (FiberSet::all(n), report);
    }
    let pos = mesh.positions();
    let tris = mesh.triangles();
    let areas = mesh.face_area_vectors();
    let adj = mesh.adjacency();
    let bvh = TriangleBvh::new(pos, tris);
    let exits = |i: usize, j: usize| {
        let d = sub(pos[j], pos[i]);
        let ld = norm(d);
        adj.faces_of(i).iter().any(|&k| {
            let a = areas[k as usize];
            dot(a, d) > opts.exit_tolerance * norm(a) * ld
        })
    };
    let rows: Vec<(Vec<u32>, usize, usize)> = (0..n)
        .into_par_iter()
        .map(|i| {
            let mut kept = Vec::new();
            let (mut ex, mut cr) = (0, 0);
            for j in i + 1..n {
                if exits(i, j) || exits(j, i) {
                    ex += 1;
                    continue;
                }
                let (p, q) = (pos[i], pos[j]);
                let crosses = bvh.any_on_segment(p, q, |k| {
                    let t = tris[k as usize];
                    if t.contains(&(i as u32)) || t.contains(&(j as u32)) {
                        return false;
                    }
                    segment_triangle(p, q, pos[t[0] as usize], pos[t[1] as usize], pos[t[2] as usize])
                        .removes_fiber()
                });
                if crosses {
                    cr += 1;
                } else {
                    kept.push(j as u32);
                }
            }
            (kept, ex, cr)
        })
        .collect();
    let removed_by_exit = rows.iter().map(|r| r.1).sum();
    let removed_by_crossing = rows.iter().map(|r| r.2).sum();
    let kept_rows: Vec<Vec<u32>> = rows.into_iter().map(|r| r.0).collect();
    let set = FiberSet::from_rows(n, &kept_rows);
    let report = VisibilityReport {
        convex: false,
        removed_by_exit,
        removed_by_crossing,
        seconds: start.elapsed().as_secs_f64(),
    };
    (set, report)
}

/// Whether segment (s_i, s_j) crosses any face not incident to i or j, by checking every
/// face (O(N') per fiber): the reference the accelerated test is compared with.
pub fn crosses_surface_brute_force(mesh: &TriMesh, i: usize, j: usize) -> bool {
    let pos = mesh.positions();
    mesh.triangles().iter().any(|t| {
        !t.contains(&(i as u32))
            && !t.contains(&(j as u32))
            && segment_triangle(pos[i], pos[j], pos[t[0] as usize], pos[t[1] as usize], pos[t[2] as usize])
                .removes_fiber()
    })
}

/// Pairs of faces sharing no vertex where an edge of one crosses the other: the surface
/// intersects itself there. Returned sorted, each pair once (lower face first).
pub fn self_intersections(mesh: &TriMesh) -> Vec<(u32, u32)> {
    let pos = mesh.positions();
    let tris = mesh.triangles();
    let bvh = TriangleBvh::new(pos, tris);
    let mut out: Vec<(u32, u32)> = (0..tris.len())
        .into_par_iter()
        .flat_map_iter(|f| {
            let t = tris[f];
            let mut hits = Vec::new();
            for e in 0..3 {
                let (a, b) = (t[e], t[(e + 1) % 3]);
                bvh.any_on_segment(pos[a as usize], pos[b as usize], |k| {
                    let u = tris[k as usize];
                    if k as usize != f && !u.iter().any(|v| t.contains(v)) {
                        let c = segment_triangle(
                            pos[a as usize],
                            pos[b as usize],
                            pos[u[0] as usize],
                            pos[u[1] as usize],
                            pos[u[2] as usize],
                        );
                        if c.removes_fiber() {
                            hits.push(((f as u32).min(k), (f as u32).max(k)));
                        }
                    }
                    false
                });
            }
            hits
        })
        .collect();
    out.sort_unstable();
    out.dedup();
    out
}
