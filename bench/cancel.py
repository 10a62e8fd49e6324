"""Cancel latency of psr through its C ABI (issue 18): how long after a host decides to stop does
psr_reconstructor_solve return?

One full solve first records when the progress callback is called (per stage, the longest gap
between two calls: a stop decided in that gap waits for the next call). Then --runs solves on
the same handle each decide to stop at a moment drawn uniformly over the full solve's duration:
the callback returns false at its first call at or after that moment. Per run it prints the
stage, the wait for a callback call, the time from the callback's "false" to the return, and
the total (the moment to the return, the latency a user sees); then the worst per stage.

    python3 bench/cancel.py --lib target/release/libpsr.so --depth 11 --runs 8
    python3 bench/cancel.py --lib /tmp/libpsr_before.so --input bunny_scans --depth 10
    python3 bench/cancel.py --stages density,octree,extract,mesh --runs 1

With --stages, each run's moment is drawn inside one of those stages instead (by the full solve's
timeline: from the stage's first callback call, or the previous stage's last, to its last),
--runs per stage. With --trim, the same is done for psr_mesh_trim (automatic threshold, its
progress callback set in psr_trim_options) on the full solve's mesh, after the solves.

    python3 bench/cancel.py --depth 11 --runs 8 --trim

Needs numpy and a libpsr.so (`cargo build --release`); data from $PSR_DATA_DIR (default
../shared/data). Only the C ABI is used, so any build of the library can be measured."""
import argparse
import ctypes
import os
import random
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
DATA = os.environ.get("PSR_DATA_DIR", os.path.join(ROOT, "..", "shared", "data"))

PROGRESS_FN = ctypes.CFUNCTYPE(ctypes.c_bool, ctypes.c_void_p, ctypes.c_int, ctypes.c_float)
STATUS_OK = 0


class TrimOptions(ctypes.Structure):
    """psr_trim_options."""
    _fields_ = [("struct_size", ctypes.c_size_t), ("threshold", ctypes.c_int32),
                ("threads", ctypes.c_uint32), ("threshold_value", ctypes.c_double),
                ("min_piece_area", ctypes.c_float), ("min_piece_triangles", ctypes.c_uint32),
                ("progress", PROGRESS_FN), ("progress_user_data", ctypes.c_void_p)]


def load(path):
    lib = ctypes.CDLL(path)
    r_p, m_p, st = ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int
    f_p, size_t = ctypes.POINTER(ctypes.c_float), ctypes.c_size_t
    for name, restype, argtypes in [
        ("psr_status_string", ctypes.c_char_p, [ctypes.c_int]),
        ("psr_stage_string", ctypes.c_char_p, [ctypes.c_int]),
        ("psr_reconstructor_new", st, [ctypes.POINTER(r_p)]),
        ("psr_reconstructor_free", None, [r_p]),
        ("psr_reconstructor_last_error", ctypes.c_char_p, [r_p]),
        ("psr_reconstructor_set_depth", st, [r_p, ctypes.c_uint32]),
        ("psr_reconstructor_set_threads", st, [r_p, ctypes.c_uint32]),
        ("psr_reconstructor_add_points", st, [r_p, f_p, size_t, f_p, size_t, size_t]),
        ("psr_reconstructor_set_progress_callback", st, [r_p, PROGRESS_FN, ctypes.c_void_p]),
        ("psr_reconstructor_solve", st, [r_p, ctypes.POINTER(m_p)]),
        ("psr_mesh_triangle_count", size_t, [m_p]),
        ("psr_mesh_free", None, [m_p]),
        ("psr_trim_options_init", st, [ctypes.POINTER(TrimOptions), size_t]),
        ("psr_mesh_trim", st, [m_p, ctypes.POINTER(TrimOptions), ctypes.POINTER(m_p)]),
    ]:
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = restype, argtypes
    return lib


