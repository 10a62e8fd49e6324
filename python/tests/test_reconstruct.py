"""Round trips through psr: parameters, meshes, attributes, implicit function, trimming, PLY."""

from __future__ import annotations

import inspect
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import psr

from conftest import KITTEN, need, same_mesh, sphere


def euler_characteristic(mesh: psr.Mesh) -> int:
    t = mesh.triangles.astype(np.int64)
    edges = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    e = len(np.unique(edges, axis=0))
    return len(mesh.vertices) - e + len(t)


def test_sphere_is_a_closed_sphere(ball_mesh: psr.Mesh) -> None:
    m = ball_mesh
    assert m.vertices.dtype == np.float32 and m.vertices.shape[1] == 3
    assert m.triangles.dtype == np.uint32 and m.triangles.shape[1] == 3
    assert m.densities.shape == (len(m.vertices),) and m.densities.dtype == np.float32
    assert len(m.triangles) > 500
    assert int(m.triangles.max()) == len(m.vertices) - 1
    radii = np.linalg.norm(m.vertices, axis=1)
    assert abs(float(radii.mean()) - 1.0) < 0.02
    assert euler_characteristic(m) == 2
    # Counter-clockwise seen from outside: the enclosed volume is positive.
    v = m.vertices.astype(np.float64)[m.triangles.astype(np.int64)]
    volume = np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum() / 6
    assert volume == pytest.approx(4 / 3 * np.pi, rel=0.05)
    assert m.normals is None and m.colors is None and m.channels == {}
    assert not m.vertices.flags.writeable


def test_defaults_are_the_c_apis() -> None:
    with psr.Reconstructor() as r:
        c_defaults = {name: getattr(r, name) for name in psr.DEFAULTS}
    for name, value in psr.DEFAULTS.items():
        assert np.float32(c_defaults[name]) == np.float32(value), name
    for fn in (psr.reconstruct, psr.Reconstructor.__init__):
        params = inspect.signature(fn).parameters
        for name, value in psr.DEFAULTS.items():
            # point_weight's None is 2 x degree, as for a fresh handle: 4 at the default degree.
            expected = None if name == "point_weight" else value
            assert params[name].default == expected, (fn.__name__, name)
            assert params[name].kind is inspect.Parameter.KEYWORD_ONLY


CHANGED: dict[str, Any] = {
    "depth": 9,
    "width": 0.25,
    "full_depth": 3,
    "kernel_depth": 4,
    "samples_per_node": 2.0,
    "scale": 1.25,
    "degree": 1,
    "point_weight": 0.0,
    "screening_follows_noise": False,
    "threads": 2,
    "max_solver_iterations": 30,
    "solver_tolerance": 1e-4,
    "boundary": psr.Boundary.DIRICHLET,
    "splatting": psr.Splatting.TRILINEAR,
    "vertex_placement": psr.VertexPlacement.ON_ISOSURFACE,
    "min_component_samples": 0,
    "max_memory": 8 << 30,
    "vertex_normals": True,
    "normal_neighbors": 12,
    "normal_orientation": psr.Orientation.SENSORS,
    "normal_reconstruction_iterations": 7,
}


def test_every_parameter_reaches_psr_and_reads_back() -> None:
    assert set(CHANGED) == set(psr.DEFAULTS)
    r = psr.Reconstructor(**CHANGED)
    assert r.parameters() == {**CHANGED, "viewpoint": None}
    r2 = psr.Reconstructor()
    for name, value in CHANGED.items():
        setattr(r2, name, value)
        assert getattr(r2, name) == value
    r2.boundary = "free"  # type: ignore[assignment]
    assert r2.boundary is psr.Boundary.FREE
    r2.viewpoint = (1, 2, 3)
    assert r2.viewpoint == (1.0, 2.0, 3.0)
    assert r2.normal_orientation is psr.Orientation.VIEWPOINT


