"""Type stubs of the fibfluid package (see __init__.py for the documentation)."""

import os
from dataclasses import dataclass
from typing import Any, Callable, Dict, List, Literal, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str
__all__: List[str]
METHODS: Tuple[str, ...]

Vector = Union[Sequence[float], npt.NDArray[np.floating[Any]]]
Progress = Union[None, bool, Callable[[int, int], Any]]
MethodName = Literal["ffm", "fem", "tsve-chainmail", "generalized-chainmail"]

class Error(ValueError):
    """Everything fibfluid refuses or fails at, with the command line's one-line message."""

class GuardWarning(RuntimeWarning):
    """A result guard fired on a Body's frame (issued once per guard and body)."""

class Scene:
    # Settings (checked on assignment; a bad value raises Error).
    steps: int
    tolerance: Optional[float]
    gravity: Tuple[float, float, float]
    fiber_modulus: Union[float, Tuple[float, float, float]]
    young: Union[float, Tuple[float, float, float]]  # the older name of fiber_modulus
    surface_tension: float
    density: float
    stiffening: Optional[float]
    fibers: Literal["paper", "projected"]
    kernel_exponent: float
    backend: Literal["structured", "faer-lu", "nalgebra-lu", "openblas-lu"]
    mode: Literal["paper", "refresh", "nonlinear"]
    stepping: Literal["euler", "heun"]
    precision: Literal["f64", "mixed"]
    constraints: Literal["eliminate", "penalty"]
    penalty: float
    @staticmethod
    def load(path: Union[str, os.PathLike[str]]) -> Scene: ...
    @staticmethod
    def from_labels(
        labels: npt.ArrayLike,
        spacing: Sequence[float],
        tissues: Dict[int, Dict[str, float]],
        model: str = ...,
        fix: Optional[Dict[str, Any]] = ...,
        gravity: Optional[Sequence[float]] = ...,
        vertices: Optional[int] = ...,
        directory: Union[str, os.PathLike[str], None] = ...,
    ) -> Scene: ...
    def with_mesh(self, vertices: npt.ArrayLike, faces: npt.ArrayLike) -> Scene: ...
    def copy(self) -> Scene: ...
    @property
    def settings(self) -> Dict[str, Any]: ...
    @settings.setter
    def settings(self, values: Dict[str, Any]) -> None: ...
    @property
    def solver(self) -> Dict[str, Any]: ...
    @solver.setter
    def solver(self, values: Dict[str, Any]) -> None: ...
    def update(self, **values: Any) -> Scene: ...
    def set_parameter(self, key: str, value: float) -> Scene: ...
    @property
    def name(self) -> str: ...
    @property
    def source(self) -> Optional[str]: ...
    @property
    def n_vertices(self) -> int: ...
    @property
    def vertices(self) -> npt.NDArray[np.float64]: ...
    @property
    def faces(self) -> npt.NDArray[np.int64]: ...
    @property
    def fixed_vertices(self) -> npt.NDArray[np.int64]: ...
    @property
    def notes(self) -> List[str]: ...
    def ineffective(self) -> List[str]: ...

@dataclass(frozen=True)
class Volume:
    nodes: npt.NDArray[np.float64]
    displacement: npt.NDArray[np.float64]
    hexahedra: npt.NDArray[np.int64]
    J: npt.NDArray[np.float64]
    max_principal_strain: npt.NDArray[np.float64]
    von_mises_stress: npt.NDArray[np.float64]
    fill: npt.NDArray[np.float64]
    material_id: npt.NDArray[np.int32]
    @property
    def n_nodes(self) -> int: ...
    @property
    def n_cells(self) -> int: ...
    @property
    def positions(self) -> npt.NDArray[np.float64]: ...
    @property
    def cell_data(self) -> Dict[str, npt.NDArray[Any]]: ...

