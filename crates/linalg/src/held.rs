//! Vertices held on a kept factorization of the bordered system: the one mechanism behind
//! the interactive fiber–fluid body and `Simulation::respond_held`.
//!
//! With `C_c = K_c^-1` (one N x N block per distinct stiffness block), the physical border
//! `S_c`, `w_c = C_c S_c` and `s = sum_c S_c . w_c`, point forces `f` at vertices give
//!
//! ```text
//! P   = (sum_c w_c . f_c) / s          (pressure change)
//! u_c = C_c f_c - w_c P                (displacement)
//! ```
//!
//! Holding k vertices `g` at displacements `d` (all axes) adds unknown reactions `r`:
//!
//! ```text
//! G r = d - y(g),    G[(v,a),(u,b)] = C_a[v,u] delta_ab - w_a[v] w_b[u] / s
//! ```
//!
//! where `y` is the field without the reactions. `G` (dk x dk) is the restriction of the
//! projected compliance `C - w w' / s` (the response at the held degrees of freedom to unit
//! forces there, pressure included), symmetric positive definite unless the held degrees of
//! freedom decide the volume alone. It is the capacitance matrix of the
//! Sherman–Morrison–Woodbury update that imposes the holds on a kept factorization instead
//! of refactoring.
//!
//! Everything above reads only the compliance columns of the touched vertices, `w` and `s`
//! ([`VertexResponse`]). Two sources provide them:
//!
//! - [`VertexColumns`]: the columns of touched vertices, computed when a vertex is first
//!   touched with the kept factorization (one bordered solve per distinct block, all new
//!   vertices of a call in one pass over the factor) and cached; `w` and `s` from one
//!   bordered solve. Works with every backend (it only solves the bordered system).
//! - the full inverse (`fibfluid_interact::Compliance` with the full precompute), every
//!   column at once, for haptic devices that need any vertex without a first-touch cost.
//!
//! The held rows are one capacitance update (`capacitance.rs`), the one every other user runs:
//! [`VertexSource`] is the [`CapacitanceSource`] of a [`VertexResponse`] (`C = E' W` is
//! `G`, read from the entries above; `x -= W r` is the point-force field of the reactions,
//! [`VertexResponse::add_field_axes`], one N-length column per force and axis), and
//! [`HeldCapacitance`] is the shared [`RowCapacitance`] over it, typed by its rows and
//! mapping a refused pivot to [`LinalgError::SingularHold`]. The dense `dN + 1` columns of
//! the dense-column source are never formed, so a hold keeps its cost: `N` values per
//! distinct block and vertex, `O(m^2)` entries for `G`, `O(k N)` per correction.
//! [`HeldCapacitance::impose`] corrects a whole solution (`Simulation::respond_held`); the
//! interactive body instead reads the gaps at the held vertices alone
//! ([`VertexResponse::displacement_at`]) and adds the reactions
//! ([`HeldCapacitance::reactions`], the same factor's solve) to its pushes' field in one
//! pass.

use std::sync::Arc;

use faer::Mat;

use crate::capacitance::{CapacitanceSource, RowCapacitance};
use crate::{Factorization, FactorizationExt, LinalgError, Result};

/// A point force (or a reaction) at a vertex: (vertex, components; unused axes zero).
pub type VertexForce = (usize, [f64; 3]);

/// The linear response of a factored bordered system to point forces at vertices, read
/// through compliance columns (see the module docs).
pub trait VertexResponse {
    /// Number of vertices N.
    fn n_vertices(&self) -> usize;
    /// Number of axes (2 or 3).
    fn axes(&self) -> usize;
    /// `w_c = C_c S_c` (physical border).
    fn w(&self, axis: usize) -> &[f64];
    /// `s = sum_c S_c . w_c` (physical border).
    fn schur(&self) -> f64;
    /// `C_axis[i, j]`. Column `j` must be available (touched, for a lazy source).
    fn entry(&self, axis: usize, i: usize, j: usize) -> f64;
    /// `y += a C_axis[:, j]` (`y` has N entries). Column `j` must be available.
    fn add_column(&self, axis: usize, j: usize, a: f64, y: &mut [f64]);
    /// Unit roundoff of the stored entries (for the capacitance's pivot check).
    fn epsilon(&self) -> f64;

