"""From a segmentation to a simulation in Python: `Scene.from_labels` and the FEM batch run."""

import json

import numpy as np
import pytest

import fibfluid
from conftest import SCENES, read_obj_vertices, run_cli

FAT = {"young": 3250.0, "poisson": 0.45, "density": 930.0}
LESION = {"young": 22000.0, "poisson": 0.45, "density": 1000.0}
H = 0.002  # voxel size, m


def phantom() -> np.ndarray:
    """A ball of fat (radius 8 voxels) with a ball of lesion (radius 3) inside, 24^3 voxels."""
    i, j, k = np.indices((24, 24, 24)) - 11.5
    r = np.sqrt(i * i + j * j + k * k)
    labels = np.where(r < 8, 1, 0).astype(np.uint8)
    labels[r < 3] = 2
    return labels


def test_a_label_volume_becomes_a_body_with_a_region_and_runs_with_the_fem(tmp_path):
    labels = phantom()
    scene = fibfluid.Scene.from_labels(
        labels, [H, H, H], {1: FAT, 2: LESION}, fix={"axis": "y", "above": 0.037, "dofs": ["x", "y", "z"]},
        gravity=[0.0, -9.81, 0.0], directory=tmp_path,
    )
    result = fibfluid.run(scene)
    report = result.report
    # The body's surface encloses the labels' voxels (marching tetrahedra at full
    # resolution, within 3 %); the lesion is a region with cells of its own.
    voxels = float(np.count_nonzero(labels)) * H ** 3
    assert abs(report["volume_initial"] / voxels - 1.0) < 0.03, (report["volume_initial"], voxels)
    (region,) = report["regions"]
    assert region["name"] == "label 2" and region["cells"] > 0
    assert region["tissue"]["young"] == LESION["young"]
    assert report["tissue"]["model"] == "neo-hookean"
    # Hanging from its top under gravity: everything moves down, and nothing far.
    assert result.displacement[:, 1].mean() < 0.0
    assert np.abs(result.displacement).max() < 0.016
    assert result.pressure == 0.0


def test_bad_label_volumes_raise():
    with pytest.raises(fibfluid.Error, match="3-D integer array"):
        fibfluid.Scene.from_labels(np.zeros((4, 4)), [H, H, H], {})
    with pytest.raises(fibfluid.Error, match="label 2 has no tissue"):
        fibfluid.Scene.from_labels(phantom(), [H, H, H], {1: FAT})
    with pytest.raises(fibfluid.Error, match="spacing"):
        fibfluid.Scene.from_labels(phantom(), [H, 0.0, H], {1: FAT, 2: LESION})
    with pytest.raises(fibfluid.Error, match="no body"):
        fibfluid.Scene.from_labels(np.zeros((4, 4, 4), dtype=int), [H, H, H], {})


def test_labels_a_label_image_cannot_hold_are_refused_naming_the_argument():
    # A label over 2^32 - 1 (the image's 32-bit labels) would wrap to another label.
    big = np.zeros((4, 4, 4), dtype=np.uint64)
    big[1:3, 1:3, 1:3] = 2**32 + 1
    with pytest.raises(fibfluid.Error, match=r"^labels: label 4294967297 is over 4294967295"):
        fibfluid.Scene.from_labels(big, [H, H, H], {2**32 + 1: FAT})
    # A side over 32767 voxels does not fit NIfTI-1's 16-bit dimensions.
    long = np.zeros((32768, 1, 1), dtype=np.uint8)
    long[0, 0, 0] = 1
    with pytest.raises(fibfluid.Error, match=r"^labels: .*side over 32767 voxels"):
        fibfluid.Scene.from_labels(long, [H, H, H], {1: FAT})


def test_the_fem_batch_run_equals_the_command_lines(cli, tmp_path):
    """`fibfluid.run(scene, method="fem")` gives `fibfluid run --method fem`'s deformed.obj
    (sphere-tissue: the unit icosphere read in cm)."""
    scene_path = SCENES / "sphere-tissue.toml"
    out = tmp_path / "out"
    done = run_cli(cli, "run", str(scene_path), "--method", "fem", "--out", str(out))
    assert done.returncode == 0, done.stderr
    result = fibfluid.run(fibfluid.Scene.load(scene_path), method="fem")
    # The package's arrays are in metres; deformed.obj is in the mesh's unit (cm here),
    # converted as the command line does it.
    in_cm = result.positions * (1.0 / 0.01)
    assert np.array_equal(in_cm, np.array(read_obj_vertices(out / "deformed.obj")))
    cli_report = json.loads((out / "report.json").read_text())
    assert result.report["fem"]["cells"] == cli_report["fem"]["cells"]


def test_a_result_converts_to_meshio_and_pyvista_without_copying_the_points():
    result = fibfluid.run(fibfluid.Scene.load(SCENES / "sphere.toml"))
    assert result.faces is not None and result.faces.shape[1] == 3
    meshio = pytest.importorskip("meshio")
    mesh = result.to_meshio()
    assert isinstance(mesh, meshio.Mesh)
    assert np.shares_memory(mesh.points, result.positions)
    assert np.array_equal(mesh.cells_dict["triangle"], result.faces)
    assert np.array_equal(mesh.point_data["displacement"], result.displacement)


def test_a_result_converts_to_pyvista():
    result = fibfluid.run(fibfluid.Scene.load(SCENES / "sphere.toml"))
    pytest.importorskip("pyvista")
    mesh = result.to_pyvista()
    assert mesh.n_points == result.positions.shape[0] and mesh.n_cells == result.faces.shape[0]
    assert np.allclose(mesh.point_data["displacement_magnitude"], np.linalg.norm(result.displacement, axis=1))
