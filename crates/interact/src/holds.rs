//! The holds a tool has asked of a body: checked as they come (vertex in range, not fixed,
//! finite values), kept by vertex until the next frame applies them. One type for every
//! method; what differs between methods (which axes exist, where a push is taken) is data.

use std::collections::BTreeMap;

use fibfluid_fem::FemHold;
use fibfluid_geometry::{AXES, Vec3};
use fibfluid_sim::Model;

use crate::{InteractError, Result};

/// What a tool does to one vertex.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Hold {
    /// The tool holds the vertex at `rest + displacement` (a prescribed displacement from
    /// the rest shape; the body answers with a reaction force).
    Grab {
        /// Displacement from the rest position.
        displacement: Vec3,
    },
    /// The tool pushes the vertex with a force (added to the scene's base loads).
    Push {
        /// The force applied to the body.
        force: Vec3,
    },
    /// Frictionless contact: the tool holds the vertex's displacement along `normal` (unit)
    /// at `along` and leaves it free across the normal; the reaction is along the normal.
    Contact {
        /// The contact normal (unit length), pointing from the tool into the body.
        normal: Vec3,
        /// The displacement from the rest position along `normal`.
        along: f64,
    },
}

/// Where a body takes pushed forces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PushRule {
    /// Nowhere: the method is displacement-driven (ChainMail); it has no contacts either.
    Refused,
    /// On any vertex (the force's components along fixed axes do nothing).
    Anywhere,
    /// On any vertex the scene leaves free along at least one axis.
    UnlessFixedEverywhere,
}

/// Forces pushed on surface vertices, by vertex.
pub(crate) type Pushes = Vec<(usize, Vec3)>;

/// Tolerance on the length of a contact normal.
pub const NORMAL_TOLERANCE: f64 = 1e-9;

/// A body's pending holds, with what is needed to check them: the number of vertices, the
/// axes the scene fixes at each, the axes the body has (2 for a polygon) and where it takes
/// pushes. A vertex has at most one hold: a later one replaces the earlier.
#[derive(Clone, Debug)]
pub struct Holds {
    /// Per vertex, the axes the scene fixes it along (bit `a` for axis `a`).
    fixed: Vec<u8>,
    axes: usize,
    pushes: PushRule,
    pending: BTreeMap<usize, Hold>,
}

impl Holds {
    /// No holds yet on `n` vertices with `axes` axes (components beyond them are dropped),
    /// vertex `v` fixed along axis `a` when `fixed(v, a)`.
    pub fn new(n: usize, axes: usize, pushes: PushRule, fixed: impl Fn(usize, usize) -> bool) -> Self {
        let axes = axes.min(3);
        let fixed =
            (0..n).map(|v| (0..axes).filter(|&a| fixed(v, a)).fold(0u8, |m, a| m | (1 << a))).collect();
        Self { fixed, axes, pushes, pending: BTreeMap::new() }
    }

    /// No holds yet on `model`'s surface (three axes), fixed where its constraints say.
    pub fn of_model(model: &Model, pushes: PushRule) -> Self {
        Self::new(model.n_vertices(), 3, pushes, |v, a| model.constraints.get(v, a).is_some())
    }

    /// No holds yet on `n` vertices (three axes), each fixed along its first fixed axis
    /// (`None`: free) and no other.
    pub fn with_first_axes(fixed: &[Option<char>], pushes: PushRule) -> Self {
        Self::new(fixed.len(), 3, pushes, |v, a| fixed[v] == Some(AXES[a]))
    }

    /// Number of vertices.
    pub fn n_vertices(&self) -> usize {
        self.fixed.len()
    }

    /// Whether the scene fixes `vertex` along any axis (false out of range).
    pub fn is_fixed(&self, vertex: usize) -> bool {
        self.fixed.get(vertex).is_some_and(|&m| m != 0)
    }

    /// Whether the body takes pushed forces (and frictionless contacts).
    pub fn supports_forces(&self) -> bool {
        self.pushes != PushRule::Refused
    }

    /// The hold on `vertex`, if any.
    pub fn get(&self, vertex: usize) -> Option<Hold> {
        self.pending.get(&vertex).copied()
    }

