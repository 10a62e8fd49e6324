#!/usr/bin/env python3
"""How far the input points lie from reconstructed meshes: the accuracy figure of
docs/benchmarks.md's comparisons with Open3D (issue 17: "at equal or better distance to the
input points than Open3D").

For every point of the cloud, the exact distance to the nearest triangle of each mesh
(Open3D's `RaycastingScene.compute_distance`), over the cloud's bounding-box diagonal; prints
per mesh its vertex and triangle counts and the mean, RMS and 99th percentile of those
distances.

    python3 bench/point_distance.py --points happy_buddha_scans.ply psr_d1.ply open3d.ply

Needs Open3D and numpy (bench/requirements.txt).
"""

from __future__ import annotations

import argparse
import sys

import numpy as np


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--points", required=True, help="the input cloud (PLY)")
    parser.add_argument("meshes", nargs="+", help="meshes to measure (PLY)")
    args = parser.parse_args()

    import open3d as o3d

    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    cloud = o3d.io.read_point_cloud(args.points)
    points = np.asarray(cloud.points, dtype=np.float64)
    if len(points) == 0:
        print(f"point_distance: no points in {args.points}", file=sys.stderr)
        return 1
    diagonal = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
    query = o3d.core.Tensor(points.astype(np.float32))
    print(f"{args.points}: {len(points)} points, bounding-box diagonal {diagonal:.6g}")
    print("| mesh | vertices | triangles | mean | RMS | 99th percentile |")
    print("|---|---:|---:|---:|---:|---:|")
    for path in args.meshes:
        mesh = o3d.io.read_triangle_mesh(path)
        if len(mesh.triangles) == 0:
            print(f"point_distance: no triangles in {path}", file=sys.stderr)
            return 1
        scene = o3d.t.geometry.RaycastingScene()
        scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(mesh))
        d = scene.compute_distance(query).numpy().astype(np.float64) / diagonal
        print(
            f"| {path} | {len(mesh.vertices):,} | {len(mesh.triangles):,} | {d.mean():.4e} | "
            f"{np.sqrt((d * d).mean()):.4e} | {np.percentile(d, 99):.4e} |"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
