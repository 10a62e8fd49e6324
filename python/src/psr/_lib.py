"""Loading libpsr and declaring the C prototypes of include/psr.h for ctypes.

ctypes is the binding layer: it is in the standard library (no compiler, no extra dependency at
import time), and a call through a ``ctypes.CDLL`` function releases the GIL for its duration,
so a long ``psr_reconstructor_solve`` leaves other Python threads running. A progress callback
re-acquires the GIL only while its Python code runs.
"""

from __future__ import annotations

import ctypes
import os
import sys
from ctypes import (
    CFUNCTYPE,
    POINTER,
    Structure,
    c_bool,
    c_char_p,
    c_double,
    c_float,
    c_int,
    c_int32,
    c_size_t,
    c_uint32,
    c_uint64,
    c_void_p,
)
from typing import Any

__all__ = [
    "LIB",
    "PROGRESS_FN",
    "PointArrays",
    "TrimOptions",
    "DepthSolve",
    "OutOfCoreReportStruct",
    "library_path",
]

# typedef bool (*psr_progress_fn)(void *user, psr_stage stage, float fraction);
PROGRESS_FN = CFUNCTYPE(c_bool, c_void_p, c_int, c_float)


class PointArrays(Structure):
    """psr_point_arrays: fields in the header's order (the struct only grows at its end)."""

    _fields_ = [
        ("struct_size", c_size_t),
        ("count", c_size_t),
        ("positions", c_void_p),
        ("position_stride_bytes", c_size_t),
        ("normals", c_void_p),
        ("normal_stride_bytes", c_size_t),
        ("confidence", c_void_p),
        ("confidence_stride_bytes", c_size_t),
        ("colors", c_void_p),
        ("color_stride_bytes", c_size_t),
        ("color_components", c_size_t),
        ("channels", c_void_p),
        ("channel_stride_bytes", c_size_t),
        ("channel_count", c_size_t),
        ("channel_names", POINTER(c_char_p)),
    ]


class TrimOptions(Structure):
    """psr_trim_options."""

    _fields_ = [
        ("struct_size", c_size_t),
        ("threshold", c_int32),
        ("threads", c_uint32),
        ("threshold_value", c_double),
        ("min_piece_area", c_float),
        ("min_piece_triangles", c_uint32),
        ("progress", PROGRESS_FN),
        ("progress_user_data", c_void_p),
    ]


class DepthSolve(Structure):
    """psr_depth_solve."""

    _fields_ = [
        ("struct_size", c_size_t),
        ("depth", c_uint32),
        ("iterations", c_uint32),
        ("unknowns", c_uint64),
        ("relative_residual", c_double),
        ("seconds", c_double),
    ]


class OutOfCoreReportStruct(Structure):
    """psr_out_of_core_report."""

    _fields_ = [
        ("points", c_uint64),
        ("vertices", c_uint64),
        ("triangles", c_uint64),
        ("slabs", c_uint64),
        ("depth", c_uint32),
        ("attributes_dropped", c_uint32),
        ("unsupported_components", c_uint64),
        ("isovalue", c_double),
        ("seconds", c_double),
    ]


class OutOfCoreNoiseStruct(Structure):
    """psr_out_of_core_noise."""

    _fields_ = [
        ("sample_noise", c_double),
        ("screening_depth", c_double),
        ("cells_beyond_padding", c_uint64),
    ]


_R = c_void_p  # psr_reconstructor *
_M = c_void_p  # psr_mesh *
_F = c_void_p  # psr_implicit *
_Y = c_void_p  # psr_ply *
_S = c_int  # psr_status
_P = c_void_p  # any data pointer (NumPy arrays pass their address)

