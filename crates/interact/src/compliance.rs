//! The precomputed response of a factored fiber–fluid body: the compliance `C_c = K_c^-1`
//! of each distinct stiffness block and the border terms.

use std::sync::Arc;
use std::time::Instant;

use faer::Mat;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{LltError, cholesky_in_place, cholesky_in_place_scratch};
use faer::linalg::triangular_solve::{solve_lower_triangular_in_place, solve_upper_triangular_in_place};
use fibfluid_assembly::{AXES, ConstraintMethod, System};
use fibfluid_geometry::Vec3;
use fibfluid_linalg::{Factorization, LinalgError, VertexColumns, VertexResponse, memory_budget};

use crate::{InteractError, Result};

/// How the compliance blocks are stored.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Storage {
    /// 8 bytes per entry; a probe frame equals a full f64 solve to rounding.
    #[default]
    F64,
    /// 4 bytes per entry (half the memory and memory traffic). The blocks are computed in
    /// f64 and rounded once, so each entry carries a relative error of at most 2^-24; the
    /// border terms stay f64.
    F32,
}

impl fibfluid_linalg::Choice for Storage {
    const WHAT: &'static str = "storage precision";
    const ALL: &'static [Self] = &[Storage::F64, Storage::F32];
    fn name(self) -> &'static str {
        match self {
            Storage::F64 => "f64",
            Storage::F32 => "f32",
        }
    }
}
fibfluid_linalg::impl_choice!(Storage);

impl Storage {
    /// Bytes per stored entry.
    pub fn word_bytes(self) -> usize {
        match self {
            Storage::F64 => 8,
            Storage::F32 => 4,
        }
    }

    /// Unit roundoff of the stored entries.
    pub fn epsilon(self) -> f64 {
        match self {
            Storage::F64 => f64::EPSILON,
            Storage::F32 => f32::EPSILON as f64,
        }
    }
}

/// How much of the response is computed before the first frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Precompute {
    /// Every column at once: the inverse of each distinct stiffness block (`N^3` flops and
    /// `N^2` words per block, about 2 minutes at N = 10,242), with a factorization of its
    /// own. Any vertex can then be touched at no extra cost (haptic devices that need every
    /// vertex at once).
    Full,
    /// The columns of a vertex when it is first grabbed or pushed: one bordered solve per
    /// distinct block with the base solve's own factorization (kept, not redone), then
    /// cached. The first frame comes right after the base solve; a frame touching a new
    /// vertex pays two triangular solves (`2 N^2` flops per block), later frames are as
    /// fast as with the full precompute.
    #[default]
    Lazy,
}

impl fibfluid_linalg::Choice for Precompute {
    const WHAT: &'static str = "precompute";
    const ALL: &'static [Self] = &[Precompute::Full, Precompute::Lazy];
    fn name(self) -> &'static str {
        match self {
            Precompute::Full => "full",
            Precompute::Lazy => "lazy",
        }
    }
}
fibfluid_linalg::impl_choice!(Precompute);

/// Options of [`Compliance::from_system`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ComplianceOptions {
    /// How the blocks are stored.
    pub storage: Storage,
    /// Refuse when the precompute's peak needs more bytes than this. `None`: the one
    /// memory policy, [`fibfluid_linalg::memory_budget`].
    pub max_memory_bytes: Option<u64>,
}

/// Memory of a precompute, before anything is allocated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryEstimate {
    /// Bytes kept once the precompute is done (the compliance blocks).
    pub stored: u64,
    /// Bytes held at the peak of the precompute (the blocks finished so far plus one f64
    /// working block), besides the caller's assembled system.
    pub peak: u64,
}

/// Columns inverted per pass of the blocked inverse.
const INVERSE_BLOCK: usize = 256;

/// The stored blocks, shared by clones (they are never modified after the precompute, so
/// several bodies, e.g. one per viewer client, can use one precompute), or the kept
/// factorization and the columns of the vertices touched so far.
#[derive(Clone)]
enum Blocks {
    F64(Arc<[Mat<f64>]>),
    F32(Arc<[Mat<f32>]>),
    Lazy { factorization: Arc<dyn Factorization>, columns: VertexColumns },
}

