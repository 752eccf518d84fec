//! Tools with a size on every method: a grasp moves its patch exactly and its reactions,
//! applied as forces in a full solve, give the same surface; a press leaves no vertex inside
//! its tip, its contact forces are frictionless and compressive and reproduce the surface,
//! and pressing deeper never lowers the reaction. References: the engine's full solve (FFM)
//! and the FEM's own solve with point forces (a body with pushes and no holds).

use fibfluid_geometry::Vec3;
use fibfluid_geometry::vec3::{cross, dist, dot, norm, sub};
use fibfluid_interact::chainmail_body::ChainmailBody;
use fibfluid_interact::chainmail_settings::{ChainmailSettings, Variant};
use fibfluid_interact::fem_body::FemInteractive;
use fibfluid_interact::{Grasp, InteractError, Interactive, Press, RigidMotion, Storage};
use fibfluid_sim::{ConstraintKind, Method, Model};

use super::{GRAB_TOLERANCE, body, full_solve, mesh_index, relative_difference, sphere};

/// A patch vertex lands where the tool puts it to this, times the body's size (the
/// issue's 1e-9).
const PATCH_TOLERANCE: f64 = 1e-9;

/// The sphere with a tissue for the FEM (E = 50 kPa, nu = 0.45) at a coarse resolution.
pub(super) fn fem_sphere() -> Model {
    let mut m = sphere(ConstraintKind::Eliminate);
    m.tissue = Some(fibfluid_fem::Tissue::new(5e4, 0.45, 1000.0).unwrap());
    m.fem.resolution = 12;
    m.load.forces.clear();
    m
}

fn chainmail(scene: &Model, method: Method) -> ChainmailBody {
    let variant = Variant::of_method(method).unwrap();
    ChainmailBody::from_model(scene, &ChainmailSettings::default(), variant, u64::MAX).unwrap()
}

/// The lowest vertex of the sphere (far from the fixed cap).
pub(super) fn lowest(b: &dyn Interactive) -> usize {
    let r = b.rest_positions();
    (0..r.len()).min_by(|&a, &c| r[a][1].total_cmp(&r[c][1])).unwrap()
}

fn motion() -> RigidMotion {
    RigidMotion::with_rotation_vector([0.03, -0.08, 0.02], [0.0, 0.0, 0.15])
}

/// The mean of the patch's rest positions.
fn rest_centroid(rest: &[Vec3], patch: &[usize]) -> Vec3 {
    let mut c = [0.0; 3];
    for &v in patch {
        (0..3).for_each(|a| c[a] += rest[v][a] / patch.len() as f64);
    }
    c
}

/// Where the rigid motion of translation `t` and rotation vector `w` about `c` takes `p`:
/// `c + t + R (p - c)`, `R (d) = d cos a + (k x d) sin a + k (k . d) (1 - cos a)`.
fn rigidly_moved(p: Vec3, c: Vec3, t: Vec3, w: Vec3) -> Vec3 {
    let a = norm(w);
    let k = w.map(|x| x / a);
    let d = sub(p, c);
    let kd = cross(k, d);
    std::array::from_fn(|i| {
        c[i] + t[i] + d[i] * a.cos() + kd[i] * a.sin() + k[i] * dot(k, d) * (1.0 - a.cos())
    })
}

/// The patch vertices are exactly where the motion takes them.
fn assert_patch_follows(b: &dyn Interactive, g: &Grasp, m: &RigidMotion) {
    let rest = b.rest_positions();
    let c = rest_centroid(rest, g.patch());
    let size = 2.0;
    for &v in g.patch() {
        let e = dist(b.positions()[v], m.apply(c, rest[v]));
        assert!(e <= PATCH_TOLERANCE * size, "{}: patch vertex {v} is {e:e} off", b.method());
    }
}

