//! The hyperelastic body at two rates: frames answered on the latest linearization, the
//! linearization refreshed by Newton's iterations on the side.
//!
//! A frame applies the pending holds to the current [`Linearization`]
//! (`fibfluid_fem::hyper`'s tracking: one solve on the kept tangent factor and the
//! capacitance system of the held vertices, exactly as the linear body's frame), so it
//! costs what a linear frame costs and never waits for a factorization. A refresh is one
//! iteration of the equilibrium for the holds the frame asked ([`HyperBody::track_with`]:
//! the step, shortened while it would invert a cell). A Newton refresh then assembles and
//! factors the tangent at the step's end and computes the held vertices' columns there; a
//! chord refresh keeps the factor and its columns and moves only the state and its force
//! (a few to tens of times cheaper). The cadence ([`ChordBudget`]): on the refresh thread,
//! chord refreshes until they have cost as much time as the last Newton one (at most
//! [`MAX_BALANCED_CHORDS`]), in the frame loop at most [`MAX_CHORD_REFRESHES`]; either
//! only with the holds within reach, a step within a cell, and while each chord step
//! halves the one before. Holding a tool still, the frames converge
//! to the batch hyperelastic answer for the same holds (a Newton refresh confirms it); with
//! the tool moving, a frame is the linear response about a state at most one refresh old.
//!
//! [`RefreshMode::Background`] runs the refreshes on a second thread, back to back while
//! the holds change or the last step was not converged, and swaps each new linearization
//! in at the start of the next frame (a channel; the frame never blocks). A refresh that
//! fails (the step would invert the body) keeps the last good linearization and says so in
//! [`LinearizationStatus::failure`]. [`RefreshMode::EveryFrames`] refreshes in the frame
//! loop before every `k`-th frame, so that two replays of the same path give the same
//! answers (the probe's schedule).

use std::sync::Mutex;
use std::sync::mpsc::{self, Receiver, Sender};
use std::time::Instant;

use fibfluid_fem::hyper::{HyperBody, Linearization, Tangent, TrackStep};
use fibfluid_fem::{FemHold, FemStats, Loads};
use fibfluid_geometry::Vec3;
use fibfluid_sim::{Method, Model};

use crate::holds::fem_reactions;
use crate::{Holds, InteractError, Interactive, LinearizationStatus, PushRule, Result, Surface};

/// A refresh whose full step moved no surface vertex more than this fraction of a cell
/// leaves the linearization converged: no new refresh is asked until the holds change.
pub const CONVERGED_STEP: f64 = 1e-9;

/// Below this fraction of a cell, a step that is not at most half the one before has
/// reached rounding (Newton's steps shrink quadratically until they do): converged too.
pub const ROUNDING_STEP: f64 = 1e-6;

/// The largest `k` [`RefreshMode::Scheduled`] picks.
pub const MAX_SCHEDULED_EVERY: u64 = 1000;

/// Refreshes that keep the factor ([`Tangent::Keep`], chord iterations) between two that
/// factor the tangent, at most, in the frame loop and for [`ChordBudget::Balanced`]
/// there: a chord refresh costs a force evaluation and two solves,
/// a refactorization the tangent's assembly, its factorization and the held vertices'
/// columns (on the bundled liver 0.016 s against 0.17 s), so the frames' state
/// follows the tool several times as often, on a tangent at most this many refreshes old.
pub const MAX_CHORD_REFRESHES: usize = 4;

/// A chord refresh for unchanged holds whose step is more than this fraction of the step
/// before it converges too slowly: the next refresh factors the tangent.
pub const CHORD_CONTRACTION: f64 = 0.5;

/// The most chord refreshes [`ChordBudget::Balanced`] runs between two refactorizations.
pub const MAX_BALANCED_CHORDS: usize = 32;

/// What the chord refreshes since the last refactorization have spent.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct ChordSpent {
    /// Chord refreshes made since it.
    pub chords: usize,
    /// Their seconds.
    pub chord_seconds: f64,
    /// Seconds of the last refactorization (0: none timed yet).
    pub refactor_seconds: f64,
}

