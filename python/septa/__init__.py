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
    "iso",
    "hyper",
    "Hypersurface",
    "CheckReport",
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
        per_label: Sequence[str] = (),
    ) -> List[str]:
        """Writes the output directory as ``septa extract`` does (``interfaces.ply``,
        ``interfaces.vtp``, ``patches/``, ``junctions.ply``, ``junctions.vtp``,
        ``manifest.json``; ``formats`` adds ``"obj"`` and ``"stl"``), in :attr:`space`
        (the files' headers and the manifest say which). ``per_label`` (any of
        ``"stl"``, ``"obj"``, ``"ply"``, ``"vtp"``) writes each label's closed
        outward surface as ``labels/<name>.<ext>``, as ``--per-label`` does.
        ``force`` replaces a directory septa wrote before. Returns the files written."""
        if isinstance(formats, str) or isinstance(per_label, str):
            raise ParameterError("formats and per_label are lists, e.g. ['stl', 'ply']")
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
                per_label=list(per_label),
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
    merge_flat: bool = False,
    max_memory: Optional[int] = None,
    progress: Optional[ProgressCallback] = None,
    select: Optional[Sequence[Union[int, str]]] = None,
    others: Union[None, int, str] = None,
    label_names: Union[None, PathLike, Mapping[int, str]] = None,
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
        merge_flat: with ``remesh=False``: merge the flat stretches of each patch
            (staircase terraces) into large polygons, the same surface in fewer, longer
            triangles (as ``--merge-flat``); leave it off to smooth the mesh elsewhere.
        space: coordinates of the returned vertices, ``"ras"`` (nibabel) or ``"lps"``
            (DICOM, ITK, 3D Slicer).
        progress: called as ``progress(event, stage, message)`` with event
            ``"started"``, ``"finished"`` or ``"warning"``.
        select: mesh only these labels (values or names); every other label is
            merged into the outside label, or into ``others`` (as ``--labels`` and
            ``--others`` of the command line; ``labels`` is the volume here).
        others: with ``select``: the label the others become (value or name).
        label_names: names of labels, as a dict ``{1: "grey matter"}`` or a file
            (JSON, TOML, 3D Slicer colour table, ITK-SNAP label description; as
            ``--label-names``); they win over the config's ``[labels]``.

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
    if others is not None and select is None:
        raise ParameterError("others: give select too (others says what the unselected labels become)")
    if isinstance(select, (str, int, np.integer)):
        select = [select]
    names_args: Dict[str, Any] = {}
    if isinstance(label_names, Mapping):
        names_args["label_names"] = [(int(k), str(v)) for k, v in label_names.items()]
    elif label_names is not None:
        names_args["label_names_path"] = os.fspath(label_names)
    native = _septa.extract(
        volume,
        affine_lps,
        labels=None if select is None else [str(_label_ref(x)) for x in select],
        others=None if others is None else str(_label_ref(others)),
        **names_args,
        remesh=remesh,
        target_edge=target_edge,
        min_edge=min_edge,
        smooth_iterations=smooth_iterations,
        max_displacement=max_displacement,
        iterations=remesh_iterations,
        surface=surface,
        decompose=decompose,
        intersections=intersections,
        merge_flat=merge_flat,
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


def _label_ref(x: Union[int, str, np.integer]) -> Union[int, str]:
    if isinstance(x, (bool, np.bool_)):
        raise ParameterError(f"select: {x!r} is not a label value or name")
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, str):
        return x
    raise ParameterError(f"select: {x!r} is not a label value or name")


@dataclass(frozen=True)
class CheckResult:
    """The verdict of :func:`check` on a file: ``passed`` and the validator's ``summary``."""

    passed: bool
    summary: str

    def __bool__(self) -> bool:
        return self.passed


@dataclass(frozen=True)
class CheckReport:
    """The validator's report on a mesh in memory (what :func:`check` returns for
    arrays or an :class:`Interfaces`): ``passed``; ``failures``, the number of
    failing elements; ``failed``, the names of the checks that failed; ``checks``,
    every check as ``{"name", "failures", "examples"}``; ``labels``, the closed
    surface of each label (``value``, ``triangles``, ``components``,
    ``volume_mm3``, ``unbounded``); ``summary``, the text ``septa check`` prints.
    True when every invariant holds."""

    passed: bool
    failures: int
    checks: List[Dict[str, Any]]
    labels: List[Dict[str, Any]]
    summary: str

    @property
    def failed(self) -> List[str]:
        return [c["name"] for c in self.checks if c["failures"]]

    def __bool__(self) -> bool:
        return self.passed

    @staticmethod
    def _from_json(text: str) -> "CheckReport":
        j = json.loads(text)
        return CheckReport(
            passed=bool(j["passed"]),
            failures=int(j["failures"]),
            checks=list(j["checks"]),
            labels=list(j["labels"]),
            summary=j["summary"],
        )


