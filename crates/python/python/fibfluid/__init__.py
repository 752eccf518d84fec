"""fibfluid from Python: soft tissue as fluid held by elastic fibers.

Read a scene file, change its settings or its mesh, run it, and read the deformed surface
and the report that the ``fibfluid run`` command writes; or build an interactive body and
grab, push and release its vertices frame by frame::

    import fibfluid
    scene = fibfluid.Scene.load("fixtures/scenes/bunny-pull.toml")
    scene.steps = 10
    result = fibfluid.run(scene, progress=True)
    print(result.report["max_displacement"], result.displacement.shape)

    body = fibfluid.Body(scene, method="ffm")
    body.grab(177, [0.0, 0.01, 0.0])
    positions, reactions = body.step()

Vertices are numbered, and arrays ordered, as in the mesh file (``deformed.obj`` and path
files use the same order). Every error is :class:`fibfluid.Error`, a ``ValueError`` whose
message is the line the command line prints after ``error:``.
"""

from __future__ import annotations

import json
import os
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, Iterator, List, Optional, Sequence, Tuple, Union

import numpy as np

from . import _native
from ._native import Error

__version__: str = _native.__version__

__all__ = ["Body", "Error", "FitResult", "GuardWarning", "Result", "Scene", "Sensitivity", "Volume", "fit", "run",
           "sensitivity", "set_threads", "sweep", "__version__"]

#: The methods a :class:`Body` can run.
METHODS: Tuple[str, ...] = ("ffm", "tsve-chainmail", "generalized-chainmail")



class GuardWarning(RuntimeWarning):
    """A result guard fired on a :class:`Body`'s frame: the answer is outside what the
    model can give (a volume far from the body's, a vertex moved further than the body's
    size, faces turned inside out, or a finite-element answer past the small-strain
    limit). :attr:`Body.warnings` lists every guard that fired on the last step."""


Vector = Union[Sequence[float], np.ndarray]
Progress = Union[None, bool, Callable[[int, int], Any]]