/// How many chord refreshes run between two refactorizations.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ChordBudget {
    /// At most this many (0: every refresh is a Newton iteration).
    AtMost(usize),
    /// On the refresh thread ([`RefreshMode::Background`]), chord refreshes until they have
    /// taken as long as the last refactorization did (at most [`MAX_BALANCED_CHORDS`]): the
    /// thread spends about half its time factoring whatever the body's size, where a
    /// refactorization costs from ten times a chord refresh (the bundled liver) to tens of
    /// times (a finer grid). In the frame loop, whose replays must be reproducible (not
    /// timed), [`MAX_CHORD_REFRESHES`].
    #[default]
    Balanced,
}

impl ChordBudget {
    /// Whether one more chord refresh is allowed after `spent`, on the refresh thread
    /// (`on_thread`) or in the frame loop. Balanced on the thread: while the chords have
    /// taken less time than the last refactorization (none before the first one is timed)
    /// and number fewer than [`MAX_BALANCED_CHORDS`].
    pub fn allows_chord(self, spent: ChordSpent, on_thread: bool) -> bool {
        match self {
            ChordBudget::AtMost(n) => spent.chords < n,
            ChordBudget::Balanced if on_thread => {
                spent.chords < MAX_BALANCED_CHORDS && spent.chord_seconds < spent.refactor_seconds
            }
            ChordBudget::Balanced => spent.chords < MAX_CHORD_REFRESHES,
        }
    }
}

/// When the linearization is refreshed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum RefreshMode {
    /// On a second thread, back to back, swapped in between frames (the viewer, Python).
    #[default]
    Background,
    /// In the frame loop, before every `k`-th frame (`k >= 1`): reproducible.
    EveryFrames(u64),
    /// In the frame loop, every `k` frames with `k` from the body's counts: the frames one
    /// refresh's factorization costs, `factor flops / (4 x factor values)` (a frame is
    /// about two triangular solves), so the schedule is what a second core would keep up
    /// with, and reproducible.
    Scheduled,
    /// In the frame loop, before every frame, until Newton has converged for its holds (at
    /// most [`MAX_CONVERGE_ITERATIONS`]): each frame is the converged nonlinear answer (the
    /// reference `compare` measures the other bodies against), at a refactorization or more
    /// per frame.
    Converged,
}

/// Newton iterations a [`RefreshMode::Converged`] frame runs at most; a frame still
/// unconverged after them says so in [`LinearizationStatus::failure`].
pub const MAX_CONVERGE_ITERATIONS: usize = 50;

/// A tool's holds as the tracking takes them.
#[derive(Clone, Debug, PartialEq, Default)]
struct Request {
    pushes: Vec<(usize, Vec3)>,
    holds: Vec<(usize, FemHold)>,
    frame: u64,
    /// Fail instead of refreshing ([`HyperInteractive::fail_next_refreshes`]).
    fail: bool,
}

impl Request {
    /// Whether `other` asks the same pushes and holds (targets included), whatever frame.
    fn same_tools(&self, other: &Request) -> bool {
        self.holds == other.holds && self.pushes == other.pushes
    }
}

/// Whether each refresh keeps the factor or makes a new one: a chord refresh while the
/// factor is fresh enough and the chord steps contract, else a refactorization.
#[derive(Debug, Default)]
struct Cadence {
    /// Chord refreshes allowed between two refactorizations (`AtMost(0)` in
    /// [`RefreshMode::Converged`]: Newton's own iterations).
    budget: ChordBudget,
    /// On the refresh thread (where a balanced budget is timed).
    on_thread: bool,
    /// Seconds of the last refresh that factored the tangent.
    refactor_seconds: f64,
    /// Seconds of the chord refreshes since it.
    chord_seconds: f64,
    /// The last refresh's request and full step (m).
    last: Option<(Request, f64)>,
    /// The last refresh was a chord step that contracted less than
    /// [`CHORD_CONTRACTION`].
    slow: bool,
}