def check(
    mesh: Union[PathLike, Interfaces, Surface, np.ndarray],
    triangles: Optional[np.ndarray] = None,
    labels: Optional[np.ndarray] = None,
    *,
    intersections: bool = True,
) -> Union[CheckResult, CheckReport]:
    """Validates a mesh against septa's invariants (with the self-intersection
    test unless ``intersections=False``).

    - ``check(path)``: a PLY file with ``label_a``/``label_b`` face properties (as
      septa writes ``interfaces.ply``); returns a :class:`CheckResult`.
    - ``check(mesh)`` with an :class:`Interfaces` (what :func:`extract` returns) or a
      :class:`Surface`, or ``check(vertices, triangles, labels=None)`` with arrays
      ((N, 3) float, (M, 3) int, optionally (M, 2) label values per triangle; without
      labels the triangles are checked as one closed surface): the mesh in memory,
      validated again; returns a :class:`CheckReport` with the failures.
    """
    if isinstance(mesh, Interfaces):
        vertices, triangles, labels = mesh.vertices, mesh.triangles, mesh.labels
        if mesh.space == "ras":
            vertices = vertices * np.array([-1.0, -1.0, 1.0])
    elif isinstance(mesh, Surface):
        vertices, triangles = mesh.vertices, mesh.triangles
    elif isinstance(mesh, (str, os.PathLike)):
        if triangles is not None or labels is not None:
            raise ParameterError("check(path) takes no arrays")
        passed, summary = _septa.check(os.fspath(mesh))
        return CheckResult(bool(passed), summary)
    else:
        vertices = mesh
        if triangles is None:
            raise ParameterError("check(vertices, triangles[, labels]): triangles are missing")
    v = np.ascontiguousarray(vertices, dtype=np.float64)
    t = np.asarray(triangles)
    if t.dtype.kind not in "iu":
        raise ParameterError(f"triangles: expected integers, got {t.dtype}")
    t = np.ascontiguousarray(t, dtype=np.int64)
    for name, a, cols in (("vertices", v, 3), ("triangles", t, 3)):
        if a.ndim != 2 or a.shape[1] != cols:
            raise ParameterError(f"{name}: expected shape (n, {cols}), got {a.shape}")
    lab = None
    if labels is not None:
        lab = np.ascontiguousarray(labels, dtype=np.int64)
        if lab.shape != (len(t), 2):
            raise ParameterError(f"labels: expected shape ({len(t)}, 2), got {lab.shape}")
    return CheckReport._from_json(_septa.check_arrays(v, t, lab, intersections=intersections))


def _geometry(
    affine: Optional[np.ndarray], spacing: Optional[Sequence[float]], affine_space: str
) -> List[List[float]]:
    """The 3×4 index → LPS affine from an affine (RAS or LPS) or a spacing."""
    if affine is not None and spacing is not None:
        raise ParameterError("give affine or spacing, not both")
    if affine is not None:
        a = np.asarray(affine, dtype=np.float64)
        if a.shape not in ((4, 4), (3, 4)):
            raise ParameterError(f"affine: expected a 4×4 or 3×4 matrix, got shape {a.shape}")
        a = _affine4(a[:3])
        if _check_space(affine_space) == "ras":
            a = _LPS_TO_RAS @ a
        return a[:3].tolist()
    s = [1.0, 1.0, 1.0] if spacing is None else [float(x) for x in spacing]
    if len(s) != 3:
        raise ParameterError(f"spacing: expected 3 numbers, got {len(s)}")
    return _septa.spacing_affine_lps(s, [0.0, 0.0, 0.0])


def _samples(values: Any, ndim: int, what: str) -> np.ndarray:
    a = np.asarray(values)
    if a.ndim != ndim:
        raise InputError(f"values: expected a {ndim}-D array {what}, got shape {a.shape}")
    if a.dtype.kind not in "iuf" and a.dtype.kind != "b":
        raise InputError(f"values: expected numbers, got {a.dtype}")
    if a.dtype not in (np.uint8, np.int16, np.uint16, np.int32, np.float32, np.float64):
        a = a.astype(np.float64)
    return a


def _surface_arrays(arrays: Dict[str, Any], space: str) -> Surface:
    vertices = np.asarray(arrays["vertices"])
    if space == "ras":
        vertices = vertices * np.array([-1.0, -1.0, 1.0])
    return Surface(vertices=vertices, triangles=np.asarray(arrays["triangles"]))


@dataclass(frozen=True)
class IsoSurface(Surface):
    """A VESTA iso-surface (what :func:`iso` returns): a closed, outward-oriented
    :class:`Surface` in :attr:`space`, and ``stats``, the N-cycle statistics and
    timing of ``septa iso --json``."""

    stats: Dict[str, Any] = None  # type: ignore[assignment]
    space: str = "ras"


