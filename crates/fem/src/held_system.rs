//! Held surface vertices by a capacitance (Schur complement) update of a kept factor: the
//! linear body's stiffness (`crate::held`) or a hyperelastic tangent
//! ([`crate::hyper::Linearization`]).
//!
//! Holding vertex `v` at displacement `d_v` adds the constraint rows `C_v u = d_v` (row
//! `(v, a)`: the trilinear weights of `v` on axis `a` of its cell's free nodes) and the
//! unknown reactions `lambda`: `K u = f + C^T lambda`. With `u0 = K^-1 f` and the
//! compliance columns `Z = K^-1 C^T`, `(C Z) lambda = d - C u0` and `u = u0 + Z lambda`.
//! `Z` is solved over the smaller basis of the rows (`crate::held_basis`: each held
//! vertex's axes, or the free dofs the rows touch) and cached; each frame then costs one
//! solve for `u0`, the dense `m x m` capacitance `C Z` and its Cholesky (`m^3 / 3`),
//! against a refactorization of K (its factor flops, see [`crate::FemStats`]) for
//! eliminating the held dofs. The capacitance is formed, factored and applied by
//! `fibfluid_linalg::RowCapacitance` (the columns by the factor's
//! `fibfluid_linalg::ComplianceSource`), the same code as the fiber–fluid method's contact
//! rows. A patch held at the targets of one affine motion (a grasp) answers its
//! surface-only frames from a dozen columns (`crate::held_affine`).

use std::collections::{HashMap, HashSet};
use std::sync::Arc;

use faer::Mat;
use fibfluid_geometry::Vec3;
use fibfluid_linalg::{
    CapacitanceSource, ComplianceSource, LinalgError, RowCapacitance, SparseCholesky, SparseRow, row_dot,
};

use crate::held_affine::{AffineFrames, FrameParts};
use crate::held_basis::{BasisKey, Combination, Combined, basis_row};
use crate::held_rows::{FemHold, Row, RowKey, SurfaceSolve, check_met, constraint_rows, refined_multipliers};

use crate::assemble::FIXED;
use crate::error::{FemError, Result};
use crate::grid::Embedded;

/// The response with some surface vertices held.
#[derive(Debug, Clone, PartialEq)]
pub struct HeldResponse {
    /// Displacement of every grid node.
    pub node_displacements: Vec<Vec3>,
    /// Displacement of every surface vertex.
    pub surface_displacements: Vec<Vec3>,
    /// The force each held vertex receives from its holder, in the order given (applied as
    /// a point force in [`FemBody::solve`], it reproduces the same displacement). An axis
    /// carried only by fixed nodes reports 0 (its reaction goes to the supports).
    pub reactions: Vec<Vec3>,
    /// The solve's measured relative residual `|K u - f - C^T lambda| / |f + C^T lambda|`.
    pub residual: f64,
}

/// Relative ridges tried in turn on a capacitance matrix that is singular because more
/// vertices of one cell are held than its nodes can satisfy independently (consistent
/// targets, such as a patch moved rigidly, are still met: the multipliers are refined
/// against the unridged matrix, `RIDGE_REFINEMENTS`, and the constraint residual is
/// checked after).
const DEPENDENT_RIDGES: [f64; 3] = [1e-12, 1e-9, 1e-6];

/// Constraint rows whose `stiffness * C^T C` was added to the factored matrix (a tangent
/// made positive definite on the held directions, an augmented Lagrangian): a hold on such
/// a row enters the right-hand side as `stiffness * C^T g` (g its target less the base
/// state's value); a penalized row not held leaves a spring there (the answer is then
/// approximate, [`HeldSolve::uncovered`]).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Penalty {
    /// The penalized rows.
    pub(crate) keys: Vec<RowKey>,
    /// Their stiffness (N/m).
    pub(crate) stiffness: f64,
}

