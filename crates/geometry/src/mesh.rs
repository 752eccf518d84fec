//! The closed triangle surface and its checks.

use crate::adjacency::Adjacency;
use crate::error::{MeshError, ScaleSite};
use crate::vec3::{Vec3, cross, dot, norm, scale, sub};

/// Two used vertices closer than this fraction of the bounding box's diagonal are a
/// near-duplicate ([`MeshError::NearDuplicateVertices`]); 1e-9 apart is still resolved by
/// every backend (tests/hard_cases.rs).
pub const NEAR_DUPLICATE: f64 = 1e-10;

/// Relative area below which a face counts as degenerate: `area <= DEGENERATE_AREA * diag^2`
/// with `diag` the bounding-box diagonal.
pub const DEGENERATE_AREA: f64 = 1e-20;

/// Relative volume at or below which a body whose volume underflowed counts as flat rather
/// than too small: `|V| <= FLAT_VOLUME * m^3`, `m` the largest absolute coordinate.
pub const FLAT_VOLUME: f64 = 1e-12;

/// A triangle surface: f64 positions and u32 triangles, outward (counter-clockwise seen
/// from outside) once [`TriMesh::validate`] has run.
#[derive(Clone, Debug, PartialEq)]
pub struct TriMesh {
    positions: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
}

/// What [`TriMesh::validate`] found and fixed.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Validation {
    /// The faces were inward (negative volume) and were flipped.
    pub flipped: bool,
    /// Euler characteristic V - E + F.
    pub euler_characteristic: i64,
    /// Genus of the closed surface (summed over the outer surface and the cavities),
    /// `(2 c - chi) / 2` for `c` closed surfaces.
    pub genus: i64,
    /// Each cavity's volume (positive; [`TriMesh::shells`]), in cavity order.
    pub cavities: Vec<f64>,
    /// Human-readable warnings (e.g. the flip).
    pub warnings: Vec<String>,
}

