//! Surfaces from label images: marching tetrahedra on a label's mask.
//!
//! The mask (1 inside the selected label(s), 0 elsewhere) is sampled at voxel centres,
//! padded by one voxel of background on every side so the surface closes, and every cube of
//! eight neighbouring samples is split into the six tetrahedra around its main diagonal (the
//! Freudenthal split: the same in every cube, so neighbouring cubes' faces match). The
//! surface is the 0.5 level set of the field linear on each tetrahedron. On a binary field
//! every surface vertex is an edge midpoint and no sample equals 0.5, so there is no
//! ambiguous case: the result is a closed 2-manifold. Vertices are shared by keying them on
//! their edge's two grid points; each triangle is oriented so its normal points from the
//! inside end of an edge to the outside end (outward, also for an affine that mirrors).
//!
//! Options: a 3x3x3 box blur of the mask (a less staircase surface; its level is then the
//! one whose surface encloses the voxels' volume, not 0.5, which rounds the body's edges
//! and corners off) and decimation to a target vertex count. The surface is extracted at full resolution (after the blur when
//! asked) and then decimated by volume-preserving edge collapses ([`crate::decimate`]): the
//! result encloses the full-resolution surface's volume (up to rounding) and stays one closed
//! 2-manifold, outward. Only when the full-resolution surface is enormous, more than 20 times
//! the target and more than 200 000 vertices, is the mask first resampled: averaged over
//! blocks of `k x k x k` voxels (k odd, the smallest that brings the surface to at most
//! that size), the surface extracted on that coarser grid and then decimated. Resampling
//! loses volume on a body only a few blocks across (the reason it is not the decimation
//! itself); [`LabelSurface::block`] says when it was used. Averages over an odd number of
//! voxels (27 for the blur, k^3 for a block) are never exactly 0.5, so the level set never
//! passes through a sample there either.

use std::collections::HashMap;

use crate::decimate::{DecimateError, decimate_valid};
use crate::error::MeshError;
use crate::image::LabelImage;
use crate::mesh::{TriMesh, Validation};
use crate::vec3::{Vec3, cross, dot, sub};

/// Which voxels are inside.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LabelSelection {
    /// The voxels of one label.
    Label(u32),
    /// Every non-zero voxel: the whole body.
    NonZero,
}

impl LabelSelection {
    fn contains(self, label: u32) -> bool {
        match self {
            LabelSelection::Label(l) => label == l,
            LabelSelection::NonZero => label != 0,
        }
    }
}

impl std::fmt::Display for LabelSelection {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LabelSelection::Label(l) => write!(f, "label {l}"),
            LabelSelection::NonZero => write!(f, "the non-zero labels"),
        }
    }
}

/// How [`extract_surface`] works.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceOptions {
    /// The voxels inside.
    pub selection: LabelSelection,
    /// Blur the mask with a 3x3x3 box before extraction.
    pub smooth: bool,
    /// Also count as inside the background that cannot reach the image border (cavities),
    /// so a shell-shaped label gives its outer surface only.
    pub fill_cavities: bool,
    /// At most this many vertices: the full-resolution surface decimated, keeping its
    /// volume (see the module documentation). `None`: full resolution.
    pub target_vertices: Option<usize>,
}

impl Default for SurfaceOptions {
    fn default() -> Self {
        Self {
            selection: LabelSelection::NonZero,
            smooth: false,
            fill_cavities: false,
            target_vertices: None,
        }
    }
}

/// Why no surface could be extracted.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SurfaceError {
    /// No voxel is selected.
    #[error("the image has no voxel of {selection}")]
    Empty {
        /// The selection.
        selection: LabelSelection,
    },
    /// Decimation cannot bring the surface down to the target (a closed surface has at
    /// least 4 vertices, and collapses that would damage it are refused).
    #[error("decimation cannot bring the surface to {target} vertices (it stopped at {smallest})")]
    TargetTooSmall {
        /// The target.
        target: usize,
        /// Vertices of the surface where decimation stopped.
        smallest: usize,
    },
    /// The extracted surface failed validation (e.g. a label in several pieces).
    #[error("the surface of {selection} is not one valid closed body: {source}")]
    Mesh {
        /// The selection whose surface it is.
        selection: LabelSelection,
        /// What validation found.
        source: MeshError,
    },
}

