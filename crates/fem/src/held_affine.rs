//! Frames of a patch held as one body: a grasp's many rows answered from a dozen columns.
//!
//! A grasp holds `n` surface vertices at the targets of one rigid motion of where it picked
//! them up: `d_i = o_i + (R - I)(Y_i - c) + t` with `Y_i = X_i + o_i` the positions it took
//! (`o_i` their displacement then: 0 for a grasp from the rest shape, the body's own
//! equilibrium for one from there), so every target is an affine function of `Y_i` plus a
//! fixed offset. The rows are made on a first frame's targets: `o_i` is taken as those, and
//! `Y_i` as where they put the vertices. With the `Y_i`'s orthonormal coordinates `phi_i`
//! (a constant and the patch's principal directions: `k <= 4` of them, 3 for a flat patch),
//! the `3n` row targets are `o + E q` for `3k` parameters `q`. Everything a surface-only frame computes
//! (`crate::held_system::HeldSystem::solve_surface`) is affine in the targets, so on the
//! same rows it is affine in `q`: the surface `s0 + S q`, the multipliers `l0 + L q` and,
//! with dependent rows, the constraints' miss `e0 + M q`, each made once per set of rows
//! with `3k` capacitance solves. A frame then fits `q` to its targets (`3 n k` flops),
//! checks the fit, and costs `3 x surface vertices x 3k` flops instead of `3 x surface
//! vertices x columns`, whatever the patch's size. Targets that no affine map fits to
//! [`AFFINE_FIT`] (a patch deformed, grabs moved one by one) take the general path; the
//! answer is the same to rounding either way.

use faer::{Accum, Mat, MatRef, Par};
use fibfluid_geometry::Vec3;
use fibfluid_linalg::RowCapacitance;

use crate::error::{FemError, Result};
use crate::held_basis::Combination;
use crate::held_rows::{CONSTRAINT_TOLERANCE, FemHold, Row, SurfaceSolve, refined_multipliers};

/// Fewest held vertices worth the affine frames: below, the rows are no more than the
/// parameters.
pub const AFFINE_MIN_VERTICES: usize = 5;

/// Largest misfit of the targets (less the offset) to an affine map of the first frame's
/// target positions, relative to the larger of the largest of them and the patch's size,
/// for a frame to take the affine path.
pub const AFFINE_FIT: f64 = 1e-12;

/// A rest coordinate whose spread over the patch is below this fraction of the patch's
/// size is dropped (a flat patch has 2 directions).
const FLAT: f64 = 1e-9;

/// What the frames of one set of rows need (see the module docs).
#[derive(Debug, Clone)]
pub(crate) struct AffineFrames {
    /// The held vertices, in hold order.
    vertices: Vec<usize>,
    /// Orthonormal coordinates of the first frame's target positions, `n x k`.
    phi: Mat<f64>,
    /// The first frame's targets (displacements from rest), the offset the fit adds to.
    offset: Vec<Vec3>,
    /// Largest distance of a held vertex from the patch's centroid (m).
    size: f64,
    /// Per row, its base state's value (the absolute target less the row's target).
    base_values: Vec<f64>,
    surface0: Vec<f64>,
    surface: Mat<f64>,
    lambda0: Vec<f64>,
    lambda: Mat<f64>,
    /// The constraints' miss, kept when the capacitance needed a ridge (dependent rows).
    miss: Option<(Vec<f64>, Mat<f64>)>,
    uncovered: usize,
}

/// The pieces of one set of rows' surface-only frames that the affine frames are made of.
pub(crate) struct FrameParts<'a> {
    pub(crate) holds: &'a [(usize, FemHold)],
    pub(crate) rows: &'a [Row],
    pub(crate) rest: &'a [Vec3],
    pub(crate) capacitance: &'a RowCapacitance,
    pub(crate) ridged: bool,
    /// Per row, the penalty stiffness its target is pushed with (0: not penalized).
    pub(crate) penalty: &'a [f64],
    pub(crate) uncovered: usize,
    /// `C u0` and `S u0`.
    pub(crate) rows_unheld: &'a [f64],
    pub(crate) surface_unheld: &'a [f64],
    pub(crate) combination: &'a Combination,
    /// `S G`.
    pub(crate) columns: MatRef<'a, f64>,
}

/// `a + b` entry by entry (column vectors).
fn plus(a: &[f64], b: &Mat<f64>) -> Vec<f64> {
    a.iter().zip(b.col_as_slice(0)).map(|(x, y)| x + y).collect()
}

