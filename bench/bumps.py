"""Issue 16's "bumps" benchmark: exact samples of analytic shapes (a sphere, a torus, a cube with
sharp edges), uniform or from virtual range scans, reconstructed by psr (default and point
weight 0) and by Open3D's Poisson (a build of PoissonRecon) at several depths, and measured
against the true surface: the mean distance from the mesh to the truth (area-weighted), from
the truth (200k uniform samples) to the mesh, their mean ("chamfer"), the area-weighted mean
agreement of the triangle normals with the true normals, and the number of components.

    python3 bench/bumps.py --shape cube --sampling uniform:100000 --depths 8,9,10,11,12
    python3 bench/bumps.py --shape torus --sampling scan:6:800:80   # 6 views, 800x80 rays each
    python3 bench/bumps.py --shape sphere --noise 0.005   # positions and normals perturbed

Needs numpy and open3d (bench/requirements.txt) and target/release/psr. Variants: psr (the
default, whose screening follows the samples' noise), pw0 (psr --point-weight 0), fixed (psr
--screening-follows-noise false: 2^depth, PoissonRecon's scale), follow (psr
--screening-follows-noise, the default before 2026-12-06), o3d, and
X:NAME:VAR=VALUE+VAR2=VALUE2 (psr with environment variables, for experiments). Work files go to bench/runs/ (not committed)."""
import argparse, json, os, subprocess, sys, time
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


# ---------- shapes: signed distance and gradient -------------------------------------------
def sdf(shape, p):
    if shape == "sphere":
        return np.linalg.norm(p, axis=1) - 1.0
    if shape == "torus":
        q = np.stack([np.hypot(p[:, 0], p[:, 1]) - 0.7, p[:, 2]], axis=1)
        return np.linalg.norm(q, axis=1) - 0.3
    if shape == "cube":
        b = 0.8
        q = np.abs(p) - b
        outside = np.linalg.norm(np.maximum(q, 0), axis=1)
        inside = np.minimum(np.max(q, axis=1), 0)
        return outside + inside
    raise ValueError(shape)


def grad(shape, p, eps=1e-6):
    g = np.zeros_like(p)
    for k in range(3):
        d = np.zeros(3)
        d[k] = eps
        g[:, k] = (sdf(shape, p + d) - sdf(shape, p - d)) / (2 * eps)
    return g / np.linalg.norm(g, axis=1, keepdims=True)


def project(shape, p, iters=8):
    for _ in range(iters):
        p = p - sdf(shape, p)[:, None] * grad(shape, p)
    return p


def uniform_samples(shape, n, rng):
    # area-uniform: normalised Gaussians (sphere), (u, v) accepted with probability
    # proportional to the area element (torus), a face by area then uniform on it (cube)
    if shape == "sphere":
        d = rng.normal(size=(n, 3))
        return d / np.linalg.norm(d, axis=1, keepdims=True)
    if shape == "torus":
        out = []
        while sum(len(o) for o in out) < n:
            u = rng.uniform(0, 2 * np.pi, n)
            v = rng.uniform(0, 2 * np.pi, n)
            keep = rng.uniform(0, 1.0, n) * 1.0 < (0.7 + 0.3 * np.cos(v)) / 1.0
            u, v = u[keep], v[keep]
            r = 0.7 + 0.3 * np.cos(v)
            out.append(np.stack([r * np.cos(u), r * np.sin(u), 0.3 * np.sin(v)], 1))
        return np.concatenate(out)[:n]
    if shape == "cube":
        b = 0.8
        face = rng.integers(0, 6, n)
        uv = rng.uniform(-b, b, (n, 2))
        p = np.zeros((n, 3))
        ax = face // 2
        sign = np.where(face % 2 == 0, 1.0, -1.0)
        for a in range(3):
            m = ax == a
            others = [k for k in range(3) if k != a]
            p[m, a] = sign[m] * b
            p[m, others[0]] = uv[m, 0]
            p[m, others[1]] = uv[m, 1]
        return p


def scan_samples(shape, views, res, rng, res_y=None):
    """Virtual range scans: `views` pinhole cameras on a sphere of radius 4, res x res rays
    each over the object's extent; sphere tracing; samples with normals facing the camera."""
    pts = []
    golden = np.pi * (3 - np.sqrt(5))
    for i in range(views):
        z = 1 - 2 * (i + 0.5) / views
        r = np.sqrt(1 - z * z)
        cam = 4.0 * np.array([r * np.cos(golden * i), r * np.sin(golden * i), z])
        fwd = -cam / np.linalg.norm(cam)
        up = np.array([0, 0, 1.0]) if abs(fwd[2]) < 0.9 else np.array([1.0, 0, 0])
        right = np.cross(fwd, up); right /= np.linalg.norm(right)
        up = np.cross(right, fwd)
        # jitter the grid per view a little so views do not align
        ry = res_y or res
        s = np.linspace(-1.25, 1.25, res) + rng.uniform(-0.5, 0.5) * 2.5 / res
        sy = np.linspace(-1.25, 1.25, ry) + rng.uniform(-0.5, 0.5) * 2.5 / ry
        X, Y = np.meshgrid(s, sy)
        target = X.reshape(-1, 1) * right + Y.reshape(-1, 1) * up
        o = cam + target  # orthographic: rays parallel to fwd through the grid
        d = np.tile(fwd, (len(o), 1))
        t = np.zeros(len(o))
        alive = np.ones(len(o), bool)
        for _ in range(200):
            p = o + t[:, None] * d
            dist = sdf(shape, p)
            t = np.where(alive, t + dist, t)
            alive &= (dist > 1e-9) & (t < 8)
        p = o + t[:, None] * d
        hit = np.abs(sdf(shape, p)) < 1e-6
        p = p[hit]
        n = grad(shape, p)
        facing = (n @ -fwd) > 0.05
        pts.append(p[facing])
    p = np.concatenate(pts)
    return project(shape, p)


