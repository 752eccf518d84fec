//! Result guards: checks on a finished answer, the same for every method, that say when it
//! is physically impossible (the step guards of [`crate::guards`] watch FFM's steps; these
//! watch what any method returns).
//!
//! | guard | measure | warns when |
//! |---|---|---|
//! | `volume` | `V / V0`, the enclosed volume over the rest volume | `V <= 0`, or outside `[1 / VOLUME_RATIO_LIMIT, VOLUME_RATIO_LIMIT]` |
//! | `displacement` | largest `|u|` over the rest bounding-box diagonal | above [`DISPLACEMENT_LIMIT`] |
//! | `inverted` | faces whose normal turned against their neighbourhood's (the faces around them) by more than a right angle since rest (a body that only rotated, however far, has none) | any (methods without step guards) |
//! | `residual` | the solve's relative residual | above [`RESULT_RESIDUAL_LIMIT`] |
//! | `linear` | largest `|u|` over the diagonal, for a small-strain (linear) FEM answer | above [`LINEAR_DISPLACEMENT_LIMIT`] |
//! | `strain` | largest principal Green–Lagrange strain over the cells, of a linear FEM batch answer (its own displacement field at each cell's centre) | above [`LINEAR_STRAIN_LIMIT`] |
//! | `dilatation` | largest `J` over the tissue's cells, of a neo-Hookean FEM batch answer | above [`DILATATION_LIMIT`] (`e`) |
//! | `grasp` | the largest distance of a grasped vertex from its target over the grid's cell size, of a neo-Hookean FEM batch answer | above [`GRASP_ERROR_LIMIT`]: the grasp's augmentations stopped short |
//! | `unstable` | the diagonal shift (over the largest diagonal entry) the last Newton tangent of a neo-Hookean FEM batch answer needed to factor | above 0: the equilibrium found is unstable |
//! | `untouched` | a moving plate (travel not 0) of a FEM batch answer that no surface sample touches (its force 0 N) | any: the plate did nothing |
//! | `unheld` | a FEM batch answer with no fixed vertex and no plate in contact: only the grasps' penalties (or nothing) hold the body | any: its rigid motion is set by penalties, not by supports |
//!
//! The `linear` guard is the small-strain model's own validity, estimated from the answer:
//! a displacement of a tenth of the body's size means strains of that order or more where
//! the body is held, where a linear answer is off by 10-20 % or more against a
//! large-deformation model (it neither stiffens nor keeps its volume; `docs/stability.md`).
//!
//! Soft tissue keeps its volume within a few per cent (Poisson's ratio near 0.5) and a body
//! held by part of itself does not move further than its own size under the loads of a
//! scene; an answer past these limits is the model outside its validity (a linear model at
//! large strain) or constraints that do not hold the body. A non-finite answer is an error
//! ([`NonFiniteAnswer`]), never a warning: nothing is written from it.
//!
//! `fibfluid_interact::FrameGuards` checks every frame of an interactive body (the live
//! viewer's, Python's `Body`'s) with the same guards and limits
//! ([`ResultChecks::for_frames`]) through [`Measures::judge`].

use fibfluid_geometry::vec3::{dist, norm, sub};
use fibfluid_geometry::{Boundary, Vec3};
use fibfluid_linalg::{Choice, impl_choice};
use serde::Serialize;

use crate::guards::inverted_faces;

/// The volume may change by at most this factor either way (`V / V0` in `[1/2, 2]`).
pub const VOLUME_RATIO_LIMIT: f64 = 2.0;
/// The largest displacement may be at most this many times the body's size (its rest
/// bounding-box diagonal).
pub const DISPLACEMENT_LIMIT: f64 = 1.0;
/// The largest displacement, over the body's size, below which a small-strain answer is
/// taken as valid.
pub const LINEAR_DISPLACEMENT_LIMIT: f64 = 0.1;
/// The largest principal strain a small-strain answer may reach before it warns: at 5 %
/// the linear force is about 5 % off the neo-Hookean one in uniaxial compression.
pub const LINEAR_STRAIN_LIMIT: f64 = 0.05;
/// The largest volume ratio `J` a neo-Hookean answer's cell may reach before it warns. Soft
/// tissue keeps its volume within a few per cent (nu 0.45 to 0.49); a cell whose volume
/// nearly tripled is torn apart by its load (a support or a grasp too small for it
/// concentrates it there), which the continuum model does not represent.
pub const DILATATION_LIMIT: f64 = std::f64::consts::E;
/// The largest distance of a grasped vertex from its target, in cells, a finite-element
/// answer may end with: a hundredth of a cell is far below the discretization's error.
pub const GRASP_ERROR_LIMIT: f64 = 1e-2;
/// The largest relative residual `|K u - f| / |f|` an answer may have.
pub const RESULT_RESIDUAL_LIMIT: f64 = 1e-8;

