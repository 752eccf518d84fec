//! Breadth-first ChainMail propagation, with and without the time-saving scheme.

use std::collections::VecDeque;

use crate::error::{ChainmailError, Result};
use fibfluid_geometry::vec3::add;

use crate::lattice::{Lattice, sub};
use crate::material::Material;

const NONE: u32 = u32::MAX;

/// Which propagation scheme [`Lattice::propagate`] uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Scheme {
    /// The time-saving scheme when [`Material::supports_time_saving`] is true, otherwise
    /// the exhaustive scheme.
    #[default]
    Auto,
    /// The paper's time-saving scheme (TSS): every element is moved at most once and
    /// processed (its neighbours checked) at most once per call; neighbours that already
    /// moved are not checked again. Exact for homogeneous TSVE materials (paper's Remarks
    /// 1–3); for other materials links may be left violated.
    TimeSaving,
    /// Without TSS: every processed element re-checks all its neighbours, including ones
    /// that already moved, and an element is queued again whenever it moves again, until no
    /// link is violated (or [`PropagationOptions::max_processed`] is reached). Axis by
    /// axis, of the two ends of a violated link the one that moved more recently along that
    /// axis leads and the other follows; sponsors and fixed elements always lead. For a push in one direction per
    /// axis (e.g. one sponsor, or a region pushed rigidly from a CBR-satisfying state) the
    /// result is the exact one: every link inside its CBR, each element moved the least.
    Exhaustive,
}

/// Options of [`Lattice::propagate`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PropagationOptions {
    /// Propagation scheme (default [`Scheme::Auto`]).
    pub scheme: Scheme,
    /// Bound on the number of element processings in the exhaustive scheme; 0 means
    /// `64 * number of elements` (default 0). The time-saving scheme never exceeds the
    /// number of elements.
    pub max_processed: usize,
    /// A link counts as violated when it lies outside its CBR by more than
    /// `tolerance * spacing` (default `1e-9`).
    pub tolerance: f64,
}

impl Default for PropagationOptions {
    fn default() -> Self {
        Self { scheme: Scheme::Auto, max_processed: 0, tolerance: 1e-9 }
    }
}

/// What one call of [`Lattice::propagate`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PropagationReport {
    /// Whether the time-saving scheme was used.
    pub time_saving: bool,
    /// Number of distinct elements whose position changed (sponsors included).
    pub moved: usize,
    /// Number of element processings (queue pops: an element's neighbours checked).
    pub processed: usize,
    /// Largest number of times a single element was processed.
    pub max_processed_per_element: usize,
    /// Number of CBR evaluations.
    pub checks: usize,
    /// Number of violated CBR checks that could not be resolved because both ends are
    /// immovable: in the time-saving scheme, a violated neighbour with zero inverse mass;
    /// in the exhaustive scheme, two sponsors, or a sponsor and a fixed element.
    pub blocked: usize,
    /// False when the exhaustive scheme stopped at `max_processed` with work left.
    pub converged: bool,
}