@dataclass(frozen=True)
class Result:
    positions: npt.NDArray[np.float64]
    displacement: npt.NDArray[np.float64]
    pressure: float
    report: Dict[str, Any]
    warnings: List[str] = ...
    faces: Optional[npt.NDArray[np.int64]] = ...
    volume: Optional[Volume] = ...
    series: Optional[Dict[str, npt.NDArray[np.float64]]] = ...
    def to_meshio(self) -> Any: ...
    def to_pyvista(self) -> Any: ...
    def volume_to_meshio(self) -> Any: ...
    def volume_to_pyvista(self) -> Any: ...

def run(
    scene: Scene,
    method: Optional[MethodName] = None,
    progress: Progress = None,
    max_memory: Optional[int] = None,
) -> Result: ...

class Body:
    def __init__(self, scene: Scene, method: Optional[MethodName] = None, max_memory: Optional[int] = None) -> None: ...
    def grab(self, vertex: int, to: Vector) -> None: ...
    def push(self, vertex: int, force: Vector) -> None: ...
    def grasp(self, vertex: int, radius: float, to: Vector, rotation: Optional[Vector] = None) -> None: ...
    def press(self, centre: Vector, radius: float) -> None: ...
    def lift(self) -> None: ...
    def tools(self) -> List[Dict[str, Any]]: ...
    def release(self, vertex: int) -> None: ...
    def release_all(self) -> None: ...
    def step(self) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
    @property
    def warnings(self) -> List[str]: ...
    @property
    def positions(self) -> npt.NDArray[np.float64]: ...
    @property
    def displacement(self) -> npt.NDArray[np.float64]: ...
    @property
    def rest_positions(self) -> npt.NDArray[np.float64]: ...
    @property
    def reactions(self) -> npt.NDArray[np.float64]: ...
    @property
    def method(self) -> str: ...
    @property
    def supports_forces(self) -> bool: ...
    @property
    def n_vertices(self) -> int: ...
    @property
    def frame(self) -> int: ...
    @property
    def setup_seconds(self) -> float: ...
    @property
    def linearization(self) -> Optional[dict]: ...
    def is_fixed(self, vertex: int) -> bool: ...

def set_threads(n: int) -> Optional[str]: ...

def sweep(
    scenes: Union[str, os.PathLike[str], Scene, Sequence[Union[str, os.PathLike[str], Scene]]],
    parameters: Optional[Sequence[Dict[str, Any]]] = None,
    executor: Any = None,
    method: Optional[MethodName] = None,
    max_memory: Optional[int] = None,
) -> List[Result]: ...

@dataclass(frozen=True)
class Sensitivity:
    positions: npt.NDArray[np.float64]  # (N, 3) deformed surface, m
    derivatives: Dict[str, npt.NDArray[np.float64]]  # key -> (N, 3) du/dtheta, m per SI unit
    values: Dict[str, float]

def sensitivity(
    scene: Union[str, os.PathLike[str], Scene],
    parameters: Sequence[str],
    max_memory: Optional[int] = None,
) -> Sensitivity: ...

@dataclass(frozen=True)
class FitResult:
    keys: List[str]
    values: Dict[str, Optional[float]]  # None: not identifiable
    sigma: Dict[str, Optional[float]]
    identifiable: Dict[str, bool]
    at_bound: Dict[str, bool]
    start: Dict[str, float]
    correlation: npt.NDArray[np.float64]  # (k, k), NaN where not identifiable
    residual_rms: float
    residual_relative: float
    iterations: int
    newton_solves: int
    sensitivity_solves: int
    converged: bool
    history: npt.NDArray[np.float64]
    report: Dict[str, Any]

def fit(
    scene: Union[str, os.PathLike[str], Scene],
    observed: Union[npt.ArrayLike, Tuple[npt.ArrayLike, npt.ArrayLike]],  # (M, 4) or (vertices, positions in m)
    parameters: Sequence[str],
    bounds: Sequence[Sequence[float]],
    progress: Optional[Callable[[Dict[str, Any]], Any]] = None,
    max_memory: Optional[int] = None,
) -> FitResult: ...
