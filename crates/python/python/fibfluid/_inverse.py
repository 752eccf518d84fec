"""Sensitivities of the static finite-element equilibrium, and the fit of a scene's tissue
parameters to observed surface positions (``fibfluid fit`` with arrays)."""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

from . import Scene, SceneSource, _memory, _native
from ._native import Error


def _scene(scene: SceneSource, what: str) -> Scene:
    if isinstance(scene, Scene):
        return scene
    if isinstance(scene, (str, os.PathLike)):
        return Scene.load(scene)
    raise Error(f"{what} needs a fibfluid.Scene or a scene file's path, got {type(scene).__name__}")


def _keys(parameters: Any, what: str) -> List[str]:
    bad = Error(f"{what}: parameters must be a list of dotted keys such as ['tissue.young']")
    if isinstance(parameters, str):
        raise bad
    try:
        keys = list(parameters)
    except TypeError:
        raise bad from None
    if not all(isinstance(k, str) for k in keys):
        raise bad
    twice = sorted({k for k in keys if keys.count(k) > 1})
    if twice:
        raise Error(f"{what}: parameters: `{twice[0]}` is named twice")
    return keys


@dataclass(frozen=True)
class Sensitivity:
    """What :func:`sensitivity` gives back, in the mesh file's vertex order, SI units."""

    #: The deformed surface ``(N, 3)`` at equilibrium (metres).
    positions: np.ndarray
    #: Per parameter key, ``du/dtheta`` of every surface vertex ``(N, 3)`` (metres per SI
    #: unit of the parameter: per Pa for a modulus, per kg/m^3, per m/s^2 of gravity).
    derivatives: Dict[str, np.ndarray]
    #: Per parameter key, its value in the scene (SI).
    values: Dict[str, float]


def sensitivity(scene: SceneSource, parameters: Sequence[str], max_memory: Optional[int] = None) -> Sensitivity:
    """Solves the scene's static finite-element equilibrium (its ``[tissue]`` law, regions,
    gravity and point forces in full) and returns the deformed surface and, per dotted key
    of ``parameters`` (``tissue.young``, ``region.NAME.poisson``, ``tissue.density``,
    ``gravity``: the keys of ``[fit]``), the derivative of every surface vertex's position,
    from one factorization at the answer and one solve per parameter. The GIL is released.
    Plates, grasps and ``[time]`` are refused."""
    s = _scene(scene, "sensitivity")
    keys = _keys(parameters, "sensitivity")
    positions, derivatives, values = _native.sensitivity(s._native, keys, _memory(max_memory))
    return Sensitivity(positions=positions, derivatives=dict(zip(keys, derivatives)), values=dict(zip(keys, values)))


@dataclass(frozen=True)
class FitResult:
    """What :func:`fit` found: ``fit.json``'s content, the per-parameter entries keyed by
    the parameter's key."""

    #: The parameters' keys, in the order asked.
    keys: List[str]
    #: The fitted values (SI); None for a parameter the observations cannot see.
    values: Dict[str, Optional[float]]
    #: One standard deviation of each value (Gauss-Newton), None where not identifiable.
    sigma: Dict[str, Optional[float]]
    #: Whether the observations can see each parameter.
    identifiable: Dict[str, bool]
    #: Whether each value sits on a bound (its sigma then understates).
    at_bound: Dict[str, bool]
    #: The values the fit started from (the scene's).
    start: Dict[str, float]
    #: The parameters' correlation ``(k, k)``, NaN where either is not identifiable.
    correlation: np.ndarray
    #: RMS distance of the fitted model's observed vertices from the observations (m).
    residual_rms: float
    #: ``residual_rms`` over the observed displacement's RMS.
    residual_relative: float
    #: Levenberg-Marquardt iterations.
    iterations: int
    #: Newton solves (one per trial) and sensitivity solves (one per parameter per
    #: accepted iteration).
    newton_solves: int
    sensitivity_solves: int
    #: Whether the steps shrank to the tolerance (False: the iteration limit).
    converged: bool
    #: The RMS residual after each iteration (m).
    history: np.ndarray
    #: ``fit.json`` as ``fibfluid fit`` writes it.
    report: Dict[str, Any]


