#!/usr/bin/env python3
"""Reconstructs a surface from an oriented point cloud through the psr C API, using ctypes only.

    PSR_LIBRARY=/prefix/lib/libpsr.so python3 reconstruct.py [cloud.ply [depth]]
    python3 reconstruct.py --library /prefix/lib/libpsr.so [cloud.ply [depth]]

The cloud is a binary little-endian PLY whose vertices are float x y z nx ny nz (as the shipped
examples/data/kitten_cgal.ply). Prints the mesh's vertex and triangle counts and its isovalue.
"""

import argparse
import ctypes
import os
import struct
import sys
from array import array

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_CLOUD = os.path.join(HERE, "..", "data", "kitten_cgal.ply")

PSR_STATUS_OK = 0

# typedef bool (*psr_progress_fn)(void *user, psr_stage stage, float fraction);
PROGRESS_FN = ctypes.CFUNCTYPE(ctypes.c_bool, ctypes.c_void_p, ctypes.c_int, ctypes.c_float)


class PsrError(RuntimeError):
    def __init__(self, lib, status, message):
        name = lib.psr_status_string(status).decode()
        super().__init__(f"{name}: {message}")
        self.status = status


def load(path):
    """Loads libpsr and declares the prototypes this script uses (ctypes would guess wrong)."""
    lib = ctypes.CDLL(path)
    r_p = ctypes.c_void_p  # psr_reconstructor *
    m_p = ctypes.c_void_p  # psr_mesh *
    status = ctypes.c_int  # psr_status (a C enum: int)
    size_t = ctypes.c_size_t
    f_p = ctypes.POINTER(ctypes.c_float)
    u32_p = ctypes.POINTER(ctypes.c_uint32)
    protos = {
        "psr_version": (ctypes.c_char_p, []),
        "psr_version_major": (ctypes.c_uint32, []),
        "psr_version_minor": (ctypes.c_uint32, []),
        "psr_status_string": (ctypes.c_char_p, [ctypes.c_int]),
        "psr_stage_string": (ctypes.c_char_p, [ctypes.c_int]),
        "psr_reconstructor_new": (status, [ctypes.POINTER(r_p)]),
        "psr_reconstructor_free": (None, [r_p]),
        "psr_reconstructor_last_error": (ctypes.c_char_p, [r_p]),
        "psr_reconstructor_set_depth": (status, [r_p, ctypes.c_uint32]),
        "psr_reconstructor_get_depth": (status, [r_p, ctypes.POINTER(ctypes.c_uint32)]),
        "psr_reconstructor_set_threads": (status, [r_p, ctypes.c_uint32]),
        "psr_reconstructor_add_points": (status, [r_p, f_p, size_t, f_p, size_t, size_t]),
        "psr_reconstructor_point_count": (status, [r_p, ctypes.POINTER(size_t)]),
        "psr_reconstructor_set_progress_callback": (status, [r_p, PROGRESS_FN, ctypes.c_void_p]),
        "psr_reconstructor_solve": (status, [r_p, ctypes.POINTER(m_p)]),
        "psr_mesh_vertex_count": (size_t, [m_p]),
        "psr_mesh_triangle_count": (size_t, [m_p]),
        "psr_mesh_isovalue": (ctypes.c_double, [m_p]),
        "psr_mesh_positions": (f_p, [m_p]),
        "psr_mesh_triangles": (u32_p, [m_p]),
        "psr_mesh_copy_positions": (status, [m_p, f_p, size_t]),
        "psr_mesh_free": (None, [m_p]),
    }
    for name, (restype, argtypes) in protos.items():
        fn = getattr(lib, name)
        fn.restype = restype
        fn.argtypes = argtypes
    return lib


