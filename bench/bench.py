#!/usr/bin/env python3
"""Time psr's CLI against Open3D's Poisson reconstruction on the shared scans.

Every run is its own process under `/usr/bin/time -v`, which gives its wall time and peak
resident memory (max RSS): psr as `target/release/psr --in X --out Y --depth D --threads T`
(build it first with `cargo build --release`), Open3D as `bench/open3d_poisson.py`, which
calls `create_from_point_cloud_poisson(pcd, depth=D, width=0, scale=1.1, linear_fit=False,
n_threads=T)` (full_depth 5, samples_per_node 1.5, point_weight 2.0: Open3D's defaults, spelled
out). Both read the PLY, reconstruct and write a binary PLY mesh. The two runs of one
configuration follow each other so they see the same machine load.

Prints a Markdown table; --out FILE also writes it, with the command line, date and machine,
as a section of FILE (replacing that section when it is already there).

    python3 bench/bench.py                                   # bunny + buddha, depths 8,9,10, threads 1,2
    python3 bench/bench.py --inputs bunny --depths 8 --threads 2 --skip-open3d
    python3 bench/bench.py --skip-psr --inputs bunny --out docs/open3d_baseline.md
    python3 bench/bench.py --out docs/benchmarks.md

Inputs are names (bunny, buddha, kitten, oni, lion) in the data directory ($PSR_DATA_DIR, default
../shared/data next to the repository) or paths to PLY files. Only the standard library is needed
here; Open3D (and numpy) are needed by open3d_poisson.py unless --skip-open3d.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import hashlib
import json
import os
import platform
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
DATA_NAMES = {
    "bunny": "bunny_scans.ply",
    "buddha": "happy_buddha_scans.ply",
    "kitten": "kitten_cgal.ply",
    "oni": "oni_cgal.ply",
    "lion": "lion_takanawa_rgb.ply",
}
TIME = "/usr/bin/time"


@dataclass
class Run:
    """One timed process."""

    ok: bool = False
    error: str = ""
    wall: float | None = None  # seconds, from /usr/bin/time
    rss_mib: float | None = None  # peak resident set size
    cpu: float | None = None  # user + system CPU seconds, from /usr/bin/time (less load-sensitive than wall)
    compute: float | None = None  # in-process reconstruction seconds, when the tool reports it
    vertices: int | None = None
    triangles: int | None = None
    load1: float | None = None  # 1-minute load average just before the run
    extra: dict = field(default_factory=dict)


def data_dir() -> Path:
    env = os.environ.get("PSR_DATA_DIR")
    return Path(env) if env else (REPO / ".." / "shared" / "data").resolve()


def resolve_input(name: str) -> Path:
    if name in DATA_NAMES:
        return data_dir() / DATA_NAMES[name]
    path = Path(name)
    if path.suffix.lower() == ".ply":
        return path
    sys.exit(f"bench: unknown input {name!r}: use one of {', '.join(DATA_NAMES)} or a .ply path")


def int_list(text: str) -> list[int]:
    try:
        return [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated integers, got {text!r}")


def parse_time_v(text: str) -> tuple[float | None, float | None, int | None, float | None]:
    """(wall seconds, max RSS in MiB, exit status, user + system CPU seconds) from GNU time -v output."""
    wall = rss = status = cpu = None
    m = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\):\s*([\d:.]+)", text)
    if m:
        seconds = 0.0
        for part in m.group(1).split(":"):
            seconds = seconds * 60 + float(part)
        wall = seconds
    m = re.search(r"Maximum resident set size \(kbytes\):\s*(\d+)", text)
    if m:
        rss = int(m.group(1)) / 1024.0
    m = re.search(r"Exit status:\s*(\d+)", text)
    if m:
        status = int(m.group(1))
    user = re.search(r"User time \(seconds\):\s*([\d.]+)", text)
    system = re.search(r"System time \(seconds\):\s*([\d.]+)", text)
    if user and system:
        cpu = float(user.group(1)) + float(system.group(1))
    return wall, rss, status, cpu


def ply_counts(path: Path) -> tuple[int | None, int | None]:
    """(vertex count, face count) from a PLY header."""
    vertices = faces = None
    try:
        with open(path, "rb") as f:
            for _ in range(200):
                line = f.readline()
                if not line or line.startswith(b"end_header"):
                    break
                words = line.split()
                if len(words) == 3 and words[0] == b"element":
                    if words[1] == b"vertex":
                        vertices = int(words[2])
                    elif words[1] == b"face":
                        faces = int(words[2])
    except OSError:
        pass
    return vertices, faces


def timed(cmd: list[str], workdir: Path, tag: str, timeout: float) -> tuple[Run, str, str]:
    """Runs cmd under /usr/bin/time -v; returns the Run (wall, RSS) and the command's stdout/stderr."""
    run = Run(load1=os.getloadavg()[0])
    time_file = workdir / f"{tag}.time"
    full = [TIME, "-v", "-o", str(time_file)] + cmd
    try:
        proc = subprocess.run(full, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        run.error = f"timeout after {timeout:.0f}s"
        return run, "", ""
    (workdir / f"{tag}.stdout").write_text(proc.stdout)
    (workdir / f"{tag}.stderr").write_text(proc.stderr)
    wall, rss, status, cpu = parse_time_v(time_file.read_text() if time_file.exists() else "")
    run.wall, run.rss_mib, run.cpu = wall, rss, cpu
    if proc.returncode != 0 or status not in (0, None):
        tail = (proc.stderr.strip().splitlines() or ["(no stderr)"])[-1]
        run.error = f"exit {proc.returncode}: {tail}"
        return run, proc.stdout, proc.stderr
    run.ok = True
    return run, proc.stdout, proc.stderr


def run_psr(psr: Path, cloud: Path, depth: int, threads: int, workdir: Path, tag: str, timeout: float, extra: list[str]) -> Run:
    out = workdir / f"{tag}.ply"
    cmd = [str(psr), "--in", str(cloud), "--out", str(out), "--depth", str(depth), "--threads", str(threads)] + extra
    run, _stdout, stderr = timed(cmd, workdir, tag, timeout)
    if run.ok:
        run.vertices, run.triangles = ply_counts(out)
        # The CLI's one-line summary: "... V vertices, T triangles; <stages> total Xs (read ...".
        m = re.search(r"total ([\d.]+)s", stderr)
        if m:
            run.compute = float(m.group(1))
        # "...; points 0.01s density 0.05s ... mesh 0.03s total ...": the per-stage seconds.
        summary = re.search(r"triangles; (.*?) total", stderr)
        if summary:
            run.extra["stages"] = {k: float(v) for k, v in re.findall(r"([a-z]+) ([\d.]+)s", summary.group(1))}
        if run.vertices is None:
            m = re.search(r"(\d+) vertices, (\d+) triangles", stderr)
            if m:
                run.vertices, run.triangles = int(m.group(1)), int(m.group(2))
    return run


def run_open3d(cloud: Path, depth: int, threads: int, workdir: Path, tag: str, timeout: float) -> Run:
    out = workdir / f"{tag}.ply"
    helper = Path(__file__).resolve().parent / "open3d_poisson.py"
    cmd = [sys.executable, str(helper), "--in", str(cloud), "--out", str(out), "--depth", str(depth), "--threads", str(threads)]
    run, stdout, _stderr = timed(cmd, workdir, tag, timeout)
    if run.ok:
        try:
            info = json.loads(stdout.strip().splitlines()[-1])
        except (IndexError, ValueError):
            run.ok, run.error = False, "no JSON from open3d_poisson.py"
            return run
        run.vertices, run.triangles = info.get("vertices"), info.get("triangles")
        run.compute = info.get("poisson_seconds")
        run.extra = info
    return run


def open3d_baseline(workdir: Path, timeout: float) -> Run:
    helper = Path(__file__).resolve().parent / "open3d_poisson.py"
    run, stdout, _ = timed([sys.executable, str(helper), "--import-only"], workdir, "open3d_import_only", timeout)
    if run.ok:
        try:
            run.extra = json.loads(stdout.strip().splitlines()[-1])
        except (IndexError, ValueError):
            pass
    return run


def best(runs: list[Run]) -> Run:
    """The successful run with the smallest wall time, else the last failure."""
    good = [r for r in runs if r.ok]
    return min(good, key=lambda r: r.wall or 0.0) if good else runs[-1]


def fmt(x: float | int | None, spec: str) -> str:
    return "–" if x is None else format(x, spec)


def ratio(a: float | None, b: float | None) -> str:
    return "–" if a is None or b is None or b == 0 else f"{a / b:.2f}"


def counts(r: Run | None) -> str:
    if r is None or not r.ok:
        return "–"
    return f"{fmt(r.vertices, ',')} / {fmt(r.triangles, ',')}"


def cell_time(r: Run | None) -> str:
    if r is None:
        return "–"
    return fmt(r.wall, ".2f") if r.ok else f"failed ({r.error})"


def machine() -> dict:
    info = {"cpu": platform.processor() or platform.machine(), "cpus": os.cpu_count(), "ram_gib": None}
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True).stdout
        for line in out.splitlines():
            key, _, value = line.partition(":")
            if key.strip() == "Model name":
                info["cpu"] = value.strip()
            elif key.strip() == "CPU(s)":
                info["cpus"] = int(value.strip())
    except (OSError, ValueError):
        pass
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal:"):
                info["ram_gib"] = int(line.split()[1]) / 1024 / 1024
    except OSError:
        pass
    return info


