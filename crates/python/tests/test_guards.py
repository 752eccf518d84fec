"""The result guards on a Body's frames: a pull far past the body's size warns, a small
one does not, and each guard is issued as a GuardWarning once per body."""

import time
import warnings

import numpy as np
import pytest

import fibfluid
from conftest import SCENES

SCENE = SCENES / "bunny-pull.toml"
V = 177  # the pulled ear's tip, free


@pytest.fixture(scope="module")
def scene():
    return fibfluid.Scene.load(SCENE)


def size_of(body):
    """The body's size as the guards measure it: the rest bounding-box diagonal."""
    rest = body.rest_positions
    return float(np.linalg.norm(rest.max(axis=0) - rest.min(axis=0)))


def step_recording(body):
    """One step; the GuardWarnings it issued (every warning recorded, none filtered)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        body.step()
    return [w for w in caught if issubclass(w.category, fibfluid.GuardWarning)]


def test_a_far_pull_warns_and_a_small_one_does_not(scene):
    body = fibfluid.Body(scene, method="ffm")
    size = size_of(body)

    body.grab(V, [0.0, 0.01 * size, 0.0])
    assert step_recording(body) == []
    assert body.warnings == []

    # Five times the body's size.
    body.grab(V, [0.0, 5.0 * size, 0.0])
    issued = step_recording(body)
    moved = float(np.linalg.norm(body.displacement, axis=1).max()) / size
    assert moved > 1.0
    assert [str(w.message) for w in issued if "`displacement`" in str(w.message)], issued
    assert all(issubclass(w.category, RuntimeWarning) for w in issued)
    (line,) = [w for w in body.warnings if "`displacement`" in w]
    # The message states the measured ratio, as Rust's `{:.3e}` writes it (`5.123e0`).
    mantissa, exponent = f"{moved:.3e}".split("e")
    assert f"{mantissa}e{int(exponent)}" in line, (line, moved)

    # Issued once per guard and body; the list still says it fired.
    assert step_recording(body) == []
    assert any("`displacement`" in w for w in body.warnings)

    # The list is the last frame's: a small pull again clears it.
    body.grab(V, [0.0, 0.01 * size, 0.0])
    step_recording(body)
    assert body.warnings == []


def test_a_new_body_warns_again(scene):
    body = fibfluid.Body(scene, method="ffm")
    body.grab(V, [0.0, 5.0 * size_of(body), 0.0])
    issued = step_recording(body)
    assert any("`displacement`" in str(w.message) for w in issued), issued


def test_only_the_finite_element_body_warns_past_the_small_strain_limit():
    scene = fibfluid.Scene.load(SCENES / "sphere-tissue.toml")  # radius 1 cm, E = 5 kPa
    bottom = 3  # y = -0.85 cm, free (the cap y > 0.8 cm is fixed)
    for method, linear in (("fem", True), ("ffm", False)):
        body = fibfluid.Body(scene, method=method)
        size = size_of(body)
        body.grab(bottom, [0.0, -0.05 * size, 0.0])
        body.step()
        assert body.warnings == [], (method, body.warnings)
        # 0.2 of the body's size: past the small-strain limit (0.1), within its size.
        body.grab(bottom, [0.12 * size, -0.16 * size, 0.0])
        issued = step_recording(body)
        moved = float(np.linalg.norm(body.displacement, axis=1).max()) / size
        assert 0.1 < moved < 1.0, (method, moved)
        fired = [w for w in body.warnings if "`linear`" in w]
        assert bool(fired) == linear, (method, body.warnings)
        assert bool([w for w in issued if "`linear`" in str(w.message)]) == linear


def test_a_finite_element_body_of_a_neo_hookean_scene_runs_at_two_rates(tmp_path):
    text = (SCENES / "sphere-tissue.toml").read_text()
    text = text.replace('path = "../meshes/', f'path = "{SCENES.parent / "meshes"}/')
    text = text.replace("[tissue]\n", '[tissue]\nmodel = "neo-hookean"\n')
    path = tmp_path / "sphere-neo-hookean.toml"
    path.write_text(text)
    scene = fibfluid.Scene.load(path)
    # The body is hyperelastic now: nothing to warn about.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        body = fibfluid.Body(scene, method="fem")
        assert fibfluid.Body(scene, method="ffm").linearization is None
    rest = body.rest_positions
    v = int(np.argmin(rest[:, 1]))
    size = float(np.linalg.norm(rest.max(axis=0) - rest.min(axis=0)))
    # 0.15 of the body's size: past the small-strain limit that the linear FEM body warns
    # of (the test above), which a neo-Hookean body does not have.
    body.grab(v, [0.0, -0.15 * size, 0.0])
    body.step()
    assert not [w for w in body.warnings if "`linear`" in w], body.warnings
    first = body.linearization
    assert first["failure"] is None and first["age_frames"] >= 0, first
    # Holding still, step until a refresh has come in and the estimated error is below
    # 1e-9 of the body's size (a step every 5 ms: stepping never waits for the refresh
    # thread). A liveness bound, not a speed claim: a refresh is seconds on a loaded 2-core
    # machine, so it waits up to 5 minutes.
    deadline = time.monotonic() + 300.0
    while time.monotonic() < deadline:
        body.step()
        lin = body.linearization
        if lin["refreshes"] >= 1 and lin["estimated_error"] < 1e-9 * size:
            break
        time.sleep(0.005)
    else:
        raise AssertionError(f"no converged refresh: {body.linearization}")
    held = body.positions[v] - rest[v]
    assert np.allclose(held, [0.0, -0.15 * size, 0.0], atol=1e-9 * size), held
    # Convergence is told by a refresh that factored the tangent (chord refreshes, which
    # keep it, count only among the refreshes).
    assert 1 <= lin["refactorizations"] <= lin["refreshes"], lin
    # Refreshes that fail (on purpose): every step still answers, the grab is met, and the
    # linearization names the failure; then the refreshes recover and converge.
    body._fail_next_refreshes(3)
    body.grab(v, [0.0, -0.2 * size, 0.0])
    failures = []
    deadline = time.monotonic() + 300.0
    while time.monotonic() < deadline:
        body.step()
        lin = body.linearization
        if lin["failure"] is not None:
            failures.append(lin["failure"])
            assert np.allclose(body.positions[v] - rest[v], [0.0, -0.2 * size, 0.0], atol=1e-9 * size)
        elif failures and lin["estimated_error"] < 1e-9 * size:
            break
        time.sleep(0.005)
    else:
        raise AssertionError(f"no recovery after the failed refreshes: {body.linearization}")
    assert failures and "failed" in failures[0], failures
    with pytest.raises(fibfluid.Error, match="refreshes"):
        fibfluid.Body(scene, method="ffm")._fail_next_refreshes(1)
    # Released, the body is back at its own equilibrium at once.
    body.release_all()
    body.step()
    assert body.linearization["estimated_error"] < 1e-15 * size
