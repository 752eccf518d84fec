//! The projected fiber model (`[ffm] fibers = "projected"`): each fiber's spring acts
//! along the fiber.
//!
//! The paper's fiber `ij` pulls vertex i with `k_ij (u_j - u_i)` on every axis alike, so
//! each axis has its own graph Laplacian and a rigid rotation of the body stretches fibers
//! that keep their length. Here the force is projected on the fiber's rest direction
//! `d_ij = (s_j - s_i) / |s_j - s_i|`: `k_ij d_ij d_ij' (u_j - u_i)`, the linearized spring.
//! The fibers and moduli are the paper's: `k_ij = Y w_ij + t_ij` (Eq. 6 over the kept
//! fibers plus Eq. 7 on mesh edges, see the crate docs). The 3x3 (2x2 for a polygon) block
//! `k d d'` is added to the (i, i) and (j, j) diagonal blocks and subtracted from (i, j)
//! and (j, i).
//!
//! Layout: axis-major, the paper's order of unknowns: row and column `c N + i` are vertex
//! i's component c. The matrix is dense, dN x dN; its null space before constraints holds
//! the translations and the infinitesimal rotations `omega x s_i` of the rest shape.
//!
//! Constraints are imposed as the paper's system does ([`ConstraintMethod`]): elimination
//! zeroes the rows and columns of fixed degrees of freedom and sets their diagonal to the
//! mean free diagonal (prescribed values go to the right-hand side); the penalty replaces
//! the diagonal by `big`. The border is the physical `S` (zero at eliminated degrees of
//! freedom): the coupled solver handles it by a Schur complement, so no pressure scaling
//! is applied.

use std::time::Instant;

use fibfluid_geometry::Vec3;
use fibfluid_linalg::Mat;
use rayon::prelude::*;

use crate::block::PairData;
use crate::body::Body;
use crate::system::AssemblyStats;
use crate::{AssemblyError, AssemblyOptions, ConstraintMethod, Constraints, Material, Result};

/// The projected bordered system `[K S; S' 0] [u; P] = [f; t]` (see the module docs).
#[derive(Clone, Debug)]
pub struct ProjectedSystem {
    /// K, dN x dN, axis-major, constraints imposed.
    pub stiffness: Mat<f64>,
    /// The physical border `S`, axis-major, zero at eliminated degrees of freedom.
    pub border: Vec<f64>,
    /// What assembly did (`blocks` is 1: one coupled matrix).
    pub stats: AssemblyStats,
    constraints: Constraints,
    method: ConstraintMethod,
    axes: usize,
    n: usize,
    diag_scale: f64,
    /// (degree of freedom, prescribed value, its column before elimination).
    lifts: Vec<(usize, f64, Vec<f64>)>,
}

/// What one column of the projected stiffness is built with.
struct ColumnSpec<'a> {
    pairs: &'a PairData<'a>,
    axes: usize,
    fiber_modulus: f64,
    /// Per degree of freedom: fixed (empty: no constraints).
    fixed: Vec<bool>,
    method: ConstraintMethod,
    /// Degrees of freedom whose column before elimination is kept (non-zero prescribed).
    keep: Vec<usize>,
}

/// What one column reports.
#[derive(Default)]
struct ColumnOut {
    diag: f64,
    kept: Option<Vec<f64>>,
    coincident: Option<(usize, usize, f64)>,
}

/// The projected stiffness of a body without constraints (dN x dN, axis-major): symmetric
/// positive semi-definite, with the rigid motions of `body.positions` in its null space.
pub fn projected_stiffness(body: &Body, material: &Material) -> Result<Mat<f64>> {
    check(body, material)?;
    let pairs = PairData::new(body, material, body.fibers.mean_connections());
    let spec = ColumnSpec {
        pairs: &pairs,
        axes: body.axes,
        fiber_modulus: material.fiber_modulus()[0],
        fixed: Vec::new(),
        method: ConstraintMethod::Eliminate,
        keep: Vec::new(),
    };
    Ok(fill(&spec)?.0)
}

