"""Reconstructor, Mesh, Implicit and reconstruct(): psr's C API in NumPy terms."""

from __future__ import annotations

import ctypes
import math
import operator
import os
import threading
import weakref
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from enum import IntEnum
from typing import Any, Generic, TypeVar, Union, overload

import numpy as np

from . import _arrays
from ._errors import (
    InvalidArgumentError,
    InvalidParameterError,
    Status,
    error_for,
)
from ._lib import (
    LIB,
    PROGRESS_FN,
    DepthSolve,
    OutOfCoreNoiseStruct,
    OutOfCoreReportStruct,
    PointArrays,
    TrimOptions,
)
from ._ply import PathLike

__all__ = [
    "Stage",
    "Boundary",
    "Splatting",
    "VertexPlacement",
    "Orientation",
    "TrimThreshold",
    "DepthSolve",
    "Reconstructor",
    "Mesh",
    "Implicit",
    "SolveStats",
    "OutOfCoreReport",
    "ProgressCallback",
    "reconstruct",
    "reconstruct_out_of_core",
]


class Stage(IntEnum):
    """psr_stage: the pipeline stages reported to a progress callback (``str()`` of one is its
    short name, e.g. ``"solve"``)."""

    POINTS = 0
    DENSITY = 1
    OCTREE = 2
    SPLAT = 3
    SYSTEM = 4
    SOLVE = 5
    ISOVALUE = 6
    EXTRACT = 7
    MESH = 8
    NORMALS = 9
    TRIM = 10

    def __str__(self) -> str:
        name: bytes = LIB.psr_stage_string(int(self))
        return name.decode()


class Boundary(IntEnum):
    """psr_boundary: boundary conditions at the bounding cube (PoissonRecon --bType 3, 1, 2)."""

    NEUMANN = 0
    FREE = 1
    DIRICHLET = 2


class Splatting(IntEnum):
    """psr_splatting: the normals' splatting weights."""

    BSPLINE = 0
    TRILINEAR = 1


class VertexPlacement(IntEnum):
    """psr_vertex_placement: where the mesh's vertices go."""

    FITTED = 0
    ON_ISOSURFACE = 1


class Orientation(IntEnum):
    """psr_orientation: how estimated normals get their signs."""

    PROPAGATE = 0
    VIEWPOINT = 1
    SENSORS = 2
    RECONSTRUCTION = 3


class TrimThreshold(IntEnum):
    """psr_trim_threshold: what ``threshold_value`` of :meth:`Mesh.trim` means."""

    AUTOMATIC = 0
    DENSITY = 1
    QUANTILE = 2
    DEPTH = 3


#: A progress callback: called with the stage and the fraction of it done (0 to 1); returning
#: ``False`` cancels the reconstruction (:class:`psr.CancelledError`), anything else goes on.
ProgressCallback = Callable[[Stage, float], Any]
#: An enum parameter: the enum, its int value or its name in any case (``"dirichlet"``).
E = TypeVar("E", bound=IntEnum)
EnumLike = Union[E, int, str]

_UINT32_MAX = 2**32 - 1
_UINT64_MAX = 2**64 - 1
_INT32_MIN, _INT32_MAX = -(2**31), 2**31 - 1


def _last_error(handle: ctypes.c_void_p) -> str:
    message: bytes = LIB.psr_reconstructor_last_error(handle)
    return message.decode(errors="replace")


def _check(status: int, handle: ctypes.c_void_p | None = None, message: str = "") -> None:
    if status != Status.OK:
        if handle is not None and not message:
            message = _last_error(handle)
        raise error_for(status, message)


def _integer(name: str, value: Any, low: int, high: int) -> int:
    """An integer parameter in the C type's range (psr checks the parameter's own range)."""
    if isinstance(value, bool):
        raise TypeError(f"{name} must be an integer, not a bool")
    try:
        v = operator.index(value)
    except TypeError:
        raise TypeError(f"{name} must be an integer, not {type(value).__name__}") from None
    if not low <= v <= high:
        raise InvalidParameterError(
            Status.INVALID_PARAMETER, f"{name} = {v} is outside the C type's range [{low}, {high}]"
        )
    return v


def _real(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name} must be a real number, not {type(value).__name__}")
    return float(value)


def _enum(kind: type[E], name: str, value: Any) -> E:
    if isinstance(value, str):
        try:
            return kind[value.upper()]
        except KeyError:
            names = ", ".join(m.name.lower() for m in kind)
            raise InvalidParameterError(
                Status.INVALID_PARAMETER, f"{name} = {value!r}: not one of {names}"
            ) from None
    v = _integer(name, value, _INT32_MIN, _INT32_MAX)
    try:
        return kind(v)
    except ValueError:
        # psr gives the message for an unknown value; pass it on as an int.
        return v  # type: ignore[return-value]


T = TypeVar("T")


class _Param(Generic[T]):
    """A parameter of the reconstructor: reads and writes go to psr's getter and setter."""

    def __init__(
        self,
        ctype: Any,
        to_c: Callable[[str, Any], Any],
        from_c: Callable[[Any], T],
        doc: str,
    ) -> None:
        self.ctype = ctype
        self.to_c = to_c
        self.from_c = from_c
        self.__doc__ = doc
        self.name = ""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name
        self.getter = getattr(LIB, f"psr_reconstructor_get_{name}")
        self.setter = getattr(LIB, f"psr_reconstructor_set_{name}")

    @overload
    def __get__(self, obj: None, owner: type) -> _Param[T]: ...

    @overload
    def __get__(self, obj: Reconstructor, owner: type) -> T: ...

    def __get__(self, obj: Reconstructor | None, owner: type) -> _Param[T] | T:
        if obj is None:
            return self
        out = self.ctype()
        with obj._lock:
            handle = obj._live()
            _check(self.getter(handle, ctypes.byref(out)), handle)
        return self.from_c(out.value)

    def __set__(self, obj: Reconstructor, value: T) -> None:
        c_value = self.to_c(self.name, value)
        with obj._lock:
            handle = obj._live()
            _check(self.setter(handle, c_value), handle)


def _u32(name: str, v: Any) -> int:
    return _integer(name, v, 0, _UINT32_MAX)


def _u64(name: str, v: Any) -> int:
    return _integer(name, v, 0, _UINT64_MAX)


def _i32(name: str, v: Any) -> int:
    return _integer(name, v, _INT32_MIN, _INT32_MAX)


def _enum_param(kind: type[E]) -> Callable[[str, Any], int]:
    return lambda name, v: int(_enum(kind, name, v))


def _enum_value(kind: type[E]) -> Callable[[int], E]:
    def convert(v: int) -> E:
        return kind(v)

    return convert


def _bool(name: str, v: Any) -> bool:
    if not isinstance(v, (bool, np.bool_)):
        raise TypeError(f"{name} must be a bool, not {type(v).__name__}")
    return bool(v)


#: Every parameter of the C API with its default (psr_reconstructor_new's), in the order the
#: constructors apply them.
DEFAULTS: dict[str, Any] = {
    "depth": 8,
    "width": 0.0,
    "full_depth": 5,
    "kernel_depth": -1,
    "samples_per_node": 1.5,
    "scale": 1.1,
    "degree": 2,
    "point_weight": 4.0,
    "screening_follows_noise": True,
    "threads": 0,
    "max_solver_iterations": 60,
    "solver_tolerance": 1e-2,
    "boundary": Boundary.NEUMANN,
    "splatting": Splatting.BSPLINE,
    "vertex_placement": VertexPlacement.FITTED,
    "min_component_samples": 8,
    "max_memory": 0,
    "vertex_normals": False,
    "normal_neighbors": 20,
    "normal_orientation": Orientation.PROPAGATE,
    "normal_reconstruction_iterations": 10,
}


@dataclass(frozen=True)
class SolveStats:
    """How one depth's linear solve ended (psr_depth_solve)."""

    depth: int
    iterations: int
    unknowns: int
    relative_residual: float
    seconds: float


