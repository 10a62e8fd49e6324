#!/usr/bin/env python3
"""Renders meshes written by psr (binary PLY) side by side to one PNG, flat shaded, e.g. a mesh
before and after trimming:

    cargo run --release --example trim -- ../shared/data/lion_takanawa_rgb.ply --depth 8 \\
        --out-before /tmp/before.ply --out-after /tmp/after.ply
    python3 bench/trim_render.py /tmp/before.ply /tmp/after.ply --out docs/trim_lion.png

A painter's-algorithm software render with matplotlib and numpy only (no OpenGL): triangles are
projected along the view direction, sorted far to near and filled with a grey for the angle
between their normal and the light; back faces are drawn darker and tinted so that the inside of
an open surface shows. Optional: nothing in the tests needs it.
"""
import argparse
import sys

import numpy as np


def read_ply(path):
    """Vertices (n, 3) and triangles (m, 3) of a binary little-endian PLY as psr writes it."""
    with open(path, "rb") as f:
        header = b""
        while not header.endswith(b"end_header\n"):
            line = f.readline()
            if not line:
                sys.exit(f"{path}: no end_header")
            header += line
        lines = header.decode("ascii").splitlines()
        if "format binary_little_endian 1.0" not in lines:
            sys.exit(f"{path}: not binary little-endian PLY")
        nv = nf = 0
        vertex_props = 0
        element = None
        for line in lines:
            words = line.split()
            if words[:1] == ["element"]:
                element = words[1]
                if element == "vertex":
                    nv = int(words[2])
                elif element == "face":
                    nf = int(words[2])
            elif words[:1] == ["property"] and element == "vertex":
                if words[1] != "float":
                    sys.exit(f"{path}: vertex property {words[-1]} is not float")
                vertex_props += 1
        vertices = np.frombuffer(f.read(4 * vertex_props * nv), dtype="<f4").reshape(nv, vertex_props)
        faces = np.frombuffer(f.read(13 * nf), dtype=np.uint8).reshape(nf, 13)
        if np.any(faces[:, 0] != 3):
            sys.exit(f"{path}: only triangles are supported")
        triangles = faces[:, 1:].copy().view("<i4").reshape(nf, 3)
    return vertices[:, :3].astype(np.float64), triangles


def view_basis(direction, up):
    d = np.asarray(direction, float)
    d /= np.linalg.norm(d)
    right = np.cross(d, up)
    right /= np.linalg.norm(right)
    return right, np.cross(right, d), d


def render(ax, vertices, triangles, basis, bounds, title):
    from matplotlib.collections import PolyCollection

    right, up, forward = basis
    p = vertices[triangles]  # (m, 3, 3)
    normals = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    lengths = np.linalg.norm(normals, axis=1)
    normals /= np.where(lengths > 0, lengths, 1.0)[:, None]
    facing = normals @ -forward
    light = np.clip(np.abs(normals @ (-forward + 0.4 * up - 0.3 * right) / 1.12), 0.0, 1.0)
    grey = 0.25 + 0.7 * light
    colours = np.stack([grey, grey, grey, np.ones_like(grey)], axis=1)
    back = facing < 0
    colours[back] = np.stack([0.55 * grey[back], 0.35 * grey[back], 0.3 * grey[back], np.ones(back.sum())], axis=1)
    depth = (p.mean(axis=1) @ forward)
    order = np.argsort(-depth)
    xy = np.stack([p @ right, p @ up], axis=-1)[order]
    ax.add_collection(PolyCollection(xy, facecolors=colours[order], edgecolors="none", antialiased=False))
    ax.set_xlim(bounds[0], bounds[1])
    ax.set_ylim(bounds[2], bounds[3])
    ax.set_aspect("equal")
    ax.set_axis_off()
    ax.set_title(title, fontsize=9)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("meshes", nargs="+", help="binary PLY meshes written by psr")
    parser.add_argument("--out", required=True, help="PNG to write")
    parser.add_argument("--view", default="1,-1,-0.6", help="view direction X,Y,Z (default 1,-1,-0.6)")
    parser.add_argument("--up", default="0,0,1", help="up direction X,Y,Z (default 0,0,1)")
    parser.add_argument("--size", type=float, default=6.0, help="inches per panel (default 6)")
    args = parser.parse_args()

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    basis = view_basis([float(x) for x in args.view.split(",")], [float(x) for x in args.up.split(",")])
    meshes = [read_ply(path) for path in args.meshes]
    # One frame for all panels: the first mesh's extent, so before and after line up.
    v0 = meshes[0][0]
    x, y = v0 @ basis[0], v0 @ basis[1]
    pad = 0.03 * max(np.ptp(x), np.ptp(y))
    bounds = (x.min() - pad, x.max() + pad, y.min() - pad, y.max() + pad)
    fig, axes = plt.subplots(1, len(meshes), figsize=(args.size * len(meshes), args.size))
    for ax, path, (vertices, triangles) in zip(np.atleast_1d(axes), args.meshes, meshes):
        render(ax, vertices, triangles, basis, bounds, f"{path.split('/')[-1]}: {len(triangles):,} triangles")
    fig.tight_layout()
    fig.savefig(args.out, dpi=100)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
