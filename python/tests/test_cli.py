"""The package gives the psr program's mesh bit for bit: same library, same defaults, and a PLY
writer that writes the same bytes."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

import psr

from conftest import KITTEN, need


def run_cli(cli: Path, cloud: Path, out: Path, *args: str) -> psr.PlyMesh:
    subprocess.run([str(cli), "--in", str(cloud), "--out", str(out), "--quiet", *args], check=True)
    return psr.read_ply_mesh(out)


def assert_same(ours: psr.Mesh, theirs: psr.PlyMesh) -> None:
    assert ours.vertices.dtype == theirs.vertices.dtype
    assert ours.vertices.tobytes() == theirs.vertices.tobytes()
    assert np.array_equal(ours.triangles, theirs.triangles)
    assert theirs.densities is not None
    assert ours.densities.tobytes() == theirs.densities.tobytes()


def test_kitten_depth_8_equals_the_cli(cli: Path, tmp_path: Path) -> None:
    kitten = need(KITTEN, "examples/data/kitten_cgal.ply")
    theirs = run_cli(cli, kitten, tmp_path / "cli.ply", "--depth", "8")
    ours = psr.reconstruct(psr.read_ply(kitten), depth=8)
    assert len(ours.triangles) > 10_000
    assert_same(ours, theirs)
    ours.write_ply(tmp_path / "py.ply")
    assert (tmp_path / "py.ply").read_bytes() == (tmp_path / "cli.ply").read_bytes()


def test_kitten_with_options_equals_the_cli(cli: Path, tmp_path: Path) -> None:
    kitten = need(KITTEN, "examples/data/kitten_cgal.ply")
    theirs = run_cli(
        cli,
        kitten,
        tmp_path / "cli.ply",
        "--depth",
        "7",
        "--vertex-normals",
        "--boundary",
        "dirichlet",
        "--point-weight",
        "2",
        "--trim",
    )
    with psr.Reconstructor(
        depth=7, vertex_normals=True, boundary="dirichlet", point_weight=2.0
    ) as r:
        r.add_points(psr.read_ply(kitten))
        ours = r.solve().trim()
    assert_same(ours, theirs)
    ours.write_ply(tmp_path / "py.ply")
    assert (tmp_path / "py.ply").read_bytes() == (tmp_path / "cli.ply").read_bytes()


@pytest.mark.parametrize("name, depth", [("bunny_scans.ply", 8), ("lion_takanawa_rgb.ply", 7)])
def test_shared_scans_equal_the_cli(
    name: str, depth: int, cli: Path, data_dir: Path, tmp_path: Path
) -> None:
    cloud = need(data_dir / name, f"the shared scan {name} (set PSR_DATA_DIR)")
    theirs = run_cli(cli, cloud, tmp_path / "cli.ply", "--depth", str(depth))
    ours = psr.reconstruct(psr.read_ply(cloud), depth=depth)
    assert_same(ours, theirs)
    ours.write_ply(tmp_path / "py.ply")
    assert (tmp_path / "py.ply").read_bytes() == (tmp_path / "cli.ply").read_bytes()