impl Cadence {
    /// The cadence of `budget`, on the refresh thread (`on_thread`) or in the frame loop.
    fn of_budget(budget: ChordBudget, on_thread: bool) -> Self {
        Self { budget, on_thread, ..Self::default() }
    }

    /// How the next refresh from `current` for `request` treats the tangent. A factor
    /// made with the holds' penalty is kept only for the same rows (its springs belong to
    /// the holds it was made for).
    fn tangent(&self, current: &Linearization, request: &Request) -> Tangent {
        let rows_kept = self.last.as_ref().is_some_and(|(last, _)| same_rows(&last.holds, &request.holds));
        let spent = ChordSpent {
            chords: current.chord_steps(),
            chord_seconds: self.chord_seconds,
            refactor_seconds: self.refactor_seconds,
        };
        let penalized = current.hold_penalty() > 0.0 && !rows_kept;
        if self.slow || penalized || !self.budget.allows_chord(spent, self.on_thread) {
            Tangent::Refactor
        } else {
            Tangent::Keep
        }
    }

    /// Records a finished refresh for `request` that took `seconds`.
    fn record(&mut self, request: &Request, step: &TrackStep, seconds: f64) {
        if step.refactored {
            self.refactor_seconds = seconds;
            self.chord_seconds = 0.0;
        } else {
            self.chord_seconds += seconds;
        }
        let same = self.last.as_ref().is_some_and(|(r, _)| r.same_tools(request));
        let previous = self.last.as_ref().map_or(f64::INFINITY, |last| last.1);
        self.slow = !step.refactored && same && step.step > CHORD_CONTRACTION * previous;
        self.last = Some((request.clone(), step.step));
    }

    /// Forgets the last refresh (the linearization went back to the body's own one).
    fn restart(&mut self) {
        self.last = None;
        self.slow = false;
        self.chord_seconds = 0.0;
    }
}

/// Whether two sets of holds make the same constraint rows (the same vertices, held the
/// same way along the same normals), whatever their targets.
fn same_rows(a: &[(usize, FemHold)], b: &[(usize, FemHold)]) -> bool {
    let row = |h: &(usize, FemHold)| match h.1 {
        FemHold::At(_) => (h.0, None),
        FemHold::Along { normal, .. } => (h.0, Some(normal)),
    };
    a.len() == b.len() && a.iter().map(row).eq(b.iter().map(row))
}

/// What a refresh produced.
enum Outcome {
    Done {
        linearization: Box<Linearization>,
        step: f64,
        /// Whether it factored the tangent (else it kept the factor: a chord step).
        refactored: bool,
        frame: u64,
        seconds: f64,
    },
    Failed {
        message: String,
        frame: u64,
    },
    /// The thread's latest linearization with the columns of newly held vertices made (sent
    /// before the refresh for those holds): the frames answer the new holds from it at once.
    Prepared(Box<Linearization>),
}