impl std::fmt::Debug for Blocks {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Blocks::F64(b) => f.debug_tuple("F64").field(&b.len()).finish(),
            Blocks::F32(b) => f.debug_tuple("F32").field(&b.len()).finish(),
            Blocks::Lazy { factorization, columns } => f
                .debug_struct("Lazy")
                .field("backend", &factorization.backend())
                .field("cached", &columns.cached())
                .finish(),
        }
    }
}

/// The physical border and the constraint flags of an assembled system.
type SceneTerms = (Vec<Vec<f64>>, Vec<[bool; 3]>, Vec<[bool; 3]>);

fn scene_terms(system: &System) -> SceneTerms {
    let a = &system.matrix;
    let (n, axes) = (a.n_vertices(), a.axes());
    let scale = a.pressure_scale();
    let border: Vec<Vec<f64>> = (0..axes).map(|c| a.border(c).iter().map(|b| b / scale).collect()).collect();
    let constraints = system.constraints();
    let eliminate = system.method() == ConstraintMethod::Eliminate;
    let mut constrained = vec![[false; 3]; n];
    let mut loaded = vec![[false; 3]; n];
    for i in 0..n {
        for c in 0..axes {
            constrained[i][c] = constraints.get(i, c).is_some();
            loaded[i][c] = !(eliminate && constrained[i][c]);
        }
    }
    (border, constrained, loaded)
}

/// A linear-algebra failure of the lazy response, in the probe's terms.
pub(crate) fn linalg_error(e: LinalgError) -> InteractError {
    match e {
        LinalgError::SingularHold { held, vertex, axis } => InteractError::Singular {
            what: format!(
                "the {held} grabbed vertices over-determine the body (capacitance pivot at vertex {vertex} along {}); release some",
                AXES[axis % 3]
            ),
        },
        LinalgError::DependentConstraints { .. } => InteractError::Singular {
            what: "the volume row's Schur complement S' K^-1 S is not positive".into(),
        },
        other => InteractError::Invalid(format!("a solve with the kept factorization failed: {other}")),
    }
}

/// The precomputed linear response of a body about its rest shape (paper mode).
///
/// For the bordered system of REFERENCE §3 (fixed degrees of freedom eliminated or
/// penalized) and a load `f` (`f_c` per axis, components on eliminated degrees of freedom
/// dropped as a full solve drops them):
///
/// ```text
/// C_c = K_c^-1                (one N x N block when the blocks are shared)
/// w_c = C_c S_c,  s = sum_c S_c . w_c     (S the physical border, zero where eliminated)
/// P   = (sum_c w_c . f_c) / s             (pressure change)
/// u_c = C_c f_c - w_c P                   (displacement)
/// ```
///
/// This is exactly the solution of the bordered system with right-hand side `[f; 0]`; the
/// pressure scaling of the assembled border cancels (it scales `w` and `s` alike), so the
/// physical border is used. A point force at vertex v costs `O(N)` for the whole field (one
/// column of `C` per axis) and `O(1)` at a single vertex.
///
/// Cloning is cheap (`O(N)`): clones share the `N x N` blocks, so one precompute serves
/// several bodies (a viewer gives each client its own [`FfmBody`](crate::FfmBody)).
#[derive(Clone, Debug)]
pub struct Compliance {
    n: usize,
    axes: usize,
    blocks: Blocks,
    border: Vec<Vec<f64>>,
    w: Vec<Vec<f64>>,
    schur: f64,
    /// Per vertex and axis: constrained by the scene.
    constrained: Vec<[bool; 3]>,
    /// Per vertex and axis: a force there reaches the right-hand side (false where the
    /// degree of freedom is eliminated).
    loaded: Vec<[bool; 3]>,
    storage: Storage,
    seconds: f64,
}

impl Compliance {
    /// The memory a precompute of `system` with `storage` needs.
    pub fn estimate(system: &System, storage: Storage) -> MemoryEstimate {
        let nblocks = if system.matrix.is_shared() { 1 } else { system.axes() };
        Self::estimate_for(system.matrix.n_vertices(), nblocks, storage)
    }

