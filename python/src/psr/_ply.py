"""PLY reading and writing in NumPy.

psr's C API has no PLY functions (the reader and writer live in the Rust crate, used by the
command-line program), so this module reads and writes the same layouts itself: point clouds
with ``x y z [nx ny nz] [red green blue [alpha]] [confidence] [other scalars]`` and meshes as
the psr program writes them, in ASCII or binary of either byte order.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import IO, Any, Union

import numpy as np

from ._lib import LIB

__all__ = ["PointCloud", "PlyMesh", "PlyError", "read_ply", "read_ply_mesh", "write_ply"]

PathLike = Union[str, "os.PathLike[str]"]

_TYPES = {
    "char": "i1",
    "int8": "i1",
    "uchar": "u1",
    "uint8": "u1",
    "short": "i2",
    "int16": "i2",
    "ushort": "u2",
    "uint16": "u2",
    "int": "i4",
    "int32": "i4",
    "uint": "u4",
    "uint32": "u4",
    "float": "f4",
    "float32": "f4",
    "double": "f8",
    "float64": "f8",
}
_COLORS = ("red", "green", "blue", "alpha")
_SENSORS = ("sensor_x", "sensor_y", "sensor_z")


class PlyError(ValueError):
    """A file that is not PLY, or a PLY this reader cannot take (the message says why)."""


@dataclass
class PointCloud:
    """Points read from a PLY file, ready for :func:`psr.reconstruct` (pass the object whole).

    ``points`` (n, 3) float32 (float64 when the file stores doubles); ``normals`` (n, 3) or
    None; ``colors`` (n, 3 or 4) float32 in 0..1 (integer colours are divided by their full
    scale) or None; ``confidence`` (n,) from a ``confidence`` (or else ``value``) property, or
    None; ``channels``: every other scalar vertex property by name, as float32 (sensor
    positions excepted). Passed whole to :func:`psr.reconstruct`, the cloud gives its normals,
    colours and channels, as the psr program does; its confidence is used only when passed
    as ``confidence=`` (the program's ``--confidence``).
    """

    points: np.ndarray
    normals: np.ndarray | None = None
    colors: np.ndarray | None = None
    confidence: np.ndarray | None = None
    channels: dict[str, np.ndarray] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.points)


@dataclass
class PlyMesh:
    """A triangle mesh read from a PLY file: ``vertices`` (n, 3) as stored (float32 or
    float64), ``triangles`` (m, 3) int64, and every other vertex property by name as stored
    (``value`` is psr's density)."""

    vertices: np.ndarray
    triangles: np.ndarray
    properties: dict[str, np.ndarray] = field(default_factory=dict)


@dataclass
class _Element:
    name: str
    count: int
    # (name, dtype) for scalars; (name, count dtype, item dtype) for lists
    properties: list[tuple[str, ...]] = field(default_factory=list)


def _read_header(f: IO[bytes], path: str) -> tuple[str, list[_Element]]:
    if f.readline().rstrip(b"\r\n") != b"ply":
        raise PlyError(f"{path}: not a PLY file (no 'ply' magic line)")
    fmt = ""
    elements: list[_Element] = []
    while True:
        line = f.readline()
        if not line:
            raise PlyError(f"{path}: the header has no end_header")
        words = line.decode("ascii", errors="replace").split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "end_header":
            break
        if words[0] == "format" and len(words) >= 2:
            fmt = words[1]
        elif words[0] == "element" and len(words) == 3:
            try:
                count = int(words[2])
            except ValueError:
                raise PlyError(f"{path}: bad element count in {line!r}") from None
            if count < 0:
                raise PlyError(f"{path}: negative element count in {line!r}")
            elements.append(_Element(words[1], count))
        elif words[0] == "property" and elements:
            try:
                if words[1] == "list" and len(words) == 5:
                    elements[-1].properties.append((words[4], _TYPES[words[2]], _TYPES[words[3]]))
                elif len(words) == 3:
                    elements[-1].properties.append((words[2], _TYPES[words[1]]))
                else:
                    raise KeyError(words[1])
            except KeyError:
                raise PlyError(f"{path}: unknown property type in {line!r}") from None
        else:
            raise PlyError(f"{path}: unexpected header line {line!r}")
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise PlyError(f"{path}: unknown or missing format {fmt!r}")
    return fmt, elements


def _read_binary(f: IO[bytes], fmt: str, elements: list[_Element], path: str) -> dict[str, Any]:
    order = "<" if fmt == "binary_little_endian" else ">"
    data: dict[str, Any] = {}
    for el in elements:
        if all(len(p) == 2 for p in el.properties):
            dt = np.dtype([(p[0], order + p[1]) for p in el.properties])
            raw = f.read(dt.itemsize * el.count)
            if len(raw) != dt.itemsize * el.count:
                raise PlyError(f"{path}: the file ends inside element {el.name}")
            data[el.name] = np.frombuffer(raw, dt)
        elif el.name == "face" and len(el.properties) == 1:
            name, count_t, item_t = el.properties[0]
            # Triangles: every record is the count 3 and three indices.
            dt = np.dtype([("n", order + count_t), ("v", order + item_t, (3,))])
            raw = f.read(dt.itemsize * el.count)
            rec = np.frombuffer(raw, dt) if len(raw) == dt.itemsize * el.count else None
            if rec is None or (rec["n"] != 3).any():
                raise PlyError(f"{path}: only triangle faces are supported")
            data[el.name] = {name: rec["v"]}
        else:
            raise PlyError(
                f"{path}: element {el.name} has list properties this reader skips "
                "only in ASCII files"
            )
    return data


def _read_ascii(f: IO[bytes], elements: list[_Element], path: str) -> dict[str, Any]:
    lines = f.read().decode("ascii", errors="replace").splitlines()
    at = 0
    data: dict[str, Any] = {}
    for el in elements:
        rows = [line.split() for line in lines[at : at + el.count]]
        at += el.count
        if len(rows) != el.count:
            raise PlyError(f"{path}: the file ends inside element {el.name}")
        if all(len(p) == 2 for p in el.properties):
            width = len(el.properties)
            try:
                table = np.array(rows, dtype=np.float64).reshape(el.count, width)
            except ValueError:
                raise PlyError(f"{path}: element {el.name} has a malformed line") from None
            rec = np.empty(el.count, np.dtype([(p[0], p[1]) for p in el.properties]))
            for j, p in enumerate(el.properties):
                rec[p[0]] = table[:, j]
            data[el.name] = rec
        elif el.name == "face" and len(el.properties) == 1:
            if any(len(r) != 4 or r[0] != "3" for r in rows):
                raise PlyError(f"{path}: only triangle faces are supported")
            v = np.array([r[1:] for r in rows], dtype=np.int64).reshape(el.count, 3)
            data[el.name] = {el.properties[0][0]: v}
    return data


def _read(path: PathLike) -> dict[str, Any]:
    p = os.fspath(path)
    with open(p, "rb") as f:
        fmt, elements = _read_header(f, p)
        if fmt == "ascii":
            return _read_ascii(f, elements, p)
        return _read_binary(f, fmt, elements, p)


def _vertex(data: dict[str, Any], path: str) -> np.ndarray:
    v: np.ndarray | None = data.get("vertex")
    if v is None or not all(k in (v.dtype.names or ()) for k in "xyz"):
        raise PlyError(f"{path}: no vertex element with x, y, z")
    return v


def _stack(v: np.ndarray, names: tuple[str, ...], dtype: Any = None) -> np.ndarray:
    return np.stack([v[n] for n in names], axis=1).astype(dtype or v.dtype[names[0]], copy=True)


def read_ply(path: PathLike) -> PointCloud:
    """Reads a point cloud from a PLY file (ASCII or binary, any property types).

    The positions keep their stored precision (float32 or float64), normals come from
    ``nx ny nz``, colours from ``red green blue [alpha]`` (scaled to 0..1), confidence from
    ``confidence``; other scalar vertex properties become channels. Raises :class:`PlyError`
    (a ValueError) for a file it cannot read, OSError when it cannot open it.
    """
    p = os.fspath(path)
    v = _vertex(_read(p), p)
    names = v.dtype.names or ()
    kind = v.dtype["x"]
    pos_type = np.float64 if kind == np.float64 else np.float32
    cloud = PointCloud(points=_stack(v, ("x", "y", "z"), pos_type))
    used = {"x", "y", "z", *_SENSORS}
    if all(k in names for k in ("nx", "ny", "nz")):
        cloud.normals = _stack(v, ("nx", "ny", "nz"), np.float32)
        used |= {"nx", "ny", "nz"}
    # The colour names the psr program reads: red green blue [alpha], diffuse_red ..., r g b [a].
    candidates = [_COLORS, tuple("diffuse_" + c for c in _COLORS), ("r", "g", "b", "a")]
    found = [c for c in candidates if all(name in names for name in c[:3])]
    if found:
        comps = found[0] if found[0][3] in names else found[0][:3]
        t = v.dtype[comps[0]]
        full = {np.dtype("u2"): 65535.0}.get(t, 1.0 if t.kind == "f" else 255.0)
        cloud.colors = (_stack(v, comps, np.float64) / full).astype(np.float32)
        used |= set(comps)
    for name in ("confidence", "value"):
        if name in names:
            # As the psr program reads it; reconstruct() uses it only when passed explicitly
            # (the program's --confidence).
            if cloud.confidence is None:
                cloud.confidence = v[name].astype(np.float32)
            used.add(name)
    for name in names:
        if name not in used:
            cloud.channels[name] = v[name].astype(np.float32)
    return cloud


def read_ply_mesh(path: PathLike) -> PlyMesh:
    """Reads a triangle mesh (such as the psr program's output) from a PLY file."""
    p = os.fspath(path)
    data = _read(p)
    v = _vertex(data, p)
    faces = data.get("face")
    if faces is None:
        raise PlyError(f"{p}: no face element")
    (triangles,) = faces.values()
    props = {n: np.array(v[n]) for n in (v.dtype.names or ()) if n not in ("x", "y", "z")}
    return PlyMesh(
        vertices=_stack(v, ("x", "y", "z")),
        triangles=np.asarray(triangles, dtype=np.int64),
        properties=props,
    )


def write_ply(path: PathLike, mesh: Any, *, ascii: bool = False) -> None:
    """Writes a mesh (a :class:`psr.Mesh`, or any object with ``vertices`` and ``triangles``
    and optionally ``normals``, ``densities``, ``colors`` and ``channels``) as PLY, in the
    layout of the psr program: vertex ``x y z`` (float, or double for float64 vertices), then
    ``nx ny nz``, ``value`` (the density), ``red green blue [alpha]`` (uchar, 255 x the 0..1
    colour) and a float per channel when present; face ``list uchar int vertex_indices``.
    Binary little-endian unless ``ascii``. The same mesh gives the same bytes as
    ``psr --out mesh.ply``.
    """
    vertices = np.asarray(mesh.vertices)
    triangles = np.asarray(mesh.triangles)
    n = len(vertices)
    if (
        vertices.ndim != 2
        or vertices.shape[1] != 3
        or triangles.ndim != 2
        or (triangles.shape[1] != 3)
    ):
        raise ValueError("write_ply: vertices and triangles must have shape (n, 3) and (m, 3)")
    if len(triangles) and (triangles.min() < 0 or triangles.max() >= n):
        raise ValueError("write_ply: a triangle refers to a vertex that does not exist")
    if n > 2**32:
        raise ValueError("write_ply: more than 2^32 vertices do not fit PLY's indices")
    pos_t = "f8" if vertices.dtype == np.float64 else "f4"
    fields: list[tuple[str, str, np.ndarray]] = [
        (c, pos_t, vertices[:, i]) for i, c in enumerate("xyz")
    ]
    normals = getattr(mesh, "normals", None)
    if normals is not None and len(normals):
        fields += [(c, "f4", np.asarray(normals)[:, i]) for i, c in enumerate(("nx", "ny", "nz"))]
    densities = getattr(mesh, "densities", None)
    if densities is not None and len(densities):
        fields.append(("value", "f4", np.asarray(densities)))
    colors = getattr(mesh, "colors", None)
    if colors is not None:
        c8 = np.clip(np.rint(np.asarray(colors, np.float64) * 255.0), 0, 255).astype(np.uint8)
        fields += [(_COLORS[i], "u1", c8[:, i]) for i in range(c8.shape[1])]
    for name, values in (getattr(mesh, "channels", None) or {}).items():
        if name in {f[0] for f in fields}:
            raise ValueError(f"write_ply: channel {name!r} is named like another property")
        fields.append((name, "f4", np.asarray(values)))
    for name, _, values in fields:
        if len(values) != n:
            raise ValueError(f"write_ply: {len(values)} {name} values for {n} vertices")
    index_t = "i4" if n <= 2**31 else "u4"
    ply_names = {"f4": "float", "f8": "double", "u1": "uchar", "i4": "int", "u4": "uint"}
    header = [
        "ply",
        f"format {'ascii' if ascii else 'binary_little_endian'} 1.0",
        f"comment written by psr {LIB.psr_version().decode()}",
        f"element vertex {n}",
        *(f"property {ply_names[t]} {name}" for name, t, _ in fields),
        f"element face {len(triangles)}",
        f"property list uchar {ply_names[index_t]} vertex_indices",
        "end_header",
    ]
    with open(os.fspath(path), "wb") as f:
        f.write(("\n".join(header) + "\n").encode())
        if ascii:
            _write_ascii(f, fields, triangles)
            return
        vdt = np.dtype([(name, "<" + t) for name, t, _ in fields])
        body = np.empty(n, vdt)
        for name, _, values in fields:
            body[name] = values
        f.write(body.tobytes())
        fdt = np.dtype([("n", "u1"), ("v", "<" + index_t, (3,))])
        faces = np.empty(len(triangles), fdt)
        faces["n"] = 3
        faces["v"] = triangles
        f.write(faces.tobytes())


def _write_ascii(f: IO[bytes], fields: list[tuple[str, str, np.ndarray]], triangles: Any) -> None:
    columns = [values for _, _, values in fields]
    for i in range(len(columns[0]) if columns else 0):
        # str() of a NumPy float is its shortest round-tripping decimal in its own precision.
        f.write((" ".join(str(c[i]) for c in columns) + "\n").encode())
    for t in np.asarray(triangles):
        f.write(f"3 {t[0]} {t[1]} {t[2]}\n".encode())