impl Lattice {
    /// Moves each listed element (the sponsors) to its target, then propagates: every
    /// neighbour that violates its CBR w.r.t. a moved element is moved to the nearest point
    /// of that CBR and propagates in turn, breadth first. Sponsors stay at their targets;
    /// elements with zero inverse mass never move.
    ///
    /// The time-saving scheme leaves every link inside its CBR when the material is a
    /// homogeneous TSVE material ([`Material::supports_time_saving`]), all sponsors end with
    /// the same displacement from rest (a single sponsor, or a region pushed from rest), and
    /// the lattice satisfied its CBRs before the call. [`Scheme::Auto`] picks it exactly in
    /// that case (the last condition is the caller's) and the exhaustive scheme otherwise.
    ///
    /// Errors: invalid material or options, an element index out of range, a non-finite
    /// target, an element listed twice; these are checked before anything moves.
    pub fn propagate<M: Material + ?Sized>(
        &mut self,
        material: &M,
        moves: &[(usize, [f64; 3])],
        options: &PropagationOptions,
    ) -> Result<PropagationReport> {
        material.validate(self.len())?;
        if !(options.tolerance.is_finite() && options.tolerance >= 0.0) {
            return Err(ChainmailError::InvalidParameter {
                name: "tolerance",
                reason: format!("{} is not finite and >= 0", options.tolerance),
            });
        }
        let n = self.len();
        let mut sponsor = vec![false; n];
        for (k, &(e, target)) in moves.iter().enumerate() {
            self.check_index(e)?;
            if target.iter().any(|v| !v.is_finite()) {
                return Err(ChainmailError::NonFinite { index: k });
            }
            if sponsor[e] {
                return Err(ChainmailError::DuplicateElement { index: e });
            }
            sponsor[e] = true;
        }
        let time_saving = match options.scheme {
            Scheme::Auto => material.supports_time_saving() && self.same_displacement(moves),
            Scheme::TimeSaving => true,
            Scheme::Exhaustive => false,
        };
        let max_processed = if options.max_processed == 0 { 64 * n } else { options.max_processed };
        let tol = options.tolerance * self.spacing();

        let mut report = PropagationReport { time_saving, converged: true, ..Default::default() };
        let mut moved = vec![false; n];
        let mut in_queue = vec![false; n];
        let mut count = vec![0usize; n];
        let mut queue = VecDeque::with_capacity(moves.len());
        for &(e, target) in moves {
            if self.pos[e] != target {
                moved[e] = true;
                self.pos[e] = target;
            }
            queue.push_back(e);
            in_queue[e] = true;
        }

        if time_saving {
            // Each element is moved at most once, hence queued and processed at most once;
            // neighbours that already moved are not checked again.
            while let Some(i) = queue.pop_front() {
                report.processed += 1;
                count[i] += 1;
                for j in self.neighbors[i] {
                    if j == NONE {
                        continue;
                    }
                    let j = j as usize;
                    if sponsor[j] || moved[j] {
                        continue;
                    }
                    report.checks += 1;
                    let cbr = material.cbr(i, j, self.rest_offset(i, j))?;
                    let rel = sub(self.pos[j], self.pos[i]);
                    if cbr.violation(rel) <= tol {
                        continue;
                    }
                    if self.inv_mass[j] == 0.0 {
                        report.blocked += 1;
                        continue;
                    }
                    self.pos[j] = add(self.pos[i], cbr.clamp(rel));
                    moved[j] = true;
                    queue.push_back(j);
                }
            }
        } else {
            // Label-correcting propagation, axis by axis. Of the two ends of a link violated
            // along an axis, the one that moved last along that axis leads and the other
            // follows; sponsors and fixed elements always lead. An element is queued again
            // whenever it moves again.
            let immovable: Vec<bool> = (0..n).map(|e| sponsor[e] || self.inv_mass[e] == 0.0).collect();
            let mut stamp = vec![[0u64; 3]; n];
            let mut clock = 0u64;
            while let Some(i) = queue.pop_front() {
                in_queue[i] = false;
                if report.processed >= max_processed {
                    report.converged = false;
                    break;
                }
                report.processed += 1;
                count[i] += 1;
                let mut requeue_i = false;
                for j in self.neighbors[i] {
                    if j == NONE {
                        continue;
                    }
                    let j = j as usize;
                    report.checks += 1;
                    let cbr = material.cbr(i, j, self.rest_offset(i, j))?;
                    let rel = sub(self.pos[j], self.pos[i]);
                    if cbr.violation(rel) <= tol {
                        continue;
                    }
                    if immovable[i] && immovable[j] {
                        report.blocked += 1;
                        continue;
                    }
                    let back =
                        if immovable[j] { Some(material.cbr(j, i, self.rest_offset(j, i))?) } else { None };
                    let mut j_moved = false;
                    for a in 0..3 {
                        if rel[a] >= cbr.min[a] - tol && rel[a] <= cbr.max[a] + tol {
                            continue;
                        }
                        clock += 1;
                        if let Some(back) = &back {
                            // `i` follows the immovable `j` along this axis.
                            let r = self.pos[i][a] - self.pos[j][a];
                            self.pos[i][a] = self.pos[j][a] + r.max(back.min[a]).min(back.max[a]);
                            stamp[i][a] = clock;
                            moved[i] = true;
                            requeue_i = true;
                        } else if !immovable[i] && stamp[j][a] > stamp[i][a] {
                            // `j` moved along this axis after `i`: `j` leads (it is queued).
                            if !in_queue[j] {
                                in_queue[j] = true;
                                queue.push_back(j);
                            }
                        } else {
                            self.pos[j][a] = self.pos[i][a] + rel[a].max(cbr.min[a]).min(cbr.max[a]);
                            stamp[j][a] = clock;
                            moved[j] = true;
                            j_moved = true;
                        }
                    }
                    if j_moved && !in_queue[j] {
                        in_queue[j] = true;
                        queue.push_back(j);
                    }
                }
                if requeue_i && !in_queue[i] {
                    in_queue[i] = true;
                    queue.push_back(i);
                }
            }
        }
        report.moved = moved.iter().filter(|&&m| m).count();
        report.max_processed_per_element = count.iter().copied().max().unwrap_or(0);
        Ok(report)
    }

    /// Whether all targets are the same displacement from rest (to within 1e-12 spacing).
    fn same_displacement(&self, moves: &[(usize, [f64; 3])]) -> bool {
        let rest = self.rest_positions();
        let Some(&(e0, t0)) = moves.first() else {
            return true;
        };
        let d0 = sub(t0, rest[e0]);
        let h = self.spacing();
        moves.iter().all(|&(e, t)| {
            let d = sub(t, rest[e]);
            (0..3).all(|a| (d[a] - d0[a]).abs() <= 1e-12 * (h + d0[a].abs()))
        })
    }
}