/// Compliance columns and the last unheld solve of one factor, kept between frames.
#[derive(Debug, Clone, Default)]
pub(crate) struct HoldCache {
    /// `A^-1 B^T` columns of the basis rows held vertices were answered from
    /// (`crate::held_basis`), computed on first hold; shared by the clones of a cache
    /// (copied only when a clone adds columns).
    columns: Arc<HashMap<BasisKey, Vec<f64>>>,
    /// The vertices whose holds the columns answer.
    vertices: HashSet<usize>,
    /// The last right-hand side solved without holds and its solution: a frame that
    /// changes only the holds reuses it.
    unheld: Option<(Vec<f64>, Vec<f64>)>,
    /// The last rows over their basis and their factored capacitance: a frame that moves
    /// the same holds reuses them.
    rows: Option<RowSet>,
    /// The surface's share of the unheld solution and of the last rows' columns: a
    /// surface-only frame ([`HeldSystem::solve_surface`]) with the same rows and
    /// right-hand side reuses it.
    surface: Option<SurfaceProjection>,
    /// The cached columns of one basis at the surface vertices (`S G`, 3 rows per vertex,
    /// a column per basis element in the basis's order): made once per basis, kept when
    /// only the right-hand side changes.
    surface_columns: Option<(Vec<BasisKey>, Arc<Mat<f64>>)>,
    /// Whether the last surface-only frame took the affine path (`crate::held_affine`).
    affine_frame: bool,
}

/// One set of rows as frames answer them: their identity, the rows over their basis
/// (`C = A B`), the basis rows `B`, and the factored capacitance `C Z` (and whether it
/// needed one of [`DEPENDENT_RIDGES`]).
#[derive(Debug, Clone)]
struct RowSet {
    keys: Vec<RowKey>,
    combination: Combination,
    basis_rows: Vec<Vec<(usize, f64)>>,
    capacitance: RowCapacitance,
    ridged: bool,
}

impl RowSet {
    /// The capacitance source of these rows on the cached columns.
    fn source<'c>(&'c self, columns: &'c HashMap<BasisKey, Vec<f64>>) -> Combined<'c> {
        Combined::new(&self.basis_rows, &self.combination.basis, columns)
    }
}

/// What a surface-only frame needs of one set of rows and one right-hand side: the held
/// system's solution restricted to the surface vertices and the rows.
#[derive(Debug, Clone)]
struct SurfaceProjection {
    /// The rows it was made for.
    keys: Vec<RowKey>,
    /// `S u0`: the unheld solution at the surface vertices (3 per vertex).
    unheld: Vec<f64>,
    /// `C u0`: the unheld solution along each row (`S G`, the rows' basis columns at the
    /// surface, is the cache's `surface_columns`).
    rows_unheld: Vec<f64>,
    /// The frames of a patch held at the targets of one affine map (a grasp), when the
    /// rows are such a patch (`crate::held_affine`).
    affine: Option<AffineFrames>,
}

impl HoldCache {
    /// Number of vertices whose columns are cached.
    pub(crate) fn vertices(&self) -> usize {
        self.vertices.len()
    }

    /// Whether the columns of `vertex`'s holds are cached.
    pub(crate) fn answers(&self, vertex: usize) -> bool {
        self.vertices.contains(&vertex)
    }

    /// Drops every cached column (and the capacitance and projection made of them).
    pub(crate) fn clear_columns(&mut self) {
        self.columns = Arc::default();
        self.vertices.clear();
        self.rows = None;
        self.surface = None;
        self.surface_columns = None;
    }

    /// The columns the last surface-only frame read: `3k` on the affine path, else one per
    /// basis element (0 before any).
    pub(crate) fn frame_columns(&self) -> usize {
        let Some(p) = &self.surface else { return 0 };
        match (&p.affine, self.affine_frame) {
            (Some(a), true) => a.parameters(),
            _ => self.surface_columns.as_ref().map_or(0, |c| c.1.ncols()),
        }
    }

    /// Bytes of the cached compliance columns and their surface projection.
    pub(crate) fn bytes(&self) -> usize {
        let columns: usize = self.columns.values().map(|c| 8 * c.len()).sum();
        let surface = self.surface_columns.as_ref().map_or(0, |p| 8 * p.1.nrows() * p.1.ncols());
        columns + surface
    }
}

