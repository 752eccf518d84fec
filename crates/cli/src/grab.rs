//! The grab comparison of the accuracy study's physical axis: every interactive method
//! (FFM with the paper's fibers, TSVE-ChainMail, Generalized ChainMail, the FEM at coarse
//! resolutions) is given the same single grab, and its surface displacement is compared with
//! the FEM reference's under that grab.
//!
//! ChainMail takes grabs only (no forces, no gravity), so it cannot join the gravity
//! comparison; here the scene's loads (gravity, point forces) are removed for every method
//! and only the grab deforms the body. **The grab**: a [`Grasp`] (a patch held rigidly) of
//! radius [`GRAB_FRACTION`] of the bounding-box diagonal around the free surface vertex
//! (fixed along no axis) farthest from the fixed vertices (the largest distance to the
//! nearest fixed vertex; with nothing fixed, the farthest from the centroid of the
//! vertices), translated by [`GRAB_FRACTION`] of the diagonal along the scene's gravity
//! (along −y without gravity). Ties go to the lowest vertex index. A patch rather than one
//! vertex: a displacement prescribed at a single point of a continuum is carried by a
//! neighbourhood that shrinks as the mesh refines, so the FEM under a one-vertex grab does
//! not converge to a limit; under a patch of fixed size it does.
//!
//! Each body is built the way `fibfluid probe` builds it ([`MethodBody::build`], default
//! [`ProbeOptions`]: lazy response, f64), so the setup time is the probe's and the first
//! frame's time is the grasp and one `update` on the fresh body (for lazy FFM and the FEM
//! it includes computing the patch vertices' compliance columns).

use std::time::Instant;

use serde::Serialize;

use fibfluid::geometry::Vec3;
use fibfluid::geometry::vec3::{dist, norm};
use fibfluid::interact::{Grasp, Method, MethodBody, ProbeError, ProbeOptions, RigidMotion};
use fibfluid::render::log_drawable;
use fibfluid::sim::FiberModel;
use fibfluid::sim::calibration::{Calibration, relative_l2};
use fibfluid::{Scene, Shape};

use crate::study_grid::{FEM_STUDY_REFERENCE, FEM_STUDY_RESOLUTIONS, PARETO_MARGIN};

/// The grasp's radius and its translation, each as a fraction of the body's bounding-box
/// diagonal.
pub const GRAB_FRACTION: f64 = 0.05;

/// The one grab every method of the comparison is given.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Grab {
    /// The picked vertex, the patch's centre (the body's vertex order, which is the scene's).
    pub vertex: usize,
    /// Its rest position (m).
    pub rest: Vec3,
    /// The patch's radius (m).
    pub radius: f64,
    /// The patch's prescribed translation (m): every patch vertex moves by it.
    pub displacement: Vec3,
}

/// One method's body under the grab.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GrabPoint {
    /// The method.
    pub method: Method,
    /// The FEM's resolution (cells along the longest side); `None` for the other methods.
    pub resolution: Option<usize>,
    /// Seconds of building the body (base solve and precompute for FFM, voxelization and
    /// embedding for ChainMail, voxelization, assembly, factorization and base solve for
    /// the FEM).
    pub setup_seconds: Option<f64>,
    /// Seconds of the first frame: the grasp and one update on the fresh body.
    pub first_frame_seconds: Option<f64>,
    /// Relative L2 difference of the surface displacement from the FEM reference's under
    /// the same grab, no scaling (`None` when the body failed).
    pub error_vs_fem: Option<f64>,
    /// How much the surface moves against the reference: `|u| / |u_reference|` (L2 norms
    /// of the stacked surface displacements; above 1 the grab drags more of the body along).
    pub amplitude_vs_fem: Option<f64>,
    /// The surface displacement after the frame, one per vertex (m); empty when the body
    /// failed.
    #[serde(skip)]
    pub field: Vec<Vec3>,
    /// Why the body failed, if it did.
    pub error: Option<String>,
}

impl GrabPoint {
    /// `ffm`, `tsve-chainmail`, `generalized-chainmail` or `fem 16`.
    pub fn label(&self) -> String {
        match self.resolution {
            Some(r) => format!("{} {r}", self.method),
            None => self.method.to_string(),
        }
    }