def iso(
    volume: np.ndarray,
    iso: float,
    mode: str = "mixed",
    *,
    affine: Optional[np.ndarray] = None,
    spacing: Optional[Sequence[float]] = None,
    affine_space: str = "ras",
    space: str = "ras",
    decompose: str = "l",
    displace: bool = True,
) -> IsoSurface:
    """The VESTA iso-surface of a grayscale volume, as ``septa iso`` makes it: a
    closed, outward-oriented, hole-free triangle mesh around the voxels with value
    ≥ ``iso``.

    Args:
        volume: an ``(nx, ny, nz)`` array of any real dtype, indexed ``[x, y, z]``.
        iso: the iso value.
        mode: where two inside voxels share only an edge: ``"disconnect"`` keeps
            them apart, ``"connect"`` joins them, ``"mixed"`` joins them where the
            mean of the four voxels around the edge is ≥ iso.
        affine, spacing, affine_space, space: as for :func:`extract`.
        decompose: ``"l"`` (N − 2 triangles per N-cycle) or ``"h"`` (a fan around
            its centroid).
        displace: move the points to where linear interpolation meets ``iso``
            (``False``: voxel face centres).

    The work runs in Rust with the GIL released.
    """
    space = _check_space(space)
    a = _samples(volume, 3, "(nx, ny, nz)")
    affine_lps = _geometry(affine, spacing, affine_space)
    arrays, stats = _septa.iso(a, affine_lps, float(iso), mode=mode, decompose=decompose, displace=displace)
    s = _surface_arrays(arrays, space)
    return IsoSurface(vertices=s.vertices, triangles=s.triangles, stats=json.loads(stats), space=space)


class Hypersurface:
    """A STEVE iso-hypersurface of a 4-D volume (what :func:`hyper` returns).

    Attributes:
        points: (N, 4) float64: x, y, z in mm (in :attr:`space`) and t.
        tets: (M, 4) int64 oriented tetrahedra.
        kinds: (N,) uint8: 0 support point, 1 face centre, 2 volume centre.
        stats: counts and timing, as ``summary.json`` of ``septa hyper``.
    """

    def __init__(self, native: Any, space: str) -> None:
        self._native = native
        self.space: str = space
        points, tets, kinds = native.arrays()
        points = np.asarray(points)
        if space == "ras":
            points = points * np.array([-1.0, -1.0, 1.0, 1.0])
        self.points: np.ndarray = points
        self.tets: np.ndarray = np.asarray(tets)
        self.kinds: np.ndarray = np.asarray(kinds)
        self.stats: Dict[str, Any] = json.loads(native.stats_json())

    def __repr__(self) -> str:
        return f"<septa.Hypersurface: {len(self.points)} vertices, {len(self.tets)} tetrahedra>"

    @property
    def time_range(self) -> Optional[Tuple[float, float]]:
        """The times the hypersurface spans (``None`` when it is empty)."""
        r = self._native.time_range()
        return None if r is None else (float(r[0]), float(r[1]))

    def slice(self, time: float) -> Surface:
        """The closed, outward-oriented surface at ``time`` (frames × time step),
        checked by septa's validator (:class:`InvariantError` if it fails)."""
        arrays, _frame, report = self._native.slice(float(time))
        r = CheckReport._from_json(report)
        if not r.passed:
            raise InvariantError(f"the slice at t = {time} violates septa's invariants:\n{r.summary}")
        return _surface_arrays(arrays, self.space)

    def check(self) -> Dict[str, Any]:
        """The closed-3-manifold check of the tetrahedra (``passed``, ``manifold``
        and the counts of ``septa hyper``'s summary)."""
        return json.loads(self._native.check_json())


def hyper(
    volume: np.ndarray,
    iso: float,
    mode: str = "mixed",
    *,
    time_step: float = 1.0,
    affine: Optional[np.ndarray] = None,
    spacing: Optional[Sequence[float]] = None,
    affine_space: str = "ras",
    space: str = "ras",
    displace: bool = True,
) -> Hypersurface:
    """The STEVE iso-hypersurface of a 4-D volume, as ``septa hyper`` makes it: a
    closed, oriented hypersurface of tetrahedra in (x, y, z, t) around the toxels
    with value ≥ ``iso``; :meth:`Hypersurface.slice` cuts it into the closed surface
    at any time.

    Args:
        volume: an ``(nx, ny, nz, nt)`` array of any real dtype, indexed ``[x, y, z, t]``
            (as nibabel gives a 4-D NIfTI).
        iso: the iso value.
        mode: where two inside toxels share only a face: ``"disconnect"``,
            ``"connect"`` or ``"mixed"`` (joined where the mean of the four toxels
            around it is ≥ iso).
        time_step: time between frames.
        affine, spacing, affine_space, space: the spatial geometry, as for :func:`extract`.
        displace: move the points to the interpolated iso value.
    """
    space = _check_space(space)
    a = _samples(volume, 4, "(nx, ny, nz, nt)")
    affine_lps = _geometry(affine, spacing, affine_space)
    native = _septa.hyper(a, affine_lps, float(iso), time_step=float(time_step), mode=mode, displace=displace)
    return Hypersurface(native, space)
