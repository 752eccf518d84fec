//! Faces turned inside out, told apart from faces that only rotated.
//!
//! A face whose normal points against its rest normal has either turned inside out (the
//! surface folded through itself there) or rotated with the body by more than a right
//! angle (a flap that swung under gravity, a body turned by a grasp). The two are told
//! apart by the face's neighbourhood, which rotates with it: the faces touching its
//! corners, the face itself left out. A face is turned inside out when the angle between
//! its normal and its neighbourhood's (their area vectors summed) grew by more than a right
//! angle ([`TURN_LIMIT`]): from near 0 to near 180 degrees where the surface folded over;
//! unchanged where the body only rotated, however far, or was mirrored as a whole (which
//! the volume's sign tells). Measuring the growth, not the angle, keeps a face on a sharp
//! edge of the rest shape (a rim, where the angle starts near a right angle) from counting
//! when the edge only bends a little more. Two passes over the faces.
//!
//! What it cannot see: a fold whose turned-over layer is wider than a face's neighbourhood
//! counts only along its creases (inside the layer every face turned with the faces around
//! it). Comparing each normal with its rest one turned by the whole body's best rotation
//! would see such a layer, but it counts every face that turned further than the body as a
//! whole: 14 faces of a cow grasped and turned by half a radian, 45 against 38 on the
//! compressed phantom (docs/stability.md).

use crate::mesh::{face_area_vector, raw_vertex_vectors};
use crate::vec3::{Vec3, dot, scale, sub};

/// How much the angle between a face's normal and its neighbourhood's must grow for the
/// face to count as turned inside out (radians): a right angle.
pub const TURN_LIMIT: f64 = std::f64::consts::FRAC_PI_2;

/// The angle (radians) between two vectors; 0 when either is zero.
fn angle_between(a: Vec3, b: Vec3) -> f64 {
    crate::vec3::norm(crate::vec3::cross(a, b)).atan2(dot(a, b))
}

/// The angle between face `t`'s normal on `positions` and its neighbourhood's: the area
/// vectors of the faces touching its corners (`raw`, the raw vertex vectors of
/// `positions`), each counted once per corner it shares, the face itself left out. NaN,
/// never counted as turned, where the neighbourhood's summed area vector is shorter than
/// the face's own (faces around a spike or a thin edge, whose directions cancel: no
/// direction to judge by).
fn neighbourhood_angle(t: &[u32; 3], positions: &[Vec3], raw: &[Vec3]) -> f64 {
    let own = face_area_vector(t.map(|v| positions[v as usize]));
    let around = t.iter().fold([0.0; 3], |s, &v| crate::vec3::add(s, raw[v as usize]));
    let around = sub(around, scale(own, 3.0));
    if crate::vec3::norm(around) < crate::vec3::norm(own) { f64::NAN } else { angle_between(own, around) }
}

/// Per face of `triangles` on `positions`, the angle (radians) between its normal and its
/// neighbourhood's (see [`faces_turned_inside_out`]; NaN where the neighbourhood's
/// directions cancel).
pub fn neighbourhood_angles(triangles: &[[u32; 3]], positions: &[Vec3]) -> Vec<f64> {
    let raw = raw_vertex_vectors(positions, triangles);
    triangles.iter().map(|t| neighbourhood_angle(t, positions, &raw)).collect()
}

/// Faces of `triangles` turned inside out between `rest` and `now` (see the module docs):
/// the angle between their normal and their neighbourhood's grew by more than
/// [`TURN_LIMIT`].
pub fn faces_turned_inside_out(triangles: &[[u32; 3]], rest: &[Vec3], now: &[Vec3]) -> usize {
    faces_turned_given(&neighbourhood_angles(triangles, rest), triangles, now)
}

/// [`faces_turned_inside_out`] with the rest shape's [`neighbourhood_angles`] made once.
pub fn faces_turned_given(rest_angles: &[f64], triangles: &[[u32; 3]], now: &[Vec3]) -> usize {
    let raw = raw_vertex_vectors(now, triangles);
    triangles
        .iter()
        .zip(rest_angles)
        .filter(|(t, rest)| neighbourhood_angle(t, now, &raw) > **rest + TURN_LIMIT)
        .count()
}

/// Edges of a closed polygon in the xy plane (vertex `i` to `i + 1`) turned inside out
/// between `rest` and `now`: the 2-D counterpart of [`faces_turned_inside_out`], the angle
/// between the edge and the edge before it, or the edge after it, grown by more than
/// [`TURN_LIMIT`] (the edge folded back over its neighbour).
pub fn edges_turned_inside_out(rest: &[Vec3], now: &[Vec3]) -> usize {
    let n = rest.len();
    let edge = |p: &[Vec3], i: usize| {
        let j = (i + 1) % n;
        [p[j][0] - p[i][0], p[j][1] - p[i][1], 0.0]
    };
    let angles = |p: &[Vec3], i: usize| {
        let own = edge(p, i);
        [angle_between(own, edge(p, (i + n - 1) % n)), angle_between(own, edge(p, (i + 1) % n))]
    };
    (0..n)
        .filter(|&i| {
            let (before, after) = (angles(rest, i), angles(now, i));
            after[0] > before[0] + TURN_LIMIT || after[1] > before[1] + TURN_LIMIT
        })
        .count()
}