def test_parameters_change_the_result(
    ball: tuple[np.ndarray, np.ndarray], ball_mesh: psr.Mesh
) -> None:
    coarse = psr.reconstruct(*ball, depth=4)
    assert coarse.depth == 4 and ball_mesh.depth == 6
    assert len(coarse.triangles) < len(ball_mesh.triangles) / 2
    on_iso = psr.reconstruct(*ball, depth=6, vertex_placement="on_isosurface")
    assert len(on_iso.vertices) == len(ball_mesh.vertices)
    assert not np.array_equal(on_iso.vertices, ball_mesh.vertices)
    by_width = psr.reconstruct(*ball, width=2.2 / 32)
    assert by_width.depth == 5


def test_screening_follows_the_samples_noise(ball: tuple[np.ndarray, np.ndarray]) -> None:
    points, normals = sphere(20000)
    rng = np.random.default_rng(3)
    noisy = points + rng.normal(scale=0.01, size=points.shape)
    plain = psr.reconstruct(noisy, normals, depth=8, screening_follows_noise=False)
    assert plain.sample_noise is None and plain.screening_depth == 8.0
    follows = psr.reconstruct(noisy, normals, depth=8)
    # sigma 0.01 per coordinate reads about 0.009 (the median of the cells' residuals)
    assert follows.sample_noise == pytest.approx(0.009, rel=0.25)
    assert follows.screening_depth < 6.0
    exact = psr.reconstruct(*ball, depth=6)
    assert exact.sample_noise == pytest.approx(0.0, abs=1e-3) and exact.screening_depth == 6.0


def test_degree_one(ball: tuple[np.ndarray, np.ndarray], ball_mesh: psr.Mesh) -> None:
    r = psr.Reconstructor(depth=6, degree=1)
    assert r.degree == 1 and r.point_weight == 2.0  # 2 x degree, like the C API and the CLI
    r.add_points(*ball)
    linear = r.solve()
    assert euler_characteristic(linear) == 2
    assert not np.array_equal(linear.vertices, ball_mesh.vertices)
    radii = np.linalg.norm(linear.vertices, axis=1)
    assert abs(float(radii.mean()) - 1.0) < 0.02
    assert psr.Reconstructor(degree=1, point_weight=8.0).point_weight == 8.0
    r.degree = 2
    assert r.point_weight == 4.0
    assert same_mesh(r.solve(), ball_mesh)


def test_reconstructor_reuse_and_batches(
    ball: tuple[np.ndarray, np.ndarray], ball_mesh: psr.Mesh
) -> None:
    p, n = ball
    r = psr.Reconstructor(depth=6)
    r.add_points(p[:1000], n[:1000])
    r.add_points(p[1000:], n[1000:])
    assert len(r) == r.point_count == len(p)
    first = r.solve()
    assert same_mesh(first, ball_mesh)
    assert same_mesh(r.solve(), first)
    r.clear_points()
    assert len(r) == 0
    p2, n2 = sphere(2000, seed=7, radius=2.0)
    r.add_points(p2, n2)
    other = r.solve()
    assert np.linalg.norm(other.vertices, axis=1).mean() == pytest.approx(2.0, rel=0.02)
    assert "2000 points" in repr(r)
    r.close()
    with pytest.raises(ValueError, match="closed"):
        r.solve()


def test_mesh_outlives_its_reconstructor(ball: tuple[np.ndarray, np.ndarray]) -> None:
    r = psr.Reconstructor(depth=5)
    r.add_points(*ball)
    m = r.solve()
    del r
    assert m.depth == 5 and len(m.trim().vertices) > 0


def test_statistics(ball_mesh: psr.Mesh) -> None:
    m = ball_mesh
    assert m.finest_depth <= m.depth == 6
    counts = m.node_counts
    assert counts.dtype == np.uint64 and len(counts) == m.finest_depth + 1 and counts[0] == 1
    stats = m.solve_stats
    assert [s.depth for s in stats] == list(range(len(stats)))
    assert all(s.iterations >= 1 and s.seconds >= 0 for s in stats)
    assert np.isfinite(m.isovalue)
    assert m.origin == (0.0, 0.0, 0.0)
    assert m.unsupported_components == 0
    assert np.isnan(m.trim_density) and np.isnan(m.trim_depth)