    /// Seconds to the first deformed frame: setup plus the first frame.
    pub fn seconds_to_first_frame(&self) -> Option<f64> {
        Some(self.setup_seconds? + self.first_frame_seconds?)
    }
}

/// The grab comparison: the grab, the FEM reference under it and every method's point.
#[derive(Clone, Debug, PartialEq)]
pub struct GrabComparison {
    /// The grab.
    pub grab: Grab,
    /// The FEM reference (resolution [`FEM_STUDY_REFERENCE`]) under the grab; its
    /// `error_vs_fem` is 0.
    pub reference: GrabPoint,
    /// FFM (paper fibers), TSVE-ChainMail, Generalized ChainMail, then the FEM at
    /// [`FEM_STUDY_RESOLUTIONS`].
    pub points: Vec<GrabPoint>,
}

/// Chooses the grab of the comparison on `scene` (see the module documentation).
///
/// Errors: [`crate::Error::NoFreeVertex`] when every vertex is fixed along some axis.
pub fn choose_grab(scene: &Scene) -> crate::Result<Grab> {
    let rest = scene.rest_positions();
    let fixed: Vec<bool> =
        (0..rest.len()).map(|v| (0..3).any(|a| scene.constraints.get(v, a).is_some())).collect();
    let anchors: Vec<Vec3> = if fixed.iter().any(|&f| f) {
        rest.iter().zip(&fixed).filter(|(_, f)| **f).map(|(p, _)| *p).collect()
    } else {
        let n = rest.len().max(1) as f64;
        let sum = rest.iter().fold([0.0; 3], |s, p| [s[0] + p[0], s[1] + p[1], s[2] + p[2]]);
        vec![[sum[0] / n, sum[1] / n, sum[2] / n]]
    };
    let nearest = |p: &Vec3| anchors.iter().map(|a| dist(*p, *a)).fold(f64::INFINITY, f64::min);
    let mut best: Option<(usize, f64)> = None;
    for (v, p) in rest.iter().enumerate().filter(|(v, _)| !fixed[*v]) {
        let d = nearest(p);
        if best.is_none_or(|(_, b)| d > b) {
            best = Some((v, d));
        }
    }
    let Some((vertex, _)) = best else {
        return Err(crate::Error::NoFreeVertex { scene: scene.display_name() });
    };
    let (lo, hi) = fibfluid::geometry::bounding_box(&rest);
    let length = GRAB_FRACTION * dist(lo, hi);
    let g = scene.load.gravity;
    let g_norm = norm(g);
    let direction =
        if g_norm > 0.0 { [g[0] / g_norm, g[1] / g_norm, g[2] / g_norm] } else { [0.0, -1.0, 0.0] };
    Ok(Grab { vertex, rest: rest[vertex], radius: length, displacement: direction.map(|c| c * length) })
}

/// The scene as the grab comparison deforms it: its loads (gravity, point forces) removed
/// and, for FFM, the paper's fibers; when the scene gave only `[tissue]`, with the paper
/// fibers' calibrated modulus from `calibrations` (as the study's physical axis found them),
/// or calibrated here (with the scene's loads) when `calibrations` has none.
pub fn grab_scene(scene: &Scene, calibrations: &[Calibration]) -> crate::Result<Scene> {
    let mut s = scene.clone();
    s.model.ffm.fibers = FiberModel::Paper;
    if s.model.ffm.calibrate {
        let c = match calibrations.iter().find(|c| c.fibers == FiberModel::Paper) {
            Some(c) => *c,
            None => fibfluid::sim::calibration::calibrate(&s.model, None)?,
        };
        c.apply(&mut s.model.material).expect("a calibration's fibers are in range (positive modulus)");
        s.model.ffm.calibrate = false;
    }
    s.model.load.gravity = [0.0; 3];
    s.model.load.forces.clear();
    Ok(s)
}

