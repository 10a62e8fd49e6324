#!/usr/bin/env python3
"""Open3D's normal estimation and consistent orientation, timed the way bench/normals.py times
psr's: estimate_normals(KDTreeSearchParamKNN(k + 1)) (Open3D's k counts the point itself) and
orient_normals_consistent_tangent_plane(k + 1) on the file's positions, then the share of the
normals that agree in sign with the file's own.

    OMP_NUM_THREADS=N python3 bench/open3d_normals.py IN.ply [--neighbors 20]
"""
import argparse
import time

import numpy as np
import open3d as o3d


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("input")
    parser.add_argument("--neighbors", type=int, default=20)
    args = parser.parse_args()
    cloud = o3d.io.read_point_cloud(args.input)
    given = np.asarray(cloud.normals).copy()
    bare = o3d.geometry.PointCloud(cloud.points)
    k = args.neighbors + 1
    started = time.perf_counter()
    bare.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(k))
    estimated = time.perf_counter()
    bare.orient_normals_consistent_tangent_plane(k)
    oriented = time.perf_counter()
    normals = np.asarray(bare.normals)
    agreement = ""
    if len(given) == len(normals):
        share = float(np.mean(np.einsum("ij,ij->i", normals, given) > 0.0))
        agreement = f"; {100.0 * share:.3f} % agree in sign with the file's normals"
    print(
        f"open3d_normals: {len(normals)} points, k = {args.neighbors}, estimated in "
        f"{estimated - started:.2f} s and oriented in {oriented - estimated:.2f} s, "
        f"total {oriented - started:.2f} s{agreement}"
    )


if __name__ == "__main__":
    main()
