//! Faces turned inside out against faces that only rotated
//! (`faces_turned_inside_out`, `edges_turned_inside_out`).

use fibfluid_geometry::vec3::{dot, norm, sub};
use fibfluid_geometry::{Vec3, edges_turned_inside_out, faces_turned_inside_out, icosphere};

/// Rotation by `angle` (radians) about the unit `axis`, by Rodrigues' formula: written out
/// here.
fn rodrigues(axis: Vec3, angle: f64, v: Vec3) -> Vec3 {
    let (s, c) = angle.sin_cos();
    let k = axis;
    let kv = dot(k, v);
    let kxv = [k[1] * v[2] - k[2] * v[1], k[2] * v[0] - k[0] * v[2], k[0] * v[1] - k[1] * v[0]];
    std::array::from_fn(|a| v[a] * c + kxv[a] * s + k[a] * kv * (1.0 - c))
}

fn unit(v: Vec3) -> Vec3 {
    let n = norm(v);
    v.map(|x| x / n)
}

/// The plain test the guard used to make: normals against the rest ones.
fn against_rest(triangles: &[[u32; 3]], rest: &[Vec3], now: &[Vec3]) -> usize {
    let area = |p: &[Vec3], t: &[u32; 3]| {
        let (a, b, c) = (p[t[0] as usize], p[t[1] as usize], p[t[2] as usize]);
        let (e, f) = (sub(a, b), sub(b, c));
        [e[1] * f[2] - e[2] * f[1], e[2] * f[0] - e[0] * f[2], e[0] * f[1] - e[1] * f[0]]
    };
    triangles.iter().filter(|t| dot(area(rest, t), area(now, t)) <= 0.0).count()
}

#[test]
fn a_body_that_only_rotated_has_no_face_inside_out() {
    let sphere = icosphere(2, 0.05);
    let rest = sphere.positions();
    for (axis, angle) in
        [([0.0, 1.0, 0.0], 2.5), ([1.0, 1.0, 1.0], std::f64::consts::PI), ([0.2, 0.0, 1.0], 1.7)]
    {
        let axis = unit(axis);
        // Rotated and stretched a little along x: not a rigid motion, still nothing turned.
        let now: Vec<Vec3> =
            rest.iter().map(|p| rodrigues(axis, angle, [1.2 * p[0], p[1], 0.9 * p[2]])).collect();
        assert!(against_rest(sphere.triangles(), rest, &now) > 50, "the plain test counts rotated faces");
        assert_eq!(faces_turned_inside_out(sphere.triangles(), rest, &now), 0, "angle {angle}");
    }
}

#[test]
fn a_fold_counts_the_same_faces_whatever_the_rotation() {
    let sphere = icosphere(2, 1.0);
    let rest = sphere.positions();
    // Vertex 0 dragged along the surface past its neighbour: the faces it crossed fold over.
    let neighbour = sphere.triangles().iter().find(|t| t.contains(&0)).map(|t| t[1].max(t[2])).unwrap();
    let mut folded = rest.to_vec();
    let toward = sub(rest[neighbour as usize], rest[0]);
    folded[0] = std::array::from_fn(|a| rest[0][a] + 1.8 * toward[a]);
    let plain = against_rest(sphere.triangles(), rest, &folded);
    assert!((1..=5).contains(&plain), "the fold turns some of vertex 0's 5 faces: {plain}");
    assert_eq!(faces_turned_inside_out(sphere.triangles(), rest, &folded), plain);
    for (axis, angle) in [([0.0, 0.0, 1.0], 2.8), ([1.0, -1.0, 0.5], std::f64::consts::PI)] {
        let now: Vec<Vec3> = folded.iter().map(|p| rodrigues(unit(axis), angle, *p)).collect();
        assert_eq!(faces_turned_inside_out(sphere.triangles(), rest, &now), plain, "angle {angle}");
    }
}

#[test]
fn a_polygon_that_only_rotated_has_no_edge_inside_out() {
    let n = 40;
    let rest: Vec<Vec3> = (0..n)
        .map(|i| {
            let t = i as f64 / n as f64 * std::f64::consts::TAU;
            [2.0 * t.cos(), t.sin(), 0.0]
        })
        .collect();
    let turned: Vec<Vec3> = rest.iter().map(|p| rodrigues([0.0, 0.0, 1.0], 3.0, *p)).collect();
    assert_eq!(edges_turned_inside_out(&rest, &turned), 0);
    let mut folded = turned.clone();
    // Vertex 10 pulled back past both neighbours along the polygon: its two edges reverse.
    folded[10] = rodrigues([0.0, 0.0, 1.0], 3.0, [2.0 * 0.2f64.cos(), 0.2f64.sin(), 0.0]);
    assert!(edges_turned_inside_out(&rest, &folded) >= 1);
}