impl TriMesh {
    /// Builds a mesh from positions and triangles, checking only that indices are in range
    /// and coordinates are finite. Use [`validate`](Self::validate) for the topology.
    pub fn new(positions: Vec<Vec3>, triangles: Vec<[u32; 3]>) -> Result<Self, MeshError> {
        if positions.is_empty() || triangles.is_empty() {
            return Err(MeshError::Empty { vertices: positions.len(), faces: triangles.len() });
        }
        if let Some(v) = positions.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
            return Err(MeshError::NonFiniteVertex { vertex: v });
        }
        for (f, t) in triangles.iter().enumerate() {
            if let Some(&i) = t.iter().find(|&&i| i as usize >= positions.len()) {
                return Err(MeshError::IndexOutOfRange {
                    face: f,
                    index: i as i64,
                    vertices: positions.len(),
                });
            }
        }
        Ok(Self { positions, triangles })
    }

    /// Number of vertices N.
    pub fn n_vertices(&self) -> usize {
        self.positions.len()
    }

    /// Number of faces N'.
    pub fn n_faces(&self) -> usize {
        self.triangles.len()
    }

    /// Vertex positions.
    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    /// Triangles (vertex indices, outward orientation after validation).
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// Replaces the positions (same count), e.g. after a deformation step.
    ///
    /// # Panics
    /// If the count differs (a programming error).
    #[track_caller]
    pub fn set_positions(&mut self, positions: Vec<Vec3>) {
        assert_eq!(positions.len(), self.positions.len(), "vertex count must not change");
        self.positions = positions;
    }

    /// The three corners of face `k`.
    #[inline]
    pub fn corners(&self, k: usize) -> [Vec3; 3] {
        let t = self.triangles[k];
        [self.positions[t[0] as usize], self.positions[t[1] as usize], self.positions[t[2] as usize]]
    }

    /// Axis-aligned bounding box (min, max).
    pub fn bounding_box(&self) -> (Vec3, Vec3) {
        bounding_box(&self.positions)
    }

    /// Length of the bounding-box diagonal.
    pub fn diagonal(&self) -> f64 {
        let (lo, hi) = self.bounding_box();
        norm(sub(hi, lo))
    }

    /// Face area vectors `A_k = (v1 - v2) x (v2 - v3) / 2` (outward, |A_k| = face area).
    pub fn face_area_vectors(&self) -> Vec<Vec3> {
        (0..self.n_faces()).map(|k| face_area_vector(self.corners(k))).collect()
    }

    /// Raw vertex vectors `R_i = sum of A_k over the faces touching i`.
    pub fn raw_vertex_vectors(&self) -> Vec<Vec3> {
        raw_vertex_vectors(&self.positions, &self.triangles)
    }

    /// Vertex area vectors `S_i = C R_i`, `C = sum|A_k| / sum|R_i|` (Eq. 1–2): outward, and
    /// `sum |S_i|` equals the surface area.
    pub fn vertex_area_vectors(&self) -> Vec<Vec3> {
        vertex_area_vectors(&self.positions, &self.triangles)
    }

    /// Surface area, `sum |A_k|`.
    pub fn area(&self) -> f64 {
        self.face_area_vectors().iter().map(|a| norm(*a)).sum()
    }

    /// Enclosed volume `V = (1/6) sum_k v1 . (v2 x v3)` (positive when outward).
    pub fn volume(&self) -> f64 {
        volume(&self.positions, &self.triangles)
    }

    /// The exact gradient of the volume with respect to each vertex, `G_i = R_i / 3`.
    pub fn volume_gradient(&self) -> Vec<Vec3> {
        self.raw_vertex_vectors().into_iter().map(|r| scale(r, 1.0 / 3.0)).collect()
    }

    /// Vertex–face and vertex–vertex adjacency (compressed rows).
    pub fn adjacency(&self) -> Adjacency {
        Adjacency::new(self.n_vertices(), &self.triangles)
    }

    /// Checks that this is one body: closed, manifold, consistently oriented surfaces with
    /// no degenerate or duplicate faces, the outer one and cavities inside it
    /// ([`crate::Shell`]); faces the outer outward and each cavity toward its hole,
    /// flipping what points the other way.
    pub fn validate(&mut self) -> Result<Validation, MeshError> {
        self.check_faces()?;
        self.check_near_duplicates()?;
        let n_edges = self.check_edges()?;
        let adj = self.adjacency();
        self.check_vertex_fans(&adj)?;
        let used = (0..self.n_vertices()).filter(|&v| !adj.faces_of(v).is_empty()).count() as i64;
        let chi = used - n_edges + self.n_faces() as i64;
        let shells = self.shells();
        let c = shells.len() as i64;
        let mut report = Validation {
            flipped: false,
            euler_characteristic: chi,
            genus: (2 * c - chi) / 2,
            cavities: vec![],
            warnings: vec![],
        };
        if shells.len() == 1 {
            if self.orient_outward()? {
                report.flipped = true;
                report.warnings.push("faces pointed inward (negative volume); flipped to outward".into());
            }
            return Ok(report);
        }
        let v = shells[0].volume;
        if !(v.is_finite() && v.abs() >= f64::MIN_POSITIVE) {
            // Names the scale problem when it is one.
            self.orient_outward()?;
            return Err(MeshError::ZeroVolume);
        }
        report.warnings = self.orient_shells(&shells)?;
        report.flipped = v < 0.0;
        report.cavities = shells[1..].iter().map(|s| s.volume.abs()).collect();
        Ok(report)
    }

    /// Reverses face `k`'s orientation.
    pub(crate) fn flip_face(&mut self, k: usize) {
        self.triangles[k].swap(1, 2);
    }

    /// No degenerate face (repeated vertex, area too small for the mesh's size) and no two
    /// faces on the same three vertices.
    fn check_faces(&self) -> Result<(), MeshError> {
        let diag = self.diagonal();
        for (k, t) in self.triangles.iter().enumerate() {
            let area = norm(face_area_vector([
                self.positions[t[0] as usize],
                self.positions[t[1] as usize],
                self.positions[t[2] as usize],
            ]));
            if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                return Err(MeshError::DegenerateFace { face: k, area });
            }
            // Not `area > limit` (a NaN area or limit must fail too); a subnormal area has
            // lost its precision.
            let larger =
                area.partial_cmp(&(DEGENERATE_AREA * diag * diag)) == Some(std::cmp::Ordering::Greater);
            if !(larger && area.is_finite() && area >= f64::MIN_POSITIVE) {
                return Err(self.area_failure(k, area));
            }
        }
        // Duplicate faces (same vertex set).
        let mut sorted: Vec<([u32; 3], usize)> = self
            .triangles
            .iter()
            .enumerate()
            .map(|(k, t)| {
                let mut s = *t;
                s.sort_unstable();
                (s, k)
            })
            .collect();
        sorted.sort_unstable();
        for w in sorted.windows(2) {
            if w[0].0 == w[1].0 {
                return Err(MeshError::DuplicateFace { first: w[0].1, second: w[1].1 });
            }
        }
        Ok(())
    }

    /// No two used vertices closer than [`NEAR_DUPLICATE`] of the diagonal (a sweep over
    /// the vertices sorted along x: `O(N log N)` for a surface).
    fn check_near_duplicates(&self) -> Result<(), MeshError> {
        let diag = self.diagonal();
        let eps = NEAR_DUPLICATE * diag;
        let mut used = vec![false; self.n_vertices()];
        self.triangles.iter().flatten().for_each(|&v| used[v as usize] = true);
        let mut order: Vec<usize> = (0..self.n_vertices()).filter(|&v| used[v]).collect();
        order.sort_unstable_by(|&a, &b| self.positions[a][0].total_cmp(&self.positions[b][0]));
        for (k, &a) in order.iter().enumerate() {
            for &b in &order[k + 1..] {
                if self.positions[b][0] - self.positions[a][0] > eps {
                    break;
                }
                let distance = norm(sub(self.positions[a], self.positions[b]));
                if distance <= eps {
                    let (a, b) = (a.min(b), a.max(b));
                    return Err(MeshError::NearDuplicateVertices {
                        a,
                        b,
                        distance,
                        relative: distance / diag,
                    });
                }
            }
        }
        Ok(())
    }

    /// Every edge shared by exactly two faces of opposite orientation. Returns the number
    /// of edges.
    fn check_edges(&self) -> Result<i64, MeshError> {
        // Edges: (min, max, face, forward?).
        let mut edges: Vec<(u32, u32, u32, bool)> = Vec::with_capacity(3 * self.n_faces());
        for (k, t) in self.triangles.iter().enumerate() {
            for e in 0..3 {
                let (a, b) = (t[e], t[(e + 1) % 3]);
                edges.push((a.min(b), a.max(b), k as u32, a < b));
            }
        }
        edges.sort_unstable();
        let mut boundary = Vec::new();
        let mut i = 0;
        let mut n_edges = 0i64;
        while i < edges.len() {
            let mut j = i;
            while j < edges.len() && edges[j].0 == edges[i].0 && edges[j].1 == edges[i].1 {
                j += 1;
            }
            let (a, b) = (edges[i].0, edges[i].1);
            n_edges += 1;
            match j - i {
                1 => boundary.push((a, b)),
                2 => {
                    if edges[i].3 == edges[i + 1].3 {
                        return Err(MeshError::InconsistentOrientation { a, b });
                    }
                }
                faces => return Err(MeshError::NonManifoldEdge { a, b, faces }),
            }
            i = j;
        }
        if let Some(&(a, b)) = boundary.first() {
            return Err(MeshError::OpenBoundary { count: boundary.len(), a, b });
        }
        Ok(n_edges)
    }

    /// The faces around each vertex form one fan.
    fn check_vertex_fans(&self, adj: &crate::Adjacency) -> Result<(), MeshError> {
        let n = self.n_vertices();
        // Non-manifold vertices: the faces around each vertex must form one fan.
        for v in 0..n {
            let faces = adj.faces_of(v);
            if faces.is_empty() {
                continue;
            }
            let mut local = UnionFind::new(faces.len());
            for (x, &fa) in faces.iter().enumerate() {
                for (y, &fb) in faces.iter().enumerate().skip(x + 1) {
                    let ta = self.triangles[fa as usize];
                    let tb = self.triangles[fb as usize];
                    let shared = ta.iter().filter(|w| **w != v as u32 && tb.contains(w)).count();
                    if shared > 0 {
                        local.union(x, y);
                    }
                }
            }
            let fans = local.count();
            if fans > 1 {
                return Err(MeshError::NonManifoldVertex { vertex: v as u32, fans });
            }
        }
        Ok(())
    }

    /// A volume that f64 can hold, not zero; faces flipped when they point inward (returns
    /// whether they were).
    fn orient_outward(&mut self) -> Result<bool, MeshError> {
        let vol = self.volume();
        if !vol.is_finite() {
            let (vertex, magnitude) = self.largest_coordinate(0..self.n_vertices());
            return Err(MeshError::CoordinateOverflow {
                site: ScaleSite::Volume,
                vertex,
                magnitude,
                suggested_scale: suggested_scale(magnitude),
            });
        }
        if vol.abs() < f64::MIN_POSITIVE {
            // Zero or subnormal: a flat body, or a real one in units too small for f64.
            let (vertex, magnitude) = self.largest_coordinate(0..self.n_vertices());
            let unit: Vec<Vec3> = self.positions.iter().map(|p| p.map(|c| c / magnitude)).collect();
            let relative = volume(&unit, &self.triangles);
            if magnitude > 0.0 && relative.abs() > FLAT_VOLUME {
                return Err(MeshError::CoordinateUnderflow {
                    site: ScaleSite::Volume,
                    vertex,
                    magnitude,
                    value: vol,
                    suggested_scale: suggested_scale(magnitude),
                });
            }
            return Err(MeshError::ZeroVolume);
        }
        if vol < 0.0 {
            for t in &mut self.triangles {
                t.swap(1, 2);
            }
            return Ok(true);
        }
        Ok(false)
    }

    /// The error for face `k`, whose area failed the degeneracy test: the same test on the
    /// coordinates divided by the largest absolute coordinate tells a degenerate shape
    /// ([`MeshError::DegenerateFace`]) from coordinates too large or too small for f64
    /// products ([`MeshError::CoordinateOverflow`] / [`MeshError::CoordinateUnderflow`]).
    fn area_failure(&self, k: usize, area: f64) -> MeshError {
        let (_, m) = self.largest_coordinate(0..self.n_vertices());
        if !(m > 0.0) {
            return MeshError::DegenerateFace { face: k, area };
        }
        // Division, not a reciprocal: 1 / m overflows when m is subnormal.
        let unit = |p: Vec3| p.map(|c| c / m);
        let (lo, hi) = self.bounding_box();
        let unit_diag = norm(sub(unit(hi), unit(lo)));
        let unit_area = norm(face_area_vector(self.corners(k).map(unit)));
        if !(unit_area > DEGENERATE_AREA * unit_diag * unit_diag) {
            return MeshError::DegenerateFace { face: k, area };
        }
        let t = self.triangles[k];
        let (vertex, magnitude) = self.largest_coordinate(t.iter().map(|&v| v as usize));
        let (site, suggested_scale) = (ScaleSite::Face(k), suggested_scale(m));
        let diag = self.diagonal();
        if !area.is_finite() || !(DEGENERATE_AREA * diag * diag).is_finite() {
            MeshError::CoordinateOverflow { site, vertex, magnitude, suggested_scale }
        } else {
            MeshError::CoordinateUnderflow { site, vertex, magnitude, value: area, suggested_scale }
        }
    }

    /// The vertex of `among` with the largest absolute coordinate, and that coordinate.
    fn largest_coordinate(&self, among: impl Iterator<Item = usize>) -> (u32, f64) {
        among
            .map(|v| (v as u32, self.positions[v].iter().fold(0.0f64, |m, c| m.max(c.abs()))))
            .fold((0, -1.0), |best, x| if x.1 > best.1 { x } else { best })
    }

    /// Whether the body is convex: no vertex lies outside any face plane by more than
    /// [`CONVEXITY_TOLERANCE`] times the bounding-box diagonal.
    pub fn is_convex(&self) -> bool {
        self.is_convex_eps(CONVEXITY_TOLERANCE)
    }

    /// [`is_convex`](Self::is_convex) with an explicit relative tolerance.
    pub fn is_convex_eps(&self, eps: f64) -> bool {
        use rayon::prelude::*;
        let tol = eps * self.diagonal();
        let areas = self.face_area_vectors();
        let face_ok = |k: usize| {
            let a = areas[k];
            let la = norm(a);
            let v1 = self.corners(k)[0];
            self.positions.iter().all(|p| dot(a, sub(*p, v1)) <= tol * la)
        };
        // Small meshes are checked on one thread: waking the pool costs more than the work.
        if self.n_vertices() * self.n_faces() < PARALLEL_WORK {
            (0..self.n_faces()).all(face_ok)
        } else {
            (0..self.n_faces()).into_par_iter().all(face_ok)
        }
    }
}

