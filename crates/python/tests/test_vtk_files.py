"""The command line's XML VTK files read back by independent readers: volume.vtu by meshio,
deformed.vtp by VTK's own XML reader (meshio reads no PolyData) and, always, by the
standard library's XML parser. A test whose reader is not installed is skipped
(`pip install meshio vtk` to run them all)."""

import importlib.util
import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from conftest import SPHERE_FEM_CM, SPHERE_MESH, read_obj_vertices, run_cli


def needs(module: str):
    """Skips a test, before its fixtures run, when `module` is not installed."""
    return pytest.mark.skipif(importlib.util.find_spec(module) is None, reason=f"{module} is not installed")


@pytest.fixture(scope="module")
def fem_run(cli, tmp_path_factory):
    """`fibfluid run` of conftest's `SPHERE_FEM_CM`: its output directory and report.json."""
    tmp = tmp_path_factory.mktemp("vtk")
    scene = tmp / "sphere-fem.toml"
    scene.write_text(SPHERE_FEM_CM.format(mesh=SPHERE_MESH.as_posix()))
    out = tmp / "out"
    done = run_cli(cli, "run", str(scene), "--out", str(out))
    assert done.returncode == 0, done.stderr
    return out, json.loads((out / "report.json").read_text())


def check_surface(out, points, triangles, displacement, magnitude):
    """The surface read back: deformed.obj's points (every digit), 320 triangles over the
    162 points, the displacement from the input mesh and its magnitude."""
    obj = np.array(read_obj_vertices(out / "deformed.obj"))
    assert points.shape == obj.shape == (162, 3)
    np.testing.assert_array_equal(points, obj)
    assert triangles.shape == (320, 3)
    assert triangles.min() == 0 and triangles.max() == 161
    assert displacement.shape == (162, 3)
    rest = np.array(read_obj_vertices(SPHERE_MESH))
    np.testing.assert_allclose(displacement, obj - rest, rtol=0, atol=1e-12)
    np.testing.assert_allclose(magnitude, np.linalg.norm(displacement, axis=1), rtol=1e-14, atol=0)
    assert np.abs(displacement).max() > 0


def test_deformed_vtp_is_xml_with_the_surface_and_the_displacement(fem_run):
    out, _ = fem_run
    root = ET.parse(out / "deformed.vtp").getroot()
    assert root.tag == "VTKFile" and root.get("type") == "PolyData"
    piece = root.find("PolyData/Piece")
    assert (piece.get("NumberOfPoints"), piece.get("NumberOfPolys")) == ("162", "320")

    def array(path, name):
        (found,) = [a for a in piece.findall(f"{path}/DataArray") if a.get("Name") == name]
        return np.array(found.text.split(), dtype=float)

    connectivity = array("Polys", "connectivity").astype(int)
    np.testing.assert_array_equal(array("Polys", "offsets"), np.arange(3, 961, 3))
    check_surface(
        out,
        array("Points", "Points").reshape(-1, 3),
        connectivity.reshape(-1, 3),
        array("PointData", "displacement").reshape(-1, 3),
        array("PointData", "displacement_magnitude"),
    )


@needs("vtk")
def test_deformed_vtp_read_by_vtk(fem_run):
    import vtk
    from vtk.util.numpy_support import vtk_to_numpy

    out, _ = fem_run
    reader = vtk.vtkXMLPolyDataReader()
    reader.SetFileName(str(out / "deformed.vtp"))
    reader.Update()
    surface = reader.GetOutput()
    assert (surface.GetNumberOfPoints(), surface.GetNumberOfPolys()) == (162, 320)
    polys = vtk_to_numpy(surface.GetPolys().GetConnectivityArray())
    point_data = surface.GetPointData()
    names = {point_data.GetArrayName(i) for i in range(point_data.GetNumberOfArrays())}
    assert names == {"displacement", "displacement_magnitude"}
    check_surface(
        out,
        vtk_to_numpy(surface.GetPoints().GetData()),
        polys.reshape(-1, 3),
        vtk_to_numpy(point_data.GetArray("displacement")),
        vtk_to_numpy(point_data.GetArray("displacement_magnitude")),
    )


@needs("meshio")
def test_volume_vtu_read_by_meshio(fem_run):
    import meshio

    out, report = fem_run
    volume = meshio.read(out / "volume.vtu")
    cells, nodes = report["fem"]["cells"], report["fem"]["nodes"]
    assert cells > 0 and nodes > 0
    assert [c.type for c in volume.cells] == ["hexahedron"]
    hexes = volume.cells_dict["hexahedron"]
    assert hexes.shape == (cells, 8)
    assert len(volume.points) == nodes
    assert hexes.max() < nodes
    assert set(volume.point_data) == {"displacement"}
    assert volume.point_data["displacement"].shape == (nodes, 3)
    fields = {"J", "max_principal_strain", "von_mises_stress", "fill", "material_id"}
    assert set(volume.cell_data) == fields
    for name in fields:
        (values,) = volume.cell_data[name]
        assert len(values) == cells, name
    (j,) = volume.cell_data["J"]
    assert np.all(j > 0)
