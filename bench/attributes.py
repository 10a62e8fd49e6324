#!/usr/bin/env python3
"""Colour accuracy of psr against Open3D's Poisson reconstruction (issue 16).

For each depth, reconstructs a coloured cloud (default: the lion scan) with the `psr` program
(which carries the input's colours onto the mesh by default) and with Open3D's
`create_from_point_cloud_poisson` (a build of Kazhdan's PoissonRecon, which interpolates the
points' colours onto its vertices), both through `bench.py`'s runners: one process each under
`/usr/bin/time -v`, Open3D with its own defaults spelled out as in `bench.py`.

The colour error of a mesh: for every input point, the closest point on the mesh (Open3D's
RaycastingScene, exact point-to-triangle) and the mesh's colour there, interpolated
barycentrically from the vertex colours of that triangle; the error is the Euclidean distance
between that colour and the point's own in RGB, 0–255 per channel (so at most 441.7), averaged
over all points. The mean absolute difference per channel (0–255) is given too. Both programs
write their colours as `uchar`, so both meshes are quantised alike.

The bleeding check: a synthetic plate 0.4 finest cells thick (red on top, blue below, green
around the rim), tilted so that its two faces share cells, written as a PLY and reconstructed
by both at the same depth. Vertices above the plate's mid-plane whose normal (from the mesh's
triangles) points up are on the top face and should be pure red, those below pointing down pure
blue; the table gives the other face's colour found there (the blue component on top, the red
one below, 0–255), away from the rim. A reconstruction that mixes the faces' colours shows
about half of each.

Prints Markdown; --out FILE also writes it, with the command line, date, machine and load, as
a section of FILE (replaced when rerun with the same --section).

    cargo build --release
    python3 bench/attributes.py                               # lion, depths 8 and 9, 2 threads
    python3 bench/attributes.py --depths 8 --skip-plate
    python3 bench/attributes.py --out docs/benchmarks.md --section issue16-colours

Needs numpy and Open3D (bench/requirements.txt).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import shlex
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench  # noqa: E402  (the runners, machine and section helpers of bench.py)


def closest_colours(mesh, points: np.ndarray) -> np.ndarray:
    """The mesh's RGB colour (0–1) at the closest surface point to each of `points`."""
    import open3d as o3d

    vertices = np.asarray(mesh.vertices, dtype=np.float32)
    triangles = np.asarray(mesh.triangles, dtype=np.uint32)
    colours = np.asarray(mesh.vertex_colors, dtype=np.float64)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(vertices), o3d.core.Tensor(triangles))
    found = scene.compute_closest_points(o3d.core.Tensor(points.astype(np.float32)))
    ids = found["primitive_ids"].numpy().astype(np.int64)
    uv = found["primitive_uvs"].numpy().astype(np.float64)
    # Embree's convention: p = (1 − u − v) v0 + u v1 + v v2. Checked against the returned points.
    w = np.column_stack([1.0 - uv[:, 0] - uv[:, 1], uv[:, 0], uv[:, 1]])
    corners = triangles[ids].astype(np.int64)
    rebuilt = np.einsum("ij,ijk->ik", w, vertices[corners].astype(np.float64))
    gap = np.abs(rebuilt - found["points"].numpy()).max()
    extent = np.ptp(vertices, axis=0).max()
    if gap > 1e-4 * extent:
        sys.exit(f"attributes: barycentric coordinates do not rebuild the closest points (off by {gap:g})")
    return np.einsum("ij,ijk->ik", w, colours[corners])


def colour_error(mesh_path: Path, points: np.ndarray, colours: np.ndarray) -> dict:
    """Mean Euclidean RGB and mean absolute per-channel error (0–255) of the mesh at `points`."""
    import open3d as o3d

    mesh = o3d.io.read_triangle_mesh(str(mesh_path))
    if not mesh.has_vertex_colors():
        return {"error": "the mesh has no vertex colours"}
    at_mesh = closest_colours(mesh, points) * 255.0
    diff = at_mesh - colours * 255.0
    return {
        "euclidean": float(np.linalg.norm(diff, axis=1).mean()),
        "per_channel": float(np.abs(diff).mean()),
    }


