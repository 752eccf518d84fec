//! Fiber culling on concave fixtures: no kept fiber crosses the surface or leaves the body
//! at an end, and the BVH-accelerated culling equals a brute-force culling written here
//! (exit test over the triangle list + crossing test over every face). Convex fixtures keep
//! every fiber with the tests forced, including the dome whose flat base makes many fibers
//! run exactly in a face plane.

use crate::common::*;
use fibfluid_geometry::{
    EXIT_TOLERANCE, FiberSet, TriMesh, VisibilityOptions, crosses_surface_brute_force, cull_fibers,
};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// Vertex pairs (i, j).
type Pairs = Vec<(usize, usize)>;

/// Fibers checked one by one on the bunny (kept and removed samples each).
const BUNNY_SAMPLE: usize = 4000;

/// Brute-force culling: every pair, the exit test at both ends over the triangle list, then
/// the crossing test against every face.
fn brute_force_culling(m: &TriMesh) -> FiberSet {
    let faces = face_vectors(m);
    let n = m.n_vertices();
    let rows: Vec<Vec<u32>> = (0..n)
        .map(|i| {
            (i + 1..n)
                .filter(|&j| {
                    !exits_at(m, &faces, i, j, EXIT_TOLERANCE)
                        && !exits_at(m, &faces, j, i, EXIT_TOLERANCE)
                        && !crosses_surface_brute_force(m, i, j)
                })
                .map(|j| j as u32)
                .collect()
        })
        .collect();
    FiberSet::from_rows(n, &rows)
}

fn check_equals_brute_force(name: &str) {
    let m = load(name).mesh;
    let (set, rep) = cull_fibers(&m, &VisibilityOptions::default());
    eprintln!(
        "{name}: N = {}, kept {} of {} fibers (exit removed {}, crossing removed {}), mean connections {:.2}",
        m.n_vertices(),
        set.kept(),
        set.total(),
        rep.removed_by_exit,
        rep.removed_by_crossing,
        set.mean_connections()
    );
    assert!(!rep.convex, "{name} is concave");
    let brute = brute_force_culling(&m);
    // Same set, and the per-vertex counts and totals agree with the pairs.
    assert_eq!(set.kept(), brute.kept(), "{name}: kept count");
    let differ: Vec<(usize, usize)> = (0..m.n_vertices())
        .flat_map(|i| (i + 1..m.n_vertices()).map(move |j| (i, j)))
        .filter(|&(i, j)| set.contains(i, j) != brute.contains(i, j))
        .take(10)
        .collect();
    assert!(differ.is_empty(), "{name}: accelerated and brute-force culling differ at {differ:?}");
    assert_eq!(set, brute);
    assert_eq!(rep.removed_by_exit + rep.removed_by_crossing + set.kept(), set.total());
    assert!(rep.removed_by_crossing > 0, "{name}: a concave body has fibers that cross the surface");
    let faces = face_vectors(&m);
    let exit_removed = (0..m.n_vertices())
        .flat_map(|i| (i + 1..m.n_vertices()).map(move |j| (i, j)))
        .filter(|&(i, j)| {
            exits_at(&m, &faces, i, j, EXIT_TOLERANCE) || exits_at(&m, &faces, j, i, EXIT_TOLERANCE)
        })
        .count();
    assert_eq!(rep.removed_by_exit, exit_removed, "{name}: fibers removed by the exit test");
    let per_vertex: Vec<u32> = (0..m.n_vertices())
        .map(|i| (0..m.n_vertices()).filter(|&j| brute.contains(i, j)).count() as u32)
        .collect();
    assert_eq!(set.per_vertex(), &per_vertex[..]);
    assert_eq!(set.pairs().count(), set.kept());
}

/// Torus (genus 1, 200 vertices): every kept fiber is checked against every face, and the
/// whole set equals the brute-force culling.
#[test]
fn torus_culling_equals_brute_force() {
    check_equals_brute_force("torus2_for_collision.obj");
}

/// liver.obj (139 referenced vertices): the same comparison.
#[test]
fn liver_culling_equals_brute_force() {
    check_equals_brute_force("liver.obj");
}

/// Bunny (1366 vertices, ~0.9 M candidate fibers): a seeded random sample of kept fibers
/// neither leaves the body at an end nor crosses any face; a sample of removed fibers each
/// fails one of the two tests (so nothing is removed without cause).
#[test]
fn bunny_kept_fibers_stay_inside() {
    let m = load("Bunny.stl").mesh;
    let (set, rep) = cull_fibers(&m, &VisibilityOptions::default());
    eprintln!(
        "Bunny.stl: N = {}, kept {} of {} fibers (exit removed {}, crossing removed {}), {:.3} s",
        m.n_vertices(),
        set.kept(),
        set.total(),
        rep.removed_by_exit,
        rep.removed_by_crossing,
        rep.seconds
    );
    assert!(!rep.convex);
    assert_eq!(rep.removed_by_exit + rep.removed_by_crossing + set.kept(), set.total());
    let n = m.n_vertices();
    let (kept, removed): (Pairs, Pairs) =
        (0..n).flat_map(|i| (i + 1..n).map(move |j| (i, j))).partition(|&(i, j)| set.contains(i, j));
    assert_eq!(kept.len(), set.kept());
    let faces = face_vectors(&m);
    let mut rng = ChaCha8Rng::seed_from_u64(0xb0_55);
    for k in rand::seq::index::sample(&mut rng, kept.len(), BUNNY_SAMPLE) {
        let (i, j) = kept[k];
        assert!(!crosses_surface_brute_force(&m, i, j), "kept fiber ({i}, {j}) crosses the surface");
        assert!(
            !exits_at(&m, &faces, i, j, EXIT_TOLERANCE) && !exits_at(&m, &faces, j, i, EXIT_TOLERANCE),
            "kept fiber ({i}, {j}) leaves the body at an end"
        );
    }
    let mut crossing_seen = 0;
    for k in rand::seq::index::sample(&mut rng, removed.len(), BUNNY_SAMPLE) {
        let (i, j) = removed[k];
        let exits = exits_at(&m, &faces, i, j, EXIT_TOLERANCE) || exits_at(&m, &faces, j, i, EXIT_TOLERANCE);
        let crosses = crosses_surface_brute_force(&m, i, j);
        crossing_seen += (!exits && crosses) as usize;
        assert!(exits || crosses, "removed fiber ({i}, {j}) passes both tests");
    }
    assert!(crossing_seen > 0, "the sample should contain fibers removed by the crossing test");
}

/// Convex fixtures keep all N(N-1)/2 fibers with both tests forced. The cube's square sides
/// are split into two triangles and the dome's base is one flat plane of many triangles, so
/// many fibers run in a face plane (Coplanar, which the policy keeps) or along the
/// boundary of faces that touch neither end.
#[test]
fn convex_fixtures_keep_every_fiber_with_tests_forced() {
    let forced = VisibilityOptions { force_tests: true, ..VisibilityOptions::default() };
    for name in ["cube.obj", "icosahedron.obj", "icosphere-2.obj", "dome.obj"] {
        let m = load(name).mesh;
        let n = m.n_vertices();
        assert!(m.is_convex(), "{name}");
        let (set, rep) = cull_fibers(&m, &forced);
        assert_eq!((rep.removed_by_exit, rep.removed_by_crossing), (0, 0), "{name}");
        assert_eq!(set.kept(), n * (n - 1) / 2, "{name}");
        assert_eq!(set, FiberSet::all(n), "{name}");
    }
}