def read_ply(path):
    """Float x y z nx ny nz vertices of a binary little-endian PLY, interleaved, as array('f')."""
    with open(path, "rb") as f:
        if f.readline().strip() != b"ply":
            raise ValueError(f"{path} is not a PLY file")
        count, props, binary_le, in_vertex = 0, [], False, False
        while True:
            line = f.readline()
            if not line:
                raise ValueError(f"{path}: no end_header")
            words = line.split()
            if words[:1] == [b"end_header"]:
                break
            if words[:2] == [b"format", b"binary_little_endian"]:
                binary_le = True
            if words[:1] == [b"element"]:
                in_vertex = words[1] == b"vertex"
                if in_vertex:
                    count = int(words[2])
            if words[:1] == [b"property"] and in_vertex:
                props.append(b" ".join(words[1:3]).decode())
        want = ["float x", "float y", "float z", "float nx", "float ny", "float nz"]
        if not binary_le or props != want or count == 0:
            raise ValueError(f"{path}: need binary_little_endian vertices with float x y z nx ny nz")
        raw = f.read(24 * count)
    if len(raw) != 24 * count:
        raise ValueError(f"{path}: truncated vertex data")
    data = array("f")
    data.frombytes(raw)
    if sys.byteorder != "little":
        data.byteswap()
    return data, count


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cloud", nargs="?", default=DEFAULT_CLOUD)
    parser.add_argument("depth", nargs="?", type=int, default=7)
    parser.add_argument("--library", default=os.environ.get("PSR_LIBRARY"),
                        help="path to libpsr.so (default: $PSR_LIBRARY)")
    args = parser.parse_args()
    if not args.library:
        parser.error("give the library with --library or the PSR_LIBRARY environment variable")

    lib = load(args.library)
    data, count = read_ply(args.cloud)
    print(f"psr {lib.psr_version().decode()}: {count} points from {args.cloud}, depth {args.depth}")

    r = ctypes.c_void_p()
    if lib.psr_reconstructor_new(ctypes.byref(r)) != PSR_STATUS_OK:
        raise RuntimeError("psr_reconstructor_new failed")
    mesh = ctypes.c_void_p()
    try:
        def check(status):
            if status != PSR_STATUS_OK:
                raise PsrError(lib, status, lib.psr_reconstructor_last_error(r).decode())

        check(lib.psr_reconstructor_set_depth(r, args.depth))

        seen = []

        def on_progress(_user, stage, _fraction):
            # Runs on this (the calling) thread; an exception here cannot cross into C, so ctypes
            # would print and return 0 (cancel). Keep it simple.
            if not seen or seen[-1] != stage:
                seen.append(stage)
                print(f"  stage: {lib.psr_stage_string(stage).decode()}", file=sys.stderr)
            return True

        callback = PROGRESS_FN(on_progress)  # keep a reference while the library may call it
        check(lib.psr_reconstructor_set_progress_callback(r, callback, None))

        # Interleaved x y z nx ny nz: 24-byte strides, normals start 3 floats in. psr copies them.
        base = (ctypes.c_float * len(data)).from_buffer(data)
        f_p = ctypes.POINTER(ctypes.c_float)
        positions = ctypes.cast(base, f_p)
        normals = ctypes.cast(ctypes.byref(base, 3 * ctypes.sizeof(ctypes.c_float)), f_p)
        check(lib.psr_reconstructor_add_points(r, positions, 24, normals, 24, count))

        check(lib.psr_reconstructor_solve(r, ctypes.byref(mesh)))
        nv = lib.psr_mesh_vertex_count(mesh)
        nt = lib.psr_mesh_triangle_count(mesh)
        print(f"vertices: {nv}")
        print(f"triangles: {nt}")
        print(f"isovalue: {lib.psr_mesh_isovalue(mesh):.6f}")

        # Copy-out into a Python-owned buffer (the borrowed view psr_mesh_positions works too).
        out = (ctypes.c_float * (3 * nv))()
        if nv:
            if lib.psr_mesh_copy_positions(mesh, out, len(out)) != PSR_STATUS_OK:
                raise RuntimeError("copy failed")
            print("first vertex: " + " ".join(f"{v:.4f}" for v in out[:3]))
        return 0 if nt > 0 else 1
    finally:
        lib.psr_mesh_free(mesh)
        lib.psr_reconstructor_free(r)


if __name__ == "__main__":
    sys.exit(main())