/// Assembles the projected bordered system for a body, material and constraints (the
/// fibers, moduli and constraint method of [`assemble`](crate::assemble); the pressure
/// scaling option is ignored). The material must be isotropic (`Y` is a fiber's modulus,
/// not an axis's). Refuses, before allocating, a matrix that does not fit in the memory
/// budget.
pub fn assemble_projected(
    body: &Body,
    material: &Material,
    constraints: &Constraints,
    opts: &AssemblyOptions,
) -> Result<ProjectedSystem> {
    let start = Instant::now();
    check(body, material)?;
    crate::system::validate(body, material, constraints)?;
    let (n, axes) = (body.positions.len(), body.axes);
    let dof = |k: usize| (k % n, k / n);
    let fixed: Vec<bool> = (0..axes * n).map(|k| constraints.get(dof(k).0, dof(k).1).is_some()).collect();
    let prescribed = |k: usize| constraints.get(dof(k).0, dof(k).1).filter(|v| *v != 0.0);
    let keep = if opts.method == ConstraintMethod::Eliminate {
        (0..axes * n).filter(|&k| prescribed(k).is_some()).collect()
    } else {
        Vec::new()
    };
    let conn = body.fibers.mean_connections();
    let pairs = PairData::new(body, material, conn);
    let spec = ColumnSpec {
        pairs: &pairs,
        axes,
        fiber_modulus: material.fiber_modulus()[0],
        fixed,
        method: opts.method,
        keep,
    };
    let (stiffness, diag_scale, kept) = fill(&spec)?;
    let lifts = kept.into_iter().map(|(k, column)| (k, prescribed(k).expect("kept"), column)).collect();
    let border = border_of(body.vertex_areas, constraints, opts.method, axes);
    let gamma = material.surface_tension();
    let stats = AssemblyStats {
        bulk_fibers: body.fibers.kept(),
        surface_fibers: if gamma > 0.0 { body.edges.len() } else { 0 },
        connections: conn,
        blocks: 1,
        seconds: start.elapsed().as_secs_f64(),
    };
    Ok(ProjectedSystem {
        stiffness,
        border,
        stats,
        constraints: constraints.clone(),
        method: opts.method,
        axes,
        n,
        diag_scale,
        lifts,
    })
}

/// The border `S` for vertex area vectors `areas`, axis-major: zero at the degrees of
/// freedom elimination removes.
fn border_of(areas: &[Vec3], constraints: &Constraints, method: ConstraintMethod, axes: usize) -> Vec<f64> {
    let n = areas.len();
    (0..axes * n)
        .map(|k| {
            let (i, c) = (k % n, k / n);
            if method == ConstraintMethod::Eliminate && constraints.get(i, c).is_some() {
                0.0
            } else {
                areas[i][c]
            }
        })
        .collect()
}

/// The checks that need no matrix: an isotropic material and a matrix that fits.
fn check(body: &Body, material: &Material) -> Result<()> {
    material.check()?;
    if !material.is_isotropic() {
        return Err(AssemblyError::Material(
            "projected fibers need an isotropic modulus (Yx = Yy = Yz): a fiber has one modulus".into(),
        ));
    }
    // The matrix and its Cholesky factor.
    fibfluid_linalg::check_dense_memory(body.axes * body.positions.len(), 2)?;
    Ok(())
}

/// Fills the matrix column by column in parallel; returns it, the mean free diagonal and
/// the kept columns.
#[allow(clippy::type_complexity)]
fn fill(spec: &ColumnSpec) -> Result<(Mat<f64>, f64, Vec<(usize, Vec<f64>)>)> {
    let m = spec.axes * spec.pairs.x.len();
    let mut k = Mat::<f64>::zeros(m, m);
    let column = |(col, v): (usize, faer::MatMut<'_, f64>)| -> ColumnOut {
        let slice = v.col_mut(0).try_as_col_major_mut().expect("contiguous column").as_slice_mut();
        fill_column(spec, col, slice)
    };
    let outs: Vec<ColumnOut> = k.as_mut().par_col_chunks_mut(1).enumerate().map(column).collect();
    if let Some(&(i, j, distance)) = outs.iter().find_map(|o| o.coincident.as_ref()) {
        return Err(AssemblyError::CoincidentVertices { i, j, distance });
    }
    let free: Vec<f64> =
        (0..m).filter(|&c| !spec.fixed.get(c).copied().unwrap_or(false)).map(|c| outs[c].diag).collect();
    let mean_diag = free.iter().sum::<f64>() / free.len().max(1) as f64;
    if spec.method == ConstraintMethod::Eliminate {
        for c in (0..m).filter(|&c| spec.fixed.get(c).copied().unwrap_or(false)) {
            k[(c, c)] = mean_diag;
        }
    }
    let kept = outs.into_iter().enumerate().filter_map(|(c, o)| o.kept.map(|v| (c, v))).collect();
    Ok((k, mean_diag, kept))
}

