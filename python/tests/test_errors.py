"""Every bad input gets its exception, with psr's status and a message naming what is wrong."""

from __future__ import annotations

import sys
from typing import Any

import numpy as np
import pytest

import psr
from psr import Status

from conftest import sphere

P, N = sphere(400, seed=3)


def raises(kind: type[psr.PsrError], status: Status, match: str | None = None) -> Any:
    class Check:
        def __enter__(self) -> None:
            self.ctx = pytest.raises(kind, match=match)
            self.info = self.ctx.__enter__()

        def __exit__(self, *exc: Any) -> bool:
            handled = self.ctx.__exit__(*exc)
            e = self.info.value
            assert isinstance(e, psr.PsrError)
            assert e.status == status, (e.status, status)
            assert str(e).startswith(f"PSR_STATUS_{status.name}")
            return bool(handled)

    return Check()


def with_value(a: np.ndarray, index: int, value: float, column: int = 1) -> np.ndarray:
    b: np.ndarray = a.copy()
    b[index, column] = value
    return b


def test_nan_and_infinite_positions_and_normals() -> None:
    with raises(psr.NonFiniteError, Status.NON_FINITE_POSITION, "17"):
        psr.reconstruct(with_value(P, 17, np.nan), N)
    with raises(psr.NonFiniteError, Status.NON_FINITE_POSITION, "5"):
        psr.reconstruct(with_value(P.astype(np.float64), 5, np.inf), N)
    with raises(psr.NonFiniteError, Status.NON_FINITE_POSITION, "9"):
        psr.reconstruct(with_value(P, 9, -np.inf))  # without normals
    with raises(psr.NonFiniteError, Status.NON_FINITE_NORMAL, "3"):
        psr.reconstruct(P, with_value(N, 3, np.nan))
    with raises(psr.ZeroNormalError, Status.ZERO_NORMAL, "8"):
        psr.reconstruct(P, np.where(np.arange(len(N))[:, None] == 8, 0, N))
    with raises(psr.NonFiniteError, Status.NON_FINITE_POSITION):
        psr.reconstruct(with_value(P.astype(np.float64), 2, 1e300), N)  # beyond float
    assert issubclass(psr.NonFiniteError, ValueError)


def test_empty_input() -> None:
    with raises(psr.EmptyInputError, Status.EMPTY_INPUT):
        psr.reconstruct(np.empty((0, 3)), np.empty((0, 3)))
    with raises(psr.EmptyInputError, Status.EMPTY_INPUT):
        psr.Reconstructor().solve()


@pytest.mark.parametrize(
    "points, normals, match",
    [
        (P[:, :2], N, r"points must have shape \(n, 3\), not \(400, 2\)"),
        (P.ravel(), N, r"points must have shape \(n, 3\)"),
        (P[None], N, r"points must have shape \(n, 3\), not \(1, 400, 3\)"),
        (P, N[:-1], "normals has 399 rows but the points are 400"),
        (P, N[:, :2], r"normals must have shape \(n, 3\)"),
        (5.0, None, r"points must have shape \(n, 3\), not \(\)"),
    ],
)
def test_shapes_and_lengths(points: Any, normals: Any, match: str) -> None:
    with raises(psr.InvalidArgumentError, Status.INVALID_ARGUMENT, match):
        psr.reconstruct(points, normals)


def test_attribute_lengths_and_values() -> None:
    with raises(psr.InvalidArgumentError, Status.INVALID_ARGUMENT, "colors has 10 rows"):
        psr.reconstruct(P, N, colors=np.ones((10, 3)))
    with raises(psr.InvalidArgumentError, Status.INVALID_ARGUMENT, "confidence"):
        psr.reconstruct(P, N, confidence=np.ones(3))
    with raises(psr.InvalidWeightError, Status.INVALID_WEIGHT, "11"):
        psr.reconstruct(P, N, confidence=with_value(np.ones((len(P), 1)), 11, -1.0, 0))
    with raises(psr.InvalidWeightError, Status.INVALID_WEIGHT):
        psr.reconstruct(P, N, confidence=np.zeros(len(P)))
    with raises(psr.NonFiniteError, Status.NON_FINITE_ATTRIBUTE, "4"):
        psr.reconstruct(P, N, colors=with_value(np.ones((len(P), 3)), 4, np.nan))
    with raises(psr.InvalidArgumentError, Status.INVALID_ARGUMENT, "name"):
        psr.reconstruct(P, N, channels={"two words": P[:, 0]})
    with raises(psr.InvalidArgumentError, Status.INVALID_ARGUMENT, "needs normals"):
        psr.reconstruct(P, colors=np.ones((len(P), 3)))
    with raises(psr.InvalidArgumentError, Status.INVALID_ARGUMENT, "without normals"):
        psr.reconstruct(P, N, sensor=(0, 0, 0))
    with raises(psr.InvalidTransformError, Status.INVALID_TRANSFORM):
        psr.reconstruct(P, N, transform=np.zeros((4, 4)))
    with raises(psr.InvalidTransformError, Status.INVALID_TRANSFORM):
        psr.reconstruct(P, N, transform=np.diag([1.0, 1.0, 1.0, 2.0]))
    with raises(psr.InvalidArgumentError, Status.INVALID_ARGUMENT, r"\(4, 4\)"):
        psr.reconstruct(P, N, transform=np.eye(3))
    with pytest.raises(TypeError, match="real numbers"):
        psr.reconstruct(np.array([["a", "b", "c"]]), None)


