"""fibfluid.sensitivity and fibfluid.fit on a column with a stiff lower half sagging under
its own weight (the command line's fit test's body): the sensitivities against central
differences of two forward runs, the moduli of a synthetic truth recovered, a parameter the
observations cannot see reported as such, and bad input refused in one line."""

import numpy as np
import pytest

import fibfluid
from conftest import SCENES

#: The body's tissue and region moduli (Pa) of the synthetic truth.
TRUTH = (3000.0, 15000.0)
KEYS = ["tissue.young", "region.lesion.young"]
BOUNDS = [[300.0, 3.0e5], [300.0, 3.0e6]]


def box_obj(n, s):
    """The surface of the box [0, n_x s] x [0, n_y s] x [0, n_z s] as OBJ text (two outward
    triangles per square of side s), numbered as the command line's test numbers it."""
    index, vertices, faces = {}, [], []

    def vid(g):
        if g not in index:
            index[g] = len(index) + 1
            vertices.append("v {} {} {}".format(*(c * s for c in g)))
        return index[g]

    for a in range(3):
        b, c = (a + 1) % 3, (a + 2) % 3
        for side in (0, n[a]):
            for i in range(n[b]):
                for j in range(n[c]):
                    def g(di, dj):
                        p = [0, 0, 0]
                        p[a], p[b], p[c] = side, i + di, j + dj
                        return tuple(p)

                    q = [vid(g(0, 0)), vid(g(1, 0)), vid(g(1, 1)), vid(g(0, 1))]
                    tris = ((0, 1, 2), (0, 2, 3)) if side == n[a] else ((0, 2, 1), (0, 3, 2))
                    for t in tris:
                        faces.append("f {} {} {}".format(*(q[k] for k in t)))
    return "\n".join(vertices + faces) + "\n"


def column_scene(young, forces=None):
    """A 2 x 2 x 3 cm neo-Hookean column on its base, its lower half a stiff region, under
    gravity down and sideways (or, with ``forces``, pressed by that TOML instead)."""
    load = forces or "[gravity]\nacceleration = [3.0, 0.0, -9.3]"
    return f"""[mesh]
path = "column.obj"
[tissue]
model = "neo-hookean"
young = {young[0]}
poisson = 0.4
density = 1000.0
[[region]]
name = "lesion"
box = {{ min = [-1.0, -1.0, -1.0], max = [1.0, 1.0, 0.015] }}
[region.tissue]
young = {young[1]}
poisson = 0.4
density = 1000.0
{load}
[[fix]]
axis = "z"
below = 0.0001
[fem]
resolution = 6
[solver]
method = "fem"
"""


@pytest.fixture()
def column(tmp_path):
    """Writes the column's mesh and returns a function writing a scene of it."""
    (tmp_path / "column.obj").write_text(box_obj((4, 4, 6), 0.005))

    def scene(name, young, forces=None):
        path = tmp_path / f"{name}.toml"
        path.write_text(column_scene(young, forces))
        return fibfluid.Scene.load(path)

    return scene


