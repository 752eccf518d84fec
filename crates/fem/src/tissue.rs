//! Isotropic linear-elastic tissue.

use serde::Serialize;

use crate::error::{FemError, Result};
use crate::law::{PronyTerm, Viscoelastic};

/// A parameter of a [`Tissue`], as errors name it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TissueParameter {
    /// Young's modulus E (Pa).
    Young,
    /// Poisson's ratio nu.
    Poisson,
    /// Mass density rho (kg/m^3).
    Density,
}

impl TissueParameter {
    /// The parameter's key in a scene's `[tissue]` table.
    pub fn key(self) -> &'static str {
        match self {
            Self::Young => "young",
            Self::Poisson => "poisson",
            Self::Density => "density",
        }
    }
}

impl std::fmt::Display for TissueParameter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.key())
    }
}

/// The constitutive model of a [`Tissue`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum TissueModel {
    /// Small-strain linear elasticity (`FemBody`): one solve, valid for small strains.
    #[default]
    Linear,
    /// Compressible neo-Hookean hyperelasticity (`hyper::HyperBody`), with the same
    /// `mu = E / (2 (1 + nu))` and `kappa = E / (3 (1 - 2 nu))`: large deformation by Newton's
    /// method.
    NeoHookean,
}

impl fibfluid_linalg::Choice for TissueModel {
    const WHAT: &'static str = "tissue model";
    const ALL: &'static [Self] = &[TissueModel::Linear, TissueModel::NeoHookean];
    fn name(self) -> &'static str {
        match self {
            TissueModel::Linear => "linear",
            TissueModel::NeoHookean => "neo-hookean",
        }
    }
}
fibfluid_linalg::impl_choice!(TissueModel);

/// Prony terms a tissue may relax by, at most.
pub const MAX_PRONY_TERMS: usize = 6;

/// A tissue's viscous relaxation: up to [`MAX_PRONY_TERMS`] Prony terms of its reduced
/// relaxation function (none: elastic). Validated by [`Tissue::with_relaxation`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Relaxation {
    terms: [Option<PronyTerm>; MAX_PRONY_TERMS],
}

impl Relaxation {
    /// The terms.
    pub fn terms(&self) -> Vec<PronyTerm> {
        self.terms.iter().flatten().copied().collect()
    }

    /// Whether the tissue relaxes at all.
    pub fn is_empty(&self) -> bool {
        self.terms.iter().all(Option::is_none)
    }
}

impl Serialize for Relaxation {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        use serde::ser::SerializeSeq;
        let terms = self.terms();
        let mut seq = s.serialize_seq(Some(terms.len()))?;
        for t in terms {
            seq.serialize_element(&[t.g, t.tau])?;
        }
        seq.end()
    }
}

/// An isotropic elastic material, SI units. Its fields are private: a `Tissue` is
/// valid by construction ([`Tissue::new`] is the one place its ranges are checked).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Tissue {
    young: f64,
    poisson: f64,
    density: f64,
    model: TissueModel,
    relaxation: Relaxation,
}

impl Tissue {
    /// A validated tissue.
    ///
    /// Errors ([`FemError::InvalidTissue`]): `young` not finite or `<= 0`, `poisson` not in
    /// the open interval (-1, 0.5) (so 0.5, the incompressible limit, is refused), `density`
    /// not finite or `< 0`.
    pub fn new(young: f64, poisson: f64, density: f64) -> Result<Self> {
        let t =
            Self { young, poisson, density, model: TissueModel::Linear, relaxation: Relaxation::default() };
        t.validate()?;
        Ok(t)
    }

    /// Young's modulus E, Pa (finite, > 0).
    pub fn young(&self) -> f64 {
        self.young
    }

    /// Poisson's ratio nu, in (-1, 0.5).
    pub fn poisson(&self) -> f64 {
        self.poisson
    }

    /// Mass density rho, kg/m^3 (finite, >= 0).
    pub fn density(&self) -> f64 {
        self.density
    }