_PROTOTYPES: dict[str, tuple[Any, list[Any]]] = {
    "psr_status_string": (c_char_p, [c_int]),
    "psr_stage_string": (c_char_p, [c_int]),
    "psr_version": (c_char_p, []),
    "psr_version_major": (c_uint32, []),
    "psr_version_minor": (c_uint32, []),
    "psr_version_patch": (c_uint32, []),
    "psr_reconstructor_new": (_S, [POINTER(_R)]),
    "psr_reconstructor_free": (None, [_R]),
    "psr_reconstructor_last_error": (c_char_p, [_R]),
    "psr_reconstructor_set_depth": (_S, [_R, c_uint32]),
    "psr_reconstructor_get_depth": (_S, [_R, POINTER(c_uint32)]),
    "psr_reconstructor_set_width": (_S, [_R, c_double]),
    "psr_reconstructor_get_width": (_S, [_R, POINTER(c_double)]),
    "psr_reconstructor_set_full_depth": (_S, [_R, c_uint32]),
    "psr_reconstructor_get_full_depth": (_S, [_R, POINTER(c_uint32)]),
    "psr_reconstructor_set_kernel_depth": (_S, [_R, c_int32]),
    "psr_reconstructor_get_kernel_depth": (_S, [_R, POINTER(c_int32)]),
    "psr_reconstructor_set_samples_per_node": (_S, [_R, c_float]),
    "psr_reconstructor_get_samples_per_node": (_S, [_R, POINTER(c_float)]),
    "psr_reconstructor_set_scale": (_S, [_R, c_float]),
    "psr_reconstructor_get_scale": (_S, [_R, POINTER(c_float)]),
    "psr_reconstructor_set_degree": (_S, [_R, c_int32]),
    "psr_reconstructor_get_degree": (_S, [_R, POINTER(c_int32)]),
    "psr_reconstructor_set_point_weight": (_S, [_R, c_float]),
    "psr_reconstructor_get_point_weight": (_S, [_R, POINTER(c_float)]),
    "psr_reconstructor_set_threads": (_S, [_R, c_uint32]),
    "psr_reconstructor_get_threads": (_S, [_R, POINTER(c_uint32)]),
    "psr_reconstructor_set_max_solver_iterations": (_S, [_R, c_uint32]),
    "psr_reconstructor_get_max_solver_iterations": (_S, [_R, POINTER(c_uint32)]),
    "psr_reconstructor_set_solver_tolerance": (_S, [_R, c_double]),
    "psr_reconstructor_get_solver_tolerance": (_S, [_R, POINTER(c_double)]),
    "psr_reconstructor_set_boundary": (_S, [_R, c_int32]),
    "psr_reconstructor_get_boundary": (_S, [_R, POINTER(c_int32)]),
    "psr_reconstructor_set_splatting": (_S, [_R, c_int32]),
    "psr_reconstructor_get_splatting": (_S, [_R, POINTER(c_int32)]),
    "psr_reconstructor_set_vertex_placement": (_S, [_R, c_int32]),
    "psr_reconstructor_get_vertex_placement": (_S, [_R, POINTER(c_int32)]),
    "psr_reconstructor_set_max_memory": (_S, [_R, c_uint64]),
    "psr_reconstructor_get_max_memory": (_S, [_R, POINTER(c_uint64)]),
    "psr_reconstructor_estimate_memory": (_S, [_R, POINTER(c_uint64)]),
    "psr_estimate_memory": (_S, [c_uint32, c_uint64, POINTER(c_uint64)]),
    "psr_reconstructor_set_min_component_samples": (_S, [_R, c_uint32]),
    "psr_reconstructor_get_min_component_samples": (_S, [_R, POINTER(c_uint32)]),
    "psr_reconstructor_set_vertex_normals": (_S, [_R, c_bool]),
    "psr_reconstructor_get_vertex_normals": (_S, [_R, POINTER(c_bool)]),
    "psr_reconstructor_set_screening_follows_noise": (_S, [_R, c_bool]),
    "psr_reconstructor_get_screening_follows_noise": (_S, [_R, POINTER(c_bool)]),
    "psr_reconstructor_set_normal_neighbors": (_S, [_R, c_uint32]),
    "psr_reconstructor_get_normal_neighbors": (_S, [_R, POINTER(c_uint32)]),
    "psr_reconstructor_set_normal_orientation": (_S, [_R, c_int32]),
    "psr_reconstructor_get_normal_orientation": (_S, [_R, POINTER(c_int32)]),
    "psr_reconstructor_set_normal_reconstruction_iterations": (_S, [_R, c_uint32]),
    "psr_reconstructor_get_normal_reconstruction_iterations": (_S, [_R, POINTER(c_uint32)]),
    "psr_reconstructor_set_viewpoint": (_S, [_R, c_double, c_double, c_double]),
    "psr_reconstructor_add_points": (_S, [_R, _P, c_size_t, _P, c_size_t, c_size_t]),
    "psr_reconstructor_add_points_f64": (_S, [_R, _P, c_size_t, _P, c_size_t, c_size_t]),
    "psr_reconstructor_add_points_transformed": (
        _S,
        [_R, _P, c_size_t, _P, c_size_t, c_size_t, _P],
    ),
    "psr_reconstructor_add_positions": (_S, [_R, _P, c_size_t, c_size_t]),
    "psr_reconstructor_add_positions_seen_from": (_S, [_R, _P, c_size_t, c_size_t, _P]),
    "psr_reconstructor_add_positions_with_sensors": (
        _S,
        [_R, _P, c_size_t, _P, c_size_t, c_size_t],
    ),
    "psr_point_arrays_init": (_S, [POINTER(PointArrays), c_size_t]),
    "psr_reconstructor_add_point_arrays": (_S, [_R, POINTER(PointArrays)]),
    "psr_reconstructor_point_count": (_S, [_R, POINTER(c_size_t)]),
    "psr_reconstructor_clear_points": (_S, [_R]),
    "psr_reconstructor_set_progress_callback": (_S, [_R, PROGRESS_FN, c_void_p]),
    "psr_reconstructor_solve": (_S, [_R, POINTER(_M)]),
    "psr_reconstructor_solve_implicit": (_S, [_R, POINTER(_M), POINTER(_F)]),
    "psr_reconstructor_solve_file_out_of_core": (
        _S,
        [_R, c_char_p, c_char_p, c_char_p, c_size_t, c_int32, POINTER(OutOfCoreReportStruct)],
    ),
    "psr_reconstructor_out_of_core_noise": (_S, [_R, POINTER(OutOfCoreNoiseStruct)]),
    "psr_mesh_free": (None, [_M]),
    "psr_mesh_vertex_count": (c_size_t, [_M]),
    "psr_mesh_triangle_count": (c_size_t, [_M]),
    "psr_mesh_isovalue": (c_double, [_M]),
    "psr_mesh_origin": (_S, [_M, POINTER(c_double)]),
    "psr_mesh_copy_positions": (_S, [_M, _P, c_size_t]),
    "psr_mesh_copy_positions_f64": (_S, [_M, _P, c_size_t]),
    "psr_mesh_copy_triangles": (_S, [_M, _P, c_size_t]),
    "psr_mesh_copy_densities": (_S, [_M, _P, c_size_t]),
    "psr_mesh_normals": (c_void_p, [_M]),
    "psr_mesh_copy_normals": (_S, [_M, _P, c_size_t]),
    "psr_mesh_color_components": (c_size_t, [_M]),
    "psr_mesh_copy_colors": (_S, [_M, _P, c_size_t]),
    "psr_mesh_channel_count": (c_size_t, [_M]),
    "psr_mesh_channel_name": (c_char_p, [_M, c_size_t]),
    "psr_mesh_copy_channel": (_S, [_M, c_size_t, _P, c_size_t]),
    "psr_mesh_depth": (_S, [_M, POINTER(c_uint32)]),
    "psr_mesh_finest_depth": (_S, [_M, POINTER(c_uint32)]),
    "psr_mesh_screening_depth": (_S, [_M, POINTER(c_double)]),
    "psr_mesh_sample_noise": (_S, [_M, POINTER(c_double)]),
    "psr_mesh_node_counts": (_S, [_M, _P, c_size_t, POINTER(c_size_t)]),
    "psr_mesh_unsupported_components": (c_size_t, [_M]),
    "psr_mesh_solve_count": (c_size_t, [_M]),
    "psr_mesh_solve_stats": (_S, [_M, c_size_t, POINTER(DepthSolve)]),
    "psr_trim_options_init": (_S, [POINTER(TrimOptions), c_size_t]),
    "psr_mesh_trim": (_S, [_M, POINTER(TrimOptions), POINTER(_M)]),
    "psr_mesh_trim_density": (c_double, [_M]),
    "psr_mesh_trim_depth": (c_double, [_M]),
    "psr_ply_read": (_S, [c_char_p, POINTER(_Y), c_char_p, c_size_t]),
    "psr_ply_free": (None, [_Y]),
    "psr_ply_vertex_count": (c_size_t, [_Y]),
    "psr_ply_positions": (POINTER(c_float), [_Y]),
    "psr_ply_positions_f64": (POINTER(c_double), [_Y]),
    "psr_ply_normals": (POINTER(c_float), [_Y]),
    "psr_ply_color_components": (c_size_t, [_Y]),
    "psr_ply_colors": (POINTER(c_float), [_Y]),
    "psr_ply_confidence": (POINTER(c_float), [_Y]),
    "psr_ply_sensors": (POINTER(c_float), [_Y]),
    "psr_ply_channel_count": (c_size_t, [_Y]),
    "psr_ply_channel_name": (c_char_p, [_Y, c_size_t]),
    "psr_ply_channel": (POINTER(c_float), [_Y, c_size_t]),
    "psr_ply_triangle_count": (c_size_t, [_Y]),
    "psr_ply_triangles": (POINTER(c_uint32), [_Y]),
    "psr_mesh_write_ply": (_S, [_M, c_char_p, c_uint32, c_char_p, c_size_t]),
    "psr_implicit_free": (None, [_F]),
    "psr_implicit_isovalue": (c_double, [_F]),
    "psr_implicit_cube": (_S, [_F, POINTER(c_double), POINTER(c_double)]),
    "psr_implicit_evaluate": (_S, [_F, _P, c_size_t, _P]),
    "psr_implicit_gradient": (_S, [_F, _P, c_size_t, _P]),
    "psr_implicit_sample_grid": (_S, [_F, c_size_t, _P, c_size_t]),
    "psr_implicit_sample_box": (_S, [_F, _P, _P, c_size_t, _P, c_size_t]),
}


def library_path() -> str:
    """The path of the libpsr shared library this package loads: the one inside the package."""
    name = {"darwin": "libpsr.dylib", "win32": "psr.dll"}.get(sys.platform, "libpsr.so")
    return os.path.join(os.path.dirname(os.path.abspath(__file__)), name)


def _load() -> ctypes.CDLL:
    path = library_path()
    if not os.path.exists(path):
        raise ImportError(
            f"psr: the shared library {path} is missing: this copy of the package was not built "
            "(install it with `pip install ./python` from the psr repository, or from a wheel)"
        )
    lib = ctypes.CDLL(path)
    for name, (restype, argtypes) in _PROTOTYPES.items():
        fn = getattr(lib, name)
        fn.restype = restype
        fn.argtypes = argtypes
    return lib


LIB = _load()