def write_ply(path, p, n):
    with open(path, "wb") as f:
        f.write(("ply\nformat binary_little_endian 1.0\nelement vertex %d\n" % len(p)).encode())
        for k in ["x", "y", "z", "nx", "ny", "nz"]:
            f.write(("property float %s\n" % k).encode())
        f.write(b"end_header\n")
        f.write(np.hstack([p, n]).astype("<f4").tobytes())


def evaluate(shape, mesh_path, truth, o3d):
    m = o3d.io.read_triangle_mesh(mesh_path)
    V = np.asarray(m.vertices).astype(np.float64)
    F = np.asarray(m.triangles)
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    cr = np.cross(b - a, c - a)
    area = np.linalg.norm(cr, axis=1)
    cen = (a + b + c) / 3
    # mesh -> truth: area-weighted |sdf| at centroids and vertices (Simpson-like)
    dm = (np.abs(sdf(shape, cen)) * 0.5 + (np.abs(sdf(shape, a)) + np.abs(sdf(shape, b)) + np.abs(sdf(shape, c))) / 6)
    mesh_to_truth = float((dm * area).sum() / area.sum())
    fn = cr / np.maximum(area[:, None], 1e-300)
    agree = float(((fn * grad(shape, cen)).sum(1) * area).sum() / area.sum())
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(m))
    dt = scene.compute_distance(o3d.core.Tensor(truth.astype(np.float32))).numpy()
    truth_to_mesh = float(dt.mean())
    # components
    tri_clusters, counts, _ = m.cluster_connected_triangles()
    return dict(v=len(V), f=len(F), m2t=mesh_to_truth, t2m=truth_to_mesh,
                chamfer=(mesh_to_truth + truth_to_mesh) / 2, normal=agree,
                components=len(counts))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--shape", default="sphere")
    ap.add_argument("--sampling", default="uniform:100000")  # uniform:N or scan:views:res
    ap.add_argument("--depths", default="8,9,10,11")
    ap.add_argument("--psr", default=os.path.join(HERE, "..", "target", "release", "psr"))
    ap.add_argument("--variants", default="psr,pw0,o3d")
    ap.add_argument("--psr-args", default="")
    ap.add_argument("--seed", type=int, default=1)
    # Gaussian noise: SIGMA on each coordinate of the positions (shape units; the sphere's
    # radius is 1), and 0.1 on each component of the normals before renormalising them.
    ap.add_argument("--noise", type=float, default=0.0)
    a = ap.parse_args()
    import open3d as o3d
    rng = np.random.default_rng(a.seed)
    tag = f"{a.shape}_{a.sampling.replace(':', '-')}_{a.seed}"
    if a.noise > 0:
        tag += f"_noise{a.noise:g}"
    work = os.path.join(HERE, "runs", tag)
    os.makedirs(work, exist_ok=True)
    ply = os.path.join(work, "in.ply")
    kind, *rest = a.sampling.split(":")
    if kind == "uniform":
        p = uniform_samples(a.shape, int(rest[0]), rng)
    else:
        p = scan_samples(a.shape, int(rest[0]), int(rest[1]), rng, int(rest[2]) if len(rest) > 2 else None)
    n = grad(a.shape, p)
    if a.noise > 0:
        p = p + rng.normal(size=p.shape) * a.noise
        n = n + rng.normal(size=n.shape) * 0.1
        n /= np.linalg.norm(n, axis=1, keepdims=True)
    write_ply(ply, p, n)
    truth = uniform_samples(a.shape, 200000, np.random.default_rng(99))
    print(f"# {tag}: {len(p)} samples", flush=True)
    print("| depth | variant | verts | mesh→truth | truth→mesh | chamfer | normal | comps | s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for d in [int(x) for x in a.depths.split(",")]:
        for var in a.variants.split(","):
            out = os.path.join(work, f"{var}_d{d}.ply")
            t0 = time.time()
            env = dict(os.environ)
            if var.startswith("X:"):
                _, name, envs = var.split(":", 2)
                for kv in envs.split("+"):
                    k, v = kv.split("=")
                    env[k] = v
            if var == "o3d" and os.path.exists(out):
                pass
            elif var == "o3d":
                pcd = o3d.io.read_point_cloud(ply)
                mesh, dens = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(
                    pcd, depth=d, width=0, scale=1.1, linear_fit=False, n_threads=2)
                o3d.io.write_triangle_mesh(out, mesh)
            else:
                extra = a.psr_args.split() if var == "psr" else []
                if var == "pw0":
                    extra = ["--point-weight", "0"]
                elif var == "follow":
                    extra = a.psr_args.split() + ["--screening-follows-noise"]
                elif var == "fixed":
                    extra = a.psr_args.split() + ["--screening-follows-noise", "false"]
                cmd = [a.psr, "--in", ply, "--out", out, "--depth", str(d), "--no-density"] + extra
                r = subprocess.run(cmd, capture_output=True, text=True, env=env)
                if r.returncode:
                    print(r.stderr); continue
            secs = time.time() - t0
            e = evaluate(a.shape, out, truth, o3d)
            print(f"| {d} | {var[:28]} | {e['v']} | {e['m2t']:.3e} | {e['t2m']:.3e} | {e['chamfer']:.3e} | {e['normal']:.5f} | {e['components']} | {secs:.1f} |", flush=True)


if __name__ == "__main__":
    main()