@dataclass(frozen=True)
class OutOfCoreReport:
    """What a reconstruction out of core did (psr_out_of_core_report):
    :meth:`Reconstructor.solve_file_out_of_core` and :func:`reconstruct_out_of_core`."""

    #: Points read from the input file.
    points: int
    #: Vertices written to the output file.
    vertices: int
    #: Triangles written to the output file.
    triangles: int
    #: Slabs the cloud was cut into.
    slabs: int
    #: The depth used (the one ``width`` chose, if set).
    depth: int
    #: The points had colours or other properties, which this path does not carry.
    attributes_dropped: bool
    #: Closed pieces left out for want of supporting samples (``min_component_samples``).
    unsupported_components: int
    #: The isovalue the surface was extracted at.
    isovalue: float
    #: Seconds the run took.
    seconds: float
    #: The samples' positional noise sigma in input units as the slabs estimated it (the
    #: in-memory :attr:`Mesh.sample_noise` of the same cloud), or None when the screening did
    #: not follow it (``screening_follows_noise=False``).
    sample_noise: float | None
    #: The noise's depth s of the screening weight (:attr:`Mesh.screening_depth`).
    screening_depth: float
    #: Cells of the noise estimate wider than their slab's padding, fitted from the samples
    #: within it (0 unless the median sample lies far coarser than the slabs' walls).
    noise_cells_beyond_padding: int


class _SolveState:
    """What a solve's progress trampoline, its worker thread and its caller share."""

    def __init__(self, progress: ProgressCallback | None) -> None:
        self.progress = progress
        self.interrupted = False  # set by the caller on Ctrl-C: the next report says stop
        self.error: BaseException | None = None  # raised by the progress callback
        self.failure: BaseException | None = None  # raised around the C call
        self.status = int(Status.OK)
        self.message = ""
        self.mesh_ptr = ctypes.c_void_p()
        self.implicit_ptr = ctypes.c_void_p()
        self.done = threading.Event()
        self.mutex = threading.Lock()
        self.abandoned = False  # the caller left: the worker frees what psr made

    def free_results(self) -> None:
        LIB.psr_mesh_free(self.mesh_ptr)
        LIB.psr_implicit_free(self.implicit_ptr)
        self.mesh_ptr = ctypes.c_void_p()
        self.implicit_ptr = ctypes.c_void_p()

    def on_progress(self, _user: Any, stage: int, fraction: float) -> bool:
        # Called from inside psr_reconstructor_solve on the solving thread; False stops psr.
        if self.interrupted or self.error is not None:
            return False
        if self.progress is None:
            return True
        try:
            try:
                s: Stage | int = Stage(stage)
            except ValueError:
                s = stage
            go_on = self.progress(s, float(fraction))  # type: ignore[arg-type]
        except BaseException as e:  # noqa: BLE001 - re-raised by solve() on the caller's side
            self.error = e
            return False
        return go_on is None or bool(go_on)


def _tqdm_progress() -> tuple[ProgressCallback, Callable[[], None]]:
    """A progress callback drawing a tqdm bar per reconstruction, and the function closing it."""
    try:
        from tqdm.auto import tqdm
    except ImportError:
        raise ImportError(
            'progress="tqdm" needs the tqdm package: pip install tqdm (or pass a callback)'
        ) from None
    bar = tqdm(total=1000, unit="‰", leave=False, bar_format="{desc}: {percentage:3.0f}%|{bar}|")
    current = [-1]

    def update(stage: Stage, fraction: float) -> bool:
        if stage != current[0]:
            current[0] = stage
            bar.set_description_str(f"psr {stage}")
        bar.n = int(1000 * min(max(fraction, 0.0), 1.0))
        bar.refresh()
        return True

    return update, bar.close


