"""Any real dtype, any strides: the same mesh, and no copy where psr can read the array."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

import psr
from psr import _arrays

from conftest import same_mesh


@pytest.fixture(scope="module")
def reference(ball: tuple[np.ndarray, np.ndarray]) -> psr.Mesh:
    return psr.reconstruct(*ball, depth=5)


def interleaved(p: np.ndarray, n: np.ndarray, dtype: str = "f4") -> np.ndarray:
    rec = np.empty(len(p), [("p", dtype, 3), ("pad", "u1"), ("n", dtype, 3)])
    rec["p"], rec["n"] = p, n
    return rec


Layout = Callable[[np.ndarray, np.ndarray], tuple[Any, Any]]
FLOAT32_LAYOUTS: dict[str, Layout] = {
    "c-contiguous": lambda p, n: (p, n),
    "fortran": lambda p, n: (np.asfortranarray(p), np.asfortranarray(n)),
    "reversed rows": lambda p, n: (p[::-1][::-1], n[::-1][::-1]),
    "every other row": lambda p, n: (np.repeat(p, 2, 0)[::2], np.repeat(n, 2, 0)[::2]),
    "interleaved xyz nxnynz": lambda p, n: (np.hstack([p, n])[:, :3], np.hstack([p, n])[:, 3:]),
    "struct with padding": lambda p, n: (interleaved(p, n)["p"], interleaved(p, n)["n"]),
    "big-endian": lambda p, n: (p.astype(">f4"), n.astype(">f4")),
    "float64 normals": lambda p, n: (p, n.astype(np.float64)),
    "lists": lambda p, n: (p.tolist(), n.tolist()),
}


@pytest.mark.parametrize("layout", FLOAT32_LAYOUTS)
def test_float32_layouts_give_the_same_mesh(
    layout: str, ball: tuple[np.ndarray, np.ndarray], reference: psr.Mesh
) -> None:
    p, n = FLOAT32_LAYOUTS[layout](*ball)
    if layout == "lists":
        # Python floats are doubles: the float64 path, whose vertices are float64.
        m = psr.reconstruct(p, n, depth=5)
        assert m.vertices.dtype == np.float64
        assert np.array_equal(m.triangles, reference.triangles)
        assert np.abs(m.vertices - reference.vertices).max() < 1e-6
        return
    assert same_mesh(psr.reconstruct(p, n, depth=5), reference)


@pytest.mark.parametrize("dtype", ["f8", ">f8", "longdouble", "f2", "i4"])
def test_other_dtypes(dtype: str, ball: tuple[np.ndarray, np.ndarray], reference: psr.Mesh) -> None:
    p, n = ball
    if dtype == "i4":
        p, n = np.rint(p * 1000), np.rint(n * 1000)  # millimetres, integers
        ref = psr.reconstruct(p.astype(np.float32), n.astype(np.float32), depth=5)
        m = psr.reconstruct(p.astype(dtype), n.astype(dtype), depth=5)
    else:
        ref = reference
        m = psr.reconstruct(p.astype(dtype), n.astype(dtype), depth=5)
    if dtype == "f2":
        assert m.vertices.dtype == np.float32  # half precision goes through float
        assert abs(len(m.vertices) - len(ref.vertices)) < len(ref.vertices) // 10
        return
    assert m.vertices.dtype == np.float64
    assert np.array_equal(m.triangles, ref.triangles)
    assert np.abs(m.vertices - ref.vertices).max() <= 1e-6 * np.abs(ref.vertices).max()


def test_float64_rows_are_read_in_place(
    ball: tuple[np.ndarray, np.ndarray], reference: psr.Mesh
) -> None:
    p, n = ball
    both = np.hstack([p, n]).astype(np.float64)
    m = psr.reconstruct(both[:, :3], both[:, 3:], depth=5)
    assert np.array_equal(m.triangles, reference.triangles)


def test_copies_only_where_psr_cannot_read() -> None:
    block = np.zeros((10, 7), np.float32)
    for view in (block[:, :3], block[:, 4:], block[::3, 1:4]):
        out, stride = _arrays.as_c_rows(view, np.float32)
        assert out is view and stride == view.strides[0]
    rec = interleaved(np.zeros((4, 3)), np.ones((4, 3)))["n"]
    out, stride = _arrays.as_c_rows(rec, np.float32)
    assert out is rec and stride == 25
    for view in (
        block[::-1, :3],
        block[:, ::-1][:, :3],
        block[:, :3].astype(">f4"),
        np.broadcast_to(block[:1, :3], (10, 3)),
        block[:, :3].T.copy().T[:, ::1],
    ):
        out, stride = _arrays.as_c_rows(view, np.float32)
        if out is view:
            # Fortran order: columns adjacent, not the three values of a row.
            pytest.fail(f"psr cannot read strides {view.strides} in place")
        assert out.flags.c_contiguous and stride == 12
    d = np.zeros((5, 4))[:, 1:]
    out, stride = _arrays.as_c_rows(d, np.float64)
    assert out is d and stride == 32
