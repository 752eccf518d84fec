//! The fiber–fluid method as an [`Interactive`] body: base state plus precomputed response,
//! with grabbed vertices solved through a capacitance matrix.

use std::collections::BTreeMap;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{cholesky_in_place, cholesky_in_place_scratch};
use faer::linalg::cholesky::llt::solve::{solve_in_place, solve_in_place_scratch};
use faer::{Mat, Par};
use fibfluid_assembly::AXES;
use fibfluid_geometry::Vec3;

use fibfluid_sim::Method;

use crate::{Compliance, Hold, InteractError, Interactive, Result};

/// Point forces by vertex.
type Forces = Vec<(usize, Vec3)>;

/// Factored capacitance matrix of one grabbed set.
#[derive(Clone, Debug)]
struct Capacitance {
    /// Grabbed vertices, ascending.
    grabbed: Vec<usize>,
    /// Lower Cholesky factor of G (`axes * k` square).
    l: Mat<f64>,
}

/// A fiber–fluid body about its rest shape, driven by a tool.
///
/// The field of a frame is the base state (the scene's own loads, computed once by a full
/// solve) plus the response to the tool's forces: pushed forces as given, and for grabbed
/// vertices the reactions `r` that hold them at their prescribed displacements `d`:
///
/// ```text
/// G r = d - u_base(g) - u_push(g)
/// G[(v,a),(w,b)] = C_a[v,w] delta_ab - w_a[v] w_b[w] / s      (3k x 3k, symmetric positive definite)
/// ```
///
/// `G` is the response at the grabbed degrees of freedom to unit forces there, including
/// the pressure the volume row adds (the `w w' / s` term). It depends only on which vertices
/// are grabbed, so it is built and factored (`O(k^2)` lookups, `k^3` flops) when the
/// grabbed set changes and reused while the tool drags them. A frame then costs `O(k^2)` for
/// the reactions and `O(N (k + m))` for the field (k grabbed, m pushed vertices).
#[derive(Clone, Debug)]
pub struct FfmBody {
    compliance: Compliance,
    rest: Vec<Vec3>,
    base: Vec<Vec3>,
    /// The base displacement axis by axis (`c * N + i`), the layout the field is summed in.
    base_axes: Vec<f64>,
    /// Scratch of the same layout.
    field_axes: Vec<f64>,
    base_pressure: f64,
    pending: BTreeMap<usize, Hold>,
    field: Vec<Vec3>,
    positions: Vec<Vec3>,
    pressure: f64,
    reactions: Vec<(usize, Vec3)>,
    capacitance: Option<Capacitance>,
    /// Scratch: the forces of the current frame (pushes then reactions).
    forces: Vec<(usize, Vec3)>,
    frame: u64,
    field_current: bool,
}

/// Pivots of the capacitance matrix at most this times `dim * eps(storage)` times their
/// diagonal entry mean a singular grabbed set.
const CAPACITANCE_PIVOT_FACTOR: f64 = 16.0;

