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

/// Material of the body: fibers and fluid. Its fields are private and every way to make or
/// change one checks the ranges of [`MaterialParameter`] (the one place they are written), so
/// a `Material` is valid by construction.
#[derive(Clone, Debug)]
pub struct Material {
    fiber_modulus: [f64; 3],
    surface_tension: f64,
    density: f64,
    law: StiffnessLaw,
    kernel_exponent: f64,
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
    /// A material with a fiber modulus per axis (Yx, Yy, Yz), a surface tension and a fluid
    /// density; linear fibers with the paper's kernel. Each value is checked
    /// ([`MaterialParameter::check`]).
    pub fn new(fiber_modulus: [f64; 3], surface_tension: f64, density: f64) -> Result<Self> {
        let mut m = Self::default();
        m.set_fiber_modulus(fiber_modulus)?;
        m.set_surface_tension(surface_tension)?;
        m.set_density(density)?;
        Ok(m)
    }

    /// An isotropic material: one fiber modulus on every axis (not a Young's modulus; see
    /// [`Material::fiber_modulus`]).
    ///
    /// # Panics
    /// On a value out of its range (a programming error: values from users go through
    /// [`Material::new`] or the setters, which return the error).
    #[track_caller]
    pub fn isotropic(fiber_modulus: f64, surface_tension: f64, density: f64) -> Self {
        match Self::new([fiber_modulus; 3], surface_tension, density) {
            Ok(m) => m,
            Err(e) => panic!("Material::isotropic: {e}"),
        }
    }

    /// FFM's fiber modulus per axis (Yx, Yy, Yz), N/m^2 per unit fiber weight; isotropic
    /// when equal. A model parameter, not a tissue's Young's modulus.
    pub fn fiber_modulus(&self) -> [f64; 3] {
        self.fiber_modulus
    }

    /// Surface tension gamma (N/m); 0 switches surface fibers off.
    pub fn surface_tension(&self) -> f64 {
        self.surface_tension
    }

    /// Fluid density rho (kg/m^3).
    pub fn density(&self) -> f64 {
        self.density
    }

    /// Strain dependence of the bulk modulus.
    pub fn law(&self) -> &StiffnessLaw {
        &self.law
    }

    /// How a bulk fiber's weight falls with its length d: `w = (|S_i| + |S_j|) / (2 n d)
    /// (l / d)^(p - 1)` with `l` the rest shape's bounding-box diagonal (so the modulus keeps
    /// its unit and a body in mm and in m agree). 1 is the paper's `1 / d`.
    pub fn kernel_exponent(&self) -> f64 {
        self.kernel_exponent
    }

    /// Sets the fiber modulus per axis, checked on every axis.
    pub fn set_fiber_modulus(&mut self, fiber_modulus: [f64; 3]) -> Result<()> {
        for (axis, y) in fiber_modulus.iter().enumerate() {
            MaterialParameter::FiberModulus { axis }.check(*y)?;
        }
        self.fiber_modulus = fiber_modulus;
        Ok(())
    }

    /// Sets the surface tension, checked.
    pub fn set_surface_tension(&mut self, surface_tension: f64) -> Result<()> {
        self.surface_tension = MaterialParameter::SurfaceTension.check(surface_tension)?;
        Ok(())
    }

    /// Sets the fluid density, checked.
    pub fn set_density(&mut self, density: f64) -> Result<()> {
        self.density = MaterialParameter::Density.check(density)?;
        Ok(())
    }

    /// Sets the stiffness law (a quadratic coefficient is checked; a custom law must keep
    /// its factor positive, which cannot be checked here).
    pub fn set_law(&mut self, law: StiffnessLaw) -> Result<()> {
        if let StiffnessLaw::Quadratic { c } = law {
            MaterialParameter::Stiffening.check(c)?;
        }
        self.law = law;
        Ok(())
    }

    /// Sets the kernel exponent, checked against [`KERNEL_EXPONENT_RANGE`].
    pub fn set_kernel_exponent(&mut self, exponent: f64) -> Result<()> {
        self.kernel_exponent = MaterialParameter::KernelExponent.check(exponent)?;
        Ok(())
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