/// A power of ten that brings a largest absolute coordinate `m` to between 1 and 10 (the
/// `[mesh].scale` suggested when coordinates overflow or underflow).
pub(crate) fn suggested_scale(m: f64) -> f64 {
    if !(m > 0.0 && m.is_finite()) {
        return 1.0;
    }
    let exponent = -(m.log10().floor().clamp(-300.0, 300.0) as i32);
    // Parsed rather than `powi`, which is off in the last digits.
    format!("1e{exponent}").parse().unwrap_or(1.0)
}

/// Below this much work (vertex-face pairs) loops run on one thread.
pub(crate) const PARALLEL_WORK: usize = 1 << 18;

/// Default relative tolerance of [`TriMesh::is_convex`].
pub const CONVEXITY_TOLERANCE: f64 = 1e-9;

/// `A = (v1 - v2) x (v2 - v3) / 2`.
#[inline]
pub fn face_area_vector(c: [Vec3; 3]) -> Vec3 {
    scale(cross(sub(c[0], c[1]), sub(c[1], c[2])), 0.5)
}

/// Raw vertex vectors for given positions and triangles.
pub fn raw_vertex_vectors(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
    let mut r = vec![[0.0; 3]; positions.len()];
    for t in triangles {
        let a =
            face_area_vector([positions[t[0] as usize], positions[t[1] as usize], positions[t[2] as usize]]);
        for &v in t {
            let rv = &mut r[v as usize];
            rv[0] += a[0];
            rv[1] += a[1];
            rv[2] += a[2];
        }
    }
    r
}

