//! The tools of one viewer connection: grasps by picked vertex and the pressing tip.

use std::collections::BTreeMap;

use fibfluid_geometry::Vec3;
use fibfluid_geometry::vec3::sub;
use fibfluid_interact::{Grasp, InteractError, Interactive, Press, RigidMotion};

use crate::protocol::ToolLoad;

/// A connection's grasps (by picked body vertex) and tip.
#[derive(Default)]
pub(crate) struct SessionTools {
    grasps: BTreeMap<usize, (Grasp, RigidMotion)>,
    tip: Option<(Press, Vec3)>,
}

impl SessionTools {
    /// Holds the patch of `radius` around body vertex `vertex` so that the vertex is at `to`
    /// (a new radius rebuilds the patch).
    pub(crate) fn grasp(
        &mut self,
        body: &mut dyn Interactive,
        vertex: usize,
        radius: f64,
        to: Vec3,
    ) -> Result<(), InteractError> {
        let motion = RigidMotion::translation(sub(to, body.rest_positions()[vertex]));
        let grasp = match self.grasps.get(&vertex) {
            Some((g, _)) if g.radius() == radius => g.clone(),
            _ => Grasp::new(&*body, vertex, radius)?,
        };
        if let Some((old, _)) = self.grasps.remove(&vertex) {
            old.release(body)?;
        }
        grasp.hold(body, &motion)?;
        self.grasps.insert(vertex, (grasp, motion));
        Ok(())
    }

    /// Drops the grasp picked at `vertex`; false if there is none.
    pub(crate) fn release(
        &mut self,
        body: &mut dyn Interactive,
        vertex: usize,
    ) -> Result<bool, InteractError> {
        match self.grasps.remove(&vertex) {
            Some((g, _)) => g.release(body).map(|_| true),
            None => Ok(false),
        }
    }

    /// Places the tip (a new radius makes a new tip).
    pub(crate) fn press(
        &mut self,
        body: &mut dyn Interactive,
        centre: Vec3,
        radius: f64,
    ) -> Result<(), InteractError> {
        match &mut self.tip {
            Some((p, c)) if p.radius() == radius => *c = centre,
            _ => {
                self.lift(body)?;
                self.tip = Some((Press::new(&*body, radius)?, centre));
            }
        }
        Ok(())
    }

    /// Takes the tip away.
    pub(crate) fn lift(&mut self, body: &mut dyn Interactive) -> Result<(), InteractError> {
        if let Some((mut p, _)) = self.tip.take() {
            p.lift(body)?;
        }
        Ok(())
    }

    /// Forgets every tool (the body's holds are dropped by the caller).
    pub(crate) fn clear(&mut self) {
        self.grasps.clear();
        self.tip = None;
    }

    /// Computes the frame (the tip's contact iterations, or one update) and the tools' loads;
    /// `to_file` maps body vertices to file vertices.
    pub(crate) fn frame(
        &mut self,
        body: &mut dyn Interactive,
        to_file: &[u32],
    ) -> Result<Vec<ToolLoad>, InteractError> {
        let mut loads = Vec::new();
        match &mut self.tip {
            Some((press, centre)) => {
                let r = press.place(body, *centre)?;
                loads.push(ToolLoad::Press {
                    centre: *centre,
                    radius: press.radius(),
                    contacts: r.contacts.len(),
                    force: r.force,
                    penetration: r.penetration,
                });
            }
            None => {
                body.update()?;
            }
        }
        for (g, motion) in self.grasps.values() {
            let w = g.wrench(&*body, motion);
            loads.push(ToolLoad::Grasp {
                vertex: to_file[g.vertex()] as usize,
                vertices: g.patch().len(),
                force: w.force,
                moment: w.moment,
            });
        }
        Ok(loads)
    }
}
