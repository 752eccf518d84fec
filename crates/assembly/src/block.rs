//! One stiffness block `K_c`, written once, column by column in parallel.

use fibfluid_linalg::Mat;
use rayon::prelude::*;

use crate::body::Body;
use crate::{AssemblyError, ConstraintMethod, Material, Result};

/// What one block is built from besides the pair data.
pub(crate) struct BlockSpec {
    /// `Y_c` of the block.
    pub fiber_modulus: f64,
    /// The degrees of freedom fixed along the block's axis.
    pub fixed: Vec<bool>,
    /// How they are imposed.
    pub method: ConstraintMethod,
    /// Free border of each served axis (empty: no automatic pressure scale).
    pub borders: Vec<Vec<f64>>,
    /// Vertices whose column before elimination is kept (prescribed non-zero values).
    pub keep: Vec<usize>,
}

/// A filled block and what the assembly needs from it.
pub(crate) struct BlockFill {
    pub k: Mat<f64>,
    /// Mean diagonal over the free degrees of freedom (before elimination).
    pub mean_diag: f64,
    /// Per served axis: `(S' K S, S' S)` over the free degrees of freedom.
    pub scale_terms: Vec<(f64, f64)>,
    /// `(vertex, column before elimination)` for the vertices of `BlockSpec::keep`.
    pub kept_columns: Vec<(usize, Vec<f64>)>,
}

/// What one column reports.
#[derive(Default)]
struct ColumnOut {
    diag: f64,
    /// `S_j (K S)_j` per served axis.
    sks: Vec<f64>,
    kept: Option<Vec<f64>>,
    coincident: Option<(usize, usize, f64)>,
}

/// Fills the block of `spec` (see the module docs of `system`).
pub(crate) fn fill_block(pairs: &PairData, spec: &BlockSpec) -> Result<BlockFill> {
    let n = pairs.x.len();
    let mut k = Mat::<f64>::zeros(n, n);
    let column = |(j, m): (usize, faer::MatMut<'_, f64>)| -> ColumnOut {
        let col = m.col_mut(0).try_as_col_major_mut().expect("contiguous column").as_slice_mut();
        fill_column(pairs, spec, j, col)
    };
    let outs: Vec<ColumnOut> = if n >= 64 {
        k.as_mut().par_col_chunks_mut(1).enumerate().map(column).collect()
    } else {
        (0..n).map(|j| column((j, k.as_mut().subcols_mut(j, 1)))).collect()
    };
    if let Some(&(i, j, distance)) = outs.iter().filter_map(|o| o.coincident.as_ref()).next() {
        return Err(AssemblyError::CoincidentVertices { i, j, distance });
    }
    let free: Vec<f64> = (0..n).filter(|&i| !spec.fixed[i]).map(|i| outs[i].diag).collect();
    let mean_diag = free.iter().sum::<f64>() / free.len().max(1) as f64;
    if spec.method == ConstraintMethod::Eliminate {
        for i in (0..n).filter(|&i| spec.fixed[i]) {
            k[(i, i)] = mean_diag;
        }
    }
    let scale_terms = spec
        .borders
        .iter()
        .enumerate()
        .map(|(a, s)| {
            let sks = outs.iter().map(|o| o.sks[a]).sum::<f64>();
            (sks, s.iter().map(|v| v * v).sum::<f64>())
        })
        .collect();
    let kept_columns = outs.into_iter().enumerate().filter_map(|(j, o)| o.kept.map(|c| (j, c))).collect();
    Ok(BlockFill { k, mean_diag, scale_terms, kept_columns })
}

