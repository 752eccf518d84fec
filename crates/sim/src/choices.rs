//! The choices of a run, each an enum with one parser (scene files, the command line and
//! reports share it).

use fibfluid_linalg::{Choice, impl_choice};

/// A deformation method: every place that names one (scene, command line, reports, the
/// interactive bodies, the viewer) uses this type.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Method {
    /// The fiber–fluid method (batch runs and interactive probing, forces and grabs).
    #[default]
    Ffm,
    /// TSVE-ChainMail (interactive only; grabs only).
    TsveChainmail,
    /// Generalized (traditional) ChainMail (interactive only; grabs only).
    GeneralizedChainmail,
    /// The finite-element reference: linear elasticity on a sparse voxel grid (batch runs
    /// and interactive probing, forces and grabs; needs `[tissue]`).
    Fem,
}

impl Choice for Method {
    const WHAT: &'static str = "method";
    const ALL: &'static [Self] =
        &[Method::Ffm, Method::TsveChainmail, Method::GeneralizedChainmail, Method::Fem];
    fn name(self) -> &'static str {
        match self {
            Method::Ffm => "ffm",
            Method::TsveChainmail => "tsve-chainmail",
            Method::GeneralizedChainmail => "generalized-chainmail",
            Method::Fem => "fem",
        }
    }
}
impl_choice!(Method);

impl Method {
    /// Whether the method is one of the ChainMail methods (displacement-driven, no
    /// forces, no batch run).
    pub fn is_chainmail(self) -> bool {
        matches!(self, Method::TsveChainmail | Method::GeneralizedChainmail)
    }
}

/// How load steps are taken (REFERENCE §4–5).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Mode {
    /// The paper: K and the border from the rest shape, factored once; each step adds the
    /// increment computed on the current shape. Volume drifts to first order.
    Paper,
    /// K factored once, but the border S and the volume target `V0 - V` are refreshed from
    /// the current shape every step: no volume drift, triangular solves only.
    #[default]
    Refresh,
    /// K, S and the loads re-assembled and refactored on the current shape every step (the
    /// paper's "slower procedure"); supports strain-dependent moduli.
    Nonlinear,
}

impl Choice for Mode {
    const WHAT: &'static str = "mode";
    const ALL: &'static [Self] = &[Mode::Paper, Mode::Refresh, Mode::Nonlinear];
    fn name(self) -> &'static str {
        match self {
            Mode::Paper => "paper",
            Mode::Refresh => "refresh",
            Mode::Nonlinear => "nonlinear",
        }
    }
}
impl_choice!(Mode);

/// How a fiber resists a displacement of its ends (`[ffm] fibers`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum FiberModel {
    /// The paper: fiber `ij` pulls with `k (u_j - u_i)` on each axis alike (a graph
    /// Laplacian per axis). Rotating the body costs energy. The structured solver's
    /// per-axis blocks.
    #[default]
    Paper,
    /// The spring acts along the fiber: `k d d^T (u_j - u_i)` with `d` the fiber's rest
    /// direction. Rigid motions cost nothing; the axes couple (one 3N x 3N system).
    Projected,
}

impl Choice for FiberModel {
    const WHAT: &'static str = "fiber model";
    const ALL: &'static [Self] = &[FiberModel::Paper, FiberModel::Projected];
    fn name(self) -> &'static str {
        match self {
            FiberModel::Paper => "paper",
            FiberModel::Projected => "projected",
        }
    }
}
impl_choice!(FiberModel);

/// The load-stepping scheme.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Stepping {
    /// Explicit first-order steps (the paper).
    #[default]
    Euler,
    /// Predictor–corrector: the load (and, outside paper mode, the operator) is evaluated
    /// again on the predicted shape and the two increments are averaged. Second order.
    Heun,
}

impl Choice for Stepping {
    const WHAT: &'static str = "stepping scheme";
    const ALL: &'static [Self] = &[Stepping::Euler, Stepping::Heun];
    fn name(self) -> &'static str {
        match self {
            Stepping::Euler => "euler",
            Stepping::Heun => "heun",
        }
    }
}
impl_choice!(Stepping);

/// When a point force is applied.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ForceTiming {
    /// All of it at the last step (the paper's sphere example).
    #[default]
    Last,
    /// Spread evenly over the load steps.
    Ramp,
}

impl Choice for ForceTiming {
    const WHAT: &'static str = "force timing";
    const ALL: &'static [Self] = &[ForceTiming::Last, ForceTiming::Ramp];
    fn name(self) -> &'static str {
        match self {
            ForceTiming::Last => "last",
            ForceTiming::Ramp => "ramp",
        }
    }
}
impl_choice!(ForceTiming);