/// A surface extracted from a label image, in metres, validated and outward.
#[derive(Clone, Debug)]
pub struct LabelSurface {
    /// The surface.
    pub mesh: TriMesh,
    /// What validation found.
    pub validation: Validation,
    /// Resampling block edge k before decimation (1: none, the full resolution).
    pub block: usize,
    /// Selected voxels (after filling cavities when asked).
    pub voxels: usize,
    /// `voxels x` the voxel volume, in cubic metres.
    pub voxel_volume: f64,
    /// Volume enclosed by the surface, in cubic metres.
    pub volume: f64,
}

/// Above this many vertices (and [`RESAMPLE_RATIO`] times the target) the mask is resampled
/// before decimation.
const RESAMPLE_ABOVE: usize = 200_000;

/// See [`RESAMPLE_ABOVE`].
const RESAMPLE_RATIO: usize = 20;

/// Extracts the surface of the selected voxels (see the module documentation).
pub fn extract_surface(image: &LabelImage, opts: &SurfaceOptions) -> Result<LabelSurface, SurfaceError> {
    let mut mask: Vec<f64> = image.labels.iter().map(|&l| opts.selection.contains(l) as u8 as f64).collect();
    if opts.fill_cavities {
        fill_cavities(&mut mask, image.dims);
    }
    let voxels = mask.iter().filter(|&&m| m > 0.5).count();
    if voxels == 0 {
        return Err(SurfaceError::Empty { selection: opts.selection });
    }
    if opts.smooth {
        box_blur(&mut mask, image.dims);
    }
    let frame = Frame::of(image);
    let mut raw = march(image, &frame, &mask, 1, HALF);
    let mut block = 1;
    if let Some(target) = opts.target_vertices {
        let enough = target.saturating_mul(RESAMPLE_RATIO).max(RESAMPLE_ABOVE);
        let largest = image.dims.iter().copied().max().unwrap_or(1);
        while raw.0.len() > enough && block <= largest {
            block += 2;
            raw = march(image, &frame, &mask, block, HALF);
        }
    }
    if opts.smooth {
        raw = volume_keeping_surface(image, &frame, &mask, block, voxels as f64 * frame.voxel_volume(), raw);
    }
    let selection = opts.selection;
    let invalid = |source| SurfaceError::Mesh { selection, source };
    let mut mesh = TriMesh::new(raw.0, raw.1).map_err(invalid)?;
    let mut validation = mesh.validate().map_err(invalid)?;
    if let Some(target) = opts.target_vertices {
        let (positions, triangles) =
            decimate_valid(mesh.positions(), mesh.triangles(), target).map_err(|e| match e {
                DecimateError::TargetTooSmall { target, reached } => {
                    SurfaceError::TargetTooSmall { target, smallest: reached }
                }
                DecimateError::Mesh(e) => invalid(e),
            })?;
        mesh = TriMesh::new(positions, triangles).map_err(invalid)?;
    }
    let world = mesh.positions().iter().map(|&q| frame.world(q)).collect();
    mesh = TriMesh::new(world, mesh.triangles().to_vec()).map_err(invalid)?;
    let flipped = validation.flipped;
    validation = mesh.validate().map_err(invalid)?;
    validation.flipped |= flipped;
    let volume = mesh.volume();
    Ok(LabelSurface {
        mesh,
        validation,
        block,
        voxels,
        voxel_volume: voxels as f64 * image.voxel_volume(),
        volume,
    })
}

/// The level of the mask's plain surface.
const HALF: f64 = 0.5;

/// The blurred mask's level is sought until the surface's volume is within this fraction of
/// the voxels' ([`volume_keeping_surface`]).
pub const SMOOTH_VOLUME_TOLERANCE: f64 = 1e-3;

/// Bisections of the level at most (2^-40 of the level's range).
const LEVEL_BISECTIONS: usize = 40;

/// The surface of the blurred `mask` (on `block`s) at the level whose surface encloses
/// `volume` (the voxels'), from `half`, its surface at 0.5: the blur rounds a body's edges
/// and corners off, and its 0.5 level loses their volume (3.9 % on the phantom, a body 16
/// voxels thick); a lower level gives it back. By bisection on `(0, 1)`, the surface's
/// volume falling as the level rises, to [`SMOOTH_VOLUME_TOLERANCE`] (the last surface
/// made when [`LEVEL_BISECTIONS`] do not get there). The levels bisection visits are
/// dyadic fractions, never equal to a blurred sample (multiples of `1 / (27 block^3)`, odd
/// denominators), so the level set never passes through one and the surface stays a
/// closed 2-manifold.
fn volume_keeping_surface(
    image: &LabelImage,
    frame: &Frame,
    mask: &[f64],
    block: usize,
    volume: f64,
    half: (Vec<Vec3>, Vec<[u32; 3]>),
) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let (mut lo, mut hi, mut level) = (0.0, 1.0, HALF);
    let mut surface = half;
    for _ in 0..LEVEL_BISECTIONS {
        let enclosed = crate::mesh::volume(&surface.0, &surface.1).abs();
        if (enclosed / volume - 1.0).abs() <= SMOOTH_VOLUME_TOLERANCE {
            break;
        }
        if enclosed > volume {
            lo = level;
        } else {
            hi = level;
        }
        level = 0.5 * (lo + hi);
        surface = march(image, frame, mask, block, level);
    }
    surface
}

