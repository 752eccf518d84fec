//! Interactive bodies: grab, push and release the vertices of a body frame by frame, and read
//! back its surface and the reaction forces a tool (or a haptic device) feels.
//!
//! - [`Interactive`]: the method-neutral, object-safe interface (grab, push, release,
//!   update, positions, field, reactions) that a viewer or a path replay drives: six
//!   required methods on a [`Surface`] (rest shape and current frame) and [`Holds`] (the
//!   pending holds, checked as they come), the rest provided. The
//!   fiber–fluid method implements it here ([`FfmBody`]); other methods (ChainMail) may
//!   implement it without forces.
//! - [`Compliance`]: the fiber–fluid method's linear response about the rest shape (paper
//!   mode), from the assembled bordered system of REFERENCE §3: the columns of touched
//!   vertices computed lazily with the base solve's kept factorization
//!   ([`Precompute::Lazy`], the default), or the full inverse ([`Precompute::Full`]).
//! - [`ChainmailBody`](chainmail_body::ChainmailBody): a ChainMail lattice (TSVE or
//!   Generalized) embedding the surface, with its [`chainmail_settings`].
//! - [`tools`]: tools with a size on any body: a [`Grasp`] holds a patch rigidly, a
//!   [`Press`] is a spherical tip in frictionless contact; a [`ToolSet`] drives them, and
//!   any other type implementing [`Tool`], frame by frame.
//! - [`MethodBody`]: a model's body for any [`Method`]; [`replay`] drives one along a
//!   checked [`ToolPath`].
//! - [`FfmBody`]: a base state (the scene's own loads, from one full solve) plus the
//!   response to the tool, with grabbed vertices solved through a capacitance matrix.
//!
//! # The math, with the border
//!
//! In paper mode the bordered system is assembled and factored once on the rest shape:
//!
//! ```text
//! K_c u_c + S_c P = f_c        (c = x, y, z; fixed degrees of freedom eliminated or penalized)
//! sum_c S_c . u_c = 0
//! ```
//!
//! so the displacement is a linear map of the applied forces. With `C_c = K_c^-1` (one
//! N x N block when the material is isotropic and every axis has the same constraints,
//! otherwise one per axis), `w_c = C_c S_c` and `s = sum_c S_c . w_c`, eliminating the
//! pressure gives
//!
//! ```text
//! P   = (sum_c w_c . f_c) / s
//! u_c = C_c f_c - w_c P
//! ```
//!
//! A point force f at vertex v: `P = (sum_c w_c[v] f_c) / s` and `u_c = C_c[:, v] f_c - w_c P`,
//! `O(N)` for the whole field and `O(1)` at one vertex. The assembled border is scaled
//! for conditioning (`PressureScaling`); the scale multiplies `w` and `s` alike and cancels,
//! so [`Compliance`] works with the physical `S`. Eliminated degrees of freedom have a zero
//! border, a decoupled identity row in `K`, and a force there is dropped, exactly as
//! [`System::rhs`](fibfluid_assembly::System::rhs) drops it; the penalty form needs nothing
//! special (its large diagonal is part of `K`). A probe frame therefore *is* the full
//! solve with the same loads, up to rounding, not an approximation of it.
//!
//! **Grabbing** k vertices `g` at prescribed displacements `d` (3k values): the unknown
//! reactions `r` at those vertices satisfy
//!
//! ```text
//! G r = d - u_base(g) - u_push(g),   G[(v,a),(w,b)] = C_a[v,w] delta_ab - w_a[v] w_b[w] / s
//! ```
//!
//! where `G` (3k x 3k) is the response at the grabbed degrees of freedom to unit forces
//! there, pressure included. `G` is the restriction of `C - w w' / s`, positive
//! semi-definite with null space `S`, so it is positive definite unless every degree of
//! freedom with a non-zero `S` is grabbed; it is factored by Cholesky. The field follows
//! from the reactions as from any point forces.
//!
//! # Costs
//!
//! | operation | flops / memory traffic |
//! |---|---|
//! | full precompute, per distinct block | `N^3 / 3` (Cholesky) `+ 2 N^3 / 3` (inverse, in place) `+ 2 N^2` per axis (`w`) |
//! | lazy: `w` and `s`, once | one bordered solve with the kept factorization (`2 N^2` per block) |
//! | lazy: a vertex touched first | one bordered solve per distinct block (`2 N^2` each), cached |
//! | grabbed set changes | `O(k^2)` lookups in `C` `+ (3k)^3 / 3` (Cholesky of `G`) |
//! | frame (full field) | `O((3k)^2)` (reactions) `+ O(N (k + m))` (field: one column of `C` per held vertex) |
//! | reaction-only query | `O((3k)^2 + k m)` |
//! | memory | full: `N^2` words per distinct block (f64 or f32, [`Storage`]); lazy: the kept system and factor plus `N` f64 per touched vertex and block |
//!
//! (k grabbed, m pushed vertices.) Overall a frame is `O(k^3 + N k)` and a reaction query
//! `O(k^3 + k^2)` in the worst case (a new grabbed set every frame); while a tool drags the
//! same vertices the `k^3` term is not paid again.
//!
//! **Why a capacitance update and not a refactorization.** Grabbing k vertices is a change
//! of the constraint set of a factored body. Imposing it by refactoring costs one Cholesky
//! per distinct block, `N^3 / 3` flops (3.6e11 at N = 10,242), plus the triangular solves
//! for the field, `2 N^2` per axis (6.3e8). The capacitance (Sherman–Morrison–Woodbury)
//! route keeps the factored response and solves a 3k x 3k system instead: `(3k)^3 / 3 +
//! O(k^2)` flops (9,000 for k = 10) for the reactions plus `6 N k` for the field (6.1e5 at
//! N = 10,242, k = 10) — about five orders of magnitude fewer, which is what makes the
//! haptic rate (1 kHz) reachable. The price is the columns of the touched vertices: all of
//! them at once with the full precompute (`N^3` flops and `N^2` words per block, paid once per
//! body), or two triangular solves per vertex when it is first touched with the lazy
//! response. The capacitance and the field are `fibfluid_linalg::HeldCapacitance` and
//! `fibfluid_linalg::VertexResponse`, shared with `Simulation::respond_held`.

