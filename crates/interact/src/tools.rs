//! Tools with a size, for every [`Interactive`] body: a [`Grasp`] holds a patch of the
//! surface and moves it rigidly; a [`Press`] is a rigid spherical tip in frictionless,
//! unilateral contact with the surface.
//!
//! - **Grasp.** The patch is every surface vertex whose *rest* position lies within the
//!   radius of the picked vertex's rest position (Euclidean distance, not geodesic: a fold
//!   of the surface closer than the radius is held too). Each patch vertex is grabbed at
//!   `c + t + R (p - c)` (`p` its rest position, `c` the patch's rest centroid, the mean of
//!   its vertices' rest positions, `t` and `R` the tool's [`RigidMotion`]): the motion of a
//!   scene's `[[grasp]]` (`fibfluid_fem::hyper::Grasp`) at its full load. A grasp of `k`
//!   vertices costs what `k` grabbed vertices cost. The reaction is the [`Wrench`]: the total
//!   force the tool applies to the patch and its moment about the tool's centre `c + t`.
//! - **Press.** A sphere of radius `r` centred at `x_c`. The active set is found per frame
//!   by the contact holds of the body ([`Interactive::contact`], a capacitance update of the
//!   kept factorization, like a plate's contact): each active vertex is held on the plane
//!   tangent to the sphere at the point nearest it (normal `n = (x - x_c) / |x - x_c|`), free
//!   across it; vertices found inside the sphere join the set, vertices whose contact force
//!   pulls (`lambda < 0` along `n`) leave it, and normals follow the vertices, until nothing
//!   changes. A vertex on a tangent plane is never inside the sphere. The reaction is the
//!   sum of the contact forces (all along their normals: frictionless). A method without
//!   forces (ChainMail) moves each vertex found inside onto the tangent plane.
//!
//! A [`ToolSet`] drives its tools through the [`Tool`] trait: each frame every tool puts its
//! holds ([`Tool::hold`]), the one tool that computes the frame itself (a tip, iterating its
//! contact set) settles it ([`Tool::settle`]) or the body updates once, and each tool reports
//! its [`ToolLoad`]. A new tool is one type implementing [`Tool`], added with
//! [`ToolSet::add`].

use std::collections::{BTreeMap, BTreeSet};

use fibfluid_geometry::Vec3;
use fibfluid_geometry::vec3::{add, cross, dist, dot, norm, scale, sub};

use crate::{Hold, InteractError, Interactive, Result};

/// Active-set iterations of one [`Press::place`] before it gives up.
pub const MAX_PRESS_ITERATIONS: usize = 60;

/// Iterations of one [`Press::place`] on a method without forces (ChainMail), which moves
/// the vertices found inside onto the tip and stops here with what is left reported as
/// [`PressReport::penetration`]: a ChainMail grab moves whole lattice cells, so vertices
/// sharing a cell cannot all land exactly where the tip puts them.
pub const MAX_SHAPE_ITERATIONS: usize = 8;

/// A vertex counts as inside the tip when it is closer to the centre than `radius * (1 -
/// INSIDE_TOLERANCE)`.
pub const INSIDE_TOLERANCE: f64 = 1e-10;

/// A contact whose normal force is below `-PULL_TOLERANCE` times the largest contact force
/// pulls and is released.
pub const PULL_TOLERANCE: f64 = 1e-9;

/// The active set has settled when no contact normal turns by more than this (radians)
/// between two iterations.
pub const NORMAL_SETTLED: f64 = 1e-7;

/// A rigid motion of a tool: rotation `R` about the tool's centre, then translation `t`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigidMotion {
    /// Translation of the centre, metres.
    pub translation: Vec3,
    /// Rotation matrix (row-major, orthonormal).
    pub rotation: [[f64; 3]; 3],
}

