"""Writes the hand-made seed inputs of the fuzz corpora (fuzz/corpus/<target>/): small PLY
clouds in each encoding (ASCII, binary little and big endian, double positions, colours and
confidence, positions with sensors and an extra property), a PLY mesh in ASCII and binary,
PoissonRecon's ASCII and binary points, a header that declares four billion vertices, and
random bytes for the structured targets (c_api, reconstruct), which libFuzzer then grows.
Deterministic (seeded); run from fuzz/: python3 seeds.py"""
import random
import struct

random.seed(19)


def ply(path, fmt, props, rows, extra=b""):
    head = "ply\nformat %s 1.0\nelement vertex %d\n" % (fmt, len(rows))
    for t, n in props:
        head += "property %s %s\n" % (t, n)
    head = head.encode() + extra + b"end_header\n"
    if fmt == "ascii":
        body = "".join(" ".join(repr(v) for v in r) + "\n" for r in rows).encode()
    else:
        e = "<" if fmt == "binary_little_endian" else ">"
        code = {"float": "f", "double": "d", "uchar": "B", "int": "i", "ushort": "H"}
        body = b"".join(struct.pack(e + "".join(code[t] for t, _ in props), *r) for r in rows)
    open(path, "wb").write(head + body)


def points(n):
    out = []
    for _ in range(n):
        p = [random.uniform(-1, 1) for _ in range(3)]
        norm = sum(x * x for x in p) ** 0.5
        out.append(p + [c / norm for c in p])
    return out


xyzn = [("float", k) for k in "x y z nx ny nz".split()]
d = "corpus/ply_reader/"
ply(d + "ascii_points.ply", "ascii", xyzn, points(8))
ply(d + "binary_le_points.ply", "binary_little_endian", xyzn, points(16))
ply(d + "binary_be_points.ply", "binary_big_endian", xyzn, points(16))
ply(d + "double_points.ply", "binary_little_endian",
    [("double", k) for k in "x y z".split()] + [("float", k) for k in "nx ny nz".split()], points(8))
colored = [r + [random.randrange(256) for _ in range(3)] + [random.random()] for r in points(8)]
ply(d + "colors_confidence.ply", "binary_little_endian",
    xyzn + [("uchar", "red"), ("uchar", "green"), ("uchar", "blue"), ("float", "confidence")], colored)
ply(d + "positions_only_sensors.ply", "ascii",
    [("float", k) for k in "x y z sensor_x sensor_y sensor_z intensity".split()],
    [r[:3] + [0, 0, 5, 1.5] for r in points(6)])
V = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]
F = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]
mesh_head = ("ply\nformat %s 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
             "property float z\nelement face 4\nproperty list uchar %s vertex_indices\nend_header\n")
open(d + "mesh_ascii.ply", "wb").write(
    (mesh_head % ("ascii", "int") + "".join("%g %g %g\n" % tuple(v) for v in V)
     + "".join("3 %d %d %d\n" % tuple(f) for f in F)).encode())
open(d + "mesh_binary.ply", "wb").write(
    (mesh_head % ("binary_little_endian", "uint")).encode()
    + b"".join(struct.pack("<3f", *v) for v in V) + b"".join(struct.pack("<B3I", 3, *f) for f in F))
open(d + "points.xyz", "w").write("".join(" ".join("%.5f" % c for c in r) + "\n" for r in points(8)))
open(d + "points.bnpts", "wb").write(b"".join(struct.pack("<6f", *r) for r in points(8)))
open(d + "huge_count_header.ply", "wb").write(
    b"ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\n"
    + b"".join(b"property float %s\n" % k.encode() for k in "x y z nx ny nz".split())
    + b"end_header\n" + bytes(48))
for target in ["c_api", "reconstruct"]:
    for n in [64, 256, 1024, 4096]:
        open("corpus/%s/random_%d" % (target, n), "wb").write(bytes(random.randrange(256) for _ in range(n)))