/// What the frames send the refresh thread.
enum Message {
    /// Refresh for these holds.
    Refresh(Request),
    /// Drop a linearization the frames no longer use (its factor is freed off the frame
    /// thread).
    Retire(#[allow(dead_code, reason = "held only to be dropped on the refresh thread")] Linearization),
    /// Start the next refresh from this linearization (the body's own equilibrium).
    Restart(Linearization),
}

/// The refresh thread's ends.
struct Worker {
    requests: Sender<Message>,
    /// Behind a lock only so the body is `Sync` (Python shares it); the frames alone read it.
    outcomes: Mutex<Receiver<Outcome>>,
    busy: bool,
}

/// Where refreshes run.
enum Refresher {
    Inline { body: Box<HyperBody>, cadence: Cadence, every: u64, converge: bool },
    Thread(Worker),
}

/// The latest linearization and what the frames know of it.
struct Current {
    linearization: Linearization,
    /// The frame whose holds it was made for.
    frame: u64,
    since: Instant,
    /// The full step of the refresh that made it (m).
    step: f64,
    /// Whether that step says Newton has converged for its holds.
    converged: bool,
    /// Whether it is the body's own equilibrium, made at setup.
    at_base: bool,
    /// The grid's cell size (m), the scale of the steps.
    cell_size: f64,
    /// The linearization it replaced, to be dropped off the frame thread.
    retired: Option<Linearization>,
    refreshes: u64,
    /// Refreshes that factored the tangent.
    refactorizations: u64,
    refresh_seconds: f64,
    failure: Option<String>,
}

/// A neo-Hookean finite-element body answered at frame rate (see the module docs).
pub struct HyperInteractive {
    refresher: Refresher,
    current: Current,
    /// The linearization at the body's own equilibrium (setup).
    base: Linearization,
    /// The frame the body last went back to its own equilibrium (older refreshes are
    /// stale).
    reset_frame: u64,
    loads: Loads,
    cell_size: f64,
    holds: Holds,
    /// The holds of the last refresh asked.
    asked: Option<Request>,
    /// Rest shape and current frame.
    surface: Surface,
    status: LinearizationStatus,
    stats: FemStats,
    newton_iteration_seconds: f64,
    setup_seconds: f64,
    /// Refreshes still to fail ([`HyperInteractive::fail_next_refreshes`]).
    failing: u32,
}

impl std::fmt::Debug for HyperInteractive {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HyperInteractive")
            .field("frame", &self.surface.frame)
            .field("status", &self.status)
            .finish()
    }
}

impl HyperInteractive {
    /// Builds the model's neo-Hookean body (refused from counts above the memory budget),
    /// solves its own loads by Newton's method as the starting state, linearizes there and
    /// starts the refreshes as `mode` says.
    ///
    /// Errors: a model with plates or scene grasps, without a tissue, or whose own loads
    /// Newton cannot reach. `EveryFrames(0)` refreshes every frame, as `EveryFrames(1)`.
    pub fn new(model: &Model, max_memory: Option<u64>, mode: RefreshMode) -> fibfluid_sim::Result<Self> {
        Self::with_chord_budget(model, max_memory, mode, ChordBudget::Balanced)
    }

    /// [`HyperInteractive::new`] with at most `chords` chord refreshes between two
    /// refactorizations (0: every refresh is a Newton iteration).
    ///
    /// Errors: those of [`HyperInteractive::new`].
    pub fn with_chord_refreshes(
        model: &Model,
        max_memory: Option<u64>,
        mode: RefreshMode,
        chords: usize,
    ) -> fibfluid_sim::Result<Self> {
        Self::with_chord_budget(model, max_memory, mode, ChordBudget::AtMost(chords))
    }

    /// [`HyperInteractive::new`] with the chord refreshes `budget` allows between two
    /// refactorizations.
    ///
    /// Errors: those of [`HyperInteractive::new`].
    pub fn with_chord_budget(
        model: &Model,
        max_memory: Option<u64>,
        mode: RefreshMode,
        budget: ChordBudget,
    ) -> fibfluid_sim::Result<Self> {
        let start = Instant::now();
        let scene = model.display_name();
        let tissue = fibfluid_sim::fem_run::tissue_of(model)?;
        let limit = fibfluid_sim::memory_budget(max_memory);
        let estimate = fibfluid_sim::fem_run::estimate(model, limit)?;
        let (mut body, solution) = tool_body(model, &tissue, limit)?;
        let stats = fibfluid_sim::hyper_run::fem_stats(&body, &solution.stats);
        let n = &solution.stats;
        let newton_iteration_seconds =
            (n.assembly_seconds + n.factor_seconds + n.solve_seconds) / n.newton_iterations.max(1) as f64;
        let failed = |source| fibfluid_sim::Error::Fem { scene: scene.clone(), source };
        let loads = fibfluid_sim::fem_run::full_loads(model);
        let state = body.state_of(&solution.node_displacements).map_err(failed)?;
        let linearization = body.linearize(state, &loads).map_err(failed)?;
        let cell_size = body.grid().cell_size();
        let scheduled = (estimate.factor_flops / (4.0 * stats.factor_nonzeros.max(1) as f64)).ceil();
        let refresher = match mode {
            RefreshMode::EveryFrames(every) => Refresher::Inline {
                body: Box::new(body),
                cadence: Cadence::of_budget(budget, false),
                every: every.max(1),
                converge: false,
            },
            RefreshMode::Scheduled => Refresher::Inline {
                body: Box::new(body),
                cadence: Cadence::of_budget(budget, false),
                every: (scheduled as u64).clamp(1, MAX_SCHEDULED_EVERY),
                converge: false,
            },
            RefreshMode::Converged => Refresher::Inline {
                body: Box::new(body),
                cadence: Cadence::of_budget(ChordBudget::AtMost(0), false),
                every: 1,
                converge: true,
            },
            RefreshMode::Background => {
                Refresher::Thread(spawn_worker(body, linearization.clone(), loads.clone(), budget))
            }
        };
        let holds = Holds::of_model(model, PushRule::Anywhere);
        let mut surface = Surface::at_rest(model.rest_positions());
        surface.set_field(solution.surface_displacements);
        let current = Current {
            linearization,
            frame: 0,
            since: Instant::now(),
            step: 0.0,
            converged: true,
            at_base: true,
            cell_size,
            retired: None,
            refreshes: 0,
            refactorizations: 0,
            refresh_seconds: 0.0,
            failure: None,
        };
        Ok(Self {
            refresher,
            base: current.linearization.clone(),
            reset_frame: 0,
            current,
            loads,
            cell_size,
            holds,
            asked: Some(Request::default()),
            surface,
            status: LinearizationStatus::default(),
            stats,
            newton_iteration_seconds,
            setup_seconds: start.elapsed().as_secs_f64(),
            failing: 0,
        })
    }

