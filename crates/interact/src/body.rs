//! The fiber–fluid method as an [`Interactive`] body: base state plus precomputed response,
//! with grabbed vertices solved through a capacitance matrix.

use std::collections::BTreeMap;

use fibfluid_assembly::AXES;
use fibfluid_geometry::Vec3;
use fibfluid_linalg::{HeldCapacitance, HeldRow};

use fibfluid_sim::Method;

use crate::compliance::linalg_error;
use crate::{Compliance, Hold, InteractError, Interactive, Result};

/// Point forces by vertex.
type Forces = Vec<(usize, Vec3)>;

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
///
/// The capacitance and the field are [`fibfluid_linalg::HeldCapacitance`] and
/// [`fibfluid_linalg::VertexResponse`], the same code that holds vertices in
/// `Simulation::respond_held`. With the lazy response ([`Precompute::Lazy`](crate::Precompute))
/// a vertex grabbed or pushed for the first time first gets its compliance columns from the
/// kept factorization (cached for later frames and copied into clones made afterwards).
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
    capacitance: Option<HeldCapacitance>,
    /// Scratch: the forces of the current frame (pushes then reactions).
    forces: Vec<(usize, Vec3)>,
    frame: u64,
    field_current: bool,
}

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

    /// Computes the reactions of the pending holds and the force list of the frame
    /// (`self.forces`: pushes, then the grabbed vertices' reactions). Returns the new
    /// capacitance if the grabbed set changed. Leaves the current frame untouched on error.
    fn solve_reactions(&mut self) -> Result<(Option<HeldCapacitance>, Forces)> {
        let touched: Vec<usize> = self.pending.keys().copied().collect();
        self.compliance.touch(&touched)?;
        let c = &self.compliance;
        let d = c.axes();
        let mut forces: Vec<(usize, Vec3)> = Vec::with_capacity(self.pending.len());
        let mut rows: Vec<HeldRow> = Vec::new();
        let mut targets: Vec<f64> = Vec::new();
        for (&v, hold) in &self.pending {
            match *hold {
                Hold::Push { force } => forces.push((v, c.effective_force(v, force))),
                Hold::Grab { displacement } => {
                    rows.extend(HeldRow::all_axes(v, d));
                    targets.extend(&displacement[..d]);
                }
                Hold::Contact { normal, along } => {
                    rows.push(HeldRow { vertex: v, direction: normal });
                    targets.push(along);
                }
            }
        }
        let mut reactions: Vec<(usize, Vec3)> = forces.clone();
        if rows.is_empty() {
            self.forces = forces;
            return Ok((None, reactions));
        }
        let fresh = match &self.capacitance {
            Some(cap) if cap.rows() == rows.as_slice() => None,
            _ => Some(HeldCapacitance::from_rows(&self.compliance, &rows).map_err(linalg_error)?),
        };
        let cap = fresh.as_ref().or(self.capacitance.as_ref()).expect("a capacitance for the held set");
        let c = &self.compliance;
        let p_push = c.pressure_of(&forces);
        let mut gap = Vec::with_capacity(rows.len());
        let mut last: Option<(usize, Vec3)> = None;
        for (row, t) in rows.iter().zip(&targets) {
            let v = row.vertex;
            let y = match last {
                Some((lv, y)) if lv == v => y,
                _ => {
                    let u_push = c.displacement_at(v, &forces, p_push);
                    let y = [0, 1, 2].map(|a| self.base[v][a] + u_push[a]);
                    last = Some((v, y));
                    y
                }
            };
            gap.push(t - (0..d).map(|a| row.direction[a] * y[a]).sum::<f64>());
        }
        let held = cap.reactions(&gap).map_err(|e| match e {
            fibfluid_linalg::LinalgError::NonFiniteSolution { index } => {
                InteractError::NonFinite { vertex: rows[index].vertex, what: "reaction", value: f64::NAN }
            }
            other => linalg_error(other),
        })?;
        for r in held {
            forces.push(r);
            reactions.push(r);
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
    /// A linear response on the kept factorization: the holds decide the frame.
    fn answers_from_holds(&self) -> bool {
        true
    }

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

    fn contact(&mut self, vertex: usize, normal: Vec3, along: f64) -> Result<()> {
        self.check_vertex(vertex)?;
        if let Some(axis) = self.first_fixed_axis(vertex) {
            return Err(InteractError::FixedVertex { vertex, axis: AXES[axis], action: "touched" });
        }
        crate::interactive::check_normal(vertex, normal, along)?;
        self.pending.insert(vertex, Hold::Contact { normal, along });
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
        let cap = self.capacitance.as_ref().map(|c| c.memory_bytes()).unwrap_or(0);
        self.compliance.memory_bytes() + 4 * n * std::mem::size_of::<Vec3>() + cap
    }
}