/// A factored matrix over a grid's free dofs, with the surface's embedding: what a held
/// response needs.
pub(crate) struct HeldSystem<'a> {
    /// The factor of `A` (the stiffness, or a tangent).
    pub(crate) factor: &'a SparseCholesky,
    /// Where each surface vertex sits in the grid.
    pub(crate) embedding: &'a [Embedded],
    /// Free-dof number of each node axis ([`FIXED`] when eliminated).
    pub(crate) free: &'a [usize],
    /// Rest position of each surface vertex (m).
    pub(crate) rest: &'a [Vec3],
}

/// The solution of a held system.
pub(crate) struct HeldSolve {
    /// The free-dof solution.
    pub(crate) u: Vec<f64>,
    /// Per hold (in the order given), the force its holder puts on the body.
    pub(crate) reactions: Vec<Vec3>,
    /// The right-hand side with the reactions applied (`f + C^T lambda`).
    pub(crate) applied: Vec<f64>,
    /// Penalized rows that no hold covers (their springs stay in the answer).
    pub(crate) uncovered: usize,
}

impl HeldSystem<'_> {
    /// Solves `A u = f + C^T lambda` with every hold met: `C (base + u) = targets` (targets
    /// are displacements from the rest shape; `base`, when given, the state `u` adds to).
    pub(crate) fn solve(
        &self,
        cache: &mut HoldCache,
        f: Vec<f64>,
        holds: &[(usize, FemHold)],
        base: Option<&[f64]>,
        penalty: Option<&Penalty>,
    ) -> Result<HeldSolve> {
        let rows = self.rows(holds, base)?;
        self.keep_row_set(cache, &rows, holds)?;
        self.solve_unheld(cache, &f);
        let mut u = cache.unheld.as_ref().expect("solved above").1.clone();
        let set = cache.rows.as_ref().expect("kept above");
        let source = set.source(&cache.columns);
        let (pushes, uncovered) = penalty_pushes(penalty, &rows);
        // A held penalized row: A^-1 (stiffness C^T g) is its column times stiffness g.
        if pushes.iter().any(|&p| p != 0.0) {
            let negated: Vec<f64> = pushes.iter().map(|p| -p).collect();
            source.correct(&set.combination.rows, &negated, &mut u);
        }
        let lambda = impose_rows(set, &rows, &source, &mut u)?;
        let reactions = reactions_of(holds, &rows, &lambda);
        let mut applied = f;
        for (row, l) in rows.iter().zip(&lambda) {
            for &(d, w) in &row.entries {
                applied[d] += w * l;
            }
        }
        Ok(HeldSolve { u, reactions, applied, uncovered })
    }

    /// The constraint rows of `holds`, their targets taken from `base` when given (the
    /// state the solution adds to).
    fn rows(&self, holds: &[(usize, FemHold)], base: Option<&[f64]>) -> Result<Vec<Row>> {
        let mut rows = constraint_rows(self.embedding, self.free, holds)?;
        if let Some(base) = base {
            rows.iter_mut().for_each(|r| r.target -= row_dot(&r.entries, base));
        }
        Ok(rows)
    }

    /// Keeps `A^-1 f` in `cache.unheld`, solved again only when `f` changed (which drops
    /// the surface projection made of the last one).
    fn solve_unheld(&self, cache: &mut HoldCache, f: &[f64]) {
        if cache.unheld.as_ref().is_some_and(|(last, _)| last.as_slice() == f) {
            return;
        }
        let n = f.len();
        let mut u0 = Mat::<f64>::from_fn(n, 1, |i, _| f[i]);
        self.factor.solve_in_place(u0.as_mut());
        cache.unheld = Some((f.to_vec(), (0..n).map(|i| u0[(i, 0)]).collect()));
        cache.surface = None;
    }

    /// The surface-only answer of [`HeldSystem::solve`]: the same holds met, the same
    /// reactions, but only the surface vertices' displacements, from the rows' columns
    /// projected onto the surface once per set of rows and right-hand side. A frame that
    /// keeps both costs `3 x surface vertices x min(rows, dofs)` flops and the
    /// `rows x rows` capacitance solve, whatever the number of unknowns; a grasp's
    /// `3 x surface vertices x 3k` (`k <= 4`, `crate::held_affine`).
    pub(crate) fn solve_surface(
        &self,
        cache: &mut HoldCache,
        f: &[f64],
        holds: &[(usize, FemHold)],
        base: Option<&[f64]>,
        penalty: Option<&Penalty>,
    ) -> Result<SurfaceSolve> {
        self.solve_unheld(cache, f);
        let affine = cache.surface.as_ref().and_then(|p| p.affine.as_ref());
        if let Some(answer) = affine.and_then(|a| a.frame(holds)) {
            cache.affine_frame = true;
            return answer;
        }
        cache.affine_frame = false;
        let rows = self.rows(holds, base)?;
        let keys: Vec<RowKey> = rows.iter().map(Row::key).collect();
        if cache.surface.as_ref().is_none_or(|p| p.keys != keys)
            || cache.rows.as_ref().is_none_or(|set| set.keys != keys)
        {
            self.keep_row_set(cache, &rows, holds)?;
            let columns = self.keep_surface_columns(cache);
            let set = cache.rows.as_ref().expect("kept above");
            let u0 = &cache.unheld.as_ref().expect("solved above").1;
            let unheld = self.at_surface(u0);
            let rows_unheld: Vec<f64> = rows.iter().map(|r| row_dot(&r.entries, u0)).collect();
            let (weights, uncovered) = penalty_weights(penalty, &rows);
            let affine = AffineFrames::new(&FrameParts {
                holds,
                rows: &rows,
                rest: self.rest,
                capacitance: &set.capacitance,
                ridged: set.ridged,
                penalty: &weights,
                uncovered,
                rows_unheld: &rows_unheld,
                surface_unheld: &unheld,
                combination: &set.combination,
                columns: columns.as_ref().as_ref(),
            });
            let projection = SurfaceProjection { unheld, rows_unheld, affine, keys };
            let answer = projection.affine.as_ref().and_then(|a| a.frame(holds));
            cache.surface = Some(projection);
            if let Some(answer) = answer {
                cache.affine_frame = true;
                return answer;
            }
        }
        let projection = cache.surface.as_ref().expect("made above");
        let set = cache.rows.as_ref().expect("made above");
        let columns = &cache.surface_columns.as_ref().expect("made with the projection").1;
        let (capacitance, ridged) = (&set.capacitance, set.ridged);
        let (pushes, uncovered) = penalty_pushes(penalty, &rows);
        // Along the rows, u = u0 + Z (pushes - r) is C u0 + (C Z)(pushes - r).
        let cz = capacitance.matrix();
        let along = |w: &[f64]| -> Vec<f64> {
            let mut out = Mat::<f64>::from_fn(w.len(), 1, |i, _| projection.rows_unheld[i]);
            let w = Mat::<f64>::from_fn(w.len(), 1, |j, _| w[j]);
            faer::linalg::matmul::matmul(out.as_mut(), faer::Accum::Add, cz, w.as_ref(), 1.0, faer::Par::Seq);
            out.col_as_slice(0).to_vec()
        };
        let gap: Vec<f64> = along(&pushes).iter().zip(&rows).map(|(c, row)| c - row.target).collect();
        let r = refined_multipliers(capacitance, ridged, &gap);
        let weights: Vec<f64> = pushes.iter().zip(&r).map(|(p, r)| p - r).collect();
        if ridged {
            check_met(&rows, &along(&weights))?;
        }
        // S u = S u0 + (S G)(A^T weights): one dense product (faer's vectorized kernel).
        let mut surface = Mat::<f64>::from_fn(projection.unheld.len(), 1, |i, _| projection.unheld[i]);
        let at_basis = set.combination.transpose_times(&weights);
        let w = Mat::<f64>::from_fn(at_basis.len(), 1, |j, _| at_basis[j]);
        faer::linalg::matmul::matmul(
            surface.as_mut(),
            faer::Accum::Add,
            columns.as_ref().as_ref(),
            w.as_ref(),
            1.0,
            faer::Par::Seq,
        );
        let lambda: Vec<f64> = r.iter().map(|x| -x).collect();
        let reactions = reactions_of(holds, &rows, &lambda);
        let displacement = (0..surface.nrows() / 3).map(|v| std::array::from_fn(|a| surface[(3 * v + a, 0)]));
        Ok(SurfaceSolve { surface: displacement.collect(), reactions, uncovered })
    }

    /// The kept rows' basis columns at the surface vertices, projected again only when the
    /// basis changed.
    fn keep_surface_columns(&self, cache: &mut HoldCache) -> Arc<Mat<f64>> {
        let set = cache.rows.as_ref().expect("rows kept before their surface columns");
        let basis = &set.combination.basis;
        match &cache.surface_columns {
            Some((kept, columns)) if kept == basis => Arc::clone(columns),
            _ => {
                let columns = Arc::new(self.columns_at_surface(&set.source(&cache.columns).columns));
                cache.surface_columns = Some((basis.clone(), Arc::clone(&columns)));
                columns
            }
        }
    }

    /// The surface vertices' values of each column (3 per vertex, a matrix column each).
    fn columns_at_surface(&self, columns: &[&[f64]]) -> Mat<f64> {
        let mut projected = Mat::<f64>::zeros(3 * self.embedding.len(), columns.len());
        for (j, column) in columns.iter().enumerate() {
            let at = interpolate_surface(self.embedding, self.free, column);
            projected.col_as_slice_mut(j).copy_from_slice(at.as_flattened());
        }
        projected
    }

    /// The surface vertices' values of the free-dof vector `x` (3 per vertex; fixed dofs
    /// are 0).
    fn at_surface(&self, x: &[f64]) -> Vec<f64> {
        interpolate_surface(self.embedding, self.free, x).into_flattened()
    }

    /// Computes `A^-1 B_k^T` for every basis row not cached yet, in one solve pass, and
    /// records `holds`' vertices as answered.
    fn cache_compliance(
        &self,
        cache: &mut HoldCache,
        basis: &[BasisKey],
        holds: &[(usize, FemHold)],
    ) -> Result<()> {
        cache.vertices.extend(holds.iter().map(|h| h.0));
        let new: Vec<BasisKey> = basis.iter().copied().filter(|k| !cache.columns.contains_key(k)).collect();
        if new.is_empty() {
            return Ok(());
        }
        let rows: Vec<Vec<(usize, f64)>> =
            new.iter().map(|&k| basis_row(k, self.embedding, self.free)).collect();
        let refs: Vec<&SparseRow> = rows.iter().map(Vec::as_slice).collect();
        let columns = self.factor.compliance_columns(&refs)?;
        Arc::make_mut(&mut cache.columns).extend(new.into_iter().zip(columns));
        Ok(())
    }

    /// Keeps `rows`' set in `cache.rows`: made again (their basis, its missing columns
    /// and the factored capacitance) only when the rows differ from the kept ones. A
    /// singular `C Z` (dependent rows) is factored with the first of [`DEPENDENT_RIDGES`]
    /// that makes it positive definite.
    fn keep_row_set(&self, cache: &mut HoldCache, rows: &[Row], holds: &[(usize, FemHold)]) -> Result<()> {
        let keys: Vec<RowKey> = rows.iter().map(Row::key).collect();
        if cache.rows.as_ref().is_some_and(|set| set.keys == keys) {
            return Ok(());
        }
        cache.rows = None;
        let combination = Combination::of(rows);
        self.cache_compliance(cache, &combination.basis, holds)?;
        let basis_rows: Vec<Vec<(usize, f64)>> =
            combination.basis.iter().map(|&k| basis_row(k, self.embedding, self.free)).collect();
        let source = Combined::new(&basis_rows, &combination.basis, &cache.columns);
        let combined = &combination.rows;
        let (capacitance, ridged) = match RowCapacitance::from_source(&source, combined, 0.0, None) {
            Ok(c) => (c, false),
            Err(LinalgError::CapacitanceNotPositiveDefinite { .. }) => {
                let dependent = FemError::DependentHolds { vertex: rows[0].vertex };
                let mut ridged = DEPENDENT_RIDGES
                    .iter()
                    .filter_map(|&ridge| RowCapacitance::from_source(&source, combined, ridge, None).ok());
                (ridged.next().ok_or(dependent)?, true)
            }
            Err(other) => return Err(other.into()),
        };
        cache.rows = Some(RowSet { keys, combination, basis_rows, capacitance, ridged });
        Ok(())
    }
}

