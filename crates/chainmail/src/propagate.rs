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
        let sponsor = self.sponsor_flags(moves)?;
        let time_saving = match options.scheme {
            Scheme::Auto => material.supports_time_saving() && self.same_displacement(moves),
            Scheme::TimeSaving => true,
            Scheme::Exhaustive => false,
        };
        let n = self.len();
        let max_processed = if options.max_processed == 0 { 64 * n } else { options.max_processed };
        let mut wave = Wave::new(sponsor, options.tolerance * self.spacing(), time_saving);
        for &(e, target) in moves {
            if self.pos[e] != target {
                wave.moved[e] = true;
                self.pos[e] = target;
            }
            wave.enqueue(e);
        }
        if time_saving {
            self.time_saving_wave(material, &mut wave)?;
        } else {
            self.exhaustive_waves(material, &mut wave, max_processed)?;
        }
        Ok(wave.finish())
    }

    /// Which elements are sponsors (listed in `moves`), after checking every move: index in
    /// range, finite target, no element listed twice.
    fn sponsor_flags(&self, moves: &[(usize, [f64; 3])]) -> Result<Vec<bool>> {
        let mut sponsor = vec![false; self.len()];
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
        Ok(sponsor)
    }

    /// The time-saving scheme: each element is moved at most once, hence queued and
    /// processed at most once; neighbours that already moved are not checked again.
    fn time_saving_wave<M: Material + ?Sized>(&mut self, material: &M, wave: &mut Wave) -> Result<()> {
        while let Some(i) = wave.queue.pop_front() {
            wave.report.processed += 1;
            wave.count[i] += 1;
            for j in self.neighbors[i] {
                if j == NONE {
                    continue;
                }
                let j = j as usize;
                if wave.sponsor[j] || wave.moved[j] {
                    continue;
                }
                wave.report.checks += 1;
                let cbr = material.cbr(i, j, self.rest_offset(i, j))?;
                let rel = sub(self.pos[j], self.pos[i]);
                if cbr.violation(rel) <= wave.tol {
                    continue;
                }
                if self.inv_mass[j] == 0.0 {
                    wave.report.blocked += 1;
                    continue;
                }
                self.pos[j] = add(self.pos[i], cbr.clamp(rel));
                wave.moved[j] = true;
                wave.queue.push_back(j);
            }
        }
        Ok(())
    }

    /// The exhaustive scheme: label-correcting propagation, axis by axis, until no link is
    /// violated or `max_processed` elements were processed. An element is queued again
    /// whenever it moves again.
    fn exhaustive_waves<M: Material + ?Sized>(
        &mut self,
        material: &M,
        wave: &mut Wave,
        max_processed: usize,
    ) -> Result<()> {
        let n = self.len();
        let mut order = MoveOrder {
            immovable: (0..n).map(|e| wave.sponsor[e] || self.inv_mass[e] == 0.0).collect(),
            stamp: vec![[0u64; 3]; n],
            clock: 0,
        };
        while let Some(i) = wave.queue.pop_front() {
            wave.in_queue[i] = false;
            if wave.report.processed >= max_processed {
                wave.report.converged = false;
                break;
            }
            wave.report.processed += 1;
            wave.count[i] += 1;
            let mut requeue_i = false;
            for j in self.neighbors[i] {
                if j != NONE {
                    requeue_i |= self.resolve_link(material, wave, &mut order, i, j as usize)?;
                }
            }
            if requeue_i {
                wave.enqueue(i);
            }
        }
        Ok(())
    }

    /// Checks the link from the processed element `i` to its neighbour `j` and, if it is
    /// violated, resolves it axis by axis: of the two ends, the one that moved last along
    /// that axis leads and the other follows; sponsors and fixed elements always lead. A
    /// following `j` is queued. Returns whether `i` followed (and must be queued again).
    fn resolve_link<M: Material + ?Sized>(
        &mut self,
        material: &M,
        wave: &mut Wave,
        order: &mut MoveOrder,
        i: usize,
        j: usize,
    ) -> Result<bool> {
        let tol = wave.tol;
        wave.report.checks += 1;
        let cbr = material.cbr(i, j, self.rest_offset(i, j))?;
        let rel = sub(self.pos[j], self.pos[i]);
        if cbr.violation(rel) <= tol {
            return Ok(false);
        }
        if order.immovable[i] && order.immovable[j] {
            wave.report.blocked += 1;
            return Ok(false);
        }
        let back = if order.immovable[j] { Some(material.cbr(j, i, self.rest_offset(j, i))?) } else { None };
        let (mut i_moved, mut j_moved) = (false, false);
        for a in 0..3 {
            if rel[a] >= cbr.min[a] - tol && rel[a] <= cbr.max[a] + tol {
                continue;
            }
            order.clock += 1;
            if let Some(back) = &back {
                // `i` follows the immovable `j` along this axis.
                let r = self.pos[i][a] - self.pos[j][a];
                self.pos[i][a] = self.pos[j][a] + r.max(back.min[a]).min(back.max[a]);
                order.stamp[i][a] = order.clock;
                wave.moved[i] = true;
                i_moved = true;
            } else if !order.immovable[i] && order.stamp[j][a] > order.stamp[i][a] {
                // `j` moved along this axis after `i`: `j` leads (it is queued).
                wave.enqueue(j);
            } else {
                self.pos[j][a] = self.pos[i][a] + rel[a].max(cbr.min[a]).min(cbr.max[a]);
                order.stamp[j][a] = order.clock;
                wave.moved[j] = true;
                j_moved = true;
            }
        }
        if j_moved {
            wave.enqueue(j);
        }
        Ok(i_moved)
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

/// Book-keeping of one [`Lattice::propagate`] call.
struct Wave {
    /// Elements listed in the moves.
    sponsor: Vec<bool>,
    /// Elements whose position changed.
    moved: Vec<bool>,
    in_queue: Vec<bool>,
    /// Number of times each element was processed.
    count: Vec<usize>,
    queue: VecDeque<usize>,
    /// Absolute tolerance of a CBR violation.
    tol: f64,
    report: PropagationReport,
}

impl Wave {
    fn new(sponsor: Vec<bool>, tol: f64, time_saving: bool) -> Self {
        let n = sponsor.len();
        Self {
            moved: vec![false; n],
            in_queue: vec![false; n],
            count: vec![0; n],
            queue: VecDeque::new(),
            sponsor,
            tol,
            report: PropagationReport { time_saving, converged: true, ..Default::default() },
        }
    }

    /// Queues `e` unless it is queued already.
    fn enqueue(&mut self, e: usize) {
        if !self.in_queue[e] {
            self.in_queue[e] = true;
            self.queue.push_back(e);
        }
    }

    /// The report, with the counts over elements filled in.
    fn finish(self) -> PropagationReport {
        let mut report = self.report;
        report.moved = self.moved.iter().filter(|&&m| m).count();
        report.max_processed_per_element = self.count.iter().copied().max().unwrap_or(0);
        report
    }
}

/// Which end of a violated link leads in the exhaustive scheme.
struct MoveOrder {
    /// Sponsors and fixed elements: they always lead.
    immovable: Vec<bool>,
    /// Per element and axis, the clock value of its last move along that axis (0: never).
    stamp: Vec<[u64; 3]>,
    clock: u64,
}
