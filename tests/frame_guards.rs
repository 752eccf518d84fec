//! The result guards of interactive frames (`FrameGuards`): shapes whose measures are known
//! in closed form (a scaled, a mirrored, a translated sphere), the errors, and random
//! deformations on which they agree with `check_answer` (the batch runs' guards, measured
//! by `Boundary::volume` and `inverted_faces`).

use fibfluid::Method;
use fibfluid::geometry::{Boundary, Vec3, icosphere};
use fibfluid::interact::{FrameGuardError, FrameGuards};
use fibfluid::sim::result_guards::{ResultChecks, ResultGuard, ResultWarning, check_answer};
use proptest::prelude::*;

const CASES: u32 = if cfg!(feature = "slow-proptests") { 256 } else { 32 };

/// Every guard but the residual (interactive frames have none).
const ALL: ResultChecks = ResultChecks { inverted: true, residual: None, linear: true };

fn sphere() -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let s = icosphere(2, 1.0);
    (s.positions().to_vec(), s.triangles().to_vec())
}

fn map(points: &[Vec3], f: impl Fn(Vec3) -> Vec3) -> Vec<Vec3> {
    points.iter().map(|&p| f(p)).collect()
}

fn guard_names(w: &[ResultWarning]) -> Vec<ResultGuard> {
    w.iter().map(|w| w.guard).collect()
}

/// The bounding-box diagonal of the unit icosphere of level 2 (its extent along each axis).
fn diagonal(rest: &[Vec3]) -> f64 {
    let extent = |a: usize| {
        let (lo, hi) =
            rest.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| (l.min(p[a]), h.max(p[a])));
        hi - lo
    };
    (0..3).map(|a| extent(a).powi(2)).sum::<f64>().sqrt()
}

#[test]
fn the_rest_shape_and_a_rigid_motion_within_the_size_pass() {
    let (rest, tris) = sphere();
    let g = FrameGuards::new(&rest, &tris).unwrap();
    assert_eq!(g.check(&rest, ALL), Ok(vec![]));
    // A turn by 30 degrees about y moves no vertex further than 2 sin(15 deg) = 0.52
    // (radius 1; the diagonal is above 3.4), keeps the volume, and turns no face's area
    // vector against its neighbourhood's.
    let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    let turned = map(&rest, |p| [c * p[0] + s * p[2], p[1], -s * p[0] + c * p[2]]);
    let w = g.check(&turned, ResultChecks::for_frames(Method::Ffm, false)).unwrap();
    assert_eq!(guard_names(&w), vec![]);
}

#[test]
fn a_scaled_body_warns_of_its_volume_by_the_cube_of_the_scale() {
    let (rest, tris) = sphere();
    let g = FrameGuards::new(&rest, &tris).unwrap();
    let grown = map(&rest, |p| p.map(|c| 1.5 * c));
    let w = g.check(&grown, ResultChecks::for_frames(Method::Ffm, false)).unwrap();
    assert_eq!(guard_names(&w), vec![ResultGuard::Volume]);
    assert!((w[0].value - 3.375).abs() < 1e-12, "{}", w[0].value);
    // The same frame of a finite-element body: a vertex moved by 0.5 (radius 1), about
    // 0.15 of the body's size, is past the small-strain limit.
    let w = g.check(&grown, ResultChecks::for_frames(Method::Fem, false)).unwrap();
    assert_eq!(guard_names(&w), vec![ResultGuard::Volume, ResultGuard::Linear]);
    assert!((w[1].value - 0.5 / diagonal(&rest)).abs() < 1e-12);
}