def _points(a: Any, what: str) -> np.ndarray:
    try:
        return np.ascontiguousarray(a, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise Error(f"{what} must be a float64 array of shape (N, 3): {e}") from None


def _faces(a: Any) -> np.ndarray:
    try:
        f = np.asarray(a)
    except (TypeError, ValueError) as e:
        raise Error(f"faces must be an integer array of shape (F, 3): {e}") from None
    if f.size == 0 and f.dtype.kind not in "iu":
        f = f.astype(np.int64)
    if f.dtype.kind not in "iu":
        raise Error(f"faces must be an integer array of shape (F, 3), got dtype {f.dtype}")
    if f.dtype.kind == "u" and f.size and int(f.max()) > np.iinfo(np.int64).max:
        raise Error("faces: a vertex index is too large")
    return np.ascontiguousarray(f, dtype=np.int64)


class Scene:
    """A scene: a body, its material, constraints, loads and solver choices.

    Read one with :meth:`Scene.load`. Settings are attributes (``scene.steps``,
    ``scene.fiber_modulus``, ``scene.backend``, ...) and also a dict (:attr:`settings`, and
    :attr:`solver` for the solver's); each value is checked as the scene file's key is,
    and an unknown name or a bad value raises :class:`Error` and changes nothing.

    Settings: ``steps`` (int), ``tolerance`` (float in (0, 1) or None: adaptive steps),
    ``gravity`` (3 floats), ``fiber_modulus`` (a float, or 3 floats per axis; older name
    ``young``), ``surface_tension``, ``density`` (fluid), ``stiffening`` (float or None),
    ``backend``, ``mode``, ``stepping``, ``precision``, ``constraints`` (names as in scene
    files), ``penalty``.
    """

    __slots__ = ("_native",)

    def __init__(self, native: "_native.NativeScene") -> None:
        """Wraps a compiled scene; use :meth:`Scene.load` to read one."""
        object.__setattr__(self, "_native", native)

    @staticmethod
    def load(path: Union[str, "os.PathLike[str]"]) -> "Scene":
        """Reads a scene file (TOML); paths inside it are relative to it."""
        return Scene(_native.NativeScene.load(os.fspath(path)))

    @staticmethod
    def from_labels(labels: Any, spacing: Sequence[float], tissues: Dict[int, Dict[str, float]],
                    model: str = "neo-hookean", fix: Optional[Dict[str, Any]] = None,
                    gravity: Optional[Sequence[float]] = None, vertices: Optional[int] = None,
                    directory: Union[str, "os.PathLike[str]", None] = None) -> "Scene":
        """A scene from a label volume: ``labels`` an integer array ``(nx, ny, nz)`` (0 the
        background, indexed x, y, z), ``spacing`` the voxel size in metres (3 floats), and
        ``tissues`` ``{label: {"young": Pa, "poisson": ..., "density": kg/m^3}}`` for every
        label in the volume.

        The body is the surface of every non-zero label (at most ``vertices`` vertices when
        given); the lowest label's tissue is the body's ``[tissue]`` (with ``model``,
        ``"linear"`` or ``"neo-hookean"``) and every other label is a ``[[region]]`` of its
        own tissue, as ``[[region]] label = k`` in a scene file. ``fix`` is one
        ``[[fix]]`` table (for example ``{"axis": "y", "below": 0.01}``), ``gravity`` the
        acceleration (m/s^2). The method is the FEM.

        The volume is written as a NIfTI-1 image (spacing in micrometres, stored as float32)
        and the scene as TOML into ``directory`` (a new temporary directory by default),
        which the scene reads, as ``Scene.load`` would: keep it while the scene is used.
        """
        return Scene.load(_labels_scene(labels, spacing, tissues, model, fix, gravity, vertices, directory))

    def with_mesh(self, vertices: Any, faces: Any) -> "Scene":
        """A new scene whose body is the surface of ``vertices`` ``(N, 3)`` and ``faces``
        ``(F, 3)`` (integer vertex indices), checked as a mesh file is (finite, closed,
        manifold, consistently oriented; an inward surface is flipped, with a note).

        The scene file is read again for what depends on the vertices: its ``[[fix]]``
        selectors (above, below, top, bottom, box) select among the new vertices, vertex
        indices (``[[fix]].vertices``, ``[[force]].vertex``) are rows of ``vertices`` and are
        checked against them, plates are checked against the new rest shape. This scene's
        settings (as changed since it was read) carry over; ``[mesh].scale`` does not
        apply. This scene is not changed.
        """
        return Scene(self._native.with_mesh(_points(vertices, "vertices"), _faces(faces)))

    def copy(self) -> "Scene":
        """An independent copy."""
        return Scene(self._native.copy())

    # -- settings -------------------------------------------------------------------

    @property
    def settings(self) -> Dict[str, Any]:
        """Every setting as a dict (a copy); assigning a dict sets the names it has, all or
        none."""
        return {name: self._native.get(name) for name in _native.NativeScene.names()}

    @settings.setter
    def settings(self, values: Dict[str, Any]) -> None:
        self.update(**values)

    @property
    def solver(self) -> Dict[str, Any]:
        """The solver's settings: backend, mode, stepping, precision, constraints, penalty
        (a copy); assigning a dict sets the names it has, all or none."""
        return {name: self._native.get(name) for name in _native.NativeScene.solver_names()}

    @solver.setter
    def solver(self, values: Dict[str, Any]) -> None:
        unknown = [k for k in values if k not in _native.NativeScene.solver_names()]
        if unknown:
            names = ", ".join(_native.NativeScene.solver_names())
            raise Error(f"unknown solver setting `{unknown[0]}` (known: {names})")
        self.update(**values)

    def update(self, **values: Any) -> "Scene":
        """Sets several settings, all or none; returns the scene."""
        self._native.update(values)
        return self

    def set_parameter(self, key: str, value: float) -> "Scene":
        """Sets a tissue, region or gravity parameter by its dotted key (``tissue.young``,
        ``region.NAME.poisson``, ``gravity``: the keys of ``[fit]`` and ``fibfluid run
        --set``), in SI units; returns the scene."""
        self._native.set_parameter(key, float(value))
        return self

    def __setattr__(self, name: str, value: Any) -> None:
        # Settings and the `settings` and `solver` dicts are properties with setters; any
        # other name is a typo or a read-only value, which must not pass silently.
        prop = getattr(type(self), name, None)
        if isinstance(prop, property) and prop.fset is not None:
            prop.fset(self, value)
        elif name in _READ_ONLY:
            raise Error(f"`{name}` is read only")
        else:
            raise Error(f"unknown setting `{name}` (known: {', '.join(_SETTINGS)})")

    # -- the body -------------------------------------------------------------------

    @property
    def name(self) -> str:
        """The scene's name (the file's stem)."""
        return self._native.name

    @property
    def source(self) -> Optional[str]:
        """The scene file."""
        s = self._native.source
        return None if s is None else os.fspath(s)

    @property
    def n_vertices(self) -> int:
        """Number of vertices in the mesh file's order (used or not)."""
        return self._native.n_vertices

    @property
    def vertices(self) -> np.ndarray:
        """Rest positions ``(N, 3)`` float64, in the mesh file's order."""
        return self._native.vertices()

    @property
    def faces(self) -> np.ndarray:
        """Triangles ``(F, 3)`` int64 in file vertex indices, oriented outward."""
        return self._native.faces()

    @property
    def fixed_vertices(self) -> np.ndarray:
        """Vertices (file order) the scene fixes along at least one axis, ascending."""
        return np.asarray(self._native.fixed_vertices(), dtype=np.int64)

    @property
    def notes(self) -> List[str]:
        """Notes about the mesh (unreferenced vertices dropped, a surface flipped)."""
        return list(self._native.notes())

    def ineffective(self) -> List[str]:
        """Settings that cannot act (the command line's ``warning:`` lines before a run)."""
        return list(self._native.ineffective())

    def __repr__(self) -> str:
        return f"<fibfluid.Scene {self.name!r}: {self.n_vertices} vertices, {self.steps} steps>"


_SETTINGS: Tuple[str, ...] = tuple(_native.NativeScene.names())

#: What each setting is (the scene file's key in brackets).
_SETTING_DOCS: Dict[str, str] = {
    "steps": "Load steps, 1 to 1000000 ([load].steps).",
    "tolerance": "Adaptive steps: the largest error estimate of a step, in (0, 1), or None ([load].tolerance).",
    "gravity": "Final acceleration (x, y, z), reached over the steps ([gravity].acceleration).",
    "fiber_modulus": "FFM's fiber modulus, N/m^2 (not a tissue's Young's modulus): a float, or (x, y, z) when it differs per axis ([ffm].fiber_modulus).",
    "young": "The older name of fiber_modulus ([ffm].young, [material].young).",
    "surface_tension": "Surface tension, N/m, >= 0 ([ffm].surface_tension).",
    "density": "The fluid's density, >= 0 ([fluid].density).",
    "stiffening": "Quadratic stiffening coefficient c >= 0, or None for linear fibers ([ffm].stiffening).",
    "fibers": "Fiber model: paper, projected ([ffm].fibers).",
    "kernel_exponent": "Bulk weights fall as 1 / d^p, p in [0.5, 6]; 1 is the paper's ([ffm].kernel_exponent).",
    "backend": "Linear backend: structured, faer-lu, nalgebra-lu ([solver].backend).",
    "mode": "Stepping mode: paper, refresh, nonlinear ([solver].mode).",
    "stepping": "Stepping scheme: euler, heun ([solver].stepping).",
    "precision": "Factorization precision: f64, mixed ([solver].precision).",
    "constraints": "How fixed vertices are imposed: eliminate, penalty ([solver].constraints).",
    "penalty": "The penalty's diagonal value, > 0 ([solver].penalty).",
}


#: The longest side of a NIfTI-1 image (its dimensions are 16-bit signed), in voxels.
_NIFTI1_MAX_DIM = 32767
#: The largest label of a label image (32-bit unsigned).
_MAX_LABEL = 2**32 - 1


def _nifti1(labels: np.ndarray, spacing_um: Sequence[float]) -> bytes:
    """A NIfTI-1 single file (uint16 or uint32 labels, x fastest, lengths in micrometres)."""
    import struct
    big = int(labels.max(initial=0)) > 65535
    datatype, bits, dtype = (768, 32, "<u4") if big else (512, 16, "<u2")
    header = bytearray(352)
    struct.pack_into("<i", header, 0, 348)
    struct.pack_into("<8h", header, 40, 3, *labels.shape, 1, 1, 1, 1)
    struct.pack_into("<2h", header, 70, datatype, bits)
    struct.pack_into("<8f", header, 76, 1.0, *spacing_um, 0.0, 0.0, 0.0, 0.0)
    struct.pack_into("<f", header, 108, 352.0)
    struct.pack_into("<B", header, 123, 3)  # xyzt_units: micrometres
    header[344:348] = b"n+1\0"
    return bytes(header) + np.asarray(labels, dtype=dtype).tobytes(order="F")


def _toml_value(v: Any) -> str:
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return repr(float(v)) if isinstance(v, float) else str(v)


def _tissue_toml(t: Dict[str, float]) -> str:
    return "".join(f"{k} = {_toml_value(float(t[k]))}\n" for k in ("young", "poisson", "density") if k in t)


def _labels_scene(labels: Any, spacing: Sequence[float], tissues: Dict[int, Dict[str, float]], model: str,
                  fix: Optional[Dict[str, Any]], gravity: Optional[Sequence[float]], vertices: Optional[int],
                  directory: Any) -> str:
    import tempfile
    a = np.asarray(labels)
    if a.ndim != 3 or not np.issubdtype(a.dtype, np.integer):
        raise Error(f"labels must be a 3-D integer array, not {a.ndim}-D {a.dtype}")
    if any(n > _NIFTI1_MAX_DIM for n in a.shape):
        raise Error(f"labels: a label volume of shape {a.shape} has a side over {_NIFTI1_MAX_DIM} voxels, "
                    "the most a NIfTI-1 image holds: crop or downsample it")
    if a.size and int(a.min()) < 0:
        raise Error("labels must not be negative (0 is the background)")
    if a.size and int(a.max()) > _MAX_LABEL:
        raise Error(f"labels: label {int(a.max())} is over {_MAX_LABEL}, the largest a label image holds "
                    "(32-bit labels): number the labels from 1")
    h = [float(x) for x in spacing]
    if len(h) != 3 or not all(np.isfinite(x) and x > 0 for x in h):
        raise Error(f"spacing must be 3 positive lengths in metres, not {spacing!r}")
    present = sorted(int(v) for v in np.unique(a) if v != 0)
    if not present:
        raise Error("the label volume has no non-zero voxel: no body")
    missing = [k for k in present if k not in tissues]
    if missing:
        raise Error(f"label {missing[0]} has no tissue (tissues gives {sorted(tissues)})")
    d = directory if directory is not None else tempfile.mkdtemp(prefix="fibfluid-labels-")
    d = os.fspath(d)
    with open(os.path.join(d, "labels.nii"), "wb") as f:
        f.write(_nifti1(a, [x * 1e6 for x in h]))
    lines = ["[mesh]", 'image = "labels.nii"']
    if vertices is not None:
        lines.append(f"vertices = {int(vertices)}")
    lines += ["", "[tissue]", f"model = {_toml_value(model)}", _tissue_toml(tissues[present[0]])]
    for k in present[1:]:
        lines += ["[[region]]", f'name = "label {k}"', f"label = {k}", "[region.tissue]", _tissue_toml(tissues[k])]
    if fix is not None:
        lines += ["[[fix]]"] + [f"{k} = {_toml_value(v)}" for k, v in fix.items()] + [""]
    if gravity is not None:
        lines += ["[gravity]", f"acceleration = {_toml_value([float(x) for x in gravity])}", ""]
    lines += ["[solver]", 'method = "fem"', ""]
    path = os.path.join(d, "scene.toml")
    with open(path, "w") as f:
        f.write("\n".join(lines))
    return path


def _setting(name: str) -> property:
    def get(self: Scene) -> Any:
        return self._native.get(name)

    def set(self: Scene, value: Any) -> None:
        self._native.set(name, value)

    return property(get, set, doc=_SETTING_DOCS.get(name, name))


#: Older names of settings (the scene file's older keys), read and written as the new ones.
_OLDER_SETTINGS: Tuple[str, ...] = ("young",)

for _name in _SETTINGS + _OLDER_SETTINGS:
    setattr(Scene, _name, _setting(_name))
del _name
_READ_ONLY: Tuple[str, ...] = ("name", "source", "n_vertices", "vertices", "faces", "fixed_vertices", "notes")


def _optional(module: str, what: str) -> Any:
    """Imports an optional dependency, or raises ImportError saying how to install it."""
    import importlib
    try:
        return importlib.import_module(module)
    except ImportError as e:
        raise ImportError(f"{what} needs {module}, which is not installed: pip install {module}") from e


@dataclass(frozen=True)
class Volume:
    """Inside the tissue: the finite-element run's grid of hexahedra and its answer, the
    data of the command line's ``volume.vtu``. SI units: lengths in metres, stresses in Pa
    (``volume.vtu`` writes lengths in the mesh's unit).

    Nodes are the grid's nodes (not the surface's vertices), cells its active cells, in the
    grid's order. Cell data are per cell; see :attr:`cell_data`."""

    #: Rest positions of the grid's nodes ``(N, 3)`` float64, metres.
    nodes: np.ndarray
    #: Displacement of every node ``(N, 3)`` float64, metres.
    displacement: np.ndarray
    #: The active cells ``(C, 8)`` int64: node indices in VTK's hexahedron corner order
    #: (``VTK_HEXAHEDRON``, type 12).
    hexahedra: np.ndarray
    #: Each cell's mean dilatation ``J`` (current over rest volume) ``(C,)`` float64.
    J: np.ndarray
    #: Each cell's largest principal Green–Lagrange strain ``(C,)`` float64.
    max_principal_strain: np.ndarray
    #: Each cell's von Mises equivalent of the Cauchy stress ``(C,)`` float64, Pa.
    von_mises_stress: np.ndarray
    #: Each cell's fill fraction, the part of it inside the surface, in (0, 1] ``(C,)``.
    fill: np.ndarray
    #: Each cell's material ``(C,)`` int32: 0 the scene's ``[tissue]``, ``k`` its ``k``-th
    #: ``[[region]]`` (the region holding most of the cell).
    material_id: np.ndarray

    @property
    def n_nodes(self) -> int:
        """Number of grid nodes."""
        return len(self.nodes)

    @property
    def n_cells(self) -> int:
        """Number of active cells."""
        return len(self.hexahedra)

    @property
    def positions(self) -> np.ndarray:
        """Deformed node positions ``(N, 3)``, metres: ``nodes + displacement`` (a new
        array at each call)."""
        return self.nodes + self.displacement

    @property
    def cell_data(self) -> Dict[str, np.ndarray]:
        """The cell fields by ``volume.vtu``'s names: ``J``, ``max_principal_strain``,
        ``von_mises_stress`` (Pa), ``fill`` and ``material_id`` (the arrays themselves,
        not copies)."""
        return {
            "J": self.J,
            "max_principal_strain": self.max_principal_strain,
            "von_mises_stress": self.von_mises_stress,
            "fill": self.fill,
            "material_id": self.material_id,
        }

    def __repr__(self) -> str:
        return f"<fibfluid.Volume: {self.n_nodes} nodes, {self.n_cells} hexahedra>"


def _volume(native: Any) -> Optional[Volume]:
    if native is None:
        return None
    return Volume(
        nodes=native.nodes,
        displacement=native.displacement,
        hexahedra=native.hexahedra,
        J=native.J,
        max_principal_strain=native.max_principal_strain,
        von_mises_stress=native.von_mises_stress,
        fill=native.fill,
        material_id=native.material_id,
    )


def _series(report: Dict[str, Any]) -> Optional[Dict[str, np.ndarray]]:
    """A timed run's series from its report (``newton.series``), as NumPy arrays."""
    rows = (report.get("newton") or {}).get("series")
    if not rows:
        return None
    out: Dict[str, np.ndarray] = {
        key: np.array([r[key] for r in rows], dtype=np.float64)
        for key in ("time", "load", "max_displacement", "volume", "kinetic_energy", "strain_energy")
    }
    plates, grasps = len(rows[0]["plate_forces"]), len(rows[0]["grasp_forces"])
    out["plate_forces"] = np.array([r["plate_forces"] for r in rows], dtype=np.float64).reshape(len(rows), plates)
    out["grasp_forces"] = np.array([r["grasp_forces"] for r in rows], dtype=np.float64).reshape(len(rows), grasps, 3)
    return out


@dataclass(frozen=True)
class Result:
    """What :func:`run` gives back. The surface's arrays are in the mesh file's vertex
    order, the order of ``deformed.obj``; a finite-element run adds :attr:`volume`, the
    answer inside the tissue. Lengths are in metres (SI), whatever the mesh file's unit."""

    #: Final positions ``(N, 3)`` float64 (``deformed.obj``'s vertices).
    positions: np.ndarray
    #: Final minus rest positions ``(N, 3)`` float64.
    displacement: np.ndarray
    #: The fluid's pressure change at the end.
    pressure: float
    #: ``report.json`` as the command line writes it, as Python objects.
    report: Dict[str, Any]
    #: Guard warnings, one line each (the report's ``warnings`` as text).
    warnings: List[str] = field(default_factory=list)
    #: Triangles ``(F, 3)`` int64 in file vertex indices (the scene's ``faces``; a 2-D
    #: polygon's fan).
    faces: Optional[np.ndarray] = None
    #: Inside the tissue, for a finite-element run (``method="fem"``): the grid's nodes,
    #: hexahedra and fields of ``volume.vtu``, in metres and Pa. None for the FFM.
    volume: Optional[Volume] = None
    #: A timed scene's series (``[time]``), the columns of ``series.csv`` as float64
    #: arrays, one entry per output time: ``time`` (s), ``load``, ``max_displacement`` (m),
    #: ``volume`` (m^3), ``kinetic_energy`` and ``strain_energy`` (J), ``plate_forces``
    #: ``(T, plates)`` and ``grasp_forces`` ``(T, grasps, 3)`` (N). None for one equilibrium.
    series: Optional[Dict[str, np.ndarray]] = None

    def volume_to_meshio(self) -> Any:
        """The finite-element volume as a ``meshio.Mesh`` (metres, Pa): the deformed nodes
        (``nodes + displacement``, the one new array), one ``"hexahedron"`` cell block, the
        point data ``displacement`` (m) and the cell data of :attr:`Volume.cell_data`
        (shared with :attr:`volume`, not copied). ``mesh.write("volume.vtu")`` writes it.
        Needs ``meshio`` (``pip install meshio``); raises :class:`Error` for an FFM run."""
        v = self._volume()
        meshio = _optional("meshio", "Result.volume_to_meshio")
        return meshio.Mesh(
            v.positions,
            [("hexahedron", v.hexahedra)],
            point_data={"displacement": v.displacement},
            cell_data={name: [values] for name, values in v.cell_data.items()},
        )

    def volume_to_pyvista(self) -> Any:
        """The finite-element volume as a ``pyvista.UnstructuredGrid`` of hexahedra (metres,
        Pa): the deformed nodes (``nodes + displacement``, a new array), the point data
        ``displacement`` (m) and the cell data of :attr:`Volume.cell_data`. PyVista copies the
        hexahedra once into VTK's cell array; the positions and the data are shared, not
        copied. Needs ``pyvista`` (``pip install pyvista``); raises :class:`Error` for an FFM
        run."""
        v = self._volume()
        pyvista = _optional("pyvista", "Result.volume_to_pyvista")
        grid = pyvista.UnstructuredGrid({pyvista.CellType.HEXAHEDRON: v.hexahedra}, v.positions)
        grid.point_data["displacement"] = v.displacement
        for name, values in v.cell_data.items():
            grid.cell_data[name] = values
        return grid

    def _volume(self) -> Volume:
        if self.volume is None:
            raise Error("this result has no volume: only a finite-element run (method=\"fem\") has one")
        return self.volume

    def to_meshio(self) -> Any:
        """The deformed surface as a ``meshio.Mesh`` (metres): triangles, and the point data
        ``displacement`` (m) and ``displacement_magnitude``. The arrays are shared, not
        copied. Needs ``meshio`` (``pip install meshio``)."""
        meshio = _optional("meshio", "Result.to_meshio")
        return meshio.Mesh(
            self.positions,
            [("triangle", self._faces())],
            point_data=self._point_data(),
        )

    def to_pyvista(self) -> Any:
        """The deformed surface as a ``pyvista.PolyData`` (metres) with the point data of
        :meth:`to_meshio`. The faces are copied once into VTK's ``[3, i, j, k, ...]`` layout.
        Needs ``pyvista`` (``pip install pyvista``)."""
        pyvista = _optional("pyvista", "Result.to_pyvista")
        faces = self._faces()
        cells = np.hstack([np.full((len(faces), 1), 3, dtype=np.int64), faces]).ravel()
        mesh = pyvista.PolyData(self.positions, cells)
        for name, values in self._point_data().items():
            mesh.point_data[name] = values
        return mesh

    def _faces(self) -> np.ndarray:
        if self.faces is None:
            raise Error("this result has no faces")
        return self.faces

    def _point_data(self) -> Dict[str, np.ndarray]:
        return {
            "displacement": self.displacement,
            "displacement_magnitude": np.linalg.norm(self.displacement, axis=1),
        }


def _progress_callback(progress: Progress) -> Tuple[Optional[Callable[[int, int], Any]], Callable[[], None]]:
    """The callback to hand to the engine, and what to call when the run ends."""
    if progress is None or progress is False:
        return None, lambda: None
    if progress is True:
        try:
            from tqdm.auto import tqdm
        except ImportError:
            warnings.warn("progress=True needs tqdm (pip install tqdm); running without a bar", stacklevel=3)
            return None, lambda: None
        bar: Dict[str, Any] = {}

        def update(step: int, total: int) -> None:
            if "bar" not in bar:
                bar["bar"] = tqdm(total=total, unit="step", desc="fibfluid")
            b = bar["bar"]
            b.total = total
            b.update(step - b.n)

        return update, lambda: bar["bar"].close() if "bar" in bar else None
    if callable(progress):
        return progress, lambda: None
    raise Error("progress must be None, True, False or a callable (step, total)")


def run(scene: Scene, method: Optional[str] = None, progress: Progress = None,
        max_memory: Optional[int] = None) -> Result:
    """Runs a scene as ``fibfluid run`` does (the same stages, numbers and report, without
    writing files) and returns a :class:`Result`.

    ``method`` may be None (the scene's own), ``"ffm"`` or ``"fem"`` (the finite-element
    method with the scene's ``[tissue]`` law, linear or neo-Hookean; its ``pressure`` is 0,
    its :attr:`Result.volume` holds the answer inside the tissue, and ``progress`` is not
    called: Newton's load steps are in ``report["newton"]``).
    ChainMail is interactive only, see :class:`Body`. ``progress`` is a callable
    ``(step, total)`` called after each load step, or True for a tqdm bar. The GIL is
    released during the solve. ``max_memory`` (bytes) refuses a scene whose plan needs
    more, as ``--max-memory``. The scene's settings that cannot act are issued as warnings.
    """
    if not isinstance(scene, Scene):
        raise Error("run needs a fibfluid.Scene (Scene.load)")
    fem = None if method is None else method == "fem"
    if method is not None and method not in ("ffm", "fem"):
        known = ", ".join(METHODS)
        if method in METHODS:
            raise Error(f"{method} is interactive only (no batch run): use fibfluid.Body(scene, method={method!r})")
        raise Error(f"unknown method `{method}` (expected one of: {known})")
    for w in scene.ineffective():
        warnings.warn(w, stacklevel=2)
    callback, close = _progress_callback(progress)
    try:
        out = _native.run(scene._native, callback, _memory(max_memory), fem)
    finally:
        close()
    report = json.loads(out.report_json)
    return Result(
        positions=out.positions,
        displacement=out.displacement,
        pressure=out.pressure,
        report=report,
        warnings=list(out.warnings),
        faces=scene.faces,
        volume=_volume(out.volume),
        series=_series(report),
    )


class Body:
    """An interactive body: grab, push and release vertices, frame by frame.

    ``method`` (default: the scene's ``[solver] method``) is ``"ffm"`` (the fiber-fluid method: a base solve of the scene's loads,
    then the precomputed response; grabs and pushes, with reaction forces), ``"fem"`` (the
    finite-element method with the scene's ``[tissue]`` law: linear, or neo-Hookean at two
    rates, its linearization refreshed by Newton's iterations on a second thread while
    :meth:`step` answers on the latest one and never waits for it; see
    :attr:`linearization`), ``"tsve-chainmail"`` or ``"generalized-chainmail"`` (grabs only,
    no forces). Building it releases the GIL. Vertices are file indices, as in path files; ``to`` is a
    displacement from the rest position. Holds take effect at the next :meth:`step`.
    """

    __slots__ = ("_native", "_warned")

    def __init__(self, scene: Scene, method: Optional[str] = None, max_memory: Optional[int] = None) -> None:
        """Builds the body of ``scene`` for ``method`` (default: the scene's method)."""
        if not isinstance(scene, Scene):
            raise Error("Body needs a fibfluid.Scene (Scene.load)")
        if method is not None and not isinstance(method, str):
            raise Error(f"method must be a string, one of: {', '.join(METHODS)}")
        self._native = _native.NativeBody(scene._native, method, _memory(max_memory))
        self._warned: set = set()

    def grab(self, vertex: int, to: Vector) -> None:
        """Holds ``vertex`` at its rest position plus ``to`` (3 floats) from the next step."""
        self._native.grab(_index(vertex), _vector(to, "the displacement"))

    def push(self, vertex: int, force: Vector) -> None:
        """Pushes ``vertex`` with ``force`` (3 floats) from the next step (ffm only)."""
        self._native.push(_index(vertex), _vector(force, "the force"))

    def grasp(self, vertex: int, radius: float, to: Vector, rotation: Optional[Vector] = None) -> None:
        """Grasps the patch of every vertex whose rest position is within ``radius`` (metres,
        Euclidean) of ``vertex``'s and moves it rigidly from the next step: translated by
        ``to`` (a displacement from rest, 3 floats) and turned by the rotation vector
        ``rotation`` (axis times angle in radians) about the patch's rest centroid (the
        mean of its vertices' rest positions), as a scene's ``[[grasp]]`` turns its patch. A
        later grasp of the same vertex moves it; :meth:`release` drops it."""
        rot = None if rotation is None else _vector(rotation, "the rotation")
        self._native.grasp(_index(vertex), _radius(radius), _vector(to, "the displacement"), rot)

    def press(self, centre: Vector, radius: float) -> None:
        """Places a rigid spherical tip of ``radius`` (metres) centred at ``centre``
        (absolute, metres): frictionless, unilateral contact, its contacts found at the next
        step. A later press moves it; :meth:`lift` takes it away."""
        self._native.press(_vector(centre, "the centre"), _radius(radius))

    def lift(self) -> None:
        """Takes the tip away from the next step."""
        self._native.lift()

    def tools(self) -> List[dict]:
        """The tools' loads after the last step: for each grasp ``{"grasp": vertex,
        "vertices": k, "force": [..], "moment": [..]}`` (total force on the patch in N, its
        moment in N m about the tool's centre) and for the tip ``{"press": centre,
        "radius": r, "contacts": k, "force": [..], "penetration": p}``."""
        return json.loads(self._native.tools_json())

    def release(self, vertex: int) -> None:
        """Drops the hold (or the grasp picked) on ``vertex`` from the next step."""
        self._native.release(_index(vertex))

    def release_all(self) -> None:
        """Drops every hold, grasp and the tip from the next step."""
        self._native.release_all()

    def _fail_next_refreshes(self, count: int) -> None:
        """Makes the next ``count`` refreshes of a neo-Hookean ``"fem"`` body fail, for
        testing what a caller does then: steps go on with the last good linearization and
        :attr:`linearization` names the failure. Raises :class:`Error` for other bodies.
        Only in a build with the ``testing`` feature (``crates/python/ci.sh``)."""
        self._native.fail_next_refreshes(_index(count))

    def step(self) -> Tuple[np.ndarray, np.ndarray]:
        """Applies the holds and computes a frame (the GIL released). Returns the positions
        ``(N, 3)`` and the reactions ``(k, 4)``: one row per held vertex, sorted, with the
        vertex (as a float) and the force on the body there (x, y, z); empty without
        forces (ChainMail).

        Each frame is checked by the result guards (see :attr:`warnings`); the first time a
        guard fires on this body it is also issued as a :class:`GuardWarning`. A frame whose
        answer is not finite raises :class:`Error`."""
        frame = self._native.step()
        for guard, message in self._native.warnings():
            if guard not in self._warned:
                self._warned.add(guard)
                warnings.warn(message, GuardWarning, stacklevel=2)
        return frame

    @property
    def warnings(self) -> List[str]:
        """The result guards that fired on the last :meth:`step`, one line each (empty when
        every guard held): the volume against the rest volume (a factor of 2 either way),
        the largest displacement against the body's size (its bounding-box diagonal), faces
        turned inside out, and for ``"fem"`` (a linear, small-strain model) a displacement
        past a tenth of the body's size."""
        return [message for _, message in self._native.warnings()]

    @property
    def positions(self) -> np.ndarray:
        """Current positions ``(N, 3)``."""
        return self._native.positions()

    @property
    def displacement(self) -> np.ndarray:
        """Current displacement from rest ``(N, 3)``."""
        return self._native.displacement()

    @property
    def rest_positions(self) -> np.ndarray:
        """Rest positions ``(N, 3)``."""
        return self._native.rest_positions()

    @property
    def reactions(self) -> np.ndarray:
        """The last frame's reactions ``(k, 4)`` (see :meth:`step`)."""
        return self._native.reactions()

    @property
    def method(self) -> str:
        """The method's name."""
        return self._native.method

    @property
    def supports_forces(self) -> bool:
        """Whether :meth:`push` and reactions are available."""
        return self._native.supports_forces

    @property
    def n_vertices(self) -> int:
        """Number of vertices (file order)."""
        return self._native.n_vertices

    @property
    def frame(self) -> int:
        """Frames computed so far."""
        return self._native.frame

    @property
    def setup_seconds(self) -> float:
        """Seconds the setup took."""
        return self._native.setup_seconds

    @property
    def linearization(self) -> Optional[dict]:
        """For a neo-Hookean ``"fem"`` body, the linearization the last step used:
        ``refreshes`` (made so far), ``refactorizations`` (those that factored the tangent;
        the others kept the factor and moved the state), ``age_frames`` and
        ``age_seconds`` (how old it is), ``step`` (m: how far the step moved the surface
        from the linearization's state), ``estimated_error`` (m: the step's distance from
        the converged answer for its holds, Newton's next correction, at least half the
        step on a kept factor), ``refresh_seconds`` (the last refresh), ``pending`` (held
        vertices the step left free: a tool just picked up, whose compliance columns the
        refresh thread is still making) and ``failure`` (why the last refresh failed, or
        None: the step then used the last good linearization). None for the other bodies,
        whose steps are exact for their model."""
        return json.loads(self._native.linearization_json())

    def is_fixed(self, vertex: int) -> bool:
        """Whether the scene fixes ``vertex`` along any axis."""
        return self._native.is_fixed(_index(vertex))

    def __repr__(self) -> str:
        return f"<fibfluid.Body {self.method}: {self.n_vertices} vertices, frame {self.frame}>"


def _radius(r: Any) -> float:
    if isinstance(r, bool) or not isinstance(r, (int, float, np.integer, np.floating)):
        raise Error(f"a radius must be a number, got {type(r).__name__}")
    if not (float(r) > 0.0 and np.isfinite(r)):
        raise Error(f"the tool's radius {r} must be positive and finite")
    return float(r)


# The native layer takes vertices as signed 64-bit integers and memory limits as unsigned
# ones; a Python integer outside those ranges is refused here as fibfluid.Error (PyO3 would
# raise OverflowError).
_I64 = range(-(2**63), 2**63)
_U64 = range(0, 2**64)


def _index(v: Any) -> int:
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
        raise Error(f"a vertex must be an integer, got {type(v).__name__}")
    i = int(v)
    if i not in _I64:
        raise Error(f"vertex {i} is out of range")
    return i


def _memory(m: Any) -> Optional[int]:
    if m is None:
        return None
    if isinstance(m, bool) or not isinstance(m, (int, np.integer)):
        raise Error(f"max_memory must be a number of bytes (an integer), got {type(m).__name__}")
    b = int(m)
    if b not in _U64:
        raise Error(f"max_memory must be a number of bytes between 0 and 2^64 - 1, got {b}")
    return b


def _vector(v: Any, what: str) -> List[float]:
    try:
        a = np.asarray(v, dtype=np.float64)
    except (TypeError, ValueError):
        raise Error(f"{what} must be three finite numbers [x, y, z]") from None
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise Error(f"{what} must be three finite numbers [x, y, z]")
    return [float(a[0]), float(a[1]), float(a[2])]


def set_threads(n: int) -> Optional[str]:
    """Sets the number of threads the solvers use (the command line's ``--threads``);
    returns a note when it was lowered. Call it before the first run."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
        raise Error("threads must be a positive integer")
    return _native.set_threads(int(n))


SceneSource = Union[str, "os.PathLike[str]", Scene]


def _sweep_scene(scene: SceneSource, values: Dict[str, Any]) -> Scene:
    """The scene with ``values`` set: dotted keys (and ``gravity``) as parameters, the rest
    as settings."""
    s = scene.copy() if isinstance(scene, Scene) else Scene.load(scene)
    settings = {k: v for k, v in values.items() if "." not in k and k != "gravity"}
    for k, v in values.items():
        if k not in settings:
            s.set_parameter(k, v)
    return s.update(**settings)


def _sweep_one(task: Tuple[SceneSource, Dict[str, Any], Optional[str], Optional[int]]) -> Result:
    """One run of :func:`sweep` (a top-level function: process and Dask workers pickle it)."""
    scene, values, method, max_memory = task
    return run(_sweep_scene(scene, values), method=method, max_memory=max_memory)


def sweep(scenes: Union[SceneSource, Sequence[SceneSource]], parameters: Optional[Sequence[Dict[str, Any]]] = None,
          executor: Any = None, method: Optional[str] = None, max_memory: Optional[int] = None) -> List[Result]:
    """Runs many scenes and returns their :class:`Result` s in order: each of ``scenes``
    (paths or :class:`Scene` s), or one scene once per dict of ``parameters`` (dotted keys
    such as ``tissue.young`` and ``region.NAME.young`` set as :meth:`Scene.set_parameter`
    does, other keys as settings: ``{"tissue.young": 3000.0, "steps": 10}``).

    ``executor`` is any ``concurrent.futures.Executor`` (its ``map``) or a Dask
    ``distributed.Client`` (anything with ``map`` and ``gather``); by default a local
    ``ProcessPoolExecutor`` of one process per core (each solving with one thread), the
    processes started by ``spawn``. Process and Dask workers get the scenes by path: give
    paths there (a :class:`Scene` does not pickle). Each parameter dict is checked before
    anything runs."""
    if parameters is not None:
        if not isinstance(scenes, (str, os.PathLike, Scene)):
            raise Error("sweep with parameters takes one scene (a path or a Scene)")
        base = scenes if isinstance(scenes, Scene) else Scene.load(scenes)
        for values in parameters:
            _sweep_scene(base, dict(values))
        tasks = [(scenes, dict(values), method, max_memory) for values in parameters]
    else:
        listed = [scenes] if isinstance(scenes, (str, os.PathLike, Scene)) else list(scenes)
        tasks = [(scene, {}, method, max_memory) for scene in listed]
    if not tasks:
        return []
    if executor is None:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        workers = min(len(tasks), os.cpu_count() or 1)
        context = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(workers, mp_context=context, initializer=set_threads, initargs=(1,)) as pool:
            return list(pool.map(_sweep_one, tasks))
    if hasattr(executor, "gather") and hasattr(executor, "map"):
        return list(executor.gather(executor.map(_sweep_one, tasks, pure=False)))
    return list(executor.map(_sweep_one, tasks))


# After Scene and the helpers it imports from this module.
from ._inverse import FitResult, Sensitivity, fit, sensitivity  # noqa: E402