class Reconstructor:
    """A reusable reconstruction (psr_reconstructor): parameters, points added in batches, and
    :meth:`solve`, which may be called again with other parameters or after
    :meth:`clear_points` and new points.

    Every parameter of the C API is a keyword argument of the constructor and a property with
    the same name, default and range; setting one out of range raises
    :class:`psr.InvalidParameterError` and leaves the old value. The object is safe to share
    between threads (calls on one reconstructor take turns); different reconstructors solve
    concurrently, each with its own worker threads, and the GIL is released while psr runs.
    """

    depth = _Param[int](ctypes.c_uint32, _u32, int, "Maximum octree depth, 1 to 16 (default 8).")
    width = _Param[float](
        ctypes.c_double,
        _real,
        float,
        "Target width of the finest cells in input units; chooses the depth instead when > 0 "
        "(default 0: off).",
    )
    full_depth = _Param[int](
        ctypes.c_uint32,
        _u32,
        int,
        "Depth down to which the octree is complete, 0 to 16 (default 5).",
    )
    kernel_depth = _Param[int](
        ctypes.c_int32,
        _i32,
        int,
        "Depth of the sampling density estimate; -1 (default) is automatic: depth - 2.",
    )
    samples_per_node = _Param[float](
        ctypes.c_float, _real, float, "Target samples per octree node, 1 to 1e6 (default 1.5)."
    )
    scale = _Param[float](
        ctypes.c_float,
        _real,
        float,
        "Ratio of the reconstruction cube to the points' bounding box, 1 to 100 (default 1.1).",
    )
    degree = _Param[int](
        ctypes.c_int32,
        _i32,
        int,
        "B-spline degree of the node functions, 2 (default) or 1 (PoissonRecon's --degree 1); "
        "setting it also sets point_weight to 2 x degree.",
    )
    point_weight = _Param[float](
        ctypes.c_float,
        _real,
        float,
        "Screening weight alpha, 0 (the 2006 method) to 1e6 (default 2 x degree: 4). Scaled by "
        "2^depth, and at the depths finer than the samples' noise supports by that depth's "
        "2^s (screening_follows_noise, on by default).",
    )
    threads = _Param[int](
        ctypes.c_uint32, _u32, int, "Worker threads of a solve; 0 (default) is one per core."
    )
    max_solver_iterations = _Param[int](
        ctypes.c_uint32,
        _u32,
        int,
        "Most conjugate-gradient iterations per depth, 1 to 10000 (default 60).",
    )
    solver_tolerance = _Param[float](
        ctypes.c_double,
        _real,
        float,
        "Relative residual at which a depth's solve stops, 1e-12 to 1 (default 1e-2).",
    )
    boundary = _Param[Boundary](
        ctypes.c_int32,
        _enum_param(Boundary),
        _enum_value(Boundary),
        "Boundary condition: Boundary.NEUMANN (default), FREE or DIRICHLET (for open scans).",
    )
    splatting = _Param[Splatting](
        ctypes.c_int32,
        _enum_param(Splatting),
        _enum_value(Splatting),
        "Splatting weights: Splatting.BSPLINE (default) or TRILINEAR.",
    )
    vertex_placement = _Param[VertexPlacement](
        ctypes.c_int32,
        _enum_param(VertexPlacement),
        _enum_value(VertexPlacement),
        "Where vertices go: VertexPlacement.FITTED (default) or ON_ISOSURFACE.",
    )
    min_component_samples = _Param[int](
        ctypes.c_uint32,
        _u32,
        int,
        "Fewest samples a closed component needs to stay in the mesh (default 8; 0 keeps all).",
    )
    max_memory = _Param[int](
        ctypes.c_uint64,
        _u64,
        int,
        "The most memory a solve may use, in bytes; 0 (default) means no limit. psr checks its "
        "accounting of the big arrays against it before allocating them, and a solve that would "
        "need more raises OutOfMemoryError (the reconstructor stays usable). See "
        "estimate_memory().",
    )
    vertex_normals = _Param[bool](
        ctypes.c_bool, _bool, bool, "Whether the mesh gets unit vertex normals (default False)."
    )
    screening_follows_noise = _Param[bool](
        ctypes.c_bool,
        _bool,
        bool,
        "Whether the screening follows the samples' noise (default True): psr estimates their "
        "scatter sigma across the surface (Mesh.sample_noise) and pulls the depths finer than "
        "the one whose cells are 10 sigma wide (Mesh.screening_depth, s) with alpha 2^s instead "
        "of alpha 2^depth, so that a high depth does not pull the surface onto the noise; "
        "exact samples keep 2^depth, and so do clouds too sparse for the estimate to resolve "
        "the surface (it reads no noise there). Out of core "
        "the slabs estimate the same sigma from their parts. False keeps 2^depth at any noise "
        "(PoissonRecon's scale: on noisy scans the surface then follows the noise more with "
        "every depth past the samples').",
    )
    normal_neighbors = _Param[int](
        ctypes.c_uint32,
        _u32,
        int,
        "Neighbours fitting each estimated normal, 1 to 1000 (default 20).",
    )
    normal_orientation = _Param[Orientation](
        ctypes.c_int32,
        _enum_param(Orientation),
        _enum_value(Orientation),
        "How estimated normals get their signs: Orientation.PROPAGATE (default), VIEWPOINT "
        "(set viewpoint first), SENSORS or RECONSTRUCTION (read off a mesh reconstructed from "
        "the normals themselves, in rounds coarse to fine: holds at folds and on sparse clouds "
        "where propagation fails, at the cost of a few reconstructions per depth).",
    )
    normal_reconstruction_iterations = _Param[int](
        ctypes.c_uint32,
        _u32,
        int,
        "The most rounds Orientation.RECONSTRUCTION runs at each depth, 1 to 1000 (default 10).",
    )

    def __init__(
        self,
        *,
        depth: int = 8,
        width: float = 0.0,
        full_depth: int = 5,
        kernel_depth: int = -1,
        samples_per_node: float = 1.5,
        scale: float = 1.1,
        degree: int = 2,
        point_weight: float | None = None,
        screening_follows_noise: bool = True,
        threads: int = 0,
        max_solver_iterations: int = 60,
        solver_tolerance: float = 1e-2,
        boundary: EnumLike[Boundary] = Boundary.NEUMANN,
        splatting: EnumLike[Splatting] = Splatting.BSPLINE,
        vertex_placement: EnumLike[VertexPlacement] = VertexPlacement.FITTED,
        min_component_samples: int = 8,
        max_memory: int = 0,
        vertex_normals: bool = False,
        normal_neighbors: int = 20,
        normal_orientation: EnumLike[Orientation] = Orientation.PROPAGATE,
        normal_reconstruction_iterations: int = 10,
        viewpoint: Sequence[float] | None = None,
        progress: ProgressCallback | str | None = None,
    ) -> None:
        """Creates a reconstructor (psr_reconstructor_new) and sets the parameters given; see
        the properties of the same names. ``viewpoint`` (x, y, z) is where normals estimated for
        points added without normals face (it selects Orientation.VIEWPOINT).
        ``progress``: a default progress callback for :meth:`solve`, or ``"tqdm"``."""
        self._lock = threading.RLock()
        self._close_pending = False
        self._double = False
        self._viewpoint: tuple[float, float, float] | None = None
        self.progress = progress
        handle = ctypes.c_void_p()
        _check(LIB.psr_reconstructor_new(ctypes.byref(handle)))
        self._handle: ctypes.c_void_p | None = handle
        self._finalizer = weakref.finalize(self, LIB.psr_reconstructor_free, handle)
        # Not at exit: the process's memory goes anyway, and a solve abandoned after Ctrl-C may
        # still be using the handle on its worker thread.
        self._finalizer.atexit = False
        self.depth = depth
        self.width = width
        self.full_depth = full_depth
        self.kernel_depth = kernel_depth
        self.samples_per_node = samples_per_node
        self.scale = scale
        self.degree = degree  # (sets point_weight to 2 x degree)
        if point_weight is not None:
            self.point_weight = point_weight
        self.screening_follows_noise = screening_follows_noise
        self.threads = threads
        self.max_solver_iterations = max_solver_iterations
        self.solver_tolerance = solver_tolerance
        self.boundary = boundary  # type: ignore[assignment]
        self.splatting = splatting  # type: ignore[assignment]
        self.vertex_placement = vertex_placement  # type: ignore[assignment]
        self.min_component_samples = min_component_samples
        self.max_memory = max_memory
        self.vertex_normals = vertex_normals
        self.normal_neighbors = normal_neighbors
        self.normal_reconstruction_iterations = normal_reconstruction_iterations
        if viewpoint is not None:
            self.viewpoint = viewpoint
        orientation = _enum(Orientation, "normal_orientation", normal_orientation)
        if viewpoint is None or orientation != Orientation.PROPAGATE:
            self.normal_orientation = orientation

    # --- the handle ----------------------------------------------------------------------------

    def _live(self) -> ctypes.c_void_p:
        if self._handle is None:
            raise ValueError("this Reconstructor was closed")
        return self._handle

    def close(self) -> None:
        """Frees the reconstructor (psr_reconstructor_free) now rather than when it is
        collected; if another thread is using it (such as a solve left running after Ctrl-C),
        as soon as that call ends. Meshes it made stay valid."""
        self._close_pending = True
        if self._lock.acquire(blocking=False):
            try:
                self._release()
            finally:
                self._lock.release()

    def _release(self) -> None:
        """Frees the handle if close() asked for it; called with the lock held."""
        if self._close_pending:
            self._handle = None
            self._finalizer()

    def __enter__(self) -> Reconstructor:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        if self._handle is None:
            return "<psr.Reconstructor (closed)>"
        params = ", ".join(f"{k}={getattr(self, k)!r}" for k in DEFAULTS)
        return f"<psr.Reconstructor {len(self)} points, {params}>"

    # --- parameters without a getter in C --------------------------------------------------------

    @property
    def viewpoint(self) -> tuple[float, float, float] | None:
        """The viewpoint estimated normals face (psr_reconstructor_set_viewpoint), or None when
        none was set. Setting it selects Orientation.VIEWPOINT."""
        return self._viewpoint

    @viewpoint.setter
    def viewpoint(self, xyz: Sequence[float]) -> None:
        v = _arrays.rows("viewpoint", np.asarray(xyz, dtype=np.float64).reshape(1, -1), 3, 1)
        x, y, z = (float(c) for c in v[0])
        with self._lock:
            handle = self._live()
            _check(LIB.psr_reconstructor_set_viewpoint(handle, x, y, z), handle)
        self._viewpoint = (x, y, z)

    def parameters(self) -> dict[str, Any]:
        """Every parameter's current value, by name (as the getters give them)."""
        values = {name: getattr(self, name) for name in DEFAULTS}
        values["viewpoint"] = self.viewpoint
        return values

    # --- points ----------------------------------------------------------------------------------

    def __len__(self) -> int:
        out = ctypes.c_size_t()
        with self._lock:
            handle = self._live()
            _check(LIB.psr_reconstructor_point_count(handle, ctypes.byref(out)), handle)
        return out.value

    @property
    def point_count(self) -> int:
        """Points added so far (with and without normals)."""
        return len(self)

    def estimate_memory(self) -> int:
        """The memory, in bytes, a solve of the points added so far with these parameters is
        estimated to need at its peak (psr_reconstructor_estimate_memory), computed before
        solving from the point count and the depth. An upper bound for scanned surfaces:
        1.8-2.5 times the measured peak on the bunny and Happy Buddha scans at depths 9-12.
        Setting ``max_memory`` to it lets that solve through."""
        out = ctypes.c_uint64()
        with self._lock:
            handle = self._live()
            _check(LIB.psr_reconstructor_estimate_memory(handle, ctypes.byref(out)), handle)
        return int(out.value)

    def clear_points(self) -> None:
        """Removes every point (parameters and the progress callback stay)."""
        with self._lock:
            handle = self._live()
            _check(LIB.psr_reconstructor_clear_points(handle), handle)
            self._double = False

    def add_points(
        self,
        points: Any,
        normals: Any = None,
        *,
        confidence: Any = None,
        colors: Any = None,
        channels: Mapping[str, Any] | None = None,
        sensor: Sequence[float] | None = None,
        sensors: Any = None,
        transform: Any = None,
    ) -> None:
        """Appends a batch of points; psr copies them, so the arrays may change afterwards.

        ``points``: shape (n, 3), any real dtype and strides; float32 rows with adjacent x y z
        are read in place, float64 ones too (psr keeps them in double: the mesh then has
        float64 vertices in the input's coordinates, for scans far from the origin); other
        layouts are copied. An Open3D ``PointCloud`` or a :class:`psr.PointCloud` is taken
        whole (its normals and colours unless given here; a psr.PointCloud without normals
        also gives its sensor positions when ``normal_orientation`` is SENSORS, as the psr
        program's ``--orientation sensors`` reads them from the file).

        ``normals``: shape (n, 3), any length but zero; None to have psr estimate and orient
        them (see ``normal_neighbors``, ``normal_orientation``, ``viewpoint``), then optionally
        with one ``sensor`` (x, y, z) the points were seen from or ``sensors`` (n, 3), one per
        point.

        With normals, optionally: ``confidence`` (n,) weights >= 0; ``colors`` (n, 3) or
        (n, 4), any scale; ``channels``, a mapping of names to (n,) values carried onto the
        mesh's vertices; ``transform``, a 4x4 affine matrix (row-major) applied to the batch.

        A bad batch (a NaN, a zero normal, a wrong shape, lengths that differ) raises a
        :class:`psr.PsrError` subclass (a ValueError) naming the first bad index, and nothing of
        it is added; earlier batches stay.
        """
        from ._ply import PointCloud

        if (
            isinstance(points, PointCloud)
            and normals is None
            and points.normals is None
            and sensor is None
            and sensors is None
            and self.normal_orientation == Orientation.SENSORS
        ):
            sensors = points.sensors
        points, normals, colors, confidence, channels = _unpack_cloud(
            points, normals, colors, confidence, channels
        )
        p = _arrays.rows("points", points, 3)
        n = p.shape[0]
        if normals is None:
            for name, value in (
                ("confidence", confidence),
                ("colors", colors),
                ("channels", channels),
                ("transform", transform),
            ):
                if value is not None:
                    raise InvalidArgumentError(
                        Status.INVALID_ARGUMENT,
                        f"{name} needs normals: points without normals carry no attributes",
                    )
            self._add_positions(p, sensor, sensors)
            return
        if sensor is not None or sensors is not None:
            raise InvalidArgumentError(
                Status.INVALID_ARGUMENT, "sensor and sensors are for points without normals"
            )
        nrm = _arrays.rows("normals", normals, 3, n)
        normals_c, normal_stride = _arrays.as_c_rows(nrm, np.float32)
        if confidence is not None or colors is not None or channels:
            if transform is not None:
                raise InvalidArgumentError(
                    Status.INVALID_ARGUMENT,
                    "transform cannot be combined with confidence, colors or channels "
                    "(the C API has no such entry point): transform the points first",
                )
            self._add_arrays(p, normals_c, normal_stride, confidence, colors, channels)
            return
        with self._lock:
            handle = self._live()
            if transform is not None:
                m = np.ascontiguousarray(np.asarray(transform, dtype=np.float64))
                if m.shape != (4, 4):
                    raise InvalidArgumentError(
                        Status.INVALID_ARGUMENT, f"transform must have shape (4, 4), not {m.shape}"
                    )
                pos, stride = _arrays.as_c_rows(p, np.float64)
                status = LIB.psr_reconstructor_add_points_transformed(
                    handle,
                    pos.ctypes.data,
                    stride,
                    normals_c.ctypes.data,
                    normal_stride,
                    n,
                    m.ctypes.data,
                )
                double = True
            elif _arrays.is_double(p):
                pos, stride = _arrays.as_c_rows(p, np.float64)
                status = LIB.psr_reconstructor_add_points_f64(
                    handle, pos.ctypes.data, stride, normals_c.ctypes.data, normal_stride, n
                )
                double = True
            else:
                pos, stride = _arrays.as_c_rows(p, np.float32)
                status = LIB.psr_reconstructor_add_points(
                    handle, pos.ctypes.data, stride, normals_c.ctypes.data, normal_stride, n
                )
                double = False
            _check(status, handle)
            self._double = self._double or (double and n > 0)

    def _add_positions(self, p: np.ndarray, sensor: Any, sensors: Any) -> None:
        n = p.shape[0]
        pos, stride = _arrays.as_c_rows(p, np.float32)
        with self._lock:
            handle = self._live()
            if sensor is not None and sensors is not None:
                raise InvalidArgumentError(
                    Status.INVALID_ARGUMENT, "give one sensor or per-point sensors, not both"
                )
            if sensor is not None:
                s = np.ascontiguousarray(np.asarray(sensor, dtype=np.float32).reshape(1, -1))
                _arrays.rows("sensor", s, 3, 1)
                status = LIB.psr_reconstructor_add_positions_seen_from(
                    handle, pos.ctypes.data, stride, n, s.ctypes.data
                )
            elif sensors is not None:
                sc, sensor_stride = _arrays.as_c_rows(
                    _arrays.rows("sensors", sensors, 3, n), np.float32
                )
                status = LIB.psr_reconstructor_add_positions_with_sensors(
                    handle, pos.ctypes.data, stride, sc.ctypes.data, sensor_stride, n
                )
            else:
                status = LIB.psr_reconstructor_add_positions(handle, pos.ctypes.data, stride, n)
            _check(status, handle)

    def _add_arrays(
        self,
        p: np.ndarray,
        normals_c: np.ndarray,
        normal_stride: int,
        confidence: Any,
        colors: Any,
        channels: Mapping[str, Any] | None,
    ) -> None:
        n = p.shape[0]
        a = PointArrays()
        _check(LIB.psr_point_arrays_init(ctypes.byref(a), ctypes.sizeof(a)))
        keep: list[Any] = []  # every buffer psr reads, alive until the call returns

        def put(arr: np.ndarray, stride: int) -> tuple[int, int]:
            keep.append(arr)
            return arr.ctypes.data, stride

        pos, stride = _arrays.as_c_rows(p, np.float32)
        a.count = n
        a.positions, a.position_stride_bytes = put(pos, stride)
        a.normals, a.normal_stride_bytes = put(normals_c, normal_stride)
        if confidence is not None:
            w, ws = _arrays.as_c_rows(_arrays.rows("confidence", confidence, 1, n), np.float32)
            a.confidence, a.confidence_stride_bytes = put(w, ws)
        if colors is not None:
            c = np.asarray(colors)
            width = c.shape[1] if c.ndim == 2 and c.shape[1] in (3, 4) else 3
            cc, cs = _arrays.as_c_rows(_arrays.rows("colors", c, width, n), np.float32)
            a.colors, a.color_stride_bytes = put(cc, cs)
            a.color_components = width
        if channels:
            names = list(channels)
            for name in names:
                if not isinstance(name, str):
                    raise TypeError(f"channel names must be str, not {type(name).__name__}")
            columns = [_arrays.rows(f"channels[{k!r}]", channels[k], 1, n) for k in names]
            values = np.ascontiguousarray(np.hstack(columns), dtype=np.float32)
            a.channels, a.channel_stride_bytes = put(values, 4 * len(names))
            a.channel_count = len(names)
            encoded = [k.encode() for k in names]
            c_names = (ctypes.c_char_p * len(names))(*encoded)
            keep.append(c_names)
            a.channel_names = ctypes.cast(c_names, ctypes.POINTER(ctypes.c_char_p))
        with self._lock:
            handle = self._live()
            _check(LIB.psr_reconstructor_add_point_arrays(handle, ctypes.byref(a)), handle)

    # --- solving ---------------------------------------------------------------------------------

    def solve(
        self,
        *,
        progress: ProgressCallback | str | None = None,
        keep_implicit: bool = False,
    ) -> Mesh:
        """Reconstructs a watertight mesh from the points added so far
        (psr_reconstructor_solve); the points and parameters stay for another solve.

        ``progress`` (or the constructor's): a callable ``(stage, fraction)`` called as the
        stages advance; returning ``False`` cancels with :class:`psr.CancelledError`, and an
        exception it raises cancels too and propagates from here. ``"tqdm"`` shows a tqdm bar
        (tqdm must be installed). ``keep_implicit=True`` keeps the solved indicator function as
        ``mesh.implicit`` (:class:`Implicit`).

        The GIL is released while psr runs. Called from the main thread, the solve runs on a
        worker thread (where the progress callback is then called) while the main thread waits,
        so that Ctrl-C raises KeyboardInterrupt at once: psr is told to stop at its next
        progress report, and if it has not stopped within 0.2 s it is left to finish
        in the background (its results are freed) while the exception propagates. From other
        threads the solve runs on the calling thread.
        """

        def call(handle: ctypes.c_void_p, state: _SolveState) -> int:
            if keep_implicit:
                status: int = LIB.psr_reconstructor_solve_implicit(
                    handle, ctypes.byref(state.mesh_ptr), ctypes.byref(state.implicit_ptr)
                )
            else:
                status = LIB.psr_reconstructor_solve(handle, ctypes.byref(state.mesh_ptr))
            return status

        state = self._run(progress, call)
        mesh = Mesh._own(state.mesh_ptr, self._double) if state.mesh_ptr.value else None
        implicit = Implicit._own(state.implicit_ptr) if state.implicit_ptr.value else None
        if state.error is not None:
            raise state.error
        if state.status != Status.OK:
            raise error_for(state.status, state.message)
        assert mesh is not None
        mesh.implicit = implicit
        return mesh

    def solve_file_out_of_core(
        self,
        input: PathLike,
        output: PathLike,
        *,
        temp_dir: PathLike | None = None,
        slabs: int | None = None,
        confidence: bool = False,
        progress: ProgressCallback | str | None = None,
    ) -> OutOfCoreReport:
        """Reconstructs the oriented points of the PLY file ``input`` into the mesh ``output``
        (binary PLY, as ``psr --out-of-core`` writes it) without holding the whole cloud, its
        octree or its mesh in memory at once (psr_reconstructor_solve_file_out_of_core): the
        cloud is read in chunks and cut across x into slabs kept in a temporary directory under
        ``temp_dir`` (None: the system's), removed however the call ends. The mesh is closed
        across the slabs and equals :meth:`solve`'s to within the solver's tolerance (not bit
        for bit). Returns an :class:`OutOfCoreReport`.

        This reconstructor's parameters, threads and progress callback are used, not its
        points. ``slabs``: how many slabs (at least 1); None chooses the fewest that fit
        ``max_memory``, which must then be set (else :class:`psr.InvalidParameterError`), and
        with them the depth solved once for the whole cloud (a finer one when the limit cuts
        the cloud thin, so that each slab's padding is thinner); a limit no cut fits raises
        :class:`psr.OutOfMemoryError` before the slabs are solved, naming the least workable
        limit. ``confidence=True`` weighs the points by their
        ``confidence`` (or ``value``) property. Colours and channels are not carried (the report
        says when the file had some); ``vertex_normals=True`` is refused.

        ``progress`` is :meth:`solve`'s, and so are the GIL, Ctrl-C and the exceptions: the
        passes report as the stages they correspond to (reading ``Stage.POINTS``, the base
        ``SYSTEM``, the slabs ``SOLVE``, seams and isovalue ``ISOVALUE``, the slabs' meshes
        ``EXTRACT``, the file ``MESH``). A missing or unreadable input, or an output or
        temporary file that cannot be written, raises :class:`psr.FileError` (an OSError) with
        the path; a file that is not a PLY of oriented points :class:`psr.PlyError`. A failure
        leaves no file at ``output`` (the mesh is written there last, and removed if that
        fails).
        """
        paths = (
            _path("input", input),
            _path("output", output),
            None if temp_dir is None else _path("temp_dir", temp_dir),
        )
        if slabs is None:
            count = 0
        else:
            count = _integer("slabs", slabs, 0, 2**64 - 1)
            if count < 1:
                raise InvalidParameterError(
                    Status.INVALID_PARAMETER,
                    f"slabs = {count} is out of range: at least 1 (or None: from max_memory)",
                )
        use_confidence = _bool("confidence", confidence)
        report = OutOfCoreReportStruct()
        noise = OutOfCoreNoiseStruct()

        def call(handle: ctypes.c_void_p, state: _SolveState) -> int:
            status: int = LIB.psr_reconstructor_solve_file_out_of_core(
                handle, *paths, count, int(use_confidence), ctypes.byref(report)
            )
            if status == Status.OK:
                status = LIB.psr_reconstructor_out_of_core_noise(handle, ctypes.byref(noise))
            return status

        state = self._run(progress, call)
        if state.error is not None:
            raise state.error
        if state.status != Status.OK:
            raise error_for(state.status, state.message)
        return OutOfCoreReport(
            points=int(report.points),
            vertices=int(report.vertices),
            triangles=int(report.triangles),
            slabs=int(report.slabs),
            depth=int(report.depth),
            attributes_dropped=bool(report.attributes_dropped),
            unsupported_components=int(report.unsupported_components),
            isovalue=float(report.isovalue),
            seconds=float(report.seconds),
            sample_noise=None if math.isnan(noise.sample_noise) else float(noise.sample_noise),
            screening_depth=float(noise.screening_depth),
            noise_cells_beyond_padding=int(noise.cells_beyond_padding),
        )

    def _run(
        self,
        progress: ProgressCallback | str | None,
        call: Callable[[ctypes.c_void_p, _SolveState], int],
    ) -> _SolveState:
        """Runs ``call(handle, state)`` (a psr call that reports progress) as :meth:`solve`
        describes: ``progress`` (or the constructor's) resolved, on a worker thread when called
        from the main thread so that Ctrl-C is handled at once, on this one otherwise. Raises
        what failed around the call; the call's status, message and the callback's exception
        are in the returned state."""
        progress = progress if progress is not None else self.progress
        close_bar: Callable[[], None] | None = None
        if progress == "tqdm":
            progress, close_bar = _tqdm_progress()
        elif isinstance(progress, str):
            raise ValueError(f'progress must be a callable, "tqdm" or None, not {progress!r}')
        state = _SolveState(progress)
        on_main = threading.current_thread() is threading.main_thread()
        try:
            if on_main:
                worker = threading.Thread(
                    target=self._locked_call,
                    args=(state, call, True),
                    name="psr-solve",
                    daemon=True,
                )
                try:
                    worker.start()
                    # Waiting in short steps: the kernel may deliver SIGINT to one of psr's
                    # threads, and Python runs its handler only when the main thread runs
                    # Python code, which a wait without a timeout would postpone to the end.
                    while not state.done.wait(_POLL_SECONDS):
                        pass
                except BaseException:
                    # Ctrl-C (or another exception from a signal handler): stop psr, give it a
                    # moment to reach a progress report, and leave it running if it does not.
                    state.interrupted = True
                    state.done.wait(_CANCEL_GRACE_SECONDS)
                    with state.mutex:
                        state.abandoned = not state.done.is_set()
                    if not state.abandoned:
                        state.free_results()
                    raise
            else:
                self._locked_call(state, call, False)
        finally:
            if close_bar is not None:
                close_bar()
        if state.failure is not None:
            raise state.failure
        return state

    def _locked_call(
        self,
        state: _SolveState,
        call: Callable[[ctypes.c_void_p, _SolveState], int],
        cancellable: bool,
    ) -> None:
        """The locked part of :meth:`_run`: callback in, the call, callback out."""
        try:
            with self._lock:
                handle = self._live()
                # The trampoline is needed for a callback to call or a cancel to deliver.
                trampoline = (
                    PROGRESS_FN(state.on_progress)
                    if state.progress is not None or cancellable
                    else None
                )
                if trampoline is not None:
                    _check(
                        LIB.psr_reconstructor_set_progress_callback(handle, trampoline, None),
                        handle,
                    )
                try:
                    status = call(handle, state)
                    state.status = status
                    state.message = _last_error(handle) if status != Status.OK else ""
                finally:
                    if trampoline is not None:
                        LIB.psr_reconstructor_set_progress_callback(handle, PROGRESS_FN(), None)
                    self._release()
        except BaseException as e:  # noqa: BLE001 - handed to the thread that called solve()
            state.failure = e
        finally:
            with state.mutex:
                state.done.set()
                if state.abandoned:
                    state.free_results()


