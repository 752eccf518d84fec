//! Property tests (seeded): invariance of area, volume and vertex area vectors under rigid
//! motions and scaling; Eq. 1 = Eq. 2 (`sum |S_i| = sum |A_k|`, `S_i = C R_i`) on random
//! closed meshes; convex bodies keep every fiber; the exact crossing test against an
//! independent floating-point test away from grazing, and the documented grazing policy on
//! configurations that are exact in f64.

use crate::common::*;
use fibfluid_geometry::{
    Crossing, FiberSet, TriMesh, TriangleBvh, VisibilityOptions, cull_fibers, icosphere, segment_triangle,
};
use proptest::prelude::*;
use proptest::test_runner::RngSeed;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Area, volume and `S_i` after a rigid motion and a scaling, relative to the exact
/// transformed value. Translations reach 10 bounding-box diagonals, which costs a few
/// digits in the origin-based volume sum; 1e-9 leaves a wide margin above that rounding.
const RIGID_REL_TOL: f64 = 1e-9;
/// Margin of the independent crossing test: cases whose segment parameter or barycentric
/// coordinates lie within this distance of a boundary (0 or 1) are skipped, and so are
/// segments within this relative angle of the triangle's plane.
const GRAZING_MARGIN: f64 = 1e-6;
/// Triangles skinnier than this (|e1 x e2| / (|e1| |e2|) = sin of the angle) are skipped by
/// the independent test, whose barycentric coordinates lose accuracy as 1 / sin.
const MIN_SINE: f64 = 1e-3;
/// Eq. 1 = Eq. 2 on random meshes: the two sides differ by rounding only, bounded by this
/// many ulps of [`rounding_scale`].
const IDENTITY_ULPS: f64 = 32.0;