/// Per hold (in the order given), the force its holder puts on the body: its rows'
/// multipliers along their directions.
fn reactions_of(holds: &[(usize, FemHold)], rows: &[Row], lambda: &[f64]) -> Vec<Vec3> {
    let mut reactions = vec![[0.0; 3]; holds.len()];
    for (row, l) in rows.iter().zip(lambda) {
        let k = holds.iter().position(|h| h.0 == row.vertex).unwrap_or(0);
        for a in 0..3 {
            reactions[k][a] += l * row.direction[a];
        }
    }
    reactions
}

/// Per row, the multiple of its column a penalized held row adds to the solution
/// (`stiffness x target`: `A^-1 (stiffness C^T g)`; 0 for a row not penalized), and the
/// penalized rows no hold covers.
fn penalty_pushes(penalty: Option<&Penalty>, rows: &[Row]) -> (Vec<f64>, usize) {
    let (weights, uncovered) = penalty_weights(penalty, rows);
    (rows.iter().zip(&weights).map(|(r, w)| w * r.target).collect(), uncovered)
}

/// Per row, the stiffness of its penalty (0 for a row not penalized), and the penalized
/// rows no hold covers.
fn penalty_weights(penalty: Option<&Penalty>, rows: &[Row]) -> (Vec<f64>, usize) {
    let Some(p) = penalty else { return (vec![0.0; rows.len()], 0) };
    let keys: Vec<RowKey> = rows.iter().map(Row::key).collect();
    if p.keys == keys {
        // The holds the linearization was made for (the usual frame): every row penalized.
        return (vec![p.stiffness; rows.len()], 0);
    }
    let penalized: HashSet<&RowKey> = p.keys.iter().collect();
    let held: HashSet<&RowKey> = keys.iter().collect();
    let weights = keys.iter().map(|k| if penalized.contains(k) { p.stiffness } else { 0.0 });
    (weights.collect(), p.keys.iter().filter(|k| !held.contains(k)).count())
}