impl RigidMotion {
    /// A pure translation.
    pub fn translation(t: Vec3) -> Self {
        Self { translation: t, rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]] }
    }

    /// A translation and a rotation given as a rotation vector (axis times angle in radians,
    /// Rodrigues' formula).
    pub fn with_rotation_vector(t: Vec3, rotation: Vec3) -> Self {
        let angle = norm(rotation);
        let mut m = Self::translation(t);
        if angle == 0.0 {
            return m;
        }
        let k = scale(rotation, 1.0 / angle);
        let (s, c) = angle.sin_cos();
        for (i, row) in m.rotation.iter_mut().enumerate() {
            for (j, e) in row.iter_mut().enumerate() {
                let kx = [[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]][i][j];
                let delta = if i == j { 1.0 } else { 0.0 };
                *e = c * delta + s * kx + (1.0 - c) * k[i] * k[j];
            }
        }
        m
    }

    /// Where the point `p` goes when the tool centred at `centre` moves.
    pub fn apply(&self, centre: Vec3, p: Vec3) -> Vec3 {
        let r = sub(p, centre);
        let rotated = self.rotation.map(|row| dot(row, r));
        add(add(centre, self.translation), rotated)
    }
}

/// The load a tool applies to the body: total force (N) and moment (N m) about the tool's
/// centre.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Wrench {
    /// Total force on the body.
    pub force: Vec3,
    /// Moment about the tool's centre.
    pub moment: Vec3,
}

/// Checks a tool's radius against a body's rest shape `rest` (known before the body is
/// assembled): positive and finite ([`InteractError::BadRadius`]) and smaller than the
/// body's size, the diagonal of its bounding box ([`InteractError::ToolTooLarge`]).
/// Returns the size.
pub(crate) fn check_tool_radius(rest: &[Vec3], radius: f64) -> Result<f64> {
    if !(radius > 0.0 && radius.is_finite()) {
        return Err(InteractError::BadRadius { radius });
    }
    let (lo, hi) = fibfluid_geometry::bounding_box(rest);
    let size = dist(lo, hi);
    if radius >= size {
        return Err(InteractError::ToolTooLarge { radius, size });
    }
    Ok(size)
}

fn check_radius(body: &dyn Interactive, radius: f64) -> Result<f64> {
    check_tool_radius(body.rest_positions(), radius)
}

/// The patch of a grasp of `radius` around `vertex`: every vertex whose rest position is
/// within the radius of the vertex's, ascending (empty for an unknown vertex).
pub(crate) fn patch_around(rest: &[Vec3], vertex: usize, radius: f64) -> Vec<usize> {
    let Some(&centre) = rest.get(vertex) else { return Vec::new() };
    (0..rest.len()).filter(|&v| dist(rest[v], centre) <= radius).collect()
}

/// The first vertex two ascending lists share.
pub(crate) fn shared_vertex(a: &[usize], b: &[usize]) -> Option<usize> {
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        match a[i].cmp(&b[j]) {
            std::cmp::Ordering::Less => i += 1,
            std::cmp::Ordering::Greater => j += 1,
            std::cmp::Ordering::Equal => return Some(a[i]),
        }
    }
    None
}

/// A grasp: a patch of the surface held rigidly by the tool (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct Grasp {
    vertex: usize,
    centre: Vec3,
    radius: f64,
    patch: Vec<usize>,
}

impl Grasp {
    /// The patch of radius `radius` (metres) around `vertex`. Errors: an unknown vertex, a
    /// radius that is not positive and finite ([`InteractError::BadRadius`]), one at least
    /// the body's size ([`InteractError::ToolTooLarge`]), a patch that holds a vertex the
    /// scene fixes ([`InteractError::PatchHoldsFixed`]).
    pub fn new(body: &dyn Interactive, vertex: usize, radius: f64) -> Result<Self> {
        let rest = body.rest_positions();
        if vertex >= rest.len() {
            return Err(InteractError::UnknownVertex { vertex, vertices: rest.len() });
        }
        check_radius(body, radius)?;
        let patch = patch_around(rest, vertex, radius);
        let fixed: Vec<usize> = patch.iter().copied().filter(|&v| body.is_fixed(v)).collect();
        if let Some(&first) = fixed.first() {
            return Err(InteractError::PatchHoldsFixed { vertex, radius, fixed: first, count: fixed.len() });
        }
        // The patch holds `vertex` itself (distance 0), so it is never empty.
        let sum = patch.iter().fold([0.0; 3], |s, &v| add(s, rest[v]));
        let centre = scale(sum, 1.0 / patch.len() as f64);
        Ok(Self { vertex, centre, radius, patch })
    }

    /// The tool's centre: the patch's rest centroid (metres), about which a motion turns it.
    pub fn centre(&self) -> Vec3 {
        self.centre
    }

