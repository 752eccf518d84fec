//! The clamp: fixed surface vertices and fixed surface triangles imposed on the embedded
//! surface points (trilinear combinations of node displacements), not on whole cells.
//!
//! The fixed part `Gamma` of the surface is held by a boundary penalty: the energy gains
//! `beta / 2 * integral over Gamma of |u_a|^2` for each fixed axis `a`, with
//! `beta = CLAMP_PENALTY * E / h` per unit area ([`clamp_stiffness`]). It is integrated by
//! points: every fixed triangle is sampled at most `h / 2` apart
//! ([`crate::fixed_surface_samples`]), each sample weighted by its share of the triangle's
//! area; a fixed vertex outside any fixed triangle stands for a third of its triangles' area.
//! Each point adds `beta * area * w w^T` (its trilinear weights `w`) to K on its axis.
//! A point that sits on a grid node (weight 1) fixes that node's axis exactly instead.

use fibfluid_geometry::Vec3;
use fibfluid_geometry::vec3::dist;
use fibfluid_geometry::vec3::{cross, sub};

use crate::grid::{Embedded, SNAP, SparseGrid};
use crate::tissue::Tissue;

/// The clamp's penalty, in units of `E / h` per unit area of fixed surface. A fixed patch of
/// area `h^2` adds `CLAMP_PENALTY * E * h` (spread by its points' weights `w w^T`) to K,
/// whose diagonal entries are themselves `E h` times a factor of order one: the penalty is
/// scaled to K's diagonal at every resolution and for every tissue.
///
/// Error bound (the clamp's slip): the penalty forces balance the load, so the
/// area-weighted mean displacement of the fixed surface along a fixed axis is exactly
/// `F_a h / (CLAMP_PENALTY * E * A)` for a net load `F_a` held by a clamp of area `A`
/// (tested). It vanishes like `h`, so the clamp converges to the exact one. Too small a
/// penalty lets the clamp slip (soft); too large a one imposes `u = 0` at every sample of a
/// curved patch, which a trilinear cell can meet only by holding nearly all its nodes
/// (stiff: the embedded-Dirichlet locking). Measured on the sphere and liver goldens at
/// resolution 16 (`docs/fem.md`): penalty 3: 1.25x too soft (liver), 10: within 4 %,
/// 30 and 100: 0.85 and 0.91 of the reference sag, a stiff exact constraint: 0.74.
pub const CLAMP_PENALTY: f64 = 10.0;

/// The penalty per unit area of fixed surface: `CLAMP_PENALTY * E / h`.
pub(crate) fn clamp_stiffness(tissue: &Tissue, h: f64) -> f64 {
    CLAMP_PENALTY * tissue.young() / h
}

/// One penalty term `beta * area * (w . u_axis)^2 / 2`: an embedded surface point held at 0
/// along one axis, standing for `area` of the fixed surface.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ClampPoint {
    pub(crate) nodes: [usize; 8],
    pub(crate) weights: [f64; 8],
    pub(crate) axis: usize,
    pub(crate) area: f64,
}

/// The clamp of a body: dofs eliminated exactly (a fixed point sitting on a node) and the
/// penalty points.
pub(crate) struct Clamp {
    pub(crate) eliminated: Vec<bool>,
    pub(crate) points: Vec<ClampPoint>,
}