/// `m x` for a matrix `x`.
fn times(m: MatRef<'_, f64>, x: MatRef<'_, f64>) -> Mat<f64> {
    let mut out = Mat::zeros(m.nrows(), x.ncols());
    faer::linalg::matmul::matmul(out.as_mut(), Accum::Replace, m, x, 1.0, Par::Seq);
    out
}

/// A column vector.
fn column(v: &[f64]) -> Mat<f64> {
    Mat::from_fn(v.len(), 1, |i, _| v[i])
}

impl AffineFrames {
    /// The affine frames of `parts`' rows, or `None` when they are not a patch held at
    /// points (fewer than [`AFFINE_MIN_VERTICES`] vertices, a contact, an axis only fixed
    /// nodes carry).
    pub(crate) fn new(parts: &FrameParts<'_>) -> Option<Self> {
        let holds = parts.holds;
        let n = holds.len();
        let at_points = holds.iter().all(|h| matches!(h.1, FemHold::At(_)));
        if n < AFFINE_MIN_VERTICES || !at_points || parts.rows.len() != 3 * n {
            return None;
        }
        let offset: Vec<Vec3> = holds
            .iter()
            .map(|h| match h.1 {
                FemHold::At(d) => d,
                FemHold::Along { .. } => unreachable!("checked above"),
            })
            .collect();
        let taken = holds.iter().zip(&offset).map(|(h, o)| fibfluid_geometry::vec3::add(parts.rest[h.0], *o));
        let (phi, size) = coordinates(taken)?;
        let k = phi.ncols();
        let p = 3 * k;
        let m = 3 * n;
        let absolute = |i: usize| offset[i / 3][i % 3];
        let base_values: Vec<f64> = (0..m).map(|i| absolute(i) - parts.rows[i].target).collect();
        // t = o + E q - base_values; E[(3i + a), (a k + j)] = phi[i, j].
        let e = Mat::from_fn(m, p, |r, c| if c / k == r % 3 { phi[(r / 3, c % k)] } else { 0.0 });
        let t0 = column(&(0..m).map(|i| absolute(i) - base_values[i]).collect::<Vec<_>>());
        let cz = parts.capacitance.matrix();
        let pushed = |x: &Mat<f64>| Mat::from_fn(m, x.ncols(), |i, j| parts.penalty[i] * x[(i, j)]);
        let (p0, pe) = (pushed(&t0), pushed(&e));
        // gap = C u0 + (C Z) pushes - t; r = (C Z)^-1 gap; w = pushes - r.
        let gap0 = plus(parts.rows_unheld, &(times(cz, p0.as_ref()) - &t0));
        let gap = times(cz, pe.as_ref()) - &e;
        let solve = |g: &[f64]| refined_multipliers(parts.capacitance, parts.ridged, g);
        let r0 = column(&solve(&gap0));
        let mut r = Mat::zeros(m, p);
        for j in 0..p {
            r.col_as_slice_mut(j).copy_from_slice(&solve(gap.col_as_slice(j)));
        }
        let (w0, w) = (&p0 - &r0, &pe - &r);
        let miss = parts.ridged.then(|| {
            let miss0 = plus(parts.rows_unheld, &(times(cz, w0.as_ref()) - &t0));
            (miss0, times(cz, w.as_ref()) - &e)
        });
        let to_basis = |x: &Mat<f64>| {
            let b = parts.combination.basis.len();
            let mut out = Mat::zeros(b, x.ncols());
            for j in 0..x.ncols() {
                out.col_as_slice_mut(j)
                    .copy_from_slice(&parts.combination.transpose_times(x.col_as_slice(j)));
            }
            out
        };
        let surface0 = plus(parts.surface_unheld, &times(parts.columns, to_basis(&w0).as_ref()));
        let surface = times(parts.columns, to_basis(&w).as_ref());
        Some(Self {
            vertices: holds.iter().map(|h| h.0).collect(),
            phi,
            offset,
            size,
            base_values,
            surface0,
            surface,
            lambda0: r0.col_as_slice(0).iter().map(|x| -x).collect(),
            lambda: -&r,
            miss,
            uncovered: parts.uncovered,
        })
    }

    /// The parameters `q` a frame fits (`3k`): the columns it reads.
    pub(crate) fn parameters(&self) -> usize {
        self.surface.ncols()
    }