/// Which result guard fired.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ResultGuard {
    /// The volume is not positive, or changed by more than [`VOLUME_RATIO_LIMIT`].
    Volume,
    /// A vertex moved further than [`DISPLACEMENT_LIMIT`] times the body's size.
    Displacement,
    /// Faces turned inside out against the rest shape.
    Inverted,
    /// The solve's residual is above [`RESULT_RESIDUAL_LIMIT`].
    Residual,
    /// A small-strain answer moved a vertex more than [`LINEAR_DISPLACEMENT_LIMIT`] times
    /// the body's size: outside the linear model's validity.
    Linear,
    /// A small-strain (linear FEM) answer's largest principal Green–Lagrange strain, over
    /// its cells, is above [`LINEAR_STRAIN_LIMIT`].
    Strain,
    /// A neo-Hookean answer's cell grew its volume past [`DILATATION_LIMIT`] times.
    Dilatation,
    /// A neo-Hookean answer is an unstable equilibrium: its tangent is not positive
    /// definite (the Newton iterations next to it factored it only with a diagonal shift).
    Unstable,
    /// A grasped vertex ends further than [`GRASP_ERROR_LIMIT`] cells from its target.
    Grasp,
    /// A moving plate of a finite-element answer never touched the body (its force is 0 N); the
    /// warning's value is the plate's 1-based number.
    Untouched,
    /// A finite-element answer with no fixed vertex and no plate in contact: the body is
    /// near free, held only by the grasps' penalties (the value: how many grasps).
    Unheld,
    /// An interactive frame's estimated distance from the converged answer for its holds
    /// is more than [`ESTIMATE_LIMIT`] times the body's size (the value: that ratio).
    Estimate,
    /// `[fem] tolerance` was not met: the finest run's estimated relative discretization
    /// error (the value; infinite when too few runs fitted to estimate it) is above the
    /// tolerance (the limit).
    Accuracy,
}

/// The largest estimated error of an interactive answer, over the body's size, that
/// passes without a warning: an estimate past the body's size says nothing of the answer.
pub const ESTIMATE_LIMIT: f64 = 1.0;

impl Choice for ResultGuard {
    const WHAT: &'static str = "result guard";
    const ALL: &'static [Self] = &[
        ResultGuard::Volume,
        ResultGuard::Displacement,
        ResultGuard::Inverted,
        ResultGuard::Residual,
        ResultGuard::Linear,
        ResultGuard::Strain,
        ResultGuard::Dilatation,
        ResultGuard::Unstable,
        ResultGuard::Grasp,
        ResultGuard::Untouched,
        ResultGuard::Unheld,
        ResultGuard::Estimate,
        ResultGuard::Accuracy,
    ];
    fn name(self) -> &'static str {
        match self {
            ResultGuard::Volume => "volume",
            ResultGuard::Displacement => "displacement",
            ResultGuard::Inverted => "inverted",
            ResultGuard::Residual => "residual",
            ResultGuard::Linear => "linear",
            ResultGuard::Strain => "strain",
            ResultGuard::Dilatation => "dilatation",
            ResultGuard::Unstable => "unstable",
            ResultGuard::Grasp => "grasp",
            ResultGuard::Untouched => "untouched",
            ResultGuard::Unheld => "unheld",
            ResultGuard::Estimate => "estimate",
            ResultGuard::Accuracy => "accuracy",
        }
    }
}
impl_choice!(ResultGuard);

