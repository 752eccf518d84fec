"""`Result.volume`, the finite-element run's answer inside the tissue, against the command
line's `volume.vtu` for the same scene file (read here with the standard library's XML
parser), and its conversions to meshio and PyVista (skipped when those are not installed)."""

import importlib.util
import re
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

import fibfluid
from conftest import SCENES, SPHERE_FEM_CM, SPHERE_MESH, run_cli

FAT = {"young": 3250.0, "poisson": 0.45, "density": 930.0}
LESION = {"young": 22000.0, "poisson": 0.45, "density": 1000.0}
H = 0.002  # voxel size, m

#: Metres per unit of the lengths volume.vtu names in its comment.
UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3}

CELL_FIELDS = ("J", "max_principal_strain", "von_mises_stress", "fill", "material_id")


def needs(module: str):
    """Skips a test, before its fixtures run, when `module` is not installed."""
    return pytest.mark.skipif(importlib.util.find_spec(module) is None, reason=f"{module} is not installed")


def two_labels() -> np.ndarray:
    """A ball of fat (radius 6 voxels) with an off-centre ball of lesion (radius 2.5)."""
    i, j, k = np.indices((16, 16, 16)) - 7.5
    labels = np.where(i * i + j * j + k * k < 36, 1, 0).astype(np.uint8)
    labels[(i - 1.5) ** 2 + j * j + k * k < 6.25] = 2
    return labels


def read_vtu(path):
    """volume.vtu as arrays: {name: values} for the points, the cells and every field, the
    counts of its Piece, and metres per unit of its lengths (its comment names the unit)."""
    text = path.read_text()
    unit = re.search(r"lengths in (\w+), stresses in Pa", text).group(1)
    piece = ET.fromstring(text).find("UnstructuredGrid/Piece")
    arrays = {}
    for section in ("Points", "Cells", "PointData", "CellData"):
        for a in piece.findall(f"{section}/DataArray"):
            kind = int if a.get("type").startswith(("Int", "UInt")) else float
            values = np.array([kind(x) for x in a.text.split()])
            components = int(a.get("NumberOfComponents"))
            arrays[a.get("Name")] = values.reshape(-1, components) if components > 1 else values
    counts = int(piece.get("NumberOfPoints")), int(piece.get("NumberOfCells"))
    return arrays, counts, UNITS[unit]


def run_both(cli, scene_path, out):
    """The command line's volume.vtu and the package's result for one scene file."""
    done = run_cli(cli, "run", str(scene_path), "--out", str(out))
    assert done.returncode == 0, done.stderr
    result = fibfluid.run(fibfluid.Scene.load(scene_path), method="fem")
    return read_vtu(out / "volume.vtu"), result