    /// The memory a precompute of `nblocks` distinct N x N blocks needs (before anything,
    /// even the system, is assembled).
    pub fn estimate_for(n: usize, nblocks: usize, storage: Storage) -> MemoryEstimate {
        let (n, nblocks) = (n as u64, nblocks as u64);
        let block = n * n;
        let stored = nblocks * block * storage.word_bytes() as u64;
        let work = block * 8 + n * INVERSE_BLOCK as u64 * 8;
        let peak = match storage {
            // The working block becomes the stored block.
            Storage::F64 => stored + n * INVERSE_BLOCK as u64 * 8,
            Storage::F32 => stored + work,
        };
        MemoryEstimate { stored, peak }
    }

    /// Precomputes the response of an assembled system: for each distinct block a Cholesky
    /// factorization (`N^3 / 3` flops) and the inverse from it (`2 N^3 / 3` flops, computed
    /// in place, blocked), then `w_c` and `s` (`2 N^2` flops per axis).
    ///
    /// Refuses with [`InteractError::OutOfMemory`] before allocating when the peak of
    /// [`estimate`](Self::estimate) exceeds the budget, and with
    /// [`InteractError::Singular`] when a block is not positive definite (too few
    /// constraints) or the Schur complement `s` vanishes.
    pub fn from_system(system: &System, opts: &ComplianceOptions) -> Result<Self> {
        let start = Instant::now();
        let a = &system.matrix;
        let (n, axes) = (a.n_vertices(), a.axes());
        let est = Self::estimate(system, opts.storage);
        let budget = memory_budget(opts.max_memory_bytes);
        if est.peak > budget {
            return Err(InteractError::OutOfMemory { bytes: est.peak, available: budget });
        }
        a.check_finite().map_err(|e| InteractError::Invalid(format!("the assembled system: {e}")))?;
        let (border, constrained, loaded) = scene_terms(system);
        let nblocks = if a.is_shared() { 1 } else { axes };
        let mut w = vec![vec![0.0; n]; axes];
        let mut stored64 = Vec::new();
        let mut stored32 = Vec::new();
        for b in 0..nblocks {
            let inv = invert_spd(a.block_full(b).into_owned()).map_err(|index| InteractError::Singular {
                what: format!(
                    "the stiffness block{} is not positive definite at vertex {index} (fix more vertices)",
                    if nblocks == 1 { String::new() } else { format!(" of axis {}", AXES[b]) }
                ),
            })?;
            // w_c = C_c S_c for every axis this block serves, from the f64 inverse, in one
            // pass over its columns.
            let served: Vec<usize> = if nblocks == 1 { (0..axes).collect() } else { vec![b] };
            for j in 0..n {
                let col = inv.col_as_slice(j);
                for &c in &served {
                    let sj = border[c][j];
                    if sj != 0.0 {
                        for (wi, ci) in w[c].iter_mut().zip(col) {
                            *wi += ci * sj;
                        }
                    }
                }
            }
            match opts.storage {
                Storage::F64 => stored64.push(inv),
                Storage::F32 => {
                    stored32.push(Mat::<f32>::from_fn(n, n, |i, j| inv[(i, j)] as f32));
                    drop(inv);
                }
            }
        }
        let schur: f64 =
            (0..axes).map(|c| border[c].iter().zip(&w[c]).map(|(s, w)| s * w).sum::<f64>()).sum();
        let s2: f64 = border.iter().flatten().map(|v| v * v).sum();
        if !(schur > 0.0) || !schur.is_finite() {
            return Err(InteractError::Singular {
                what: format!("the volume row's Schur complement S' K^-1 S = {schur:e} (|S|^2 = {s2:e})"),
            });
        }
        let blocks = match opts.storage {
            Storage::F64 => Blocks::F64(stored64.into()),
            Storage::F32 => Blocks::F32(stored32.into()),
        };
        Ok(Self {
            n,
            axes,
            blocks,
            border,
            w,
            schur,
            constrained,
            loaded,
            storage: opts.storage,
            seconds: start.elapsed().as_secs_f64(),
        })
    }

