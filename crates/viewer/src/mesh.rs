//! The surface a viewer shows, in the input file's vertex order, and the map to a body's
//! own vertex order.

use fibfluid_geometry::{MeshFile, Vec3};
use fibfluid_interact::Interactive;

use crate::{Result, ViewerError};

/// The rest shape of a body as the protocol speaks of it: positions, triangles and fixed
/// vertices in the input file's vertex order, and the map from the body's vertices to the
/// file's.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewMesh {
    /// Rest positions in file order (every vertex of the file, used by a face or not).
    pub positions: Vec<Vec3>,
    /// Triangles in file vertex indices.
    pub triangles: Vec<[u32; 3]>,
    /// File vertices the scene fixes along any axis, ascending.
    pub fixed: Vec<u32>,
    /// For each body vertex, its index in the file.
    pub to_file: Vec<u32>,
    /// For each file vertex, its body vertex (`None` for a vertex no face uses).
    to_body: Vec<Option<u32>>,
}

impl ViewMesh {
    /// The mesh of a body whose vertices are the compacted vertices of `file` (as a scene's
    /// body is): rest positions from the body, fixed vertices from
    /// [`Interactive::is_fixed`].
    pub fn new(file: &MeshFile, body: &dyn Interactive) -> Result<Self> {
        let n = body.n_vertices();
        if file.to_file.len() != n {
            return Err(ViewerError::Mismatch {
                problem: format!("the body has {n} vertices, the mesh {}", file.to_file.len()),
            });
        }
        let positions = file.positions_in_file_order(body.rest_positions());
        Self::from_parts(positions, file.triangles_in_file_order(), file.to_file.clone(), body)
    }

    /// The mesh of a body whose vertex order is the file order (a mesh built in code):
    /// rest positions from the body.
    pub fn identity(triangles: Vec<[u32; 3]>, body: &dyn Interactive) -> Result<Self> {
        let n = body.n_vertices();
        Self::from_parts(body.rest_positions().to_vec(), triangles, (0..n as u32).collect(), body)
    }

    fn from_parts(
        positions: Vec<Vec3>,
        triangles: Vec<[u32; 3]>,
        to_file: Vec<u32>,
        body: &dyn Interactive,
    ) -> Result<Self> {
        let count = positions.len();
        if let Some(t) = triangles.iter().find(|t| t.iter().any(|&v| v as usize >= count)) {
            return Err(ViewerError::Mismatch {
                problem: format!("triangle {t:?} refers to a vertex beyond the {count} of the mesh"),
            });
        }
        let mut to_body = vec![None; count];
        for (b, &f) in to_file.iter().enumerate() {
            match to_body.get_mut(f as usize) {
                Some(slot) => *slot = Some(b as u32),
                None => {
                    return Err(ViewerError::Mismatch {
                        problem: format!(
                            "body vertex {b} maps to file vertex {f} beyond the {count} of the mesh"
                        ),
                    });
                }
            }
        }
        let mut fixed: Vec<u32> =
            (0..to_file.len()).filter(|&b| body.is_fixed(b)).map(|b| to_file[b]).collect();
        fixed.sort_unstable();
        Ok(Self { positions, triangles, fixed, to_file, to_body })
    }

    /// Number of vertices in the file (the `N` of the binary position messages).
    pub fn n_file_vertices(&self) -> usize {
        self.positions.len()
    }

    /// The body vertex of file vertex `v` (`None` when out of range or used by no face).
    pub fn body_vertex(&self, v: usize) -> Option<usize> {
        self.to_body.get(v).copied().flatten().map(|b| b as usize)
    }

    /// `GET /mesh`: `{"positions": [x, y, z, ...], "triangles": [i, j, k, ...], "fixed": [v, ...]}`.
    pub fn to_json(&self) -> String {
        let positions: Vec<f64> = self.positions.iter().flatten().copied().collect();
        let triangles: Vec<u32> = self.triangles.iter().flatten().copied().collect();
        serde_json::json!({ "positions": positions, "triangles": triangles, "fixed": self.fixed }).to_string()
    }
}