/// Marks as inside (1) the outside voxels (< 0.5) that cannot reach the image border
/// through outside voxels (6-connected).
fn fill_cavities(mask: &mut [f64], dims: [usize; 3]) {
    let [nx, ny, nz] = dims;
    let idx = |i: usize, j: usize, k: usize| i + nx * (j + ny * k);
    let mut reached = vec![false; mask.len()];
    let mut stack = Vec::new();
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let border = i == 0 || j == 0 || k == 0 || i + 1 == nx || j + 1 == ny || k + 1 == nz;
                if border && mask[idx(i, j, k)] < 0.5 {
                    reached[idx(i, j, k)] = true;
                    stack.push([i, j, k]);
                }
            }
        }
    }
    while let Some(p) = stack.pop() {
        for axis in 0..3 {
            for up in [false, true] {
                let mut q = p;
                if up {
                    q[axis] += 1;
                    if q[axis] == dims[axis] {
                        continue;
                    }
                } else if q[axis] == 0 {
                    continue;
                } else {
                    q[axis] -= 1;
                }
                let n = idx(q[0], q[1], q[2]);
                if !reached[n] && mask[n] < 0.5 {
                    reached[n] = true;
                    stack.push(q);
                }
            }
        }
    }
    for (m, r) in mask.iter_mut().zip(reached) {
        if !r {
            *m = m.max(1.0);
        }
    }
}

/// 3x3x3 box blur, background (0) outside the image: three passes of a 3-sample mean.
fn box_blur(field: &mut [f64], dims: [usize; 3]) {
    let stride = [1, dims[0], dims[0] * dims[1]];
    let mut out = vec![0.0; field.len()];
    for axis in 0..3 {
        for (n, o) in out.iter_mut().enumerate() {
            let c = (n / stride[axis]) % dims[axis];
            let mut s = field[n];
            if c > 0 {
                s += field[n - stride[axis]];
            }
            if c + 1 < dims[axis] {
                s += field[n + stride[axis]];
            }
            *o = s / 3.0;
        }
        field.copy_from_slice(&out);
    }
}

/// The field on the padded coarse grid: block means over `block^3` voxels (background
/// outside the image), one sample of background on every side. Returns it with its dims.
fn coarse_field(image: &LabelImage, mask: &[f64], block: usize) -> (Vec<f64>, [usize; 3]) {
    let d = image.dims;
    let g = d.map(|n| n.div_ceil(block) + 2);
    let mut field = vec![0.0; g[0] * g[1] * g[2]];
    let inv = 1.0 / (block * block * block) as f64;
    for k in 0..d[2] {
        for j in 0..d[1] {
            for i in 0..d[0] {
                let m = mask[image.index(i, j, k)];
                if m != 0.0 {
                    let (a, b, c) = (i / block + 1, j / block + 1, k / block + 1);
                    field[a + g[0] * (b + g[1] * c)] += m * inv;
                }
            }
        }
    }
    (field, g)
}

/// The six tetrahedra of a cube around its diagonal from corner 0 to corner 7 (corner bits:
/// 1 = +i, 2 = +j, 4 = +k).
const TETS: [[usize; 4]; 6] =
    [[0, 1, 3, 7], [0, 1, 5, 7], [0, 2, 3, 7], [0, 2, 6, 7], [0, 4, 5, 7], [0, 4, 6, 7]];

/// The voxel-to-world affine as `world = scale * (linear * ijk) + offset`, `scale` the
/// largest entry of the affine's linear part. Surfaces are made and decimated in the local
/// coordinates `linear * ijk` and moved to the world last: a change of length unit changes
/// `scale` and `offset` only (an axis-aligned image of cubic voxels has `linear` the identity
/// in every unit), so the decimation, whose collapse order breaks many exact ties on a voxel
/// surface, sees the same numbers in every unit, and a surface in millimetres and one in
/// metres are the same surface, scaled.
struct Frame {
    linear: [[f64; 3]; 3],
    scale: f64,
    offset: Vec3,
}