@pytest.fixture(scope="module")
def sphere(cli, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("volume-sphere")
    scene = tmp / "sphere-fem.toml"
    scene.write_text(SPHERE_FEM_CM.format(mesh=SPHERE_MESH.as_posix()))
    return run_both(cli, scene, tmp / "out")


@pytest.fixture(scope="module")
def lesion(cli, tmp_path_factory):
    """A label volume with a lesion (two materials, neo-Hookean), written by
    `Scene.from_labels` and run by both from the same scene file, on a coarse grid (about
    750 cells: a few seconds for an unoptimized command line)."""
    tmp = tmp_path_factory.mktemp("volume-lesion")
    scene = fibfluid.Scene.from_labels(
        two_labels(), [H, H, H], {1: FAT, 2: LESION}, fix={"axis": "y", "above": 0.025, "dofs": ["x", "y", "z"]},
        gravity=[0.0, -9.81, 0.0], directory=tmp,
    )
    path = Path(scene.source)
    path.write_text(path.read_text() + "[fem]\nresolution = 10\n")
    return run_both(cli, path, tmp / "out")


@pytest.mark.parametrize("case", ["sphere", "lesion"])
def test_the_volume_equals_the_command_lines_volume_vtu(case, request):
    (vtu, (n_points, n_cells), metres), result = request.getfixturevalue(case)
    v = result.volume
    assert isinstance(v, fibfluid.Volume)
    assert (v.n_nodes, v.n_cells) == (n_points, n_cells) == (len(v.nodes), len(v.hexahedra))
    assert n_cells == result.report["fem"]["cells"] and n_points == result.report["fem"]["nodes"]
    assert v.nodes.shape == v.displacement.shape == (n_points, 3)
    assert v.hexahedra.shape == (n_cells, 8) and v.hexahedra.dtype == np.int64
    assert set(vtu["types"]) == {12}
    np.testing.assert_array_equal(vtu["offsets"], 8 * np.arange(1, n_cells + 1))
    np.testing.assert_array_equal(v.hexahedra, vtu["connectivity"].reshape(-1, 8))
    # Lengths: the package's are metres, the file's in the mesh's unit, converted as the
    # command line converts them (one product), printed to the last digit.
    to_unit = 1.0 / metres
    np.testing.assert_array_equal((v.nodes + v.displacement) * to_unit, vtu["Points"])
    np.testing.assert_array_equal(v.displacement * to_unit, vtu["displacement"])
    assert np.abs(v.displacement).max() > 0
    for name in CELL_FIELDS:
        values = v.cell_data[name]
        assert values.shape == (n_cells,), name
        np.testing.assert_array_equal(values, vtu[name], err_msg=name)
    assert np.all(v.J > 0) and np.all((v.fill > 0) & (v.fill <= 1))
    assert v.von_mises_stress.max() > 0


def test_the_lesion_has_cells_of_its_own_material(lesion):
    (vtu, _, _), result = lesion
    v = result.volume
    assert set(np.unique(v.material_id)) == {0, 1}
    (region,) = result.report["regions"]
    assert np.count_nonzero(v.material_id == 1) == region["cells"]


def test_the_rest_grid_is_regular_hexahedra(sphere):
    """Every rest cell is an axis-aligned cube: corners in VTK's order (0, 1, 2, 3 around
    the bottom face, 4 to 7 above them) at the offsets VTK_HEXAHEDRON expects."""
    _, result = sphere
    v = result.volume
    corners = v.nodes[v.hexahedra]  # (C, 8, 3)
    h = corners[0, 1, 0] - corners[0, 0, 0]
    assert h > 0
    vtk_offsets = np.array(
        [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], dtype=float
    )
    np.testing.assert_allclose(corners - corners[:, :1, :], np.broadcast_to(h * vtk_offsets, corners.shape),
                               rtol=0, atol=1e-12)


def test_an_ffm_run_has_no_volume():
    result = fibfluid.run(fibfluid.Scene.load(SCENES / "sphere.toml"))
    assert result.volume is None
    with pytest.raises(fibfluid.Error, match="no volume"):
        result.volume_to_meshio()
    with pytest.raises(fibfluid.Error, match="no volume"):
        result.volume_to_pyvista()


def test_a_missing_optional_dependency_says_how_to_install_it(sphere, monkeypatch):
    _, result = sphere
    monkeypatch.setitem(sys.modules, "meshio", None)
    monkeypatch.setitem(sys.modules, "pyvista", None)
    with pytest.raises(ImportError, match="pip install meshio"):
        result.volume_to_meshio()
    with pytest.raises(ImportError, match="pip install pyvista"):
        result.volume_to_pyvista()


@needs("meshio")
@pytest.mark.parametrize("case", ["sphere", "lesion"])
def test_the_volume_converts_to_meshio(case, request):
    import meshio

    (vtu, (n_points, n_cells), metres), result = request.getfixturevalue(case)
    v = result.volume
    mesh = result.volume_to_meshio()
    assert isinstance(mesh, meshio.Mesh)
    assert [c.type for c in mesh.cells] == ["hexahedron"]
    np.testing.assert_array_equal(mesh.cells_dict["hexahedron"], vtu["connectivity"].reshape(-1, 8))
    assert mesh.points.shape == (n_points, 3)
    np.testing.assert_array_equal(mesh.points * (1.0 / metres), vtu["Points"])
    assert set(mesh.point_data) == {"displacement"}
    np.testing.assert_array_equal(mesh.point_data["displacement"] * (1.0 / metres), vtu["displacement"])
    assert set(mesh.cell_data) == set(CELL_FIELDS)
    for name in CELL_FIELDS:
        (values,) = mesh.cell_data[name]
        np.testing.assert_array_equal(values, vtu[name], err_msg=name)
        assert np.shares_memory(values, v.cell_data[name]), f"{name} was copied"
    assert np.shares_memory(mesh.cells[0].data, v.hexahedra)
    assert np.shares_memory(mesh.point_data["displacement"], v.displacement)


@needs("pyvista")
@pytest.mark.parametrize("case", ["sphere", "lesion"])
def test_the_volume_converts_to_pyvista(case, request):
    import pyvista

    (vtu, (n_points, n_cells), metres), result = request.getfixturevalue(case)
    v = result.volume
    grid = result.volume_to_pyvista()
    assert isinstance(grid, pyvista.UnstructuredGrid)
    assert (grid.n_cells, grid.n_points) == (n_cells, n_points)
    assert set(grid.celltypes) == {pyvista.CellType.HEXAHEDRON}
    np.testing.assert_array_equal(grid.cell_connectivity.reshape(-1, 8), v.hexahedra)
    np.testing.assert_array_equal(grid.points, v.nodes + v.displacement)
    np.testing.assert_array_equal(np.asarray(grid.points) * (1.0 / metres), vtu["Points"])
    np.testing.assert_array_equal(grid.point_data["displacement"], v.displacement)
    for name in CELL_FIELDS:
        np.testing.assert_array_equal(grid.cell_data[name], vtu[name], err_msg=name)
    assert np.shares_memory(np.asarray(grid.cell_data["von_mises_stress"]), v.von_mises_stress)
    # VTK measures each deformed cell's volume from its corners: in VTK's order it is the
    # rest cell's times J (a wrong corner order would twist the cells).
    h = v.nodes[v.hexahedra[0, 1], 0] - v.nodes[v.hexahedra[0, 0], 0]
    sizes = grid.compute_cell_sizes(length=False, area=False, volume=True)
    np.testing.assert_allclose(sizes.cell_data["Volume"], v.J * h**3, rtol=0.02)
