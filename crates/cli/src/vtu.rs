//! `volume.vtu`: the finite-element run's active cells as an XML VTK unstructured grid
//! (ASCII), so ParaView shows inside the tissue: the deformed grid nodes with their
//! displacement, and per cell its mean dilatation `J`, the largest principal Green–Lagrange
//! strain, the von Mises Cauchy stress (Pa), its fill fraction and its material id.

use std::io::Write;

use fibfluid::fem::SparseGrid;
use fibfluid::fem::Tissue;
use fibfluid::fem::hyper::{CellState, TimeFields};
use fibfluid::geometry::{LengthUnit, Vec3};
use fibfluid::sim::fem_run::FemRun;

/// The name of the volume file a finite-element run writes.
pub const VOLUME_FILE: &str = "volume.vtu";

/// VTK's corner order of a hexahedron (`VTK_HEXAHEDRON`, type 12) in the grid's corner
/// numbering (corner `b` at `(b & 1, (b >> 1) & 1, (b >> 2) & 1)`).
const VTK_HEX: [usize; 8] = [0, 1, 3, 2, 4, 5, 7, 6];

/// Writes one ASCII `DataArray` of VTK type `kind` (`Float64`, `Int64`, ...), one value
/// (a tuple of `components`) per line.
pub(crate) fn array(
    out: &mut impl Write,
    kind: &str,
    name: &str,
    components: usize,
    values: impl Iterator<Item = String>,
) -> std::io::Result<()> {
    writeln!(
        out,
        r#"<DataArray type="{kind}" Name="{name}" NumberOfComponents="{components}" format="ascii">"#
    )?;
    for v in values {
        writeln!(out, "{v}")?;
    }
    writeln!(out, "</DataArray>")
}

/// `text` made safe inside an XML comment (no `--`, one line).
pub(crate) fn comment_text(text: &str) -> String {
    let mut s = text.replace(['\n', '\r'], " ");
    while s.contains("--") {
        s = s.replace("--", "- -");
    }
    s
}

/// What a volume file shows: the grid, its nodes' displacements (m), its cells' states
/// and region ids.
#[derive(Debug, Clone, Copy)]
pub struct VolumeView<'a> {
    /// The grid.
    pub grid: &'a SparseGrid,
    /// The displacement of every grid node, m.
    pub node_displacements: &'a [Vec3],
    /// Each cell's strain, `J` and stress (Pa).
    pub cells: &'a [CellState],
    /// Each cell's region id (`material_id`).
    pub region_ids: &'a [u16],
}

impl<'a> VolumeView<'a> {
    /// A finished run's volume.
    pub fn of_run(run: &'a FemRun) -> Self {
        let v = &run.volume;
        Self {
            grid: &v.grid,
            node_displacements: &v.node_displacements,
            cells: &v.cells,
            region_ids: &v.region_ids,
        }
    }

    /// A timed run's volume at one output time.
    pub fn of_fields(fields: &'a TimeFields<'a>) -> Self {
        Self {
            grid: fields.grid,
            node_displacements: fields.node_displacements,
            cells: fields.cells,
            region_ids: fields.region_ids,
        }
    }
}

/// The comment a volume file opens with: the scene's name, the tissue's law and the units.
pub fn volume_comment(name: &str, tissue: &Tissue, unit: LengthUnit) -> String {
    format!("fibfluid {name} ({}, {unit}): lengths in {unit}, stresses in Pa", tissue.model())
}

/// Writes the run's cells (positions and displacements in the mesh file's unit, stresses in
/// Pa).
pub fn write_vtu(out: &mut impl Write, run: &FemRun) -> std::io::Result<()> {
    let comment = volume_comment(&run.model.name, &run.tissue, run.model.unit);
    write_volume(out, &comment, run.model.unit, &VolumeView::of_run(run))
}

/// Writes `volume`'s cells under the XML comment `comment` (one line, made safe here):
/// positions and displacements in `unit`, stresses in Pa.
pub fn write_volume(
    out: &mut impl Write,
    comment: &str,
    unit: LengthUnit,
    volume: &VolumeView<'_>,
) -> std::io::Result<()> {
    let to_unit = 1.0 / unit.metres();
    let grid = volume.grid;
    let nodes = grid.node_positions();
    let cells = grid.cell_nodes();
    writeln!(out, r#"<?xml version="1.0"?>"#)?;
    writeln!(
        out,
        r#"<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64">"#
    )?;
    writeln!(out, "<!-- {} -->", comment_text(comment))?;
    writeln!(out, "<UnstructuredGrid>")?;
    writeln!(out, r#"<Piece NumberOfPoints="{}" NumberOfCells="{}">"#, nodes.len(), cells.len())?;
    writeln!(out, "<Points>")?;
    let deformed = nodes.iter().zip(volume.node_displacements).map(|(p, u)| {
        format!("{:?} {:?} {:?}", (p[0] + u[0]) * to_unit, (p[1] + u[1]) * to_unit, (p[2] + u[2]) * to_unit)
    });
    array(out, "Float64", "Points", 3, deformed)?;
    writeln!(out, "</Points>")?;
    writeln!(out, "<Cells>")?;
    let connectivity = cells.iter().map(|c| VTK_HEX.map(|b| c[b].to_string()).join(" "));
    array(out, "Int64", "connectivity", 1, connectivity)?;
    array(out, "Int64", "offsets", 1, (1..=cells.len()).map(|k| (8 * k).to_string()))?;
    array(out, "UInt8", "types", 1, cells.iter().map(|_| "12".to_string()))?;
    writeln!(out, "</Cells>")?;
    writeln!(out, r#"<PointData Vectors="displacement">"#)?;
    let disp = volume
        .node_displacements
        .iter()
        .map(|u| format!("{:?} {:?} {:?}", u[0] * to_unit, u[1] * to_unit, u[2] * to_unit));
    array(out, "Float64", "displacement", 3, disp)?;
    writeln!(out, "</PointData>")?;
    writeln!(out, r#"<CellData Scalars="J">"#)?;
    let cell = |f: fn(&CellState) -> f64| volume.cells.iter().map(move |c| format!("{:?}", f(c)));
    array(out, "Float64", "J", 1, cell(|c| c.dilatation))?;
    array(out, "Float64", "max_principal_strain", 1, cell(|c| c.max_principal_strain))?;
    array(out, "Float64", "von_mises_stress", 1, cell(|c| c.von_mises))?;
    array(out, "Float64", "fill", 1, grid.fill().iter().map(|f| format!("{f:?}")))?;
    array(out, "Int32", "material_id", 1, volume.region_ids.iter().map(|m| m.to_string()))?;
    writeln!(out, "</CellData>")?;
    writeln!(out, "</Piece>")?;
    writeln!(out, "</UnstructuredGrid>")?;
    writeln!(out, "</VTKFile>")
}