/// Vertex area vectors `S_i = C R_i` for given positions and triangles.
pub fn vertex_area_vectors(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
    let r = raw_vertex_vectors(positions, triangles);
    let face_sum: f64 = triangles
        .iter()
        .map(|t| {
            norm(face_area_vector([
                positions[t[0] as usize],
                positions[t[1] as usize],
                positions[t[2] as usize],
            ]))
        })
        .sum();
    let raw_sum: f64 = r.iter().map(|v| norm(*v)).sum();
    let c = if raw_sum > 0.0 { face_sum / raw_sum } else { 0.0 };
    r.into_iter().map(|v| scale(v, c)).collect()
}

/// Enclosed volume for given positions and triangles.
pub fn volume(positions: &[Vec3], triangles: &[[u32; 3]]) -> f64 {
    triangles
        .iter()
        .map(|t| {
            let (a, b, c) = (positions[t[0] as usize], positions[t[1] as usize], positions[t[2] as usize]);
            dot(a, cross(b, c))
        })
        .sum::<f64>()
        / 6.0
}

/// Bounding box of a point set.
pub fn bounding_box(points: &[Vec3]) -> (Vec3, Vec3) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        for c in 0..3 {
            lo[c] = lo[c].min(p[c]);
            hi[c] = hi[c].max(p[c]);
        }
    }
    (lo, hi)
}

pub(crate) struct UnionFind {
    parent: Vec<usize>,
}

impl UnionFind {
    pub(crate) fn new(n: usize) -> Self {
        Self { parent: (0..n).collect() }
    }
    pub(crate) fn find(&mut self, mut x: usize) -> usize {
        while self.parent[x] != x {
            self.parent[x] = self.parent[self.parent[x]];
            x = self.parent[x];
        }
        x
    }
    pub(crate) fn union(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            self.parent[ra] = rb;
        }
    }
    pub(crate) fn count(&mut self) -> usize {
        (0..self.parent.len()).filter(|&i| self.find(i) == i).count()
    }
}
