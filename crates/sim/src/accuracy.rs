//! Resolution chosen by accuracy (`[fem] tolerance`): the finite-element run repeated at
//! growing resolutions until the surface displacement's estimated discretization error is
//! below the tolerance.
//!
//! The runs go from the scene's `[fem] resolution` up by [`RESOLUTION_RATIO`]. With the
//! surface displacements `u_1, u_2, u_3` of the last three, the relative L2 changes over
//! the surface's vertices `d_k = |u_k - u_(k-1)| / |u_k|` give the observed order
//! `p = ln(d_2 / d_3) / ln r` (kept within [`ORDER_RANGE`]) and the finest answer's
//! relative error estimate `d_3 / (r^p - 1)` (Richardson's); the study stops when that is
//! at most the tolerance, or when the next resolution would not fit the machine or passes
//! [`MAX_STUDY_RUNS`] (then a warning says the tolerance was not met). The L2 norm, not
//! the largest vertex's: next to a clamp's edge single vertices move with the grid.

use serde::Serialize;

use fibfluid_geometry::Vec3;

/// Each run's resolution over the last one's.
pub const RESOLUTION_RATIO: f64 = 1.5;

/// The observed order is kept within this range (a first-order method on cut cells is
/// about 1, trilinear cells on a smooth body about 2).
pub const ORDER_RANGE: (f64, f64) = (0.5, 4.0);

/// Runs at most in one study.
pub const MAX_STUDY_RUNS: usize = 6;

/// What a study measured: `report.json`'s `accuracy`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AccuracyStudy {
    /// The tolerance asked for: the estimated relative L2 error of the surface's
    /// displacement.
    pub tolerance: f64,
    /// Each run's resolution (cells along the longest side), the last one the answer's.
    pub resolutions: Vec<usize>,
    /// Each run's wall-clock seconds.
    pub seconds: Vec<f64>,
    /// Each run's largest surface displacement (m).
    pub max_displacements: Vec<f64>,
    /// Each run's relative L2 change of the surface's displacement from the run before
    /// (none for the first).
    pub changes: Vec<f64>,
    /// The observed order of convergence (from three runs or more).
    pub observed_order: Option<f64>,
    /// The answer's estimated discretization error, relative L2 over the surface's
    /// displacement (from three runs or more).
    pub estimated_error: Option<f64>,
    /// Whether the estimate is within the tolerance.
    pub met: bool,
    /// Why the study stopped short of the tolerance (none when it met it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stopped: Option<String>,
}

impl AccuracyStudy {
    /// A study for `tolerance`, no run yet.
    pub fn new(tolerance: f64) -> Self {
        Self {
            tolerance,
            resolutions: Vec::new(),
            seconds: Vec::new(),
            max_displacements: Vec::new(),
            changes: Vec::new(),
            observed_order: None,
            estimated_error: None,
            met: false,
            stopped: None,
        }
    }

    /// The resolution after `resolution`.
    pub fn next_resolution(resolution: usize) -> usize {
        ((resolution as f64 * RESOLUTION_RATIO).round() as usize).max(resolution + 1)
    }

    /// Records a run at `resolution` (its surface displacements `surface`, taken after
    /// `previous`'s, `seconds` long) and updates the estimate; whether the tolerance is met.
    pub fn record(
        &mut self,
        resolution: usize,
        surface: &[Vec3],
        previous: Option<&[Vec3]>,
        seconds: f64,
    ) -> bool {
        let largest = surface.iter().map(|u| fibfluid_geometry::vec3::norm(*u)).fold(0.0, f64::max);
        let size: f64 = surface.iter().map(|u| fibfluid_geometry::vec3::dot(*u, *u)).sum::<f64>().sqrt();
        let change = previous.map(|p| {
            let diff: f64 = surface
                .iter()
                .zip(p)
                .map(|(a, b)| fibfluid_geometry::vec3::dist(*a, *b).powi(2))
                .sum::<f64>()
                .sqrt();
            if size > 0.0 { diff / size } else { 0.0 }
        });
        self.resolutions.push(resolution);
        self.seconds.push(seconds);
        self.max_displacements.push(largest);
        self.changes.extend(change);
        if let [.., coarse, fine] = self.changes[..] {
            let ratio = self.ratio_of_last_two();
            let order =
                if coarse > 0.0 && fine > 0.0 { (coarse / fine).ln() / ratio.ln() } else { ORDER_RANGE.1 };
            let order = order.clamp(ORDER_RANGE.0, ORDER_RANGE.1);
            let error = fine / (ratio.powf(order) - 1.0);
            self.observed_order = Some(order);
            self.estimated_error = Some(error);
            self.met = error <= self.tolerance;
        }
        self.met
    }

    /// The last two runs' resolution ratio.
    fn ratio_of_last_two(&self) -> f64 {
        match self.resolutions[..] {
            [.., a, b] => b as f64 / a as f64,
            _ => RESOLUTION_RATIO,
        }
    }
}