    /// The holds by vertex, ascending.
    pub fn iter(&self) -> impl Iterator<Item = (usize, Hold)> + '_ {
        self.pending.iter().map(|(&v, &h)| (v, h))
    }

    /// The holds by vertex, ascending, as a list.
    pub fn to_vec(&self) -> Vec<(usize, Hold)> {
        self.iter().collect()
    }

    /// Number of held vertices.
    pub fn len(&self) -> usize {
        self.pending.len()
    }

    /// Whether nothing is held.
    pub fn is_empty(&self) -> bool {
        self.pending.is_empty()
    }

    fn check_vertex(&self, vertex: usize) -> Result<()> {
        match vertex < self.fixed.len() {
            true => Ok(()),
            false => Err(InteractError::UnknownVertex { vertex, vertices: self.fixed.len() }),
        }
    }

    fn check_free(&self, vertex: usize, action: &'static str) -> Result<()> {
        self.check_vertex(vertex)?;
        let mask = self.fixed[vertex];
        match (0..3).find(|a| mask & (1 << a) != 0) {
            Some(a) => Err(InteractError::FixedVertex { vertex, axis: AXES[a], action }),
            None => Ok(()),
        }
    }

    fn finite(&self, vertex: usize, v: Vec3, what: &'static str) -> Result<Vec3> {
        if let Some(&value) = v.iter().find(|c| !c.is_finite()) {
            return Err(InteractError::NonFinite { vertex, what, value });
        }
        let mut v = v;
        v[self.axes..].iter_mut().for_each(|x| *x = 0.0);
        Ok(v)
    }

    /// The errors [`grab`](Self::grab) would give, without grabbing.
    pub fn check_grab(&self, vertex: usize, displacement: Vec3) -> Result<()> {
        self.check_free(vertex, "grabbed")?;
        self.finite(vertex, displacement, "displacement").map(|_| ())
    }

    /// Holds `vertex` at `rest + displacement` (see [`crate::Interactive::grab`]).
    pub fn grab(&mut self, vertex: usize, displacement: Vec3) -> Result<()> {
        self.check_free(vertex, "grabbed")?;
        let displacement = self.finite(vertex, displacement, "displacement")?;
        self.pending.insert(vertex, Hold::Grab { displacement });
        Ok(())
    }

    /// Pushes `vertex` with `force` (see [`crate::Interactive::push`]); refused as
    /// [`InteractError::Invalid`] by a body without forces.
    pub fn push(&mut self, vertex: usize, force: Vec3) -> Result<()> {
        self.check_vertex(vertex)?;
        let everywhere = (1u8 << self.axes) - 1;
        match self.pushes {
            PushRule::Refused => return Err(InteractError::Invalid("this body takes no forces".into())),
            PushRule::UnlessFixedEverywhere if self.fixed[vertex] == everywhere => {
                return Err(InteractError::FixedVertex { vertex, axis: AXES[0], action: "pushed" });
            }
            _ => {}
        }
        let force = self.finite(vertex, force, "force")?;
        self.pending.insert(vertex, Hold::Push { force });
        Ok(())
    }

    /// Holds `vertex` in frictionless contact (see [`crate::Interactive::contact`]);
    /// refused as [`InteractError::Invalid`] by a body without forces.
    pub fn contact(&mut self, vertex: usize, normal: Vec3, along: f64) -> Result<()> {
        self.check_free(vertex, "touched")?;
        check_normal(vertex, normal, along)?;
        if !self.supports_forces() {
            return Err(InteractError::Invalid("this body takes no frictionless contacts".into()));
        }
        self.pending.insert(vertex, Hold::Contact { normal, along });
        Ok(())
    }

    /// Drops the hold on `vertex` (nothing happens if it has none).
    pub fn release(&mut self, vertex: usize) -> Result<()> {
        self.check_vertex(vertex)?;
        self.pending.remove(&vertex);
        Ok(())
    }

    /// Drops every hold.
    pub fn clear(&mut self) {
        self.pending.clear();
    }

    /// The holds as the FEM takes them: the held vertices (grabs, contacts) and the pushed
    /// forces.
    pub(crate) fn split(&self) -> (Vec<(usize, FemHold)>, Pushes) {
        let (mut held, mut pushes) = (Vec::new(), Vec::new());
        for (v, h) in self.iter() {
            match h {
                Hold::Grab { displacement } => held.push((v, FemHold::At(displacement))),
                Hold::Contact { normal, along } => held.push((v, FemHold::Along { normal, along })),
                Hold::Push { force } => pushes.push((v, force)),
            }
        }
        (held, pushes)
    }
}

/// The reactions of a finite-element frame: the held vertices' (in `held`'s order) and the
/// pushed forces, sorted by vertex.
pub(crate) fn fem_reactions(
    held: &[(usize, FemHold)],
    forces: Vec<Vec3>,
    pushes: &[(usize, Vec3)],
) -> Vec<(usize, Vec3)> {
    let mut reactions: Vec<(usize, Vec3)> = held.iter().map(|h| h.0).zip(forces).collect();
    reactions.extend(pushes.iter().copied());
    reactions.sort_by_key(|r| r.0);
    reactions
}

/// Checks a contact's normal (unit length, finite) and displacement (finite).
pub(crate) fn check_normal(vertex: usize, normal: Vec3, along: f64) -> Result<()> {
    if let Some(&value) = normal.iter().chain([&along]).find(|c| !c.is_finite()) {
        return Err(InteractError::NonFinite { vertex, what: "contact", value });
    }
    let len = normal.iter().map(|c| c * c).sum::<f64>().sqrt();
    if (len - 1.0).abs() > NORMAL_TOLERANCE {
        return Err(InteractError::Invalid(format!(
            "vertex {vertex}: the contact normal has length {len}, not 1"
        )));
    }
    Ok(())
}
