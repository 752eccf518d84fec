"""Every refusal is fibfluid.Error (a ValueError) with the command line's message; never a
panic."""

import numpy as np
import pytest

import fibfluid
from conftest import SCENES, run_cli

SCENE = SCENES / "bunny-pull.toml"


@pytest.fixture
def scene():
    return fibfluid.Scene.load(SCENE)


def test_error_is_a_value_error():
    assert issubclass(fibfluid.Error, ValueError)
    assert fibfluid.Error.__module__ == "fibfluid"


def test_a_nan_vertex_raises(scene):
    v = scene.vertices
    v[5, 1] = np.nan
    with pytest.raises(fibfluid.Error, match="vertex 5 has a non-finite coordinate"):
        scene.with_mesh(v, scene.faces)
    with pytest.raises(ValueError):
        scene.with_mesh(v, scene.faces)


@pytest.mark.parametrize(
    "vertices, faces, message",
    [
        (lambda s: s.vertices[:, :2], lambda s: s.faces, r"vertices must be an array of shape \(N, 3\)"),
        (lambda s: s.vertices.ravel(), lambda s: s.faces, r"vertices must be an array of shape \(N, 3\)"),
        (lambda s: s.vertices, lambda s: s.faces[:, :2], r"faces must be an array of shape \(F, 3\)"),
        (lambda s: s.vertices, lambda s: s.faces.astype(float), "faces must be an integer array"),
        (lambda s: s.vertices, lambda s: s.faces - 1, "face 0 refers to vertex -1"),
        (lambda s: s.vertices, lambda s: s.faces + 10**6, "refers to vertex"),
        (lambda s: s.vertices[:0], lambda s: s.faces[:0], "the mesh is empty"),
        (lambda s: s.vertices, lambda s: s.faces[1:], "the surface is open"),
        (lambda s: "not an array", lambda s: s.faces, "vertices must be"),
        (lambda s: s.vertices, lambda s: [[0, 1]], "faces must be"),
    ],
)
def test_a_bad_mesh_raises(scene, vertices, faces, message):
    with pytest.raises(fibfluid.Error, match=message):
        scene.with_mesh(vertices(scene), faces(scene))


def test_views_and_other_dtypes_are_read(scene):
    # A Fortran-ordered float32 copy and int32 faces describe the same mesh.
    v = np.asfortranarray(scene.vertices.astype(np.float32))
    again = scene.with_mesh(v, scene.faces.astype(np.int32))
    assert again.n_vertices == scene.n_vertices


def test_an_unknown_method_raises(scene):
    with pytest.raises(fibfluid.Error, match="unknown method `gibson`"):
        fibfluid.run(scene, method="gibson")
    with pytest.raises(fibfluid.Error, match="`gibson` is not a method"):
        fibfluid.Body(scene, method="gibson")
    # The finite-element method needs the tissue, which this scene does not give.
    with pytest.raises(fibfluid.Error, match=r"needs a \[tissue\] section"):
        fibfluid.run(scene, method="fem")
    # The finite-element body needs the tissue, which this scene does not give.
    with pytest.raises(fibfluid.Error, match=r"needs a \[tissue\] section"):
        fibfluid.Body(scene, method="fem")
    with pytest.raises(fibfluid.Error, match="interactive only"):
        fibfluid.run(scene, method="tsve-chainmail")


@pytest.mark.parametrize(
    "name, value, message",
    [
        ("steps", 0, "steps: must be between 1 and 1000000, got 0"),
        ("steps", 2.5, "steps: must be an integer"),
        ("steps", True, "steps: must be an integer"),
        ("fiber_modulus", -1.0, "fiber_modulus: must be positive"),
        ("fiber_modulus", [1.0, 2.0], "fiber_modulus"),
        ("young", -1.0, "fiber_modulus: must be positive"),
        ("surface_tension", float("nan"), "surface_tension: must be >= 0"),
        ("density", "heavy", "density: expected a number, got str"),
        ("tolerance", 1.5, "tolerance: must be between 0 and 1"),
        ("gravity", [0.0, -9.81], r"gravity must be three finite numbers"),
        ("gravity", [0.0, float("inf"), 0.0], r"gravity must be three finite numbers"),
        ("backend", "cholesky", "backend: `cholesky` is not a backend"),
        ("mode", "fast", "mode: `fast` is not a mode"),
        ("stepping", 3, "stepping: expected a string"),
        ("precision", "f16", "precision: `f16` is not a precision"),
        ("penalty", 0.0, "penalty: must be positive"),
        ("fibers", "springs", "fibers: `springs` is not a"),
        ("kernel_exponent", 7.0, r"kernel_exponent: must be in \[0.5, 6\]"),
    ],
)
def test_a_bad_setting_raises_and_changes_nothing(scene, name, value, message):
    before = scene.settings
    with pytest.raises(fibfluid.Error, match=message):
        setattr(scene, name, value)
    with pytest.raises(fibfluid.Error, match=message):
        scene.settings = {"steps": 7, name: value}
    assert scene.settings == before


