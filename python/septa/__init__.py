"""septa: consistent manifold interface meshes between all labels of a segmented volume.

numpy in, meshes out::

    import nibabel as nib
    import septa

    img = nib.load("data/heart_phantom_48.nii.gz")
    labels = np.asarray(img.dataobj).astype(np.int64)
    mesh = septa.extract(labels, affine=img.affine, config="configs/heart.toml")
    mesh.vertices        # (N, 3) float64, RAS mm (as nibabel's affine)
    mesh.triangles       # (M, 3) int64 vertex ids
    mesh.labels          # (M, 2) label values: normals point from labels[:, 0] into labels[:, 1]
    mesh.to_pyvista().plot(scalars="patch")

The work runs in Rust with the GIL released; septa's errors are raised as
:class:`SeptaError` subclasses (or :class:`OSError` for files) with septa's messages.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _septa
from ._septa import (  # noqa: F401  (re-exported)
    ConfigError,
    InputError,
    InvariantError,
    ParameterError,
    SeptaError,
)

__version__: str = _septa.__version__

__all__ = [
    "Volume",
    "Interfaces",
    "Junction",
    "Surface",
    "read_volume",
    "extract",
    "check",
    "SeptaError",
    "InputError",
    "ConfigError",
    "ParameterError",
    "InvariantError",
]

_LPS_TO_RAS = np.diag([-1.0, -1.0, 1.0, 1.0])

PathLike = Union[str, "os.PathLike[str]"]
ProgressCallback = Callable[[str, str, str], None]


def _check_space(space: str) -> str:
    s = space.lower()
    if s not in ("ras", "lps"):
        raise ParameterError(f'space = {space!r}: use "ras" or "lps"')
    return s


def _affine4(rows34: Any) -> np.ndarray:
    a = np.eye(4)
    a[:3, :] = np.asarray(rows34, dtype=np.float64)
    return a


@dataclass(frozen=True)
class Volume:
    """A label volume read from a file.

    ``labels`` is an ``(nx, ny, nz)`` int64 array indexed ``[x, y, z]`` (as
    nibabel gives it); ``affine_ras`` maps voxel indices to RAS mm (nibabel's
    ``img.affine``), ``affine_lps`` to LPS mm (DICOM, ITK, 3D Slicer).
    """

    labels: np.ndarray
    affine_ras: np.ndarray
    affine_lps: np.ndarray

    @property
    def affine(self) -> np.ndarray:
        """The RAS affine (nibabel's convention)."""
        return self.affine_ras

    @property
    def spacing(self) -> np.ndarray:
        """Voxel spacing in mm along each index axis."""
        return np.linalg.norm(self.affine_lps[:3, :3], axis=0)


def read_volume(path: PathLike) -> Volume:
    """Reads a label volume (.nii, .nii.gz, .nrrd, .nhdr, .mha, .mhd, .hdr/.img).

    Floating-point samples must be integral. Raises :class:`InputError` for a file
    septa cannot use and :class:`FileNotFoundError` / :class:`OSError` for one it
    cannot read.
    """
    flat, dims, affine_lps = _septa.read_volume(os.fspath(path))
    nx, ny, nz = dims
    labels = np.asarray(flat).reshape((nz, ny, nx)).transpose(2, 1, 0)
    lps = _affine4(affine_lps)
    return Volume(labels=labels, affine_ras=_LPS_TO_RAS @ lps, affine_lps=lps)


@dataclass(frozen=True)
class Junction:
    """A curve where three or more labels meet: the label values, the vertex ids
    along it (into :attr:`Interfaces.vertices`), their positions, and whether it
    is a closed loop."""

    labels: Tuple[int, ...]
    vertex_ids: np.ndarray
    points: np.ndarray
    closed: bool


@dataclass(frozen=True)
class Surface:
    """A triangle mesh on its own vertices: ``vertices`` (N, 3) float64 and
    ``triangles`` (M, 3) int64."""

    vertices: np.ndarray
    triangles: np.ndarray

    def to_pyvista(self) -> Any:
        """The surface as a ``pyvista.PolyData`` (needs pyvista)."""
        return _polydata(self.vertices, self.triangles)


def _polydata(vertices: np.ndarray, triangles: np.ndarray) -> Any:
    try:
        import pyvista as pv
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError("to_pyvista() needs pyvista: pip install pyvista") from e
    faces = np.hstack([np.full((len(triangles), 1), 3, dtype=np.int64), triangles]).ravel()
    return pv.PolyData(np.asarray(vertices, dtype=np.float64), faces)


def _compact(vertices: np.ndarray, triangles: np.ndarray) -> Surface:
    used, inverse = np.unique(triangles.ravel(), return_inverse=True)
    return Surface(vertices=vertices[used], triangles=inverse.reshape(-1, 3).astype(np.int64))


class Interfaces:
    """The interface mesh between all labels of a volume (what :func:`extract` returns).

    Attributes:
        vertices: (N, 3) float64 positions in mm, in :attr:`space` (``"ras"`` or ``"lps"``).
        triangles: (M, 3) int64 vertex ids, counter-clockwise about the normal.
        labels: (M, 2) int64 label values of each triangle's patch; the normal points
            from ``labels[:, 0]`` into ``labels[:, 1]`` (``labels[:, 0] < labels[:, 1]``).
        patch: (M,) int64 patch id of each triangle (into :attr:`manifest` ``["patches"]``).
        junctions: the curves where three or more labels meet.
        quality: the remeshed mesh against the extraction (empty without remeshing).
        manifest: what ``manifest.json`` holds (input, parameters, labels, patches, timings).
        warnings: findings of the run that may change the result.
    """

    def __init__(self, native: Any, space: str) -> None:
        self._native = native
        self.space: str = space
        arrays = native.arrays()
        vertices = np.asarray(arrays["vertices"])
        if space == "ras":
            vertices = vertices * np.array([-1.0, -1.0, 1.0])
        self.vertices: np.ndarray = vertices
        self.triangles: np.ndarray = np.asarray(arrays["triangles"])
        self.labels: np.ndarray = np.asarray(arrays["labels"])
        self.patch: np.ndarray = np.asarray(arrays["patch"])
        self.manifest: Dict[str, Any] = json.loads(native.manifest_json())
        self.quality: Dict[str, Any] = self.manifest.get("quality") or {}
        self.warnings: List[str] = list(native.warnings())
        self.label_names: Dict[int, str] = dict(native.label_names())
        self.junctions: List[Junction] = [
            Junction(labels=tuple(ls), vertex_ids=np.asarray(ids), points=self.vertices[np.asarray(ids)], closed=closed)
            for ls, ids, closed in native.junctions()
        ]

    def __repr__(self) -> str:
        return (
            f"<septa.Interfaces: {len(self.vertices)} vertices, {len(self.triangles)} triangles, "
            f"{len(self.manifest['patches'])} patches, {len(self.junctions)} junctions, {self.space.upper()} mm>"
        )

    @property
    def passed(self) -> bool:
        """Whether every invariant holds (manifold patches, closed label surfaces, ...)."""
        return bool(self._native.passed())

    def label_surface(self, label: int) -> Surface:
        """The closed surface of one label (by value): every patch touching it,
        oriented outward (normals pointing away from the label)."""
        touches_a = self.labels[:, 0] == label
        touches_b = self.labels[:, 1] == label
        if not (touches_a.any() or touches_b.any()):
            raise ParameterError(f"label {label} has no patch (labels: {sorted(self.label_names)})")
        triangles = self.triangles.copy()
        # normals point from label_a into label_b: flip where the label is label_b
        triangles[touches_b] = triangles[touches_b][:, ::-1]
        return _compact(self.vertices, triangles[touches_a | touches_b])

    def patch_surface(self, a: int, b: int) -> Surface:
        """The patch between labels ``a`` and ``b`` (values, either order), oriented
        so that normals point from ``a`` into ``b``."""
        lo, hi = min(a, b), max(a, b)
        mask = (self.labels[:, 0] == lo) & (self.labels[:, 1] == hi)
        if not mask.any():
            raise ParameterError(f"labels {a} and {b} do not touch: there is no patch between them")
        triangles = self.triangles[mask]
        if a > b:
            triangles = triangles[:, ::-1]
        return _compact(self.vertices, triangles)

    def save(
        self,
        directory: PathLike,
        force: bool = False,
        formats: Sequence[str] = (),
    ) -> List[str]:
        """Writes the output directory as ``septa extract`` does (``interfaces.ply``,
        ``interfaces.vtp``, ``patches/``, ``junctions.ply``, ``junctions.vtp``,
        ``manifest.json``; ``formats`` adds ``"obj"`` and ``"stl"``), in :attr:`space`
        (the files' headers and the manifest say which).
        ``force`` replaces a directory septa wrote before. Returns the files written."""
        unknown = set(formats) - {"obj", "stl", "vtp"}
        if unknown:
            raise ParameterError(f"formats: unknown {sorted(unknown)} (use obj, stl)")
        return list(
            self._native.save(
                os.fspath(directory),
                force=force,
                obj="obj" in formats,
                stl="stl" in formats,
                space=self.space,
            )
        )

    def to_pyvista(self) -> Any:
        """The mesh as a ``pyvista.PolyData`` with cell arrays ``label_a``,
        ``label_b`` and ``patch`` (needs pyvista)."""
        mesh = _polydata(self.vertices, self.triangles)
        mesh.cell_data["label_a"] = self.labels[:, 0].astype(np.int32)
        mesh.cell_data["label_b"] = self.labels[:, 1].astype(np.int32)
        mesh.cell_data["patch"] = np.asarray(self.patch, dtype=np.int32)
        return mesh


# `patch(a, b)` as the issue and README name it; the attribute `patch` holds
# the per-triangle ids, so the method lives on a small callable array type.
class _PatchIds(np.ndarray):
    """Per-triangle patch ids; calling it with two label values gives that patch."""

    _owner: Optional[Interfaces] = None

    def __call__(self, a: int, b: int) -> Surface:
        if self._owner is None:
            raise TypeError("patch ids are not attached to a mesh")
        return self._owner.patch_surface(a, b)

    def __array_finalize__(self, obj: Any) -> None:
        self._owner = getattr(obj, "_owner", None)


def _attach_patch_ids(mesh: Interfaces) -> Interfaces:
    ids = np.asarray(mesh.patch).view(_PatchIds)
    ids._owner = mesh
    mesh.patch = ids
    return mesh


def _config_args(config: Union[None, PathLike, Mapping[str, Any]]) -> Dict[str, Optional[str]]:
    if config is None:
        return {"config_toml": None, "config_path": None}
    if isinstance(config, Mapping):
        text = _septa.config_json_to_toml(json.dumps(_stringify_keys(config)))
        return {"config_toml": text, "config_path": None}
    return {"config_toml": None, "config_path": os.fspath(config)}


def _stringify_keys(value: Any) -> Any:
    # TOML keys are strings: {"labels": {1: "lv"}} is {"labels": {"1": "lv"}}
    if isinstance(value, Mapping):
        return {str(k): _stringify_keys(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_stringify_keys(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def extract(
    labels: np.ndarray,
    affine: Optional[np.ndarray] = None,
    spacing: Optional[Sequence[float]] = None,
    config: Union[None, PathLike, Mapping[str, Any]] = None,
    target_edge: Optional[float] = None,
    remesh: Optional[bool] = None,
    space: str = "ras",
    *,
    affine_space: str = "ras",
    min_edge: Optional[float] = None,
    smooth_iterations: Optional[int] = None,
    max_displacement: Optional[float] = None,
    remesh_iterations: Optional[int] = None,
    surface: str = "vesta",
    decompose: str = "l",
    intersections: bool = False,
    max_memory: Optional[int] = None,
    progress: Optional[ProgressCallback] = None,
) -> Interfaces:
    """Extracts the interface mesh between all labels of ``labels``.

    Args:
        labels: an integer array of shape ``(nx, ny, nz)`` indexed ``[x, y, z]`` (as
            ``nibabel``'s ``img.dataobj``); integral floats are accepted.
        affine: 4×4 (or 3×4) voxel index → mm matrix; RAS as nibabel gives it
            (``img.affine``), or LPS with ``affine_space="lps"``. Default: ``spacing``.
        spacing: voxel spacing in mm when there is no affine (axes along L, P, S;
            default 1 mm).
        config: a config file (TOML, as for the command line) or the same as a dict,
            e.g. ``{"labels": {1: "lv"}, "outside": 0, "remesh": {"target_edge": 2.0}}``.
        target_edge: largest edge length of the remeshed mesh in mm (default: twice
            the mean spacing, or the config's).
        remesh: ``False`` keeps the extraction as it is (default: the config's, else True).
        space: coordinates of the returned vertices, ``"ras"`` (nibabel) or ``"lps"``
            (DICOM, ITK, 3D Slicer).
        progress: called as ``progress(event, stage, message)`` with event
            ``"started"``, ``"finished"`` or ``"warning"``.

    Raises:
        ParameterError, ConfigError, InputError: septa's message says what to change.
        InvariantError: the result violates septa's invariants (please report it).
    """
    space = _check_space(space)
    volume = np.asarray(labels)
    if volume.ndim != 3:
        raise InputError(f"labels: expected a 3-D array (nx, ny, nz), got shape {volume.shape}")
    if volume.dtype.kind == "f":
        rounded = np.rint(volume)
        if not np.array_equal(rounded, volume):
            raise InputError("labels: floating-point values must be integral (a label map, not an intensity image)")
        volume = rounded
    elif volume.dtype.kind not in "iub":
        raise InputError(f"labels: expected integers, got {volume.dtype}")
    volume = np.ascontiguousarray(volume, dtype=np.int64)
    if affine is not None and spacing is not None:
        raise ParameterError("give affine or spacing, not both")
    if affine is not None:
        a = np.asarray(affine, dtype=np.float64)
        if a.shape not in ((4, 4), (3, 4)):
            raise ParameterError(f"affine: expected a 4×4 or 3×4 matrix, got shape {a.shape}")
        a = _affine4(a[:3])
        if _check_space(affine_space) == "ras":
            a = _LPS_TO_RAS @ a
        affine_lps = a[:3].tolist()
    else:
        s = [1.0, 1.0, 1.0] if spacing is None else [float(x) for x in spacing]
        if len(s) != 3:
            raise ParameterError(f"spacing: expected 3 numbers, got {len(s)}")
        affine_lps = _septa.spacing_affine_lps(s, [0.0, 0.0, 0.0])
    native = _septa.extract(
        volume,
        affine_lps,
        remesh=remesh,
        target_edge=target_edge,
        min_edge=min_edge,
        smooth_iterations=smooth_iterations,
        max_displacement=max_displacement,
        iterations=remesh_iterations,
        surface=surface,
        decompose=decompose,
        intersections=intersections,
        max_memory=max_memory,
        progress=progress,
        **_config_args(config),
    )
    mesh = _attach_patch_ids(Interfaces(native, space))
    if not mesh.passed:
        raise InvariantError(
            "the output violates septa's invariants; please report this with the input volume:\n"
            + native.validation_summary()
        )
    return mesh


@dataclass(frozen=True)
class CheckResult:
    """The verdict of :func:`check`: ``passed`` and the validator's ``summary``."""

    passed: bool
    summary: str

    def __bool__(self) -> bool:
        return self.passed


def check(mesh: Union[PathLike, Interfaces]) -> CheckResult:
    """Validates a PLY file with ``label_a``/``label_b`` face properties (as septa
    writes ``interfaces.ply``) against septa's invariants, with the
    self-intersection test. An :class:`Interfaces` gives its own verdict."""
    if isinstance(mesh, Interfaces):
        return CheckResult(mesh.passed, mesh._native.validation_summary())
    passed, summary = _septa.check(os.fspath(mesh))
    return CheckResult(bool(passed), summary)