    /// The pressure change `P = sum_c w_c . f_c / s` caused by point forces.
    fn pressure_of(&self, forces: &[VertexForce]) -> f64 {
        let mut p = 0.0;
        for &(v, f) in forces {
            for c in 0..self.axes() {
                p += self.w(c)[v] * f[c];
            }
        }
        p / self.schur()
    }

    /// The displacement at one vertex caused by point forces whose pressure change is
    /// `pressure`: `O(forces)`.
    fn displacement_at(&self, vertex: usize, forces: &[VertexForce], pressure: f64) -> [f64; 3] {
        let mut u = [0.0; 3];
        for c in 0..self.axes() {
            let mut acc = -self.w(c)[vertex] * pressure;
            for &(v, f) in forces {
                acc += self.entry(c, vertex, v) * f[c];
            }
            u[c] = acc;
        }
        u
    }

    /// Adds the field of point forces whose pressure change is `pressure` to `u`, stored
    /// axis by axis as the system's unknowns are (`u[c * N + i]`, `axes * N` entries):
    /// `u_c += sum_v C_c[:, v] f_v,c - w_c P`. One column per force and axis, `O(N)` each.
    ///
    /// # Panics
    /// If `u` does not have `axes * N` entries (a programming error).
    #[track_caller]
    fn add_field_axes(&self, forces: &[VertexForce], pressure: f64, u: &mut [f64]) {
        add_field_by_columns(self, forces, pressure, u)
    }
}

/// [`VertexResponse::add_field_axes`] through [`VertexResponse::add_column`]: one pass over
/// `u_c` per force and axis.
#[track_caller]
pub fn add_field_by_columns<R: VertexResponse + ?Sized>(
    r: &R,
    forces: &[VertexForce],
    pressure: f64,
    u: &mut [f64],
) {
    let n = r.n_vertices();
    assert_eq!(u.len(), r.axes() * n, "field length");
    for (c, uc) in u.chunks_exact_mut(n).enumerate() {
        for (ui, wi) in uc.iter_mut().zip(r.w(c)) {
            *ui -= wi * pressure;
        }
        for &(v, f) in forces {
            if f[c] != 0.0 {
                r.add_column(c, v, f[c], uc);
            }
        }
    }
}

/// Rows per pass of the blocked field sum: the axes' slices of `u` (3 x 4 KiB) stay in the
/// first-level cache while each column's slice streams through once for every axis.
const FIELD_CHUNK: usize = 512;

/// Pivots of the capacitance matrix at most this times `dim * epsilon` times their diagonal
/// entry mean a singular held set.
pub const CAPACITANCE_PIVOT_FACTOR: f64 = 16.0;

/// One held degree of freedom: the displacement of `vertex` along `direction` (a unit
/// vector; an axis for a full hold, a contact normal for a hold that leaves the vertex free
/// across it).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeldRow {
    /// The vertex.
    pub vertex: usize,
    /// The direction of the held displacement (unit length).
    pub direction: [f64; 3],
}

impl HeldRow {
    /// The rows of `vertex` held along each of the first `axes` axes.
    pub fn all_axes(vertex: usize, axes: usize) -> impl Iterator<Item = HeldRow> {
        (0..axes).map(move |a| {
            let mut direction = [0.0; 3];
            direction[a] = 1.0;
            HeldRow { vertex, direction }
        })
    }

    /// The axis of the largest component of the direction (for error messages).
    fn main_axis(&self) -> usize {
        let d = self.direction.map(f64::abs);
        if d[0] >= d[1] && d[0] >= d[2] {
            0
        } else if d[1] >= d[2] {
            1
        } else {
            2
        }
    }
}

/// A [`VertexResponse`] read as the [`CapacitanceSource`] of held rows ([`HeldRow`]) on the
/// bordered system (see the module docs): `C = E' W` is `G`, formed from `O(m^2)` compliance
/// entries, and `x -= W r` is the point-force field of the reactions `-r` along their
/// directions ([`VertexResponse::add_field_axes`], one N-length column per force and axis),
/// never a dense `dN + 1` column per row.
///
/// The vectors it corrects are the displacements stored axis by axis (`axes * N` entries,
/// [`field`](Self::field)) or the bordered system's unknowns (`axes * N + 1`, the last the
/// pressure unknown `P / lambda`, [`bordered`](Self::bordered)).
#[derive(Clone, Copy, Debug)]
pub struct VertexSource<'a, R: ?Sized> {
    response: &'a R,
    /// `lambda` when the corrected vectors end with the pressure unknown.
    pressure_scale: Option<f64>,
}

