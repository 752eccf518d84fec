//! Result guards: checks on a finished answer, the same for every method, that say when it
//! is physically impossible (the step guards of [`crate::guards`] watch FFM's steps; these
//! watch what any method returns).
//!
//! | guard | measure | warns when |
//! |---|---|---|
//! | `volume` | `V / V0`, the enclosed volume over the rest volume | `V <= 0`, or outside `[1 / VOLUME_RATIO_LIMIT, VOLUME_RATIO_LIMIT]` |
//! | `displacement` | largest `|u|` over the rest bounding-box diagonal | above [`DISPLACEMENT_LIMIT`] |
//! | `inverted` | faces whose normal turned against the rest shape's | any (methods without step guards) |
//! | `residual` | the solve's relative residual | above [`RESULT_RESIDUAL_LIMIT`] |
//! | `linear` | largest `|u|` over the diagonal, for a small-strain (linear) FEM answer | above [`LINEAR_DISPLACEMENT_LIMIT`] |
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
}

impl Choice for ResultGuard {
    const WHAT: &'static str = "result guard";
    const ALL: &'static [Self] = &[
        ResultGuard::Volume,
        ResultGuard::Displacement,
        ResultGuard::Inverted,
        ResultGuard::Residual,
        ResultGuard::Linear,
    ];
    fn name(self) -> &'static str {
        match self {
            ResultGuard::Volume => "volume",
            ResultGuard::Displacement => "displacement",
            ResultGuard::Inverted => "inverted",
            ResultGuard::Residual => "residual",
            ResultGuard::Linear => "linear",
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
        };
        let what = what
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
    let (v0, v1) = (boundary.volume(rest), boundary.volume(positions));
    if !v1.is_finite() {
        return Err(NonFiniteAnswer { vertex: 0 });
    }
    let mut out = vec![];
    let ratio = v1 / v0;
    if !(v1 > 0.0 && (1.0 / VOLUME_RATIO_LIMIT..=VOLUME_RATIO_LIMIT).contains(&ratio)) {
        out.push(ResultWarning { guard: ResultGuard::Volume, value: ratio, limit: VOLUME_RATIO_LIMIT });
    }
    let (lo, hi) = fibfluid_geometry::bounding_box(rest);
    let size = dist(lo, hi);
    let largest = lengths.iter().copied().fold(0.0, f64::max);
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
    if checks.inverted {
        let inverted = inverted_faces(boundary, rest, positions);
        if inverted > 0 {
            out.push(ResultWarning { guard: ResultGuard::Inverted, value: inverted as f64, limit: 0.0 });
        }
    }
    if let Some(r) = checks.residual
        && !(r <= RESULT_RESIDUAL_LIMIT)
    {
        out.push(ResultWarning { guard: ResultGuard::Residual, value: r, limit: RESULT_RESIDUAL_LIMIT });
    }
    Ok(out)
}