def _path(name: str, value: PathLike) -> bytes:
    """A path argument as the C API takes it (bytes without NUL; psr refuses an empty one)."""
    try:
        encoded = os.fsencode(value)
    except TypeError:
        raise TypeError(f"{name} must be a path, not {type(value).__name__}") from None
    if b"\0" in encoded:
        raise InvalidArgumentError(Status.INVALID_ARGUMENT, f"{name} contains a NUL character")
    return encoded


#: How often the main thread wakes while psr works, so a Ctrl-C is handled within this time.
_POLL_SECONDS = 0.05
#: How long a solve interrupted by Ctrl-C may take to reach psr's next progress report before
#: KeyboardInterrupt propagates without it.
_CANCEL_GRACE_SECONDS = 0.2


def _unpack_cloud(
    points: Any, normals: Any, colors: Any, confidence: Any, channels: Any
) -> tuple[Any, Any, Any, Any, Any]:
    """The arrays of an Open3D PointCloud or a psr.PointCloud (explicit arguments win)."""
    from ._ply import PointCloud

    if isinstance(points, PointCloud):
        cloud = points
        return (
            cloud.points,
            normals if normals is not None else cloud.normals,
            colors if colors is not None else cloud.colors,
            confidence,  # as the psr program: the file's confidence only when asked for
            channels if channels is not None else (cloud.channels or None),
        )
    if type(points).__module__.startswith("open3d") and hasattr(points, "points"):
        pcd = points
        xyz = np.asarray(pcd.points)
        if normals is None and pcd.has_normals():
            normals = np.asarray(pcd.normals)
        if colors is None and pcd.has_colors() and normals is not None:
            colors = np.asarray(pcd.colors)
        return xyz, normals, colors, confidence, channels
    return points, normals, colors, confidence, channels


