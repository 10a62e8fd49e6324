#!/usr/bin/env python3
"""A picture of a mesh of any size (tens of millions of triangles), for the out-of-core
showcase in docs/benchmarks.md: the whole mesh and a close-up, side by side.

    python3 bench/mesh_picture.py --mesh planet_200m_d11.ply \
        --out docs/gallery/planet_200m_d11.png --title "200 M points, depth 11"

Reads a binary little-endian PLY as psr writes it (float x y z, any further float vertex
properties, faces as a uchar count and int indices, triangles only) with bench/trim_render.py's
reader. Each vertex gets the area-weighted normal of its triangles; the vertices are drawn as
pixels, orthographically, with a z-buffer (the nearest vertex per pixel) and Lambert shading. At
the resolutions used here a mesh of millions of vertices has several vertices per pixel, so this
shows the surface as a triangle rasteriser would, in seconds and with numpy alone. The close-up
draws the triangles within a square window around the point of the surface nearest the viewer's
centre line, each one painted (far to near, shaded by its own normal), so its detail is the
mesh's own, triangle by triangle.

Needs numpy (bench/requirements.txt) and matplotlib (`pip install matplotlib`)."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from trim_render import read_ply  # noqa: E402


def vertex_normals(v: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals (unit; zero where a vertex has no area)."""
    n = np.zeros_like(v)
    chunk = 1 << 22
    for start in range(0, t.shape[0], chunk):
        tri = t[start : start + chunk]
        a, b, c = v[tri[:, 0]], v[tri[:, 1]], v[tri[:, 2]]
        face = np.cross(b - a, c - a)  # length: twice the area
        for k in range(3):
            np.add.at(n, tri[:, k], face)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return n / np.maximum(length, 1e-30)


def rotation(azimuth: float, elevation: float) -> np.ndarray:
    """Rows: the screen's right, up and towards-the-viewer axes for a view from (azimuth,
    elevation) in degrees, z up."""
    a, e = np.radians(azimuth), np.radians(elevation)
    towards = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
    right = np.cross([0.0, 0.0, 1.0], towards)
    right /= np.linalg.norm(right)
    up = np.cross(towards, right)
    return np.stack([right, up, towards])


def rasterise(screen: np.ndarray, shade: np.ndarray, lo: np.ndarray, pixel: float, size: int):
    """The image (size×size, NaN where empty) of the points `screen` (n×3: right, up, towards
    the viewer) with their `shade`, pixels of `pixel` width from the lower-left corner `lo`."""
    ij = np.floor((screen[:, :2] - lo) / pixel).astype(np.int64)
    inside = np.all((ij >= 0) & (ij < size), axis=1)
    ij, depth, shade = ij[inside], screen[inside, 2], shade[inside]
    cell = (size - 1 - ij[:, 1]) * size + ij[:, 0]
    # The nearest point of each pixel: sorted by pixel, then by depth towards the viewer.
    order = np.lexsort((-depth, cell))
    cell, shade = cell[order], shade[order]
    first = np.ones(cell.shape[0], dtype=bool)
    first[1:] = cell[1:] != cell[:-1]
    image = np.full(size * size, np.nan)
    image[cell[first]] = shade[first]
    image = image.reshape(size, size)
    # A pixel no visible point fell in, amid pixels that have one, gets their mean (the points
    # are scattered, not a grid: a few pixels of a covered area miss out).
    padded = np.pad(image, 1, constant_values=np.nan)
    around = np.stack(
        [
            padded[1 + di : 1 + di + size, 1 + dj : 1 + dj + size]
            for di in (-1, 0, 1)
            for dj in (-1, 0, 1)
        ]
    )
    covered = np.sum(~np.isnan(around), axis=0)
    gaps = np.isnan(image) & (covered >= 5)
    image[gaps] = np.nanmean(around[:, gaps], axis=0)
    return image


