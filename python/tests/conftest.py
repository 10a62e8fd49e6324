"""Shared fixtures: small synthetic clouds, the repository's kitten, the shared scans and the
psr program. Tests that need a file that is absent skip with the reason; under CI=true they fail
instead (CI must run them all)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

import psr

REPO = Path(__file__).resolve().parents[2]
KITTEN = REPO / "examples" / "data" / "kitten_cgal.ply"


def in_ci() -> bool:
    return os.environ.get("CI", "").lower() == "true"


def need(path: Path, what: str) -> Path:
    """``path``, or a skip (a failure under CI=true) saying what is missing."""
    if not path.exists():
        message = f"{what} not found at {path}"
        if in_ci():
            pytest.fail(message + " (CI=true: required)")
        pytest.skip(message)
    return path


def sphere(n: int, seed: int = 1, radius: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """n points on a sphere of ``radius`` about the origin with outward unit normals (float32)."""
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    return (radius * v).astype(np.float32), v.astype(np.float32)


def same_mesh(a: psr.Mesh, b: psr.Mesh) -> bool:
    """Bit-for-bit equality of the arrays two reconstructions returned."""
    return bool(
        a.vertices.dtype == b.vertices.dtype
        and a.vertices.tobytes() == b.vertices.tobytes()
        and a.triangles.tobytes() == b.triangles.tobytes()
        and a.densities.tobytes() == b.densities.tobytes()
    )


@pytest.fixture(scope="session")
def ball() -> tuple[np.ndarray, np.ndarray]:
    return sphere(3000)


@pytest.fixture(scope="session")
def ball_mesh(ball: tuple[np.ndarray, np.ndarray]) -> psr.Mesh:
    return psr.reconstruct(*ball, depth=6)


@pytest.fixture(scope="session")
def data_dir() -> Path:
    return Path(os.environ.get("PSR_DATA_DIR", str(REPO.parent / "shared" / "data")))


@pytest.fixture(scope="session")
def cli() -> Path:
    """The psr program ($PSR_CLI, default target/release/psr of this repository)."""
    return need(
        Path(os.environ.get("PSR_CLI", str(REPO / "target" / "release" / "psr"))),
        "the psr program (cargo build --release -p psr-cli, or set PSR_CLI)",
    )


def pytest_report_header(config: pytest.Config) -> str:
    return f"psr {psr.library_version} from {psr.library_path()}"


def pytest_sessionstart(session: pytest.Session) -> None:
    # .ci/python.sh sets this: the tests must exercise the installed wheel, not python/src.
    if os.environ.get("PSR_TEST_INSTALLED") == "1":
        source = REPO / "python" / "src"
        if Path(psr.__file__).resolve().is_relative_to(source.resolve()):
            raise pytest.UsageError(f"psr was imported from the source tree {psr.__file__}")