/// Column `col` (vertex j, axis c): `-k d_a d_c` at (vertex i, axis a) for each fiber ij,
/// and `sum_i k d_a d_c` at (j, a); then the constraints.
fn fill_column(spec: &ColumnSpec, col: usize, v: &mut [f64]) -> ColumnOut {
    let pairs = spec.pairs;
    let n = pairs.x.len();
    let (j, c) = (col % n, col / n);
    let pos = pairs.body.positions;
    let mut out = ColumnOut::default();
    let mut diag = [0.0; 3];
    let mut add = |i: usize, k: f64, d: f64, v: &mut [f64]| {
        let dir = [(pos[i][0] - pos[j][0]) / d, (pos[i][1] - pos[j][1]) / d, (pos[i][2] - pos[j][2]) / d];
        for a in 0..spec.axes {
            // k (d_a d_c), the same rounding in column (a, i) row (c, j): bitwise symmetric.
            let e = k * (dir[a] * dir[c]);
            v[a * n + i] -= e;
            diag[a] += e;
        }
    };
    for i in (0..n).filter(|&i| i != j && pairs.body.fibers.contains(i, j)) {
        let (w, d) = pairs.bulk(i, j);
        if !(d > 0.0 && w.is_finite()) {
            out.coincident = Some((i.min(j), i.max(j), d));
            return out;
        }
        add(i, spec.fiber_modulus * w, d, v);
    }
    let gamma = pairs.material.surface_tension();
    for &i in pairs.neighbors.get(j).map(Vec::as_slice).unwrap_or(&[]) {
        let i = i as usize;
        let d = pairs.bulk(i, j).1;
        if d > 0.0 {
            add(i, gamma * (pairs.area[i] + pairs.area[j]) / (2.0 * d * d), d, v);
        }
    }
    for a in 0..spec.axes {
        v[a * n + j] = diag[a];
    }
    out.diag = diag[c];
    if spec.keep.binary_search(&col).is_ok() {
        out.kept = Some(v.to_vec());
    }
    if spec.fixed.is_empty() {
        return out;
    }
    match spec.method {
        ConstraintMethod::Penalty { big } => {
            if spec.fixed[col] {
                v[col] = big;
            }
        }
        ConstraintMethod::Eliminate => {
            if spec.fixed[col] {
                v.fill(0.0);
            } else {
                v.iter_mut().zip(&spec.fixed).filter(|(_, f)| **f).for_each(|(x, _)| *x = 0.0);
            }
        }
    }
    out
}

impl ProjectedSystem {
    /// Number of axes.
    pub fn axes(&self) -> usize {
        self.axes
    }

    /// Number of vertices.
    pub fn n_vertices(&self) -> usize {
        self.n
    }

    /// The constraints it was assembled with.
    pub fn constraints(&self) -> &Constraints {
        &self.constraints
    }

    /// The constraint method.
    pub fn method(&self) -> ConstraintMethod {
        self.method
    }

    /// The border `S` of another shape (its vertex area vectors), as assembly builds it:
    /// axis-major, zero at eliminated degrees of freedom (refresh mode's new border).
    pub fn border_for(&self, areas: &[Vec3]) -> Vec<f64> {
        border_of(areas, &self.constraints, self.method, self.axes)
    }

    /// The right-hand side `[f; t]` for a load vector `b` (length dN, axis-major) and a
    /// volume target, as [`System::rhs`](crate::System::rhs) builds it: prescribed
    /// displacements (times `prescribed_scale`) enter through the constraint method,
    /// and under elimination through the volume row with `border_areas`.
    pub fn rhs(
        &self,
        b: &[f64],
        volume_target: f64,
        border_areas: &[Vec3],
        prescribed_scale: f64,
    ) -> Vec<f64> {
        let n = self.n;
        let mut r = Vec::with_capacity(self.axes * n + 1);
        r.extend_from_slice(b);
        let mut target = volume_target;
        for c in 0..self.axes {
            for i in 0..n {
                if let Some(v) = self.constraints.get(i, c) {
                    let v = v * prescribed_scale;
                    match self.method {
                        ConstraintMethod::Penalty { big } => r[c * n + i] += big * v,
                        ConstraintMethod::Eliminate => {
                            r[c * n + i] = self.diag_scale * v;
                            target -= border_areas[i][c] * v;
                        }
                    }
                }
            }
        }
        for (dof, value, column) in &self.lifts {
            for (k, rk) in r.iter_mut().enumerate() {
                if k != *dof && self.constraints.get(k % n, k / n).is_none() {
                    *rk -= column[k] * value * prescribed_scale;
                }
            }
        }
        r.push(target);
        r
    }

    /// Splits a solution `[u; P]` into per-vertex displacements and the pressure.
    pub fn split_solution(&self, x: &[f64]) -> (Vec<Vec3>, f64) {
        let n = self.n;
        let u = (0..n)
            .map(|i| {
                let mut v = [0.0; 3];
                for (c, vc) in v.iter_mut().enumerate().take(self.axes) {
                    *vc = x[c * n + i];
                }
                v
            })
            .collect();
        (u, x[self.axes * n])
    }
}