    /// The lazy response of an assembled system from its kept factorization (the base
    /// solve's, not a second one): `w` and `s` from one bordered solve now, the columns of
    /// a vertex when [`touch`](Self::touch) first asks for them (one bordered solve per
    /// distinct block, two triangular solves each). Nothing of size `N^2` is allocated.
    ///
    /// Refuses with [`InteractError::Singular`] when the Schur complement `s` is not
    /// positive.
    pub fn lazy(system: &System, factorization: Arc<dyn Factorization>) -> Result<Self> {
        let start = Instant::now();
        let a = &system.matrix;
        let (n, axes) = (a.n_vertices(), a.axes());
        let (border, constrained, loaded) = scene_terms(system);
        let columns = VertexColumns::new(factorization.as_ref()).map_err(linalg_error)?;
        let w = (0..axes).map(|c| columns.w(c).to_vec()).collect();
        let schur = columns.schur();
        Ok(Self {
            n,
            axes,
            blocks: Blocks::Lazy { factorization, columns },
            border,
            w,
            schur,
            constrained,
            loaded,
            storage: Storage::F64,
            seconds: start.elapsed().as_secs_f64(),
        })
    }

    /// How the response was computed.
    pub fn precompute(&self) -> Precompute {
        match self.blocks {
            Blocks::Lazy { .. } => Precompute::Lazy,
            _ => Precompute::Full,
        }
    }

    /// Makes the columns of `vertices` available: with the lazy response, computes those
    /// not cached yet (one bordered solve per distinct block and new vertex, all in one
    /// pass over the factor) and returns how many vertices were new; with the full
    /// precompute, nothing to do (0).
    ///
    /// # Panics
    /// If a vertex is out of range.
    pub fn touch(&mut self, vertices: &[usize]) -> Result<usize> {
        match &mut self.blocks {
            Blocks::Lazy { factorization, columns } => {
                columns.touch(factorization.as_ref(), vertices).map_err(linalg_error)
            }
            _ => Ok(0),
        }
    }

    /// Number of vertices N.
    pub fn n_vertices(&self) -> usize {
        self.n
    }

    /// Number of axes (2 for a polygon, 3 for a surface).
    pub fn axes(&self) -> usize {
        self.axes
    }

    /// How the blocks are stored (f64 for the lazy response).
    pub fn storage(&self) -> Storage {
        self.storage
    }

    /// Number of distinct N x N blocks (1 when shared by every axis).
    pub fn n_blocks(&self) -> usize {
        match &self.blocks {
            Blocks::F64(b) => b.len(),
            Blocks::F32(b) => b.len(),
            Blocks::Lazy { columns, .. } => columns.n_blocks(),
        }
    }

    /// Seconds the precompute took (the lazy response: its one solve for `w` and `s`).
    pub fn seconds(&self) -> f64 {
        self.seconds
    }

    /// Bytes held: the blocks plus the border vectors; for the lazy response, the kept
    /// factorization and the stiffness blocks it factors (kept for its residual checks; the
    /// same bytes when it was factored in place), the cached columns and the border vectors.
    pub fn memory_bytes(&self) -> usize {
        let border = 2 * self.axes * self.n * 8;
        match &self.blocks {
            Blocks::Lazy { factorization, columns } => {
                // A factorization made in place holds the blocks in its own bytes.
                let blocks = if factorization.matrix().is_factored_in_place() {
                    0
                } else {
                    columns.n_blocks() * self.n * self.n * 8
                };
                factorization.cost().bytes + blocks + columns.memory_bytes() + border
            }
            _ => self.n_blocks() * self.n * self.n * self.storage.word_bytes() + border,
        }
    }

    /// `s = sum_c S_c . K_c^-1 S_c`, the Schur complement of the volume row (physical S).
    pub fn schur(&self) -> f64 {
        self.schur
    }

    /// `w_c = K_c^-1 S_c` for one axis.
    pub fn w(&self, axis: usize) -> &[f64] {
        &self.w[axis]
    }

    /// The physical border `S_c` of one axis (zero on eliminated degrees of freedom).
    pub fn border(&self, axis: usize) -> &[f64] {
        &self.border[axis]
    }

    /// Whether the scene constrains `vertex` along `axis`.
    pub fn is_constrained(&self, vertex: usize, axis: usize) -> bool {
        self.constrained[vertex][axis]
    }

