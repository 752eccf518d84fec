//! The method-neutral interface of a body a tool can touch.

use fibfluid_geometry::Vec3;

use crate::Result;
use crate::holds::{Holds, check_normal};

/// A body that a tool (a mouse, a haptic device, a scripted path) can grab, push and release,
/// frame by frame.
///
/// Calls to [`grab`](Self::grab), [`push`](Self::push), [`release`](Self::release) and
/// [`release_all`](Self::release_all) edit a *pending* set of holds and are checked at once
/// (an unknown or fixed vertex, a non-finite value is an error and changes nothing);
/// [`update`](Self::update) applies the pending set and computes the new frame. A vertex
/// has at most one hold: a later grab or push of the same vertex replaces the earlier one.
/// Vertices are indexed in the body's own order (`0..n_vertices()`).
///
/// The trait is object-safe (`Box<dyn Interactive>`) so that a viewer or a replay can drive
/// any method: the fiber–fluid method's precomputed response ([`FfmBody`](crate::FfmBody))
/// and displacement-driven methods such as ChainMail, which may not support forces
/// ([`supports_forces`](Self::supports_forces) is then false and [`push`](Self::push)
/// returns [`InteractError::Unsupported`](crate::InteractError::Unsupported)).
///
/// A body implements six methods: its [`method`](Self::method), its [`surface`](Self::surface)
/// (rest shape and current frame), its [`Holds`] ([`holds`](Self::holds),
/// [`holds_mut`](Self::holds_mut)), [`update`](Self::update) and
/// [`memory_bytes`](Self::memory_bytes); the rest is provided on them and may be overridden
/// where a method does better (a reaction-only update, a linearization's status).
pub trait Interactive {
    /// The method this body runs.
    fn method(&self) -> fibfluid_sim::Method;

    /// The body's surface: its rest shape and the current frame.
    fn surface(&self) -> &Surface;

    /// The pending holds (what the next [`update`](Self::update) applies).
    fn holds(&self) -> &Holds;

    /// The pending holds, to edit (each edit is checked, as [`grab`](Self::grab) says).
    fn holds_mut(&mut self) -> &mut Holds;

    /// Applies the pending holds and computes the frame: positions, field and reactions.
    /// Returns the reactions (see [`reactions`](Self::reactions)).
    ///
    /// On error (for instance a singular set of grabbed vertices) the previous frame stays
    /// current and the pending holds are kept, so the caller can release some and retry.
    fn update(&mut self) -> Result<&[(usize, Vec3)]>;

    /// Bytes held by the body's precomputed data (the dominant term; small vectors may be
    /// left out).
    fn memory_bytes(&self) -> usize;

    /// Number of vertices of the surface.
    fn n_vertices(&self) -> usize {
        self.surface().rest.len()
    }

    /// Rest positions of the surface, one per vertex.
    fn rest_positions(&self) -> &[Vec3] {
        &self.surface().rest
    }

    /// Whether the scene fixes the vertex along any axis (a grab there is an error).
    /// Out-of-range vertices are not fixed.
    fn is_fixed(&self, vertex: usize) -> bool {
        self.holds().is_fixed(vertex)
    }

    /// Whether [`push`](Self::push) is supported (forces as tool input and reaction forces
    /// as output).
    fn supports_forces(&self) -> bool {
        self.holds().supports_forces()
    }

    /// Holds `vertex` at `rest + displacement` from the next [`update`](Self::update) on.
    ///
    /// Errors: [`UnknownVertex`](crate::InteractError::UnknownVertex),
    /// [`FixedVertex`](crate::InteractError::FixedVertex) (fixed along any axis),
    /// [`NonFinite`](crate::InteractError::NonFinite).
    fn grab(&mut self, vertex: usize, displacement: Vec3) -> Result<()> {
        self.holds_mut().grab(vertex, displacement)
    }

    /// Pushes `vertex` with `force` from the next [`update`](Self::update) on.
    ///
    /// Errors: as [`grab`](Self::grab) (the fiber–fluid method refuses a vertex fixed along
    /// every axis; on a vertex fixed along some axes the force's components along them do
    /// nothing, as in a full solve), plus [`Unsupported`](crate::InteractError::Unsupported)
    /// for a method without forces.
    fn push(&mut self, vertex: usize, force: Vec3) -> Result<()> {
        if !self.supports_forces() {
            let method = self.method();
            return Err(crate::InteractError::Unsupported {
                method,
                what: "forces (it is displacement-driven)",
            });
        }
        self.holds_mut().push(vertex, force)
    }

    /// Holds `vertex` in frictionless contact from the next [`update`](Self::update) on:
    /// its displacement along the unit `normal` is `along`, its motion across the normal
    /// free, its reaction along the normal ([`Hold::Contact`](crate::Hold::Contact)). A method without forces
    /// cannot leave the vertex free across the normal (ChainMail): it moves it along the
    /// normal from its current position onto the contact plane and holds it there.
    ///
    /// Errors: as [`grab`](Self::grab), plus [`InteractError::Invalid`] for a normal that is
    /// not of unit length (within 1e-9).
    fn contact(&mut self, vertex: usize, normal: Vec3, along: f64) -> Result<()> {
        if self.supports_forces() {
            return self.holds_mut().contact(vertex, normal, along);
        }
        check_normal(vertex, normal, along)?;
        let u = *self
            .field()
            .get(vertex)
            .ok_or(crate::InteractError::UnknownVertex { vertex, vertices: self.n_vertices() })?;
        let un: f64 = (0..3).map(|a| u[a] * normal[a]).sum();
        let d = along - un;
        self.grab(vertex, [u[0] + d * normal[0], u[1] + d * normal[1], u[2] + d * normal[2]])
    }

