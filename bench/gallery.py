#!/usr/bin/env python3
"""Regenerates docs/gallery.md and its pictures: psr's meshes of the sample and shared scans,
and time and memory against depth beside Open3D's Poisson from the benchmark data.

    pip install ./python matplotlib
    python3 bench/gallery.py [--depth 8] [--section latest]

Meshes are reconstructed with the Python package (psr.reconstruct, default parameters) and
drawn by a small software renderer (matplotlib, no GPU): triangles projected orthographically,
sorted far to near, shaded by the angle of their normal to the light, or coloured by the
points' colours where the scan has them. The plots read the table of one bench.py section of
docs/benchmarks.md (``<!-- bench:begin NAME -->``; default ``latest``), so they show measured
runs, with that section's date, machine and command quoted under them. Scans missing from
$PSR_DATA_DIR (default ../shared/data) are skipped with a message.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402

import psr  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
DATA = Path(os.environ.get("PSR_DATA_DIR", str(ROOT.parent / "shared" / "data")))
DOCS = ROOT / "docs"
OUT = DOCS / "gallery"

# name, file, the scan's up axis, view (azimuth, elevation in degrees), what to say
SCANS = [
    ("kitten", ROOT / "examples" / "data" / "kitten_cgal.ply", "y", (30, 15), "CGAL's kitten"),
    ("oni", DATA / "oni_cgal.ply", "y", (20, 10), "CGAL's oni mask"),
    ("bunny", DATA / "bunny_scans.ply", "y", (0, 10), "the Stanford bunny's range scans"),
    ("buddha", DATA / "happy_buddha_scans.ply", "y", (0, 5), "the Stanford Buddha's scans"),
    ("lion", DATA / "lion_takanawa_rgb.ply", "z", (135, 25), "a coloured photogrammetry lion"),
]


def rotation(azimuth: float, elevation: float) -> np.ndarray:
    a, e = np.radians(azimuth), np.radians(elevation)
    rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    rx = np.array([[1, 0, 0], [0, np.cos(e), -np.sin(e)], [0, np.sin(e), np.cos(e)]])
    return rx @ rz


def up_axis(vertices: np.ndarray, up: str) -> np.ndarray:
    """Turns the scan so that its vertical (y or z) is the picture's up (z here)."""
    if up == "z":
        return vertices
    return vertices[:, [0, 2, 1]] * np.array([1.0, -1.0, 1.0])


def render(ax: plt.Axes, mesh: psr.Mesh, up: str, view: tuple[float, float], title: str) -> None:
    v = up_axis(np.asarray(mesh.vertices, np.float64), up)
    v = v @ rotation(*view).T  # the viewer looks along +y
    t = mesh.triangles.astype(np.int64)
    tri = v[t]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-30)
    light = np.array([-0.4, -1.0, 0.6])
    light /= np.linalg.norm(light)
    lit = np.clip(normal @ light, 0, 1)
    facing = normal[:, 1] < 0  # towards the viewer, who is at -y
    shade = 0.25 + 0.75 * lit
    if mesh.colors is not None:
        base = np.clip(mesh.colors[:, :3][t].mean(axis=1), 0, 1)
    else:
        base = np.tile([0.80, 0.78, 0.72], (len(t), 1))
    rgb = base * shade[:, None]
    rgb[~facing] = 0.35 * base[~facing] + np.array([0.25, 0.05, 0.05])  # insides: dark red
    order = np.argsort(-tri[:, :, 1].mean(axis=1))  # far to near
    polys = tri[order][:, :, [0, 2]]
    ax.add_collection(
        PolyCollection(
            polys, facecolors=np.clip(rgb[order], 0, 1), edgecolors="none", antialiased=False
        )
    )
    lo, hi = v[:, [0, 2]].min(axis=0), v[:, [0, 2]].max(axis=0)
    pad = 0.03 * (hi - lo).max()
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal")
    ax.axis("off")
    ax.set_title(title, fontsize=9)


