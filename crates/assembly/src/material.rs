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

    /// Checks every parameter's range ([`MaterialParameter::check`], the one place the
    /// ranges are written): fiber modulus > 0, gamma >= 0, rho >= 0, stiffening >= 0, all
    /// finite, kernel exponent in [`KERNEL_EXPONENT_RANGE`].
    pub fn check(&self) -> Result<()> {
        for (axis, y) in self.fiber_modulus.iter().enumerate() {
            MaterialParameter::FiberModulus { axis }.check(*y)?;
        }
        MaterialParameter::SurfaceTension.check(self.surface_tension)?;
        MaterialParameter::Density.check(self.density)?;
        if let StiffnessLaw::Quadratic { c } = self.law {
            MaterialParameter::Stiffening.check(c)?;
        }
        MaterialParameter::KernelExponent.check(self.kernel_exponent)?;
        Ok(())
    }
}

/// A parameter of FFM's [`Material`], as range errors name it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MaterialParameter {
    /// The fiber modulus along one axis (0, 1, 2 for x, y, z).
    FiberModulus {
        /// The axis.
        axis: usize,
    },
    /// The surface tension gamma.
    SurfaceTension,
    /// The fluid density rho.
    Density,
    /// The quadratic stiffening coefficient.
    Stiffening,
    /// The bulk fibers' kernel exponent.
    KernelExponent,
}

impl MaterialParameter {
    /// The rule a value must meet, in words (`positive`, `>= 0`, `in [0.5, 6]`); a value
    /// must also be finite.
    pub fn rule(self) -> &'static str {
        match self {
            Self::FiberModulus { .. } => "positive",
            Self::SurfaceTension | Self::Density | Self::Stiffening => ">= 0",
            Self::KernelExponent => "in [0.5, 6]",
        }
    }

    /// Whether `value` meets the rule.
    pub fn accepts(self, value: f64) -> bool {
        match self {
            Self::FiberModulus { .. } => value.is_finite() && value > 0.0,
            Self::SurfaceTension | Self::Density | Self::Stiffening => value.is_finite() && value >= 0.0,
            Self::KernelExponent => KERNEL_EXPONENT_RANGE.contains(&value),
        }
    }

    /// `value` when it meets the rule, else [`AssemblyError::InvalidMaterial`].
    pub fn check(self, value: f64) -> Result<f64> {
        if self.accepts(value) {
            Ok(value)
        } else {
            Err(AssemblyError::InvalidMaterial { parameter: self, value })
        }
    }
}

impl std::fmt::Display for MaterialParameter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::FiberModulus { axis } => write!(f, "fiber modulus along {}", crate::AXES[*axis % 3]),
            Self::SurfaceTension => f.write_str("surface tension"),
            Self::Density => f.write_str("density"),
            Self::Stiffening => f.write_str("stiffening coefficient"),
            Self::KernelExponent => f.write_str("kernel exponent"),
        }
    }
}
