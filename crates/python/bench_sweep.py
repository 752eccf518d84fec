"""Times a sweep of 8 runs (one scene, 8 tissue moduli) three ways: serially in this
process, on `fibfluid.sweep`'s default process pool (its processes' start timed), and on a
local Dask cluster of 2 worker processes of one thread each (started before the clock);
prints each time, its ratio to the serial one, and the machine's load (`os.getloadavg()`),
since other work on the machine slows the parallel runs most. The answers are checked equal.

    python crates/python/bench_sweep.py [SCENE] [--runs 8] [--no-dask]

Needs the package installed (`pip install ./crates/python`), and dask and distributed for
the cluster. The default scene is fixtures/scenes/liver-hanging.toml (the neo-Hookean FEM,
a few seconds a run).
"""

import argparse
import os
import time
import warnings
from pathlib import Path

import numpy as np

import fibfluid

REPO = Path(__file__).resolve().parents[2]


def timed(label, f, serial=None):
    start = time.perf_counter()
    out = f()
    seconds = time.perf_counter() - start
    ratio = "" if serial is None else f"  {seconds / serial:.2f}x serial"
    print(f"{label:<34} {seconds:7.2f} s{ratio}   load {os.getloadavg()[0]:.2f}", flush=True)
    return seconds, out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", nargs="?", default=str(REPO / "fixtures/scenes/liver-hanging.toml"))
    ap.add_argument("--runs", type=int, default=8)
    ap.add_argument("--no-dask", action="store_true", help="skip the Dask cluster")
    args = ap.parse_args()
    warnings.simplefilter("ignore")  # the scene's ineffective settings, once per run
    fibfluid.Scene.load(args.scene)  # a bad path fails here, before any timing
    grid = [{"tissue.young": float(e)} for e in np.geomspace(2000.0, 8000.0, args.runs)]
    print(f"{args.runs} runs of {args.scene} on {os.cpu_count()} cores; load before: {os.getloadavg()}")

    def serial():
        return [fibfluid.run(fibfluid.Scene.load(args.scene).set_parameter("tissue.young", p["tissue.young"]))
                for p in grid]

    base, expected = timed("serial (this process)", serial)
    _, pool = timed("sweep, default process pool", lambda: fibfluid.sweep(args.scene, grid), base)
    assert all(np.array_equal(a.positions, b.positions) for a, b in zip(pool, expected))
    if not args.no_dask:
        from distributed import Client, LocalCluster

        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
            with Client(cluster) as client:
                client.run(fibfluid.set_threads, 1)
                _, dask = timed("sweep, Dask LocalCluster 2 x 1", lambda: fibfluid.sweep(args.scene, grid,
                                                                                       executor=client), base)
        assert all(np.array_equal(a.positions, b.positions) for a, b in zip(dask, expected))
    print(f"load after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
