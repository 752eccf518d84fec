//! ndarray in and out (feature `ndarray`), for crates that already keep their data in
//! [`ndarray`] arrays.
//!
//! Points and vectors are `N x 3` arrays of `f64`, one row per vertex and the columns x, y,
//! z, in the order of the mesh's vertices (for a mesh read from a file that is the order of
//! the vertices the faces use, see [`MeshFile`]). Triangles are `F x 3` arrays of vertex
//! indices of any integer type. Arrays are read through their strides, so views (a
//! transposed or sliced array) work as well as standard-layout arrays.
//!
//! ```no_run
//! use fibfluid::ndarray_io::{displacements, ndarray, positions_array, scene_from_arrays};
//! use fibfluid::{RunOptions, Simulation};
//! # fn get() -> (ndarray::Array2<f64>, ndarray::Array2<i64>) { unimplemented!() }
//! let (points, faces) = get(); // N x 3 and F x 3 from elsewhere
//! let material = fibfluid::assembly::Material::isotropic(800.0, 40.0, 1000.0);
//! let scene = scene_from_arrays("body", points.view(), faces.view(), material)?;
//! // ... fix vertices in `scene.constraints`, set loads ...
//! let mut sim = Simulation::new(scene)?;
//! sim.run(&RunOptions::default())?;
//! let u = displacements(&sim); // N x 3
//! let x = positions_array(sim.positions());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::fmt::Display;

use fibfluid_assembly::Material;
use fibfluid_geometry::{MeshError, MeshFile, TriMesh, Vec3};
use ndarray::{Array2, ArrayView2};

use crate::{Scene, Simulation};

/// The ndarray crate these functions take and return (0.17), for callers that want the
/// same version.
pub use ndarray;

/// An array that cannot be turned into points or triangles.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ArrayError {
    /// The array does not have 3 columns.
    #[error("{what} must be an N x 3 array, got {rows} x {cols}")]
    Shape {
        /// What the array was meant to hold (`positions`, `triangles`).
        what: &'static str,
        /// Rows given.
        rows: usize,
        /// Columns given.
        cols: usize,
    },
    /// A triangle's vertex index is negative or does not fit in `u32`.
    #[error("triangle {row}: vertex index {value} is not a valid index (0 to 4294967295)")]
    Index {
        /// The triangle (row of the array).
        row: usize,
        /// The index as given.
        value: String,
    },
    /// The points and triangles are not one closed, manifold, consistently oriented surface,
    /// or a coordinate is not finite.
    #[error(transparent)]
    Mesh(#[from] MeshError),
}

/// Points as an `N x 3` array, one row per point.
pub fn positions_array(points: &[Vec3]) -> Array2<f64> {
    Array2::from_shape_fn((points.len(), 3), |(i, c)| points[i][c])
}

/// Points from an `N x 3` array (any strides); an error names the shape if it is not N x 3.
pub fn vec3s_from_array(a: ArrayView2<'_, f64>) -> Result<Vec<Vec3>, ArrayError> {
    check_n_by_3("positions", a.dim())?;
    Ok(a.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect())
}

/// The displacement field `x - x0` of a simulation, `N x 3`, in the order of
/// [`Simulation::positions`] (z = 0 for the 2D variant).
pub fn displacements(sim: &Simulation) -> Array2<f64> {
    let (x, x0) = (sim.positions(), sim.rest_positions());
    Array2::from_shape_fn((x.len(), 3), |(i, c)| x[i][c] - x0[i][c])
}

/// Triangles as an `F x 3` array of vertex indices.
pub fn triangles_array(triangles: &[[u32; 3]]) -> Array2<u32> {
    Array2::from_shape_fn((triangles.len(), 3), |(k, c)| triangles[k][c])
}

/// Triangles from an `F x 3` array of vertex indices of any integer type (`i64` from
/// NumPy, `usize`, `u32`); an error names a negative or too large index and its row.
pub fn triangles_from_array<T>(t: ArrayView2<'_, T>) -> Result<Vec<[u32; 3]>, ArrayError>
where
    T: Copy + Display + TryInto<u32>,
{
    check_n_by_3("triangles", t.dim())?;
    t.rows()
        .into_iter()
        .enumerate()
        .map(|(row, r)| {
            let index = |v: T| v.try_into().map_err(|_| ArrayError::Index { row, value: v.to_string() });
            Ok([index(r[0])?, index(r[1])?, index(r[2])?])
        })
        .collect()
}

/// A validated mesh from `N x 3` positions and `F x 3` triangles: the arrays' vertex order
/// is kept (an inward surface is flipped, with a warning in the [`MeshFile`]'s notes), and
/// `name` stands for the file in messages.
pub fn mesh_file_from_arrays<T>(
    name: &str,
    positions: ArrayView2<'_, f64>,
    triangles: ArrayView2<'_, T>,
) -> Result<MeshFile, ArrayError>
where
    T: Copy + Display + TryInto<u32>,
{
    let mesh = TriMesh::new(vec3s_from_array(positions)?, triangles_from_array(triangles)?)?;
    Ok(MeshFile::from_mesh(name, mesh)?)
}

/// A scene for the surface given by `N x 3` positions and `F x 3` triangles, like
/// [`Scene::from_mesh`]: no constraints, no loads, the default solver.
pub fn scene_from_arrays<T>(
    name: &str,
    positions: ArrayView2<'_, f64>,
    triangles: ArrayView2<'_, T>,
    material: Material,
) -> Result<Scene, ArrayError>
where
    T: Copy + Display + TryInto<u32>,
{
    Ok(Scene::from_mesh(name, mesh_file_from_arrays(name, positions, triangles)?, material))
}

fn check_n_by_3(what: &'static str, (rows, cols): (usize, usize)) -> Result<(), ArrayError> {
    if cols == 3 { Ok(()) } else { Err(ArrayError::Shape { what, rows, cols }) }
}