/// Displacement of every embedded surface vertex of the free-dof vector `x` (fixed dofs
/// are 0).
pub(crate) fn interpolate_surface(embedding: &[Embedded], free: &[usize], x: &[f64]) -> Vec<Vec3> {
    let node = |n: usize, a: usize| match free[3 * n + a] {
        FIXED => 0.0,
        i => x[i],
    };
    embedding
        .iter()
        .map(|e| std::array::from_fn(|a| (0..8).map(|b| e.weights[b] * node(e.nodes[b], a)).sum()))
        .collect()
}

/// Imposes the rows of `set` on `u` (`A^-1 f` on entry) by the capacitance update of
/// `fibfluid_linalg` and returns the multipliers `lambda` (`u = u0 + Z lambda`, the
/// reactions `C^T lambda`). A ridged capacitance (dependent rows) is accepted only if the
/// constraints are then met.
fn impose_rows(set: &RowSet, rows: &[Row], source: &Combined<'_>, u: &mut [f64]) -> Result<Vec<f64>> {
    if rows.is_empty() {
        return Ok(Vec::new());
    }
    let combined = &set.combination.rows;
    // The update's multipliers r are the negated reactions: u = u0 - Z r.
    let along = source.row_values(combined, u);
    let gap: Vec<f64> = along.iter().zip(rows).map(|(a, row)| a - row.target).collect();
    let r = refined_multipliers(&set.capacitance, set.ridged, &gap);
    source.correct(combined, &r, u);
    if set.ridged {
        let met: Vec<f64> = rows.iter().map(|row| row_dot(&row.entries, u)).collect();
        check_met(rows, &met)?;
    }
    Ok(r.into_iter().map(|x| -x).collect())
}
