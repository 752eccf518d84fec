//! The pictures of a run with plates: the rest and compressed shapes between the plates'
//! outlines, colored by contact pressure (`render.png`), and each plate's force against
//! the plate gap (`compression.png`). FFM runs and static finite-element runs draw the same.

use fibfluid::contact::{Plate, gap_to_next_plate};
use fibfluid::geometry::Vec3;
use fibfluid::geometry::vec3::{add, cross, dot, norm, scale, sub};
use fibfluid::sim::fem_run::FemRun;
use fibfluid::{Model, Simulation};

use crate::Result;

/// One plate run's shapes and contact, whichever method made it.
pub(crate) struct PlateScene<'a> {
    pub(crate) model: &'a Model,
    /// Rest and deformed surface positions (m), and the triangles.
    pub(crate) rest: &'a [Vec3],
    pub(crate) now: &'a [Vec3],
    pub(crate) triangles: Vec<[u32; 3]>,
    /// Contact pressure at each vertex (Pa).
    pub(crate) pressure: Vec<f64>,
    /// The plates' final load factor, and their final forces (N).
    pub(crate) lambda: f64,
    pub(crate) forces: Vec<f64>,
    /// The deformed panel's title.
    pub(crate) title: String,
}

impl<'a> PlateScene<'a> {
    /// An FFM simulation with plates: pressure is each contact's force over its vertex area.
    pub(crate) fn of_simulation(sim: &'a Simulation, triangles: Vec<[u32; 3]>) -> Self {
        let areas = sim.body().boundary.vertex_area_vectors(sim.positions());
        let mut pressure = vec![0.0; sim.positions().len()];
        for c in &sim.state().contacts {
            let a = norm(areas[c.vertex]);
            if a > 0.0 {
                pressure[c.vertex] += c.force / a;
            }
        }
        let forces = sim.plate_records().iter().map(|r| r.force.last().copied().unwrap_or(0.0)).collect();
        Self {
            model: sim.model(),
            rest: sim.rest_positions(),
            now: sim.positions(),
            triangles,
            pressure,
            lambda: sim.state().load_factor,
            forces,
            title: format!("compressed ({} contacts)", sim.state().contacts.len()),
        }
    }

    /// A static finite-element run with plates: the plates at the full load.
    pub(crate) fn of_fem(run: &'a FemRun, triangles: Vec<[u32; 3]>) -> Self {
        let mut pressure = vec![0.0; run.positions.len()];
        for plate in &run.plates {
            pressure.iter_mut().zip(&plate.pressure).for_each(|(p, q)| *p += q);
        }
        let samples: usize = run.plates.iter().map(|p| p.contact_samples).sum();
        Self {
            model: &run.model,
            rest: &run.rest,
            now: &run.positions,
            triangles,
            pressure,
            lambda: 1.0,
            forces: run.plates.iter().map(|p| p.force).collect(),
            title: format!("compressed (fem, {samples} samples in contact)"),
        }
    }

    /// The rest shape and the compressed shape between their plates (outlines), colored by
    /// contact pressure, seen from the side the most loaded plate presses on.
    pub(crate) fn render(&self) -> Result<Vec<u8>> {
        let diag = diagonal(self.rest);
        let zero = vec![0.0; self.rest.len()];
        let (p0, t0, s0) = self.with_plates(self.rest, &zero, 0.0, diag);
        let (p1, t1, s1) = self.with_plates(self.now, &self.pressure, self.lambda, diag);
        // A few vertices pinched against a plate (a voxel staircase's edges) can carry many
        // times the pressure of the rest: the scale then stops at the 95th percentile.
        let range = fibfluid::render::robust_range(&self.pressure);
        let label = match range {
            Some((_, top)) => format!("contact pressure (Pa; {top:.0} and above at the top)"),
            None => "contact pressure (Pa)".into(),
        };
        let mut opts = fibfluid::render::ViewOptions { scalar_label: label, ..Default::default() };
        let loaded = self.forces.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1)).map(|(k, _)| k);
        if let Some(k) = loaded {
            let n = self.model.plates[k].normal;
            let tilt = sub(opts.view_dir, scale(n, dot(opts.view_dir, n)));
            let v = add(n, scale(tilt, 0.8));
            opts.view_dir = scale(v, 1.0 / norm(v));
        }
        let panels = [
            fibfluid::render::Surface {
                positions: &p0,
                triangles: &t0,
                scalar: &s0,
                title: "rest, plates".into(),
            },
            fibfluid::render::Surface {
                positions: &p1,
                triangles: &t1,
                scalar: &s1,
                title: self.title.clone(),
            },
        ];
        Ok(fibfluid::render::render_surfaces(&panels, range, &opts)?)
    }

    /// `positions` with each plate's outline at load factor `lambda` appended.
    fn with_plates(
        &self,
        positions: &[Vec3],
        scalar: &[f64],
        lambda: f64,
        diag: f64,
    ) -> (Vec<Vec3>, Vec<[u32; 3]>, Vec<f64>) {
        let (mut p, mut t, mut s) = (positions.to_vec(), self.triangles.clone(), scalar.to_vec());
        let centroid = centroid(positions);
        for plate in &self.model.plates {
            let (corners, quads) = plate_outline(plate, centroid, lambda, 0.6 * diag, 0.01 * diag);
            let base = p.len() as u32;
            p.extend_from_slice(&corners);
            s.extend(std::iter::repeat_n(0.0, corners.len()));
            t.extend(quads.iter().map(|q| q.map(|i| base + i)));
        }
        (p, t, s)
    }
}