impl FfmBody {
    /// A body at rest (no base load) with this precomputed response.
    pub fn new(compliance: Compliance, rest: Vec<Vec3>) -> Result<Self> {
        let n = compliance.n_vertices();
        if rest.len() != n {
            return Err(InteractError::Invalid(format!(
                "{} rest positions for a response of {n} vertices",
                rest.len()
            )));
        }
        if let Some(i) = rest.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
            return Err(InteractError::Invalid(format!("rest position of vertex {i} is not finite")));
        }
        Ok(Self {
            base: vec![[0.0; 3]; n],
            base_axes: vec![0.0; compliance.axes() * n],
            field_axes: vec![0.0; compliance.axes() * n],
            base_pressure: 0.0,
            pending: BTreeMap::new(),
            field: vec![[0.0; 3]; n],
            positions: rest.clone(),
            pressure: 0.0,
            reactions: Vec::new(),
            capacitance: None,
            forces: Vec::new(),
            frame: 0,
            field_current: true,
            rest,
            compliance,
        })
    }

    /// Sets the base state: the displacement from rest and pressure change under the
    /// scene's own loads (gravity, pressure, point forces, prescribed displacements), as one
    /// full paper-mode solve gives them. Probe frames add to it. The current frame shows the
    /// base state until the next update.
    pub fn set_base(&mut self, displacement: Vec<Vec3>, pressure: f64) -> Result<()> {
        let n = self.rest.len();
        if displacement.len() != n {
            return Err(InteractError::Invalid(format!(
                "base state has {} displacements for {n} vertices",
                displacement.len()
            )));
        }
        if let Some(i) = displacement.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
            return Err(InteractError::Invalid(format!("base displacement of vertex {i} is not finite")));
        }
        if !pressure.is_finite() {
            return Err(InteractError::Invalid(format!("base pressure {pressure} is not finite")));
        }
        let d = self.compliance.axes();
        for c in 0..d {
            for i in 0..n {
                self.base_axes[c * n + i] = displacement[i][c];
            }
        }
        self.base = displacement;
        self.base_pressure = pressure;
        self.field.clone_from(&self.base);
        self.pressure = pressure;
        self.refresh_positions();
        Ok(())
    }

    /// The precomputed response.
    pub fn compliance(&self) -> &Compliance {
        &self.compliance
    }

    /// The base displacement (the scene's loads alone).
    pub fn base_field(&self) -> &[Vec3] {
        &self.base
    }

    /// Pressure change of the current frame (base plus tool), physical units.
    pub fn pressure(&self) -> f64 {
        self.pressure
    }

    /// Whether [`positions`](Interactive::positions) describe the latest frame (false after
    /// a reaction-only update).
    pub fn field_is_current(&self) -> bool {
        self.field_current
    }

    fn check_vertex(&self, vertex: usize) -> Result<()> {
        let n = self.rest.len();
        if vertex >= n {
            return Err(InteractError::UnknownVertex { vertex, vertices: n });
        }
        Ok(())
    }

    fn check_finite(vertex: usize, v: Vec3, what: &'static str) -> Result<()> {
        match v.iter().find(|c| !c.is_finite()) {
            Some(&value) => Err(InteractError::NonFinite { vertex, what, value }),
            None => Ok(()),
        }
    }

    fn first_fixed_axis(&self, vertex: usize) -> Option<usize> {
        (0..self.compliance.axes()).find(|&c| self.compliance.is_constrained(vertex, c))
    }

    /// Builds and factors G for a grabbed set.
    fn capacitance(&self, grabbed: &[usize]) -> Result<Capacitance> {
        let c = &self.compliance;
        let (d, k) = (c.axes(), grabbed.len());
        let dim = d * k;
        let s = c.schur();
        let mut g = Mat::<f64>::zeros(dim, dim);
        for (jl, &wv) in grabbed.iter().enumerate() {
            for (jr, &vv) in grabbed.iter().enumerate().skip(jl) {
                for a in 0..d {
                    let caa = c.entry(a, vv, wv);
                    for b in 0..d {
                        let mut e = -c.w(a)[vv] * c.w(b)[wv] / s;
                        if a == b {
                            e += caa;
                        }
                        g[(jr * d + a, jl * d + b)] = e;
                        g[(jl * d + b, jr * d + a)] = e;
                    }
                }
            }
        }
        let diag: Vec<f64> = (0..dim).map(|i| g[(i, i)]).collect();
        let singular = |index: usize| InteractError::Singular {
            what: format!(
                "the {k} grabbed vertices over-determine the body (capacitance pivot {index}, vertex {} along {}); release some",
                grabbed[index / d],
                AXES[index % d]
            ),
        };
        let mut mem = MemBuffer::new(cholesky_in_place_scratch::<f64>(dim, Par::Seq, Default::default()));
        cholesky_in_place(
            g.as_mut(),
            Default::default(),
            Par::Seq,
            MemStack::new(&mut mem),
            Default::default(),
        )
        .map_err(|e| match e {
            faer::linalg::cholesky::llt::factor::LltError::NonPositivePivot { index } => singular(index),
        })?;
        let tol = CAPACITANCE_PIVOT_FACTOR * dim as f64 * c.storage().epsilon();
        for (i, gii) in diag.iter().enumerate() {
            let lii = g[(i, i)];
            if !(lii * lii > tol * gii.abs()) {
                return Err(singular(i));
            }
        }
        Ok(Capacitance { grabbed: grabbed.to_vec(), l: g })
    }

    /// Computes the reactions of the pending holds and the force list of the frame
    /// (`self.forces`: pushes, then the grabbed vertices' reactions). Returns the new
    /// capacitance if the grabbed set changed. Leaves the current frame untouched on error.
    fn solve_reactions(&mut self) -> Result<(Option<Capacitance>, Forces)> {
        let c = &self.compliance;
        let d = c.axes();
        let mut forces: Vec<(usize, Vec3)> = Vec::with_capacity(self.pending.len());
        let mut grabbed = Vec::new();
        let mut targets = Vec::new();
        for (&v, hold) in &self.pending {
            match *hold {
                Hold::Push { force } => forces.push((v, c.effective_force(v, force))),
                Hold::Grab { displacement } => {
                    grabbed.push(v);
                    targets.push(displacement);
                }
            }
        }
        let mut reactions: Vec<(usize, Vec3)> = forces.clone();
        if grabbed.is_empty() {
            self.forces = forces;
            return Ok((None, reactions));
        }
        let fresh = match &self.capacitance {
            Some(cap) if cap.grabbed == grabbed => None,
            _ => Some(self.capacitance(&grabbed)?),
        };
        let cap = fresh.as_ref().or(self.capacitance.as_ref()).expect("a capacitance for the grabbed set");
        let c = &self.compliance;
        let p_push = c.pressure_of(&forces);
        let mut rhs = Mat::<f64>::zeros(d * grabbed.len(), 1);
        for (j, (&v, t)) in grabbed.iter().zip(&targets).enumerate() {
            let u_push = c.displacement_at(v, &forces, p_push);
            for a in 0..d {
                rhs[(j * d + a, 0)] = t[a] - self.base[v][a] - u_push[a];
            }
        }
        let mut mem = MemBuffer::new(solve_in_place_scratch::<f64>(d * grabbed.len(), 1, Par::Seq));
        solve_in_place(cap.l.as_ref(), rhs.as_mut(), Par::Seq, MemStack::new(&mut mem));
        for (j, &v) in grabbed.iter().enumerate() {
            let mut r = [0.0; 3];
            for a in 0..d {
                r[a] = rhs[(j * d + a, 0)];
            }
            if let Some(&value) = r.iter().find(|x| !x.is_finite()) {
                return Err(InteractError::NonFinite { vertex: v, what: "reaction", value });
            }
            forces.push((v, r));
            reactions.push((v, r));
        }
        reactions.sort_by_key(|&(v, _)| v);
        self.forces = forces;
        Ok((fresh, reactions))
    }

    fn refresh_positions(&mut self) {
        for ((p, r), u) in self.positions.iter_mut().zip(&self.rest).zip(&self.field) {
            *p = [r[0] + u[0], r[1] + u[1], r[2] + u[2]];
        }
    }
}

