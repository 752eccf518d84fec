//! Material laws: what a tissue's energy, stress and tangent are at a point.
//!
//! A law is a [`MaterialLaw`]: the hyperelastic body asks it, at each Gauss point of each
//! cell, for the isochoric (shape-changing) energy density, its first Piola–Kirchhoff
//! stress and the stress's derivative, and, once per cell on the cell's mean dilatation
//! `theta`, for the volumetric energy `U(theta)` and its first two derivatives (the mean
//! dilatation split of [`crate::hyper::HyperCell`], which keeps the element free of locking
//! as nu -> 0.5). A law may keep state between steps (a viscous history, damage): it says
//! how many values it keeps per Gauss point ([`MaterialLaw::state_len`]), the body owns the
//! buffer ([`LawStates`]) and hands each point its slice.
//!
//! The laws a scene can name are [`LinearLaw`] (small strain; the B-bar element's quadratic
//! energy) and [`NeoHookean`]; code outside this crate asks a law's capabilities
//! ([`MaterialLaw::is_linear`], [`crate::Tissue::is_linear`]) and never branches on which
//! law it is. A new law is a type implementing [`MaterialLaw`] (one file here) plus its
//! scene key ([`crate::TissueModel`]); a law defined outside the crate works the same way
//! through [`crate::hyper::HyperBody::with_law`].
//!
//! Units: moduli in Pa, energy densities in J/m^3 (Pa), stresses in Pa.

mod linear;
mod neo_hookean;
pub(crate) mod state;
pub(crate) mod tensor;
mod viscoelastic;

use std::fmt::Debug;

pub use linear::LinearLaw;
pub use neo_hookean::NeoHookean;
pub use state::{CellLawState, LawStates, PointState};
pub use tensor::{M3, Tangent9, cofactor, det};
pub use viscoelastic::{PronyTerm, Viscoelastic};

/// The two moduli a law is evaluated with at a cell (a region's, or a blend of tissues').
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Moduli {
    /// Shear modulus `mu`, Pa.
    pub mu: f64,
    /// Bulk modulus `kappa`, Pa.
    pub kappa: f64,
}

/// A constitutive law at a point (see the module docs). Every method is evaluated with the
/// cell's [`Moduli`]; constants of the law's own (Prony terms, a second modulus ratio) live
/// in the implementing type.
pub trait MaterialLaw: Debug + Send + Sync {
    /// The law's name, as a scene names it (`"neo-hookean"`).
    fn name(&self) -> &'static str;

    /// Whether the law is small-strain linear: a cell's energy is then the B-bar element's
    /// quadratic form in the moduli (assembled once), and one linear solve is the answer.
    fn is_linear(&self) -> bool {
        false
    }

    /// How many `f64` the law keeps per Gauss point between steps (0: none).
    fn state_len(&self) -> usize {
        0
    }

    /// Sets a point's state at rest (called once per point when the buffer is made).
    fn initial_state(&self, _state: &mut [f64]) {}

    /// The isochoric energy density at the deformation gradient `f` (Pa), `None` when
    /// `det f <= 0`. A law with state returns the step's incremental energy, whose
    /// derivative is the stress at the step's end.
    fn isochoric_energy(&self, f: &M3, moduli: &Moduli, state: PointState<'_>) -> Option<f64>;

    /// The isochoric first Piola–Kirchhoff stress `P = dW/dF` (Pa) and its derivative
    /// `A[3 i + J][3 k + L] = dP_iJ / dF_kL`, for `det f > 0`.
    fn isochoric_stress(&self, f: &M3, moduli: &Moduli, state: PointState<'_>) -> (M3, Tangent9);

    /// The volumetric energy `U(theta)` of a cell's mean dilatation and its first two
    /// derivatives (Pa), `None` when `theta <= 0`; `state` is the cell's first point's
    /// (where a law keeps the cell's volumetric history).
    fn volumetric(&self, theta: f64, moduli: &Moduli, state: PointState<'_>) -> Option<[f64; 3]>;

    /// Updates a point's state at the end of a converged step of `dt` seconds, at the
    /// step's deformation gradient `f`. Stateless laws keep the default (nothing).
    fn commit_state(&self, _f: &M3, _moduli: &Moduli, _state: &mut [f64], _dt: f64) {}

    /// Updates a cell's volumetric history (in its first point's state) at the end of a
    /// converged step of `dt` seconds, at the cell's mean dilatation `theta`.
    fn commit_volumetric(&self, _theta: f64, _moduli: &Moduli, _state: &mut [f64], _dt: f64) {}

    /// The von Mises equivalent of the Cauchy stress at `f` (Pa), for reports; the default
    /// takes it from [`MaterialLaw::isochoric_stress`] (`sigma = P F^T / J`; the
    /// volumetric part is a pressure and drops out). `NaN` when `det f <= 0`.
    fn von_mises(&self, f: &M3, moduli: &Moduli, state: PointState<'_>) -> f64 {
        let j = det(f);
        if !(j > 0.0) {
            return f64::NAN;
        }
        let (p, _) = self.isochoric_stress(f, moduli, state);
        tensor::cauchy_von_mises(&p, f, j)
    }
}