class Mesh:
    """A reconstructed triangle mesh (psr_mesh), with its arrays copied into NumPy:

    - ``vertices`` (n, 3): float32, or float64 in the input's coordinates when the points came
      in float64 (see :meth:`Reconstructor.add_points`);
    - ``triangles`` (m, 3) uint32, counter-clockwise seen from outside;
    - ``densities`` (n,) float32: the sampling density at each vertex (low = far from samples);
    - ``normals`` (n, 3) float32 or None (``vertex_normals=True``);
    - ``colors`` (n, 3 or 4) float32 or None (the points had colours);
    - ``channels``: name -> (n,) float32 (the points' channels);
    - ``implicit``: the :class:`Implicit` function when solved with ``keep_implicit=True``.

    The underlying psr_mesh stays alive for :meth:`trim` and the statistics; it is freed with
    the object (or by :meth:`close`).
    """

    _ptr: ctypes.c_void_p
    _double: bool
    _finalizer: Any
    vertices: np.ndarray
    triangles: np.ndarray
    densities: np.ndarray
    normals: np.ndarray | None
    colors: np.ndarray | None
    channels: dict[str, np.ndarray]
    implicit: Implicit | None

    def __init__(self) -> None:
        raise TypeError("meshes come from Reconstructor.solve, reconstruct and Mesh.trim")

    @classmethod
    def _own(cls, ptr: ctypes.c_void_p, double: bool) -> Mesh:
        self = object.__new__(cls)
        self._ptr = ptr
        self._double = double
        self._finalizer = weakref.finalize(self, LIB.psr_mesh_free, ptr)
        self._finalizer.atexit = False
        self.implicit = None
        nv = LIB.psr_mesh_vertex_count(ptr)
        nt = LIB.psr_mesh_triangle_count(ptr)
        if double:
            self.vertices = np.empty((nv, 3), np.float64)
            _check(LIB.psr_mesh_copy_positions_f64(ptr, self.vertices.ctypes.data, 3 * nv))
        else:
            self.vertices = np.empty((nv, 3), np.float32)
            _check(LIB.psr_mesh_copy_positions(ptr, self.vertices.ctypes.data, 3 * nv))
        self.triangles = np.empty((nt, 3), np.uint32)
        _check(LIB.psr_mesh_copy_triangles(ptr, self.triangles.ctypes.data, 3 * nt))
        self.densities = np.empty(nv, np.float32)
        _check(LIB.psr_mesh_copy_densities(ptr, self.densities.ctypes.data, nv))
        self.normals = None
        if LIB.psr_mesh_normals(ptr):
            self.normals = np.empty((nv, 3), np.float32)
            _check(LIB.psr_mesh_copy_normals(ptr, self.normals.ctypes.data, 3 * nv))
        k = LIB.psr_mesh_color_components(ptr)
        self.colors = None
        if k and nv:
            self.colors = np.empty((nv, k), np.float32)
            _check(LIB.psr_mesh_copy_colors(ptr, self.colors.ctypes.data, k * nv))
        self.channels = {}
        for i in range(LIB.psr_mesh_channel_count(ptr)):
            name = LIB.psr_mesh_channel_name(ptr, i).decode()
            values = np.empty(nv, np.float32)
            _check(LIB.psr_mesh_copy_channel(ptr, i, values.ctypes.data, nv))
            self.channels[name] = values
        for a in (
            self.vertices,
            self.triangles,
            self.densities,
            self.normals,
            self.colors,
            *self.channels.values(),
        ):
            if a is not None:
                a.flags.writeable = False
        return self

    def _live(self) -> ctypes.c_void_p:
        if not self._finalizer.alive:
            raise ValueError("this Mesh was closed")
        return self._ptr

    def close(self) -> None:
        """Frees the psr_mesh now (the NumPy arrays stay; trim, write_ply and the statistics no
        longer work)."""
        self._finalizer()

    def __repr__(self) -> str:
        return (
            f"<psr.Mesh {len(self.vertices)} vertices, {len(self.triangles)} triangles"
            f"{', normals' if self.normals is not None else ''}"
            f"{', colors' if self.colors is not None else ''}"
            f"{', channels ' + str(list(self.channels)) if self.channels else ''}>"
        )

    # --- what the reconstruction reports ---------------------------------------------------------

    @property
    def isovalue(self) -> float:
        """The isovalue the surface was extracted at."""
        return float(LIB.psr_mesh_isovalue(self._live()))

    @property
    def origin(self) -> tuple[float, float, float]:
        """The point psr's float positions are relative to: (0, 0, 0) unless the points came in
        double (``vertices`` is then already in the input's coordinates)."""
        out = (ctypes.c_double * 3)()
        _check(LIB.psr_mesh_origin(self._live(), out))
        return (out[0], out[1], out[2])

    @property
    def depth(self) -> int:
        """The maximum octree depth used (the one ``width`` chose, if set)."""
        out = ctypes.c_uint32()
        _check(LIB.psr_mesh_depth(self._live(), ctypes.byref(out)))
        return out.value

    @property
    def finest_depth(self) -> int:
        """The octree's finest depth (less than ``depth`` where no sample reached it)."""
        out = ctypes.c_uint32()
        _check(LIB.psr_mesh_finest_depth(self._live(), ctypes.byref(out)))
        return out.value

    @property
    def screening_depth(self) -> float:
        """The noise's depth s of the screening weight: the depths finer than s were pulled
        with alpha 2^s instead of alpha 2^depth (those up to floor(s) keep alpha 2^depth).
        ``depth`` when the samples read no noise or the screening did not follow it
        (``screening_follows_noise``); less when the noise set it."""
        out = ctypes.c_double()
        _check(LIB.psr_mesh_screening_depth(self._live(), ctypes.byref(out)))
        return out.value

    @property
    def sample_noise(self) -> float | None:
        """The samples' scatter across the surface (sigma, input units; 0 for exact samples of
        a smooth surface), or None when the reconstruction did not estimate it."""
        out = ctypes.c_double()
        _check(LIB.psr_mesh_sample_noise(self._live(), ctypes.byref(out)))
        return None if math.isnan(out.value) else out.value

    @property
    def node_counts(self) -> np.ndarray:
        """Octree nodes per depth, index = depth, 0 to ``finest_depth``."""
        ptr = self._live()
        count = ctypes.c_size_t()
        _check(LIB.psr_mesh_node_counts(ptr, None, 0, ctypes.byref(count)))
        out = np.zeros(count.value, np.uint64)
        if count.value:
            _check(LIB.psr_mesh_node_counts(ptr, out.ctypes.data, count.value, ctypes.byref(count)))
        return out

    @property
    def unsupported_components(self) -> int:
        """Closed components left out for lack of samples (``min_component_samples``)."""
        return int(LIB.psr_mesh_unsupported_components(self._live()))

    @property
    def solve_stats(self) -> list[SolveStats]:
        """How each depth's linear solve ended, coarse to fine."""
        ptr = self._live()
        stats = []
        for i in range(LIB.psr_mesh_solve_count(ptr)):
            s = DepthSolve()
            s.struct_size = ctypes.sizeof(s)
            _check(LIB.psr_mesh_solve_stats(ptr, i, ctypes.byref(s)))
            stats.append(
                SolveStats(s.depth, s.iterations, s.unknowns, s.relative_residual, s.seconds)
            )
        return stats

    @property
    def trim_density(self) -> float:
        """The density this mesh was cut at by :meth:`trim` (NaN if it was not trimmed)."""
        return float(LIB.psr_mesh_trim_density(self._live()))

    @property
    def trim_depth(self) -> float:
        """That threshold as PoissonRecon's depth-like value (NaN if not trimmed)."""
        return float(LIB.psr_mesh_trim_depth(self._live()))

    # --- trimming and conversions ----------------------------------------------------------------

    def trim(
        self,
        *,
        threshold: EnumLike[TrimThreshold] = TrimThreshold.AUTOMATIC,
        threshold_value: float = 0.0,
        threads: int = 0,
        min_piece_area: float = 0.0,
        min_piece_triangles: int = 0,
        progress: ProgressCallback | str | None = None,
    ) -> Mesh:
        """A new mesh cut back to where the sampling density is at least a threshold
        (psr_mesh_trim, PoissonRecon's SurfaceTrimmer); this mesh is unchanged.

        ``threshold`` says how ``threshold_value`` is read: TrimThreshold.AUTOMATIC (default;
        the value is ignored), DENSITY (a density, >= 0), QUANTILE (a fraction of the area in
        [0, 1]) or DEPTH (PoissonRecon's depth-like value, 0 to 32). Pieces left with less than
        ``min_piece_area`` of the area (a fraction) or fewer than ``min_piece_triangles`` are
        dropped. ``threads``: 0 is one per core.

        ``progress``: a callable ``(stage, fraction)``, called with ``Stage.TRIM`` as the cut
        advances (returning ``False`` cancels with :class:`psr.CancelledError`; an exception it
        raises cancels too and propagates from here), or ``"tqdm"`` for a bar. The GIL is
        released while psr works; on the main thread Ctrl-C stops the cut at its next step and
        raises KeyboardInterrupt.
        """
        close_bar: Callable[[], None] | None = None
        if progress == "tqdm":
            progress, close_bar = _tqdm_progress()
        elif isinstance(progress, str):
            raise ValueError(f'progress must be a callable, "tqdm" or None, not {progress!r}')
        opts = TrimOptions()
        _check(LIB.psr_trim_options_init(ctypes.byref(opts), ctypes.sizeof(opts)))
        opts.threshold = int(_enum(TrimThreshold, "threshold", threshold))
        opts.threshold_value = _real("threshold_value", threshold_value)
        opts.threads = _u32("threads", threads)
        opts.min_piece_area = _real("min_piece_area", min_piece_area)
        opts.min_piece_triangles = _u32("min_piece_triangles", min_piece_triangles)
        # The callback runs on this thread between psr's steps, so a Ctrl-C on the main thread
        # is raised inside it (and handed back here) even when nobody asked for progress.
        state = _SolveState(progress)
        if progress is not None or threading.current_thread() is threading.main_thread():
            opts.progress = PROGRESS_FN(state.on_progress)
        out = ctypes.c_void_p()
        try:
            status = LIB.psr_mesh_trim(self._live(), ctypes.byref(opts), ctypes.byref(out))
        finally:
            if close_bar is not None:
                close_bar()
        if state.error is not None:
            LIB.psr_mesh_free(out)
            raise state.error
        if status != Status.OK:
            raise error_for(
                status,
                "psr_mesh_trim refused the options: threshold_value, min_piece_area or the "
                "threshold kind is out of its range"
                if status != Status.CANCELLED
                else "the trim was cancelled by its progress callback",
            )
        return Mesh._own(out, self._double)

    def to_open3d(self) -> Any:
        """The mesh as an ``open3d.geometry.TriangleMesh`` (with vertex normals and colours
        when it has them; colours are given in Open3D's 0-1 scale as they are). Needs open3d."""
        try:
            import open3d as o3d
        except ImportError:
            raise ImportError("Mesh.to_open3d needs open3d: pip install open3d") from None
        # Copies: Open3D's vectors take writeable arrays only, and the mesh's are read-only.
        m = o3d.geometry.TriangleMesh(
            o3d.utility.Vector3dVector(np.array(self.vertices, dtype=np.float64)),
            o3d.utility.Vector3iVector(np.array(self.triangles, dtype=np.int32)),
        )
        if self.normals is not None:
            m.vertex_normals = o3d.utility.Vector3dVector(self.normals.astype(np.float64))
        if self.colors is not None:
            m.vertex_colors = o3d.utility.Vector3dVector(self.colors[:, :3].astype(np.float64))
        return m

    def to_trimesh(self) -> Any:
        """The mesh as a ``trimesh.Trimesh`` (process=False: vertices and faces as they are;
        densities and channels in ``vertex_attributes``). Needs trimesh."""
        try:
            import trimesh
        except ImportError:
            raise ImportError("Mesh.to_trimesh needs trimesh: pip install trimesh") from None
        attributes: dict[str, Any] = {"density": self.densities, **self.channels}
        return trimesh.Trimesh(
            vertices=self.vertices,
            faces=self.triangles,
            vertex_normals=self.normals,
            vertex_colors=self.colors,
            vertex_attributes=attributes,
            process=False,
        )

    def write_ply(self, path: Any, *, ascii: bool = False) -> None:
        """Writes the mesh as PLY with the psr program's writer, the same bytes as ``psr --out``
        (see :func:`psr.write_ply`); the library's mesh is written, so not after :meth:`close`."""
        from ._ply import write_ply

        write_ply(path, self, ascii=ascii)