pub mod chainmail_body;
pub mod chainmail_settings;
mod compliance;
mod error;
pub mod fem_body;
mod ffm_body;
mod frame_guards;
mod holds;
pub mod hyper_body;
mod interactive;
mod method_body;
pub mod replay;
pub mod tools;

pub use compliance::{Compliance, ComplianceOptions, MemoryEstimate, Precompute, Storage};
pub use error::{InteractError, Result};
pub use ffm_body::FfmBody;
pub use fibfluid_linalg::memory_budget;
pub use fibfluid_sim::Method;
pub use frame_guards::{FrameGuardError, FrameGuards};
pub use holds::{Hold, Holds, NORMAL_TOLERANCE, PushRule};
pub use hyper_body::{
    CHORD_CONTRACTION, ChordBudget, ChordSpent, HyperInteractive, MAX_BALANCED_CHORDS, MAX_CHORD_REFRESHES,
    RefreshMode,
};
pub use interactive::{Interactive, LinearizationStatus, Surface};
pub use method_body::{MethodBody, ProbeBody, ProbeOptions, build_body, linearized};
pub use replay::{
    CheckedPath, FrameRow, Latency, MAX_FRAME, MAX_REACH, PathHold, PathKind, PathProblem, PathRow,
    ProbeError, Replay, TipHold, ToolPath, check_method, check_path, replay, replay_observed,
};
pub use tools::{
    Grasp, HeldGrasp, PlacedPress, Press, PressReport, RigidMotion, Tool, ToolLoad, ToolSet, Wrench,
};