def test_an_unknown_setting_raises(scene):
    with pytest.raises(fibfluid.Error, match="unknown setting `step`"):
        scene.step = 5
    with pytest.raises(fibfluid.Error, match="unknown setting `youngs`"):
        scene.settings = {"youngs": 5.0}
    with pytest.raises(fibfluid.Error, match="unknown solver setting `steps`"):
        scene.solver = {"steps": 5}
    with pytest.raises(fibfluid.Error, match="read only"):
        scene.vertices = np.zeros((3, 3))
    with pytest.raises(AttributeError):
        scene.no_such_thing  # noqa: B018 (reading an unknown name is an AttributeError, as usual)


def test_settings_are_read_and_written(scene):
    scene.steps = 7
    scene.solver = {"mode": "paper", "constraints": "penalty"}
    scene.fiber_modulus = [1000.0, 2000.0, 3000.0]
    scene.gravity = (0, -9.81, 0)
    scene.tolerance = 0.01
    s = scene.settings
    assert s["steps"] == 7 and scene.steps == 7
    assert scene.solver["mode"] == "paper" and scene.constraints == "penalty"
    assert s["fiber_modulus"] == (1000.0, 2000.0, 3000.0)
    assert "young" not in s and scene.young == scene.fiber_modulus
    scene.young = 4000.0  # the older name writes the same setting
    assert scene.fiber_modulus == 4000.0
    assert s["gravity"] == (0.0, -9.81, 0.0)
    assert s["tolerance"] == 0.01
    scene.tolerance = None
    assert scene.tolerance is None
    assert (scene.fibers, scene.kernel_exponent) == ("paper", 1.0)
    scene.fibers = "projected"
    scene.kernel_exponent = 3
    assert scene.settings["fibers"] == "projected" and scene.settings["kernel_exponent"] == 3.0


def test_a_missing_scene_file_raises():
    with pytest.raises(fibfluid.Error, match="no-such-scene.toml"):
        fibfluid.Scene.load("no-such-scene.toml")


def test_the_message_is_the_command_lines(cli, tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(SCENE.read_text().replace("steps = 5", "steps = 0").replace("../meshes/", str(SCENES.parent / "meshes") + "/"))
    done = run_cli(cli, "run", str(bad), "--out", str(tmp_path / "out"))
    assert done.returncode != 0
    line = [l for l in done.stderr.splitlines() if l.startswith("error: ")][0]
    with pytest.raises(fibfluid.Error) as e:
        fibfluid.Scene.load(bad)
    assert "error: " + str(e.value) == line


def test_a_body_refuses_what_the_probe_refuses(scene):
    body = fibfluid.Body(scene, method="tsve-chainmail")
    with pytest.raises(fibfluid.Error, match="does not support forces"):
        body.push(177, [0.0, 1.0, 0.0])
    with pytest.raises(fibfluid.Error, match="vertex 5000 is out of range"):
        body.grab(5000, [0.0, 0.01, 0.0])
    with pytest.raises(fibfluid.Error, match="vertex -1 is out of range"):
        body.release(-1)
    with pytest.raises(fibfluid.Error, match="three finite numbers"):
        body.grab(177, [0.0, float("nan"), 0.0])
    with pytest.raises(fibfluid.Error, match="three finite numbers"):
        body.grab(177, [0.0, 1.0])
    fixed = int(scene.fixed_vertices[0])
    with pytest.raises(fibfluid.Error, match=f"vertex {fixed} is fixed"):
        body.grab(fixed, [0.0, 0.01, 0.0])


def test_a_polygon_scene_has_no_body():
    with pytest.raises(fibfluid.Error, match="2D polygon"):
        fibfluid.Body(fibfluid.Scene.load(SCENES / "rectangle.toml"))


def test_integers_out_of_every_range_are_fibfluid_errors():
    """Vertex numbers beyond 64 bits and a negative memory limit are refusals
    (fibfluid.Error), not OverflowError; vertex -1 and N stay refusals too."""
    scene = fibfluid.Scene.load(SCENES / "sphere.toml")
    body = fibfluid.Body(scene)
    n = scene.n_vertices
    cases = [
        lambda: body.grab(2**70, [0.0, 0.0, 0.0]),
        lambda: body.grasp(np.uint64(2**64 - 1), 0.1, [0.0, 0.0, 0.0]),
        lambda: body.release(-(2**63) - 1),
        lambda: body.grab(-1, [0.0, 0.0, 0.0]),
        lambda: body.grab(n, [0.0, 0.0, 0.0]),
        lambda: fibfluid.run(scene, max_memory=-1),
        lambda: fibfluid.run(scene, max_memory=2**64),
        lambda: fibfluid.Body(scene, max_memory=-1),
    ]
    for case in cases:
        with pytest.raises(fibfluid.Error):
            case()
