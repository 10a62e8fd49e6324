"""NumPy arrays in the shapes and dtypes the C ABI reads, copied only when it cannot read them."""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from ._errors import InvalidArgumentError, Status

__all__ = ["rows", "as_c_rows", "is_double"]


def rows(name: str, data: Any, width: int, count: int | None = None) -> np.ndarray:
    """``data`` as a NumPy array of shape (n, width) (``width`` 1 also takes shape (n,)), any
    real dtype; raises InvalidArgumentError (a ValueError) for another shape or a count other
    than ``count``, TypeError for a non-numeric dtype. No copy is made here."""
    a = np.asarray(data)
    if a.dtype.kind not in "fiu":
        raise TypeError(f"{name} must hold real numbers, not {a.dtype}")
    if width == 1 and a.ndim == 1:
        a = a.reshape(-1, 1)
    if a.ndim != 2 or a.shape[1] != width:
        want = "(n,)" if width == 1 else f"(n, {width})"
        raise InvalidArgumentError(
            Status.INVALID_ARGUMENT, f"{name} must have shape {want}, not {a.shape}"
        )
    if count is not None and a.shape[0] != count:
        raise InvalidArgumentError(
            Status.INVALID_ARGUMENT,
            f"{name} has {a.shape[0]} rows but the points are {count}: one per point",
        )
    return a


def is_double(a: np.ndarray) -> bool:
    """Whether positions in ``a`` go through psr's double-precision entry points: float64 (and
    wider floats and integers, which float32 would round); float32 and float16 go as float."""
    return not (a.dtype.kind == "f" and a.dtype.itemsize <= 4)


def as_c_rows(a: np.ndarray, dtype: npt.DTypeLike) -> tuple[np.ndarray, int]:
    """``a`` (shape (n, k)) as rows psr can read in place, and their byte stride: the array
    itself when it has the native ``dtype``, its k values of a row are adjacent and the rows are
    at least a row apart going forward (psr takes any such stride, interleaved structs
    included); otherwise a packed copy. The caller keeps the returned array alive during the
    call."""
    dt = np.dtype(dtype)
    k = a.shape[1]
    if (
        a.dtype == dt
        and a.dtype.isnative
        and (k == 1 or a.strides[1] == dt.itemsize)
        and (a.shape[0] <= 1 or a.strides[0] >= k * dt.itemsize)
    ):
        stride = a.strides[0] if a.shape[0] > 1 else k * dt.itemsize
        return a, int(stride)
    c = np.ascontiguousarray(a, dtype=dt)
    return c, k * dt.itemsize