    /// Drops the hold on `vertex` (nothing happens if it has none) from the next update on.
    ///
    /// Errors: [`UnknownVertex`](crate::InteractError::UnknownVertex).
    fn release(&mut self, vertex: usize) -> Result<()> {
        self.holds_mut().release(vertex)
    }

    /// Drops every hold from the next update on.
    fn release_all(&mut self) {
        self.holds_mut().clear();
    }

    /// Whether a frame's answer depends only on the holds it applies (a linear response on a
    /// kept factorization: FFM, the FEM), so that a frame asking exactly what the last one
    /// asked needs no update. ChainMail, whose lattice carries its last frame, says no.
    fn answers_from_holds(&self) -> bool {
        false
    }

    /// Applies the pending holds and computes only the reactions (the haptic query), which
    /// some methods do much faster than a whole frame. [`positions`](Self::positions) and
    /// [`field`](Self::field) may then describe the last full [`update`](Self::update)
    /// until the next one. The default runs a full update.
    fn update_reactions(&mut self) -> Result<&[(usize, Vec3)]> {
        self.update()
    }

    /// Current positions (rest + field), one per vertex.
    fn positions(&self) -> &[Vec3] {
        &self.surface().positions
    }

    /// Current displacement from the rest shape, one per vertex.
    fn field(&self) -> &[Vec3] {
        &self.surface().field
    }

    /// The force on the body at each held vertex, sorted by vertex: for a grab, the reaction
    /// the tool must apply to hold the vertex there (applied as a point force in a full solve
    /// it gives the same surface; a haptic device renders its opposite); for a push, the
    /// pushed force. Empty for a method without forces.
    fn reactions(&self) -> &[(usize, Vec3)] {
        &self.surface().reactions
    }

    /// Number of frames computed so far (full updates and reaction-only updates).
    fn frame(&self) -> u64 {
        self.surface().frame
    }

    /// For a body answered on a linearization that a second rate refreshes (the
    /// hyperelastic body), the one the last frame used; `None` for a body whose frames are
    /// exact for its own model (the linear ones, ChainMail).
    fn linearization(&self) -> Option<LinearizationStatus> {
        None
    }
}

/// A body's surface as a tool sees it: the rest shape and the current frame (positions,
/// displacement field, reactions) with the number of frames computed.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Surface {
    /// Rest positions, one per vertex.
    pub rest: Vec<Vec3>,
    /// Current positions (rest + field).
    pub positions: Vec<Vec3>,
    /// Current displacement from rest.
    pub field: Vec<Vec3>,
    /// The force on the body at each held vertex, sorted by vertex.
    pub reactions: Vec<(usize, Vec3)>,
    /// Frames computed so far.
    pub frame: u64,
}

impl Surface {
    /// The surface at rest, no frame computed.
    pub fn at_rest(rest: Vec<Vec3>) -> Self {
        let n = rest.len();
        Self { positions: rest.clone(), rest, field: vec![[0.0; 3]; n], reactions: Vec::new(), frame: 0 }
    }

    /// Sets the field and the positions from it (rest + field).
    pub fn set_field(&mut self, field: Vec<Vec3>) {
        self.field = field;
        self.refresh_positions();
    }

    /// Recomputes the positions from the rest shape and the field.
    pub fn refresh_positions(&mut self) {
        self.positions.resize(self.rest.len(), [0.0; 3]);
        for ((p, r), u) in self.positions.iter_mut().zip(&self.rest).zip(&self.field) {
            *p = [r[0] + u[0], r[1] + u[1], r[2] + u[2]];
        }
    }
}

/// The linearization a frame was answered on.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct LinearizationStatus {
    /// Linearizations made since the body was built (0: the starting state's).
    pub refreshes: u64,
    /// Those refreshes that factored the tangent (Newton's iterations); the others kept the
    /// factor and moved the state (chord iterations, a force evaluation and two solves).
    pub refactorizations: u64,
    /// Frames since the frame whose holds the linearization was made for.
    pub age_frames: u64,
    /// Seconds since the linearization was swapped in.
    pub age_seconds: f64,
    /// The largest distance a surface vertex moved from the linearization's state in this
    /// frame (m): the Newton step the frame took.
    pub step: f64,
    /// The frame's estimated distance from the converged answer for its holds (m):
    /// Newton's next correction, `step^2 / h` (h the grid's cell size); on a linearization
    /// that kept an earlier factor (a chord refresh), at least half the step.
    pub estimated_error: f64,
    /// Seconds the last refresh took.
    pub refresh_seconds: f64,
    /// Whether the frame kept springs on vertices the linearization was made holding and
    /// the frame released (until the next refresh).
    pub approximate: bool,
    /// Held vertices the frame left free because the linearization has no columns for
    /// them yet: a tool just picked up, whose columns the refresh thread is making (the
    /// frames never make them on their own thread; the frame after they arrive holds them).
    pub pending: usize,
    /// Why the last refresh failed, when it did (the frame then used the last good one).
    pub failure: Option<String>,
}