/// A result guard that fired.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ResultWarning {
    /// The guard.
    pub guard: ResultGuard,
    /// The measured value (`V / V0`, largest `|u|` over the diagonal, faces, residual).
    pub value: f64,
    /// The limit it passed (for `volume`, the factor either way).
    pub limit: f64,
}

impl std::fmt::Display for ResultWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (what, hint) = match self.guard {
            ResultGuard::Volume => (
                "the volume is {value} times the body's at rest (limit: a factor of {limit} either way)",
                "soft tissue keeps its volume: the constraints may not hold the body, or the load is far beyond a linear model",
            ),
            ResultGuard::Displacement => (
                "a vertex moved {value} times the body's size (limit {limit})",
                "check that the fixed vertices hold the body; a linear model is not valid this far",
            ),
            ResultGuard::Inverted => (
                "{value} faces turned inside out (limit {limit})",
                "the deformation is beyond what the model can represent: lower the load, or stiffen the tissue",
            ),
            ResultGuard::Residual => (
                "the solve's relative residual is {value} (limit {limit})",
                "the system is ill-conditioned: check the constraints and the tissue's values",
            ),
            ResultGuard::Linear => (
                "the largest displacement is {value} of the body's size (limit {limit})",
                "a small-strain (linear) model is off at this deformation: it neither stiffens nor keeps its volume; read the answer as qualitative",
            ),
            ResultGuard::Strain => (
                "the linear answer's largest principal strain is {value} (limit {limit})",
                "against the neo-Hookean model a linear answer is then off by about 10 % in force at 10 % strain and 20-55 % at 20-50 % (docs/fem.md): set [tissue] model = \"neo-hookean\"",
            ),
            ResultGuard::Dilatation => (
                "a cell's volume grew {value} times (limit {limit}; tissue keeps its volume within a few per cent)",
                "the load pulls the tissue apart there and the answer near that cell is not physical (a support or grasp too small for its load): support the body more, or load it less",
            ),
            ResultGuard::Grasp => (
                "a grasped vertex ends {value} cells from its target (limit {limit})",
                "the grasp's augmentations stopped short of meeting it (report.json: each grasp's error, newton.stats.failed_augmentations): check that no two grasps hold the same vertices apart; else grasp a wider patch, move it less far, or raise [fem] resolution",
            ),
            ResultGuard::Unstable => (
                "the equilibrium found is unstable: its tangent needed a diagonal shift of {value} of its largest entry to factor (limit {limit})",
                "the body is past a buckling load and would sway or fold to a shape this answer does not show: support it more widely, or load it less",
            ),
            ResultGuard::Untouched => (
                "[[plate]] #{count} never touched the body: its force is 0 N",
                "the plate does nothing where it is: move it (or its travel) so that it reaches the body, or remove it",
            ),
            ResultGuard::Unheld => (
                "no vertex is fixed and no plate touches the body: only {count} grasp(s) hold it, by penalties",
                "the body is near free and its rigid motion is whatever the penalties leave: fix vertices ([[fix]]) or support it with a plate",
            ),
            ResultGuard::Estimate => (
                "a frame's estimated distance from the converged answer is {value} times the body's size (limit {limit})",
                "the frames used an old linearization (a path shorter than one refresh, or failed refreshes): read the answer as the rest shape's linear response, or refresh more often (--refresh-every)",
            ),
            ResultGuard::Accuracy => (
                "the finest resolution's estimated relative error is {value} ([fem] tolerance {limit})",
                "report.json's accuracy says why the study stopped: allow more memory (--max-memory) or raise the tolerance",
            ),
        };
        let what = what
            .replace("{count}", &format!("{}", self.value))
            .replace("{value}", &format!("{:.3e}", self.value))
            .replace("{limit}", &format!("{}", self.limit));
        write!(f, "result guard `{}`: {what}; {hint}", self.guard)
    }
}

/// An answer with a non-finite position, displacement or volume: an error, never written.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NonFiniteAnswer {
    /// The first vertex whose position or displacement is not finite (0 when only the
    /// volume overflows).
    pub vertex: usize,
}

/// What to check of an answer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ResultChecks {
    /// Count faces turned inside out (methods without FFM's step guard for it).
    pub inverted: bool,
    /// The solve's relative residual, when the method measures one.
    pub residual: Option<f64>,
    /// Check the small-strain model's validity (a linear FEM answer).
    pub linear: bool,
}

