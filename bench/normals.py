#!/usr/bin/env python3
"""Times psr's normal estimation + orientation against Open3D's on the same clouds.

psr: `target/release/examples/estimate_normals IN --neighbors K --threads T` (build it with
`cargo build --release --example estimate_normals`); Open3D: `bench/open3d_normals.py` with
OMP_NUM_THREADS=T (estimate_normals + orient_normals_consistent_tangent_plane). Both read the
file's positions only; each prints its own time for estimating and orienting (file reading
excluded) and the share of its normals that agree in sign with the file's own normals, which
point outward on the shared scans. Every run is its own process under `/usr/bin/time -v`, for
the peak resident memory. A benchmark: nothing fails when psr is slow.

    python3 bench/normals.py                       # bunny + buddha, k = 20, threads 1,2
    python3 bench/normals.py --inputs bunny --threads 2 --skip-open3d
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


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--inputs", default="bunny,buddha")
    parser.add_argument("--threads", type=int_list, default=[1, 2])
    parser.add_argument("--neighbors", type=int, default=20)
    parser.add_argument("--skip-open3d", action="store_true")
    parser.add_argument("--timeout", type=float, default=3600)
    args = parser.parse_args()
    example = ROOT / "target/release/examples/estimate_normals"
    if not example.exists():
        print(f"build {example} first: cargo build --release --example estimate_normals")
        return 2
    info = machine()
    print(f"machine: {info['cpu']}, {info['cpus']} CPUs, {info['ram_gib'] or 0:.1f} GiB RAM")
    print(f"k = {args.neighbors} neighbours (Open3D's KNN given k + 1: it counts the point)\n")
    print("| input | threads | psr s | psr peak MiB | psr agree % | Open3D s | Open3D peak MiB | Open3D agree % | psr / Open3D time | psr / Open3D memory |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory(prefix="psr-normals-bench-") as tmp:
        work = Path(tmp)
        for name in args.inputs.split(","):
            cloud = resolve_input(name)
            for threads in args.threads:
                row = [name, str(threads)]
                results = []
                runs = [("psr", [str(example), str(cloud), "--neighbors", str(args.neighbors), "--threads", str(threads)])]
                if not args.skip_open3d:
                    runs.append(("open3d", [sys.executable, str(ROOT / "bench/open3d_normals.py"), str(cloud), "--neighbors", str(args.neighbors)]))
                for tool, cmd in runs:
                    os.environ["OMP_NUM_THREADS"] = str(threads)
                    run, stdout, _ = timed(cmd, work, f"{tool}-{name}-{threads}", args.timeout)
                    seconds = SECONDS.findall(stdout)
                    agree = AGREE.search(stdout)
                    if not run.ok or not seconds:
                        results.append(None)
                        row += [run.error or "failed", "–", "–"]
                        continue
                    results.append((float(seconds[-1]), run.rss_mib))
                    row += [seconds[-1], f"{run.rss_mib:.0f}", agree.group(1) if agree else "–"]
                if args.skip_open3d:
                    row += ["–"] * 3
                if len(results) == 2 and all(results):
                    row += [f"{results[0][0] / results[1][0]:.2f}", f"{results[0][1] / results[1][1]:.2f}"]
                else:
                    row += ["–", "–"]
                print("| " + " | ".join(row) + " |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