    /// The picked vertex.
    pub fn vertex(&self) -> usize {
        self.vertex
    }

    /// The radius, metres.
    pub fn radius(&self) -> f64 {
        self.radius
    }

    /// The held vertices, ascending.
    pub fn patch(&self) -> &[usize] {
        &self.patch
    }

    /// Grabs every patch vertex where `motion` takes it from rest (from the next update
    /// on).
    pub fn hold(&self, body: &mut dyn Interactive, motion: &RigidMotion) -> Result<()> {
        for &v in &self.patch {
            let p = body.rest_positions()[v];
            let target = motion.apply(self.centre, p);
            body.grab(v, sub(target, p))?;
        }
        Ok(())
    }

    /// As [`hold`](Self::hold), each vertex moved from `origin[v]` (a displacement from
    /// rest, for instance the body's state under its own loads) instead of from rest.
    pub fn hold_from(&self, body: &mut dyn Interactive, motion: &RigidMotion, origin: &[Vec3]) -> Result<()> {
        for &v in &self.patch {
            let p = body.rest_positions()[v];
            let moved = sub(motion.apply(self.centre, p), p);
            let o = origin.get(v).copied().unwrap_or([0.0; 3]);
            body.grab(v, add(o, moved))?;
        }
        Ok(())
    }

    /// Releases every patch vertex.
    pub fn release(&self, body: &mut dyn Interactive) -> Result<()> {
        self.patch.iter().try_for_each(|&v| body.release(v))
    }

    /// The tool's load on the body after an update: the patch's reactions summed, their
    /// moment about the tool's centre moved by `motion`. Zero for a method without forces.
    pub fn wrench(&self, body: &dyn Interactive, motion: &RigidMotion) -> Wrench {
        let centre = add(self.centre, motion.translation);
        let positions = body.positions();
        let mut w = Wrench::default();
        for &(v, f) in body.reactions() {
            if self.patch.binary_search(&v).is_ok() {
                w.force = add(w.force, f);
                w.moment = add(w.moment, cross(sub(positions[v], centre), f));
            }
        }
        w
    }
}

/// What one placement of a [`Press`] found.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PressReport {
    /// Total force of the tip on the body (N; zero for a method without forces).
    pub force: Vec3,
    /// The vertices in contact, ascending.
    pub contacts: Vec<usize>,
    /// Active-set iterations (body updates) it took.
    pub iterations: usize,
    /// The deepest a vertex is left inside the tip (m): 0 for a method with forces (within
    /// [`INSIDE_TOLERANCE`] of the radius); what a method without forces could not remove
    /// in [`MAX_SHAPE_ITERATIONS`].
    pub penetration: f64,
}

/// A rigid spherical tip pressing the surface (see the module docs). Keeps its active set
/// from one placement to the next.
///
/// The tip leaves alone what it cannot move: a vertex the scene fixes (one inside the tip
/// is an error, [`InteractError::TipReachesFixed`]) and a vertex another tool holds (a
/// grasp's patch, a grabbed vertex: that tool keeps it, and lifting the tip never releases
/// it; it may lie inside the tip).
#[derive(Clone, Debug, PartialEq)]
pub struct Press {
    radius: f64,
    /// Active contacts and their normals.
    active: BTreeMap<usize, Vec3>,
    /// The holds the tip has put on the body, as the body reports them (released when they
    /// leave the set; a vertex whose hold is not this one any more belongs to another tool).
    applied: BTreeMap<usize, Hold>,
}

impl Press {
    /// A tip of radius `radius` (metres). Errors: [`InteractError::BadRadius`],
    /// [`InteractError::ToolTooLarge`] (at least the body's size).
    pub fn new(body: &dyn Interactive, radius: f64) -> Result<Self> {
        check_radius(body, radius)?;
        Ok(Self { radius, active: BTreeMap::new(), applied: BTreeMap::new() })
    }

    /// The radius, metres.
    pub fn radius(&self) -> f64 {
        self.radius
    }

    /// The vertices in contact after the last placement.
    pub fn contacts(&self) -> Vec<usize> {
        self.active.keys().copied().collect()
    }