def test_vertex_normals_point_outward(ball: tuple[np.ndarray, np.ndarray]) -> None:
    m = psr.reconstruct(*ball, depth=6, vertex_normals=True)
    assert m.normals is not None and m.normals.shape == m.vertices.shape
    assert np.allclose(np.linalg.norm(m.normals, axis=1), 1, atol=1e-4)
    radial = m.vertices / np.linalg.norm(m.vertices, axis=1, keepdims=True)
    assert np.einsum("ij,ij->i", radial, m.normals).min() > 0.9


def test_colors_channels_and_confidence(ball: tuple[np.ndarray, np.ndarray]) -> None:
    p, n = ball
    colors = np.where(p[:, :1] > 0, [[1.0, 0.0, 0.0]], [[0.0, 0.0, 1.0]]).astype(np.float32)
    m = psr.reconstruct(
        p, n, depth=6, colors=colors, channels={"height": p[:, 2]}, confidence=np.full(len(p), 2.0)
    )
    assert m.colors is not None and m.colors.shape == (len(m.vertices), 3)
    far = np.abs(m.vertices[:, 0]) > 0.3
    red = m.colors[:, 0] > m.colors[:, 2]
    assert np.array_equal(red[far], (m.vertices[:, 0] > 0)[far])
    assert list(m.channels) == ["height"]
    assert np.abs(m.channels["height"] - m.vertices[:, 2]).max() < 0.1
    rgba = psr.reconstruct(p, n, depth=5, colors=np.ones((len(p), 4)))
    assert rgba.colors is not None and rgba.colors.shape[1] == 4


def test_implicit_function(ball: tuple[np.ndarray, np.ndarray]) -> None:
    m = psr.reconstruct(*ball, depth=6, keep_implicit=True)
    f = m.implicit
    assert f is not None and f.isovalue == pytest.approx(m.isovalue)
    values = f.evaluate(np.array([[0, 0, 0], [0, 0, 1.05], [0.5, 0, 0]], np.float64))
    assert values.shape == (3,)
    assert values[0] < f.isovalue < values[1] and values[2] < f.isovalue
    g = f.gradient([[0.0, 0.0, 1.0]])
    assert g.shape == (1, 3) and g[0, 2] > abs(g[0, 0]) + abs(g[0, 1])
    origin, size = f.cube
    assert size == pytest.approx(2 * 1.1, rel=0.01) and origin[0] == pytest.approx(-1.1, rel=0.02)
    grid = f.sample_grid(8)
    assert grid.shape == (8, 8, 8) and grid[4, 4, 4] < f.isovalue < grid[0, 0, 0]
    # A box: over the cube, the grid bit for bit; over another box, chi at its cell centres.
    corner = np.asarray(origin, np.float64)
    assert np.array_equal(f.sample_box(corner, corner + size, 8), grid)
    box = f.sample_box([-0.5, -0.5, 0.0], [0.5, 0.5, 0.0], 4)
    assert box.shape == (4, 4, 4)
    centres = [
        [-0.5 + (i + 0.5) / 4, -0.5 + (j + 0.5) / 4, 0.0] for i in range(4) for j in range(4)
    ]
    values = f.evaluate(centres).reshape(4, 4)
    assert np.allclose(box[:, :, 0], values, atol=1e-5)
    assert np.array_equal(box[:, :, 0], box[:, :, 3])  # a flat box: every k is the same point
    assert psr.reconstruct(*ball, depth=4).implicit is None