impl Frame {
    fn of(image: &LabelImage) -> Self {
        let a = &image.affine;
        let scale = (0..3).flat_map(|r| (0..3).map(move |c| a[r][c].abs())).fold(0.0, f64::max);
        Self {
            linear: std::array::from_fn(|r| std::array::from_fn(|c| a[r][c] / scale)),
            scale,
            offset: std::array::from_fn(|r| a[r][3]),
        }
    }

    /// Local coordinates of a (possibly fractional) voxel index.
    fn local(&self, ijk: Vec3) -> Vec3 {
        self.linear.map(|r| r[0] * ijk[0] + r[1] * ijk[1] + r[2] * ijk[2])
    }

    /// World position (metres) of local coordinates.
    fn world(&self, q: Vec3) -> Vec3 {
        std::array::from_fn(|r| self.scale * q[r] + self.offset[r])
    }

    /// Volume of one voxel in local coordinates: `|det linear|`.
    fn voxel_volume(&self) -> f64 {
        let a = &self.linear;
        let det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
            - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
        det.abs()
    }
}

/// Marching tetrahedra on the padded block-mean field at `level`: positions (local
/// coordinates of `frame`) and outward triangles.
fn march(
    image: &LabelImage,
    frame: &Frame,
    mask: &[f64],
    block: usize,
    level: f64,
) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let (field, g) = coarse_field(image, mask, block);
    let half = (block as f64 - 1.0) / 2.0;
    let world = |n: usize| {
        let (i, j, k) = (n % g[0], (n / g[0]) % g[1], n / (g[0] * g[1]));
        let ijk = [i, j, k].map(|c| (c as f64 - 1.0) * block as f64 + half);
        frame.local(ijk)
    };
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    let mut vertex_of: HashMap<(usize, usize), u32> = HashMap::new();
    let mut vertex = |a: usize, b: usize, positions: &mut Vec<Vec3>| {
        let key = (a.min(b), a.max(b));
        *vertex_of.entry(key).or_insert_with(|| {
            let (va, vb) = (field[a], field[b]);
            let t = (level - va) / (vb - va);
            let (pa, pb) = (world(a), world(b));
            positions.push(std::array::from_fn(|c| pa[c] + t * (pb[c] - pa[c])));
            (positions.len() - 1) as u32
        })
    };
    for k in 0..g[2] - 1 {
        for j in 0..g[1] - 1 {
            for i in 0..g[0] - 1 {
                let base = i + g[0] * (j + g[1] * k);
                let corner: [usize; 8] =
                    std::array::from_fn(|c| base + (c & 1) + g[0] * ((c >> 1) & 1) + g[0] * g[1] * (c >> 2));
                let inside = corner.map(|n| field[n] > level);
                if inside.iter().all(|&x| x) || inside.iter().all(|&x| !x) {
                    continue;
                }
                for tet in TETS {
                    let (ins, outs): (Vec<usize>, Vec<usize>) =
                        tet.iter().map(|&c| corner[c]).partition(|&n| field[n] > level);
                    // Each polygon as its crossing edges (inside end, outside end), in order
                    // around the polygon.
                    let polys: Vec<Vec<(usize, usize)>> = match (ins.len(), outs.len()) {
                        (1, 3) => vec![outs.iter().map(|&o| (ins[0], o)).collect()],
                        (3, 1) => vec![ins.iter().map(|&i| (i, outs[0])).collect()],
                        (2, 2) => {
                            let q =
                                [(ins[0], outs[0]), (ins[0], outs[1]), (ins[1], outs[1]), (ins[1], outs[0])];
                            vec![vec![q[0], q[1], q[2]], vec![q[0], q[2], q[3]]]
                        }
                        _ => continue,
                    };
                    for tri in polys {
                        let v: Vec<u32> = tri.iter().map(|&(a, b)| vertex(a, b, &mut positions)).collect();
                        let p = v.iter().map(|&x| positions[x as usize]).collect::<Vec<_>>();
                        let normal = cross(sub(p[1], p[0]), sub(p[2], p[0]));
                        let outward = sub(world(tri[0].1), world(tri[0].0));
                        if dot(normal, outward) >= 0.0 {
                            triangles.push([v[0], v[1], v[2]]);
                        } else {
                            triangles.push([v[0], v[2], v[1]]);
                        }
                    }
                }
            }
        }
    }
    (positions, triangles)
}