    /// Releases the tip's contacts (from the next update on); a vertex another tool has
    /// taken over since (a grasp's patch) keeps that tool's hold.
    pub fn lift(&mut self, body: &mut dyn Interactive) -> Result<()> {
        let own: Vec<usize> =
            body.holds().iter().filter(|(v, h)| self.applied.get(v) == Some(h)).map(|(v, _)| v).collect();
        for v in own {
            body.release(v)?;
        }
        self.active.clear();
        self.applied.clear();
        Ok(())
    }

    /// Moves the tip's centre to `centre` (metres, absolute) and updates the body until the
    /// contact set settles. Errors: a non-finite centre ([`InteractError::NonFiniteCentre`]),
    /// a tip that reaches vertices the scene fixes ([`InteractError::TipReachesFixed`], before
    /// anything changes), a body that refuses a frame, and [`InteractError::PressUnsettled`]
    /// when vertices are still inside the tip after [`MAX_PRESS_ITERATIONS`].
    pub fn place(&mut self, body: &mut dyn Interactive, centre: Vec3) -> Result<PressReport> {
        check_centre(centre)?;
        self.check_fixed(&*body, centre)?;
        let forces = body.supports_forces();
        if !forces {
            // Without forces nothing pulls a held vertex back: start from a free surface.
            self.lift(body)?;
            body.update()?;
        }
        let others = self.others(&*body);
        self.active.retain(|v, _| !others.contains(v));
        self.applied.retain(|v, _| !others.contains(v));
        let mut iterations = 0;
        let limit = if forces { MAX_PRESS_ITERATIONS } else { MAX_SHAPE_ITERATIONS };
        loop {
            let changed = self.refresh(body, centre, forces, &others);
            if (!changed && iterations > 0) || iterations == limit {
                break;
            }
            self.apply(body, centre)?;
            body.update()?;
            iterations += 1;
        }
        self.check_fixed(&*body, centre)?;
        let inside = self.inside(&*body, centre, &others);
        let positions = body.positions();
        let penetration =
            inside.iter().map(|(v, _)| self.radius - dist(positions[*v], centre)).fold(0.0, f64::max);
        if forces && !inside.is_empty() {
            return Err(InteractError::PressUnsettled { iterations, inside: inside.len() });
        }
        let mut force = [0.0; 3];
        for &(v, f) in body.reactions() {
            if self.active.contains_key(&v) {
                force = add(force, f);
            }
        }
        Ok(PressReport { force, contacts: self.contacts(), iterations, penetration })
    }

    /// Refuses a tip that reaches vertices the scene fixes (it cannot move them).
    fn check_fixed(&self, body: &dyn Interactive, centre: Vec3) -> Result<()> {
        check_reach(body, centre, self.radius)
    }

    /// The vertices another tool holds: every pending hold the tip did not put there.
    fn others(&self, body: &dyn Interactive) -> BTreeSet<usize> {
        body.holds().iter().filter(|(v, h)| self.applied.get(v) != Some(h)).map(|(v, _)| v).collect()
    }

    /// Vertices closer to `centre` than the tip's radius allows, with their outward normals
    /// (active ones too: a method without forces may leave a held vertex short of its
    /// target), except those the tip leaves alone: fixed ones and those in `others`.
    fn inside(&self, body: &dyn Interactive, centre: Vec3, others: &BTreeSet<usize>) -> Vec<(usize, Vec3)> {
        let limit = self.radius * (1.0 - INSIDE_TOLERANCE);
        body.positions()
            .iter()
            .enumerate()
            .filter(|(v, x)| dist(**x, centre) < limit && !body.is_fixed(*v) && !others.contains(v))
            .map(|(v, x)| (v, outward(*x, centre, body.rest_positions()[v])))
            .collect()
    }