    /// The force as the right-hand side sees it: components on eliminated degrees of freedom
    /// are dropped (a full solve overwrites those rows with the prescribed value).
    pub fn effective_force(&self, vertex: usize, f: Vec3) -> Vec3 {
        let mut g = [0.0; 3];
        for c in 0..self.axes {
            if self.loaded[vertex][c] {
                g[c] = f[c];
            }
        }
        g
    }

    /// `C_axis[i, j]` (with the lazy response, column j must be
    /// [touched](Self::touch)).
    #[inline]
    pub fn entry(&self, axis: usize, i: usize, j: usize) -> f64 {
        match &self.blocks {
            Blocks::F64(b) => b[if b.len() == 1 { 0 } else { axis }][(i, j)],
            Blocks::F32(b) => b[if b.len() == 1 { 0 } else { axis }][(i, j)] as f64,
            Blocks::Lazy { columns, .. } => columns.entry(axis, i, j),
        }
    }

    /// The pressure change `P = sum_c w_c . f_c / s` caused by point forces (already
    /// [effective](Self::effective_force)).
    pub fn pressure_of(&self, forces: &[(usize, Vec3)]) -> f64 {
        VertexResponse::pressure_of(self, forces)
    }

    /// The displacement at one vertex caused by point forces (already effective) whose
    /// pressure change is `pressure`: `O(forces)`.
    pub fn displacement_at(&self, vertex: usize, forces: &[(usize, Vec3)], pressure: f64) -> Vec3 {
        VertexResponse::displacement_at(self, vertex, forces, pressure)
    }

    /// Adds the field of point forces (already effective) whose pressure change is
    /// `pressure` to `u`, stored axis by axis as the system's unknowns are (`u[c * N + i]`,
    /// `axes * N` entries): `u_c += sum_v C_c[:, v] f_v,c - w_c P`. One streamed column of
    /// `C` per force and axis, `O(N)` per force.
    ///
    /// # Panics
    /// If `u` does not have `axes * N` entries or a vertex is out of range (or, with the
    /// lazy response, not [touched](Self::touch)): programming errors.
    #[track_caller]
    pub fn add_field_axes(&self, forces: &[(usize, Vec3)], pressure: f64, u: &mut [f64]) {
        VertexResponse::add_field_axes(self, forces, pressure, u)
    }

    /// [`add_field_axes`](Self::add_field_axes) on a field stored vertex by vertex.
    ///
    /// # Panics
    /// If `field` does not have N entries or a vertex is out of range.
    #[track_caller]
    pub fn add_field(&self, forces: &[(usize, Vec3)], pressure: f64, field: &mut [Vec3]) {
        let n = self.n;
        assert_eq!(field.len(), n, "field length");
        let mut u = vec![0.0; self.axes * n];
        self.add_field_axes(forces, pressure, &mut u);
        for (i, fi) in field.iter_mut().enumerate() {
            for c in 0..self.axes {
                fi[c] += u[c * n + i];
            }
        }
    }

    /// Solves the bordered system for a full right-hand side as [`System::rhs`] builds it
    /// (`axes * N` load rows, then `pressure_scale * volume_target`), returning the
    /// displacements and the physical pressure: `O(N^2)`, the cost of the triangular solves
    /// it replaces. Used for base states computed from the precomputed response.
    ///
    /// # Panics
    /// If `rhs` does not have `axes * N + 1` entries.
    #[track_caller]
    pub fn solve_rhs(&self, system: &System, rhs: &[f64]) -> (Vec<Vec3>, f64) {
        let (n, d) = (self.n, self.axes);
        assert_eq!(rhs.len(), d * n + 1, "rhs length");
        if let Blocks::Lazy { factorization, .. } = &self.blocks {
            // The kept factorization solves it directly (unrefined, as the inverse would).
            let mut x = rhs.to_vec();
            factorization.solve_unrefined(&mut x);
            return system.split_solution(&x);
        }
        let t = rhs[d * n] / system.matrix.pressure_scale();
        let mut y = vec![[0.0; 3]; n];
        for c in 0..d {
            let b = &rhs[c * n..(c + 1) * n];
            for j in 0..n {
                if b[j] != 0.0 {
                    for (i, yi) in y.iter_mut().enumerate() {
                        yi[c] += self.entry(c, i, j) * b[j];
                    }
                }
            }
        }
        let sy: f64 = (0..d).map(|c| (0..n).map(|i| self.border[c][i] * y[i][c]).sum::<f64>()).sum();
        let p = (sy - t) / self.schur;
        for (i, yi) in y.iter_mut().enumerate() {
            for c in 0..d {
                yi[c] -= self.w[c][i] * p;
            }
        }
        (y, p)
    }
}