def draw_close_up(ax, screen, t, light, focus, extent) -> None:
    """The triangles of the square window of side `extent` around `focus` (screen
    coordinates) that face the viewer, painted far to near, each shaded by its own normal."""
    lo, hi = focus - extent / 2, focus + extent / 2
    inside = np.all((screen[:, :2] >= lo) & (screen[:, :2] <= hi), axis=1)
    tri = t[np.any(inside[t], axis=1)]
    corners = screen[tri]  # triangles × 3 corners × (right, up, towards)
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    facing = normal[:, 2] > 0
    corners, normal = corners[facing], normal[facing]
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-30)
    shade = np.clip(normal @ light, 0.0, 1.0) * 0.7 + 0.3
    order = np.argsort(corners[:, :, 2].mean(axis=1))
    polygons = PolyCollection(
        corners[order, :, :2],
        facecolors=np.repeat(shade[order, None], 3, axis=1),
        edgecolors="none",
        antialiased=False,
    )
    ax.add_collection(polygons)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mesh", required=True, help="binary PLY written by psr")
    parser.add_argument("--out", required=True, help="PNG to write")
    parser.add_argument("--title", default="", help="the picture's title")
    parser.add_argument("--size", type=int, default=1600, help="pixels a side of each panel")
    parser.add_argument("--zoom", type=float, default=32.0, help="the close-up's magnification")
    parser.add_argument("--view", type=float, nargs=2, default=(35.0, 25.0), metavar=("AZ", "EL"))
    args = parser.parse_args()

    started = time.time()
    v, t = read_ply(args.mesh)
    print(f"{args.mesh}: {v.shape[0]:,} vertices, {t.shape[0]:,} triangles", file=sys.stderr)
    n = vertex_normals(v, t)
    rot = rotation(*args.view)
    screen = v.astype(np.float64) @ rot.T
    light = np.array([-0.4, 0.5, 0.77])
    light /= np.linalg.norm(light)
    shade = np.clip((n.astype(np.float64) @ rot.T) @ light, 0.0, 1.0) * 0.7 + 0.3

    # Only the vertices facing the viewer: where the front misses a pixel, the far side of a
    # closed surface would show through.
    facing = (n.astype(np.float64) @ rot.T)[:, 2] > 0
    lo, hi = screen[:, :2].min(axis=0), screen[:, :2].max(axis=0)
    extent = float(np.max(hi - lo)) * 1.02
    centre = (lo + hi) / 2
    whole = rasterise(
        screen[facing], shade[facing], centre - extent / 2, extent / args.size, args.size
    )
    # The close-up: around the surface point nearest the viewer near the centre of the view.
    near_axis = np.linalg.norm(screen[:, :2] - centre, axis=1) < extent / 50
    focus = screen[near_axis][np.argmax(screen[near_axis, 2]), :2]
    close_extent = extent / args.zoom

    fig, axes = plt.subplots(1, 2, figsize=(16, 8.4), dpi=args.size / 8)
    cmap = matplotlib.colormaps["gray"].copy()
    cmap.set_bad("white")
    axes[0].imshow(whole, cmap=cmap, vmin=0.0, vmax=1.0, interpolation="nearest")
    axes[0].set_title(f"whole mesh: {v.shape[0]:,} vertices, {t.shape[0]:,} triangles")
    # The close-up's square on the whole view.
    corner = (focus - close_extent / 2 - (centre - extent / 2)) / (extent / args.size)
    side = args.size / args.zoom
    axes[0].add_patch(
        matplotlib.patches.Rectangle(
            (corner[0], args.size - corner[1] - side), side, side, fill=False, color="red"
        )
    )
    draw_close_up(axes[1], screen, t, light, focus, close_extent)
    axes[1].set_title(f"the red square, {args.zoom:g}× larger: every triangle drawn")
    for ax in axes:
        ax.set_axis_off()
    fig.suptitle(args.title, fontsize="x-large")
    fig.tight_layout(rect=(0, 0, 1, 0.95))
    fig.savefig(args.out)
    print(f"wrote {args.out} in {time.time() - started:.1f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