    /// Updates the active set from the last frame: releases pulling contacts, turns normals
    /// toward the vertices, adds vertices inside (but none of `others`). Returns whether
    /// anything changed.
    fn refresh(
        &mut self,
        body: &dyn Interactive,
        centre: Vec3,
        forces: bool,
        others: &BTreeSet<usize>,
    ) -> bool {
        let mut changed = false;
        if forces {
            let reactions: BTreeMap<usize, Vec3> = body.reactions().iter().copied().collect();
            let along = |v: &usize, n: &Vec3| reactions.get(v).map(|f| dot(*f, *n)).unwrap_or(0.0);
            let largest = self.active.iter().map(|(v, n)| along(v, n).abs()).fold(0.0, f64::max);
            let pulling: Vec<usize> = self
                .active
                .iter()
                .filter(|(v, n)| reactions.contains_key(v) && along(v, n) < -PULL_TOLERANCE * largest)
                .map(|(v, _)| *v)
                .collect();
            changed |= !pulling.is_empty();
            for v in pulling {
                self.active.remove(&v);
            }
            for (&v, n) in self.active.iter_mut() {
                let fresh = outward(body.positions()[v], centre, body.rest_positions()[v]);
                if dot(fresh, *n).clamp(-1.0, 1.0).acos() > NORMAL_SETTLED {
                    *n = fresh;
                    changed = true;
                }
            }
        }
        let inside = self.inside(body, centre, others);
        changed |= !inside.is_empty();
        self.active.extend(inside);
        changed
    }

    /// Holds each active vertex on the plane tangent to the tip along its normal, releases
    /// the tip's holds of vertices that left the set, and records the holds it put.
    fn apply(&mut self, body: &mut dyn Interactive, centre: Vec3) -> Result<()> {
        for &v in self.applied.keys().filter(|v| !self.active.contains_key(v)) {
            body.release(v)?;
        }
        let radius = self.radius;
        let placed = self.active.iter().try_for_each(|(&v, &n)| {
            let p = body.rest_positions()[v];
            // n . (p + u) = n . centre + radius
            body.contact(v, n, dot(n, sub(centre, p)) + radius)
        });
        // Recorded even when a contact was refused, so that a lift releases what was put.
        self.applied = body.holds().iter().filter(|(v, _)| self.active.contains_key(v)).collect();
        placed
    }
}

/// Refuses a tip of `radius` at `centre` that reaches vertices the scene fixes (at their
/// current positions): it cannot move them.
fn check_reach(body: &dyn Interactive, centre: Vec3, radius: f64) -> Result<()> {
    let limit = radius * (1.0 - INSIDE_TOLERANCE);
    let positions = body.positions();
    let fixed: Vec<usize> =
        (0..positions.len()).filter(|&v| body.is_fixed(v) && dist(positions[v], centre) < limit).collect();
    match fixed.first() {
        Some(&first) => {
            Err(InteractError::TipReachesFixed { radius, centre, fixed: first, count: fixed.len() })
        }
        None => Ok(()),
    }
}

/// Refuses a tip centre with a NaN or infinite component.
fn check_centre(centre: Vec3) -> Result<()> {
    match centre.iter().find(|c| !c.is_finite()) {
        Some(&value) => Err(InteractError::NonFiniteCentre { value }),
        None => Ok(()),
    }
}

/// The unit direction from the tip's centre to a vertex at `x` (from its rest position `p`,
/// then straight up, when `x` is the centre).
fn outward(x: Vec3, centre: Vec3, p: Vec3) -> Vec3 {
    for d in [sub(x, centre), sub(p, centre), [0.0, 1.0, 0.0]] {
        let l = norm(d);
        if l > 0.0 {
            return scale(d, 1.0 / l);
        }
    }
    unreachable!("the last candidate has unit length")
}

/// A tool applied to a body frame by frame: a grasp, a pressing tip, or one defined outside
/// this crate. A [`ToolSet`] calls [`hold`](Self::hold) on every tool, then
/// [`settle`](Self::settle) on the one that [`settles`](Self::settles) (or updates the body
/// once), then [`load`](Self::load) on every tool.
pub trait Tool: std::fmt::Debug + Send + Sync {
    /// Puts the tool's holds for the next frame on the body. The default puts none (a
    /// grasp's holds are put once, when it is placed, and stay).
    fn hold(&mut self, body: &mut dyn Interactive) -> Result<()> {
        let _ = body;
        Ok(())
    }

    /// Whether the tool computes the frame itself (a tip iterates its contact set); a
    /// [`ToolSet`] holds at most one such tool.
    fn settles(&self) -> bool {
        false
    }

    /// Computes the frame: the default is one update.
    fn settle(&mut self, body: &mut dyn Interactive) -> Result<()> {
        body.update().map(|_| ())
    }

    /// Takes the tool's holds off the body (from the next update on).
    fn release(&mut self, body: &mut dyn Interactive) -> Result<()>;

