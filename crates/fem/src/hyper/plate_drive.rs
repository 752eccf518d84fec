//! Plates driven by a force in a timed solve: each step finds the plates' positions at
//! which their contact forces are the ones asked for.
//!
//! A force-driven plate ([`RigidPlate::force`]) is a rigid plane whose offset `s` along its
//! normal is one more unknown, with the equation `f(s) = F c(t)` (`f` the contact force on
//! the body at the step's equilibrium, `F` the plate's force, `c` the load curve). `f`
//! grows with `s` (0 until the plate touches), so each step brackets the root and closes
//! in by secant steps, each one a Newton solve of the step from the last trial's state.
//! The first trial of a step starts from the last step's offset moved by its measured
//! compliance: under a constant force a creeping body needs two or three trials a step.

use super::body::HyperBody;
use super::contact::RigidPlate;
use super::solve::{Multipliers, Progress};

/// A plate's force is met when it is within this fraction of the plate's full force (or
/// of the largest plate force, for a plate asked for 0 N).
pub const PLATE_FORCE_TOLERANCE: f64 = 1e-6;

/// Secant trials at most per step and plate; a step that needs more is cut.
pub const MAX_PLATE_FORCE_TRIALS: usize = 40;

/// The first offset a plate that has not pressed yet tries, in cells.
const FIRST_REACH: f64 = 0.25;

/// The force-driven plates' offsets during a timed solve.
pub(super) struct PlateDrive {
    /// Per plate: its offset along its normal from its start (m; 0 for a travel-driven
    /// plate).
    offsets: Vec<f64>,
    /// Per plate: the last step's compliance `ds / df` (m/N), once measured.
    compliance: Vec<Option<f64>>,
}

/// One plate's bracket of its force's root during a step: the largest offset with a
/// force below the target and the smallest with one above, with their forces.
#[derive(Clone, Copy, Default)]
struct Bracket {
    below: Option<(f64, f64)>,
    above: Option<(f64, f64)>,
}

impl PlateDrive {
    /// Every plate at its start.
    pub(super) fn new(plates: &[RigidPlate]) -> Self {
        Self { offsets: vec![0.0; plates.len()], compliance: vec![None; plates.len()] }
    }

    /// The plates where the drive holds them now (see [`placed`]).
    pub(super) fn place(&self, plates: &[RigidPlate]) -> Vec<RigidPlate> {
        placed(plates, &self.offsets)
    }

    /// The offsets a step tries first: where the last step ended, except for a plate that
    /// has not pressed yet, which starts [`FIRST_REACH`] cells of `reach` into the body
    /// (at rest it carries no load, where Newton's relative residual means nothing).
    fn first_trial(&self, plates: &[RigidPlate], reach: f64) -> Vec<f64> {
        let unmeasured =
            |k: usize| plates[k].force.is_some() && self.compliance[k].is_none() && self.offsets[k] == 0.0;
        (0..plates.len()).map(|k| if unmeasured(k) { FIRST_REACH * reach } else { self.offsets[k] }).collect()
    }

    /// The next offset of a plate whose force at offset `s` is `f`, against `target`:
    /// inside the bracket by the secant (kept off its ends), before it by the compliance
    /// or, unmeasured, by steps of `reach` that double.
    fn next_offset(&self, k: usize, bracket: &Bracket, s: f64, f: f64, target: f64, reach: f64) -> f64 {
        match (bracket.below, bracket.above) {
            (Some((s0, f0)), Some((s1, f1))) => {
                let secant =
                    if f1 > f0 { s0 + (target - f0) * (s1 - s0) / (f1 - f0) } else { 0.5 * (s0 + s1) };
                let margin = 0.05 * (s1 - s0);
                secant.clamp(s0 + margin, s1 - margin)
            }
            _ => match self.compliance[k] {
                Some(c) if f > 0.0 => s + c * (target - f),
                // Unmeasured and short: each step reaches one more cell past the last.
                _ if f < target => s + reach + (s - self.offsets[k]).abs(),
                _ => s - reach,
            },
        }
    }
}

/// `plates` with each force-driven one fixed at its offset along its normal (whatever the
/// load factor), the others as given.
fn placed(plates: &[RigidPlate], offsets: &[f64]) -> Vec<RigidPlate> {
    plates
        .iter()
        .zip(offsets)
        .map(|(p, &s)| match p.force {
            Some(_) => {
                let at = std::array::from_fn(|a| p.start[a] + s * p.normal[a]);
                RigidPlate { start: at, end: at, ..*p }
            }
            None => *p,
        })
        .collect()
}

impl HyperBody {
    /// One step of a timed solve with its force-driven plates moved until each one's
    /// contact force is its force times the load factor (see the module docs); a step
    /// without such plates is [`HyperBody::time_step`]. The relative residual (or force
    /// error) where it stopped when it failed: the caller cuts the step.
    pub(super) fn driven_step(
        &mut self,
        run: &mut Progress,
        external: &[f64],
        plates: &[RigidPlate],
        drive: &mut PlateDrive,
        duals: &mut Multipliers,
    ) -> crate::error::Result<Option<f64>> {
        if plates.iter().all(|p| p.force.is_none()) {
            return self.time_step(run, external, plates, duals);
        }
        let reach = self.model.grid.cell_size();
        let scale = plates.iter().filter_map(|p| p.force).fold(0.0, f64::max);
        let start_duals = duals.clone();
        let mut brackets = vec![Bracket::default(); plates.len()];
        let mut trial = drive.first_trial(plates, reach);
        let mut error = 0.0;
        for _ in 0..MAX_PLATE_FORCE_TRIALS {
            let at = placed(plates, &trial);
            *duals = start_duals.clone();
            if let Some(residual) = self.time_step(run, external, &at, duals)? {
                return Ok(Some(residual));
            }
            let forces = self.plate_forces(&run.x, &at, &duals.contact, run.t);
            error = 0.0;
            let mut next = trial.clone();
            for (k, plate) in plates.iter().enumerate() {
                let Some(full) = plate.force else { continue };
                let (s, f, target) = (trial[k], forces[k], full * run.t);
                let miss = (f - target).abs() / full.max(scale).max(f64::MIN_POSITIVE);
                error = f64::max(error, miss);
                if miss <= PLATE_FORCE_TOLERANCE {
                    continue;
                }
                let bracket = &mut brackets[k];
                if f < target {
                    bracket.below =
                        Some((s, f)).filter(|_| bracket.below.is_none_or(|b| s > b.0)).or(bracket.below);
                } else {
                    bracket.above =
                        Some((s, f)).filter(|_| bracket.above.is_none_or(|b| s < b.0)).or(bracket.above);
                }
                next[k] = drive.next_offset(k, bracket, s, f, target, reach);
            }
            if error <= PLATE_FORCE_TOLERANCE {
                for (k, b) in brackets.iter().enumerate() {
                    if let (Some((s0, f0)), Some((s1, f1))) = (b.below, b.above)
                        && f1 > f0
                        && f0 > 0.0
                    {
                        drive.compliance[k] = Some((s1 - s0) / (f1 - f0));
                    }
                }
                drive.offsets = trial;
                return Ok(None);
            }
            trial = next;
        }
        Ok(Some(error))
    }
}
