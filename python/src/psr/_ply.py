"""PLY reading and writing through psr's own reader and writer (psr_ply_read,
psr_mesh_write_ply): the files the psr program reads are read alike, with the same properties
and the same errors, and a mesh is written with the same bytes as ``psr --out mesh.ply``.
"""

from __future__ import annotations

import ctypes
import os
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Union

import numpy as np

from ._errors import PlyError, Status, error_for
from ._lib import LIB

if TYPE_CHECKING:
    from ._core import Mesh

__all__ = ["PointCloud", "PlyMesh", "PlyError", "read_ply", "read_ply_mesh", "write_ply"]

PathLike = Union[str, bytes, "os.PathLike[str]", "os.PathLike[bytes]"]

#: psr_mesh_write_ply's flags (include/psr.h).
_PLY_ASCII = 1
_PLY_DOUBLE_POSITIONS = 4

#: Room for the library's message about a file (it shortens longer ones).
_MESSAGE_BYTES = 1024


@dataclass
class PointCloud:
    """Points read from a PLY file, ready for :func:`psr.reconstruct` (pass the object whole).

    ``points`` (n, 3) float32 (float64 when the file stores doubles); ``normals`` (n, 3) or
    None; ``colors`` (n, 3 or 4) float32 in 0..1 (integer colours are divided by their full
    scale) or None; ``confidence`` (n,) from a ``confidence`` (or else ``value``) property, or
    None; ``sensors`` (n, 3), the position of the sensor that saw each point, or None;
    ``channels``: every other scalar vertex property by name, as float32. Passed whole to
    :func:`psr.reconstruct`, the cloud gives its normals, colours and channels, as the psr
    program does; its confidence is used only when passed as ``confidence=`` (the program's
    ``--confidence``).
    """

    points: np.ndarray
    normals: np.ndarray | None = None
    colors: np.ndarray | None = None
    confidence: np.ndarray | None = None
    channels: dict[str, np.ndarray] = field(default_factory=dict)
    sensors: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.points)


@dataclass
class PlyMesh:
    """A triangle mesh read from a PLY file (such as the psr program's output), as
    :func:`read_ply_mesh` gives it: ``vertices`` (n, 3) float32 (float64 when the file stores
    doubles), ``triangles`` (m, 3) uint32 (polygons split into fans), ``densities`` (n,) from
    the ``value`` property psr writes (or ``confidence``) or None, ``normals`` (n, 3) or None,
    ``colors`` (n, 3 or 4) in 0..1 or None, and ``channels`` (every other scalar vertex
    property by name)."""

    vertices: np.ndarray
    triangles: np.ndarray
    densities: np.ndarray | None = None
    normals: np.ndarray | None = None
    colors: np.ndarray | None = None
    channels: dict[str, np.ndarray] = field(default_factory=dict)


def _array(pointer: Any, shape: tuple[int, ...]) -> np.ndarray | None:
    """A NumPy copy of the `shape` values the library's view `pointer` shows, or None for a NULL
    view (what the file does not have)."""
    if not pointer:
        return None
    values: np.ndarray = np.ctypeslib.as_array(pointer, shape).copy()
    return values


