//! The finite-element run's volume as NumPy arrays: the grid's nodes and hexahedra with the
//! fields `volume.vtu` holds, in SI units (metres, Pa) and VTK's corner order.

use fibfluid_sim::fem_run::VolumeAnswer;
use numpy::ndarray::{Array1, Array2};
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::prelude::*;

/// VTK's corner order of a hexahedron (`VTK_HEXAHEDRON`) in the grid's corner numbering
/// (corner `b` at `(b & 1, (b >> 1) & 1, (b >> 2) & 1)`), as `volume.vtu` writes it
/// (`crates/cli/src/vtu.rs`; a test compares the two).
const VTK_HEX: [usize; 8] = [0, 1, 3, 2, 4, 5, 7, 6];

/// The volume's arrays, built without the GIL (flat, row-major).
pub(crate) struct VolumeArrays {
    nodes: Vec<f64>,
    displacement: Vec<f64>,
    hexahedra: Vec<i64>,
    dilatation: Vec<f64>,
    max_principal_strain: Vec<f64>,
    von_mises: Vec<f64>,
    fill: Vec<f64>,
    material_id: Vec<i32>,
}

impl VolumeArrays {
    /// Takes the run's volume: the node positions (computed once) and the displacements are
    /// flattened in place, the cells converted once (corner order, `i64`) and each cell field
    /// gathered once.
    pub(crate) fn of(volume: VolumeAnswer) -> Self {
        let cells = volume.grid.cell_nodes();
        // A node index is far below 2^63 (the grid's nodes are in memory).
        let hexahedra = cells.iter().flat_map(|c| VTK_HEX.map(|b| c[b] as i64)).collect();
        Self {
            nodes: volume.grid.node_positions().into_flattened(),
            hexahedra,
            dilatation: volume.cells.iter().map(|c| c.dilatation).collect(),
            max_principal_strain: volume.cells.iter().map(|c| c.max_principal_strain).collect(),
            von_mises: volume.cells.iter().map(|c| c.von_mises).collect(),
            fill: volume.grid.fill().to_vec(),
            material_id: volume.region_ids.iter().map(|&m| i32::from(m)).collect(),
            displacement: volume.node_displacements.into_flattened(),
        }
    }
}

/// The finite-element run's volume (`volume.vtu` without the file): the grid's nodes and
/// its active cells, in SI units.
#[pyclass(module = "fibfluid._native", name = "VolumeOutput", frozen)]
pub(crate) struct VolumeOutput {
    /// Rest positions of the grid's nodes `(N, 3)`, metres.
    #[pyo3(get)]
    nodes: Py<PyArray2<f64>>,
    /// Displacement of every node `(N, 3)`, metres.
    #[pyo3(get)]
    displacement: Py<PyArray2<f64>>,
    /// Node indices of every active cell `(C, 8)`, in VTK's hexahedron corner order.
    #[pyo3(get)]
    hexahedra: Py<PyArray2<i64>>,
    /// Each cell's mean dilatation `J` (current over rest volume) `(C,)`.
    #[pyo3(get, name = "J")]
    dilatation: Py<PyArray1<f64>>,
    /// Each cell's largest principal Green–Lagrange strain `(C,)`.
    #[pyo3(get)]
    max_principal_strain: Py<PyArray1<f64>>,
    /// Each cell's von Mises Cauchy stress `(C,)`, Pa.
    #[pyo3(get)]
    von_mises_stress: Py<PyArray1<f64>>,
    /// Each cell's fill fraction, in `(0, 1]` `(C,)`.
    #[pyo3(get)]
    fill: Py<PyArray1<f64>>,
    /// Each cell's material: 0 the `[tissue]`, `k` the `k`-th `[[region]]` `(C,)`.
    #[pyo3(get)]
    material_id: Py<PyArray1<i32>>,
}

/// `(n, k)` from a flat row-major vector of `n * k` values, without a copy.
fn rows<T: numpy::Element>(py: Python<'_>, flat: Vec<T>, k: usize, what: &str) -> PyResult<Py<PyArray2<T>>> {
    let n = flat.len() / k;
    let a = Array2::from_shape_vec((n, k), flat)
        .map_err(|e| crate::error(format!("the volume's {what}: {e}")))?;
    Ok(a.into_pyarray(py).unbind())
}

/// A 1-D array, without a copy.
fn column<T: numpy::Element>(py: Python<'_>, v: Vec<T>) -> Py<PyArray1<T>> {
    Array1::from_vec(v).into_pyarray(py).unbind()
}

impl VolumeOutput {
    /// The arrays handed to NumPy (their buffers move, nothing is copied).
    pub(crate) fn new(py: Python<'_>, v: VolumeArrays) -> PyResult<Self> {
        Ok(Self {
            nodes: rows(py, v.nodes, 3, "nodes")?,
            displacement: rows(py, v.displacement, 3, "displacements")?,
            hexahedra: rows(py, v.hexahedra, 8, "cells")?,
            dilatation: column(py, v.dilatation),
            max_principal_strain: column(py, v.max_principal_strain),
            von_mises_stress: column(py, v.von_mises),
            fill: column(py, v.fill),
            material_id: column(py, v.material_id),
        })
    }
}