impl<'a, R: VertexResponse + ?Sized> VertexSource<'a, R> {
    /// Corrects displacement fields of `axes * N` entries (the pressure change is not
    /// stored).
    pub fn field(response: &'a R) -> Self {
        Self { response, pressure_scale: None }
    }

    /// Corrects the bordered system's unknowns: `axes * N` displacements and the pressure
    /// unknown `P / pressure_scale`.
    pub fn bordered(response: &'a R, pressure_scale: f64) -> Self {
        Self { response, pressure_scale: Some(pressure_scale) }
    }

    /// The response read.
    pub fn response(&self) -> &'a R {
        self.response
    }
}

impl<R: VertexResponse + ?Sized> CapacitanceSource<HeldRow> for VertexSource<'_, R> {
    /// `G[i,j] = sum_a n_a m_a C_a[v,u] - (n . w[v]) (m . w[u]) / s` (the lower triangle
    /// computed, mirrored). Every row's vertex must have its columns available.
    fn capacitance(&self, rows: &[HeldRow]) -> Mat<f64> {
        let r = self.response;
        let (d, dim) = (r.axes(), rows.len());
        let s = r.schur();
        let nw = |row: &HeldRow| (0..d).map(|a| row.direction[a] * r.w(a)[row.vertex]).sum::<f64>();
        let rw: Vec<f64> = rows.iter().map(nw).collect();
        let mut g = Mat::<f64>::zeros(dim, dim);
        for (j, rj) in rows.iter().enumerate() {
            for (i, ri) in rows.iter().enumerate().skip(j) {
                let mut e = -rw[i] * rw[j] / s;
                for a in 0..d {
                    let nn = ri.direction[a] * rj.direction[a];
                    if nn != 0.0 {
                        e += nn * r.entry(a, ri.vertex, rj.vertex);
                    }
                }
                g[(i, j)] = e;
                g[(j, i)] = e;
            }
        }
        g
    }

    /// `n . u_v` for each row, `u` read axis by axis from `x`.
    fn row_values(&self, rows: &[HeldRow], x: &[f64]) -> Vec<f64> {
        let n = self.response.n_vertices();
        let d = self.response.axes();
        rows.iter()
            .map(|row| {
                (0..d)
                    .filter(|&a| row.direction[a] != 0.0)
                    .map(|a| row.direction[a] * x[a * n + row.vertex])
                    .sum()
            })
            .collect()
    }

    /// Adds the field of the reactions `-r` (and, for [`bordered`](Self::bordered) vectors,
    /// their pressure unknown).
    ///
    /// # Panics
    /// If `x` does not have the length its layout says, or `r` one entry per row.
    #[track_caller]
    fn correct(&self, rows: &[HeldRow], r: &[f64], x: &mut [f64]) {
        assert_eq!(r.len(), rows.len(), "one multiplier per held row");
        let resp = self.response;
        let dn = resp.axes() * resp.n_vertices();
        let expected = dn + usize::from(self.pressure_scale.is_some());
        assert_eq!(x.len(), expected, "vector length of the source's layout");
        let forces = row_forces(rows, r.iter().map(|ri| -ri));
        let p = resp.pressure_of(&forces);
        resp.add_field_axes(&forces, p, &mut x[..dn]);
        if let Some(lambda) = self.pressure_scale {
            x[dn] += p / lambda;
        }
    }
}

/// The forces of row multipliers: per vertex (consecutive rows of one vertex summed, in
/// the rows' order), the multipliers times their directions.
fn row_forces(rows: &[HeldRow], multipliers: impl Iterator<Item = f64>) -> Vec<VertexForce> {
    let mut out: Vec<VertexForce> = Vec::new();
    for (row, l) in rows.iter().zip(multipliers) {
        if out.last().is_none_or(|last| last.0 != row.vertex) {
            out.push((row.vertex, [0.0; 3]));
        }
        let f = &mut out.last_mut().expect("pushed above").1;
        for a in 0..3 {
            f[a] += l * row.direction[a];
        }
    }
    out
}

