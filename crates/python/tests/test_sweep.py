"""fibfluid.sweep: runs in order on a thread pool and on the default process pool, the
same answers either way; a linear body's sag scales as 1/E."""

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import fibfluid
from conftest import SPHERE_FEM_CM, SPHERE_MESH


@pytest.fixture()
def scene_path(tmp_path):
    path = tmp_path / "sphere.toml"
    path.write_text(SPHERE_FEM_CM.format(mesh=SPHERE_MESH.as_posix()))
    return str(path)


PARAMETERS = [{"tissue.young": 5000.0}, {"tissue.young": 10000.0}]


def test_sweep_on_a_thread_pool_and_the_default_processes(scene_path):
    with ThreadPoolExecutor(2) as pool:
        threads = fibfluid.sweep(scene_path, PARAMETERS, executor=pool)
    processes = fibfluid.sweep(scene_path, PARAMETERS)
    assert [r.report["tissue"]["young"] for r in threads] == [5000.0, 10000.0]
    for a, b in zip(threads, processes):
        np.testing.assert_array_equal(a.displacement, b.displacement)
    # Linear elasticity: doubling E halves every displacement.
    u = [np.abs(r.displacement).max() for r in threads]
    assert u[0] / u[1] == pytest.approx(2.0, rel=1e-6)
    # The scene run as it is, as a list of one path twice.
    same = fibfluid.sweep([scene_path, scene_path])
    np.testing.assert_array_equal(same[0].displacement, threads[0].displacement)
    np.testing.assert_array_equal(same[1].displacement, same[0].displacement)


def test_sweep_checks_every_parameter_before_running(scene_path):
    with pytest.raises(fibfluid.Error, match="tissue.yung"):
        fibfluid.sweep(scene_path, [{"tissue.young": 5000.0}, {"tissue.yung": 1.0}])
    with pytest.raises(fibfluid.Error, match="one scene"):
        fibfluid.sweep([scene_path], [{"tissue.young": 5000.0}])


def test_sweep_on_a_dask_local_cluster(scene_path):
    """Two worker processes of one thread each: the same answers as serial runs, in order."""
    pytest.importorskip("dask")
    distributed = pytest.importorskip("distributed")
    many = [{"tissue.young": e} for e in (4000.0, 5000.0, 8000.0, 10000.0)]
    serial = [fibfluid.run(fibfluid.Scene.load(scene_path).set_parameter("tissue.young", p["tissue.young"]))
              for p in many]
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with distributed.Client(cluster) as client:
            results = fibfluid.sweep(scene_path, many, executor=client)
    assert [r.report["tissue"]["young"] for r in results] == [p["tissue.young"] for p in many]
    for a, b in zip(results, serial):
        np.testing.assert_array_equal(a.positions, b.positions)
        np.testing.assert_array_equal(a.displacement, b.displacement)
