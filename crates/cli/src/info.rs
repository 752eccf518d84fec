//! `mesh-info`: what a mesh is, as a serializable summary.

use std::path::Path;
use std::time::Instant;

use fibfluid::geometry::vec3::norm;
use fibfluid::geometry::{Vec3, VisibilityOptions, cull_fibers, load_mesh, self_intersections};
use serde::Serialize;

use crate::Result;

/// A summary of a mesh file: size, area, volume, convexity and kept fibers (the groups are
/// flattened into one JSON object).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MeshInfo {
    /// The file, as given.
    pub path: String,
    /// Vertices used by faces.
    pub vertices: usize,
    /// Faces (triangles).
    pub faces: usize,
    /// Vertices in the file, used or not.
    pub file_vertices: usize,
    /// Area and volume of the surface.
    #[serde(flatten)]
    pub measures: SurfaceMeasures,
    /// Closedness, genus and orientation.
    #[serde(flatten)]
    pub topology: SurfaceTopology,
    /// Axis-aligned bounding box, lower corner.
    pub bbox_min: Vec3,
    /// Axis-aligned bounding box, upper corner.
    pub bbox_max: Vec3,
    /// Convexity and the fibers the visibility tests kept.
    #[serde(flatten)]
    pub fibers: FiberCounts,
    /// Pairs of faces that cross each other.
    pub self_intersections: usize,
    /// Warnings about the mesh.
    pub notes: Vec<String>,
    /// Seconds to load, check and cull.
    pub seconds: f64,
}

/// Area and volume of the surface.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SurfaceMeasures {
    /// Surface area, sum |A_k| (Eq. 1).
    pub area: f64,
    /// Sum of the vertex area vectors' lengths, sum |S_i| (Eq. 2; equals `area`).
    pub vertex_area_sum: f64,
    /// Enclosed volume.
    pub volume: f64,
}

/// Closedness, genus and orientation.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SurfaceTopology {
    /// Always true: an open surface is an error.
    pub closed: bool,
    /// Genus of the surface.
    pub genus: i64,
    /// Whether the file's faces pointed inward and were flipped.
    pub flipped: bool,
    /// Each cavity's volume (closed surfaces inside the outer one; cavity `K` is entry
    /// `K - 1`).
    pub cavities: Vec<f64>,
}

/// Convexity and the fibers the visibility tests kept.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FiberCounts {
    /// Whether the body is convex (every fiber kept, no test run).
    pub convex: bool,
    /// Candidate fibers, N(N-1)/2.
    pub fibers_total: usize,
    /// Fibers kept.
    pub fibers_kept: usize,
    /// Fibers removed by the exit test.
    pub fibers_removed_exit: usize,
    /// Fibers removed by the crossing test.
    pub fibers_removed_crossing: usize,
}

impl MeshInfo {
    /// Loads `path`, validates it, culls its fibers and summarizes it; the kept fibers
    /// are returned too (for writing them out).
    pub fn of_file(path: &Path) -> Result<(Self, fibfluid::geometry::FiberSet)> {
        let start = Instant::now();
        let file = load_mesh(path)?;
        let mesh = &file.mesh;
        let (fibers, vis) = cull_fibers(mesh, &VisibilityOptions::default());
        let seconds = start.elapsed().as_secs_f64();
        let crossings = self_intersections(mesh);
        let mut notes = file.notes.clone();
        if let Some(&(a, b)) = crossings.first() {
            notes.push(format!(
                "the surface intersects itself: {} face pairs cross (e.g. faces {a} and {b}); fibers near them may be culled inconsistently",
                crossings.len(),
            ));
        }
        let (bbox_min, bbox_max) = mesh.bounding_box();
        let info = MeshInfo {
            path: path.display().to_string(),
            vertices: mesh.n_vertices(),
            faces: mesh.n_faces(),
            file_vertices: file.file_vertex_count(),
            measures: SurfaceMeasures {
                area: mesh.area(),
                vertex_area_sum: mesh.vertex_area_vectors().iter().map(|s| norm(*s)).sum(),
                volume: mesh.volume(),
            },
            topology: SurfaceTopology {
                closed: true,
                genus: file.validation.genus,
                flipped: file.validation.flipped,
                cavities: file.validation.cavities.clone(),
            },
            bbox_min,
            bbox_max,
            fibers: FiberCounts {
                convex: vis.convex,
                fibers_total: fibers.total(),
                fibers_kept: fibers.kept(),
                fibers_removed_exit: vis.removed_by_exit,
                fibers_removed_crossing: vis.removed_by_crossing,
            },
            self_intersections: crossings.len(),
            notes,
            seconds,
        };
        Ok((info, fibers))
    }
}