    /// The tool's load on the body after a frame; `to_file` maps body vertices to file
    /// vertices.
    fn load(&self, body: &dyn Interactive, to_file: &[u32]) -> ToolLoad;
}

/// A [`Grasp`] placed with its motion: the patch is held from placement on.
#[derive(Clone, Debug, PartialEq)]
pub struct HeldGrasp {
    /// The grasp.
    pub grasp: Grasp,
    /// Its motion.
    pub motion: RigidMotion,
}

impl Tool for HeldGrasp {
    fn release(&mut self, body: &mut dyn Interactive) -> Result<()> {
        self.grasp.release(body)
    }

    fn load(&self, body: &dyn Interactive, to_file: &[u32]) -> ToolLoad {
        let w = self.grasp.wrench(body, &self.motion);
        ToolLoad::Grasp {
            grasp: to_file[self.grasp.vertex()] as usize,
            vertices: self.grasp.patch().len(),
            force: w.force,
            moment: w.moment,
        }
    }
}

/// A [`Press`] at its centre, with what its last placement found.
#[derive(Clone, Debug, PartialEq)]
pub struct PlacedPress {
    /// The tip.
    pub press: Press,
    /// Its centre (metres, absolute).
    pub centre: Vec3,
    /// What the last placement found.
    pub report: PressReport,
}

impl Tool for PlacedPress {
    fn settles(&self) -> bool {
        true
    }

    fn settle(&mut self, body: &mut dyn Interactive) -> Result<()> {
        self.report = self.press.place(body, self.centre)?;
        Ok(())
    }

    fn release(&mut self, body: &mut dyn Interactive) -> Result<()> {
        self.press.lift(body)
    }

    fn load(&self, _body: &dyn Interactive, _to_file: &[u32]) -> ToolLoad {
        ToolLoad::Press {
            press: self.centre,
            radius: self.press.radius(),
            contacts: self.report.contacts.len(),
            force: self.report.force,
            penetration: self.report.penetration,
        }
    }
}

/// The tools of one user of a body (a viewer connection, a Python body): grasps by picked
/// vertex, at most one pressing tip, and any other [`Tool`], with each tool's load after a
/// frame.
#[derive(Debug, Default)]
pub struct ToolSet {
    grasps: BTreeMap<usize, HeldGrasp>,
    tip: Option<PlacedPress>,
    /// Tools added with [`ToolSet::add`], by the number it returned.
    others: BTreeMap<usize, Box<dyn Tool>>,
    next: usize,
}

impl ToolSet {
    /// Holds the patch of `radius` around body vertex `vertex`, moved by `motion` (a later
    /// grasp of the same vertex moves it; a new radius rebuilds the patch). A patch that
    /// shares a vertex with another grasp's is refused ([`InteractError::GraspsOverlap`]);
    /// a refused grasp changes nothing.
    pub fn grasp(
        &mut self,
        body: &mut dyn Interactive,
        vertex: usize,
        radius: f64,
        motion: RigidMotion,
    ) -> Result<()> {
        let grasp = match self.grasps.get(&vertex) {
            Some(g) if g.grasp.radius() == radius => g.grasp.clone(),
            _ => Grasp::new(&*body, vertex, radius)?,
        };
        let overlap = self
            .grasps
            .values()
            .map(|h| &h.grasp)
            .filter(|g| g.vertex() != vertex)
            .find_map(|g| shared_vertex(g.patch(), grasp.patch()).map(|shared| (g.vertex(), shared)));
        if let Some((first, shared)) = overlap {
            return Err(InteractError::GraspsOverlap { first, second: vertex, shared });
        }
        if let Some(mut old) = self.grasps.remove(&vertex) {
            old.release(body)?;
        }
        grasp.hold(body, &motion)?;
        self.grasps.insert(vertex, HeldGrasp { grasp, motion });
        Ok(())
    }

    /// Drops the grasp picked at `vertex`; false if there is none.
    pub fn release(&mut self, body: &mut dyn Interactive, vertex: usize) -> Result<bool> {
        match self.grasps.remove(&vertex) {
            Some(mut g) => g.release(body).map(|_| true),
            None => Ok(false),
        }
    }