/// Runs the grab comparison on `scene` (see the module documentation). A method whose body
/// cannot be built or refuses the grab gets a point with its `error`; the FEM reference
/// failing is an error of the whole comparison.
pub fn grab_comparison(scene: &Scene, calibrations: &[Calibration]) -> crate::Result<GrabComparison> {
    let grab = choose_grab(scene)?;
    let s = grab_scene(scene, calibrations)?;
    let mut reference = grab_point(&s, Method::Fem, Some(FEM_STUDY_REFERENCE), &grab)?;
    reference.error_vs_fem = Some(0.0);
    reference.amplitude_vs_fem = Some(1.0);
    let runs = [Method::Ffm, Method::TsveChainmail, Method::GeneralizedChainmail]
        .map(|m| (m, None))
        .into_iter()
        .chain(FEM_STUDY_RESOLUTIONS.map(|r| (Method::Fem, Some(r))));
    let mut points = Vec::new();
    for (method, resolution) in runs {
        let point = match grab_point(&s, method, resolution, &grab) {
            Ok(mut p) => {
                p.error_vs_fem = Some(relative_l2(&p.field, &reference.field));
                p.amplitude_vs_fem = Some(stacked_norm(&p.field) / stacked_norm(&reference.field));
                p
            }
            Err(e) => GrabPoint {
                method,
                resolution,
                setup_seconds: None,
                first_frame_seconds: None,
                error_vs_fem: None,
                amplitude_vs_fem: None,
                field: Vec::new(),
                error: Some(e.to_string()),
            },
        };
        points.push(point);
    }
    Ok(GrabComparison { grab, reference, points })
}

/// Builds `method`'s body of `s` (the FEM at `resolution`), grabs and updates once.
fn grab_point(s: &Scene, method: Method, resolution: Option<usize>, grab: &Grab) -> crate::Result<GrabPoint> {
    let mut model = s.model.clone();
    model.solver.method = method;
    if let Some(r) = resolution {
        model.fem.resolution = r;
    }
    let mut body = MethodBody::build(&model, &s.chainmail, method, &ProbeOptions::default())?;
    let setup_seconds = body.setup_seconds();
    let b = body.interactive();
    let start = Instant::now();
    let grasp = Grasp::new(b, grab.vertex, grab.radius).map_err(ProbeError::from)?;
    grasp.hold(b, &RigidMotion::translation(grab.displacement)).map_err(ProbeError::from)?;
    b.update().map_err(ProbeError::from)?;
    let first_frame_seconds = start.elapsed().as_secs_f64();
    Ok(GrabPoint {
        method,
        resolution,
        setup_seconds: Some(setup_seconds),
        first_frame_seconds: Some(first_frame_seconds),
        error_vs_fem: None,
        amplitude_vs_fem: None,
        field: b.field().to_vec(),
        error: None,
    })
}

/// The L2 norm of the stacked displacements.
fn stacked_norm(u: &[Vec3]) -> f64 {
    u.iter().map(|&a| norm(a).powi(2)).sum::<f64>().sqrt()
}

/// The reference row first, then every point, in table order.
fn rows(c: &GrabComparison) -> impl Iterator<Item = &GrabPoint> {
    std::iter::once(&c.reference).chain(&c.points)
}

/// `accuracy-grab.csv`: one row per method (the FEM reference first), times in seconds.
pub fn to_csv(c: &GrabComparison) -> String {
    let mut out = String::from(
        "method,resolution,vertex,ux,uy,uz,setup_seconds,first_frame_seconds,error_vs_fem,amplitude_vs_fem,error\n",
    );
    let f = |v: Option<f64>| v.map(|x| format!("{x:e}")).unwrap_or_default();
    let d = c.grab.displacement;
    for p in rows(c) {
        let cells = [
            p.method.to_string(),
            p.resolution.map(|r| r.to_string()).unwrap_or_default(),
            c.grab.vertex.to_string(),
            format!("{:e}", d[0]),
            format!("{:e}", d[1]),
            format!("{:e}", d[2]),
            f(p.setup_seconds),
            f(p.first_frame_seconds),
            f(p.error_vs_fem),
            f(p.amplitude_vs_fem),
            p.error.as_deref().unwrap_or("").replace(',', ";").replace('\n', " "),
        ];
        out.push_str(&cells.join(","));
        out.push('\n');
    }
    out
}

