//! Generalized ChainMail and TSVE-ChainMail: a volumetric, real-time soft-tissue
//! deformation method, after Zhang, Zhong, Smith & Gu, "A new ChainMail approach for
//! real-time soft tissue simulation", *Bioengineered* 7(4):246–252, 2016.
//!
//! # Method
//!
//! An object is a [`Lattice`] of chain elements (mass points) on a regular grid of spacing
//! `h`, each linked to its (up to six) face neighbours; the rest offset of a link is
//! `d = r_j − r_i = ±h e_a`. When element `P_i` moves to `P_i*`, each neighbour `P_j` must
//! stay inside its ChainMail bounding region `CBR_{j,i}` — an axis-aligned box of allowed
//! offsets `x_j − x_i*` (Eq. 1). A neighbour outside is moved to the nearest point of the
//! box and propagates the move to its own neighbours, breadth first
//! ([`Lattice::propagate`]).
//!
//! With `Δ = |d|` per axis, the two CBRs implemented are (x limits shown; y, z alike):
//!
//! * Generalized ChainMail (Eq. 2, [`GeneralizedMaterial`]):
//!   `x_i* + (α_min Δx − β(Δy + Δz)) ≤ x_j ≤ x_i* + (α_max Δx + β(Δy + Δz))`
//!   for a neighbour on the +x side (mirrored on the −x side).
//! * TSVE-ChainMail (Eq. 3, [`TsveMaterial`]), per-element parameters `α_i`:
//!   `x_i* + Δx ∓ ((α_i + α_j)/2)(Δx + Δy + Δz)` (with the signed `d_x` in place of `Δx`
//!   on the −x side); for `α_i = α_j = α` this is Eq. 4,
//!   `x_i* + (1 − α)Δx − α(Δy + Δz) ≤ x_j ≤ x_i* + (1 + α)Δx + α(Δy + Δz)`.
//!   Anisotropy: `α_i` is a per-axis triple, the axis-`a` component in the axis-`a` limit.
//!
//! **Time-saving scheme** ([`Scheme::TimeSaving`]): for isotropic (homogeneous) TSVE
//! materials the paper proves (Remarks 1–3) that elements moved in one wave satisfy their
//! CBRs w.r.t. each other, so each element is moved and processed at most once per call
//! of [`Lattice::propagate`] (one "iteration") and already-moved neighbours are not
//! re-checked. [`Scheme::Exhaustive`] re-checks them and re-queues elements that move
//! again (needed for heterogeneous materials and for Generalized ChainMail on
//! non-convex lattices); [`Scheme::Auto`] picks between them.
//!
//! **Volume and strain-energy conservation** ([`Lattice::relax`]): every full grid cell is
//! split into six tetrahedra, and position-based corrections (Eq. 15)
//! `ΔP_i = −w_i C / (Σ_j w_j |∇_j C|²) ∇_i C` are applied, with `w_i` the inverse masses,
//! for the volume constraint (Eq. 16) `C = V(tet) − V0` and the strain-energy constraint
//! (Eq. 17) `C = ½ Σ_i k_i (|P_i − P_C| − l_i)²` (`P_C` the tetrahedron's barycenter,
//! `l_i` the rest distances). [`Lattice::release`] relaxes with no element held, which
//! brings a TSVE model back toward its rest shape once the push is removed; traditional
//! (Generalized) ChainMail has no such mechanism and stays deformed.
//!
//! A TSVE-ChainMail step is therefore `propagate` (sponsors to their targets) followed by
//! `relax` with the sponsors held; removing the push is `release`.
//!
//! # Reading choices
//!
//! * Signed rest offsets: the paper writes `Δx = |x_j − x_i|`; for a neighbour on the
//!   negative side the box is mirrored (Generalized) or centred on `x_i* + d_x` (TSVE).
//! * Per-direction parameters: the axis-`a` parameter enters the axis-`a` limits.
//! * "Nearest point of the CBR" is the per-axis clamp (the Euclidean projection onto the
//!   box).
//! * The time-saving scheme is exact (no link left violated) for a homogeneous TSVE
//!   material when all sponsors end with the same displacement from rest and the lattice
//!   satisfied its CBRs before: then each axis is a difference-constraint system with one
//!   half-width per link, which a hop-count breadth-first wave solves. `Auto` uses it only
//!   then. Elsewhere the exhaustive scheme resolves a violated link, axis by axis, by moving
//!   the end that moved less recently (sponsors and fixed elements never move).
//! * Eq. 16 uses the absolute value of the volume; here the signed volume (tetrahedra are
//!   positively oriented at rest), which is the same for uninverted tetrahedra and lets the
//!   constraint undo an inversion.
//! * The minus sign of Eq. 15, lost in the paper's text, is restored (standard
//!   position-based dynamics).
//! * `P_C` is the plain mean of the four vertices; `k_i` defaults to 1
//!   ([`Lattice::set_stiffness`]). Eq. 17 is used as written, a single scalar constraint
//!   per tetrahedron, so one projection halves the distance errors.
//! * Each relaxation sweep projects energy, then volume, then (optionally) the CBR of every
//!   link, Gauss–Seidel; held and fixed elements have weight 0.
//! * [`GeneralizedMaterial`] requires `α_min ≤ 1 ≤ α_max` so that the rest state satisfies
//!   its own CBRs.
//!
//! Measured volume changes and release residuals are in the crate's README
//! (`cargo run --release -p fibfluid-chainmail --example volume_change`).
//!
//! # Example
//!
//! ```
//! use fibfluid_chainmail::{Lattice, PropagationOptions, RelaxOptions, TsveMaterial};
//!
//! let mut lattice = Lattice::new_box([6, 6, 6], 1.0, [0.0; 3])?;
//! let material = TsveMaterial::isotropic(lattice.len(), 0.1);
//! let top = lattice.element_at([3, 3, 5]).unwrap();
//! let target = [3.0, 3.0, 4.0];
//! let report = lattice.propagate(&material, &[(top, target)], &PropagationOptions::default())?;
//! assert!(report.time_saving && report.max_processed_per_element <= 1);
//! lattice.relax(&material, &[top], &RelaxOptions::default())?;
//! lattice.release(&material, &RelaxOptions::default())?;
//! # Ok::<(), fibfluid_chainmail::ChainmailError>(())
//! ```

mod embed;
mod error;
mod lattice;
mod material;
mod propagate;
mod relax;

pub use embed::{BYTES_PER_ELEMENT, BYTES_PER_NODE, BYTES_PER_VERTEX, Embedding, EmbeddingGrid};
pub use error::{ChainmailError, Result};
pub use lattice::{Lattice, MAX_GRID_NODES};
pub use material::{AlphaProblem, Cbr, GeneralizedMaterial, Material, TsveMaterial, alpha_limits_problem};
pub use propagate::{PropagationOptions, PropagationReport, Scheme};
pub use relax::{RelaxOptions, RelaxReport};
