//! The holds a tool has asked of a finite-element body (linear or at two rates): checked
//! as they come, kept by vertex until the next frame applies them.

use std::collections::BTreeMap;

use fibfluid_fem::FemHold;
use fibfluid_geometry::Vec3;
use fibfluid_sim::Model;

use crate::{Hold, InteractError, Result};

/// Forces pushed on surface vertices, by vertex.
pub(crate) type Pushes = Vec<(usize, Vec3)>;

/// A finite-element body's pending holds, its rest shape and its fixed vertices.
#[derive(Debug, Clone)]
pub(crate) struct PendingHolds {
    rest: Vec<Vec3>,
    /// Per vertex, the first axis the scene fixes it along.
    fixed: Vec<Option<char>>,
    pending: BTreeMap<usize, Hold>,
}

impl PendingHolds {
    /// No holds yet on `model`'s surface.
    pub(crate) fn of(model: &Model) -> Self {
        let rest = model.rest_positions();
        let fixed = (0..rest.len())
            .map(|v| {
                (0..3).find(|&a| model.constraints.get(v, a).is_some()).map(|a| fibfluid_geometry::AXES[a])
            })
            .collect();
        Self { rest, fixed, pending: BTreeMap::new() }
    }

    /// The rest positions.
    pub(crate) fn rest(&self) -> &[Vec3] {
        &self.rest
    }

    /// Whether the scene fixes `vertex` along any axis.
    pub(crate) fn is_fixed(&self, vertex: usize) -> bool {
        self.fixed.get(vertex).is_some_and(Option::is_some)
    }

    /// A vertex in range and a finite value, or the error naming them.
    fn check(&self, vertex: usize, value: Vec3, what: &'static str) -> Result<()> {
        if vertex >= self.rest.len() {
            return Err(InteractError::UnknownVertex { vertex, vertices: self.rest.len() });
        }
        if let Some(&value) = value.iter().find(|c| !c.is_finite()) {
            return Err(InteractError::NonFinite { vertex, what, value });
        }
        Ok(())
    }

    /// A checked vertex the scene leaves free, or the error naming the axis.
    fn check_free(&self, vertex: usize, value: Vec3, what: &'static str, action: &'static str) -> Result<()> {
        self.check(vertex, value, what)?;
        match self.fixed[vertex] {
            Some(axis) => Err(InteractError::FixedVertex { vertex, axis, action }),
            None => Ok(()),
        }
    }

    /// See [`crate::Interactive::grab`].
    pub(crate) fn grab(&mut self, vertex: usize, displacement: Vec3) -> Result<()> {
        self.check_free(vertex, displacement, "displacement", "grabbed")?;
        self.pending.insert(vertex, Hold::Grab { displacement });
        Ok(())
    }

    /// See [`crate::Interactive::push`].
    pub(crate) fn push(&mut self, vertex: usize, force: Vec3) -> Result<()> {
        self.check(vertex, force, "force")?;
        self.pending.insert(vertex, Hold::Push { force });
        Ok(())
    }

    /// See [`crate::Interactive::contact`].
    pub(crate) fn contact(&mut self, vertex: usize, normal: Vec3, along: f64) -> Result<()> {
        self.check_free(vertex, normal, "contact", "touched")?;
        crate::interactive::check_normal(vertex, normal, along)?;
        self.pending.insert(vertex, Hold::Contact { normal, along });
        Ok(())
    }

    /// See [`crate::Interactive::release`].
    pub(crate) fn release(&mut self, vertex: usize) -> Result<()> {
        self.check(vertex, [0.0; 3], "displacement")?;
        self.pending.remove(&vertex);
        Ok(())
    }

    /// Drops every hold.
    pub(crate) fn release_all(&mut self) {
        self.pending.clear();
    }

    /// The pending holds by vertex.
    pub(crate) fn holds(&self) -> Vec<(usize, Hold)> {
        self.pending.iter().map(|(&v, &h)| (v, h)).collect()
    }

    /// The pending holds as the FEM takes them: the held vertices (grabs, contacts) and the
    /// pushed forces.
    pub(crate) fn split(&self) -> (Vec<(usize, FemHold)>, Pushes) {
        let (mut held, mut pushes) = (Vec::new(), Vec::new());
        for (&v, h) in &self.pending {
            match *h {
                Hold::Grab { displacement } => held.push((v, FemHold::At(displacement))),
                Hold::Contact { normal, along } => held.push((v, FemHold::Along { normal, along })),
                Hold::Push { force } => pushes.push((v, force)),
            }
        }
        (held, pushes)
    }

    /// The reactions of a frame: the held vertices' (in `held`'s order) and the pushed
    /// forces, sorted by vertex.
    pub(crate) fn reactions(
        held: &[(usize, FemHold)],
        forces: Vec<Vec3>,
        pushes: &[(usize, Vec3)],
    ) -> Vec<(usize, Vec3)> {
        let mut reactions: Vec<(usize, Vec3)> = held.iter().map(|h| h.0).zip(forces).collect();
        reactions.extend(pushes.iter().copied());
        reactions.sort_by_key(|r| r.0);
        reactions
    }
}

/// The [`crate::Interactive`] methods a finite-element body answers from its
/// [`PendingHolds`] (the field named `holds`), for the bodies' `impl` blocks.
macro_rules! delegate_holds {
    () => {
        fn n_vertices(&self) -> usize {
            self.holds.rest().len()
        }

        fn rest_positions(&self) -> &[Vec3] {
            self.holds.rest()
        }

        fn is_fixed(&self, vertex: usize) -> bool {
            self.holds.is_fixed(vertex)
        }

        fn supports_forces(&self) -> bool {
            true
        }

        fn grab(&mut self, vertex: usize, displacement: Vec3) -> Result<()> {
            self.holds.grab(vertex, displacement)
        }

        fn push(&mut self, vertex: usize, force: Vec3) -> Result<()> {
            self.holds.push(vertex, force)
        }

        fn contact(&mut self, vertex: usize, normal: Vec3, along: f64) -> Result<()> {
            self.holds.contact(vertex, normal, along)
        }

        fn release(&mut self, vertex: usize) -> Result<()> {
            self.holds.release(vertex)
        }

        fn release_all(&mut self) {
            self.holds.release_all();
        }

        fn holds(&self) -> Vec<(usize, Hold)> {
            self.holds.holds()
        }
    };
}
pub(crate) use delegate_holds;