fn config(cases: u32) -> ProptestConfig {
    ProptestConfig {
        cases,
        rng_seed: RngSeed::Fixed(0x00f1_bf1d),
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

fn quaternion() -> impl Strategy<Value = [f64; 4]> {
    prop::array::uniform4(-1.0f64..1.0)
        .prop_filter("rotation needs a non-zero quaternion", |q| q.iter().map(|c| c * c).sum::<f64>() > 0.04)
}

/// The meshes of the invariance tests: liver.obj, the torus (genus 1), and a star-shaped
/// bumpy sphere (level-2 icosphere with seeded random radii in [0.75, 1.25]).
fn base_mesh(which: usize, seed: u64) -> TriMesh {
    match which {
        0 => load("liver.obj").mesh,
        1 => load("torus2_for_collision.obj").mesh,
        _ => {
            let sphere = icosphere(2, 1.0);
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let p = sphere.positions().iter().map(|p| mul(*p, rng.random_range(0.75..1.25))).collect();
            TriMesh::new(p, sphere.triangles().to_vec()).unwrap()
        }
    }
}

/// `((b - a) x (c - a)) . (d - a)`, exact for coordinates below 2^40 in magnitude.
fn orient(a: [i64; 3], b: [i64; 3], c: [i64; 3], d: [i64; 3]) -> i128 {
    let [u, v, w] = [b, c, d].map(|p| [0, 1, 2].map(|k| (p[k] - a[k]) as i128));
    let n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
    n[0] * w[0] + n[1] * w[1] + n[2] * w[2]
}

/// Points with integer coordinates and the triangles over them.
type IntegerMesh = (Vec<[i64; 3]>, Vec<[u32; 3]>);

/// Convex hull of points with integer coordinates, by brute force and exactly (written here,
/// not taken from the crate): the triangle (i, j, k) is a face when every other point lies
/// strictly on one side of its plane, and it is oriented so that they lie behind it. Only
/// the points on the hull are kept. None when the points are not in general position (four
/// on a face's plane), when a face would be a polygon rather than a triangle, or when the
/// hull has fewer than five vertices.
fn integer_hull(points: &[[i64; 3]]) -> Option<IntegerMesh> {
    let n = points.len();
    let mut faces = Vec::new();
    for i in 0..n {
        for j in i + 1..n {
            for k in j + 1..n {
                let (mut ahead, mut behind, mut on) = (false, false, false);
                for (l, &d) in points.iter().enumerate() {
                    if l == i || l == j || l == k {
                        continue;
                    }
                    match orient(points[i], points[j], points[k], d).signum() {
                        1 => ahead = true,
                        -1 => behind = true,
                        _ => on = true,
                    }
                    if ahead && behind {
                        break;
                    }
                }
                if ahead && behind {
                    continue;
                }
                if on {
                    return None;
                }
                faces.push(if behind { [i, j, k] } else { [i, k, j] });
            }
        }
    }
    let mut index = vec![u32::MAX; n];
    let mut kept = Vec::new();
    let faces: Vec<[u32; 3]> = faces
        .iter()
        .map(|f| {
            f.map(|v| {
                if index[v] == u32::MAX {
                    index[v] = kept.len() as u32;
                    kept.push(points[v]);
                }
                index[v]
            })
        })
        .collect();
    // A tetrahedron has C = 1 exactly (each R_i is minus the opposite face's vector), so it
    // could not tell whether C is applied: ask for five hull vertices or more.
    (kept.len() >= 5).then_some((kept, faces))
}

/// The closed meshes of the Eq. 1 = Eq. 2 property, drawn from `seed`:
/// 0. a perturbed icosphere (levels 0-3): every vertex moved by a random vector of up to
///    0.3 of the shortest edge, so the faces stay proper triangles but no two are alike;
/// 1. a random star-shaped body: icosphere directions (levels 1-3) at a radius that is a
///    random smooth function (four random plane waves, amplitude 0.15 each) times a random
///    factor in [0.8, 1.2] per vertex: strongly concave and rough;
/// 2. the convex hull of 6 to 40 random points with integer coordinates (three in four near
///    a sphere of radius 2^20, the rest inside), built by [`integer_hull`].
fn random_closed_mesh(family: usize, level: u32, seed: u64) -> TriMesh {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    match family {
        0 => {
            let sphere = icosphere(level, 1.0);
            let shortest = face_edges(&sphere).fold(f64::INFINITY, f64::min);
            let p = sphere
                .positions()
                .iter()
                .map(|p| {
                    add(*p, mul(random_direction(&mut rng), 0.3 * shortest * rng.random_range(0.0..1.0)))
                })
                .collect();
            TriMesh::new(p, sphere.triangles().to_vec()).unwrap()
        }
        1 => {
            let sphere = icosphere(level.max(1), 1.0);
            let waves: Vec<(V3, f64)> = (0..4)
                .map(|_| {
                    (mul(random_direction(&mut rng), rng.random_range(0.5..4.0)), rng.random_range(0.0..6.3))
                })
                .collect();
            let p = sphere
                .positions()
                .iter()
                .map(|d| {
                    let smooth =
                        1.0 + waves.iter().map(|(k, phase)| 0.15 * (dot(*k, *d) + phase).sin()).sum::<f64>();
                    mul(*d, smooth * rng.random_range(0.8..1.2))
                })
                .collect();
            TriMesh::new(p, sphere.triangles().to_vec()).unwrap()
        }
        _ => loop {
            let n = rng.random_range(6..=40);
            let points: Vec<[i64; 3]> = (0..n)
                .map(|_| {
                    let r = if rng.random_bool(0.75) {
                        rng.random_range(0.9..1.0)
                    } else {
                        rng.random_range(0.0..0.6)
                    };
                    mul(random_direction(&mut rng), r * 2f64.powi(20)).map(|c| c.round() as i64)
                })
                .collect();
            if let Some((kept, faces)) = integer_hull(&points) {
                let p = kept.iter().map(|v| v.map(|c| c as f64 * 2f64.powi(-20))).collect();
                break TriMesh::new(p, faces).unwrap();
            }
        },
    }
}

/// A uniformly random unit vector.
fn random_direction(rng: &mut ChaCha8Rng) -> V3 {
    loop {
        let d = [0; 3].map(|_: i32| rng.random_range(-1.0..1.0));
        if (0.01..1.0).contains(&dot(d, d)) {
            return mul(d, 1.0 / norm(d));
        }
    }
}

/// Lengths of every face's edges.
fn face_edges(m: &TriMesh) -> impl Iterator<Item = f64> + '_ {
    let p = m.positions();
    m.triangles().iter().flat_map(move |t| {
        [(0, 1), (1, 2), (2, 0)].map(|(a, b)| norm(sub(p[t[a] as usize], p[t[b] as usize])))
    })
}

/// What rounding in `sum |A_k|` and `sum |S_i|` scales with: each face vector is a cross
/// product of coordinate differences, off by a few ulps of `l (l + |p|max)` for a face whose
/// longest edge is `l` (coordinates far from the origin lose digits in the differences), and
/// each sum of F positive terms is off by up to F ulps of the total.
fn rounding_scale(m: &TriMesh, area: f64) -> f64 {
    let pmax = m.positions().iter().map(|p| norm(*p)).fold(0.0, f64::max);
    let faces: Vec<f64> = face_edges(m).collect();
    let per_face: f64 =
        faces.chunks(3).map(|e| e.iter().fold(0.0f64, |a, b| a.max(*b))).map(|l| l * (l + pmax)).sum();
    per_face + m.n_faces() as f64 * area
}

/// Möller–Trumbore in f64, written here as the independent reference: Some(hit) for the
/// open segment (p, q) against the open triangle, or None when the configuration is within
/// [`GRAZING_MARGIN`] of a boundary and floating point cannot be trusted to decide.
fn moller_trumbore(p: V3, q: V3, a: V3, b: V3, c: V3) -> Option<bool> {
    let d = sub(q, p);
    let (e1, e2) = (sub(b, a), sub(c, a));
    let h = cross(d, e2);
    let det = dot(e1, h);
    if det.abs() <= GRAZING_MARGIN * norm(d) * norm(cross(e1, e2)) {
        return None;
    }
    let f = 1.0 / det;
    let s = sub(p, a);
    let u = f * dot(s, h);
    let qv = cross(s, e1);
    let v = f * dot(d, qv);
    let t = f * dot(e2, qv);
    if [u, v, 1.0 - u - v, t, 1.0 - t].iter().any(|x| x.abs() < GRAZING_MARGIN) {
        return None;
    }
    Some(u > 0.0 && v > 0.0 && u + v < 1.0 && t > 0.0 && t < 1.0)
}

/// The classification must not depend on the direction of the segment nor on which corner
/// of the triangle comes first, nor on the triangle's orientation.
fn all_orders(p: V3, q: V3, a: V3, b: V3, c: V3) -> Vec<Crossing> {
    let mut out = Vec::new();
    for (x, y) in [(p, q), (q, p)] {
        for (r, s, t) in [(a, b, c), (b, c, a), (c, a, b), (a, c, b), (c, b, a), (b, a, c)] {
            out.push(segment_triangle(x, y, r, s, t));
        }
    }
    out
}

fn assert_all(p: V3, q: V3, a: V3, b: V3, c: V3, want: Crossing, what: &str) {
    for (k, got) in all_orders(p, q, a, b, c).into_iter().enumerate() {
        assert_eq!(got, want, "{what}, order {k}: p {p:?} q {q:?} triangle {a:?} {b:?} {c:?}");
    }
}

proptest! {
    #![proptest_config(config(64))]

    /// Area and volume are invariant under rotation + translation and scale as s^2, s^3;
    /// a mirror keeps the area and negates the volume; `S_i` rotates with the mesh and scales
    /// as s^2 (Eq. 2 is built from cross products of edge vectors).
    #[test]
    fn rigid_motion_and_scaling(
        which in 0usize..3,
        seed in any::<u64>(),
        q in quaternion(),
        shift in prop::array::uniform3(-10.0f64..10.0),
        s in 0.1f64..10.0,
    ) {
        let m = base_mesh(which, seed);
        let (area, vol, sv) = (m.area(), m.volume(), m.vertex_area_vectors());
        let r = rotation(q);
        let t = mul(shift, m.diagonal());
        let moved: Vec<V3> = m.positions().iter().map(|p| add(mul(apply(&r, *p), s), t)).collect();
        let mm = TriMesh::new(moved.clone(), m.triangles().to_vec()).unwrap();
        let (a2, v2) = (mm.area(), mm.volume());
        prop_assert!((a2 - s * s * area).abs() <= RIGID_REL_TOL * s * s * area, "area {a2} vs {}", s * s * area);
        let v_want = s * s * s * vol;
        prop_assert!((v2 - v_want).abs() <= RIGID_REL_TOL * v_want, "volume {v2} vs {v_want}");

        let smax = sv.iter().map(|x| norm(*x)).fold(0.0, f64::max);
        for (i, (moved_s, si)) in mm.vertex_area_vectors().iter().zip(&sv).enumerate() {
            let want = mul(apply(&r, *si), s * s);
            prop_assert!(norm(sub(*moved_s, want)) <= RIGID_REL_TOL * s * s * smax,
                "S_{} = {:?}, rotated original {:?}", i, moved_s, want);
        }

        let mirrored: Vec<V3> = moved.iter().map(|p| [-p[0], p[1], p[2]]).collect();
        let mirror = TriMesh::new(mirrored, m.triangles().to_vec()).unwrap();
        prop_assert!((mirror.area() - a2).abs() <= RIGID_REL_TOL * a2);
        prop_assert!((mirror.volume() + v2).abs() <= RIGID_REL_TOL * v2);
    }
}

proptest! {
    #![proptest_config(config(96))]

    /// Eq. 1 = Eq. 2 on random closed meshes ([`random_closed_mesh`]: perturbed icospheres,
    /// random star-shaped bodies, convex hulls of random points), after a random rotation,
    /// anisotropic scaling (0.2 to 5 per axis) and translation (up to 10 diagonals):
    /// `sum |S_i|` from the crate equals `sum |A_k|` computed here with another cross product,
    /// and `S_i = c R_i` vertex by vertex with `c = sum |A_k| / sum |R_i|`, both from the
    /// plain loops of `common`. The tolerance is [`IDENTITY_ULPS`] ulps of the mesh's
    /// [`rounding_scale`]. The property would fail without the global factor C: on every
    /// mesh drawn `sum |R_i|` differs from the area by more than 1000 times the tolerance
    /// (by 17 % to 195 % on the seeded cases), which is asserted too.
    #[test]
    fn eq1_equals_eq2_on_random_closed_meshes(
        family in 0usize..3,
        level in 0u32..4,
        seed in any::<u64>(),
        q in quaternion(),
        axes in prop::array::uniform3(0.2f64..5.0),
        shift in prop::array::uniform3(-10.0f64..10.0),
    ) {
        let base = random_closed_mesh(family, level, seed);
        let r = rotation(q);
        let t = mul(shift, base.diagonal() * axes.iter().fold(0.0f64, |a, b| a.max(*b)));
        let moved = base.positions().iter().map(|p| add(apply(&r, [p[0] * axes[0], p[1] * axes[1], p[2] * axes[2]]), t));
        let mut m = TriMesh::new(moved.collect(), base.triangles().to_vec()).unwrap();
        let v = m.validate().unwrap();
        prop_assert_eq!(v.genus, 0);
        prop_assert!(!v.flipped, "the random meshes are built outward");

        let area = area_independent(m.positions(), m.triangles());
        let rel = IDENTITY_ULPS * f64::EPSILON * rounding_scale(&m, area) / area;
        let s = m.vertex_area_vectors();
        let s_sum: f64 = s.iter().map(|x| norm(*x)).sum();
        prop_assert!((s_sum - area).abs() <= rel * area, "sum |S| {} vs sum |A| {} (tolerance {:e} relative)", s_sum, area, rel);

        let raw = raw_vectors(&m);
        let raw_sum: f64 = raw.iter().map(|x| norm(*x)).sum();
        prop_assert!((raw_sum - area).abs() > 1e3 * rel * area, "sum |R| {} is as close as the area {}: C is 1", raw_sum, area);
        let c = area / raw_sum;
        let smax = s.iter().map(|x| norm(*x)).fold(0.0, f64::max);
        for (i, (si, ri)) in s.iter().zip(&raw).enumerate() {
            prop_assert!(norm(sub(*si, mul(*ri, c))) <= rel * smax, "vertex {}: S {:?} vs C R {:?}", i, si, mul(*ri, c));
        }
    }
}

proptest! {
    #![proptest_config(config(32))]

    /// Random convex meshes keep all N(N-1)/2 fibers, through the convexity shortcut and
    /// with both tests forced. The convex meshes are icospheres (levels 0-2) mapped by a random
    /// invertible affine map (axes 0.2..5, rotation, translation) onto an ellipsoid: an affine
    /// image of a convex polyhedron is convex with the same faces, so the triangulation is
    /// known to be the hull without writing (and trusting) a hull routine, and the mesh has no
    /// coplanar neighbouring faces that would turn the test into a grazing test. The same
    /// mesh with one vertex pulled 70 % of the way to the centre is concave: it must not pass
    /// as convex and must lose fibers, so the test can tell the two apart.
    #[test]
    fn convex_bodies_keep_every_fiber(
        level in 0u32..3,
        axes in prop::array::uniform3(0.2f64..5.0),
        q in quaternion(),
        shift in prop::array::uniform3(-10.0f64..10.0),
    ) {
        let r = rotation(q);
        let sphere = icosphere(level, 1.0);
        let map = |p: V3| add(apply(&r, [p[0] * axes[0], p[1] * axes[1], p[2] * axes[2]]), shift);
        let positions: Vec<V3> = sphere.positions().iter().map(|p| map(*p)).collect();
        let mut m = TriMesh::new(positions, sphere.triangles().to_vec()).unwrap();
        let v = m.validate().unwrap();
        prop_assert!(!v.flipped);
        let n = m.n_vertices();
        let all = FiberSet::all(n);
        prop_assert_eq!(all.kept(), n * (n - 1) / 2);
        prop_assert!(m.is_convex());

        let (set, rep) = cull_fibers(&m, &VisibilityOptions::default());
        prop_assert!(rep.convex);
        prop_assert_eq!(&set, &all);
        prop_assert_eq!(set.mean_connections(), (n - 1) as f64);

        let forced = VisibilityOptions { force_tests: true, ..VisibilityOptions::default() };
        let (set, rep) = cull_fibers(&m, &forced);
        prop_assert!(!rep.convex);
        prop_assert_eq!((rep.removed_by_exit, rep.removed_by_crossing), (0, 0));
        prop_assert_eq!(&set, &all);

        let mut dented = m.positions().to_vec();
        dented[0] = add(shift, mul(sub(dented[0], shift), 0.3));
        let mut d = TriMesh::new(dented, m.triangles().to_vec()).unwrap();
        d.validate().unwrap();
        prop_assert!(!d.is_convex());
        let (set, rep) = cull_fibers(&d, &VisibilityOptions::default());
        prop_assert!(!rep.convex);
        prop_assert!(set.kept() < all.kept());
        prop_assert_eq!(rep.removed_by_exit + rep.removed_by_crossing + set.kept(), all.kept());
    }
}

proptest! {
    #![proptest_config(config(20_000))]

    /// Away from grazing, the exact test agrees with Möller–Trumbore: Interior when the
    /// independent test hits, None when it misses. The segment is aimed at a random point of
    /// the triangle's plane (barycentric -0.25..1) so that a good share of cases hit. The
    /// answer is the same in every order of the inputs and after scaling by powers of two
    /// (which is exact in f64).
    #[test]
    fn crossing_agrees_with_moller_trumbore(
        a in prop::array::uniform3(-1.0f64..1.0),
        b in prop::array::uniform3(-1.0f64..1.0),
        c in prop::array::uniform3(-1.0f64..1.0),
        u in -0.25f64..1.0,
        v in -0.25f64..1.0,
        d in prop::array::uniform3(-1.0f64..1.0),
        s1 in -0.5f64..1.5,
        s2 in -0.5f64..1.5,
    ) {
        let (e1, e2) = (sub(b, a), sub(c, a));
        prop_assume!(norm(cross(e1, e2)) > MIN_SINE * norm(e1) * norm(e2));
        let x = add(a, add(mul(e1, u), mul(e2, v)));
        let (p, q) = (sub(x, mul(d, s1)), add(x, mul(d, s2)));
        let reference = moller_trumbore(p, q, a, b, c);
        prop_assume!(reference.is_some());
        let want = if reference == Some(true) { Crossing::Interior } else { Crossing::None };
        for got in all_orders(p, q, a, b, c) {
            prop_assert_eq!(got, want);
        }
        for k in [-60, 60] {
            let f = 2f64.powi(k);
            prop_assert_eq!(segment_triangle(mul(p, f), mul(q, f), mul(a, f), mul(b, f), mul(c, f)), want);
        }
    }

    /// A segment that starts exactly at one of the triangle's corners never counts as a
    /// crossing (Chirkov's published test reports one in a few percent of such cases from
    /// rounding alone).
    #[test]
    fn segment_from_a_corner_never_crosses(
        a in prop::array::uniform3(-1.0f64..1.0),
        b in prop::array::uniform3(-1.0f64..1.0),
        c in prop::array::uniform3(-1.0f64..1.0),
        q in prop::array::uniform3(-1.0f64..1.0),
        corner in 0usize..3,
    ) {
        let p = [a, b, c][corner];
        prop_assert_eq!(segment_triangle(p, q, a, b, c), Crossing::None);
        prop_assert_eq!(segment_triangle(q, p, a, b, c), Crossing::None);
    }
}

fn f(v: [i64; 3], shift: [i64; 3], pow: i32) -> V3 {
    let s = 2f64.powi(pow);
    [(v[0] + shift[0]) as f64 * s, (v[1] + shift[1]) as f64 * s, (v[2] + shift[2]) as f64 * s]
}

fn iadd(a: [i64; 3], b: [i64; 3]) -> [i64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn isub(a: [i64; 3], b: [i64; 3]) -> [i64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn imul(a: [i64; 3], k: i64) -> [i64; 3] {
    [a[0] * k, a[1] * k, a[2] * k]
}

proptest! {
    #![proptest_config(config(3_000))]

    /// The grazing policy of src/crossing.rs on configurations built from small integers, so
    /// that every point is exact in f64 (the triangle is scaled by 6 so that edge midpoints
    /// and the centroid are integers; then everything is shifted by an integer vector and
    /// scaled by a power of two from 2^-40 to 2^40, both exact):
    /// through the interior -> Interior; through an edge -> Edge; through a corner -> Vertex;
    /// an endpoint on the plane (inside, on an edge, at a corner) -> None; in the plane ->
    /// Coplanar, which does not remove a fiber; short of the plane or past the triangle -> None.
/// Every crossing case is also found through a [`TriangleBvh`] over the triangle.
    #[test]
    fn grazing_policy_on_exact_configurations(
        a in prop::array::uniform3(-8i64..=8),
        b in prop::array::uniform3(-8i64..=8),
        c in prop::array::uniform3(-8i64..=8),
        d in prop::array::uniform3(-8i64..=8),
        k in 1i64..4,
        shift in prop::array::uniform3(-100i64..100),
        pow in -40i32..=40,
    ) {
        let n = {
            let (u, v) = (isub(b, a), isub(c, a));
            [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
        };
        prop_assume!(n != [0, 0, 0]);
        prop_assume!(n[0] * d[0] + n[1] * d[1] + n[2] * d[2] != 0);
        let (ta, tb, tc) = (imul(a, 6), imul(b, 6), imul(c, 6));
        let g = imul(iadd(iadd(a, b), c), 2);
        let mids = [imul(iadd(a, b), 3), imul(iadd(b, c), 3), imul(iadd(c, a), 3)];
        let corners = [ta, tb, tc];
        let kd = imul(d, k);
        let x = |v: [i64; 3]| f(v, shift, pow);
        let (fa, fb, fc) = (x(ta), x(tb), x(tc));
        // The BVH must hand every triangle that the policy counts as crossed to the exact
        // test, including contacts at a corner of the triangle's bounding box where the
        // segment meets the box in a single point (this is what the box padding is for).
        let bvh = TriangleBvh::new(&[fa, fb, fc], &[[0, 1, 2]]);
        let check = |p: [i64; 3], q: [i64; 3], want: Crossing, what: &str| {
            assert_all(x(p), x(q), fa, fb, fc, want, what);
            if want.removes_fiber() {
                for (s, t) in [(x(p), x(q)), (x(q), x(p))] {
                    assert!(bvh.any_on_segment(s, t, |k| k == 0), "{what}: the BVH skipped the triangle");
                }
            }
        };

        check(isub(g, d), iadd(g, kd), Crossing::Interior, "through the centroid");
        check(g, iadd(g, kd), Crossing::None, "starts at the centroid");
        check(iadd(g, d), iadd(g, iadd(d, kd)), Crossing::None, "short of the plane");
        for m in mids {
            check(isub(m, kd), iadd(m, d), Crossing::Edge, "through an edge midpoint");
            check(m, isub(m, d), Crossing::None, "starts on an edge");
            // Beyond the edge, in the plane: 2m - g is outside the triangle.
            let out = isub(imul(m, 2), g);
            check(isub(out, d), iadd(out, kd), Crossing::None, "past an edge");
        }
        for v in corners {
            check(isub(v, d), iadd(v, kd), Crossing::Vertex, "through a corner");
            check(iadd(v, kd), v, Crossing::None, "ends at a corner");
            let out = isub(imul(v, 2), g);
            check(isub(out, kd), iadd(out, d), Crossing::None, "past a corner");
        }
        // In the plane: across the whole triangle, and entirely outside it.
        let across = (isub(imul(ta, 2), g), isub(imul(mids[1], 2), g));
        check(across.0, across.1, Crossing::Coplanar, "coplanar through the triangle");
        check(isub(imul(ta, 3), imul(g, 2)), isub(imul(ta, 4), imul(g, 3)), Crossing::Coplanar, "coplanar outside");
        prop_assert!(!Crossing::Coplanar.removes_fiber());
    }
}

proptest! {
    #![proptest_config(config(2_000))]

    /// The BVH's boxes must not decide grazing contacts. Here the triangle's corner v is the
    /// maximum corner of its bounding box and the segment passes through v in a direction
    /// (+, -, any): it meets the box in the single point v, where the slab test's rounded
    /// parameters may disagree by an ulp. The exact test says Vertex, and the BVH query over
    /// the triangle must hand it over. (Without the box padding about a fifth of these
    /// contacts are lost.) Small integers, an integer shift and a power-of-two scale keep
    /// every coordinate exact.
    #[test]
    fn bvh_finds_contacts_at_box_corners(
        v in prop::array::uniform3(-50i64..=50),
        db in prop::array::uniform3(1i64..=20),
        dc in prop::array::uniform3(1i64..=20),
        d in (1i64..=30, 1i64..=30, -30i64..=30),
        k1 in 1i64..=7,
        k2 in 1i64..=7,
        pow in -20i32..=20,
    ) {
        let (b, c) = (isub(v, db), isub(v, dc));
        let d = [d.0, -d.1, d.2];
        let n = {
            let (u, w) = (isub(b, v), isub(c, v));
            [u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]]
        };
        prop_assume!(n != [0, 0, 0] && n[0] * d[0] + n[1] * d[1] + n[2] * d[2] != 0);
        let x = |p: [i64; 3]| f(p, [0, 0, 0], pow);
        let (p, q) = (x(isub(v, imul(d, k1))), x(iadd(v, imul(d, k2))));
        let tri = [x(v), x(b), x(c)];
        prop_assert_eq!(segment_triangle(p, q, tri[0], tri[1], tri[2]), Crossing::Vertex);
        let bvh = TriangleBvh::new(&tri, &[[0, 1, 2]]);
        prop_assert!(bvh.any_on_segment(p, q, |k| k == 0));
        prop_assert!(bvh.any_on_segment(q, p, |k| k == 0));
    }
}

/// The same policy on explicit configurations against the triangle (0,0,0), (4,0,0),
/// (0,4,0) in z = 0, and the two traps named in REFERENCE §2: a segment through an edge
/// shared by two faces must be seen by both, and a segment through a vertex shared by a fan
/// of faces must be seen by all of them.
#[test]
fn grazing_policy_by_hand() {
    let (a, b, c) = ([0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [0.0, 4.0, 0.0]);
    let cases: &[(V3, V3, Crossing, &str)] = &[
        ([1.0, 1.0, -1.0], [1.0, 1.0, 1.0], Crossing::Interior, "vertical through (1,1)"),
        ([0.0, 1.0, -1.0], [2.0, 1.0, 3.0], Crossing::Interior, "oblique through (0.5,1)"),
        ([2.0, 0.0, -1.0], [2.0, 0.0, 1.0], Crossing::Edge, "through (2,0) on edge ab"),
        ([1.0, 3.0, -1.0], [3.0, 1.0, 1.0], Crossing::Edge, "oblique through (2,2) on edge bc"),
        ([0.0, 3.0, -2.0], [0.0, 1.0, 2.0], Crossing::Edge, "through (0,2) on edge ca"),
        ([0.0, 0.0, -1.0], [0.0, 0.0, 1.0], Crossing::Vertex, "through corner a"),
        ([3.0, -1.0, -1.0], [5.0, 1.0, 1.0], Crossing::Vertex, "oblique through corner b"),
        ([-1.0, 5.0, -1.0], [1.0, 3.0, 1.0], Crossing::Vertex, "oblique through corner c"),
        ([-1.0, 1.0, -1.0], [-1.0, 1.0, 1.0], Crossing::None, "beside edge ca"),
        ([3.0, 3.0, -1.0], [3.0, 3.0, 1.0], Crossing::None, "beyond edge bc"),
        ([1.0, 1.0, 0.0], [1.0, 1.0, 5.0], Crossing::None, "starts inside the triangle"),
        ([2.0, 0.0, 0.0], [2.0, 0.0, -5.0], Crossing::None, "starts on an edge"),
        ([0.0, 4.0, 0.0], [1.0, 1.0, 1.0], Crossing::None, "starts at a corner"),
        ([1.0, 1.0, 1.0], [1.0, 1.0, 3.0], Crossing::None, "above, not reaching the plane"),
        ([1.0, 1.0, 0.0], [5.0, 5.0, 0.0], Crossing::Coplanar, "in the plane, leaving the triangle"),
        ([9.0, 9.0, 0.0], [8.0, 10.0, 0.0], Crossing::Coplanar, "in the plane, far away"),
    ];
    for &(p, q, want, what) in cases {
        assert_all(p, q, a, b, c, want, what);
        // Large and tiny copies (exact): no size-dependent threshold.
        for s in [2f64.powi(50), 2f64.powi(-50)] {
            let sc = |v: V3| mul(v, s);
            assert_all(sc(p), sc(q), sc(a), sc(b), sc(c), want, what);
        }
    }
    assert!(Crossing::Interior.removes_fiber());
    assert!(Crossing::Edge.removes_fiber());
    assert!(Crossing::Vertex.removes_fiber());
    assert!(!Crossing::Coplanar.removes_fiber());
    assert!(!Crossing::None.removes_fiber());

    // Edge (4,0,0)-(0,4,0) shared by two faces; the segment goes through its midpoint.
    let d = [4.0, 4.0, 0.0];
    let (p, q) = ([2.0, 2.0, -3.0], [2.0, 2.0, 1.0]);
    assert_eq!(segment_triangle(p, q, a, b, c), Crossing::Edge);
    assert_eq!(segment_triangle(p, q, b, d, c), Crossing::Edge);
    // A fan of six faces around (0,0,1) (a hexagonal pyramid); the segment goes through it.
    let apex = [0.0, 0.0, 1.0];
    let ring = [
        [2.0, 0.0, 0.0],
        [1.0, 2.0, 0.0],
        [-1.0, 2.0, 0.0],
        [-2.0, 0.0, 0.0],
        [-1.0, -2.0, 0.0],
        [1.0, -2.0, 0.0],
    ];
    for (p, q) in [([0.0, 0.0, 3.0], [0.0, 0.0, -1.0]), ([1.0, 1.0, 2.0], [-1.0, -1.0, 0.0])] {
        for i in 0..6 {
            assert_eq!(
                segment_triangle(p, q, apex, ring[i], ring[(i + 1) % 6]),
                Crossing::Vertex,
                "fan face {i}"
            );
        }
    }
}
