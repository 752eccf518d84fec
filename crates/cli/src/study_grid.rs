//! The accuracy study's fixed grid: the FEM resolutions it measures, its reference, and
//! the margin of its Pareto front. Shared by the study and its grab comparison.

/// Resolutions of the FEM points of a study's physical axis.
pub const FEM_STUDY_RESOLUTIONS: [usize; 4] = [8, 12, 16, 24];
/// The resolution of the physical axis' FEM reference (finer than every FEM point).
pub const FEM_STUDY_REFERENCE: usize = 32;

/// Relative improvement a slower point needs to count on the Pareto front.
pub const PARETO_MARGIN: f64 = 0.01;
