#!/usr/bin/env python3
"""Reconstructs real scans and synthetic clouds under many parameter combinations and checks
that every mesh is a valid surface: no directed edge in two triangles, no edge in more than two
triangles, and open edges (free boundaries) only on the bounding cube's faces.

The fuzzer's `reconstruct` target explores small clouds (at most 400 points, depth 7); this
sweep covers what it cannot reach: scans of 10^4-10^6 points at depths up to 10, on every
degree, boundary, scale (1.0 puts samples on the cube's faces), full depth, splatting, vertex
placement, kernel depth and samples per node. The grid of degree x boundary x scale x full depth
x depth is run on every cloud; the other parameters are drawn per run from a fixed seed, so a
run is reproducible. It is a check to run by hand (minutes to an hour), not a CI test; results
go in docs/reliability.md.

    cargo build --release
    python3 scripts/topology_sweep.py                       # synthetic clouds only (~2 min)
    python3 scripts/topology_sweep.py --scans bunny_scans happy_buddha_scans --max-points 150000

Needs NumPy and the psr Python package: installed (`pip install ./python`), or from this tree
with `--library target/release/libpsr.so` (the package's sources are then used in place).
"""

from __future__ import annotations

import argparse
import itertools
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def import_psr(library: str | None):  # type: ignore[no-untyped-def]
    """The psr package: the installed one, or this tree's sources with `library` beside them."""
    if library:
        staging = Path(tempfile.mkdtemp(prefix="psr-sweep-"))
        shutil.copytree(ROOT / "python" / "src" / "psr", staging / "psr")
        shutil.copy(library, staging / "psr" / "libpsr.so")
        sys.path.insert(0, str(staging))
    import psr

    return psr


def violations(
    vertices: np.ndarray, triangles: np.ndarray, low: np.ndarray, size: float, tolerance: float
) -> tuple[int, int, int]:
    """(directed edges in two triangles, edges in more than two, open edges off the cube's
    faces), the cube given by its low corner and side; `tolerance` in units of the side."""
    edges = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    edges = edges.astype(np.int64)
    n = max(len(vertices), 1)
    _, directed = np.unique(edges[:, 0] * n + edges[:, 1], return_counts=True)
    undirected = np.sort(edges, axis=1)
    keys, uses = np.unique(undirected[:, 0] * n + undirected[:, 1], return_counts=True)
    open_keys = keys[uses == 1]

    def on_a_face(index: np.ndarray) -> np.ndarray:
        c = (vertices[index].astype(np.float64) - low) / size
        return ((np.abs(c) <= tolerance) | (np.abs(c - 1.0) <= tolerance)).any(axis=1)

    off_faces = ~(on_a_face(open_keys // n) & on_a_face(open_keys % n))
    return int((directed > 1).sum()), int((uses > 2).sum()), int(off_faces.sum())


def bounding_cube(points: np.ndarray, scale: float) -> tuple[np.ndarray, float]:
    """The cube psr reconstructs in: centred on the bounding box, `scale` times its longest side."""
    low, high = points.min(0).astype(np.float64), points.max(0).astype(np.float64)
    size = scale * float((high - low).max())
    return (low + high) / 2 - size / 2, size


def synthetic(rng: np.random.Generator, n: int) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """A box (sharp edges, faces on the cube's when scale = 1), a sphere and an open hemisphere."""
    half = np.array([1.0, 0.8, 0.6])
    axis = rng.integers(0, 3, n)
    side = rng.choice([-1.0, 1.0], n)
    box = rng.uniform(-half, half, (n, 3))
    box_normals = np.zeros((n, 3))
    box[np.arange(n), axis] = side * half[axis]
    box_normals[np.arange(n), axis] = side
    sphere = rng.normal(size=(2 * n, 3))
    sphere /= np.linalg.norm(sphere, axis=1)[:, None]
    upper = sphere[:, 2] > 0
    return {
        "box": (box.astype(np.float32), box_normals.astype(np.float32)),
        "sphere": (sphere[:n].astype(np.float32), sphere[:n].astype(np.float32)),
        "hemisphere": (sphere[upper].astype(np.float32), sphere[upper].astype(np.float32)),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scans", nargs="*", default=[], help="shared-data scan names")
    parser.add_argument(
        "--data", default=os.environ.get("PSR_DATA_DIR", ROOT.parent / "shared" / "data")
    )
    parser.add_argument("--max-points", type=int, default=150_000, help="subsample larger scans")
    parser.add_argument("--synthetic-points", type=int, default=20_000)
    parser.add_argument("--no-synthetic", action="store_true")
    parser.add_argument("--depths", default="5,7,9")
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--seed", type=int, default=3)
    parser.add_argument("--library", help="a libpsr.so to use with this tree's package sources")
    args = parser.parse_args()
    psr = import_psr(args.library)
    rng = np.random.default_rng(args.seed)

    clouds = {} if args.no_synthetic else synthetic(rng, args.synthetic_points)
    for name in args.scans:
        cloud = psr.read_ply(Path(args.data) / f"{name}.ply")
        points = np.asarray(cloud.points, dtype=np.float32)
        normals = np.asarray(cloud.normals, dtype=np.float32)
        if len(points) > args.max_points:
            keep = rng.choice(len(points), args.max_points, replace=False)
            points, normals = points[keep], normals[keep]
        clouds[name] = (points, normals)

    depths = [int(d) for d in args.depths.split(",")]
    grid = itertools.product(
        clouds.items(), [1, 2], ["free", "neumann", "dirichlet"], [1.0, 1.1, 2.0], [0, 5], depths
    )
    runs = failures = 0
    started = time.time()
    for (name, (points, normals)), degree, boundary, scale, full_depth, depth in grid:
        extra = {
            "splatting": str(rng.choice(["bspline", "trilinear"])),
            "vertex_placement": str(rng.choice(["fitted", "on_isosurface"])),
            "samples_per_node": float(rng.choice([1.0, 1.5, 5.0, 20.0])),
            "kernel_depth": int(rng.integers(max(depth - 4, 0), depth + 1)),
        }
        label = (
            f"{name} degree {degree} {boundary} scale {scale} full depth {full_depth} "
            f"depth {depth} {extra}"
        )
        try:
            mesh = psr.reconstruct(
                points,
                normals,
                depth=depth,
                degree=degree,
                boundary=boundary,
                scale=scale,
                full_depth=full_depth,
                threads=args.threads,
                min_component_samples=0,
                **extra,
            )
        except psr.PsrError as error:
            print(f"ERROR {label}: {error}", flush=True)
            failures += 1
            continue
        runs += 1
        low, size = bounding_cube(points, scale)
        magnitude = float(np.abs(points).max())
        tolerance = max(0.25 / 2**mesh.finest_depth, 4 * magnitude / size * 1.2e-7)
        found = violations(mesh.vertices, mesh.triangles, low, size, tolerance)
        if any(found):
            failures += 1
            print(
                f"BAD {label}: directed twice, edges in > 2, open off the faces = {found}",
                flush=True,
            )
    print(f"{runs} meshes, {failures} failures, {time.time() - started:.0f} s")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