def pictures(depth: int) -> list[str]:
    lines = []
    for name, path, up, view, what in SCANS:
        if not path.exists():
            print(f"gallery: {path} not found, {name} skipped", file=sys.stderr)
            continue
        cloud = psr.read_ply(path)
        t0 = time.perf_counter()
        mesh = psr.reconstruct(cloud.points, cloud.normals, depth=depth, colors=cloud.colors)
        seconds = time.perf_counter() - t0
        trimmed = mesh.trim()
        fig, axes = plt.subplots(1, 2, figsize=(9, 4.6), dpi=110)
        render(axes[0], mesh, up, view, f"psr, depth {depth}: {len(mesh.triangles):,} triangles")
        render(
            axes[1],
            trimmed,
            up,
            view,
            f"trimmed (automatic threshold): {len(trimmed.triangles):,} triangles",
        )
        fig.tight_layout()
        png = OUT / f"{name}.png"
        fig.savefig(png)
        plt.close(fig)
        print(f"gallery: {png} ({seconds:.1f} s to reconstruct)", file=sys.stderr)
        colours = " with its points' colours" if mesh.colors is not None else ""
        lines += [
            f"### {name}",
            "",
            f"{what}, {len(cloud):,} points (`{path.name}`): `psr.reconstruct(cloud.points, "
            f"cloud.normals, depth={depth}{', colors=cloud.colors' if colours else ''})`"
            f"{colours}, then `mesh.trim()`. Inside faces, where the surface is open after "
            "trimming, are drawn dark red.",
            "",
            f"![{name}](gallery/{name}.png)",
            "",
        ]
    return lines


def bench_table(section: str) -> tuple[list[dict[str, str]], list[str]]:
    text = (DOCS / "benchmarks.md").read_text()
    m = re.search(rf"<!-- bench:begin {re.escape(section)} -->(.*?)<!-- bench:end", text, re.S)
    if not m:
        sys.exit(f"no section {section} in docs/benchmarks.md")
    body = m.group(1).splitlines()
    rows = [line for line in body if line.startswith("|")]
    header = [c.strip() for c in rows[0].strip("|").split("|")]
    table = [dict(zip(header, (c.strip() for c in r.strip("|").split("|")))) for r in rows[2:]]
    # Only the rows of the timing table (a section may hold other tables).
    table = [r for r in table if r.get("depth", "").isdigit() and "psr wall s" in r]
    facts = [line for line in body if line.startswith(("- date", "- command", "- machine"))]
    return table, facts


def plots(section: str) -> list[str]:
    table, facts = bench_table(section)
    inputs = sorted({r["input"] for r in table})
    fig, axes = plt.subplots(2, len(inputs), figsize=(5 * len(inputs), 7.5), dpi=100, squeeze=False)
    for col, name in enumerate(inputs):
        for threads, style in (("1", "--"), ("2", "-")):
            rows = [r for r in table if r["input"] == name and r["threads"] == threads]
            if not rows:
                continue
            d = [int(r["depth"]) for r in rows]
            for row, (what, unit) in enumerate((("wall s", "s"), ("peak MiB", "MiB"))):
                ax = axes[row][col]
                for tool, colour in (("psr", "tab:blue"), ("Open3D", "tab:orange")):
                    values = [float(r[f"{tool} {what}"].replace(",", "")) for r in rows]
                    ax.plot(
                        d,
                        values,
                        style,
                        marker="o",
                        color=colour,
                        label=f"{tool}, {threads} thread{'s' if threads != '1' else ''}",
                    )
                ax.set_xlabel("depth")
                ax.set_ylabel(f"{'wall time' if unit == 's' else 'peak memory'} ({unit})")
                ax.set_title(f"{name}: {'time' if unit == 's' else 'memory'}")
                ax.set_xticks(sorted(set(d)))
                ax.grid(alpha=0.3)
                ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(OUT / "time_memory.png")
    plt.close(fig)
    return [
        "## Time and memory against depth",
        "",
        f"From the `{section}` section of `docs/benchmarks.md` (whole processes under "
        "`/usr/bin/time -v`: reading the PLY, reconstructing, writing the mesh; Open3D's "
        "`create_from_point_cloud_poisson` with the same parameters):",
        "",
        *facts,
        "",
        "![time and memory against depth](gallery/time_memory.png)",
        "",
    ]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--depth", type=int, default=8)
    ap.add_argument("--section", default="latest")
    args = ap.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    lines = [
        "# Gallery: what psr makes",
        "",
        "Written by `python3 bench/gallery.py` (after `pip install ./python matplotlib`); "
        "rerun it to regenerate this page and `docs/gallery/`. Every mesh below is the "
        "output of the Python package with its default parameters but the depth; the "
        "pictures are flat-shaded software renders.",
        "",
        "## Meshes of the sample and shared scans",
        "",
        *pictures(args.depth),
        *plots(args.section),
    ]
    (DOCS / "gallery.md").write_text("\n".join(lines))
    print("gallery: wrote docs/gallery.md", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