class Implicit:
    """The solved indicator function chi of one reconstruction (psr_implicit): evaluate it and
    its gradient at points, or sample it on a grid. The surface is where chi equals
    ``isovalue``; chi - isovalue is negative inside. Safe to use from several threads."""

    _ptr: ctypes.c_void_p
    _finalizer: Any

    def __init__(self) -> None:
        raise TypeError("implicit functions come from solve(keep_implicit=True)")

    @classmethod
    def _own(cls, ptr: ctypes.c_void_p) -> Implicit:
        self = object.__new__(cls)
        self._ptr = ptr
        self._finalizer = weakref.finalize(self, LIB.psr_implicit_free, ptr)
        self._finalizer.atexit = False
        return self

    def _live(self) -> ctypes.c_void_p:
        if not self._finalizer.alive:
            raise ValueError("this Implicit was closed")
        return self._ptr

    def close(self) -> None:
        """Frees the function (about the octree's memory) now."""
        self._finalizer()

    @property
    def isovalue(self) -> float:
        """The isovalue the mesh was extracted at."""
        return float(LIB.psr_implicit_isovalue(self._live()))

    @property
    def cube(self) -> tuple[tuple[float, float, float], float]:
        """The bounding cube chi was solved in: (minimum corner, edge length)."""
        origin = (ctypes.c_double * 3)()
        size = ctypes.c_double()
        _check(LIB.psr_implicit_cube(self._live(), origin, ctypes.byref(size)))
        return (origin[0], origin[1], origin[2]), size.value

    def _points(self, points: Any) -> np.ndarray:
        p = _arrays.rows("points", points, 3)
        return np.ascontiguousarray(p, dtype=np.float32)

    def evaluate(self, points: Any) -> np.ndarray:
        """chi at each of the points (shape (n, 3)), as float32 of shape (n,)."""
        p = self._points(points)
        out = np.empty(p.shape[0], np.float32)
        status = LIB.psr_implicit_evaluate(self._live(), p.ctypes.data, p.shape[0], out.ctypes.data)
        _check(status, message=_bad_point(p, status))
        return out

    def gradient(self, points: Any) -> np.ndarray:
        """The gradient of chi at each of the points, float32 of shape (n, 3)."""
        p = self._points(points)
        out = np.empty((p.shape[0], 3), np.float32)
        status = LIB.psr_implicit_gradient(self._live(), p.ctypes.data, p.shape[0], out.ctypes.data)
        _check(status, message=_bad_point(p, status))
        return out

    def sample_grid(self, resolution: int) -> np.ndarray:
        """chi at the centres of a resolution^3 grid over :attr:`cube`, float32 of shape
        (resolution,) * 3 indexed [i, j, k] along x, y, z."""
        r = _integer("resolution", resolution, 0, 2**63 - 1)
        if not 1 <= r <= 4096:
            raise InvalidParameterError(
                Status.INVALID_PARAMETER, f"resolution = {r} is outside [1, 4096]"
            )
        out = np.empty((r, r, r), np.float32)
        _check(LIB.psr_implicit_sample_grid(self._live(), r, out.ctypes.data, out.size))
        return out

    def sample_box(self, min: Any, max: Any, resolution: int) -> np.ndarray:
        """chi at the centres of a resolution^3 grid over the box from ``min`` to ``max`` (3
        coordinates each, in the points' coordinates; a side may have zero length and the box
        may reach outside :attr:`cube`), float32 of shape (resolution,) * 3 indexed [i, j, k]
        along x, y, z: cell (i, j, k) is at min + ((i, j, k) + 0.5) * (max - min) / resolution.
        ``sample_grid(n)`` is ``sample_box`` over the cube."""
        corners = []
        for name, corner in (("min", min), ("max", max)):
            c = np.ascontiguousarray(corner, dtype=np.float64)
            if c.shape != (3,):
                raise ValueError(f"{name} must hold 3 coordinates, not shape {c.shape}")
            corners.append(c)
        r = _integer("resolution", resolution, 0, 2**63 - 1)
        if not 1 <= r <= 4096:
            raise InvalidParameterError(
                Status.INVALID_PARAMETER, f"resolution = {r} is outside [1, 4096]"
            )
        lo, hi = corners
        out = np.empty((r, r, r), np.float32)
        status = LIB.psr_implicit_sample_box(
            self._live(), lo.ctypes.data, hi.ctypes.data, r, out.ctypes.data, out.size
        )
        message = ""
        if status == Status.INVALID_PARAMETER:
            message = (
                f"box from {lo.tolist()} to {hi.tolist()}: both corners need finite coordinates, "
                "min at most max on every axis"
            )
        _check(status, message=message)
        return out