fn area(c: [Vec3; 3]) -> f64 {
    let n = cross(sub(c[1], c[0]), sub(c[2], c[0]));
    0.5 * (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt()
}

/// Quadrature weights (shares of the triangle's area) of the lattice points of
/// [`fixed_surface_samples`] at `k` subdivisions: each of the `k^2` sub-triangles gives a
/// third of its area to each of its corners (exact for linear functions, sums to 1).
pub(crate) fn lattice_shares(k: usize) -> Vec<f64> {
    // Points are produced in the order (i, j) for i in 0..=k, j in 0..=k-i.
    let mut offset = Vec::with_capacity(k + 2);
    let mut acc = 0;
    for i in 0..=k {
        offset.push(acc);
        acc += k - i + 1;
    }
    let at = |i: usize, j: usize| offset[i] + j;
    let mut share = vec![0.0; acc];
    let third = 1.0 / (3.0 * (k * k) as f64);
    for i in 0..k {
        for j in 0..k - i {
            for (a, b) in [(i, j), (i + 1, j), (i, j + 1)] {
                share[at(a, b)] += third;
            }
            if i + j + 2 <= k {
                for (a, b) in [(i + 1, j), (i, j + 1), (i + 1, j + 1)] {
                    share[at(a, b)] += third;
                }
            }
        }
    }
    share
}

impl Clamp {
    /// Builds the clamp of `fixed` on `grid` (see [`crate::FemBody`]).
    pub(crate) fn new(grid: &SparseGrid, fixed: &[[bool; 3]]) -> Self {
        let mut eliminated = vec![false; 3 * grid.n_nodes()];
        let mut points = Vec::new();
        let pos = grid.surface_positions();
        let h = grid.cell_size();
        let mut covered = vec![[false; 3]; pos.len()];
        let mut push = |e: &Embedded, axis: usize, area: f64, eliminated: &mut Vec<bool>| {
            if let Some(b) = (0..8).find(|&b| e.weights[b] >= 1.0 - SNAP) {
                eliminated[3 * e.nodes[b] + axis] = true;
            } else {
                points.push(ClampPoint { nodes: e.nodes, weights: e.weights, axis, area });
            }
        };
        // Lumped vertex areas, for fixed vertices outside any fully fixed triangle.
        let mut lumped = vec![0.0; pos.len()];
        for t in grid.surface_triangles() {
            let corners = t.map(|v| pos[v as usize]);
            let a = area(corners);
            for &v in t {
                lumped[v as usize] += a / 3.0;
            }
            let axes: [bool; 3] = std::array::from_fn(|a| t.iter().all(|&v| fixed[v as usize][a]));
            if !axes.iter().any(|&f| f) {
                continue;
            }
            for &v in t {
                for ax in 0..3 {
                    covered[v as usize][ax] |= axes[ax];
                }
            }
            let samples = fixed_surface_samples(corners, h);
            let k = ((((8 * samples.len() + 1) as f64).sqrt() - 3.0) / 2.0).round() as usize;
            let shares = lattice_shares(k);
            for (p, s) in samples.into_iter().zip(shares) {
                if let Some(e) = grid.locate(p) {
                    for ax in (0..3).filter(|&ax| axes[ax]) {
                        push(&e, ax, s * a, &mut eliminated);
                    }
                }
            }
        }
        for (v, (e, axes)) in grid.embedding().iter().zip(fixed).enumerate() {
            for ax in (0..3).filter(|&ax| axes[ax] && !covered[v][ax]) {
                push(e, ax, lumped[v], &mut eliminated);
            }
        }
        Self { eliminated, points }
    }
}

/// Points of a triangle at barycentric spacing `1/k` with `k = ceil(2 * longest edge / h)`:
/// samples at most `h / 2` apart, the corners included.
pub fn fixed_surface_samples(corners: [Vec3; 3], h: f64) -> Vec<Vec3> {
    let edge = (0..3).map(|i| dist(corners[i], corners[(i + 1) % 3])).fold(0.0, f64::max);
    let k = ((2.0 * edge / h).ceil() as usize).clamp(1, 1 << 12);
    let mut out = Vec::with_capacity((k + 1) * (k + 2) / 2);
    for i in 0..=k {
        for j in 0..=k - i {
            let (s, t) = (i as f64 / k as f64, j as f64 / k as f64);
            out.push(std::array::from_fn(|a| {
                corners[0][a] + s * (corners[1][a] - corners[0][a]) + t * (corners[2][a] - corners[0][a])
            }));
        }
    }
    out
}
