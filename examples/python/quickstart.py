#!/usr/bin/env python3
"""Reconstructs a surface with the psr Python package (pip install ./python).

    python3 examples/python/quickstart.py [cloud.ply [mesh.ply [depth]]]

Reads an oriented point cloud (default: examples/data/kitten_cgal.ply), reconstructs it with a
progress bar when tqdm is installed, trims the surface invented far from the samples and writes
both meshes. examples/python/reconstruct.py does the same through ctypes alone, without the
package.
"""

import sys
from pathlib import Path

import psr

here = Path(__file__).resolve().parent
cloud_path = sys.argv[1] if len(sys.argv) > 1 else here.parent / "data" / "kitten_cgal.ply"
out = Path(sys.argv[2] if len(sys.argv) > 2 else "kitten_mesh.ply")
depth = int(sys.argv[3]) if len(sys.argv) > 3 else 8

cloud = psr.read_ply(cloud_path)
try:
    import tqdm  # noqa: F401  (only to choose the progress display)

    progress = "tqdm"
except ImportError:
    progress = None
mesh = psr.reconstruct(cloud.points, cloud.normals, depth=depth, progress=progress)
trimmed = mesh.trim()
mesh.write_ply(out)
trimmed.write_ply(out.with_name(out.stem + "_trimmed.ply"))
print(
    f"psr {psr.__version__}: {len(cloud)} points -> {mesh}; trimmed at density "
    f"{trimmed.trim_density:.3g}: {len(trimmed.triangles)} triangles; wrote {out}"
)