def test_trim(ball: tuple[np.ndarray, np.ndarray]) -> None:
    p, n = ball
    cap = p[:, 2] < 0.5  # a sphere with its top cut off: the lid is invented far from samples
    m = psr.reconstruct(p[cap], n[cap], depth=6)
    t = m.trim()
    assert 0 < len(t.triangles) < len(m.triangles)
    assert t.vertices[:, 2].max() < m.vertices[:, 2].max()
    assert np.isfinite(t.trim_density) and np.isfinite(t.trim_depth)
    everything = m.trim(threshold=psr.TrimThreshold.DENSITY, threshold_value=0.0)
    assert len(everything.triangles) == len(m.triangles)
    half = m.trim(threshold="quantile", threshold_value=0.5)
    assert len(half.triangles) < len(t.triangles)


def test_points_without_normals(ball: tuple[np.ndarray, np.ndarray]) -> None:
    p, _ = ball
    m = psr.reconstruct(p, depth=6)
    assert euler_characteristic(m) == 2
    assert np.linalg.norm(m.vertices, axis=1).mean() == pytest.approx(1.0, abs=0.03)
    for kwargs in (
        {"sensor": (0.0, 0.0, 0.0)},
        {"sensors": np.zeros_like(p)},
        {"viewpoint": (0.0, 0.0, 0.0)},
    ):
        # Normals facing the centre: the surface is the same sphere, turned inside out.
        inside_out = psr.reconstruct(p, depth=5, **kwargs)
        assert np.linalg.norm(inside_out.vertices, axis=1).mean() == pytest.approx(1.0, abs=0.05)


def test_transform_and_far_from_the_origin(ball: tuple[np.ndarray, np.ndarray]) -> None:
    p, n = ball
    shift = np.array([1e6, -2e6, 5e5])
    far = psr.reconstruct(p.astype(np.float64) + shift, n, depth=6)
    assert far.vertices.dtype == np.float64 and far.origin != (0.0, 0.0, 0.0)
    assert np.linalg.norm(far.vertices - shift, axis=1).mean() == pytest.approx(1.0, rel=0.02)
    m = np.eye(4)
    m[:3, 3] = shift
    moved = psr.reconstruct(p, n, depth=6, transform=m)
    assert moved.vertices.dtype == np.float64
    assert np.abs(moved.vertices - far.vertices).max() < 1e-3  # 1e-9 of the coordinates


def test_ply_round_trip(tmp_path: Path, ball: tuple[np.ndarray, np.ndarray]) -> None:
    p, n = ball
    m = psr.reconstruct(
        p,
        n,
        depth=5,
        vertex_normals=True,
        colors=np.tile([0.2, 0.4, 1.0], (len(p), 1)),
        channels={"t": p[:, 0]},
    )
    for ascii in (False, True):
        path = tmp_path / f"m{ascii}.ply"
        m.write_ply(path, ascii=ascii)
        back = psr.read_ply_mesh(path)
        assert np.array_equal(back.vertices, m.vertices)
        assert back.triangles.dtype == np.uint32 and np.array_equal(back.triangles, m.triangles)
        assert back.densities is not None and np.array_equal(back.densities, m.densities)
        assert np.array_equal(back.channels["t"], m.channels["t"])
        assert m.normals is not None and back.normals is not None
        assert np.array_equal(back.normals, m.normals)
        # uchar colours in the file: within half a step of 1/255.
        assert back.colors is not None and np.abs(back.colors - m.colors).max() <= 0.5 / 255 + 1e-6
        cloud = psr.read_ply(path)
        assert np.array_equal(cloud.points, m.vertices) and cloud.normals is not None
        assert (
            cloud.colors is not None and np.abs(cloud.colors - m.colors).max() <= 0.5 / 255 + 1e-6
        )
        assert set(cloud.channels) == {"t"}
        assert cloud.confidence is not None and np.array_equal(cloud.confidence, m.densities)


