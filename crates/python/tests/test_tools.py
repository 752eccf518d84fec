"""Tools with a size from Python: a grasp moves its patch rigidly, a tip presses without
letting any vertex inside, and bad tools are errors. The references are the definitions
(the rigid motion of the rest positions; the tip's sphere), not the code's own output."""

import numpy as np
import pytest

import fibfluid
from conftest import SCENES

SCENE = SCENES / "bunny-pull.toml"
V = 177  # the pulled ear's tip, free


@pytest.fixture(scope="module")
def body():
    return fibfluid.Body(fibfluid.Scene.load(SCENE), method="ffm")


def test_a_grasp_moves_its_patch_rigidly(body):
    body.release_all()
    rest = body.rest_positions
    radius = 0.25 * np.linalg.norm(rest.max(axis=0) - rest.min(axis=0)) / 10
    to = np.array([0.002, 0.004, -0.001])
    angle = np.array([0.0, 0.0, 0.1])
    body.grasp(V, radius, to, rotation=angle)
    positions, reactions = body.step()
    patch = np.nonzero(np.linalg.norm(rest - rest[V], axis=1) <= radius)[0]
    assert len(patch) >= 3 and len(reactions) == len(patch)
    c, s = np.cos(0.1), np.sin(0.1)
    rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    # Turned about the patch's rest centroid, as a scene's [[grasp]] turns its patch.
    centroid = rest[patch].mean(axis=0)
    expected = centroid + to + (rest[patch] - centroid) @ rz.T
    np.testing.assert_allclose(positions[patch], expected, rtol=0, atol=1e-9)
    (tool,) = body.tools()
    assert tool["grasp"] == V and tool["vertices"] == len(patch)
    np.testing.assert_allclose(tool["force"], reactions[:, 1:].sum(axis=0), rtol=1e-12, atol=1e-12)
    body.release(V)
    _, none = body.step()
    assert none.shape == (0, 4) and body.tools() == []


def test_a_tip_leaves_no_vertex_inside_and_pushes_harder_deeper(body):
    body.release_all()
    positions, _ = body.step()
    rest = body.rest_positions
    radius = 0.05 * np.linalg.norm(rest.max(axis=0) - rest.min(axis=0))
    normal = positions[V] - positions.mean(axis=0)
    normal /= np.linalg.norm(normal)
    pushes = []
    for depth in (0.2, 0.4, 0.6):
        centre = positions[V] + normal * (radius - depth * radius)
        body.press(centre, radius)
        p, _ = body.step()
        assert np.linalg.norm(p - centre, axis=1).min() >= radius * (1 - 1e-9)
        (tool,) = body.tools()
        assert tool["contacts"] >= 1
        pushes.append(-np.dot(tool["force"], normal))
    assert pushes[0] > 0 and pushes[1] >= pushes[0] and pushes[2] >= pushes[1], pushes
    body.lift()
    body.step()
    assert body.tools() == []


@pytest.mark.parametrize("radius", [0.0, -1.0, float("nan"), "a"])
def test_bad_radii_are_errors(body, radius):
    with pytest.raises(fibfluid.Error, match="radius"):
        body.grasp(V, radius, [0, 0, 0])
    with pytest.raises(fibfluid.Error, match="radius"):
        body.press([0, 0, 0], radius)


def test_a_tool_larger_than_the_body_is_an_error(body):
    with pytest.raises(fibfluid.Error, match="larger than the body"):
        body.grasp(V, 1e6, [0, 0, 0])
