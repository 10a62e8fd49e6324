"""Threads: two reconstructions at once give the meshes they give one after the other, and the
GIL is released while psr works."""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np

import psr

from conftest import same_mesh, sphere


def test_two_threads_reconstruct_at_once() -> None:
    clouds = [sphere(20_000, seed=s, radius=1 + s) for s in (1, 2)]
    alone = [psr.reconstruct(p, n, depth=7, threads=1) for p, n in clouds]
    barrier = threading.Barrier(2)

    def run(cloud: tuple[np.ndarray, np.ndarray]) -> psr.Mesh:
        barrier.wait()
        return psr.reconstruct(*cloud, depth=7, threads=1)

    for _ in range(2):
        with ThreadPoolExecutor(2) as pool:
            together = list(pool.map(run, clouds))
        assert all(same_mesh(a, b) for a, b in zip(alone, together))


def test_one_reconstructor_shared_by_threads_takes_turns() -> None:
    p, n = sphere(5000, seed=4)
    r = psr.Reconstructor(depth=6)
    r.add_points(p, n)
    expected = r.solve()
    with ThreadPoolExecutor(4) as pool:
        meshes = list(pool.map(lambda _: r.solve(), range(4)))
    assert all(same_mesh(m, expected) for m in meshes)


def test_the_gil_is_released_during_the_solve() -> None:
    p, n = sphere(30_000, seed=6)
    in_solve = threading.Event()
    done = threading.Event()

    def solve() -> None:
        psr.reconstruct(
            p,
            n,
            depth=8,
            threads=1,
            progress=lambda s, f: in_solve.set() if s is psr.Stage.SOLVE else None,
        )
        done.set()

    t = threading.Thread(target=solve)
    t.start()
    in_solve.wait()
    spins = 0
    while not done.is_set():
        spins += 1
    t.join()
    # Had psr held the GIL, this thread could not run until it returned: no spins at all.
    assert spins > 10_000
