#!/usr/bin/env python3
"""The topology of a large mesh, for benchmark records (docs/benchmarks.md, issue 20): whether
it is closed, manifold and consistently oriented, its Euler characteristic and its duplicated
vertices, with numpy alone (the 123-million-triangle planet at depth 12 in 7 minutes and
14.5 GB).

    python3 bench/mesh_topology.py planet_200m_d11.ply [more.ply ...]

Reads binary little-endian PLYs as psr writes them (with bench/trim_render.py's reader).
Prints per mesh: V, E, F, V − E + F, the edges with one triangle (open), with more than two
(non-manifold), the directed edges used twice (two triangles disagreeing in orientation
across an edge, or a fold), and the vertices at the same position as another.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from trim_render import read_ply  # noqa: E402


def edge_keys(triangles: np.ndarray, undirected: bool) -> np.ndarray:
    """Every triangle's three edges as 64-bit keys (first vertex << 32 | second), sorted; with
    `undirected`, each edge's smaller vertex first. One array of 3 F keys at a time (24 bytes
    a triangle)."""
    keys = np.empty(3 * triangles.shape[0], dtype=np.int64)
    for slot, (i, j) in enumerate(((0, 1), (1, 2), (2, 0))):
        a = triangles[:, i].astype(np.int64)
        b = triangles[:, j].astype(np.int64)
        if undirected:
            a, b = np.minimum(a, b), np.maximum(a, b)
        keys[slot::3] = (a << 32) | b
        del a, b
    keys.sort()
    return keys


def run_lengths(sorted_keys: np.ndarray) -> np.ndarray:
    """How many times each distinct key occurs in a sorted array."""
    starts = np.flatnonzero(np.diff(sorted_keys)) + 1
    bounds = np.concatenate(([0], starts, [sorted_keys.shape[0]]))
    return np.diff(bounds)


def topology(vertices: np.ndarray, triangles: np.ndarray) -> dict[str, int]:
    directed = edge_keys(triangles, undirected=False)
    repeated_directed = directed.shape[0] - run_lengths(directed).shape[0]
    del directed
    uses = run_lengths(edge_keys(triangles, undirected=True))
    by_position = vertices[np.lexsort(vertices.T)]
    same = np.all(by_position[1:] == by_position[:-1], axis=1)
    del by_position
    v, e, f = vertices.shape[0], uses.shape[0], triangles.shape[0]
    return {
        "V": v,
        "E": e,
        "F": f,
        "euler": v - e + f,
        "open edges": int(np.sum(uses == 1)),
        "non-manifold edges": int(np.sum(uses > 2)),
        "directed edges used twice": int(repeated_directed),
        "duplicated vertices": int(np.sum(same)),
    }


def main() -> int:
    if len(sys.argv) < 2:
        print(__doc__, file=sys.stderr)
        return 2
    for path in sys.argv[1:]:
        figures = topology(*read_ply(path))
        closed = (
            figures["open edges"] == 0
            and figures["non-manifold edges"] == 0
            and figures["directed edges used twice"] == 0
        )
        print(
            f"{path}: "
            + ", ".join(f"{k} {v:,}" for k, v in figures.items())
            + (": a closed, consistently oriented 2-manifold" if closed else ": NOT closed")
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