impl VertexResponse for Compliance {
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
        Compliance::entry(self, axis, i, j)
    }

    #[inline]
    fn add_column(&self, axis: usize, j: usize, a: f64, y: &mut [f64]) {
        match &self.blocks {
            Blocks::F64(b) => axpy(y, b[if b.len() == 1 { 0 } else { axis }].col_as_slice(j), a),
            Blocks::F32(b) => axpy(y, b[if b.len() == 1 { 0 } else { axis }].col_as_slice(j), a),
            Blocks::Lazy { columns, .. } => columns.add_column(axis, j, a, y),
        }
    }

    fn epsilon(&self) -> f64 {
        self.storage.epsilon()
    }

    fn add_field_axes(&self, forces: &[(usize, Vec3)], pressure: f64, u: &mut [f64]) {
        match &self.blocks {
            Blocks::Lazy { columns, .. } => columns.add_field_axes(forces, pressure, u),
            _ => fibfluid_linalg::add_field_by_columns(self, forces, pressure, u),
        }
    }
}

/// A stored entry type.
trait Entry: Copy + Send + Sync + 'static {
    fn f64(self) -> f64;
}

impl Entry for f64 {
    #[inline(always)]
    fn f64(self) -> f64 {
        self
    }
}

impl Entry for f32 {
    #[inline(always)]
    fn f64(self) -> f64 {
        self as f64
    }
}

/// `y += a x` with x converted to f64 (vectorized by the compiler).
#[inline]
fn axpy<T: Entry>(y: &mut [f64], x: &[T], a: f64) {
    for (yi, xi) in y.iter_mut().zip(x) {
        *yi += xi.f64() * a;
    }
}

/// Inverts a symmetric positive definite matrix: Cholesky in place, then the lower triangle
/// of the inverse overwrites the factor block column by block column (the columns
/// `j0..j1` of the inverse, rows `j0..`, depend only on the trailing factor
/// `L[j0.., j0..]`, and no later block needs those columns of L), then the upper triangle
/// is mirrored. One N x N f64 buffer; `N^3` flops in all. Returns the failing pivot's index
/// on a matrix that is not (numerically) positive definite.
fn invert_spd(k: Mat<f64>) -> std::result::Result<Mat<f64>, usize> {
    let n = k.nrows();
    let par = fibfluid_linalg::parallel::compute_par();
    let diagonal: Vec<f64> = (0..n).map(|i| k[(i, i)]).collect();
    let mut a = k;
    {
        let mut mem = MemBuffer::new(cholesky_in_place_scratch::<f64>(n, par, Default::default()));
        cholesky_in_place(a.as_mut(), Default::default(), par, MemStack::new(&mut mem), Default::default())
            .map_err(|e| match e {
            LltError::NonPositivePivot { index } => index,
        })?;
    }
    // As the structured backend does: a tiny positive pivot is a singular block.
    let tol = n as f64 * f64::EPSILON;
    for i in 0..n {
        let lii = a[(i, i)];
        if !(lii * lii > tol * diagonal[i].abs()) {
            return Err(i);
        }
    }
    let mut j0 = 0;
    while j0 < n {
        let j1 = (j0 + INVERSE_BLOCK).min(n);
        let (m, b) = (n - j0, j1 - j0);
        let mut x = Mat::<f64>::zeros(m, b);
        for t in 0..b {
            x[(t, t)] = 1.0;
        }
        {
            let l = a.as_ref().submatrix(j0, j0, m, m);
            solve_lower_triangular_in_place(l, x.as_mut(), par);
            solve_upper_triangular_in_place(l.transpose(), x.as_mut(), par);
        }
        a.as_mut().submatrix_mut(j0, j0, m, b).copy_from(&x);
        j0 = j1;
    }
    for j in 1..n {
        for i in 0..j {
            a[(i, j)] = a[(j, i)];
        }
    }
    Ok(a)
}