def uptime() -> str:
    try:
        return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    except OSError:
        la = os.getloadavg()
        return f"load average: {la[0]:.2f}, {la[1]:.2f}, {la[2]:.2f}"


def git_revision() -> str:
    try:
        rev = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
        # Only what goes into the binary counts (editing bench/ or docs/ does not change psr).
        built_from = ["src", "cli", "Cargo.toml", "Cargo.lock", "build.rs"]
        dirty = subprocess.run(["git", "-C", str(REPO), "status", "--porcelain", "--untracked-files=no", "--"] + built_from, capture_output=True, text=True).stdout.strip()
        return rev + (" (with uncommitted changes to src/, cli/ or Cargo files)" if dirty else "") if rev else "unknown"
    except OSError:
        return "unknown"


def table(rows: list[tuple], skip_psr: bool, skip_open3d: bool) -> str:
    """rows: (input, points, depth, threads, psr Run | None, open3d Run | None)."""
    if skip_psr:
        head = ["input", "points", "depth", "threads", "Open3D wall s", "Open3D peak MiB", "Open3D poisson s", "Open3D V / T", "load"]
    elif skip_open3d:
        head = ["input", "points", "depth", "threads", "psr wall s", "psr peak MiB", "psr reconstruct s", "psr V / T", "load"]
    else:
        head = [
            "input", "points", "depth", "threads", "psr wall s", "psr peak MiB", "Open3D wall s", "Open3D peak MiB",
            "time ratio psr/Open3D", "memory ratio psr/Open3D", "psr reconstruct s", "Open3D poisson s",
            "compute ratio", "psr CPU s", "Open3D CPU s", "psr V / T", "Open3D V / T", "load",
        ]
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join("---" if i < 1 else "---:" for i in range(len(head))) + "|"]
    for name, points, depth, threads, p, o in rows:
        load = max((r.load1 for r in (p, o) if r is not None and r.load1 is not None), default=None)
        base = [name, fmt(points, ","), str(depth), str(threads)]
        if skip_psr:
            cells = [cell_time(o), fmt(o.rss_mib if o.ok else None, ".0f"), fmt(o.compute, ".2f"), counts(o)]
        elif skip_open3d:
            cells = [cell_time(p), fmt(p.rss_mib if p.ok else None, ".0f"), fmt(p.compute, ".2f"), counts(p)]
        else:
            pw = p.wall if p.ok else None
            ow = o.wall if o.ok else None
            cells = [
                cell_time(p), fmt(p.rss_mib if p.ok else None, ".0f"), cell_time(o), fmt(o.rss_mib if o.ok else None, ".0f"),
                ratio(pw, ow), ratio(p.rss_mib if p.ok else None, o.rss_mib if o.ok else None),
                fmt(p.compute, ".2f"), fmt(o.compute, ".2f"), ratio(p.compute, o.compute),
                fmt(p.cpu if p.ok else None, ".1f"), fmt(o.cpu if o.ok else None, ".1f"), counts(p), counts(o),
            ]
        lines.append("| " + " | ".join(base + cells + [fmt(load, ".2f")]) + " |")
    return "\n".join(lines)