/// The factored capacitance `G` of one held set (see the module docs): the shared
/// [`RowCapacitance`] over a [`VertexSource`], built from `O(m^2)` compliance entries for
/// `m` held rows and factored by Cholesky (`m^3 / 3` flops) when the held set changes,
/// reused while the holds only move. A row is a vertex's displacement along a direction
/// ([`HeldRow`]): a full hold is one row per axis, a frictionless contact one row along its
/// normal. For rows `i`, `j` at vertices `v`, `u` with directions `n`, `m`:
/// `G[i,j] = sum_a n_a m_a C_a[v,u] - (n . w[v]) (m . w[u]) / s`.
#[derive(Clone, Debug)]
pub struct HeldCapacitance {
    rows: Vec<HeldRow>,
    vertices: Vec<usize>,
    /// `G` and its Cholesky factor.
    capacitance: RowCapacitance,
}

impl HeldCapacitance {
    /// Builds and factors `G` for `vertices` held along every axis, whose columns must be
    /// available in `r`. A pivot at most [`CAPACITANCE_PIVOT_FACTOR`] `* dim * epsilon`
    /// times its diagonal entry is [`LinalgError::SingularHold`] (the held set
    /// over-determines the body).
    pub fn new<R: VertexResponse + ?Sized>(r: &R, vertices: &[usize]) -> Result<Self> {
        let rows: Vec<HeldRow> = vertices.iter().flat_map(|&v| HeldRow::all_axes(v, r.axes())).collect();
        Self::from_rows(r, &rows)
    }

    /// Builds and factors `G` for arbitrary held rows (directions with components only on
    /// the body's axes); errors as [`new`](Self::new).
    pub fn from_rows<R: VertexResponse + ?Sized>(r: &R, rows: &[HeldRow]) -> Result<Self> {
        let mut vertices: Vec<usize> = rows.iter().map(|row| row.vertex).collect();
        vertices.dedup();
        let tol = CAPACITANCE_PIVOT_FACTOR * rows.len() as f64 * r.epsilon();
        let capacitance = RowCapacitance::from_source(&VertexSource::field(r), rows, 0.0, Some(tol))
            .map_err(|e| match e {
                LinalgError::CapacitanceNotPositiveDefinite { constraint: i, .. } => {
                    LinalgError::SingularHold {
                        held: vertices.len(),
                        vertex: rows[i].vertex,
                        axis: rows[i].main_axis(),
                    }
                }
                other => other,
            })?;
        Ok(Self { rows: rows.to_vec(), vertices, capacitance })
    }

    /// The held vertices, in the order of the reactions (a vertex with several consecutive
    /// rows once).
    pub fn vertices(&self) -> &[usize] {
        &self.vertices
    }

    /// The held rows, in the order of the gaps.
    pub fn rows(&self) -> &[HeldRow] {
        &self.rows
    }

    /// The shared capacitance: `G` and its factor.
    pub fn capacitance(&self) -> &RowCapacitance {
        &self.capacitance
    }

    /// Bytes of the factor.
    pub fn memory_bytes(&self) -> usize {
        self.capacitance.factor().memory_bytes()
    }

    /// The reaction multipliers that close `gap` (one value per row, in the order of
    /// [`rows`](Self::rows): the target of the row minus the displacement along it without
    /// the reactions): solves `G lambda = gap`. A non-finite value is
    /// [`LinalgError::NonFiniteSolution`] with its row.
    ///
    /// # Panics
    /// If `gap` does not have one entry per row.
    #[track_caller]
    pub fn multipliers(&self, gap: &[f64]) -> Result<Vec<f64>> {
        let m = self.rows.len();
        assert_eq!(gap.len(), m, "one gap per held row");
        finite_multipliers(self.capacitance.multipliers(gap))
    }

    /// The reactions that close `gap` (see [`multipliers`](Self::multipliers)) as forces,
    /// one per held vertex in the order of [`vertices`](Self::vertices): the sum of its rows'
    /// multipliers times their directions.
    ///
    /// # Panics
    /// If `gap` does not have one entry per row.
    #[track_caller]
    pub fn reactions(&self, gap: &[f64]) -> Result<Vec<VertexForce>> {
        let lambda = self.multipliers(gap)?;
        Ok(row_forces(&self.rows, lambda.into_iter()))
    }

