#!/usr/bin/env python3
"""What the Python package adds to the C library's time: psr.reconstruct against a C program
making the same C API calls, on the same points and the same libpsr.

    python3 bench/python_overhead.py [--input bunny_scans.ply] [--depth 10] [--pairs 3]
                                     [--out docs/benchmarks.md]

Needs the psr package installed (pip install ./python) and a C compiler: the C side,
bench/python_overhead.c, is compiled against include/psr.h and linked with the very libpsr the
package loads (psr.library_path()). Each pair runs the C program (its own process, timing
new + add_points + solve + copy-out + free from inside) and psr.reconstruct in this process
(timing the call), alternating which goes first. Two figures:

- paired: (Python - C) / C per pair, and over the fastest of each side; on a loaded machine the
  run-to-run noise of a multi-second solve is larger than the overhead, so also
- in-process split: during the Python runs every C API call the package makes is timed, and
  the overhead is the call's time outside them (array checks and conversions, the worker thread,
  copying the mesh out into NumPy) plus the progress trampoline's time inside the solve, as a
  share of the time inside them.

Prints a Markdown section; --out replaces the section between its markers in that file.
"""

from __future__ import annotations

import argparse
import datetime
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

import psr
from psr import _core, _lib

ROOT = Path(__file__).resolve().parent.parent
DATA = Path(os.environ.get("PSR_DATA_DIR", str(ROOT.parent / "shared" / "data")))
BEGIN, END = "<!-- bench:begin python-overhead -->", "<!-- bench:end python-overhead -->"


class CallTimer:
    """Wraps the package's C functions to sum the time spent inside them."""

    TIMED = (
        "psr_reconstructor_add_points",
        "psr_reconstructor_add_points_f64",
        "psr_reconstructor_solve",
        "psr_mesh_copy_positions",
        "psr_mesh_copy_triangles",
        "psr_mesh_copy_densities",
        "psr_reconstructor_new",
        "psr_reconstructor_free",
        "psr_mesh_free",
    )

    def __init__(self) -> None:
        self.inside = 0.0
        self.callback = 0.0
        self.callbacks = 0

    def install(self) -> None:
        lib = _lib.LIB
        for name in self.TIMED:
            fn = getattr(lib, name)

            def timed(*args: Any, _fn: Any = fn) -> Any:
                t = time.perf_counter()
                try:
                    return _fn(*args)
                finally:
                    self.inside += time.perf_counter() - t

            setattr(lib, name, timed)
        # The progress trampoline runs inside psr_reconstructor_solve: its Python time is the
        # package's, not the library's.
        original = _core._SolveState.on_progress

        def on_progress(state: Any, user: Any, stage: int, fraction: float) -> bool:
            t = time.perf_counter()
            try:
                return original(state, user, stage, fraction)
            finally:
                self.callback += time.perf_counter() - t
                self.callbacks += 1

        _core._SolveState.on_progress = on_progress  # type: ignore[method-assign]