    /// Seconds of the setup (voxelization, the Newton solve of the body's own loads, the
    /// first linearization).
    pub fn setup_seconds(&self) -> f64 {
        self.setup_seconds
    }

    /// The grid's sizes, and the timings of the Newton solve of the body's own loads.
    pub fn stats(&self) -> FemStats {
        self.stats
    }

    /// Seconds of one Newton iteration of that batch solve (its assembly, factorization
    /// and solve seconds over its iterations): what a refresh is measured against.
    pub fn newton_iteration_seconds(&self) -> f64 {
        self.newton_iteration_seconds
    }

    /// Frames between two refreshes in the frame loop (`None`: on a second thread).
    pub fn refresh_every(&self) -> Option<u64> {
        match &self.refresher {
            Refresher::Inline { every, .. } => Some(*every),
            Refresher::Thread(_) => None,
        }
    }

    /// Makes the next `count` refreshes fail as a refresh that cannot step does, without
    /// running them: the frames keep the last good linearization and say so in
    /// [`LinearizationStatus::failure`]. For testing what a caller does with a failed
    /// refresh (a refresh of a valid state rarely fails: its step is halved until no cell
    /// inverts). Only with the `testing` feature.
    #[cfg(feature = "testing")]
    pub fn fail_next_refreshes(&mut self, count: u32) {
        self.failing = count;
    }

    /// The pending holds as the tracking takes them, for frame `frame`.
    fn request(&self, frame: u64) -> Request {
        let (holds, pushes) = self.holds.split();
        Request { pushes, holds, frame, fail: false }
    }

    /// `request` as a refresh is asked for it: failing while
    /// [`HyperInteractive::fail_next_refreshes`] says so.
    fn asking(&mut self, request: &Request) -> Request {
        let fail = self.failing > 0;
        self.failing = self.failing.saturating_sub(1);
        Request { fail, ..request.clone() }
    }

    /// Whether a refresh is worth asking for `request`: its holds differ from the last
    /// asked, or the last refresh's step was not converged.
    fn wants_refresh(&self, request: &Request) -> bool {
        let same = self.asked.as_ref().is_some_and(|a| a.same_tools(request));
        !same || !self.current.converged
    }