/// Column j (= row j): off-diagonals `-(Y w_ij + t_ij)`, the diagonal, then the fixed
/// degrees of freedom and the pressure-scale terms.
fn fill_column(pairs: &PairData, spec: &BlockSpec, j: usize, col: &mut [f64]) -> ColumnOut {
    let mut out = ColumnOut::default();
    pulp::Arch::new().dispatch(Weights { pairs, fiber_modulus: spec.fiber_modulus, j, col });
    if !pairs.material.law().is_linear() {
        for (i, v) in col.iter_mut().enumerate() {
            *v = if i == j { 0.0 } else { -(spec.fiber_modulus * pairs.bulk(i, j).0) };
        }
    }
    if !pairs.all_fibers {
        for (i, v) in col.iter_mut().enumerate() {
            if !pairs.body.fibers.contains(i, j) {
                *v = 0.0;
            }
        }
    }
    col[j] = 0.0;
    if col.iter().any(|v| !v.is_finite()) {
        // A zero (or NaN) distance on a kept fiber: name the pair, as the paper's loop would.
        for i in (0..col.len()).filter(|&i| i != j && pairs.body.fibers.contains(i, j)) {
            let d = pairs.bulk(i, j).1;
            if !(d > 0.0) {
                out.coincident = Some((i.min(j), i.max(j), d));
                return out;
            }
        }
    }
    if let Some(nbrs) = pairs.neighbors.get(j) {
        let gamma = pairs.material.surface_tension();
        for &i in nbrs {
            let i = i as usize;
            let d = dist(pairs.body.positions[i], pairs.body.positions[j]);
            if d > 0.0 {
                let t = gamma * (pairs.area[i] + pairs.area[j]) / (2.0 * d * d);
                let w = if pairs.all_fibers || pairs.body.fibers.contains(i, j) {
                    pairs.bulk(i, j).0
                } else {
                    0.0
                };
                col[i] = -(spec.fiber_modulus * w + t);
            }
        }
    }
    out.diag = -sum8(col);
    col[j] = out.diag;
    if spec.keep.binary_search(&j).is_ok() {
        out.kept = Some(col.to_vec());
    }
    impose_fixed(spec, j, col);
    out.sks = spec.borders.iter().map(|s| if s[j] != 0.0 { s[j] * dot8(s, col) } else { 0.0 }).collect();
    out
}

/// The constraint method on column j: a fixed column is zero (its diagonal is set to the
/// mean diagonal later) under elimination and has `big` on the diagonal under the penalty;
/// the rows of fixed degrees of freedom are zero under elimination.
fn impose_fixed(spec: &BlockSpec, j: usize, col: &mut [f64]) {
    match spec.method {
        ConstraintMethod::Penalty { big } => {
            if spec.fixed[j] {
                col[j] = big;
            }
        }
        ConstraintMethod::Eliminate => {
            if spec.fixed[j] {
                col.fill(0.0);
            } else {
                for (v, f) in col.iter_mut().zip(&spec.fixed) {
                    if *f {
                        *v = 0.0;
                    }
                }
            }
        }
    }
}

#[inline]
fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Sum with eight accumulators (vectorized).
fn sum8(v: &[f64]) -> f64 {
    let (c, r) = v.as_chunks::<8>();
    let mut acc = [0.0f64; 8];
    for x in c {
        for l in 0..8 {
            acc[l] += x[l];
        }
    }
    acc.iter().sum::<f64>() + r.iter().sum::<f64>()
}

/// Dot product with eight accumulators (vectorized).
fn dot8(a: &[f64], b: &[f64]) -> f64 {
    let (ca, ra) = a.as_chunks::<8>();
    let (cb, rb) = b[..a.len()].as_chunks::<8>();
    let mut acc = [0.0f64; 8];
    for (x, y) in ca.iter().zip(cb) {
        for l in 0..8 {
            acc[l] += x[l] * y[l];
        }
    }
    acc.iter().sum::<f64>() + ra.iter().zip(rb).map(|(x, y)| x * y).sum::<f64>()
}

/// The bulk weights of column j, `-(Y (|S_i| + |S_j|) / (2 n_eff d_ij))`, over contiguous
/// arrays; compiled for the widest vector unit (runtime dispatch).
struct Weights<'a, 'b> {
    pairs: &'a PairData<'b>,
    fiber_modulus: f64,
    j: usize,
    col: &'a mut [f64],
}