def machine() -> str:
    lscpu = subprocess.run(["lscpu"], capture_output=True, text=True).stdout.splitlines()[:10]
    return f"`nproc` = {os.cpu_count()}; `lscpu | head`:\n\n```\n" + "\n".join(lscpu) + "\n```"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--input", default=str(DATA / "bunny_scans.ply"))
    ap.add_argument("--depth", type=int, default=10)
    ap.add_argument("--pairs", type=int, default=3)
    ap.add_argument("--cc", default=os.environ.get("CC", "cc"))
    ap.add_argument("--out")
    args = ap.parse_args()

    cloud = psr.read_ply(args.input)
    if cloud.normals is None or cloud.points.dtype != np.float32:
        sys.exit(f"{args.input}: need float x y z nx ny nz")
    lib = Path(psr.library_path())
    work = Path(tempfile.mkdtemp(prefix="psr-py-overhead."))
    exe = work / "python_overhead"
    subprocess.run(
        [
            args.cc,
            "-O2",
            "-std=c99",
            "-D_DEFAULT_SOURCE",
            f"-I{ROOT / 'include'}",
            str(ROOT / "bench" / "python_overhead.c"),
            "-o",
            str(exe),
            str(lib),
            f"-Wl,-rpath,{lib.parent}",
        ],
        check=True,
    )
    points_bin = work / "points.bin"
    np.hstack([cloud.points, cloud.normals]).astype("<f4").tofile(points_bin)
    n = len(cloud)

    def run_c() -> dict[str, float]:
        out = subprocess.run(
            [str(exe), str(points_bin), str(n), str(args.depth)],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.split()
        return {"wall": float(out[0]), "cpu": float(out[1]), "v": int(out[2]), "t": int(out[3])}

    timer = CallTimer()
    timer.install()

    def cpu() -> float:
        u = resource.getrusage(resource.RUSAGE_SELF)
        return u.ru_utime + u.ru_stime

    def run_py() -> dict[str, float]:
        timer.inside = 0.0
        timer.callback = 0.0
        t, c = time.perf_counter(), cpu()
        mesh = psr.reconstruct(cloud.points, cloud.normals, depth=args.depth)
        wall, cpu_s = time.perf_counter() - t, cpu() - c
        # Read before the mesh is freed (psr_mesh_free, timed too, comes after the call).
        inside, callback = timer.inside, timer.callback
        nv, nt = len(mesh.vertices), len(mesh.triangles)
        del mesh
        # The trampoline's Python time counts as the package's, outside the library's.
        return {
            "wall": wall,
            "cpu": cpu_s,
            "v": nv,
            "t": nt,
            "inside": inside - callback,
            "callback": callback,
        }

    rows: list[tuple[dict[str, float], dict[str, float]]] = []
    started = datetime.datetime.now(datetime.timezone.utc)
    load_before = os.getloadavg()
    for i in range(args.pairs):
        if i % 2 == 0:
            c = run_c()
            p = run_py()
        else:
            p = run_py()
            c = run_c()
        if (c["v"], c["t"]) != (p["v"], p["t"]):
            sys.exit(f"the C and Python meshes differ: {c} vs {p}")
        rows.append((c, p))
        print(
            f"pair {i + 1}: wall C {c['wall']:.3f} s, Python {p['wall']:.3f} s; CPU C "
            f"{c['cpu']:.3f} s, Python {p['cpu']:.3f} s; Python inside C calls "
            f"{p['inside']:.3f} s, outside {p['wall'] - p['inside']:.4f} s",
            file=sys.stderr,
            flush=True,
        )
    ended = datetime.datetime.now(datetime.timezone.utc)

    def pct(a: float, b: float) -> str:
        return f"{100 * (a - b) / b:+.2f} %"

    best = {k: (min(c[k] for c, _ in rows), min(p[k] for _, p in rows)) for k in ("wall", "cpu")}
    split = [100 * (p["wall"] - p["inside"]) / p["inside"] for _, p in rows]
    lines = [
        BEGIN,
        f"## Python package overhead (issue 18; {started:%Y-%m-%d %H:%M}–{ended:%H:%M} UTC)",
        "",
        f"Command: `python3 bench/python_overhead.py --input {args.input} --depth {args.depth} "
        f"--pairs {args.pairs}`; input {Path(args.input).name} ({n:,} points), depth "
        f"{args.depth}, default threads (one per core); psr {psr.__version__} from "
        f"`{lib}` (the installed wheel; the C program links the same file); Python "
        f"{sys.version.split()[0]}, NumPy {np.__version__}. Mesh: {rows[0][0]['v']:,} vertices, "
        f"{rows[0][0]['t']:,} triangles, the same from both sides. Load average before "
        f"{load_before[0]:.2f}, after {os.getloadavg()[0]:.2f}.",
        "",
        machine(),
        "",
        "| pair | C wall s | Python wall s | C CPU s | Python CPU s | Python: inside its C calls "
        "s | outside them s | outside / inside |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for i, ((c, p), sp) in enumerate(zip(rows, split)):
        lines.append(
            f"| {i + 1} | {c['wall']:.3f} | {p['wall']:.3f} | {c['cpu']:.3f} | {p['cpu']:.3f} | "
            f"{p['inside']:.3f} | {p['wall'] - p['inside']:.4f} | {sp:+.3f} % |"
        )
    lines += [
        "",
        f"- **Package overhead** (its own time: argument checks, the worker thread and its "
        f"waiting, the progress trampoline, copying the mesh into NumPy; measured in the same "
        f"runs as the call's wall time outside the C calls it makes): "
        f"{statistics.median(split):+.3f} % of the time inside them (median; max "
        f"{max(split):+.3f} %); {timer.callbacks // len(rows)} trampoline calls per run, "
        f"{1e3 * rows[-1][1]['callback']:.1f} ms of Python in the last.",
        f"- Fastest of each side, C program vs psr.reconstruct: wall {best['wall'][0]:.3f} vs "
        f"{best['wall'][1]:.3f} s ({pct(best['wall'][1], best['wall'][0])}), CPU "
        f"{best['cpu'][0]:.3f} vs {best['cpu'][1]:.3f} s ({pct(best['cpu'][1], best['cpu'][0])}). "
        "Across processes on a shared machine these differ by the run-to-run noise of the "
        "library itself (other sessions' load), which the in-process split does not see.",
        END,
    ]
    section = "\n".join(lines)
    print(section)
    if args.out:
        path = Path(args.out)
        text = path.read_text()
        if BEGIN in text:
            text = text[: text.index(BEGIN)] + section + text[text.index(END) + len(END) :]
        else:
            head, sep, rest = text.partition("\n## ")
            text = head + "\n" + section + "\n\n" + sep.lstrip("\n") + rest
        path.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
