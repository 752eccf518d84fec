//! Isotropic linear-elastic tissue.

use serde::Serialize;

use crate::error::{FemError, Result};

/// An isotropic linear-elastic material, SI units.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Tissue {
    /// Young's modulus E, Pa (finite, > 0).
    pub young: f64,
    /// Poisson's ratio nu, in (-1, 0.5).
    pub poisson: f64,
    /// Mass density rho, kg/m^3 (finite, >= 0).
    pub density: f64,
}

impl Tissue {
    /// A validated tissue.
    ///
    /// Errors ([`FemError::InvalidTissue`]): `young` not finite or `<= 0`, `poisson` not in
    /// the open interval (-1, 0.5) (so 0.5, the incompressible limit, is refused), `density`
    /// not finite or `< 0`.
    pub fn new(young: f64, poisson: f64, density: f64) -> Result<Self> {
        let t = Self { young, poisson, density };
        t.validate()?;
        Ok(t)
    }

    /// Checks the ranges of [`Tissue::new`] (for a value built from its public fields).
    pub fn validate(&self) -> Result<()> {
        let bad = |name, value, reason| Err(FemError::InvalidTissue { name, value, reason });
        if !(self.young.is_finite() && self.young > 0.0) {
            return bad("young", self.young, "must be finite and > 0");
        }
        if !(self.poisson > -1.0 && self.poisson < 0.5) {
            return bad("poisson", self.poisson, "must lie in (-1, 0.5)");
        }
        if !(self.density.is_finite() && self.density >= 0.0) {
            return bad("density", self.density, "must be finite and >= 0");
        }
        Ok(())
    }

    /// Shear modulus `mu = E / (2 (1 + nu))`.
    pub fn shear_modulus(&self) -> f64 {
        self.young / (2.0 * (1.0 + self.poisson))
    }

    /// Bulk modulus `kappa = E / (3 (1 - 2 nu))` (= lambda + 2 mu / 3).
    pub fn bulk_modulus(&self) -> f64 {
        self.young / (3.0 * (1.0 - 2.0 * self.poisson))
    }
}