def test_read_ply_kitten_and_errors(tmp_path: Path) -> None:
    cloud = psr.read_ply(need(KITTEN, "examples/data/kitten_cgal.ply"))
    assert len(cloud) == 5210 and cloud.points.dtype == np.float32
    assert cloud.normals is not None and cloud.colors is None and cloud.channels == {}
    mesh = psr.reconstruct(cloud, depth=6)
    assert len(mesh.triangles) > 1000
    bad = tmp_path / "bad.ply"
    bad.write_bytes(b"not a ply\n")
    with pytest.raises(psr.PlyError, match="not a PLY"):
        psr.read_ply(bad)
    bad.write_bytes(KITTEN.read_bytes()[:2000])
    with pytest.raises(psr.PlyError, match="truncated"):
        psr.read_ply(bad)
    with pytest.raises(psr.FileError, match="missing.ply") as info:
        psr.read_ply(tmp_path / "missing.ply")
    assert isinstance(info.value, OSError) and info.value.status is psr.Status.IO_ERROR
    with pytest.raises(psr.FileError, match="no-such-dir"):
        psr.reconstruct(cloud, depth=4).write_ply(tmp_path / "no-such-dir" / "m.ply")
    with pytest.raises(TypeError, match="psr.Mesh"):
        psr.write_ply(tmp_path / "m.ply", object())  # type: ignore[arg-type]


def test_ply_files_with_every_property(tmp_path: Path) -> None:
    # A cloud with double positions, uchar colours, sensors, a confidence and a channel, and a
    # quad face: read as the psr program reads it.
    path = tmp_path / "cloud.ply"
    header = (
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty double x\nproperty double y\n"
        "property double z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
        "property float confidence\nproperty float sensor_x\nproperty float sensor_y\n"
        "property float sensor_z\nproperty float intensity\nelement face 1\n"
        "property list uchar int vertex_indices\nend_header\n"
    )
    rows = [f"{1000000 + i}.125 2 3 255 0 51 0.5 0 0 {i} {i * 10}" for i in range(4)]
    path.write_text(header + "\n".join(rows) + "\n4 0 1 2 3\n")
    cloud = psr.read_ply(path)
    assert cloud.points.dtype == np.float64 and cloud.points[1, 0] == 1e6 + 1.125
    assert cloud.colors is not None and np.allclose(cloud.colors[0], [1.0, 0.0, 0.2])
    assert cloud.confidence is not None and np.all(cloud.confidence == 0.5)
    assert cloud.sensors is not None and np.array_equal(cloud.sensors[:, 2], [0, 1, 2, 3])
    assert set(cloud.channels) == {"intensity"} and cloud.channels["intensity"][3] == 30
    assert cloud.normals is None
    mesh = psr.read_ply_mesh(path)
    assert np.array_equal(mesh.triangles, [[0, 1, 2], [0, 2, 3]])


def test_trimesh_interop(ball_mesh: psr.Mesh) -> None:
    trimesh = pytest.importorskip("trimesh", reason="trimesh is not installed")
    t = ball_mesh.to_trimesh()
    assert isinstance(t, trimesh.Trimesh)
    assert np.array_equal(t.faces, ball_mesh.triangles) and t.is_watertight
    assert np.array_equal(t.vertex_attributes["density"], ball_mesh.densities)


def test_open3d_interop(ball: tuple[np.ndarray, np.ndarray], ball_mesh: psr.Mesh) -> None:
    o3d = pytest.importorskip("open3d", reason="open3d is not installed")
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(ball[0].astype(np.float64)))
    pcd.normals = o3d.utility.Vector3dVector(ball[1].astype(np.float64))
    m = psr.reconstruct(pcd, depth=6)
    assert np.abs(m.vertices - ball_mesh.vertices).max() < 1e-6
    tm = m.to_open3d()
    assert isinstance(tm, o3d.geometry.TriangleMesh)
    assert len(tm.triangles) == len(m.triangles) and tm.is_watertight()


def test_conversions_say_what_is_missing(
    ball_mesh: psr.Mesh, monkeypatch: pytest.MonkeyPatch
) -> None:
    import sys

    for module, method in (("trimesh", "to_trimesh"), ("open3d", "to_open3d")):
        monkeypatch.setitem(sys.modules, module, None)
        with pytest.raises(ImportError, match=f"pip install {module}"):
            getattr(ball_mesh, method)()