@pytest.mark.parametrize(
    "name, value",
    [
        ("depth", 0),
        ("depth", 17),
        ("depth", 100),
        ("depth", -1),
        ("depth", 2**40),
        ("full_depth", 17),
        ("kernel_depth", 17),
        ("samples_per_node", 0.5),
        ("samples_per_node", float("nan")),
        ("scale", 0.9),
        ("scale", float("inf")),
        ("point_weight", -1.0),
        ("degree", 0),
        ("degree", 3),
        ("threads", 5000),
        ("max_solver_iterations", 0),
        ("solver_tolerance", 1.0),
        ("solver_tolerance", 0.0),
        ("width", -1.0),
        ("width", float("nan")),
        ("boundary", 3),
        ("boundary", "soft"),
        ("splatting", 2),
        ("vertex_placement", -1),
        ("normal_neighbors", 0),
        ("normal_orientation", 5),
        ("normal_reconstruction_iterations", 0),
        ("normal_reconstruction_iterations", 1001),
        ("normal_orientation", psr.Orientation.VIEWPOINT),  # before any viewpoint
    ],
)
def test_parameters_out_of_range(name: str, value: Any) -> None:
    with raises(psr.InvalidParameterError, Status.INVALID_PARAMETER, name.split("_")[0]):
        psr.reconstruct(P, N, **{name: value})
    r = psr.Reconstructor()
    before = getattr(r, name)
    with raises(psr.InvalidParameterError, Status.INVALID_PARAMETER):
        setattr(r, name, value)
    assert getattr(r, name) == before  # a refused value leaves the old one


def test_parameters_that_disagree_are_refused_at_solve() -> None:
    r = psr.Reconstructor(depth=5, kernel_depth=7)  # each alone is fine
    r.add_points(P, N)
    with raises(psr.InvalidParameterError, Status.INVALID_PARAMETER, "kernel"):
        r.solve()
    r.kernel_depth = 3
    assert len(r.solve().triangles) > 0


@pytest.mark.parametrize(
    "name, value",
    [("depth", 8.5), ("depth", "8"), ("depth", True), ("scale", "big"), ("vertex_normals", 1)],
)
def test_parameters_of_the_wrong_type(name: str, value: Any) -> None:
    with pytest.raises(TypeError, match=name):
        psr.reconstruct(P, N, **{name: value})


def test_a_rejected_batch_adds_nothing() -> None:
    r = psr.Reconstructor(depth=5)
    r.add_points(P[:200], N[:200])
    with raises(psr.NonFiniteError, Status.NON_FINITE_POSITION, "7"):
        r.add_points(with_value(P[200:], 7, np.nan), N[200:])
    assert len(r) == 200
    with raises(psr.InvalidArgumentError, Status.INVALID_ARGUMENT):
        r.add_points(P[200:], N[200:], colors=np.ones((200, 3)))  # earlier batch had none
    assert len(r) == 200


def test_degenerate_clouds() -> None:
    with raises(psr.InvalidArgumentError, Status.INVALID_ARGUMENT, "coincide"):
        psr.reconstruct(np.ones((50, 3)), N[:50])
    with raises(psr.InvalidArgumentError, Status.INVALID_ARGUMENT):
        psr.reconstruct(P[:5])  # too few points to estimate normals


def test_implicit_and_trim_arguments() -> None:
    m = psr.reconstruct(P, N, depth=5, keep_implicit=True)
    assert m.implicit is not None
    with raises(psr.NonFiniteError, Status.NON_FINITE_POSITION, "point 1"):
        m.implicit.evaluate([[0, 0, 0], [np.nan, 0, 0]])
    with raises(psr.InvalidArgumentError, Status.INVALID_ARGUMENT):
        m.implicit.gradient(np.zeros((4, 2)))
    for r in (0, 5000):
        with raises(psr.InvalidParameterError, Status.INVALID_PARAMETER):
            m.implicit.sample_grid(r)
        with raises(psr.InvalidParameterError, Status.INVALID_PARAMETER):
            m.implicit.sample_box([0, 0, 0], [1, 1, 1], r)
    for lo, hi in (
        ([1, 0, 0], [0, 1, 1]),
        ([np.nan, 0, 0], [1, 1, 1]),
        ([0, 0, 0], [1, np.inf, 1]),
    ):
        with raises(psr.InvalidParameterError, Status.INVALID_PARAMETER, "finite coordinates"):
            m.implicit.sample_box(lo, hi, 2)
    with pytest.raises(ValueError, match="3 coordinates"):
        m.implicit.sample_box([0, 0], [1, 1, 1], 2)
    with raises(psr.InvalidParameterError, Status.INVALID_PARAMETER):
        m.trim(threshold="quantile", threshold_value=2.0)
    with raises(psr.InvalidParameterError, Status.INVALID_PARAMETER):
        m.trim(threshold=9)
    with raises(psr.InvalidParameterError, Status.INVALID_PARAMETER):
        m.trim(min_piece_area=-0.5)
    with pytest.raises(TypeError):
        psr.Mesh()
    m.close()
    with pytest.raises(ValueError, match="closed"):
        m.trim()
    assert len(m.vertices) > 0  # the arrays stay


def test_progress_arguments(monkeypatch: pytest.MonkeyPatch) -> None:
    with pytest.raises(ValueError, match="tqdm"):
        psr.reconstruct(P, N, depth=4, progress="bar")
    monkeypatch.setitem(sys.modules, "tqdm", None)
    monkeypatch.setitem(sys.modules, "tqdm.auto", None)
    with pytest.raises(ImportError, match="pip install tqdm"):
        psr.reconstruct(P, N, depth=4, progress="tqdm")


def test_status_names_come_from_the_library() -> None:
    for status in Status:
        if status is Status.OK:
            continue
        e = psr.PsrError(status, "why")
        assert str(e) == f"PSR_STATUS_{status.name}: why" and e.message == "why"
    assert str(psr.PsrError(999, "x")).startswith("PSR_STATUS_UNKNOWN")
