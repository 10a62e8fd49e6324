"""Reconstruction out of core, PLY file to PLY file (psr_reconstructor_solve_file_out_of_core):
the mesh against the in-memory one, the report, the temporary files, the errors, cancelling."""

from __future__ import annotations

import dataclasses
import os
import signal
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import psr
from psr import Status

from conftest import sphere

N = 20_000
# Depth 6 with full depth 4: the slabs' shared base is solved to the depth - 3 but at least the
# full depth, and must stay 2 below the finest depth the samples reach (6 for these points), so
# the default full depth of 5 would be refused.
PARAMS: dict[str, Any] = {"depth": 6, "full_depth": 4}


def write_cloud(path: Path, points: np.ndarray, normals: np.ndarray) -> Path:
    """Oriented points as a binary little-endian PLY."""
    header = (
        f"ply\nformat binary_little_endian 1.0\nelement vertex {len(points)}\n"
        + "".join(f"property float {name}\n" for name in ("x", "y", "z", "nx", "ny", "nz"))
        + "end_header\n"
    )
    body = np.hstack([points, normals]).astype("<f4").tobytes()
    path.write_bytes(header.encode() + body)
    return path


@pytest.fixture(scope="module")
def cloud() -> tuple[np.ndarray, np.ndarray]:
    return sphere(N, seed=11)


@pytest.fixture
def cloud_file(tmp_path: Path, cloud: tuple[np.ndarray, np.ndarray]) -> Path:
    return write_cloud(tmp_path / "sphere.ply", *cloud)


@pytest.fixture
def temp(tmp_path: Path) -> Path:
    """An empty directory for the run's temporary directory (it must be empty after)."""
    path = tmp_path / "temp"
    path.mkdir()
    return path


def closed(triangles: np.ndarray) -> bool:
    """Every undirected edge in exactly two triangles."""
    t = triangles.astype(np.int64)
    edges = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return bool(len(t) > 0 and (counts == 2).all())


def test_the_mesh_matches_the_in_memory_one(
    tmp_path: Path, cloud: tuple[np.ndarray, np.ndarray], cloud_file: Path, temp: Path
) -> None:
    output = tmp_path / "mesh.ply"
    report = psr.reconstruct_out_of_core(cloud_file, output, slabs=3, temp_dir=temp, **PARAMS)
    assert isinstance(report, psr.OutOfCoreReport)
    assert (report.points, report.slabs, report.depth) == (N, 3, 6)
    assert report.attributes_dropped is False and report.unsupported_components == 0
    assert np.isfinite(report.isovalue) and report.seconds >= 0.0
    assert list(temp.iterdir()) == [], "temporary files left"
    with pytest.raises(dataclasses.FrozenInstanceError):
        report.slabs = 4  # type: ignore[misc]

    mesh = psr.read_ply_mesh(output)
    assert (len(mesh.vertices), len(mesh.triangles)) == (report.vertices, report.triangles)
    assert mesh.densities is not None  # written as `value`
    assert closed(mesh.triangles)
    in_memory = psr.reconstruct(*cloud, **PARAMS)
    assert abs(report.vertices - len(in_memory.vertices)) <= 0.01 * len(in_memory.vertices)
    # The same surface: every vertex within a finest cell (2.2 / 64) of the unit sphere.
    radii = np.linalg.norm(mesh.vertices.astype(np.float64), axis=1)
    assert np.abs(radii - 1.0).max() < 2.2 / 64


def test_the_report_gives_the_in_memory_noise_reading(tmp_path: Path, temp: Path) -> None:
    points, normals = sphere(N, seed=11)
    rng = np.random.default_rng(5)
    noisy = (points + rng.normal(scale=0.004, size=points.shape)).astype(np.float32)
    cloud_file = write_cloud(tmp_path / "noisy.ply", noisy, normals)
    output = tmp_path / "mesh.ply"
    report = psr.reconstruct_out_of_core(cloud_file, output, slabs=3, temp_dir=temp, **PARAMS)
    in_memory = psr.reconstruct(noisy, normals, **PARAMS)
    assert in_memory.sample_noise is not None and in_memory.sample_noise > 0.0
    # The slabs' estimate is the in-memory one, bit for bit.
    assert report.sample_noise == in_memory.sample_noise
    assert report.screening_depth == in_memory.screening_depth < 6.0
    assert report.noise_cells_beyond_padding == 0
    report = psr.reconstruct_out_of_core(
        cloud_file, output, slabs=3, temp_dir=temp, screening_follows_noise=False, **PARAMS
    )
    assert report.sample_noise is None and report.screening_depth == 6.0


def test_the_reconstructor_method_uses_its_parameters_and_reports_progress(
    tmp_path: Path, cloud_file: Path, temp: Path
) -> None:
    seen: list[tuple[psr.Stage, float, str]] = []
    with psr.Reconstructor(**PARAMS, max_memory=1 << 30) as r:
        r.add_points(np.zeros((3, 3)), np.ones((3, 3)))  # not used: the file's points are
        report = r.solve_file_out_of_core(
            str(cloud_file),
            os.fsencode(tmp_path / "mesh.ply"),
            temp_dir=temp,
            progress=lambda s, f: seen.append((s, f, threading.current_thread().name)),
        )
        assert report.points == N and report.slabs >= 1  # slabs from max_memory
        assert len(r) == 3
    stages = [s for s, _, _ in seen]
    order = [s for i, s in enumerate(stages) if i == 0 or stages[i - 1] != s]
    assert order == [
        psr.Stage.POINTS,
        psr.Stage.SYSTEM,
        psr.Stage.SOLVE,
        psr.Stage.ISOVALUE,
        psr.Stage.EXTRACT,
        psr.Stage.MESH,
    ]
    assert all(0.0 <= f <= 1.0 for _, f, _ in seen)
    # From the main thread the run is on the worker thread, as a solve is.
    assert {name for _, _, name in seen} == {"psr-solve"}
    assert list(temp.iterdir()) == []