/// What the guards measure of an answer, before the limits are applied.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measures {
    /// The enclosed volume at rest.
    pub rest_volume: f64,
    /// The enclosed volume now.
    pub volume: f64,
    /// The largest displacement.
    pub largest: f64,
    /// The body's size: its rest bounding-box diagonal.
    pub size: f64,
    /// Faces turned inside out (counted only when [`ResultChecks::inverted`] asks).
    pub inverted: usize,
}

impl Measures {
    /// The warnings of these measures against the limits of the module docs.
    pub fn judge(&self, checks: ResultChecks) -> Vec<ResultWarning> {
        judge(self, checks)
    }
}

/// The warnings of measured values against the limits of the module docs.
fn judge(m: &Measures, checks: ResultChecks) -> Vec<ResultWarning> {
    let mut out = vec![];
    let ratio = m.volume / m.rest_volume;
    if !(m.volume > 0.0 && (1.0 / VOLUME_RATIO_LIMIT..=VOLUME_RATIO_LIMIT).contains(&ratio)) {
        out.push(ResultWarning { guard: ResultGuard::Volume, value: ratio, limit: VOLUME_RATIO_LIMIT });
    }
    let (largest, size) = (m.largest, m.size);
    if largest > DISPLACEMENT_LIMIT * size {
        out.push(ResultWarning {
            guard: ResultGuard::Displacement,
            value: largest / size,
            limit: DISPLACEMENT_LIMIT,
        });
    }
    if checks.linear && largest > LINEAR_DISPLACEMENT_LIMIT * size && largest <= DISPLACEMENT_LIMIT * size {
        out.push(ResultWarning {
            guard: ResultGuard::Linear,
            value: largest / size,
            limit: LINEAR_DISPLACEMENT_LIMIT,
        });
    }
    if checks.inverted && m.inverted > 0 {
        out.push(ResultWarning { guard: ResultGuard::Inverted, value: m.inverted as f64, limit: 0.0 });
    }
    if let Some(r) = checks.residual
        && !(r <= RESULT_RESIDUAL_LIMIT)
    {
        out.push(ResultWarning { guard: ResultGuard::Residual, value: r, limit: RESULT_RESIDUAL_LIMIT });
    }
    out
}

/// The result guards of an answer: `positions` against `rest` on `boundary` (see the module
/// docs). Errors on a non-finite position.
pub fn check_answer(
    boundary: &Boundary,
    rest: &[Vec3],
    positions: &[Vec3],
    checks: ResultChecks,
) -> Result<Vec<ResultWarning>, NonFiniteAnswer> {
    // Positions, displacements (a difference of two huge positions overflows) and the volume.
    let lengths: Vec<f64> = positions.iter().zip(rest).map(|(p, r)| norm(sub(*p, *r))).collect();
    let finite = |v: usize| positions[v].iter().all(|x| x.is_finite()) && lengths[v].is_finite();
    if let Some(vertex) = (0..lengths.len()).find(|&v| !finite(v)) {
        return Err(NonFiniteAnswer { vertex });
    }
    let (rest_volume, volume) = (boundary.volume(rest), boundary.volume(positions));
    if !volume.is_finite() {
        return Err(NonFiniteAnswer { vertex: 0 });
    }
    let (lo, hi) = fibfluid_geometry::bounding_box(rest);
    let measures = Measures {
        rest_volume,
        volume,
        largest: lengths.iter().copied().fold(0.0, f64::max),
        size: dist(lo, hi),
        inverted: if checks.inverted { inverted_faces(boundary, rest, positions) } else { 0 },
    };
    Ok(judge(&measures, checks))
}

impl ResultChecks {
    /// The checks of an interactive body's frames (a viewer's, a Python `Body`'s): faces
    /// turned inside out for every method (no step guard watches a frame), no residual, and
    /// the small-strain validity for the finite-element method when its body is linear
    /// (`large_strain`: the neo-Hookean body, which needs none).
    pub fn for_frames(method: crate::Method, large_strain: bool) -> Self {
        Self { inverted: true, residual: None, linear: method == crate::Method::Fem && !large_strain }
    }
}