def read_ply(path):
    """x y z nx ny nz (float) of a binary little-endian PLY's vertices, as two (n, 3) arrays."""
    with open(path, "rb") as f:
        count, props, element = 0, [], None
        while True:
            line = f.readline().strip().decode("ascii", "replace")
            if line == "end_header":
                break
            words = line.split()
            if words[:1] == ["element"]:
                element = words[1]
                if element == "vertex":
                    count = int(words[2])
            elif words[:1] == ["property"] and element == "vertex":
                props.append((words[-1], words[1]))
        types = {"float": "<f4", "float32": "<f4", "double": "<f8", "uchar": "u1", "uint8": "u1",
                 "int": "<i4", "uint": "<u4", "short": "<i2", "ushort": "<u2"}
        dtype = np.dtype([(name, types[t]) for name, t in props])
        v = np.frombuffer(f.read(count * dtype.itemsize), dtype=dtype, count=count)
    pos = np.stack([v["x"], v["y"], v["z"]], axis=1).astype(np.float32)
    nrm = np.stack([v["nx"], v["ny"], v["nz"]], axis=1).astype(np.float32)
    return np.ascontiguousarray(pos), np.ascontiguousarray(nrm)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--lib", default=os.path.join(ROOT, "target", "release", "libpsr.so"))
    ap.add_argument("--input", default="happy_buddha_scans", help="a file in the data directory")
    ap.add_argument("--depth", type=int, default=11)
    ap.add_argument("--threads", type=int, default=0)
    ap.add_argument("--runs", type=int, default=8)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--stages", default="", help="comma-separated stage names (see above)")
    ap.add_argument("--trim", action="store_true", help="also stop psr_mesh_trim (see above)")
    args = ap.parse_args()

    lib = load(args.lib)
    path = args.input if os.path.exists(args.input) else os.path.join(DATA, args.input + ".ply")
    pos, nrm = read_ply(path)
    fp = ctypes.POINTER(ctypes.c_float)
    r = ctypes.c_void_p()
    assert lib.psr_reconstructor_new(ctypes.byref(r)) == STATUS_OK
    lib.psr_reconstructor_set_depth(r, args.depth)
    lib.psr_reconstructor_set_threads(r, args.threads)
    s = lib.psr_reconstructor_add_points(r, pos.ctypes.data_as(fp), 0, nrm.ctypes.data_as(fp), 0,
                                         len(pos))
    assert s == STATUS_OK, lib.psr_reconstructor_last_error(r)
    stage_name = lambda s: lib.psr_stage_string(s).decode()

    state = {}

    def on_progress(_user, stage, fraction):
        now = time.perf_counter()
        state["calls"].append((now, stage, fraction))
        stop_at = state["stop_at"]
        if stop_at is not None and now >= stop_at:
            state["stopped"] = (now, stage)
            return False
        return True

    callback = PROGRESS_FN(on_progress)  # kept alive for as long as r uses it
    lib.psr_reconstructor_set_progress_callback(r, callback, None)

    kept = {}

    def solve(stop_at_offset, trim_of=None):
        state.update(calls=[], stopped=None)
        mesh = ctypes.c_void_p()
        start = time.perf_counter()
        state["stop_at"] = None if stop_at_offset is None else start + stop_at_offset
        if trim_of is None:
            status = lib.psr_reconstructor_solve(r, ctypes.byref(mesh))
        else:
            opts = TrimOptions()
            lib.psr_trim_options_init(ctypes.byref(opts), ctypes.sizeof(opts))
            opts.threads, opts.progress = args.threads, callback
            status = lib.psr_mesh_trim(trim_of, ctypes.byref(opts), ctypes.byref(mesh))
        end = time.perf_counter()
        triangles = lib.psr_mesh_triangle_count(mesh) if status == STATUS_OK else 0
        if status == STATUS_OK and args.trim and trim_of is None and "mesh" not in kept:
            kept["mesh"] = mesh  # the mesh the trims cut
        elif status == STATUS_OK:
            lib.psr_mesh_free(mesh)
        return status, start, end, triangles

    print(f"# {args.lib}: {path}, {len(pos)} points, depth {args.depth}, threads {args.threads}")
    status, start, end, triangles = solve(None)
    assert status == STATUS_OK, lib.psr_reconstructor_last_error(r)
    full = end - start
    # The longest wait for a callback call in each stage (from the previous call, or the start).
    gaps, span, prev = {}, {}, start
    for t, stage, _ in state["calls"]:
        name = stage_name(stage)
        span[name] = (span.get(name, (prev - start, 0.0))[0], t - start)
        gaps[name] = max(gaps.get(name, 0.0), t - prev)
        prev = t
    gaps["(return)"] = end - prev
    print(f"full solve: {full:.2f} s, {triangles} triangles, {len(state['calls'])} callback calls")
    print("longest gap between callback calls, per stage (s):")
    for name, gap in gaps.items():
        print(f"  {name:9s} {gap:8.3f}")

    rng = random.Random(args.seed)
    worst = {}
    print("run  stop at s  stage      wait s  stop->return s  total s  status")
    if args.stages:
        moments = [(name, rng.uniform(*span[name])) for name in args.stages.split(",")
                   for _ in range(args.runs)]
    else:
        moments = [(None, rng.uniform(0.0, full)) for _ in range(args.runs)]
    for run, (_, offset) in enumerate(moments):
        status, start, end, _ = solve(offset)
        moment = start + offset
        if state["stopped"] is None:
            print(f"{run:3d}  {offset:9.2f}  (finished before the stop)  status {status}")
            continue
        called, stage = state["stopped"]
        name = stage_name(stage)
        total = end - moment
        print(f"{run:3d}  {offset:9.2f}  {name:9s} {called - moment:7.3f}  {end - called:14.3f}"
              f"  {total:7.3f}  {lib.psr_status_string(status).decode()}")
        worst[name] = max(worst.get(name, 0.0), total)
    print("worst total latency per stage (s):",
          ", ".join(f"{k} {v:.3f}" for k, v in worst.items()))
    # The handle is reusable after cancels: one more full solve gives the same triangle count.
    status, _, _, again = solve(None)
    print(f"after the cancels: status {lib.psr_status_string(status).decode()}, {again} triangles"
          f" ({'same' if again == triangles else 'DIFFERENT'})")
    lib.psr_reconstructor_free(r)
    if args.trim:
        trim_latency(lib, kept["mesh"], solve, state, args.runs, rng)
        lib.psr_mesh_free(kept["mesh"])


def trim_latency(lib, mesh, solve, state, runs, rng):
    """The trim's timeline, gaps between callback calls and stops, as for the solve."""
    status, start, end, triangles = solve(None, mesh)
    assert status == STATUS_OK, lib.psr_status_string(status)
    full = end - start
    print(f"full trim: {full:.3f} s, {lib.psr_mesh_triangle_count(mesh)} -> {triangles} triangles")
    print("run  stop at s  wait s  stop->return s  total s  status")
    worst = 0.0
    for run in range(runs):
        offset = rng.uniform(0.0, full)
        status, start, end, _ = solve(offset, mesh)
        return_status = lib.psr_status_string(status).decode()
        stopped = state["stopped"]
        if stopped is None:
            print(f"{run:3d}  {offset:9.3f}  (finished before the stop)  {return_status}")
            continue
        moment = start + offset
        print(f"{run:3d}  {offset:9.3f}  {stopped[0] - moment:6.3f}  {end - stopped[0]:14.3f}"
              f"  {end - moment:7.3f}  {return_status}")
        worst = max(worst, end - moment)
    print(f"worst total latency of the trim (s): {worst:.3f}")


if __name__ == "__main__":
    sys.exit(main())