#[test]
fn a_grasp_moves_its_patch_rigidly_and_its_reactions_reproduce_the_run() {
    let scene = sphere(ConstraintKind::Eliminate);
    let mut b = body(&scene, Storage::F64);
    let g = Grasp::new(&b, lowest(&b), 0.45).unwrap();
    assert!(g.patch().len() >= 5, "a patch, not a vertex: {}", g.patch().len());
    let m = motion();
    g.hold(&mut b, &m).unwrap();
    let reactions = b.update().unwrap().to_vec();
    assert_patch_follows(&b, &g, &m);
    assert_eq!(reactions.len(), g.patch().len(), "one reaction per patch vertex");
    let extra: Vec<(usize, Vec3)> = reactions.iter().filter(|r| g.patch().contains(&r.0)).copied().collect();
    let reference = full_solve(&scene, &extra);
    let d = relative_difference(b.positions(), &reference, b.rest_positions());
    assert!(d <= GRAB_TOLERANCE, "grasp reactions vs the full solve {d:e}");
    // The wrench is the patch's total and its moment about the moved centre.
    let w = g.wrench(&b, &m);
    let c = rest_centroid(b.rest_positions(), g.patch());
    let centre = m.apply(c, c);
    let (mut f, mut mo) = ([0.0; 3], [0.0; 3]);
    for &(v, r) in &extra {
        f = fibfluid_geometry::vec3::add(f, r);
        mo = fibfluid_geometry::vec3::add(mo, cross(sub(b.positions()[v], centre), r));
    }
    assert!(dist(w.force, f) <= 1e-12 * norm(f) && dist(w.moment, mo) <= 1e-12 * norm(mo).max(1e-30));
}

#[test]
fn a_fem_grasp_moves_its_patch_and_its_reactions_reproduce_the_solve() {
    let scene = fem_sphere();
    let mut b = FemInteractive::new(&scene, None).unwrap();
    let g = Grasp::new(&b, lowest(&b), 0.45).unwrap();
    let m = motion();
    g.hold(&mut b, &m).unwrap();
    let reactions = b.update().unwrap().to_vec();
    assert_patch_follows(&b, &g, &m);
    let mut pushed = FemInteractive::new(&scene, None).unwrap();
    for &(v, f) in &reactions {
        pushed.push(v, f).unwrap();
    }
    pushed.update().unwrap();
    let d = relative_difference(b.positions(), pushed.positions(), b.rest_positions());
    assert!(d <= GRAB_TOLERANCE, "FEM grasp reactions vs the solve with them as forces {d:e}");
}

/// A grasp's rotation is one motion: the interactive grasp (`probe`, the viewer, Python's
/// `Body.grasp`) and the batch run's `[[grasp]]` of the same patch, translation and
/// rotation vector put every patch vertex where the rigid motion of the patch about its
/// rest centroid puts it (computed here with Rodrigues' formula).
#[test]
fn an_interactive_grasp_and_a_batch_grasp_turn_the_patch_about_its_centroid() {
    let mut scene = fem_sphere();
    let (t, w) = ([0.03, -0.08, 0.02], [0.0, 0.0, 0.4]);
    let mut b = FemInteractive::new(&scene, None).unwrap();
    let g = Grasp::new(&b, lowest(&b), 0.45).unwrap();
    let rest = b.rest_positions().to_vec();
    let c = rest_centroid(&rest, g.patch());
    assert!(dist(c, rest[g.vertex()]) > 1e-3, "the centroid is not the picked vertex");
    assert!(dist(g.centre(), c) <= 1e-15, "the grasp's centre {:?} against {c:?}", g.centre());
    g.hold(&mut b, &RigidMotion::with_rotation_vector(t, w)).unwrap();
    b.update().unwrap();
    scene.fem.grasps =
        vec![fibfluid_fem::hyper::Grasp { vertices: g.patch().to_vec(), translation: t, rotation: w }];
    let batch = fibfluid_sim::fem_run::FemRun::new(scene, None).unwrap();
    let size = 2.0;
    for &v in g.patch() {
        let target = rigidly_moved(rest[v], c, t, w);
        let interactive = dist(b.positions()[v], target);
        assert!(interactive <= PATCH_TOLERANCE * size, "interactive: vertex {v} is {interactive:e} off");
        // The batch grasp's augmentations stop within 1e-7 of a cell.
        let run = dist(batch.positions[v], target);
        assert!(run <= 1e-7 * size, "batch: vertex {v} is {run:e} off");
    }
}

#[test]
fn a_chainmail_grasp_moves_its_patch_with_the_tool() {
    let scene = sphere(ConstraintKind::Eliminate);
    for method in [Method::TsveChainmail, Method::GeneralizedChainmail] {
        let mut b = chainmail(&scene, method);
        let g = Grasp::new(&b, lowest(&b), 0.3).unwrap();
        let m = RigidMotion::translation([0.02, -0.06, 0.0]);
        g.hold(&mut b, &m).unwrap();
        b.update().unwrap();
        assert_patch_follows(&b, &g, &m);
    }
}