    /// Imposes the held rows at `targets` (one per row) on `x` in place, by the shared
    /// [`RowCapacitance::correct_with`] over `source` (the response this was built from, in
    /// the layout of `x`): `x` enters as the solution without holds and leaves with the
    /// reactions' field added. Returns the reactions as [`reactions`](Self::reactions) does;
    /// a non-finite multiplier is [`LinalgError::NonFiniteSolution`] with its row.
    ///
    /// # Panics
    /// If `targets` does not have one entry per row or `x` the source's length.
    #[track_caller]
    pub fn impose<R: VertexResponse + ?Sized>(
        &self,
        source: &VertexSource<'_, R>,
        targets: &[f64],
        x: &mut [f64],
    ) -> Result<Vec<VertexForce>> {
        let r = finite_multipliers(self.capacitance.correct_with(source, &self.rows, targets, x))?;
        Ok(row_forces(&self.rows, r.into_iter().map(|ri| -ri)))
    }
}

/// `v`, or [`LinalgError::NonFiniteSolution`] at its first non-finite entry.
fn finite_multipliers(v: Vec<f64>) -> Result<Vec<f64>> {
    match v.iter().position(|x| !x.is_finite()) {
        Some(index) => Err(LinalgError::NonFiniteSolution { index }),
        None => Ok(v),
    }
}

/// The compliance columns of touched vertices, computed with a kept factorization of the
/// bordered system and cached (see the module docs); `w` and `s` from one bordered solve.
///
/// For a vertex v and a distinct block b, the bordered solve with the unit right-hand side
/// at unknown `(b, v)` gives `u_c = C_b[:, v] delta_cb - w_c P` with `P = w_b[v] / s`, so
/// `C_b[:, v] = u_b + w_b P`; the bordered solve with the unit volume target gives
/// `u = w / (lambda s)` and the pressure unknown `-1 / (lambda^2 s)` (`lambda` the pressure
/// scale). Each solve is checked and refined as [`FactorizationExt::solve_many`] does.
///
/// Clones share the columns computed so far (each column is an `Arc`).
#[derive(Clone, Debug)]
pub struct VertexColumns {
    n: usize,
    axes: usize,
    nblocks: usize,
    w: Vec<Vec<f64>>,
    schur: f64,
    /// Per vertex: `nblocks * N` values (`C_b[:, v]` block after block), once touched.
    columns: Vec<Option<Arc<[f64]>>>,
    cached: usize,
}

impl VertexColumns {
    /// The border terms `w` and `s` of factorization `f` (one bordered solve); no column
    /// yet. [`LinalgError::SingularHold`] is not possible here; a Schur complement that is
    /// not positive is [`LinalgError::DependentConstraints`] with `held = 0`.
    pub fn new(f: &dyn Factorization) -> Result<Self> {
        let a = f.matrix();
        let (n, axes) = (a.n_vertices(), a.axes());
        let dim = a.dim();
        let mut e = vec![0.0; dim];
        e[dim - 1] = 1.0;
        let x = f.solve(&e)?.x;
        let lambda = a.pressure_scale();
        let q = x[dim - 1];
        let schur = -1.0 / (lambda * lambda * q);
        if !(schur > 0.0) || !schur.is_finite() {
            return Err(LinalgError::DependentConstraints { held: 0 });
        }
        let w =
            (0..axes).map(|c| x[c * n..(c + 1) * n].iter().map(|u| u * lambda * schur).collect()).collect();
        let nblocks = if a.is_shared() { 1 } else { axes };
        Ok(Self { n, axes, nblocks, w, schur, columns: vec![None; n], cached: 0 })
    }