/// Indices into `points` on the Pareto front of (seconds to the first frame, difference
/// from the FEM reference).
pub fn grab_front(c: &GrabComparison) -> Vec<usize> {
    let idx: Vec<usize> = (0..c.points.len())
        .filter(|&i| {
            c.points[i].seconds_to_first_frame().is_some()
                && c.points[i].error_vs_fem.is_some_and(log_drawable)
        })
        .collect();
    let xy: Vec<(f64, f64)> = idx
        .iter()
        .map(|&i| {
            (c.points[i].seconds_to_first_frame().unwrap_or(0.0), c.points[i].error_vs_fem.unwrap_or(0.0))
        })
        .collect();
    fibfluid::render::pareto_front_with_margin(&xy, PARETO_MARGIN).into_iter().map(|k| idx[k]).collect()
}

/// The grab comparison as Markdown: the grab, then one row per method, Pareto points marked.
pub fn to_markdown(c: &GrabComparison) -> String {
    let (g, d) = (c.grab.rest, c.grab.displacement);
    let mut out = format!(
        "\n#### One grasp, every interactive method (reference: the FEM at resolution {FEM_STUDY_REFERENCE} under the same grab)\n\n\
         No gravity or point forces: a grasp of radius {:.4e} m around vertex {} at ({:.4e}, {:.4e}, {:.4e}) m, the free vertex \
         farthest from the fixed ones, translated by ({:.4e}, {:.4e}, {:.4e}) m (radius and translation {} of the bounding-box diagonal). \
         `*` marks the Pareto front of difference against setup plus first frame.\n\n",
        c.grab.radius, c.grab.vertex, g[0], g[1], g[2], d[0], d[1], d[2], GRAB_FRACTION
    );
    out.push_str(
        "| method | setup (s) | first frame (s) | difference from the FEM | amplitude / FEM's | |\n|---|---|---|---|---|---|\n",
    );
    let front = grab_front(c);
    let f =
        |v: Option<f64>, p: usize| v.map(|x| format!("{x:.prec$}", prec = p)).unwrap_or_else(|| "—".into());
    for (i, p) in rows(c).enumerate() {
        let mark = match (i, &p.error) {
            (0, _) => "reference".to_string(),
            (_, Some(e)) => format!("failed: {e}"),
            _ if front.contains(&(i - 1)) => "*".to_string(),
            _ => String::new(),
        };
        out.push_str(&format!(
            "| {} | {} | {} | {} | {} | {mark} |\n",
            p.label(),
            f(p.setup_seconds, 4),
            f(p.first_frame_seconds, 5),
            f(p.error_vs_fem, 3),
            f(p.amplitude_vs_fem, 2)
        ));
    }
    out
}

/// `accuracy-grab.png`: log-log chart of the difference from the FEM reference against the
/// seconds to the first frame (setup plus first frame): one point per FFM and ChainMail
/// method, one line for the FEM across resolutions, the Pareto front marked.
pub fn chart(c: &GrabComparison, title: &str) -> crate::Result<Vec<u8>> {
    let mut series: Vec<fibfluid::render::Series> = Vec::new();
    for p in &c.points {
        let (Some(t), Some(e)) = (p.seconds_to_first_frame(), p.error_vs_fem) else { continue };
        if !(log_drawable(t) && log_drawable(e)) {
            continue;
        }
        let label = match p.method {
            Method::Fem => format!("fem, resolution {FEM_STUDY_RESOLUTIONS:?}"),
            Method::Ffm => "ffm (paper fibers)".to_string(),
            m => m.to_string(),
        };
        match series.iter_mut().find(|s| s.label == label) {
            Some(s) => s.points.push((t, e)),
            None => series.push(fibfluid::render::Series { label, points: vec![(t, e)] }),
        }
    }
    for s in &mut series {
        s.points.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
    let front: Vec<(f64, f64)> = grab_front(c)
        .into_iter()
        .filter_map(|i| Some((c.points[i].seconds_to_first_frame()?, c.points[i].error_vs_fem?)))
        .filter(|&(t, e)| log_drawable(t) && log_drawable(e))
        .collect();
    Ok(fibfluid::render::loglog_chart(
        title,
        "seconds to the first frame (setup and one grasp)",
        &format!("relative L2 difference from the FEM at resolution {FEM_STUDY_REFERENCE}, same grab"),
        &series,
        &front,
        1200,
        800,
    )?)
}

/// Whether `scene` can be grabbed by every method: a surface mesh (ChainMail and the
/// interactive bodies need one).
pub fn applies(scene: &Scene) -> bool {
    matches!(scene.shape, Shape::Surface(_))
}