/// Presses a tip of radius 0.6 from below into the sphere at each depth and checks every
/// frame; returns the upward reactions.
pub(super) fn press_checks(b: &mut dyn Interactive, depths: &[f64], forces: bool) -> Vec<f64> {
    b.release_all();
    b.update().unwrap();
    let bottom = b.positions()[lowest(b)];
    eprintln!("{}: base displacement of the lowest vertex {:?}", b.method(), b.field()[lowest(b)]);
    let radius = 0.6;
    let mut tip = Press::new(&*b, radius).unwrap();
    let mut out = Vec::new();
    for &depth in depths {
        let centre = [bottom[0], bottom[1] - radius + depth, bottom[2]];
        let report = tip.place(b, centre).unwrap();
        assert!(!report.contacts.is_empty(), "{}: depth {depth}: no contact", b.method());
        eprintln!(
            "{}: depth {depth}: {} contacts, {} iterations, force {:?}",
            b.method(),
            report.contacts.len(),
            report.iterations,
            report.force
        );
        for (v, x) in b.positions().iter().enumerate() {
            let gap = dist(*x, centre) - radius;
            assert!(gap >= -1e-9 * radius, "{}: vertex {v} is {gap:e} inside the tip", b.method());
        }
        if forces {
            let mut sum = [0.0; 3];
            for &(v, f) in b.reactions() {
                assert!(report.contacts.contains(&v));
                let n = sub(b.positions()[v], centre);
                let n = [n[0] / norm(n), n[1] / norm(n), n[2] / norm(n)];
                let along = dot(f, n);
                let across = norm(sub(f, [n[0] * along, n[1] * along, n[2] * along]));
                assert!(along >= 0.0, "vertex {v}: the contact pulls ({along:e})");
                assert!(across <= 1e-6 * norm(f), "vertex {v}: tangential force {across:e} of {}", norm(f));
                sum = fibfluid_geometry::vec3::add(sum, f);
            }
            assert!(dist(sum, report.force) <= 1e-12 * norm(sum));
        }
        out.push(report.force[1]);
    }
    out
}

#[test]
fn a_press_leaves_no_vertex_inside_and_deeper_never_lowers_the_reaction() {
    let scene = sphere(ConstraintKind::Eliminate);
    let mut b = body(&scene, Storage::F64);
    let depths = [0.05, 0.15, 0.3, 0.45];
    let up = press_checks(&mut b, &depths, true);
    assert!(up[0] > 0.0 && up.windows(2).all(|w| w[1] >= w[0]), "upward reaction by depth {up:?}");
    // The contact forces, applied as forces in a full solve, give the same surface.
    let contacts: Vec<(usize, Vec3)> =
        b.reactions().iter().copied().filter(|r| r.0 != mesh_index(&scene, 3)).collect();
    let reference = full_solve(&scene, &contacts);
    let d = relative_difference(b.positions(), &reference, b.rest_positions());
    assert!(d <= GRAB_TOLERANCE, "press contact forces vs the full solve {d:e}");
}

#[test]
fn a_press_on_the_fem_and_chainmail_leaves_no_vertex_inside() {
    let scene = fem_sphere();
    let mut b = FemInteractive::new(&scene, None).unwrap();
    let up = press_checks(&mut b, &[0.05, 0.15, 0.3], true);
    assert!(up.windows(2).all(|w| w[1] >= w[0]), "FEM upward reaction by depth {up:?}");
    let scene = sphere(ConstraintKind::Eliminate);
    for method in [Method::TsveChainmail, Method::GeneralizedChainmail] {
        let mut b = chainmail(&scene, method);
        press_checks(&mut b, &[0.05, 0.3], false);
    }
}

#[test]
fn bad_tools_are_one_line_errors() {
    let scene = sphere(ConstraintKind::Eliminate);
    let b = body(&scene, Storage::F64);
    let v = lowest(&b);
    for r in [0.0, -0.1, f64::NAN, f64::INFINITY] {
        assert!(matches!(Grasp::new(&b, v, r), Err(InteractError::BadRadius { .. })), "{r}");
        assert!(matches!(Press::new(&b, r), Err(InteractError::BadRadius { .. })), "{r}");
    }
    let e = Grasp::new(&b, v, 5.0).unwrap_err();
    assert!(matches!(e, InteractError::ToolTooLarge { .. }), "{e}");
    assert!(matches!(Press::new(&b, 5.0), Err(InteractError::ToolTooLarge { .. })));
    let top = (0..b.n_vertices()).find(|&u| b.rest_positions()[u][1] > 0.6 && !b.is_fixed(u)).unwrap();
    let e = Grasp::new(&b, top, 0.5).unwrap_err();
    assert!(matches!(e, InteractError::PatchHoldsFixed { .. }), "{e}");
    for e in [e, Grasp::new(&b, v, 0.0).unwrap_err(), Grasp::new(&b, 99_999, 0.1).unwrap_err()] {
        assert!(!e.to_string().contains('\n'), "{e}");
    }
}