def stage_table(rows: list[tuple]) -> str:
    """psr's per-stage seconds (from its summary line) for every configuration that ran."""
    stages: list[str] = []
    for row in rows:
        p = row[4]
        if p is not None and p.ok:
            for k in p.extra.get("stages", {}):
                if k not in stages:
                    stages.append(k)
    if not stages:
        return ""
    head = ["input", "depth", "threads"] + stages + ["total"]
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join("---" if i < 1 else "---:" for i in range(len(head))) + "|"]
    for name, _points, depth, threads, p, _o in rows:
        if p is None or not p.ok or "stages" not in p.extra:
            continue
        st = p.extra["stages"]
        cells = [fmt(st.get(k), ".2f") for k in stages] + [fmt(p.compute, ".2f")]
        lines.append("| " + " | ".join([name, str(depth), str(threads)] + cells) + " |")
    return "\n".join(lines)


def growth_table(rows: list[tuple]) -> str:
    """Cost per depth: each configuration's wall time and output size over the previous depth's."""
    by_key = {(r[0], r[2], r[3]): r for r in rows}
    head = ["input", "threads", "depth", "psr wall ×", "psr peak ×", "Open3D wall ×", "triangles ×"]
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join("---" if i < 1 else "---:" for i in range(len(head))) + "|"]
    for (name, depth, threads), (_n, _pts, _d, _t, p, o) in sorted(by_key.items()):
        prev = by_key.get((name, depth - 1, threads))
        if prev is None:
            continue
        pp, po = prev[4], prev[5]
        grow = lambda a, b, attr: ratio(getattr(a, attr) if a is not None and a.ok else None, getattr(b, attr) if b is not None and b.ok else None)
        tri = ratio(p.triangles if p is not None and p.ok else None, pp.triangles if pp is not None and pp.ok else None)
        lines.append("| " + " | ".join([name, str(threads), f"{depth - 1} → {depth}", grow(p, pp, "wall"), grow(p, pp, "rss_mib"), grow(o, po, "wall"), tri]) + " |")
    return "\n".join(lines) if len(lines) > 2 else ""