def test_max_memory_out_of_memory_and_estimate(
    ball: tuple[np.ndarray, np.ndarray], ball_mesh: psr.Mesh
) -> None:
    r = psr.Reconstructor(depth=6, max_memory=4096)
    assert r.max_memory == 4096
    r.add_points(*ball)
    estimate = r.estimate_memory()
    assert estimate > 1 << 20
    with pytest.raises(psr.OutOfMemoryError) as caught:
        r.solve()
    assert caught.value.status is psr.Status.OUT_OF_MEMORY
    assert isinstance(caught.value, MemoryError)
    assert "memory limit of 4.00 KiB" in str(caught.value)
    # The reconstructor stays usable: no limit, or the estimate, give the same mesh.
    r.max_memory = 0
    assert same_mesh(r.solve(), ball_mesh)
    r.max_memory = estimate
    assert same_mesh(r.solve(), ball_mesh)
    with pytest.raises(psr.OutOfMemoryError):
        psr.reconstruct(*ball, depth=6, max_memory=4096)
    with pytest.raises(ValueError):
        psr.Reconstructor(max_memory=-1)


def test_a_cloud_file_gives_its_sensors_to_sensor_orientation(tmp_path: Path) -> None:
    # A sphere without normals whose file stores, per point, a "scanner" inside it: the
    # normals face their scanner, so with SENSORS orientation (and only then) they point inward
    # and the mesh comes out inside-out (negative signed volume), which propagation would not do.
    p, _ = sphere(3000, seed=4)
    sensors = p * 0.3
    path = tmp_path / "scan.ply"
    header = (
        "ply\nformat ascii 1.0\nelement vertex 3000\nproperty float x\nproperty float y\n"
        "property float z\nproperty float sensor_x\nproperty float sensor_y\n"
        "property float sensor_z\nend_header\n"
    )
    rows = "\n".join(" ".join(f"{v:.6f}" for v in (*a, *b)) for a, b in zip(p, sensors))
    path.write_text(header + rows + "\n")
    cloud = psr.read_ply(path)
    assert cloud.normals is None and cloud.sensors is not None

    def signed_volume(m: psr.Mesh) -> float:
        v = m.vertices.astype(np.float64)[m.triangles.astype(np.int64)]
        return float(np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum() / 6)

    facing = psr.reconstruct(cloud, depth=5, normal_orientation="sensors")
    assert signed_volume(facing) < -3.0  # about -4.19, the unit ball inside-out
    propagated = psr.reconstruct(cloud, depth=5)
    assert signed_volume(propagated) > 3.0
    with psr.Reconstructor(depth=5, normal_orientation=psr.Orientation.SENSORS) as r:
        r.add_points(cloud)
        assert same_mesh(r.solve(), facing)


def test_reconstruction_orientation_faces_outward() -> None:
    # Points alone: the orientation read off the reconstruction itself gives a mesh facing
    # outward (positive signed volume, about that of the unit ball), the same through
    # psr.reconstruct and through a Reconstructor whose round count is set as a property.
    p, _ = sphere(3000, seed=5)

    def signed_volume(m: psr.Mesh) -> float:
        v = m.vertices.astype(np.float64)[m.triangles.astype(np.int64)]
        return float(np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum() / 6)

    mesh = psr.reconstruct(
        p, depth=5, normal_orientation="reconstruction", normal_reconstruction_iterations=5
    )
    assert 3.0 < signed_volume(mesh) < 4.5
    with psr.Reconstructor(depth=5, normal_orientation=psr.Orientation.RECONSTRUCTION) as r:
        assert r.normal_reconstruction_iterations == 10
        r.normal_reconstruction_iterations = 5
        r.add_points(p)
        assert same_mesh(r.solve(), mesh)