def _bad_point(p: np.ndarray, status: int) -> str:
    """The message for a failed evaluation (psr keeps none for an implicit function)."""
    if status == Status.NON_FINITE_POSITION:
        i = int(np.flatnonzero(~np.isfinite(p).all(axis=1))[0])
        return f"point {i} has a NaN or infinite coordinate: {p[i].tolist()}"
    return ""


def reconstruct(
    points: Any,
    normals: Any = None,
    *,
    depth: int = 8,
    width: float = 0.0,
    full_depth: int = 5,
    kernel_depth: int = -1,
    samples_per_node: float = 1.5,
    scale: float = 1.1,
    degree: int = 2,
    point_weight: float | None = None,
    screening_follows_noise: bool = True,
    threads: int = 0,
    max_solver_iterations: int = 60,
    solver_tolerance: float = 1e-2,
    boundary: EnumLike[Boundary] = Boundary.NEUMANN,
    splatting: EnumLike[Splatting] = Splatting.BSPLINE,
    vertex_placement: EnumLike[VertexPlacement] = VertexPlacement.FITTED,
    min_component_samples: int = 8,
    max_memory: int = 0,
    vertex_normals: bool = False,
    normal_neighbors: int = 20,
    normal_orientation: EnumLike[Orientation] = Orientation.PROPAGATE,
    normal_reconstruction_iterations: int = 10,
    viewpoint: Sequence[float] | None = None,
    confidence: Any = None,
    colors: Any = None,
    channels: Mapping[str, Any] | None = None,
    sensor: Sequence[float] | None = None,
    sensors: Any = None,
    transform: Any = None,
    progress: ProgressCallback | str | None = None,
    keep_implicit: bool = False,
) -> Mesh:
    """Reconstructs a watertight surface from an oriented point cloud (screened Poisson).

    ``points`` (n, 3) and ``normals`` (n, 3): NumPy arrays (or anything array-like) of any real
    dtype and strides, an Open3D ``PointCloud`` or a :class:`psr.PointCloud`; without normals
    psr estimates and orients them. The other arguments are the C API's parameters with its
    names and defaults (see :class:`Reconstructor`) and the per-point arrays of
    :meth:`Reconstructor.add_points`; ``progress`` and ``keep_implicit`` are those of
    :meth:`Reconstructor.solve`.

    >>> mesh = psr.reconstruct(points, normals, depth=9)
    >>> mesh.vertices.shape, mesh.triangles.shape

    Raises a :class:`psr.PsrError` subclass carrying psr's status and message on bad input
    (NaN, zero normals, wrong shapes, an out-of-range parameter, no points),
    :class:`psr.CancelledError` when ``progress`` returns False, and KeyboardInterrupt on
    Ctrl-C.
    """
    with Reconstructor(
        depth=depth,
        width=width,
        full_depth=full_depth,
        kernel_depth=kernel_depth,
        samples_per_node=samples_per_node,
        scale=scale,
        degree=degree,
        point_weight=point_weight,
        screening_follows_noise=screening_follows_noise,
        threads=threads,
        max_solver_iterations=max_solver_iterations,
        solver_tolerance=solver_tolerance,
        boundary=boundary,
        splatting=splatting,
        vertex_placement=vertex_placement,
        min_component_samples=min_component_samples,
        max_memory=max_memory,
        vertex_normals=vertex_normals,
        normal_neighbors=normal_neighbors,
        normal_orientation=normal_orientation,
        normal_reconstruction_iterations=normal_reconstruction_iterations,
        viewpoint=viewpoint,
    ) as r:
        r.add_points(
            points,
            normals,
            confidence=confidence,
            colors=colors,
            channels=channels,
            sensor=sensor,
            sensors=sensors,
            transform=transform,
        )
        return r.solve(progress=progress, keep_implicit=keep_implicit)


