//! Closed triangle surfaces for the fiber–fluid method (FFM).
//!
//! - [`TriMesh`]: f64 positions, u32 triangles; [`TriMesh::validate`] checks that it is one
//!   closed, manifold, consistently oriented surface and flips an inward one.
//! - Area vectors (REFERENCE §1, the paper's Eq. 1–2): face vectors
//!   `A_k = (v1 - v2) x (v2 - v3) / 2`, raw vertex vectors `R_i = sum_k A_k`, and vertex area
//!   vectors `S_i = C R_i` with `C = sum|A_k| / sum|R_i|` so that `sum |S_i| = sum |A_k|`.
//!   The volume `V = (1/6) sum v1 . (v2 x v3)` has the exact gradient `R_i / 3`.
//! - Fiber visibility ([`cull_fibers`]): a convex body keeps every vertex pair; otherwise a
//!   fiber is removed when it leaves the body at one of its ends, or when it crosses the
//!   surface ([`segment_triangle`], exact predicates, BVH-accelerated).
//! - Files: OBJ, STL, PLY (ASCII and binary) and OFF in ([`load_mesh`]; regular files only,
//!   at most [`DEFAULT_MAX_FILE_BYTES`] unless raised, see [`read_file_limited`]); OBJ, PLY
//!   and OFF out ([`write_obj`], [`write_ply`], [`write_off`]); [`Polygon`] for the paper's
//!   2D example; [`icosphere`] for the sphere cases.
//! - Voxelization ([`inside_lattice`], [`for_each_inside_line`]): which points of a regular
//!   lattice lie inside a closed surface, by exact-predicate ray crossings along x.
//! - Label images ([`read_nifti`]: NIfTI-1/2, `.nii` and `.nii.gz`) and the surface of a
//!   label ([`extract_surface`]: marching tetrahedra, optional smoothing, and decimation to a
//!   vertex target that keeps the volume, [`decimate`]).

mod adjacency;
mod block;
mod boundary;
mod bvh;
mod crossing;
mod decimate;
mod error;
mod fibers;
mod icosphere;
mod image;
mod io;
mod isosurface;
mod limits;
mod mesh;
mod off;
mod ply;
mod polygon;
mod raw;
mod shells;
mod turned;
mod unit;
pub mod vec3;
mod voxel;

pub use adjacency::Adjacency;
pub use block::box_surface;
pub use boundary::Boundary;
pub use bvh::TriangleBvh;
pub use crossing::{Crossing, segment_triangle};
pub use decimate::{DecimateError, MAX_PASSES, MIN_QUALITY, SHAPE_WEIGHT, decimate};
pub use error::{FileKind, GeometryError, MeshError, ReadError, Result, ScaleSite};
pub use fibers::{
    EXIT_TOLERANCE, FiberSet, VisibilityOptions, VisibilityReport, crosses_surface_brute_force, cull_fibers,
    self_intersections,
};
pub use icosphere::{fibonacci_sphere, hollow_icosphere, icosphere};
pub use image::{
    AffineSource, GZIP_MARGIN, ImageError, ImageProblem, LabelImage, LabelType, NiftiWriteOptions,
    nifti_bytes, read_nifti, read_nifti_bytes, read_nifti_with, write_nifti,
};
pub use io::{
    DEFAULT_MAX_FILE_BYTES, MAX_FILE_BYTES_ENV, MeshFile, ReadOptions, load_mesh, load_mesh_with,
    max_file_bytes, parse_byte_count, read_file_limited, read_obj_bytes, read_off_bytes, read_ply_bytes,
    read_stl_bytes, set_max_file_bytes, write_obj, write_obj_to, write_off, write_ply,
};
pub use isosurface::{
    LabelSelection, LabelSurface, SMOOTH_VOLUME_TOLERANCE, SurfaceError, SurfaceOptions, extract_surface,
};
pub use mesh::{
    CONVEXITY_TOLERANCE, DEGENERATE_AREA, NEAR_DUPLICATE, TriMesh, Validation, bounding_box,
    face_area_vector, raw_vertex_vectors, vertex_area_vectors, volume,
};
pub use off::write_off_to;
pub use ply::{PlyFormat, write_ply_to};
pub use polygon::Polygon;
pub use shells::{Shell, winding_number};
pub use turned::{
    TURN_LIMIT, edges_turned_inside_out, faces_turned_given, faces_turned_inside_out, neighbourhood_angles,
};
pub use unit::LengthUnit;
pub use vec3::{AXES, Vec3};
pub use voxel::{PointLattice, for_each_inside_line, inside_lattice};