def plate_rotation(degrees_x: float, degrees_y: float) -> np.ndarray:
    """The plate's tilt: about y, then about x. A plate square to the axes and centred in the
    bounding cube has its faces on either side of a cell boundary (the cube's centre is one at
    every depth), where a kernel that stays inside one cell cannot mix them; tilted, the faces
    share cells."""
    ax, ay = np.radians(degrees_x), np.radians(degrees_y)
    rx = np.array([[1, 0, 0], [0, np.cos(ax), -np.sin(ax)], [0, np.sin(ax), np.cos(ax)]])
    ry = np.array([[np.cos(ay), 0, np.sin(ay)], [0, 1, 0], [-np.sin(ay), 0, np.cos(ay)]])
    return rx @ ry


def write_plate(path: Path, cells: float, depth: int, count: int, rotation: np.ndarray, seed: int) -> float:
    """A box [-1, 1]² × [-t, t] sampled uniformly on its surface, red on top (+z), blue below,
    green on the rim, turned by `rotation`; `2t` is `cells` finest cells at `depth` (the
    bounding cube is 1.1 × the bounding box's largest side). Returns t."""
    corners = np.array([[x, y, 0.0] for x in (-1, 1) for y in (-1, 1)]) @ rotation.T
    half = cells * 1.1 * np.ptp(corners, axis=0).max() / 2**depth / 2.0
    rng = np.random.default_rng(seed)
    faces = [  # (area, axis, sign)
        (4.0, 2, 1.0), (4.0, 2, -1.0),
        (4.0 * half, 0, 1.0), (4.0 * half, 0, -1.0),
        (4.0 * half, 1, 1.0), (4.0 * half, 1, -1.0),
    ]
    areas = np.array([f[0] for f in faces])
    which = rng.choice(len(faces), size=count, p=areas / areas.sum())
    extent = np.array([1.0, 1.0, half])
    positions = (rng.random((count, 3)) * 2.0 - 1.0) * extent
    normals = np.zeros((count, 3))
    rgb = np.zeros((count, 3), dtype=np.uint8)
    for k, (_, axis, sign) in enumerate(faces):
        on = which == k
        positions[on, axis] = sign * extent[axis]
        normals[on, axis] = sign
        rgb[on] = (255, 0, 0) if axis == 2 and sign > 0 else (0, 0, 255) if axis == 2 else (0, 255, 0)
    record = np.dtype([("p", "<f4", 3), ("n", "<f4", 3), ("c", "u1", 3)])
    data = np.empty(count, dtype=record)
    data["p"], data["n"], data["c"] = positions @ rotation.T, normals @ rotation.T, rgb
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"comment bench/attributes.py plate: {cells} cells at depth {depth} thick, seed {seed}\n"
        f"element vertex {count}\n"
        "property float x\nproperty float y\nproperty float z\n"
        "property float nx\nproperty float ny\nproperty float nz\n"
        "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n"
    )
    with open(path, "wb") as f:
        f.write(header.encode())
        f.write(data.tobytes())
    return half


