//! The fiber–fluid method as an [`Interactive`] body: base state plus precomputed response,
//! with grabbed vertices solved through a capacitance matrix.

use fibfluid_geometry::Vec3;
use fibfluid_linalg::{HeldCapacitance, HeldRow};

use fibfluid_sim::Method;

use crate::compliance::linalg_error;
use crate::{Compliance, Hold, Holds, InteractError, Interactive, PushRule, Result, Surface};

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
    /// Rest shape and current frame.
    surface: Surface,
    base: Vec<Vec3>,
    /// The base displacement axis by axis (`c * N + i`), the layout the field is summed in.
    base_axes: Vec<f64>,
    /// Scratch of the same layout.
    field_axes: Vec<f64>,
    base_pressure: f64,
    holds: Holds,
    pressure: f64,
    capacitance: Option<HeldCapacitance>,
    /// Scratch: the forces of the current frame (pushes then reactions).
    forces: Vec<(usize, Vec3)>,
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
        let holds = Holds::new(n, compliance.axes(), PushRule::UnlessFixedEverywhere, |v, a| {
            compliance.is_constrained(v, a)
        });
        Ok(Self {
            base: vec![[0.0; 3]; n],
            base_axes: vec![0.0; compliance.axes() * n],
            field_axes: vec![0.0; compliance.axes() * n],
            base_pressure: 0.0,
            holds,
            surface: Surface::at_rest(rest),
            pressure: 0.0,
            capacitance: None,
            forces: Vec::new(),
            field_current: true,
            compliance,
        })
    }

    /// Sets the base state: the displacement from rest and pressure change under the
    /// scene's own loads (gravity, pressure, point forces, prescribed displacements), as one
    /// full paper-mode solve gives them. Probe frames add to it. The current frame shows the
    /// base state until the next update.
    pub fn set_base(&mut self, displacement: Vec<Vec3>, pressure: f64) -> Result<()> {
        let n = self.surface.rest.len();
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
        self.surface.set_field(self.base.clone());
        self.pressure = pressure;
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

    /// Computes the reactions of the pending holds and the force list of the frame
    /// (`self.forces`: pushes, then the grabbed vertices' reactions). Returns the new
    /// capacitance if the grabbed set changed. Leaves the current frame untouched on error.
    fn solve_reactions(&mut self) -> Result<(Option<HeldCapacitance>, Forces)> {
        let touched: Vec<usize> = self.holds.iter().map(|(v, _)| v).collect();
        self.compliance.touch(&touched)?;
        let c = &self.compliance;
        let d = c.axes();
        let mut forces: Vec<(usize, Vec3)> = Vec::with_capacity(self.holds.len());
        let mut rows: Vec<HeldRow> = Vec::new();
        let mut targets: Vec<f64> = Vec::new();
        for (v, hold) in self.holds.iter() {
            match hold {
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
}

impl Interactive for FfmBody {
    /// A linear response on the kept factorization: the holds decide the frame.
    fn answers_from_holds(&self) -> bool {
        true
    }

    fn method(&self) -> Method {
        Method::Ffm
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
        let (fresh, reactions) = self.solve_reactions()?;
        if fresh.is_some() {
            self.capacitance = fresh;
        }
        let p = self.compliance.pressure_of(&self.forces);
        self.field_axes.copy_from_slice(&self.base_axes);
        self.compliance.add_field_axes(&self.forces, p, &mut self.field_axes);
        let (n, d) = (self.surface.rest.len(), self.compliance.axes());
        let u = &self.field_axes;
        let s = &mut self.surface;
        for (i, ((fi, pi), ri)) in s.field.iter_mut().zip(s.positions.iter_mut()).zip(&s.rest).enumerate() {
            for c in 0..d {
                fi[c] = u[c * n + i];
                pi[c] = ri[c] + fi[c];
            }
        }
        self.pressure = self.base_pressure + p;
        self.surface.reactions = reactions;
        self.surface.frame += 1;
        self.field_current = true;
        Ok(&self.surface.reactions)
    }

    fn update_reactions(&mut self) -> Result<&[(usize, Vec3)]> {
        let (fresh, reactions) = self.solve_reactions()?;
        if fresh.is_some() {
            self.capacitance = fresh;
        }
        self.surface.reactions = reactions;
        self.surface.frame += 1;
        self.field_current = false;
        Ok(&self.surface.reactions)
    }

    fn memory_bytes(&self) -> usize {
        let n = self.surface.rest.len();
        let cap = self.capacitance.as_ref().map(|c| c.memory_bytes()).unwrap_or(0);
        self.compliance.memory_bytes() + 4 * n * std::mem::size_of::<Vec3>() + cap
    }
}
