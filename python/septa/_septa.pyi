"""Type stubs of septa's Rust extension (the Python API is in septa/__init__.py)."""

from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np
import numpy.typing as npt

__version__: str

class SeptaError(ValueError):
    """Base class of septa's errors."""

class InputError(SeptaError):
    """A file or volume septa cannot use (the message names it and the problem)."""

class ConfigError(SeptaError):
    """A wrong entry in the configuration (the message names the key)."""

class ParameterError(SeptaError):
    """A parameter out of its bounds (the message names it)."""

class InvariantError(Exception):
    """The output violates septa's invariants (please report it)."""

class Extraction:
    """The result of :func:`extract`, as the Python side reads it."""

    def arrays(self) -> Dict[str, npt.NDArray[Any]]:
        """``vertices`` (N, 3) float64 LPS mm, ``triangles`` (M, 3) int64,
        ``labels`` (M, 2) int64 label values, ``patch`` (M,) int64."""
    def junctions(self) -> List[Tuple[List[int], npt.NDArray[np.int64], bool]]:
        """``[(label values, vertex ids, closed)]``."""
    def label_names(self) -> List[Tuple[int, str]]: ...
    def manifest_json(self) -> str: ...
    def warnings(self) -> List[str]: ...
    def passed(self) -> bool: ...
    def validation_summary(self) -> str: ...
    def save(
        self,
        directory: str,
        force: bool = False,
        obj: bool = False,
        stl: bool = False,
        space: str = "lps",
        per_label: Sequence[str] = ...,
    ) -> List[str]:
        """``per_label``: any of ``"stl"``, ``"obj"``, ``"ply"``, ``"vtp"`` (``labels/<name>.<ext>``)."""

class Hyper:
    """A STEVE iso-hypersurface, as the Python side reads it."""

    def arrays(self) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.int64], npt.NDArray[np.uint8]]:
        """``(points (N, 4) x, y, z LPS mm and t, tets (M, 4), kinds (N,))``."""
    def stats_json(self) -> str: ...
    def time_range(self) -> Optional[Tuple[float, float]]: ...
    def slice(self, time: float) -> Tuple[Dict[str, npt.NDArray[Any]], Optional[int], str]:
        """``(arrays as Extraction.arrays, frame or None, validator report as JSON)``."""
    def check_json(self) -> str: ...

def read_volume(path: str) -> Tuple[npt.NDArray[np.int64], Tuple[int, int, int], List[List[float]]]:
    """``(values flat x fastest, (nx, ny, nz), 3×4 index → LPS affine rows)``."""

def extract(
    volume: npt.NDArray[np.int64],
    affine_lps: Sequence[Sequence[float]],
    config_toml: Optional[str] = None,
    config_path: Optional[str] = None,
    remesh: Optional[bool] = None,
    target_edge: Optional[float] = None,
    min_edge: Optional[float] = None,
    smooth_iterations: Optional[int] = None,
    max_displacement: Optional[float] = None,
    iterations: Optional[int] = None,
    surface: str = "vesta",
    decompose: str = "l",
    intersections: bool = False,
    max_memory: Optional[int] = None,
    source_file: Optional[str] = None,
    progress: Optional[Callable[[str, str, str], None]] = None,
    label_names: Optional[Sequence[Tuple[int, str]]] = None,
    label_names_path: Optional[str] = None,
    labels: Optional[Sequence[str]] = None,
    others: Optional[str] = None,
    merge_flat: bool = False,
) -> Extraction: ...
def config_json_to_toml(json: str) -> str: ...
def read_mesh(path: str) -> Dict[str, npt.NDArray[Any]]: ...
def check(path: str) -> Tuple[bool, str]: ...
def spacing_affine_lps(spacing: Sequence[float], origin: Sequence[float]) -> List[List[float]]: ...
def check_arrays(
    vertices: npt.NDArray[np.float64],
    triangles: npt.NDArray[np.int64],
    labels: Optional[npt.NDArray[np.int64]] = None,
    intersections: bool = True,
) -> str:
    """The validator's report on the arrays, as JSON text."""
def iso(
    values: npt.NDArray[Any],
    affine_lps: Sequence[Sequence[float]],
    iso: float,
    mode: str = "mixed",
    decompose: str = "l",
    displace: bool = True,
) -> Tuple[Dict[str, npt.NDArray[Any]], str]:
    """``(arrays as Extraction.arrays, N-cycle statistics as JSON)``."""
def hyper(
    values: npt.NDArray[Any],
    affine_lps: Sequence[Sequence[float]],
    iso: float,
    time_step: float = 1.0,
    mode: str = "mixed",
    displace: bool = True,
) -> Hyper: ...
