//! Material parameters.

use std::fmt;
use std::sync::Arc;

use crate::{AssemblyError, Result};

/// How a bulk fiber's modulus depends on its current strain `(d - d0) / d0`.
#[derive(Clone, Default)]
pub enum StiffnessLaw {
    /// Constant modulus (the paper's linear material).
    #[default]
    Linear,
    /// `Y (1 + c strain^2)`: stiffening with stretch or compression.
    Quadratic {
        /// The coefficient c (>= 0).
        c: f64,
    },
    /// Any factor `f(strain)` multiplying Y (must stay positive).
    Custom(Arc<dyn Fn(f64) -> f64 + Send + Sync>),
}

impl StiffnessLaw {
    /// The factor multiplying Y at a strain.
    pub fn factor(&self, strain: f64) -> f64 {
        match self {
            StiffnessLaw::Linear => 1.0,
            StiffnessLaw::Quadratic { c } => 1.0 + c * strain * strain,
            StiffnessLaw::Custom(f) => f(strain),
        }
    }

    /// Whether the factor is 1 everywhere.
    pub fn is_linear(&self) -> bool {
        matches!(self, StiffnessLaw::Linear)
    }
}

impl fmt::Debug for StiffnessLaw {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StiffnessLaw::Linear => write!(f, "Linear"),
            StiffnessLaw::Quadratic { c } => write!(f, "Quadratic {{ c: {c} }}"),
            StiffnessLaw::Custom(_) => write!(f, "Custom(..)"),
        }
    }
}

/// Material of the body: fibers and fluid.
#[derive(Clone, Debug)]
pub struct Material {
    /// FFM's fiber modulus per axis (Yx, Yy, Yz), N/m^2 per unit fiber weight; isotropic
    /// when equal. A model parameter, not a tissue's Young's modulus.
    pub fiber_modulus: [f64; 3],
    /// Surface tension gamma; 0 switches surface fibers off.
    pub surface_tension: f64,
    /// Fluid density rho.
    pub density: f64,
    /// Strain dependence of the bulk modulus.
    pub law: StiffnessLaw,
    /// How a bulk fiber's weight falls with its length d: `w = (|S_i| + |S_j|) / (2 n d)
    /// (l / d)^(p - 1)` with `l` the rest shape's bounding-box diagonal (so the modulus keeps
    /// its unit and a body in mm and in m agree). 1 is the paper's `1 / d`.
    pub kernel_exponent: f64,
}

/// The paper's kernel exponent: bulk weights fall as `1 / d`.
pub const PAPER_KERNEL_EXPONENT: f64 = 1.0;
/// The kernel exponents a scene may choose (`[ffm] kernel_exponent`).
pub const KERNEL_EXPONENT_RANGE: std::ops::RangeInclusive<f64> = 0.5..=6.0;

impl Default for Material {
    /// The paper's sphere example: fiber modulus Y = gamma = 3000, rho = 1000.
    fn default() -> Self {
        Self {
            fiber_modulus: [3000.0; 3],
            surface_tension: 3000.0,
            density: 1000.0,
            law: StiffnessLaw::Linear,
            kernel_exponent: PAPER_KERNEL_EXPONENT,
        }
    }
}

impl Material {
    /// An isotropic material: one fiber modulus on every axis (not a Young's modulus; see
    /// [`Material::fiber_modulus`]).
    pub fn isotropic(fiber_modulus: f64, surface_tension: f64, density: f64) -> Self {
        Self {
            fiber_modulus: [fiber_modulus; 3],
            surface_tension,
            density,
            law: StiffnessLaw::Linear,
            kernel_exponent: PAPER_KERNEL_EXPONENT,
        }
    }

    /// Whether Yx = Yy = Yz.
    pub fn is_isotropic(&self) -> bool {
        self.fiber_modulus[0] == self.fiber_modulus[1] && self.fiber_modulus[1] == self.fiber_modulus[2]
    }

    /// Checks ranges: Y > 0, gamma >= 0, rho >= 0, all finite.
    pub fn check(&self) -> Result<()> {
        for (c, y) in self.fiber_modulus.iter().enumerate() {
            if !(y.is_finite() && *y > 0.0) {
                return Err(AssemblyError::Material(format!(
                    "fiber modulus along {} must be positive and finite, got {y}",
                    crate::AXES[c]
                )));
            }
        }
        if !(self.surface_tension.is_finite() && self.surface_tension >= 0.0) {
            return Err(AssemblyError::Material(format!(
                "surface tension must be >= 0 and finite, got {}",
                self.surface_tension
            )));
        }
        if !(self.density.is_finite() && self.density >= 0.0) {
            return Err(AssemblyError::Material(format!(
                "density must be >= 0 and finite, got {}",
                self.density
            )));
        }
        if let StiffnessLaw::Quadratic { c } = self.law
            && !(c.is_finite() && c >= 0.0)
        {
            return Err(AssemblyError::Material(format!("stiffening coefficient must be >= 0, got {c}")));
        }
        if !KERNEL_EXPONENT_RANGE.contains(&self.kernel_exponent) {
            return Err(AssemblyError::Material(format!(
                "kernel exponent must be in [{}, {}], got {}",
                KERNEL_EXPONENT_RANGE.start(),
                KERNEL_EXPONENT_RANGE.end(),
                self.kernel_exponent
            )));
        }
        Ok(())
    }
}