    /// The constitutive model (linear unless [`Tissue::with_model`] says otherwise).
    pub fn model(&self) -> TissueModel {
        self.model
    }

    /// The law of this tissue's model, viscoelastic when it relaxes (shared by every cell
    /// that uses it).
    pub fn law(&self) -> std::sync::Arc<dyn crate::law::MaterialLaw> {
        let elastic: std::sync::Arc<dyn crate::law::MaterialLaw> = match self.model {
            TissueModel::Linear => std::sync::Arc::new(crate::law::LinearLaw),
            TissueModel::NeoHookean => std::sync::Arc::new(crate::law::NeoHookean),
        };
        if self.relaxation.is_empty() {
            return elastic;
        }
        match Viscoelastic::new(elastic.clone(), self.relaxation.terms()) {
            Ok(law) => std::sync::Arc::new(law),
            // Validated by `with_relaxation`; unreachable, but never a panic.
            Err(_) => elastic,
        }
    }

    /// The same tissue relaxing by `terms` (none: elastic).
    ///
    /// Errors ([`FemError::InvalidRelaxation`]): more than [`MAX_PRONY_TERMS`] terms, or
    /// terms [`Viscoelastic::new`] refuses.
    pub fn with_relaxation(&self, terms: &[PronyTerm]) -> Result<Self> {
        if terms.len() > MAX_PRONY_TERMS {
            return Err(FemError::InvalidRelaxation {
                reason: format!("{} Prony terms, at most {MAX_PRONY_TERMS}", terms.len()),
            });
        }
        if !terms.is_empty() {
            Viscoelastic::new(std::sync::Arc::new(crate::law::LinearLaw), terms.to_vec())?;
        }
        let mut relaxation = Relaxation::default();
        for (slot, t) in relaxation.terms.iter_mut().zip(terms) {
            *slot = Some(*t);
        }
        Ok(Self { relaxation, ..*self })
    }

    /// The tissue's relaxation (empty: elastic).
    pub fn relaxation(&self) -> &Relaxation {
        &self.relaxation
    }

    /// Whether the tissue's law is small-strain linear (one solve is its answer; its
    /// strains say when that answer is untrue).
    pub fn is_linear(&self) -> bool {
        self.model == TissueModel::Linear && self.relaxation.is_empty()
    }

    /// The same tissue with the small-strain linear law (the linearization of any law at
    /// rest: the same `mu` and `kappa`).
    pub fn linearized(&self) -> Self {
        self.with_model(TissueModel::Linear)
    }

    /// The same tissue with the large-deformation (neo-Hookean) law, the same moduli at rest.
    pub fn nonlinear(&self) -> Self {
        self.with_model(TissueModel::NeoHookean)
    }

    /// The same tissue with another constitutive model.
    pub fn with_model(&self, model: TissueModel) -> Self {
        Self { model, ..*self }
    }

    /// The same tissue with another density (validated as [`Tissue::new`] does).
    pub fn with_density(&self, density: f64) -> Result<Self> {
        let t = Self::new(self.young, self.poisson, density)?.with_model(self.model);
        Ok(Self { relaxation: self.relaxation, ..t })
    }

    /// The same tissue (law, relaxation) with another Young's modulus and Poisson's ratio
    /// (validated as [`Tissue::new`] does).
    pub fn with_elastic(&self, young: f64, poisson: f64) -> Result<Self> {
        let t = Self { young, poisson, ..*self };
        t.validate()?;
        Ok(t)
    }

    fn validate(&self) -> Result<()> {
        let bad = |name, value, reason| Err(FemError::InvalidTissue { name, value, reason });
        if !(self.young.is_finite() && self.young > 0.0) {
            return bad(TissueParameter::Young, self.young, "must be finite and > 0");
        }
        if !(self.poisson > -1.0 && self.poisson < 0.5) {
            return bad(TissueParameter::Poisson, self.poisson, "must lie in (-1, 0.5)");
        }
        if !(self.density.is_finite() && self.density >= 0.0) {
            return bad(TissueParameter::Density, self.density, "must be finite and >= 0");
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