def _observed(observed: Any) -> Tuple[np.ndarray, np.ndarray]:
    """The observed vertices ``(M,)`` int64 and positions ``(M, 3)`` float64."""
    shape_error = Error("fit: observed must be an (M, 4) array [vertex, x, y, z] or a pair (vertices (M,), positions (M, 3))")
    if isinstance(observed, tuple) and len(observed) == 2:
        vertices, positions = (np.asarray(a) for a in observed)
    else:
        try:
            table = np.asarray(observed, dtype=np.float64)
        except (TypeError, ValueError):
            raise shape_error from None
        if table.ndim != 2 or table.shape[1] != 4:
            raise shape_error
        vertices, positions = table[:, 0], table[:, 1:]
    if vertices.dtype.kind == "f":
        if not np.all(np.isfinite(vertices) & (vertices == np.round(vertices))):
            raise Error("fit: observed vertices must be whole numbers (indices in the mesh file's order)")
    elif vertices.dtype.kind not in "iu" and vertices.size:
        raise Error(f"fit: observed vertices must be integers, got dtype {vertices.dtype}")
    if vertices.ndim != 1:
        raise Error(f"fit: observed vertices must have shape (M,), got {vertices.shape}")
    try:
        positions = np.ascontiguousarray(positions, dtype=np.float64)
    except (TypeError, ValueError):
        raise shape_error from None
    return np.ascontiguousarray(vertices, dtype=np.int64), positions


def fit(scene: SceneSource, observed: Any, parameters: Sequence[str], bounds: Sequence[Sequence[float]],
        progress: Optional[Callable[[Dict[str, Any]], Any]] = None, max_memory: Optional[int] = None) -> FitResult:
    """Fits ``parameters`` (dotted keys, as ``[fit] parameters``) within ``bounds`` (one
    ``[lower, upper]`` each, SI) to ``observed``, as ``fibfluid fit`` does: Levenberg-Marquardt
    in the parameters' logarithms from the scene's values, each step's Jacobian from the
    equilibrium's sensitivities. ``observed``: an ``(M, 4)`` array of rows ``[vertex, x, y,
    z]``, or a pair ``(vertices, positions)`` of shapes ``(M,)`` and ``(M, 3)``: vertices
    numbered as in the mesh file (0-based), deformed positions in metres (as every length in
    this package; ``observed.csv`` is in the mesh's unit). ``progress`` is called after each
    iteration with a dict (``iteration``, ``rms`` in m, ``relative``, ``values`` by key); an
    exception it raises is raised when the fit ends. The GIL is released."""
    s = _scene(scene, "fit")
    keys = _keys(parameters, "fit")
    try:
        b = np.asarray(bounds, dtype=np.float64)
    except (TypeError, ValueError):
        b = None
    if b is None or b.ndim != 2 or b.shape[1] != 2:
        raise Error("fit: bounds must be one [lower, upper] pair per parameter")
    vertices, positions = _observed(observed)
    tell = None
    if progress is not None:
        if not callable(progress):
            raise Error("fit: progress must be a callable taking a dict, or None")

        def tell(iteration: int, rms: float, relative: float, values: List[float]) -> None:
            progress({"iteration": iteration, "rms": rms, "relative": relative, "values": dict(zip(keys, values))})

    text = _native.fit(s._native, vertices, positions, keys, [[float(lo), float(hi)] for lo, hi in b], tell,
                       _memory(max_memory))
    report = json.loads(text)
    entries = report["parameters"]
    correlation = np.array([[np.nan if c is None else c for c in row] for row in report["correlation"]],
                           dtype=np.float64).reshape(len(keys), len(keys))
    return FitResult(
        keys=keys,
        values={p["key"]: p["value"] for p in entries},
        sigma={p["key"]: p["sigma"] for p in entries},
        identifiable={p["key"]: p["identifiable"] for p in entries},
        at_bound={p["key"]: p["at_bound"] for p in entries},
        start={p["key"]: p["start"] for p in entries},
        correlation=correlation,
        residual_rms=report["residual_rms"],
        residual_relative=report["residual_relative"],
        iterations=report["iterations"],
        newton_solves=report["newton_solves"],
        sensitivity_solves=report["sensitivity_solves"],
        converged=report["converged"],
        history=np.asarray(report["history"], dtype=np.float64),
        report=report,
    )