impl Interactive for FfmBody {
    fn method(&self) -> Method {
        Method::Ffm
    }

    fn n_vertices(&self) -> usize {
        self.rest.len()
    }

    fn rest_positions(&self) -> &[Vec3] {
        &self.rest
    }

    fn is_fixed(&self, vertex: usize) -> bool {
        vertex < self.rest.len() && self.first_fixed_axis(vertex).is_some()
    }

    fn supports_forces(&self) -> bool {
        true
    }

    fn grab(&mut self, vertex: usize, displacement: Vec3) -> Result<()> {
        self.check_vertex(vertex)?;
        if let Some(axis) = self.first_fixed_axis(vertex) {
            return Err(InteractError::FixedVertex { vertex, axis: AXES[axis], action: "grabbed" });
        }
        Self::check_finite(vertex, displacement, "displacement")?;
        let mut displacement = displacement;
        displacement[self.compliance.axes()..].iter_mut().for_each(|x| *x = 0.0);
        self.pending.insert(vertex, Hold::Grab { displacement });
        Ok(())
    }

    fn push(&mut self, vertex: usize, force: Vec3) -> Result<()> {
        self.check_vertex(vertex)?;
        let d = self.compliance.axes();
        if (0..d).all(|c| self.compliance.is_constrained(vertex, c)) {
            return Err(InteractError::FixedVertex { vertex, axis: AXES[0], action: "pushed" });
        }
        Self::check_finite(vertex, force, "force")?;
        let mut force = force;
        force[d..].iter_mut().for_each(|x| *x = 0.0);
        self.pending.insert(vertex, Hold::Push { force });
        Ok(())
    }

    fn release(&mut self, vertex: usize) -> Result<()> {
        self.check_vertex(vertex)?;
        self.pending.remove(&vertex);
        Ok(())
    }

    fn release_all(&mut self) {
        self.pending.clear();
    }

    fn holds(&self) -> Vec<(usize, Hold)> {
        self.pending.iter().map(|(&v, &h)| (v, h)).collect()
    }

    fn update(&mut self) -> Result<&[(usize, Vec3)]> {
        let (fresh, reactions) = self.solve_reactions()?;
        if fresh.is_some() {
            self.capacitance = fresh;
        }
        let p = self.compliance.pressure_of(&self.forces);
        self.field_axes.copy_from_slice(&self.base_axes);
        self.compliance.add_field_axes(&self.forces, p, &mut self.field_axes);
        let (n, d) = (self.rest.len(), self.compliance.axes());
        let u = &self.field_axes;
        for (i, ((fi, pi), ri)) in
            self.field.iter_mut().zip(self.positions.iter_mut()).zip(&self.rest).enumerate()
        {
            for c in 0..d {
                fi[c] = u[c * n + i];
                pi[c] = ri[c] + fi[c];
            }
        }
        self.pressure = self.base_pressure + p;
        self.reactions = reactions;
        self.frame += 1;
        self.field_current = true;
        Ok(&self.reactions)
    }

    fn update_reactions(&mut self) -> Result<&[(usize, Vec3)]> {
        let (fresh, reactions) = self.solve_reactions()?;
        if fresh.is_some() {
            self.capacitance = fresh;
        }
        self.reactions = reactions;
        self.frame += 1;
        self.field_current = false;
        Ok(&self.reactions)
    }

    fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    fn field(&self) -> &[Vec3] {
        &self.field
    }

    fn reactions(&self) -> &[(usize, Vec3)] {
        &self.reactions
    }

    fn frame(&self) -> u64 {
        self.frame
    }

    fn memory_bytes(&self) -> usize {
        let n = self.rest.len();
        let cap = self.capacitance.as_ref().map(|c| c.l.nrows() * c.l.ncols() * 8).unwrap_or(0);
        self.compliance.memory_bytes() + 4 * n * std::mem::size_of::<Vec3>() + cap
    }
}