def _read(path: PathLike) -> tuple[PointCloud, np.ndarray]:
    """Everything psr_ply_read reads of a file: its vertices as a cloud, and its triangles."""
    handle = ctypes.c_void_p()
    message = ctypes.create_string_buffer(_MESSAGE_BYTES)
    status = LIB.psr_ply_read(os.fsencode(path), ctypes.byref(handle), message, len(message))
    if status != Status.OK:
        raise error_for(status, message.value.decode("utf-8", "replace"))
    try:
        n = LIB.psr_ply_vertex_count(handle)
        exact = _array(LIB.psr_ply_positions_f64(handle), (n, 3))
        points = exact if exact is not None else _array(LIB.psr_ply_positions(handle), (n, 3))
        k = LIB.psr_ply_color_components(handle)
        cloud = PointCloud(
            points=points if points is not None else np.empty((0, 3), np.float32),
            normals=_array(LIB.psr_ply_normals(handle), (n, 3)),
            colors=_array(LIB.psr_ply_colors(handle), (n, k)) if k else None,
            confidence=_array(LIB.psr_ply_confidence(handle), (n,)),
            sensors=_array(LIB.psr_ply_sensors(handle), (n, 3)),
        )
        for i in range(LIB.psr_ply_channel_count(handle)):
            name = LIB.psr_ply_channel_name(handle, i).decode("utf-8", "replace")
            values = _array(LIB.psr_ply_channel(handle, i), (n,))
            cloud.channels[name] = values if values is not None else np.empty(0, np.float32)
        m = LIB.psr_ply_triangle_count(handle)
        triangles = _array(LIB.psr_ply_triangles(handle), (m, 3))
        return cloud, (triangles if triangles is not None else np.empty((0, 3), np.uint32))
    finally:
        LIB.psr_ply_free(handle)


def read_ply(path: PathLike) -> PointCloud:
    """Reads a point cloud from a PLY file with psr's own reader (the psr program's).

    ASCII or binary of either byte order, any property types. The positions keep their stored
    precision (float32, or float64 for doubles); normals come from ``nx ny nz``, colours from
    ``red green blue [alpha]`` (scaled to 0..1), confidence from ``confidence`` (or else
    ``value``), sensor positions from ``sensor_x sensor_y sensor_z``; other scalar vertex
    properties become channels. Raises :class:`PlyError` (a ValueError) for a file psr cannot
    read, with where the problem is, and :class:`psr.FileError` (an OSError) for one it cannot
    open.
    """
    cloud, _ = _read(path)
    return cloud


def read_ply_mesh(path: PathLike) -> PlyMesh:
    """Reads a triangle mesh (such as the psr program's output) from a PLY file with psr's own
    reader: the vertices as :func:`read_ply` reads them (``value`` as the densities) and the
    faces as triangles, polygons split into fans (no triangles for a file without faces).
    Raises as :func:`read_ply` does."""
    cloud, triangles = _read(path)
    return PlyMesh(
        vertices=cloud.points,
        triangles=triangles,
        densities=cloud.confidence,
        normals=cloud.normals,
        colors=cloud.colors,
        channels=cloud.channels,
    )


def write_ply(path: PathLike, mesh: Mesh, *, ascii: bool = False) -> None:
    """Writes a :class:`psr.Mesh` as PLY with psr's own writer, so the same mesh gives the same
    bytes as ``psr --out mesh.ply`` (``--ascii`` with ``ascii=True``): vertex ``x y z`` (float,
    or double when the points were given in float64), ``nx ny nz`` when the mesh has vertex
    normals, ``value`` (the density), ``red green blue [alpha]`` (uchar) when it has colours, a
    float per channel; face ``list uchar int vertex_indices``. Binary little-endian unless
    ``ascii``. Raises :class:`psr.FileError` (an OSError) when the file cannot be written.

    The mesh written is the library's (which :meth:`psr.Mesh.trim` cuts too); its NumPy arrays
    are read-only copies of it. A mesh from elsewhere (trimesh, Open3D) is written by its own
    library.
    """
    from ._core import Mesh

    if not isinstance(mesh, Mesh):
        raise TypeError(
            f"write_ply writes a psr.Mesh, not {type(mesh).__name__}: write other meshes with "
            "their own library (trimesh's export, Open3D's write_triangle_mesh)"
        )
    flags = (_PLY_ASCII if ascii else 0) | (_PLY_DOUBLE_POSITIONS if mesh._double else 0)
    message = ctypes.create_string_buffer(_MESSAGE_BYTES)
    status = LIB.psr_mesh_write_ply(mesh._live(), os.fsencode(path), flags, message, len(message))
    if status != Status.OK:
        raise error_for(status, message.value.decode("utf-8", "replace"))