def plate_bleeding(mesh_path: Path, rotation: np.ndarray) -> dict:
    """The other face's colour (0–255) at the plate's face vertices, away from the rim."""
    import open3d as o3d

    mesh = o3d.io.read_triangle_mesh(str(mesh_path))
    if not mesh.has_vertex_colors():
        return {"error": "the mesh has no vertex colours"}
    mesh.compute_vertex_normals()
    # In the plate's own frame (rows times the rotation = the inverse rotation of each row).
    p = np.asarray(mesh.vertices) @ rotation
    n = np.asarray(mesh.vertex_normals) @ rotation
    c = np.asarray(mesh.vertex_colors) * 255.0
    inner = (np.abs(p[:, 0]) <= 0.8) & (np.abs(p[:, 1]) <= 0.8)
    # On a face: on its side of the mid-plane and facing its way (normal within 60° of it).
    # A plate thinner than a cell comes out wavy, so neither test alone is reliable.
    top = inner & (n[:, 2] > 0.5) & (p[:, 2] > 0.0)
    bottom = inner & (n[:, 2] < -0.5) & (p[:, 2] < 0.0)
    wrong = np.concatenate([c[top, 2], c[bottom, 0]])  # blue on top, red below
    return {
        "top": int(top.sum()),
        "bottom": int(bottom.sum()),
        "mean": float(wrong.mean()) if wrong.size else float("nan"),
        "max": float(wrong.max()) if wrong.size else float("nan"),
        "mixed": int((wrong > 0.1 * 255).sum()),
    }


