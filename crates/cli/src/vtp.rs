//! `deformed.vtp`: the deformed surface as an XML VTK PolyData file (ASCII), with the point
//! data `deformed.vtk` carries: the displacement vector and its magnitude, in the mesh file's
//! unit. Readers that take XML VTK but not the legacy format (meshio, VTK's XML readers,
//! ParaView's time series) open it.

use std::io::Write;

use fibfluid::geometry::Vec3;

use crate::vtu::{array, comment_text};

/// The name of the XML surface file every run writes.
pub const SURFACE_FILE: &str = "deformed.vtp";

/// Writes the surface: `positions` (points), `triangles` (polys) and per point
/// `displacement` and `displacement_magnitude`. `title` goes into an XML comment.
pub fn write_vtp(
    out: &mut impl Write,
    title: &str,
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    displacement: &[Vec3],
) -> std::io::Result<()> {
    let xyz = |p: &Vec3| format!("{:?} {:?} {:?}", p[0], p[1], p[2]);
    writeln!(out, r#"<?xml version="1.0"?>"#)?;
    writeln!(
        out,
        r#"<VTKFile type="PolyData" version="1.0" byte_order="LittleEndian" header_type="UInt64">"#
    )?;
    writeln!(out, "<!-- {} -->", comment_text(title))?;
    writeln!(out, "<PolyData>")?;
    writeln!(
        out,
        r#"<Piece NumberOfPoints="{}" NumberOfVerts="0" NumberOfLines="0" NumberOfStrips="0" NumberOfPolys="{}">"#,
        positions.len(),
        triangles.len()
    )?;
    writeln!(out, r#"<PointData Vectors="displacement" Scalars="displacement_magnitude">"#)?;
    array(out, "Float64", "displacement", 3, displacement.iter().map(xyz))?;
    let magnitude =
        displacement.iter().map(|d| format!("{:?}", (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()));
    array(out, "Float64", "displacement_magnitude", 1, magnitude)?;
    writeln!(out, "</PointData>")?;
    writeln!(out, "<Points>")?;
    array(out, "Float64", "Points", 3, positions.iter().map(xyz))?;
    writeln!(out, "</Points>")?;
    writeln!(out, "<Polys>")?;
    let connectivity = triangles.iter().map(|t| format!("{} {} {}", t[0], t[1], t[2]));
    array(out, "Int64", "connectivity", 1, connectivity)?;
    array(out, "Int64", "offsets", 1, (1..=triangles.len()).map(|k| (3 * k).to_string()))?;
    writeln!(out, "</Polys>")?;
    writeln!(out, "</Piece>")?;
    writeln!(out, "</PolyData>")?;
    writeln!(out, "</VTKFile>")
}