    /// Takes in what the refresh thread finished (the newest linearization wins).
    fn poll(&mut self) {
        let Refresher::Thread(worker) = &mut self.refresher else { return };
        let outcomes = worker.outcomes.get_mut().unwrap_or_else(std::sync::PoisonError::into_inner);
        while let Ok(outcome) = outcomes.try_recv() {
            let frame = match &outcome {
                Outcome::Done { frame, .. } | Outcome::Failed { frame, .. } => Some(*frame),
                Outcome::Prepared(_) => None,
            };
            if frame.is_some() {
                worker.busy = false;
            }
            // A refresh asked before the body went back to its own equilibrium is stale.
            if frame.is_none_or(|f| f >= self.reset_frame) {
                self.current.accept(outcome);
            }
        }
    }

    /// With nothing held or pushed, the answer is the body's own equilibrium: the
    /// linearization made there at setup comes back at once (no Newton iteration), for the
    /// frames and the refresh thread alike.
    fn return_to_base(&mut self, request: &Request) {
        if !(request.holds.is_empty() && request.pushes.is_empty()) || self.current.at_base {
            return;
        }
        let retired = std::mem::replace(&mut self.current.linearization, self.base.clone());
        self.current.retired = Some(retired);
        self.current.at_base = true;
        self.current.converged = true;
        self.current.step = 0.0;
        self.current.frame = request.frame;
        self.current.since = Instant::now();
        self.reset_frame = request.frame;
        match &mut self.refresher {
            Refresher::Thread(worker) => {
                let _ = worker.requests.send(Message::Restart(self.base.clone()));
            }
            Refresher::Inline { cadence, .. } => cadence.restart(),
        }
        self.asked = Some(request.clone());
    }

    /// Refreshes inline (every `k`-th frame; to convergence when asked) or asks the thread
    /// (when idle).
    fn schedule(&mut self, request: &Request) {
        if !self.wants_refresh(request) {
            return;
        }
        let due = match &self.refresher {
            Refresher::Inline { every, .. } => self.surface.frame.is_multiple_of(*every),
            Refresher::Thread(worker) => !worker.busy,
        };
        if !due {
            return;
        }
        let asked = self.asking(request);
        match &mut self.refresher {
            Refresher::Inline { body, cadence, converge, .. } => {
                let iterations = if *converge { MAX_CONVERGE_ITERATIONS } else { 1 };
                for _ in 0..iterations {
                    let outcome =
                        refresh(body, cadence, &mut self.current.linearization, &self.loads, &asked);
                    let failed = matches!(outcome, Outcome::Failed { .. });
                    self.current.accept(outcome);
                    if failed || self.current.converged {
                        break;
                    }
                }
                if *converge && !self.current.converged {
                    self.current.failure = Some(format!(
                        "Newton did not converge in {MAX_CONVERGE_ITERATIONS} iterations at frame {} (last step {:.3e} m)",
                        request.frame, self.current.step
                    ));
                }
                self.current.retired = None;
                self.asked = Some(request.clone());
            }
            Refresher::Thread(worker) => {
                if let Some(old) = self.current.retired.take() {
                    // A closed channel (the thread gone) drops it here instead.
                    let _ = worker.requests.send(Message::Retire(old));
                }
                if worker.requests.send(Message::Refresh(asked)).is_ok() {
                    worker.busy = true;
                    self.asked = Some(request.clone());
                }
            }
        }
    }
}

impl Current {
    /// Swaps in a finished refresh or a prepared linearization, or records a refresh's
    /// failure (keeping the linearization).
    fn accept(&mut self, outcome: Outcome) {
        match outcome {
            Outcome::Done { linearization, step, refactored, frame, seconds } => {
                let retired = std::mem::replace(&mut self.linearization, *linearization);
                self.retired = Some(retired);
                self.at_base = false;
                // Convergence and rounding are told by Newton's steps only: a chord step
                // shrinks linearly, and the cadence ends a run of them with a Newton one.
                let stalled = step <= ROUNDING_STEP * self.cell_size && step > 0.5 * self.step;
                self.refactorizations += u64::from(refactored);
                self.converged = refactored && (step <= CONVERGED_STEP * self.cell_size || stalled);
                self.frame = frame;
                self.since = Instant::now();
                self.step = step;
                self.refreshes += 1;
                self.refresh_seconds = seconds;
                self.failure = None;
            }
            Outcome::Prepared(prepared) => {
                // Taken only onto the state it was made from (not a stale one).
                if prepared.same_state(&self.linearization) {
                    let retired = std::mem::replace(&mut self.linearization, *prepared);
                    self.retired = Some(retired);
                }
            }
            Outcome::Failed { message, frame } => {
                // Not converged for the holds asked: the next frame asks again.
                self.converged = false;
                self.failure = Some(format!(
                    "the refresh for frame {frame} failed ({message}); frames use the linearization of frame {}",
                    self.frame
                ));
            }
        }
    }
}