def thread_table(rows: list[tuple]) -> str:
    """Speed-up from 1 to 2 threads: wall time with 1 thread over wall time with 2."""
    by_key = {(r[0], r[2], r[3]): r for r in rows}
    head = ["input", "depth", "psr 1 thread / 2 threads", "Open3D 1 thread / 2 threads"]
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join("---" if i < 1 else "---:" for i in range(len(head))) + "|"]
    for (name, depth, threads), row in sorted(by_key.items()):
        if threads != 1 or (name, depth, 2) not in by_key:
            continue
        two = by_key[(name, depth, 2)]
        wall = lambda r: r.wall if r is not None and r.ok else None
        lines.append("| " + " | ".join([name, str(depth), ratio(wall(row[4]), wall(two[4])), ratio(wall(row[5]), wall(two[5]))]) + " |")
    return "\n".join(lines) if len(lines) > 2 else ""


def write_section(path: Path, name: str, body: str) -> None:
    begin, end = f"<!-- bench:begin {name} -->", f"<!-- bench:end {name} -->"
    block = f"{begin}\n{body.rstrip()}\n{end}\n"
    text = path.read_text() if path.exists() else ""
    if begin in text and end in text:
        before, _, rest = text.partition(begin)
        _, _, after = rest.partition(end)
        text = before + block.rstrip("\n") + after
    else:
        if not text:
            text = "# Benchmarks\n\nWritten by `bench/bench.py`; each section is replaced when the same benchmark is rerun.\n"
        text = text.rstrip("\n") + "\n\n" + block
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--inputs", default="bunny,buddha", help="comma-separated names or .ply paths (default bunny,buddha)")
    parser.add_argument("--depths", type=int_list, default=[8, 9, 10], help="default 8,9,10")
    parser.add_argument("--threads", type=int_list, default=[1, 2], help="default 1,2")
    parser.add_argument("--skip-open3d", action="store_true", help="time psr only")
    parser.add_argument("--skip-psr", action="store_true", help="time Open3D only")
    parser.add_argument("--psr", type=Path, default=REPO / "target" / "release" / "psr", help="the psr binary (default target/release/psr)")
    parser.add_argument("--psr-args", default="", help="extra psr options, e.g. '--point-weight 2'")
    parser.add_argument("--repeat", type=int, default=1, help="runs per configuration; the fastest is reported (default 1)")
    parser.add_argument("--timeout", type=float, default=3600.0, help="seconds per run (default 3600)")
    parser.add_argument("--out", type=Path, help="also write the results as a section of this Markdown file")
    parser.add_argument("--section", help="section name in --out (default: derived from what ran)")
    parser.add_argument("--keep", type=Path, help="keep meshes, logs and /usr/bin/time output in this directory")
    args = parser.parse_args()

    if args.skip_psr and args.skip_open3d:
        parser.error("--skip-psr and --skip-open3d leave nothing to run")
    if not Path(TIME).exists():
        sys.exit(f"bench: {TIME} not found: apt-get install -y time")
    if not args.skip_psr and not args.psr.exists():
        sys.exit(f"bench: {args.psr} not found: run `cargo build --release` first")
    inputs = [(name, resolve_input(name)) for name in args.inputs.split(",") if name.strip()]
    for name, path in inputs:
        if not path.exists():
            sys.exit(f"bench: input {name}: {path} not found (set PSR_DATA_DIR)")

    if args.keep:
        args.keep.mkdir(parents=True, exist_ok=True)
        workdir_ctx = None
        workdir = args.keep
    else:
        workdir_ctx = tempfile.TemporaryDirectory(prefix="psr-bench-")
        workdir = Path(workdir_ctx.name)

    # Time a private copy of the psr binary: on a shared checkout a concurrent `cargo build
    # --release` replaces target/release/psr, and a run would then mix two builds.
    psr_sha = None
    psr_git = git_revision()  # of the checkout when the binary is copied
    if not args.skip_psr:
        snapshot = workdir / "psr-under-test"
        shutil.copy2(args.psr, snapshot)
        psr_sha = hashlib.sha256(snapshot.read_bytes()).hexdigest()[:16]
        psr_bin = snapshot
    else:
        psr_bin = args.psr

    started = _dt.datetime.now(_dt.timezone.utc).astimezone()
    uptime_before = uptime()
    baseline = None if args.skip_open3d else open3d_baseline(workdir, args.timeout)
    rows = []
    for name, cloud in inputs:
        points, _ = ply_counts(cloud)
        for depth in args.depths:
            for threads in args.threads:
                p_runs, o_runs = [], []
                for k in range(args.repeat):
                    tag = f"{name}_d{depth}_t{threads}_r{k}"
                    if not args.skip_psr:
                        r = run_psr(psr_bin, cloud, depth, threads, workdir, "psr_" + tag, args.timeout, shlex.split(args.psr_args))
                        p_runs.append(r)
                        print(f"psr     {tag}: {'ok' if r.ok else r.error} wall {fmt(r.wall, '.2f')} s, {fmt(r.rss_mib, '.0f')} MiB, load {r.load1:.2f}", file=sys.stderr)
                    if not args.skip_open3d:
                        r = run_open3d(cloud, depth, threads, workdir, "open3d_" + tag, args.timeout)
                        o_runs.append(r)
                        print(f"open3d  {tag}: {'ok' if r.ok else r.error} wall {fmt(r.wall, '.2f')} s, {fmt(r.rss_mib, '.0f')} MiB, load {r.load1:.2f}", file=sys.stderr)
                    if not args.keep:
                        for mesh in workdir.glob("*.ply"):
                            mesh.unlink()
                rows.append((name, points, depth, threads, best(p_runs) if p_runs else None, best(o_runs) if o_runs else None))
    uptime_after = uptime()

    md = table(rows, args.skip_psr, args.skip_open3d)
    extras = []
    if not args.skip_psr:
        for title, body in [
            ("psr per stage (seconds, from its summary line; `psr --verbose` prints the same)", stage_table(rows)),
            ("Growth per depth (this depth over the previous one)", growth_table(rows)),
            ("Threads", thread_table(rows)),
        ]:
            if body:
                extras += ["", f"### {title}", "", body]
    if extras:
        md += "\n" + "\n".join(extras)
    print(md)

    if args.out:
        m = machine()
        what = "Open3D" if args.skip_psr else "psr" if args.skip_open3d else "psr vs Open3D"
        section = args.section or ("open3d-baseline" if args.skip_psr else "psr-only" if args.skip_open3d else "psr-vs-open3d")
        command = " ".join(shlex.quote(a) for a in [Path(sys.argv[0]).as_posix()] + sys.argv[1:])
        notes = [
            f"## {what}: {', '.join(n for n, _ in inputs)}, depths {','.join(map(str, args.depths))}, threads {','.join(map(str, args.threads))}",
            "",
            f"- date: {started.strftime('%Y-%m-%d %H:%M %Z')}",
            f"- command: `python3 {command}`",
            f"- machine: {m['cpu']}, {m['cpus']} CPUs, {fmt(m['ram_gib'], '.1f')} GiB RAM, {platform.system()} {platform.release()}",
            f"- load before: `{uptime_before}`",
            f"- load after: `{uptime_after}`",
            f"- psr: {'not run' if args.skip_psr else f'`{args.psr}` {args.psr_args}'.rstrip() + f', git {psr_git}, binary sha256 {psr_sha}… (copied before the first run)'}",
        ]
        if baseline is not None:
            version = baseline.extra.get("open3d", "?")
            notes.append(
                f"- Open3D {version} (`create_from_point_cloud_poisson`, depth=D, width=0, scale=1.1, linear_fit=False, "
                "n_threads=T, full_depth=5, samples_per_node=1.5, point_weight=2.0), one process per run via "
                "`bench/open3d_poisson.py`. Starting Python and importing Open3D alone costs "
                f"{fmt(baseline.wall, '.2f')} s wall and {fmt(baseline.rss_mib, '.0f')} MiB peak RSS on this machine; "
                "both are inside the Open3D wall and peak columns."
            )
        notes.append(
            "- wall s and peak MiB: `/usr/bin/time -v` of the whole process (read PLY, reconstruct, write binary PLY mesh);"
            " peak = maximum resident set size." + (f" Fastest of {args.repeat} runs." if args.repeat > 1 else "")
        )
        if not args.skip_psr and not args.skip_open3d:
            notes.append("- time and memory ratios: psr / Open3D of those whole-process figures (below 1: psr is faster or smaller).")
        if not args.skip_psr:
            notes.append("- psr reconstruct s: the `total` of psr's summary line (the reconstruction alone, no I/O).")
        if not args.skip_open3d:
            notes.append("- Open3D poisson s: the in-process time of the `create_from_point_cloud_poisson` call alone.")
        if not args.skip_psr and not args.skip_open3d:
            notes.append("- compute ratio: psr reconstruct s / Open3D poisson s.")
            notes.append(
                "- CPU s: user + system CPU seconds of the whole process (`/usr/bin/time -v`), of the same run;"
                " less inflated by other load than wall time."
            )
        notes += [
            "- V / T: vertices / triangles of the output mesh. load: 1-minute load average just before the run"
            " (the machine is shared; loads near or above the core count inflate wall times).",
            "",
            md,
        ]
        write_section(args.out, section, "\n".join(notes) + "\n")
        print(f"bench: wrote section {section!r} of {args.out}", file=sys.stderr)

    if workdir_ctx is not None:
        workdir_ctx.cleanup()
    failed = [r for row in rows for r in row[4:] if r is not None and not r.ok]
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