fn centroid(positions: &[Vec3]) -> Vec3 {
    scale(positions.iter().fold([0.0; 3], |a, x| add(a, *x)), 1.0 / positions.len().max(1) as f64)
}

/// The diagonal of the positions' bounding box.
fn diagonal(positions: &[Vec3]) -> f64 {
    let (lo, hi) = fibfluid::geometry::bounding_box(positions);
    if positions.is_empty() { 0.0 } else { norm(sub(hi, lo)) }
}

/// The outline of a plate as four thin quads (two triangles each): a square of half-side
/// `half` about the centroid's projection, strips `width` wide.
fn plate_outline(
    plate: &Plate,
    centroid: Vec3,
    lambda: f64,
    half: f64,
    width: f64,
) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let n = plate.normal;
    let helper = if n[0].abs() < 0.9 { [1.0, 0.0, 0.0] } else { [0.0, 1.0, 0.0] };
    let a = cross(n, helper);
    let a = scale(a, 1.0 / norm(a));
    let b = cross(n, a);
    let origin = plate.point_at(lambda);
    let center = sub(centroid, scale(n, dot(n, sub(centroid, origin))));
    let at = |u: f64, v: f64| add(center, add(scale(a, u), scale(b, v)));
    let mut corners = Vec::new();
    let mut quads = Vec::new();
    let (o, i) = (half, half - width);
    for (u0, v0, u1, v1) in [(-o, -o, o, -i), (-o, i, o, o), (-o, -i, -i, i), (i, -i, o, i)] {
        let k = corners.len() as u32;
        corners.extend([at(u0, v0), at(u1, v0), at(u1, v1), at(u0, v1)]);
        quads.extend([[k, k + 1, k + 2], [k, k + 2, k + 3]]);
    }
    (corners, quads)
}

/// Each plate's (gap, force) series: gap in metres, force in N.
pub(crate) struct PlateCurve {
    pub(crate) gap: Vec<f64>,
    pub(crate) force: Vec<f64>,
}

/// Force (N) against thickness (the mesh's unit) for each plate (`compression.png`).
pub(crate) fn compression_png(model: &Model, curves: &[PlateCurve]) -> Result<Vec<u8>> {
    let unit = model.unit;
    let to_unit = 1.0 / unit.metres();
    let series: Vec<fibfluid::render::Series> = curves
        .iter()
        .enumerate()
        .map(|(k, r)| fibfluid::render::Series {
            label: format!("plate {}", k + 1),
            points: r.gap.iter().map(|g| g * to_unit).zip(r.force.iter().copied()).collect(),
        })
        .collect();
    let title = format!("{}: plate force against thickness", model.name);
    Ok(fibfluid::render::line_chart(
        &title,
        &format!("thickness, the plate gap ({unit})"),
        "force on the plate (N)",
        &series,
        900,
        560,
    )?)
}

/// A static finite-element run's curves, one point per converged load step (contact
/// augmentations refine the last): the gap is FFM's, the distance to the next plate
/// ([`gap_to_next_plate`]), or for a single plate the rest body's extent in front of it.
pub(crate) fn fem_curves(run: &FemRun) -> Vec<PlateCurve> {
    let plates = &run.model.plates;
    let steps = run.newton.as_ref().map(|n| n.steps.as_slice()).unwrap_or_default();
    // The rest body's farthest reach along each plate's normal.
    let reach: Vec<f64> =
        plates.iter().map(|p| run.rest.iter().map(|x| dot(p.normal, *x)).fold(f64::MIN, f64::max)).collect();
    let gap = |k: usize, t: f64| {
        gap_to_next_plate(plates, k, t)
            .unwrap_or_else(|| (reach[k] - dot(plates[k].normal, plates[k].point_at(t))).max(0.0))
    };
    (0..plates.len())
        .map(|k| {
            let mut curve = PlateCurve { gap: vec![gap(k, 0.0)], force: vec![0.0] };
            for s in steps.iter().filter(|s| s.plate_forces.len() == plates.len()) {
                if s.augmentation > 0 {
                    curve.force.pop();
                    curve.gap.pop();
                }
                curve.gap.push(gap(k, s.load));
                curve.force.push(s.plate_forces[k]);
            }
            curve
        })
        .collect()
}