/// One tracking iteration from `current` for `request`, its tangent as `cadence` says,
/// timed.
fn refresh(
    body: &mut HyperBody,
    cadence: &mut Cadence,
    current: &mut Linearization,
    loads: &Loads,
    request: &Request,
) -> Outcome {
    let start = Instant::now();
    if request.fail {
        let message = "failed as asked by fail_next_refreshes".to_string();
        return Outcome::Failed { message, frame: request.frame };
    }
    let tangent = cadence.tangent(current, request);
    match body.track_with(current, loads, &request.pushes, &request.holds, tangent) {
        Ok(s) => {
            let seconds = start.elapsed().as_secs_f64();
            cadence.record(request, &s, seconds);
            Outcome::Done {
                refactored: s.refactored,
                linearization: Box::new(s.linearization),
                step: s.step,
                frame: request.frame,
                seconds,
            }
        }
        Err(e) => Outcome::Failed { message: e.to_string(), frame: request.frame },
    }
}

/// `linearization` with the columns of `request`'s holds made, when it lacks some (`None`
/// when it has them all, or when a hold cannot be answered: the refresh then says why).
fn prepare(linearization: &Linearization, request: &Request) -> Option<Linearization> {
    if request.fail || request.holds.iter().all(|(v, _)| linearization.has_columns_for(*v)) {
        return None;
    }
    let mut prepared = linearization.clone();
    prepared.respond_at_surface(&request.pushes, &request.holds).ok()?;
    Some(prepared)
}

/// Starts the refresh thread: it answers each request (the newest waiting) with one
/// tracking iteration from its last linearization, on one thread of its own (the frames
/// keep the other cores), and ends when the body is dropped.
fn spawn_worker(
    mut body: HyperBody,
    mut linearization: Linearization,
    loads: Loads,
    budget: ChordBudget,
) -> Worker {
    let (requests, inbox) = mpsc::channel::<Message>();
    let (outbox, outcomes) = mpsc::channel();
    std::thread::spawn(move || {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().ok();
        let mut cadence = Cadence::of_budget(budget, true);
        while let Ok(first) = inbox.recv() {
            let mut request = match first {
                Message::Refresh(r) => r,
                Message::Retire(_) => continue,
                Message::Restart(base) => {
                    linearization = base;
                    cadence.restart();
                    continue;
                }
            };
            while let Ok(newer) = inbox.try_recv() {
                match newer {
                    Message::Refresh(r) => request = r,
                    Message::Restart(base) => {
                        linearization = base;
                        cadence.restart();
                    }
                    Message::Retire(_) => {}
                }
            }
            if let Some(prepared) = prepare(&linearization, &request) {
                linearization = prepared.clone();
                if outbox.send(Outcome::Prepared(Box::new(prepared))).is_err() {
                    break;
                }
            }
            let mut run = || refresh(&mut body, &mut cadence, &mut linearization, &loads, &request);
            let outcome = match &pool {
                Some(pool) => pool.install(run),
                None => run(),
            };
            if let Outcome::Done { linearization: made, .. } = &outcome {
                linearization = (**made).clone();
            }
            if outbox.send(outcome).is_err() {
                break;
            }
        }
    });
    Worker { requests, outcomes: Mutex::new(outcomes), busy: false }
}