    /// Computes the columns of the vertices of `vertices` not cached yet with `f` (the
    /// factorization this was made from): one [`solve_many`](FactorizationExt::solve_many)
    /// of `blocks * new` right-hand sides. Returns how many vertices were new.
    ///
    /// # Panics
    /// If a vertex is out of range (a programming error).
    #[track_caller]
    pub fn touch(&mut self, f: &dyn Factorization, vertices: &[usize]) -> Result<usize> {
        let mut new: Vec<usize> = vertices.iter().copied().filter(|&v| self.columns[v].is_none()).collect();
        new.sort_unstable();
        new.dedup();
        if new.is_empty() {
            return Ok(0);
        }
        let (n, nb) = (self.n, self.nblocks);
        let dim = f.matrix().dim();
        let lambda = f.matrix().pressure_scale();
        let mut e = vec![0.0; dim * nb * new.len()];
        for (j, &v) in new.iter().enumerate() {
            for b in 0..nb {
                e[(j * nb + b) * dim + b * n + v] = 1.0;
            }
        }
        let solutions = f.solve_many(&e, nb * new.len())?;
        for (j, &v) in new.iter().enumerate() {
            let mut col = vec![0.0; nb * n];
            for b in 0..nb {
                let x = &solutions[j * nb + b].x;
                let p = x[dim - 1] * lambda;
                for ((ci, ui), wi) in
                    col[b * n..(b + 1) * n].iter_mut().zip(&x[b * n..(b + 1) * n]).zip(&self.w[b])
                {
                    *ci = ui + wi * p;
                }
            }
            self.columns[v] = Some(col.into());
        }
        self.cached += new.len();
        Ok(new.len())
    }

    /// Whether the columns of `vertex` are cached.
    pub fn is_cached(&self, vertex: usize) -> bool {
        self.columns.get(vertex).is_some_and(|c| c.is_some())
    }

    /// Number of vertices whose columns are cached.
    pub fn cached(&self) -> usize {
        self.cached
    }

    /// Number of distinct blocks (1 when every axis shares one).
    pub fn n_blocks(&self) -> usize {
        self.nblocks
    }

    /// Bytes held: the cached columns and the border terms.
    pub fn memory_bytes(&self) -> usize {
        (self.cached * self.nblocks * self.n + self.axes * self.n) * 8
            + self.n * std::mem::size_of::<Option<Arc<[f64]>>>()
    }

    #[inline]
    #[track_caller]
    fn column(&self, axis: usize, j: usize) -> &[f64] {
        let b = if self.nblocks == 1 { 0 } else { axis };
        let col = self.columns[j].as_deref().expect("the vertex's columns are touched before use");
        &col[b * self.n..(b + 1) * self.n]
    }
}

impl VertexResponse for VertexColumns {
    fn n_vertices(&self) -> usize {
        self.n
    }

    fn axes(&self) -> usize {
        self.axes
    }

    fn w(&self, axis: usize) -> &[f64] {
        &self.w[axis]
    }

    fn schur(&self) -> f64 {
        self.schur
    }

    #[inline]
    fn entry(&self, axis: usize, i: usize, j: usize) -> f64 {
        self.column(axis, j)[i]
    }

    #[inline]
    fn add_column(&self, axis: usize, j: usize, a: f64, y: &mut [f64]) {
        for (yi, ci) in y.iter_mut().zip(self.column(axis, j)) {
            *yi += ci * a;
        }
    }

    fn epsilon(&self) -> f64 {
        f64::EPSILON
    }

    /// With one block shared by every axis, each column is read once for all axes (rows in
    /// chunks of [`FIELD_CHUNK`]); otherwise as [`add_field_by_columns`].
    #[track_caller]
    fn add_field_axes(&self, forces: &[VertexForce], pressure: f64, u: &mut [f64]) {
        let (n, d) = (self.n, self.axes);
        if self.nblocks != 1 {
            return add_field_by_columns(self, forces, pressure, u);
        }
        assert_eq!(u.len(), d * n, "field length");
        let cols: Vec<(&[f64], [f64; 3])> = forces.iter().map(|&(v, f)| (self.column(0, v), f)).collect();
        let mut axes: Vec<&mut [f64]> = u.chunks_exact_mut(n).collect();
        let mut i0 = 0;
        while i0 < n {
            let i1 = (i0 + FIELD_CHUNK).min(n);
            for (c, uc) in axes.iter_mut().enumerate() {
                let uc = &mut uc[i0..i1];
                for (ui, wi) in uc.iter_mut().zip(&self.w[c][i0..i1]) {
                    *ui -= wi * pressure;
                }
                for &(col, f) in &cols {
                    if f[c] != 0.0 {
                        for (ui, ci) in uc.iter_mut().zip(&col[i0..i1]) {
                            *ui += ci * f[c];
                        }
                    }
                }
            }
            i0 = i1;
        }
    }
}