def reconstruct_out_of_core(
    input: PathLike,
    output: PathLike,
    *,
    depth: int = 8,
    width: float = 0.0,
    full_depth: int = 5,
    kernel_depth: int = -1,
    samples_per_node: float = 1.5,
    scale: float = 1.1,
    degree: int = 2,
    point_weight: float | None = None,
    screening_follows_noise: bool = True,
    threads: int = 0,
    max_solver_iterations: int = 60,
    solver_tolerance: float = 1e-2,
    boundary: EnumLike[Boundary] = Boundary.NEUMANN,
    splatting: EnumLike[Splatting] = Splatting.BSPLINE,
    vertex_placement: EnumLike[VertexPlacement] = VertexPlacement.FITTED,
    min_component_samples: int = 8,
    max_memory: int | None = None,
    slabs: int | None = None,
    temp_dir: PathLike | None = None,
    confidence: bool = False,
    progress: ProgressCallback | str | None = None,
) -> OutOfCoreReport:
    """Reconstructs the oriented points of the PLY file ``input`` into the mesh ``output``
    without holding the whole cloud, its octree or its mesh in memory at once (screened
    Poisson, out of core); see :meth:`Reconstructor.solve_file_out_of_core`.

    >>> report = psr.reconstruct_out_of_core("scan.ply", "mesh.ply", depth=11,
    ...                                      max_memory=4 << 30)
    >>> report.slabs, report.vertices

    The parameters are :func:`reconstruct`'s that apply to this path, with their names and
    defaults (points without normals, vertex normals and per-point attributes do not).
    ``max_memory`` (bytes; None or 0: no limit) chooses the number of slabs unless ``slabs``
    is given; one of the two is needed. ``temp_dir`` is where the temporary slab files go
    (about twice the cloud's size; None: the system's temporary directory). ``confidence=True``
    weighs the points by the file's ``confidence`` (or ``value``) property. Raises as
    :meth:`Reconstructor.solve_file_out_of_core` does.
    """
    with Reconstructor(
        depth=depth,
        width=width,
        full_depth=full_depth,
        kernel_depth=kernel_depth,
        samples_per_node=samples_per_node,
        scale=scale,
        degree=degree,
        point_weight=point_weight,
        screening_follows_noise=screening_follows_noise,
        threads=threads,
        max_solver_iterations=max_solver_iterations,
        solver_tolerance=solver_tolerance,
        boundary=boundary,
        splatting=splatting,
        vertex_placement=vertex_placement,
        min_component_samples=min_component_samples,
        max_memory=0 if max_memory is None else max_memory,
    ) as r:
        return r.solve_file_out_of_core(
            input,
            output,
            temp_dir=temp_dir,
            slabs=slabs,
            confidence=confidence,
            progress=progress,
        )