def observed_rows(scene, positions):
    """30 vertices off the base (file order, evenly strided) and their positions: (30, 4)."""
    off_base = np.flatnonzero(scene.vertices[:, 2] > 0.001)
    chosen = off_base[:: len(off_base) // 30][:30]
    return np.column_stack([chosen, positions[chosen]])


def test_sensitivity_matches_central_differences_of_two_forward_runs(column):
    base = column("base", TRUTH)
    keys = KEYS + ["tissue.poisson", "tissue.density", "gravity"]
    s = fibfluid.sensitivity(base, keys)
    forward = fibfluid.run(base, method="fem")
    scale = np.abs(forward.displacement).max()
    np.testing.assert_allclose(s.positions, forward.positions, rtol=0, atol=1e-8 * scale)
    assert s.values == {KEYS[0]: 3000.0, KEYS[1]: 15000.0, "tissue.poisson": 0.4, "tissue.density": 1000.0,
                        "gravity": pytest.approx(np.hypot(3.0, 9.3))}
    for key in keys:
        h = 1e-3 * s.values[key]
        ends = [fibfluid.run(base.copy().set_parameter(key, s.values[key] + d), method="fem").positions
                for d in (h, -h)]
        central = (ends[0] - ends[1]) / (2 * h)
        d = s.derivatives[key]
        assert d.shape == (base.n_vertices, 3)
        err = np.abs(d - central).max() / np.abs(central).max()
        assert err < 1e-5, (key, err)


def test_fit_recovers_the_moduli_of_a_synthetic_truth(column):
    truth = column("truth", TRUTH)
    rows = observed_rows(truth, fibfluid.run(truth, method="fem").positions)
    start = column("start", (1000.0, 1000.0))
    seen = []
    r = fibfluid.fit(start, rows, KEYS, BOUNDS, progress=seen.append)
    for key, value in zip(KEYS, TRUTH):
        assert r.values[key] == pytest.approx(value, rel=0.01)
        assert r.identifiable[key] and r.sigma[key] is not None
    assert r.start == {KEYS[0]: 1000.0, KEYS[1]: 1000.0}
    assert r.residual_relative < 1e-3 and r.converged
    assert r.correlation.shape == (2, 2) and abs(r.correlation[0, 1]) <= 1.0
    assert r.report["observations"] == 30 and r.newton_solves > r.iterations
    assert [p["iteration"] for p in seen] == list(range(1, r.iterations + 1))
    assert set(seen[-1]["values"]) == set(KEYS)
    # The same observations as a pair of arrays.
    again = fibfluid.fit(start, (rows[:, 0].astype(int), rows[:, 1:]), KEYS, BOUNDS)
    assert again.values == r.values


def test_a_parameter_the_observations_cannot_see_is_not_identifiable(column):
    """Without gravity, pressed by a point force, the density does nothing."""
    top = int(np.flatnonzero(np.all(np.isclose(column("probe", TRUTH).vertices, [0.01, 0.01, 0.03]), axis=1))[0])
    force = f"[[force]]\nvertex = {top}\nvalue = [0.004, 0.002, -0.01]"
    truth = column("truth", TRUTH, force)
    rows = observed_rows(truth, fibfluid.run(truth, method="fem").positions)
    r = fibfluid.fit(column("start", (1000.0, TRUTH[1]), force), rows, ["tissue.young", "tissue.density"],
                     [[300.0, 3.0e5], [100.0, 3000.0]])
    assert r.values["tissue.young"] == pytest.approx(TRUTH[0], rel=0.01)
    assert not r.identifiable["tissue.density"]
    assert r.values["tissue.density"] is None and r.sigma["tissue.density"] is None
    assert np.isnan(r.correlation[0, 1])


def test_an_exception_in_progress_is_raised_when_the_fit_ends(column):
    truth = column("truth", TRUTH)
    rows = observed_rows(truth, fibfluid.run(truth, method="fem").positions)
    calls = []

    def progress(step):
        calls.append(step["iteration"])
        raise RuntimeError("stop")

    with pytest.raises(RuntimeError, match="stop"):
        fibfluid.fit(column("start", (2500.0, 15000.0)), rows, KEYS, BOUNDS, progress=progress)
    assert calls == [1]


def one_line_error(match, f, *args, **kwargs):
    with pytest.raises(fibfluid.Error, match=match) as e:
        f(*args, **kwargs)
    assert "\n" not in str(e.value)


def test_bad_input_is_a_one_line_error(column):
    start = column("start", (1000.0, 1000.0))
    rows = np.column_stack([np.arange(30), start.vertices[:30]])
    fit = fibfluid.fit
    one_line_error(r"observed row 1: vertex 100000 is not a vertex of the mesh",
                   fit, start, np.vstack([rows[:1], [100000, 0, 0, 0]]), KEYS, BOUNDS)
    one_line_error(r"observed row 1: vertex 0 is observed twice", fit, start, rows[[0, 0]], KEYS, BOUNDS)
    one_line_error(r"observed row 0: vertex -1 is not an index", fit, start, [[-1, 0, 0, 0]], KEYS, BOUNDS)
    one_line_error(r"`tissue.stiffness`", fit, start, rows, ["tissue.stiffness"], BOUNDS[:1])
    one_line_error(r"region.tumour.young`: no \[\[region\]\] of that name", fit, start, rows,
                   ["region.tumour.young"], BOUNDS[:1])
    one_line_error(r"fit: bounds: `tissue.young`: the start 1000 lies outside \[2000, 300000\]",
                   fit, start, rows, KEYS, [[2000.0, 3.0e5], BOUNDS[1]])
    one_line_error(r"1 bounds for 2 parameters", fit, start, rows, KEYS, BOUNDS[:1])
    one_line_error(r"bounds must be one \[lower, upper\] pair", fit, start, rows, KEYS, [1.0, 2.0])
    one_line_error(r"observed must be an \(M, 4\) array", fit, start, rows[:, 1:], KEYS, BOUNDS)
    one_line_error(r"3 observed vertices but 2 positions", fit, start, (np.arange(3), rows[:2, 1:]), KEYS, BOUNDS)
    one_line_error(r"whole numbers", fit, start, [[0.5, 0, 0, 0]], KEYS, BOUNDS)
    one_line_error(r"`tissue.young` is named twice", fit, start, rows, KEYS[:1] * 2, BOUNDS)
    one_line_error(r"parameters must be a list of dotted keys", fit, start, rows, "tissue.young", BOUNDS[:1])
    one_line_error(r"`tissue.yung`", fibfluid.sensitivity, start, ["tissue.yung"])
    one_line_error(r"names no parameter", fibfluid.sensitivity, start, [])
    # What the static fit does not cover: plates; a body without a [tissue].
    plates = fibfluid.Scene.load(SCENES / "phantom-compression.toml")
    one_line_error(r"\[\[plate\]\]", fibfluid.sensitivity, plates, ["tissue.young"])
    one_line_error(r"\[\[plate\]\]", fit, plates, rows, ["tissue.young"], [[1.0, 1e9]])
    one_line_error(r"\[tissue\]", fibfluid.sensitivity, SCENES / "sphere.toml", ["gravity"])