def read_cloud(path: Path) -> tuple[np.ndarray, np.ndarray]:
    import open3d as o3d

    pcd = o3d.io.read_point_cloud(str(path))
    if not pcd.has_colors():
        sys.exit(f"attributes: {path} has no colours")
    return np.asarray(pcd.points), np.asarray(pcd.colors)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--input", default="lion", help="a name bench.py knows or a coloured .ply (default lion)")
    parser.add_argument("--depths", default="8,9", help="comma-separated (default 8,9)")
    parser.add_argument("--threads", type=int, default=2, help="threads for both (default 2)")
    parser.add_argument("--psr", default=str(bench.REPO / "target" / "release" / "psr"))
    parser.add_argument("--skip-open3d", action="store_true")
    parser.add_argument("--skip-plate", action="store_true", help="no bleeding check")
    parser.add_argument("--plate-depth", type=int, default=8)
    parser.add_argument("--plate-cells", type=float, default=0.4, help="plate thickness in finest cells (default 0.4)")
    parser.add_argument("--plate-points", type=int, default=200_000)
    parser.add_argument("--plate-tilt", default="11,17", help="degrees about x, y (default 11,17; 0,0 = square to the cube)")
    parser.add_argument("--timeout", type=float, default=1800)
    parser.add_argument("--keep", help="keep meshes and logs in this directory")
    parser.add_argument("--out", help="also write the results as a section of this Markdown file")
    parser.add_argument("--section", default="issue16-colours")
    args = parser.parse_args()

    cloud = bench.resolve_input(args.input)
    if not cloud.exists():
        sys.exit(f"attributes: {cloud} not found (set PSR_DATA_DIR)")
    psr_src = Path(args.psr)
    if not psr_src.exists():
        sys.exit(f"attributes: {psr_src} not found: cargo build --release")
    if args.keep:
        workdir = Path(args.keep)
        workdir.mkdir(parents=True, exist_ok=True)
    else:
        workdir = Path(tempfile.mkdtemp(prefix="psr-attributes-"))
    # A copy, so that a rebuild during the run cannot mix two binaries (as bench.py does).
    psr = workdir / "psr"
    shutil.copy2(psr_src, psr)

    info = bench.machine()
    load_before = bench.uptime()
    started = _dt.datetime.now(_dt.timezone.utc)
    points, colours = read_cloud(cloud)

    tools = [("psr", lambda c, d, tag: bench.run_psr(psr, c, d, args.threads, workdir, tag, args.timeout, []))]
    if not args.skip_open3d:
        tools.append(("Open3D", lambda c, d, tag: bench.run_open3d(c, d, args.threads, workdir, tag, args.timeout)))
    rows = []
    for depth in bench.int_list(args.depths):
        for name, run_tool in tools:
            tag = f"{name.lower()}_d{depth}"
            run = run_tool(cloud, depth, tag)
            error = colour_error(workdir / f"{tag}.ply", points, colours) if run.ok else {}
            rows.append((depth, name, run, error))
            print(f"depth {depth} {name}: {error} ({run.compute} s, load {run.load1:.2f})", file=sys.stderr, flush=True)

    lines = [
        f"Colour error on `{cloud.name}` ({len(points):,} points): mean over the points of the RGB "
        "distance (0–255 per channel) between each point's colour and the mesh's at its closest "
        "surface point.",
        "",
        "| depth | tool | vertices | triangles | mean colour error (Euclidean RGB) | mean abs. error per channel | reconstruct s | wall s | load |",
        "|---:|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for depth, name, run, error in rows:
        if not run.ok:
            lines.append(f"| {depth} | {name} | failed ({run.error}) | | | | | | |")
            continue
        e = bench.fmt(error.get("euclidean"), ".2f") if "error" not in error else error["error"]
        lines.append(
            f"| {depth} | {name} | {bench.fmt(run.vertices, ',')} | {bench.fmt(run.triangles, ',')} | {e} | "
            f"{bench.fmt(error.get('per_channel'), '.2f')} | {bench.fmt(run.compute, '.2f')} | "
            f"{bench.fmt(run.wall, '.2f')} | {run.load1:.2f} |"
        )

    if not args.skip_plate:
        plate = workdir / "plate.ply"
        tilt = [float(x) for x in args.plate_tilt.split(",")]
        rotation = plate_rotation(*tilt)
        half = write_plate(plate, args.plate_cells, args.plate_depth, args.plate_points, rotation, seed=7)
        lines += [
            "",
            f"Bleeding across a thin plate: [-1, 1]² × [-{half:.5f}, {half:.5f}] ({args.plate_cells} finest "
            f"cells thick at depth {args.plate_depth}), turned {tilt[0]:g}° about x after {tilt[1]:g}° about y, "
            f"{args.plate_points:,} points, red on top, blue below; the other face's colour component "
            "(0–255) at the face vertices (in the plate's frame: |x|, |y| ≤ 0.8, on the face's side of the "
            "mid-plane z = 0 and with a normal, from the mesh's triangles, within 60° of the face's), "
            "and how many of them have more than 10 % (25.5) of it.",
            "",
            "| depth | tool | top / bottom vertices | other face's colour: mean | max | vertices > 10 % |",
            "|---:|---|---:|---:|---:|---:|",
        ]
        for name, run_tool in tools:
            tag = f"{name.lower()}_plate"
            run = run_tool(plate, args.plate_depth, tag)
            if not run.ok:
                lines.append(f"| {args.plate_depth} | {name} | failed ({run.error}) | | | |")
                continue
            b = plate_bleeding(workdir / f"{tag}.ply", rotation)
            print(f"plate {name}: {b}", file=sys.stderr, flush=True)
            if "error" in b:
                lines.append(f"| {args.plate_depth} | {name} | {b['error']} | | | |")
            else:
                lines.append(
                    f"| {args.plate_depth} | {name} | {b['top']:,} / {b['bottom']:,} | {b['mean']:.2f} | "
                    f"{b['max']:.2f} | {b['mixed']:,} ({100 * b['mixed'] / max(1, b['top'] + b['bottom']):.2f} %) |"
                )

    table = "\n".join(lines)
    print(table)
    if args.out:
        command = "python3 bench/attributes.py " + " ".join(shlex.quote(a) for a in sys.argv[1:])
        ram = f"{info['ram_gib']:.1f} GiB" if info["ram_gib"] else "unknown"
        body = "\n".join(
            [
                f"## Colours: psr vs Open3D on {cloud.name}, depths {args.depths}, {args.threads} threads",
                "",
                table,
                "",
                f"- command: `{command}`",
                f"- date: {started:%Y-%m-%d %H:%M} UTC",
                f"- machine: {info['cpu']}, {info['cpus']} CPUs, {ram} RAM",
                f"- load before: `{load_before}`",
                f"- load after: `{bench.uptime()}`",
                f"- psr: {bench.git_revision()}",
            ]
        )
        bench.write_section(Path(args.out), args.section, body)
    if not args.keep:
        shutil.rmtree(workdir, ignore_errors=True)
    return 0 if all(run.ok for _, _, run, _ in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
