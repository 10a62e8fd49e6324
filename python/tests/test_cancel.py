"""Cancelling: by the progress callback, by an exception in it, and by Ctrl-C (SIGINT) in a
child process running a long reconstruction, which must end with KeyboardInterrupt within a
second."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import threading
import time

import numpy as np
import pytest

import psr

from conftest import same_mesh, sphere


def test_progress_reports_every_stage_in_order(ball: tuple[np.ndarray, np.ndarray]) -> None:
    seen: list[tuple[psr.Stage, float, str]] = []
    psr.reconstruct(
        *ball, depth=6, progress=lambda s, f: seen.append((s, f, threading.current_thread().name))
    )
    stages = [s for s, _, _ in seen]
    assert all(isinstance(s, psr.Stage) for s in stages)
    order = [s for i, s in enumerate(stages) if i == 0 or stages[i - 1] != s]
    assert order == sorted(order) and order[0] is psr.Stage.POINTS
    assert order[-1] is psr.Stage.MESH and psr.Stage.SOLVE in order
    assert all(0.0 <= f <= 1.0 for _, f, _ in seen)
    assert str(psr.Stage.SOLVE) == "solve"
    # Called from the main thread, the solve (and so the callback) runs on a worker thread.
    assert {name for _, _, name in seen} == {"psr-solve"}
    unoriented: list[psr.Stage] = []
    psr.reconstruct(ball[0], depth=5, progress=lambda s, f: unoriented.append(s))
    assert unoriented[0] is psr.Stage.NORMALS


@pytest.mark.parametrize("stage", [psr.Stage.OCTREE, psr.Stage.SOLVE, psr.Stage.EXTRACT])
def test_callback_returning_false_cancels(
    stage: psr.Stage, ball: tuple[np.ndarray, np.ndarray]
) -> None:
    r = psr.Reconstructor(depth=6)
    r.add_points(*ball)
    after: list[psr.Stage] = []

    def stop_at(s: psr.Stage, f: float) -> bool:
        after.append(s)
        return bool(s < stage)

    with pytest.raises(psr.CancelledError) as info:
        r.solve(progress=stop_at)
    assert info.value.status is psr.Status.CANCELLED
    assert after[-1] is stage and after.count(stage) == 1  # no call after the "stop"
    assert same_mesh(r.solve(), psr.reconstruct(*ball, depth=6))  # the handle is fine


def test_exception_in_callback_propagates(ball: tuple[np.ndarray, np.ndarray]) -> None:
    class Stop(Exception):
        pass

    def fail(s: psr.Stage, f: float) -> None:
        if s is psr.Stage.SPLAT:
            raise Stop("from the callback")

    with pytest.raises(Stop, match="from the callback"):
        psr.reconstruct(*ball, depth=6, progress=fail)


def test_tqdm_bar(ball: tuple[np.ndarray, np.ndarray], capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("tqdm", reason="tqdm is not installed")
    m = psr.reconstruct(*ball, depth=5, progress="tqdm")
    assert len(m.triangles) > 0
    assert "psr" in capsys.readouterr().err


# A reconstruction that takes many seconds: 300,000 points at depth 10. It prints each stage as
# it starts, so the parent can interrupt it in the stage it chooses.
CHILD = textwrap.dedent(
    """
    import sys, numpy as np, psr
    rng = np.random.default_rng(5)
    v = rng.normal(size=(300_000, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    last = [None]
    def report(stage, fraction):
        if stage != last[0]:
            last[0] = stage
            print(f"stage {stage}", flush=True)
    print("ready", flush=True)
    mesh = psr.reconstruct(v, v, depth=10, progress=report)
    print("finished", flush=True)
    """
)


@pytest.mark.parametrize("when", ["density", "octree", "splat", "solve"])
def test_sigint_stops_a_long_reconstruction_within_a_second(when: str) -> None:
    child = subprocess.Popen(
        [sys.executable, "-c", CHILD], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        assert child.stdout is not None
        lines = []
        for line in child.stdout:
            lines.append(line.strip())
            if line.strip() == f"stage {when}":
                break
        else:
            pytest.fail(f"the child ended before stage {when}: {lines} {child.communicate()}")
        time.sleep(0.2)  # well inside the stage
        sent = time.monotonic()
        child.send_signal(signal.SIGINT)
        try:
            _, err = child.communicate(timeout=10)
        except subprocess.TimeoutExpired:
            pytest.fail("the child did not stop within 10 s of SIGINT")
        took = time.monotonic() - sent
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    assert "KeyboardInterrupt" in err, err
    assert child.returncode == -signal.SIGINT, (child.returncode, err)
    assert took < 1.0, f"stopped {took:.2f} s after SIGINT"
    print(f"SIGINT in stage {when}: the process ended {took * 1000:.0f} ms later")


def test_sigint_in_process_leaves_the_reconstructor_usable() -> None:
    p, n = sphere(100_000, seed=9)
    r = psr.Reconstructor(depth=9)
    r.add_points(p, n)
    started = threading.Event()
    timer = threading.Timer(0.3, lambda: os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    t0 = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        r.solve(progress=lambda s, f: started.set())
    took = time.monotonic() - t0
    timer.join()
    assert started.is_set() and took < 1.3
    r.depth = 5  # waits for a solve left running, if any, then works
    assert len(r.solve().triangles) > 0


def test_trim_reports_progress_and_cancels(ball: tuple[np.ndarray, np.ndarray]) -> None:
    p, n = ball
    cap = p[:, 2] < 0.5
    m = psr.reconstruct(p[cap], n[cap], depth=6)
    seen: list[tuple[psr.Stage, float]] = []
    t = m.trim(progress=lambda s, f: seen.append((s, f)))
    assert {s for s, _ in seen} == {psr.Stage.TRIM} and str(psr.Stage.TRIM) == "trim"
    assert seen[0][1] == 0.0 and seen[-1][1] == 1.0
    assert same_mesh(t, m.trim())
    calls: list[float] = []

    def stop(s: psr.Stage, f: float) -> bool:
        calls.append(f)
        return False

    with pytest.raises(psr.CancelledError):
        m.trim(progress=stop)
    assert calls == [0.0]  # no call after the "stop"

    class Stop(Exception):
        pass

    def fail(s: psr.Stage, f: float) -> None:
        raise Stop("from the trim's callback")

    with pytest.raises(Stop, match="trim's callback"):
        m.trim(progress=fail)
    assert same_mesh(m.trim(), t)  # the mesh is unchanged and trims again alike
