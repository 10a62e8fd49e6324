#!/usr/bin/env python3
"""Run Open3D's Poisson reconstruction on one PLY point cloud, in its own process.

bench.py starts this script under `/usr/bin/time -v`, so the peak RSS it reports is Open3D's
alone. Prints one JSON line on stdout:

    {"points": N, "vertices": V, "triangles": T, "import_seconds": s, "read_seconds": s,
     "poisson_seconds": s, "write_seconds": s, "open3d": "0.20.0", ...}

`poisson_seconds` is the in-process time of create_from_point_cloud_poisson alone.

    python3 bench/open3d_poisson.py --in cloud.ply --depth 8 --threads 2 [--out mesh.ply]
    python3 bench/open3d_poisson.py --import-only     # the cost of starting Python + Open3D
"""

import argparse
import json
import sys
import time


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--in", dest="input", help="input PLY with x y z nx ny nz")
    parser.add_argument("--out", help="write the mesh here (binary PLY); default: do not write")
    parser.add_argument("--depth", type=int, default=8)
    parser.add_argument("--threads", type=int, default=-1, help="n_threads (-1 = Open3D's choice)")
    parser.add_argument("--scale", type=float, default=1.1)
    parser.add_argument("--full-depth", type=int, default=5)
    parser.add_argument("--samples-per-node", type=float, default=1.5)
    parser.add_argument("--point-weight", type=float, default=2.0)
    parser.add_argument("--import-only", action="store_true", help="import Open3D and exit (baseline cost)")
    args = parser.parse_args()

    t0 = time.perf_counter()
    import open3d as o3d  # noqa: E402  (timed on purpose)

    import_seconds = time.perf_counter() - t0
    result = {"open3d": o3d.__version__, "import_seconds": import_seconds}
    if args.import_only:
        print(json.dumps(result))
        return 0
    if not args.input:
        parser.error("--in is required unless --import-only")

    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    t0 = time.perf_counter()
    pcd = o3d.io.read_point_cloud(args.input)
    result["read_seconds"] = time.perf_counter() - t0
    result["points"] = len(pcd.points)
    if result["points"] == 0:
        print(f"open3d_poisson: no points read from {args.input}", file=sys.stderr)
        return 1
    if not pcd.has_normals():
        print(f"open3d_poisson: {args.input} has no normals", file=sys.stderr)
        return 1

    t0 = time.perf_counter()
    mesh, _densities = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(
        pcd,
        depth=args.depth,
        width=0,
        scale=args.scale,
        linear_fit=False,
        n_threads=args.threads,
        full_depth=args.full_depth,
        samples_per_node=args.samples_per_node,
        point_weight=args.point_weight,
    )
    result["poisson_seconds"] = time.perf_counter() - t0
    result["vertices"] = len(mesh.vertices)
    result["triangles"] = len(mesh.triangles)
    result["params"] = {
        "depth": args.depth,
        "width": 0,
        "scale": args.scale,
        "linear_fit": False,
        "n_threads": args.threads,
        "full_depth": args.full_depth,
        "samples_per_node": args.samples_per_node,
        "point_weight": args.point_weight,
    }

    if args.out:
        t0 = time.perf_counter()
        ok = o3d.io.write_triangle_mesh(args.out, mesh, write_ascii=False, compressed=False)
        result["write_seconds"] = time.perf_counter() - t0
        if not ok:
            print(f"open3d_poisson: could not write {args.out}", file=sys.stderr)
            return 1
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
