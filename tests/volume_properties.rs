//! Property tests over random bodies, materials and loads: the volume-refreshing mode keeps
//! the enclosed volume, and in paper mode every step satisfies the (frozen) volume row.
//! More cases with `--features slow-proptests`.

use fibfluid::assembly::{Material, Selector};
use fibfluid::geometry::{MeshFile, TriMesh, Vec3, icosphere};
use fibfluid::{ForceTiming, Mode, PointForce, Scene, Simulation, Stepping};
use proptest::prelude::*;

const CASES: u32 = if cfg!(feature = "slow-proptests") { 256 } else { 12 };

/// Volume error accepted after refresh-mode steps (the correction stops at 1e-12).
const REFRESH_VOLUME: f64 = 1e-10;

fn ellipsoid(level: u32, axes: Vec3, angle: f64) -> TriMesh {
    let ico = icosphere(level, 1.0);
    let (c, s) = (angle.cos(), angle.sin());
    let pos = ico
        .positions()
        .iter()
        .map(|p| {
            let q = [p[0] * axes[0], p[1] * axes[1], p[2] * axes[2]];
            [c * q[0] - s * q[2], q[1], s * q[0] + c * q[2]]
        })
        .collect();
    let mut m = TriMesh::new(pos, ico.triangles().to_vec()).unwrap();
    m.validate().unwrap();
    m
}

fn scene(
    mesh: TriMesh,
    young: f64,
    gamma_ratio: f64,
    density: f64,
    g: Vec3,
    force: Vec3,
    mode: Mode,
    stepping: Stepping,
) -> Scene {
    let n = mesh.n_vertices();
    let diag = mesh.diagonal();
    let file = MeshFile::from_mesh("random", mesh).unwrap();
    // Sized so the sag stays a few percent of the body (see tests/hard_cases.rs).
    let y = young * 10.0 * density * 9.81 * diag;
    let mut s = Scene::from_mesh("random", file, Material::isotropic(y, y * gamma_ratio, density));
    let pos = s.rest_positions();
    s.constraints.fix_selected(&Selector::Top { axis: 1, within: 0.15 * diag }, &pos, [true; 3]).unwrap();
    s.load.gravity = g;
    let bottom = (0..n).min_by(|&a, &b| pos[a][1].total_cmp(&pos[b][1])).unwrap();
    s.load.forces = vec![PointForce {
        vertex: bottom,
        value: force.map(|c| c * y * diag / 100.0),
        timing: ForceTiming::Ramp,
    }];
    s.load.steps = 3;
    s.solver.mode = mode;
    s.solver.stepping = stepping;
    s.solver.constraints = fibfluid::ConstraintKind::Eliminate;
    s
}

fn arb_case() -> impl Strategy<Value = (Vec3, f64, f64, f64, f64, Vec3, Vec3, bool)> {
    (
        [0.5f64..2.0, 0.5f64..2.0, 0.5f64..2.0],
        0.0f64..std::f64::consts::TAU,
        0.5f64..4.0,
        prop_oneof![Just(0.0), 1e-3f64..1.0],
        prop_oneof![Just(0.0), 1.0f64..3000.0],
        [-12.0f64..12.0, -12.0f64..-1.0, -12.0f64..12.0],
        [-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0],
        any::<bool>(),
    )
}

proptest! {
    #![proptest_config(ProptestConfig { cases: CASES, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn refresh_mode_keeps_the_enclosed_volume(case in arb_case()) {
        let (axes, angle, young, gamma_ratio, density, g, f, heun) = case;
        let stepping = if heun { Stepping::Heun } else { Stepping::Euler };
        let s = scene(ellipsoid(1, axes, angle), young, gamma_ratio, density.max(1.0), g, f, Mode::Refresh, stepping);
        let mut sim = Simulation::new(s).unwrap();
        for k in 0..3 {
            sim.step_load((k + 1) as f64 / 3.0).unwrap();
            let drift = (sim.volume() / sim.volume_initial() - 1.0).abs();
            prop_assert!(drift <= REFRESH_VOLUME, "step {k}: drift {drift:e}");
        }
        prop_assert!(sim.counters().residual_max < 1e-12);
    }

    #[test]
    fn paper_steps_satisfy_the_frozen_volume_row(case in arb_case()) {
        let (axes, angle, young, gamma_ratio, density, g, f, _) = case;
        let s = scene(ellipsoid(1, axes, angle), young, gamma_ratio, density.max(1.0), g, f, Mode::Paper, Stepping::Euler);
        let mut sim = Simulation::new(s).unwrap();
        // The volume row of paper mode is sum S0_i . u_i = 0 with S0 the rest border.
        let s0 = sim.rest_positions().to_vec();
        let areas = fibfluid::geometry::vertex_area_vectors(&s0, match &sim.model().shape { fibfluid::Shape::Surface(m) => m.mesh.triangles(), _ => unreachable!() });
        let scale: f64 = areas.iter().map(|a| (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()).sum();
        for k in 0..3 {
            let before = sim.positions().to_vec();
            sim.step_load((k + 1) as f64 / 3.0).unwrap();
            let row: f64 = sim.positions().iter().zip(&before).zip(&areas).map(|((p, q), a)| (0..3).map(|c| a[c] * (p[c] - q[c])).sum::<f64>()).sum();
            let du = sim.positions().iter().zip(&before).map(|(p, q)| (0..3).map(|c| (p[c] - q[c]).abs()).fold(0.0, f64::max)).fold(0.0, f64::max);
            // Size-scaled: the row's terms are |S| |du|, summed over N vertices.
            prop_assert!(row.abs() <= 1e-12 * scale * du.max(1e-300) * 10.0, "step {k}: row {row:e}, |S| {scale:e}, du {du:e}");
        }
    }
}
