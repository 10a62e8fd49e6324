#!/usr/bin/env python3
"""How close reconstructions come to samples held out of them: an accuracy figure for real
scans, which have no true surface to compare with (issue 16's screening that follows the noise).

A fixed random tenth of the cloud's points (seed 7) is held out; the other nine tenths are
reconstructed by each variant, and the exact distance from every held-out point to the mesh
(Open3D's `RaycastingScene`) is averaged, over the cloud's bounding-box diagonal. A surface
pulled onto the reconstructed samples' own noise is farther from the held-out ones (their noise
is their own); one smoothed past the scan's detail is farther too. Unlike the distance to the
input points or to a reference mesh built from the same scans, this does not reward following
the noise.

    python3 bench/heldout.py --cloud ../shared/data/bunny_scans.ply --depth 10 \\
        --variants psr,fixed,pw0,o3d
    python3 bench/heldout.py --cloud ../shared/data/bunny_scans.ply --depths 8,9,10,11,12 \\
        --variants psr,fixed,pw0,o3d --plot docs/gallery/heldout_bunny.png

With --depths, every variant runs at every depth; --plot draws each variant's held-out mean
against the depth (needs matplotlib).

Variants: psr (the default, whose screening follows the samples' noise), fixed
(--screening-follows-noise false: the screening scaled by 2^depth, PoissonRecon's scale),
follow (--screening-follows-noise, the default before 2026-12-06), pw0 (--point-weight 0), o3d
(Open3D's Poisson, a build of PoissonRecon), and psr:ARGS (psr with the extra arguments ARGS,
words split on '+', e.g. psr:--degree+1). Needs numpy and open3d (bench/requirements.txt) and
target/release/psr (--psr). Work files go to bench/runs/heldout/ (not committed).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
# The psr variants by name: their extra arguments.
NAMED = {
    "psr": [],
    "fixed": ["--screening-follows-noise", "false"],
    "follow": ["--screening-follows-noise"],
    "pw0": ["--point-weight", "0"],
}


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--cloud", required=True, help="a PLY cloud with normals")
    parser.add_argument("--depth", type=int, default=10)
    parser.add_argument("--depths", help="comma-separated depths (instead of --depth)")
    parser.add_argument("--plot", help="a PNG of the held-out mean against the depth")
    parser.add_argument("--variants", default="psr,fixed,pw0,o3d")
    parser.add_argument("--fraction", type=float, default=0.1, help="the share held out")
    parser.add_argument("--seed", type=int, default=7, help="picks the points held out")
    parser.add_argument("--psr", default=os.path.join(HERE, "..", "target", "release", "psr"))
    args = parser.parse_args()

    import open3d as o3d

    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    cloud = o3d.io.read_point_cloud(args.cloud)
    points = np.asarray(cloud.points)
    normals = np.asarray(cloud.normals)
    if len(points) == 0 or len(normals) != len(points):
        print(f"heldout: {args.cloud} has no points with normals", file=sys.stderr)
        return 1
    held = np.random.default_rng(args.seed).random(len(points)) < args.fraction
    train = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points[~held]))
    train.normals = o3d.utility.Vector3dVector(normals[~held])
    work = os.path.join(HERE, "runs", "heldout")
    os.makedirs(work, exist_ok=True)
    name = os.path.splitext(os.path.basename(args.cloud))[0]
    train_path = os.path.join(work, f"{name}_train.ply")
    o3d.io.write_point_cloud(train_path, train)
    diagonal = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
    query = o3d.core.Tensor(points[held].astype(np.float32))
    depths = [int(d) for d in args.depths.split(",")] if args.depths else [args.depth]
    print(
        f"{name}: {len(points)} points, {int(held.sum())} held out (seed {args.seed}), "
        f"depths {','.join(map(str, depths))}, diagonal {diagonal:.6g}"
    )
    print("| depth | variant | vertices | held-out mean | RMS | median |")
    print("|---:|---|---:|---:|---:|---:|")
    means: dict[str, list[float]] = {}
    for depth in depths:
        for variant in args.variants.split(","):
            mesh_path = os.path.join(work, f"{name}_d{depth}_{variant.replace('/', '_')}.ply")
            if variant == "o3d":
                mesh, _ = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(
                    train, depth=depth
                )
                o3d.io.write_triangle_mesh(mesh_path, mesh)
            else:
                words = NAMED.get(variant)
                if words is None:
                    if not variant.startswith("psr:"):
                        print(f"heldout: unknown variant {variant}", file=sys.stderr)
                        return 1
                    words = variant[4:].split("+")
                command = [args.psr, "--in", train_path, "--out", mesh_path, "--quiet"]
                command += ["--depth", str(depth), *words]
                subprocess.run(command, check=True)
            mesh = o3d.t.io.read_triangle_mesh(mesh_path)
            scene = o3d.t.geometry.RaycastingScene()
            scene.add_triangles(mesh)
            d = scene.compute_distance(query).numpy().astype(np.float64) / diagonal
            means.setdefault(variant, []).append(float(d.mean()))
            print(
                f"| {depth} | {variant} | {mesh.vertex.positions.shape[0]} | {d.mean():.4e} | "
                f"{np.sqrt((d * d).mean()):.4e} | {np.median(d):.4e} |",
                flush=True,
            )
    if args.plot:
        plot(args.plot, name, args.seed, args.fraction, depths, means)
    return 0


LABELS = {
    "psr": "psr (default)",
    "fixed": "psr --screening-follows-noise false",
    "follow": "psr --screening-follows-noise",
    "pw0": "psr --point-weight 0",
    "o3d": "Open3D (PoissonRecon)",
}
# One colour per named variant in every picture.
COLORS = {"psr": "C0", "follow": "C1", "pw0": "C2", "o3d": "C3", "fixed": "C4"}


def plot(path, name, seed, fraction, depths, means):
    """Each variant's held-out mean distance against the depth, as a PNG at `path`."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(figsize=(6.4, 4.0), dpi=110)
    for variant, values in means.items():
        axes.plot(
            depths, values, marker="o", label=LABELS.get(variant, variant), color=COLORS.get(variant)
        )
    axes.set_xticks(depths)
    axes.set_xlabel("depth")
    axes.set_ylabel("mean distance to held-out points / diagonal")
    axes.set_title(f"{name}: {fraction:.0%} of the points held out (seed {seed})")
    axes.grid(alpha=0.3)
    axes.legend()
    figure.tight_layout()
    figure.savefig(path)
    print(f"heldout: wrote {path}")


if __name__ == "__main__":
    sys.exit(main())