    /// Places the tip (a new radius makes a new tip). The centre, the radius and the fixed
    /// vertices the tip would reach ([`InteractError::TipReachesFixed`]) are checked first:
    /// a refused tip changes nothing (the tip in place, if any, stays).
    pub fn press(&mut self, body: &mut dyn Interactive, centre: Vec3, radius: f64) -> Result<()> {
        check_centre(centre)?;
        check_radius(&*body, radius)?;
        check_reach(&*body, centre, radius)?;
        match &mut self.tip {
            Some(tip) if tip.press.radius() == radius => tip.centre = centre,
            _ => {
                let press = Press::new(&*body, radius)?;
                self.lift(body)?;
                self.tip = Some(PlacedPress { press, centre, report: PressReport::default() });
            }
        }
        Ok(())
    }

    /// Takes the tip away.
    pub fn lift(&mut self, body: &mut dyn Interactive) -> Result<()> {
        if let Some(mut tip) = self.tip.take() {
            tip.release(body)?;
        }
        Ok(())
    }

    /// Adds a tool; returns its number for [`remove`](Self::remove). A second tool that
    /// [`settles`](Tool::settles) the frame (beside the tip or another) is refused
    /// ([`InteractError::Invalid`]).
    pub fn add(&mut self, tool: Box<dyn Tool>) -> Result<usize> {
        if tool.settles() && (self.tip.is_some() || self.others.values().any(|t| t.settles())) {
            return Err(InteractError::Invalid(
                "a tool set has at most one tool that settles the frame".into(),
            ));
        }
        let id = self.next;
        self.next += 1;
        self.others.insert(id, tool);
        Ok(id)
    }

    /// Removes the tool numbered `id` by [`add`](Self::add) and its holds; false if there is
    /// none.
    pub fn remove(&mut self, body: &mut dyn Interactive, id: usize) -> Result<bool> {
        match self.others.remove(&id) {
            Some(mut tool) => tool.release(body).map(|_| true),
            None => Ok(false),
        }
    }

    /// Forgets every tool (the body's holds are dropped by the caller, `release_all`).
    pub fn clear(&mut self) {
        self.grasps.clear();
        self.tip = None;
        self.others.clear();
    }

    /// Every tool: the tip, the grasps by picked vertex, the added tools in order.
    fn tools_mut(&mut self) -> Vec<&mut (dyn Tool + 'static)> {
        let tip = self.tip.iter_mut().map(|t| t as &mut dyn Tool);
        let grasps = self.grasps.values_mut().map(|g| g as &mut dyn Tool);
        tip.chain(grasps).chain(self.others.values_mut().map(|t| t.as_mut())).collect()
    }

    /// Computes the frame (each tool's holds, then the settling tool's iterations or one
    /// update) and the tools' loads; `to_file` maps body vertices to file vertices.
    pub fn frame(&mut self, body: &mut dyn Interactive, to_file: &[u32]) -> Result<Vec<ToolLoad>> {
        let mut tools = self.tools_mut();
        for tool in tools.iter_mut() {
            tool.hold(body)?;
        }
        match tools.iter_mut().find(|t| t.settles()) {
            Some(tool) => tool.settle(body)?,
            None => {
                body.update()?;
            }
        }
        Ok(tools.iter().map(|t| t.load(&*body, to_file)).collect())
    }
}

/// The load of one tool after a frame, as the viewer's protocol and the Python package
/// report it (JSON objects `{"grasp": V, ...}` and `{"press": [x, y, z], ...}`).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
#[serde(untagged)]
pub enum ToolLoad {
    /// A grasp: its patch size and total force and moment (about the tool's centre) on the
    /// body.
    Grasp {
        /// Picked vertex (file order).
        grasp: usize,
        /// Patch vertices.
        vertices: usize,
        /// Total force on the body (N).
        force: Vec3,
        /// Moment about the tool's centre (N m).
        moment: Vec3,
    },
    /// The tip.
    Press {
        /// Tip centre.
        press: Vec3,
        /// Tip radius.
        radius: f64,
        /// Vertices in contact.
        contacts: usize,
        /// Total force on the body (N).
        force: Vec3,
        /// Deepest vertex left inside (0 for a method with forces).
        penetration: f64,
    },
    /// Any other tool: its name and total force on the body.
    Other {
        /// The tool's name.
        tool: String,
        /// Total force on the body (N).
        force: Vec3,
    },
}