#[test]
fn a_mirrored_body_is_inside_out_as_a_whole_and_a_turned_one_not_at_all() {
    let s = icosphere(2, 1.0);
    let (rest, tris) = (s.positions().to_vec(), s.triangles().to_vec());
    let g = FrameGuards::new(&rest, &tris).unwrap();
    let mirrored = map(&rest, |p| [-p[0], p[1], p[2]]);
    let w = g.check(&mirrored, ResultChecks::for_frames(Method::TsveChainmail, false)).unwrap();
    // Negating x negates every triple product exactly: the volume says the body is inside
    // out. Every face's area vector and its neighbourhood's map alike (by the cofactor of
    // diag(-1, 1, 1), orthogonal), so no face turned against the faces around it, where
    // the plain test (a face's normal against its rest one) counts those with
    // a_x^2 <= a_y^2 + a_z^2.
    assert_eq!(guard_names(&w), vec![ResultGuard::Volume]);
    assert_eq!(w[0].value, -1.0);
    // Turned by 150 degrees about z: every vertex moves at most 2 sin(75 deg) = 1.93 (the
    // diagonal is above 3.4) and the faces whose normal turned against its rest one are
    // many, but none turned inside out.
    let (c, si) = (150f64.to_radians().cos(), 150f64.to_radians().sin());
    let turned = map(&rest, |p| [c * p[0] - si * p[1], si * p[0] + c * p[1], p[2]]);
    let against =
        s.face_area_vectors().iter().filter(|a| c * (a[0] * a[0] + a[1] * a[1]) + a[2] * a[2] <= 0.0).count();
    assert!(against > tris.len() / 3, "{against}");
    assert_eq!(g.check(&turned, ResultChecks::for_frames(Method::Ffm, false)), Ok(vec![]));
}

#[test]
fn a_body_carried_away_warns_of_its_displacement() {
    let (rest, tris) = sphere();
    let g = FrameGuards::new(&rest, &tris).unwrap();
    let size = diagonal(&rest);
    let far = map(&rest, |p| [p[0] + 10.0 * size, p[1], p[2]]);
    let w = g.check(&far, ALL).unwrap();
    // Past the displacement limit, the small-strain guard says nothing more.
    assert_eq!(guard_names(&w), vec![ResultGuard::Displacement]);
    assert!((w[0].value - 10.0).abs() < 1e-12, "{}", w[0].value);
}

#[test]
fn non_finite_frames_wrong_lengths_and_bad_faces_are_errors() {
    let (rest, tris) = sphere();
    let g = FrameGuards::new(&rest, &tris).unwrap();
    let mut bad = rest.clone();
    bad[7][1] = f64::NAN;
    assert_eq!(g.check(&bad, ALL), Err(FrameGuardError::NonFinite { vertex: 7 }));
    // Finite positions whose displacement overflows.
    let mut huge = rest.clone();
    huge[4] = [f64::MAX, 0.0, 0.0];
    huge[5] = [-f64::MAX, 0.0, 0.0];
    assert!(matches!(g.check(&huge, ALL), Err(FrameGuardError::NonFinite { .. })));
    assert_eq!(
        g.check(&rest[1..], ALL),
        Err(FrameGuardError::Count { found: rest.len() - 1, count: rest.len() })
    );
    let mut faces = tris.clone();
    faces[3][2] = rest.len() as u32;
    assert_eq!(
        FrameGuards::new(&rest, &faces),
        Err(FrameGuardError::FaceVertex { face: 3, vertex: rest.len() as u32, count: rest.len() })
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(CASES))]

    /// Random affine maps (reflections included), noise, and one vertex pulled anywhere:
    /// the same warnings as `check_answer`, values equal to rounding.
    #[test]
    fn frames_agree_with_check_answer(
        m in prop::array::uniform9(-2.0..2.0f64),
        noise in prop::collection::vec(prop::array::uniform3(-0.3..0.3f64), 162),
        pulled in 0usize..162,
        pull in prop::array::uniform3(-8.0..8.0f64),
        inverted in any::<bool>(),
        linear in any::<bool>(),
    ) {
        let (rest, tris) = sphere();
        let mut now: Vec<Vec3> = rest
            .iter()
            .zip(&noise)
            .map(|(p, e)| {
                std::array::from_fn(|r| m[3 * r] * p[0] + m[3 * r + 1] * p[1] + m[3 * r + 2] * p[2] + e[r])
            })
            .collect();
        now[pulled] = std::array::from_fn(|a| now[pulled][a] + pull[a]);
        let checks = ResultChecks { inverted, residual: None, linear };
        let frame = FrameGuards::new(&rest, &tris).unwrap().check(&now, checks).unwrap();
        let batch = check_answer(&Boundary::Surface { triangles: tris.clone() }, &rest, &now, checks).unwrap();
        prop_assert_eq!(guard_names(&frame), guard_names(&batch));
        for (f, b) in frame.iter().zip(&batch) {
            prop_assert!((f.value - b.value).abs() <= 1e-9 * b.value.abs().max(1.0), "{:?} vs {:?}", f, b);
            prop_assert_eq!(f.limit, b.limit);
        }
    }
}