/// The model's hyperelastic body for a tool to hold (its regions; the scene's grasps are
/// left to batch runs, as `ineffective_interactive` says: the tool grasps), with its own
/// loads solved as the starting state.
///
/// Errors: a model with plates (named), and those of the build and the Newton solve.
fn tool_body(
    model: &Model,
    tissue: &fibfluid_sim::Tissue,
    limit: u64,
) -> fibfluid_sim::Result<(HyperBody, fibfluid_fem::hyper::HyperSolution)> {
    fibfluid_sim::fem_run::refuse_plates(model)?;
    let mut log = fibfluid_sim::StageLog::default();
    let mut body = fibfluid_sim::hyper_run::build(model, tissue, &[], limit, &mut log)?;
    let solution = body
        .solve(&fibfluid_sim::fem_run::full_loads(model), &[])
        .map_err(|source| fibfluid_sim::Error::Fem { scene: model.display_name(), source })?;
    Ok((body, solution))
}

/// A frame's estimated distance from the converged answer for its holds (m), from its
/// `step` on `linearization`: Newton's next correction `step^2 / h` on a factor made at the
/// linearization's state; on a kept factor (chord steps) at least `CHORD_CONTRACTION x
/// step`, the contraction the cadence keeps them to.
fn estimated_error(step: f64, cell_size: f64, linearization: &Linearization) -> f64 {
    let newton = step * step / cell_size;
    if linearization.chord_steps() > 0 { newton.max(CHORD_CONTRACTION * step) } else { newton }
}

impl Interactive for HyperInteractive {
    fn method(&self) -> Method {
        Method::Fem
    }

    fn surface(&self) -> &Surface {
        &self.surface
    }

    fn holds(&self) -> &Holds {
        &self.holds
    }

    fn holds_mut(&mut self) -> &mut Holds {
        &mut self.holds
    }

    fn update(&mut self) -> Result<&[(usize, Vec3)]> {
        self.poll();
        let request = self.request(self.surface.frame);
        self.return_to_base(&request);
        if matches!(self.refresher, Refresher::Inline { .. }) {
            self.schedule(&request);
        }
        // On the thread, holds whose columns the linearization lacks wait for it (the
        // thread makes them first); the frame answers the others.
        let thread = matches!(self.refresher, Refresher::Thread(_));
        let lacks = |v: usize| thread && !self.current.linearization.has_columns_for(v);
        let pending: Vec<usize> = (0..request.holds.len()).filter(|&k| lacks(request.holds[k].0)).collect();
        let holds: std::borrow::Cow<'_, [(usize, FemHold)]> = if pending.is_empty() {
            std::borrow::Cow::Borrowed(&request.holds)
        } else {
            request.holds.iter().enumerate().filter(|(k, _)| !pending.contains(k)).map(|(_, h)| *h).collect()
        };
        let response = self
            .current
            .linearization
            .respond_at_surface(&request.pushes, &holds)
            .map_err(|e| InteractError::Singular { what: e.to_string() })?;
        self.surface.set_field(response.surface_displacements);
        let mut forces = response.reactions;
        // A pending hold's vertex is free this frame: no force.
        pending.iter().for_each(|&k| forces.insert(k, [0.0; 3]));
        self.surface.reactions = fem_reactions(&request.holds, forces, &request.pushes);
        self.status = LinearizationStatus {
            refreshes: self.current.refreshes,
            refactorizations: self.current.refactorizations,
            age_frames: self.surface.frame - self.current.frame.min(self.surface.frame),
            age_seconds: self.current.since.elapsed().as_secs_f64(),
            step: response.step,
            estimated_error: estimated_error(response.step, self.cell_size, &self.current.linearization),
            refresh_seconds: self.current.refresh_seconds,
            approximate: response.approximate,
            pending: pending.len(),
            failure: self.current.failure.clone(),
        };
        if thread {
            self.schedule(&request);
        }
        self.surface.frame += 1;
        Ok(&self.surface.reactions)
    }

    fn memory_bytes(&self) -> usize {
        // The frames' linearization and the refresh's (the thread's, or the next inline).
        2 * self.current.linearization.memory_bytes()
    }

    fn linearization(&self) -> Option<LinearizationStatus> {
        Some(self.status.clone())
    }
}
