"""Interactive bodies: grabs go exactly where asked, reactions, release."""

import numpy as np
import pytest

import fibfluid
from conftest import SCENES

SCENE = SCENES / "bunny-pull.toml"
V = 177  # the pulled ear's tip, free


@pytest.fixture(scope="module")
def scene():
    return fibfluid.Scene.load(SCENE)


@pytest.fixture(scope="module")
def ffm(scene):
    return fibfluid.Body(scene, method="ffm")


def test_a_grab_moves_the_vertex_exactly_where_asked(ffm):
    ffm.release_all()
    to = np.array([0.002, 0.01, -0.003])
    ffm.grab(V, to)
    positions, reactions = ffm.step()
    assert positions.shape == (ffm.n_vertices, 3) and positions.dtype == np.float64
    np.testing.assert_allclose(positions[V], ffm.rest_positions[V] + to, rtol=0, atol=1e-12)
    np.testing.assert_allclose(ffm.displacement[V], to, rtol=0, atol=1e-12)
    # One reaction row: the vertex, then a finite, non-zero force.
    assert reactions.shape == (1, 4)
    assert reactions[0, 0] == V
    assert np.all(np.isfinite(reactions[0, 1:]))
    assert np.linalg.norm(reactions[0, 1:]) > 1e-6


def test_release_returns_to_the_base_state(ffm):
    ffm.release_all()
    base, none = ffm.step()
    assert none.shape == (0, 4)
    ffm.grab(V, [0.0, 0.02, 0.0])
    grabbed, _ = ffm.step()
    assert np.abs(grabbed - base).max() > 1e-3
    ffm.release(V)
    released, reactions = ffm.step()
    assert reactions.shape == (0, 4)
    np.testing.assert_allclose(released, base, rtol=0, atol=1e-12)


def test_the_base_state_is_the_scenes_loads_solved_once(scene, ffm):
    # Paper mode, one step (the probe's linearization): the base is that run's surface.
    linear = scene.copy()
    linear.update(mode="paper", steps=1, backend="structured", precision="f64")
    ffm.release_all()
    base, _ = ffm.step()
    np.testing.assert_allclose(base, fibfluid.run(linear).positions, rtol=0, atol=1e-9)


def test_a_push_is_answered_as_a_force(ffm):
    ffm.release_all()
    base, _ = ffm.step()
    ffm.push(V, [0.0, 50.0, 0.0])
    pushed, reactions = ffm.step()
    assert pushed[V, 1] > base[V, 1]
    np.testing.assert_array_equal(reactions, [[V, 0.0, 50.0, 0.0]])
    ffm.release_all()


@pytest.mark.parametrize("method", ["tsve-chainmail", "generalized-chainmail"])
def test_chainmail_grabs_exactly_and_has_no_forces(scene, method):
    body = fibfluid.Body(scene, method=method)
    assert body.method == method and not body.supports_forces
    rest = body.rest_positions
    body.grab(V, [0.0, 0.01, 0.0])
    positions, reactions = body.step()
    np.testing.assert_allclose(positions[V], rest[V] + [0.0, 0.01, 0.0], rtol=0, atol=1e-12)
    assert reactions.shape == (0, 4)
    # Neighbours follow: the lattice moved more than the one vertex.
    assert np.count_nonzero(np.abs(positions - rest).max(axis=1) > 1e-9) > 1
    body.release_all()
    positions, _ = body.step()
    assert np.abs(positions[V] - rest[V]).max() < 0.01


def test_the_default_method_is_the_scenes(tmp_path):
    """Without ``method`` a body takes the scene's ``[solver] method``, as ``run`` does."""
    text = (SCENES / "sphere-tissue.toml").read_text()
    assert fibfluid.Body(fibfluid.Scene.load(SCENES / "sphere-tissue.toml")).method == "ffm"
    fem = tmp_path / "sphere-fem.toml"
    fem.write_text(text.replace("../meshes/", str(SCENES.parent / "meshes") + "/") + 'method = "fem"\n')
    assert fibfluid.Body(fibfluid.Scene.load(fem)).method == "fem"
    assert fibfluid.Body(fibfluid.Scene.load(fem), method="ffm").method == "ffm"
