"""Issue 16's "bubbles" on the shared scans: psr's default mesh at each depth, its connected
components, and for each but the largest the number of input samples within one cell of its
vertices (the finest cell, the bounding cube's side / 2^depth, or the component's mean edge
length where it is longer: its own resolution), the measure tests/bubbles.rs asserts at
depths 10-11 (12 for the bunny). This script runs the depths too slow for the test suite
(the Happy Buddha at 12) and any other scan or setting.

    python3 bench/bubbles.py --inputs happy_buddha_scans --depths 10,11,12
    python3 bench/bubbles.py --inputs bunny_scans --depths 11 --psr-args '--min-component-samples 0'

Prints, per run: components, how many psr left out (--verbose's count) and the components
supported by fewer than --min-support samples (the rule tests/bubbles.rs asserts: 8), with
their (triangles, samples). Needs numpy, scipy and open3d (bench/requirements.txt, plus scipy)
and target/release/psr; data from $PSR_DATA_DIR (default ../shared/data)."""
import argparse
import os
import re
import shlex
import subprocess
import sys
import tempfile

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)


def components_and_support(mesh_path, points, cell):
    import open3d as o3d

    mesh = o3d.io.read_triangle_mesh(mesh_path)
    v = np.asarray(mesh.vertices)
    t = np.asarray(mesh.triangles)
    n = len(v)
    edges = np.concatenate([t[:, [0, 1]], t[:, [1, 2]]])
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    count, label = connected_components(graph, directed=False)
    triangles = np.bincount(label[t[:, 0]], minlength=count)
    largest = int(np.argmax(triangles))
    tree = cKDTree(points)
    out = []
    for c in range(count):
        if c == largest or triangles[c] == 0:
            continue
        tc = t[label[t[:, 0]] == c]
        edges = np.linalg.norm(v[tc] - v[np.roll(tc, 1, axis=1)], axis=2).mean()
        near = tree.query_ball_point(v[label == c], max(cell, edges))
        support = len(set(i for ids in near for i in ids))
        out.append((int(triangles[c]), support))
    return int((triangles > 0).sum()), sorted(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--inputs", default="bunny_scans,happy_buddha_scans")
    ap.add_argument("--depths", default="10,11,12")
    ap.add_argument("--psr-args", default="", help="extra psr options")
    ap.add_argument("--min-support", type=int, default=8)
    args = ap.parse_args()
    import open3d as o3d

    data = os.environ.get("PSR_DATA_DIR", os.path.join(ROOT, "..", "shared", "data"))
    psr = os.path.join(ROOT, "target", "release", "psr")
    if not os.path.exists(psr):
        sys.exit("build psr first: cargo build --release")
    for name in args.inputs.split(","):
        path = os.path.join(data, name + ".ply")
        points = np.asarray(o3d.io.read_point_cloud(path).points)
        side = (points.max(axis=0) - points.min(axis=0)).max() * 1.1
        for depth in [int(d) for d in args.depths.split(",")]:
            with tempfile.TemporaryDirectory() as tmp:
                out = os.path.join(tmp, "mesh.ply")
                cmd = [psr, "--in", path, "--out", out, "--depth", str(depth), "--verbose"]
                cmd += shlex.split(args.psr_args)
                run = subprocess.run(cmd, capture_output=True, text=True, check=True)
                left = re.search(r"(\d+) unsupported components left out", run.stderr)
                count, support = components_and_support(out, points, side / 2**depth)
            under = [s for s in support if s[1] < args.min_support]
            print(
                f"{name} depth {depth} {args.psr_args}: {count} components, "
                f"{left.group(1) if left else '?'} left out by psr; other components "
                f"(triangles, samples within a cell) {support}; under {args.min_support}: {under}",
                flush=True,
            )


if __name__ == "__main__":
    main()
