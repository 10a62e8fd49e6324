#!/usr/bin/env python3
"""Times psr's normal estimation + orientation against Open3D's and CGAL's on the same clouds.

psr: `target/release/examples/estimate_normals IN --neighbors K --threads T` (build it with
`cargo build --release --example estimate_normals`); Open3D: `bench/open3d_normals.py` with
OMP_NUM_THREADS=T (estimate_normals + orient_normals_consistent_tangent_plane). Both read the
file's positions only; each prints its own time for estimating and orienting (file reading
excluded) and the share of its normals that agree in sign with the file's own normals, which
point outward on the shared scans. CGAL (optional): `bench/cgal_normals.cpp` built as
target/cgal_normals (build command in bench/README.md; skipped when absent), jet_estimate_normals
on T TBB threads + mst_orient_normals (sequential), which drops the points it could not orient:
they are counted, and its agreement is over the oriented points. Every run is its own process
under `/usr/bin/time -v`, for the peak resident memory. A benchmark: nothing fails when psr is
slow.

    python3 bench/normals.py                       # bunny + buddha, k = 20, threads 1,2
    python3 bench/normals.py --inputs bunny --threads 2 --skip-open3d --skip-cgal
    python3 bench/normals.py --cgal path/to/cgal_normals
"""
from __future__ import annotations

import argparse
import os
import re
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench import int_list, machine, resolve_input, timed  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
SECONDS = re.compile(r"(?:oriented in|total) ([\d.]+) s")
AGREE = re.compile(r"([\d.]+) % agree")
UNORIENTED = re.compile(r"(\d+) points left unoriented")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--inputs", default="bunny,buddha")
    parser.add_argument("--threads", type=int_list, default=[1, 2])
    parser.add_argument("--neighbors", type=int, default=20)
    parser.add_argument("--skip-open3d", action="store_true")
    parser.add_argument("--cgal", type=Path, default=ROOT / "target/cgal_normals",
                        help="bench/cgal_normals.cpp built (see bench/README.md); skipped if absent")
    parser.add_argument("--skip-cgal", action="store_true")
    parser.add_argument("--timeout", type=float, default=3600)
    args = parser.parse_args()
    example = ROOT / "target/release/examples/estimate_normals"
    if not example.exists():
        print(f"build {example} first: cargo build --release --example estimate_normals")
        return 2
    tools = ["psr"]
    if not args.skip_open3d:
        tools.append("open3d")
    if not args.skip_cgal:
        if args.cgal.exists():
            tools.append("cgal")
        else:
            print(f"no {args.cgal}: CGAL skipped (build command in bench/README.md)")
    info = machine()
    print(f"machine: {info['cpu']}, {info['cpus']} CPUs, {info['ram_gib'] or 0:.1f} GiB RAM")
    print(f"k = {args.neighbors} neighbours (Open3D's KNN given k + 1: it counts the point; CGAL's k")
    print("does not count it); CGAL's agreement is over the points mst_orient_normals oriented\n")
    names = {"psr": "psr", "open3d": "Open3D", "cgal": "CGAL"}
    header = ["input", "threads", "load"]
    for tool in tools:
        header += [f"{names[tool]} s", f"{names[tool]} peak MiB", f"{names[tool]} agree %"]
        if tool == "cgal":
            header.append("CGAL unoriented")
    for tool in tools[1:]:
        header += [f"psr / {names[tool]} time", f"psr / {names[tool]} memory"]
    print("| " + " | ".join(header) + " |")
    print("|---|" + "---:|" * (len(header) - 1))
    with tempfile.TemporaryDirectory(prefix="psr-normals-bench-") as tmp:
        work = Path(tmp)
        for name in args.inputs.split(","):
            cloud = resolve_input(name)
            for threads in args.threads:
                row = [name, str(threads), f"{os.getloadavg()[0]:.2f}"]
                results = {}
                commands = {
                    "psr": [str(example), str(cloud), "--neighbors", str(args.neighbors), "--threads", str(threads)],
                    "open3d": [sys.executable, str(ROOT / "bench/open3d_normals.py"), str(cloud), "--neighbors", str(args.neighbors)],
                    "cgal": [str(args.cgal), str(cloud), "--neighbors", str(args.neighbors), "--threads", str(threads)],
                }
                for tool in tools:
                    os.environ["OMP_NUM_THREADS"] = str(threads)
                    run, stdout, _ = timed(commands[tool], work, f"{tool}-{name}-{threads}", args.timeout)
                    seconds = SECONDS.findall(stdout)
                    agree = AGREE.search(stdout)
                    if not run.ok or not seconds:
                        row += [run.error or "failed", "–", "–"] + (["–"] if tool == "cgal" else [])
                        continue
                    results[tool] = (float(seconds[-1]), run.rss_mib)
                    row += [seconds[-1], f"{run.rss_mib:.0f}", agree.group(1) if agree else "–"]
                    if tool == "cgal":
                        unoriented = UNORIENTED.search(stdout)
                        row.append(unoriented.group(1) if unoriented else "–")
                for tool in tools[1:]:
                    if "psr" in results and tool in results:
                        row += [f"{results['psr'][0] / results[tool][0]:.2f}", f"{results['psr'][1] / results[tool][1]:.2f}"]
                    else:
                        row += ["–", "–"]
                print("| " + " | ".join(row) + " |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