    /// The frame for `holds` on the affine path: `None` when they are not these rows'
    /// vertices held at points, or their targets fit no affine map of the rest positions.
    ///
    /// Errors: dependent holds whose targets contradict each other.
    pub(crate) fn frame(&self, holds: &[(usize, FemHold)]) -> Option<Result<SurfaceSolve>> {
        if holds.len() != self.vertices.len() || holds.iter().zip(&self.vertices).any(|(h, v)| h.0 != *v) {
            return None;
        }
        let targets: Vec<Vec3> = holds
            .iter()
            .map(|h| if let FemHold::At(d) = h.1 { Some(d) } else { None })
            .collect::<Option<_>>()?;
        let moved: Vec<Vec3> =
            targets.iter().zip(&self.offset).map(|(t, o)| fibfluid_geometry::vec3::sub(*t, *o)).collect();
        let q = self.fit(&moved)?;
        let affine = |v0: &[f64], v: &Mat<f64>| -> Vec<f64> {
            let mut out = column(v0);
            faer::linalg::matmul::matmul(out.as_mut(), Accum::Add, v.as_ref(), q.as_ref(), 1.0, Par::Seq);
            out.col_as_slice(0).to_vec()
        };
        if let Some((miss0, miss)) = &self.miss {
            let relative = |i: usize| targets[i / 3][i % 3] - self.base_values[i];
            let scale = (0..self.base_values.len()).fold(1.0_f64, |a, i| a.max(relative(i).abs()));
            let missed = affine(miss0, miss).iter().position(|e| e.abs() > CONSTRAINT_TOLERANCE * scale);
            if let Some(i) = missed {
                return Some(Err(FemError::DependentHolds { vertex: self.vertices[i / 3] }));
            }
        }
        let surface = affine(&self.surface0, &self.surface);
        let lambda = affine(&self.lambda0, &self.lambda);
        let reactions =
            (0..self.vertices.len()).map(|i| [lambda[3 * i], lambda[3 * i + 1], lambda[3 * i + 2]]);
        let displacement =
            (0..surface.len() / 3).map(|v| [surface[3 * v], surface[3 * v + 1], surface[3 * v + 2]]);
        Some(Ok(SurfaceSolve {
            surface: displacement.collect(),
            reactions: reactions.collect(),
            uncovered: self.uncovered,
        }))
    }

    /// The parameters `q` (a column: per axis, the `k` coordinates' coefficients) of the
    /// targets less the offset, or `None` when they miss the fit by more than
    /// [`AFFINE_FIT`].
    fn fit(&self, targets: &[Vec3]) -> Option<Mat<f64>> {
        let (n, k) = (self.phi.nrows(), self.phi.ncols());
        let q = Mat::from_fn(3 * k, 1, |c, _| (0..n).map(|i| self.phi[(i, c % k)] * targets[i][c / k]).sum());
        let largest = targets.iter().flatten().fold(0.0_f64, |a, d| a.max(d.abs()));
        let tolerance = AFFINE_FIT * largest.max(self.size);
        let fits = (0..n).all(|i| {
            (0..3).all(|a| {
                let fitted: f64 = (0..k).map(|j| self.phi[(i, j)] * q[(a * k + j, 0)]).sum();
                (fitted - targets[i][a]).abs() <= tolerance
            })
        });
        fits.then_some(q)
    }
}

/// Orthonormal coordinates (`n x k`) of `points` spanning the constants and their affine
/// directions (Gram–Schmidt on `1, x, y, z` about the centroid, a direction dropped when
/// its spread is below [`FLAT`] of the patch's size), and the patch's size (m); `None` for
/// coincident points.
fn coordinates(points: impl Iterator<Item = Vec3>) -> Option<(Mat<f64>, f64)> {
    let points: Vec<Vec3> = points.collect();
    let n = points.len() as f64;
    let centroid: Vec3 = std::array::from_fn(|a| points.iter().map(|p| p[a]).sum::<f64>() / n);
    let centred: Vec<Vec3> = points.iter().map(|p| std::array::from_fn(|a| p[a] - centroid[a])).collect();
    let size = centred.iter().map(|c| fibfluid_geometry::vec3::norm(*c)).fold(0.0, f64::max);
    if size <= 0.0 {
        return None;
    }
    let mut basis: Vec<Vec<f64>> = vec![vec![1.0 / n.sqrt(); points.len()]];
    for a in 0..3 {
        let mut v: Vec<f64> = centred.iter().map(|c| c[a] / size).collect();
        // Twice: one pass leaves rounding along the earlier directions.
        for b in basis.iter().chain(&basis) {
            let dot: f64 = v.iter().zip(b).map(|(x, y)| x * y).sum();
            v.iter_mut().zip(b).for_each(|(x, y)| *x -= dot * y);
        }
        let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        if norm > FLAT * n.sqrt() {
            basis.push(v.into_iter().map(|x| x / norm).collect());
        }
    }
    let phi = Mat::from_fn(points.len(), basis.len(), |i, j| basis[j][i]);
    Some((phi, size))
}