impl pulp::WithSimd for Weights<'_, '_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        let p = self.pairs;
        let j = self.j;
        let (xj, yj, zj, aj) = (p.x[j], p.y[j], p.z[j], p.area[j]);
        let (two_conn, fiber_modulus) = (p.two_conn, self.fiber_modulus);
        let n = self.col.len();
        let it = self.col.iter_mut().zip(&p.x[..n]).zip(&p.y[..n]).zip(&p.z[..n]).zip(&p.area[..n]);
        match p.kernel {
            None => {
                for ((((v, x), y), z), a) in it {
                    let (dx, dy, dz) = (x - xj, y - yj, z - zj);
                    let d = (dx * dx + dy * dy + dz * dz).sqrt();
                    *v = -(fiber_modulus * ((a + aj) / (two_conn * d)));
                }
            }
            Some((length, power)) => {
                for ((((v, x), y), z), a) in it {
                    let (dx, dy, dz) = (x - xj, y - yj, z - zj);
                    let d = (dx * dx + dy * dy + dz * dz).sqrt();
                    *v = -(fiber_modulus * ((a + aj) / (two_conn * d)) * (length / d).powf(power));
                }
            }
        }
    }
}

/// The kernel of [`PairData::kernel`]: `None` for the paper's exponent.
fn kernel(body: &Body, material: &Material) -> Option<(f64, f64)> {
    let p = material.kernel_exponent();
    if p == crate::PAPER_KERNEL_EXPONENT {
        return None;
    }
    let (lo, hi) = fibfluid_geometry::bounding_box(body.rest_positions.unwrap_or(body.positions));
    Some((dist(lo, hi), p - 1.0))
}

/// What the weight of a vertex pair depends on, in contiguous per-vertex arrays.
pub(crate) struct PairData<'a> {
    pub(crate) x: Vec<f64>,
    pub(crate) y: Vec<f64>,
    pub(crate) z: Vec<f64>,
    /// `|S_i|`.
    pub(crate) area: Vec<f64>,
    /// `2 n_eff`, the denominator factor of Eq. 6.
    pub(crate) two_conn: f64,
    pub(crate) body: &'a Body<'a>,
    pub(crate) material: &'a Material,
    /// Every pair is a fiber (no bitset lookups).
    pub(crate) all_fibers: bool,
    /// Surface-edge neighbours of each vertex (empty when gamma = 0).
    pub(crate) neighbors: Vec<Vec<u32>>,
    /// `(l, p - 1)` of a kernel exponent `p` other than the paper's 1: the weight is
    /// multiplied by `(l / d)^(p - 1)`, `l` the rest shape's bounding-box diagonal.
    pub(crate) kernel: Option<(f64, f64)>,
}

impl<'a> PairData<'a> {
    pub(crate) fn new(body: &'a Body<'a>, material: &'a Material, conn: f64) -> Self {
        let n = body.positions.len();
        let coord = |c: usize| body.positions.iter().map(|p| p[c]).collect();
        let mut neighbors: Vec<Vec<u32>> =
            vec![Vec::new(); if material.surface_tension() > 0.0 { n } else { 0 }];
        if material.surface_tension() > 0.0 {
            for e in body.edges {
                neighbors[e[0] as usize].push(e[1]);
                neighbors[e[1] as usize].push(e[0]);
            }
            neighbors.iter_mut().for_each(|v| v.sort_unstable());
        }
        Self {
            x: coord(0),
            y: coord(1),
            z: coord(2),
            area: body
                .vertex_areas
                .iter()
                .map(|s| (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt())
                .collect(),
            two_conn: 2.0 * conn,
            body,
            material,
            all_fibers: body.fibers.kept() == body.fibers.total(),
            neighbors,
            kernel: kernel(body, material),
        }
    }

    /// The bulk weight `w_ij` (Eq. 6, strain factor included) and the distance.
    pub(crate) fn bulk(&self, i: usize, j: usize) -> (f64, f64) {
        let d = dist(self.body.positions[i], self.body.positions[j]);
        let mut w = (self.area[i] + self.area[j]) / (self.two_conn * d);
        if let Some((length, power)) = self.kernel {
            w *= (length / d).powf(power);
        }
        if !self.material.law().is_linear() {
            let rest = self.body.rest_positions.unwrap_or(self.body.positions);
            let d0 = dist(rest[i], rest[j]);
            w *= self.material.law().factor((d - d0) / d0);
        }
        (w, d)
    }
}