def test_errors_map_to_their_exceptions(tmp_path: Path, cloud_file: Path, temp: Path) -> None:
    output = tmp_path / "mesh.ply"
    missing = tmp_path / "no-such-cloud.ply"
    with pytest.raises(psr.FileError, match="no-such-cloud.ply") as info:
        psr.reconstruct_out_of_core(missing, output, slabs=2, **PARAMS)
    assert info.value.status is Status.IO_ERROR and isinstance(info.value, OSError)
    with pytest.raises(psr.InvalidArgumentError) as invalid:
        psr.reconstruct_out_of_core("", output, slabs=2, **PARAMS)
    assert invalid.value.status is Status.INVALID_ARGUMENT
    with pytest.raises(psr.InvalidArgumentError, match="NUL"):
        psr.reconstruct_out_of_core(cloud_file, "mesh\0.ply", slabs=2, **PARAMS)
    with pytest.raises(TypeError, match="input must be a path"):
        psr.reconstruct_out_of_core(3, output, slabs=2)  # type: ignore[arg-type]
    not_ply = tmp_path / "cloud.txt"
    not_ply.write_text("solid not a ply\n")
    with pytest.raises(psr.PlyError) as bad_file:
        psr.reconstruct_out_of_core(not_ply, output, slabs=2, **PARAMS)
    assert bad_file.value.status is Status.INVALID_FILE
    # Neither slabs nor a memory limit; zero slabs; vertex normals.
    with pytest.raises(psr.InvalidParameterError, match="max_memory") as no_budget:
        psr.reconstruct_out_of_core(cloud_file, output, **PARAMS)
    assert no_budget.value.status is Status.INVALID_PARAMETER
    with pytest.raises(psr.InvalidParameterError, match="slabs = 0"):
        psr.reconstruct_out_of_core(cloud_file, output, slabs=0, **PARAMS)
    with psr.Reconstructor(**PARAMS, vertex_normals=True) as r:
        with pytest.raises(psr.InvalidParameterError, match="vertex_normals"):
            r.solve_file_out_of_core(cloud_file, output, slabs=2)
    # A limit no cut fits, refused before the slabs are solved.
    with pytest.raises(psr.OutOfMemoryError, match="allow at least") as oom:
        psr.reconstruct_out_of_core(cloud_file, output, max_memory=4096, temp_dir=temp, **PARAMS)
    assert oom.value.status is Status.OUT_OF_MEMORY and isinstance(oom.value, MemoryError)
    assert list(temp.iterdir()) == []


@pytest.mark.parametrize("stage", [psr.Stage.POINTS, psr.Stage.SOLVE, psr.Stage.EXTRACT])
def test_the_progress_callback_cancels_and_no_temporary_file_stays(
    stage: psr.Stage, tmp_path: Path, cloud_file: Path, temp: Path
) -> None:
    calls: list[psr.Stage] = []

    def stop_at(s: psr.Stage, f: float) -> bool:
        calls.append(s)
        return bool(s != stage)

    r = psr.Reconstructor(**PARAMS)
    with pytest.raises(psr.CancelledError) as info:
        r.solve_file_out_of_core(
            cloud_file, tmp_path / "mesh.ply", slabs=3, temp_dir=temp, progress=stop_at
        )
    assert info.value.status is Status.CANCELLED
    assert calls[-1] is stage and calls.count(stage) == 1  # no call after the "stop"
    assert list(temp.iterdir()) == []

    class Stop(Exception):
        pass

    def fail(s: psr.Stage, f: float) -> None:
        if s is stage:
            raise Stop("from the callback")

    with pytest.raises(Stop, match="from the callback"):
        r.solve_file_out_of_core(
            cloud_file, tmp_path / "mesh.ply", slabs=3, temp_dir=temp, progress=fail
        )
    assert list(temp.iterdir()) == []
    # The reconstructor is fine afterwards.
    report = r.solve_file_out_of_core(cloud_file, tmp_path / "mesh.ply", slabs=3, temp_dir=temp)
    assert report.slabs == 3 and report.triangles > 0
    r.close()


def test_sigint_stops_a_run_and_its_temporary_files_go(tmp_path: Path, temp: Path) -> None:
    # A run of many seconds (100,000 points at depth 9), interrupted 0.3 s in.
    big = write_cloud(tmp_path / "big.ply", *sphere(100_000, seed=9))
    r = psr.Reconstructor(depth=9)
    started = threading.Event()
    timer = threading.Timer(0.3, lambda: os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    t0 = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        r.solve_file_out_of_core(
            big, tmp_path / "mesh.ply", slabs=4, temp_dir=temp, progress=lambda s, f: started.set()
        )
    took = time.monotonic() - t0
    timer.join()
    assert started.is_set() and took < 1.3
    r.depth = 6  # waits for a run left going, if any
    assert list(temp.iterdir()) == [], "temporary files left after Ctrl-C"
    r.close()
