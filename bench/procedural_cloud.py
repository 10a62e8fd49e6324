"""A procedural oriented point cloud of any size, for the out-of-core and distributed benchmarks
(issues 20 and 21): exact samples of a closed "fractal planet", a sphere of radius 1 whose radius
is displaced by waves at every scale, written as a binary little-endian PLY (float x y z nx ny
nz, 24 bytes a point) in chunks, so that 200 million points (4.8 GB) take
about two minutes and a few tens of MB to generate.

    python3 bench/procedural_cloud.py --points 200000000 --out /data/planet_200m.ply
    python3 bench/procedural_cloud.py --points 10000000 --octaves 12 --out planet_10m.ply

The surface is r(u) = 1 + h(u) over unit directions u, with h a sum of octaves k = 0..K-1, each
`--waves` plane waves a_k sin(2^k f ω·u + φ) (random unit ω, random phase φ, f = 3), amplitude
a_k = A 2^-k (A = 0.05): self-similar, every octave as steep as the first (slope 0.15), so the
surface has bumps of every size from the first octave's (wavelength 2 and height 0.05) down to
the last's (with K = 13, wavelength 5e-4, one of depth 12's finest cells of the 2.2-wide cube).
The normal is the gradient of F(x) = |x| - 1 - h(x/|x|), exact.
Directions are uniform on the sphere, so the samples' density varies only with the surface's
stretch. Everything is fixed by `--seed`: the same arguments write the same bytes (on one
machine: the waves are summed in single precision, so positions are exact to float rounding and
normals to about 1e-4).

Needs numpy (bench/requirements.txt)."""

import argparse
import os
import sys
import time

import numpy as np

BASE_FREQUENCY = 3.0


def make_waves(octaves, waves, amplitude, seed):
    """The waves of every octave: unit directions (n×3), frequencies, amplitudes and phases."""
    rng = np.random.default_rng(seed)
    count = octaves * waves
    directions = rng.normal(size=(count, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    octave = np.repeat(np.arange(octaves), waves)
    frequencies = BASE_FREQUENCY * np.exp2(octave)
    # The octave's amplitude split among its waves so that their sum has amplitude about a_k.
    amplitudes = amplitude * np.exp2(-octave) / np.sqrt(waves)
    phases = rng.uniform(0.0, 2.0 * np.pi, size=count)
    return directions, frequencies, amplitudes, phases


def max_height(waves):
    """An upper bound of |h| over the sphere: the sum of the waves' amplitudes."""
    return float(np.sum(waves[2]))


def samples(directions_u, waves):
    """Positions and unit outward normals of the surface at unit directions `directions_u`."""
    omega, frequencies, amplitudes, phases = waves
    u = directions_u
    # Every wave's argument at once (points × waves), then h and its gradient by two products;
    # in single precision, which numpy's sin and cos vectorise (the arguments' rounding, at most
    # about 1e-3 radians for the finest octave, moves the surface by about 1e-8).
    t = u.astype(np.float32) @ (omega * frequencies[:, None]).T.astype(np.float32)
    t += phases.astype(np.float32)
    h = (np.sin(t) @ amplitudes.astype(np.float32)).astype(np.float64)
    grad_u = (np.cos(t) @ (omega * (amplitudes * frequencies)[:, None]).astype(np.float32)).astype(
        np.float64
    )
    radius = 1.0 + h
    positions = u * radius[:, None]
    # ∇F = u - (I - u uᵀ) ∇_u h / |x|: the tangential part of h's gradient, scaled by 1/r.
    tangential = grad_u - np.sum(grad_u * u, axis=1, keepdims=True) * u
    normals = u - tangential / radius[:, None]
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return positions, normals


def write(path, count, waves, seed, chunk, description):
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"comment procedural_cloud.py {description}\n"
        f"element vertex {count}\n"
        "property float x\nproperty float y\nproperty float z\n"
        "property float nx\nproperty float ny\nproperty float nz\nend_header\n"
    )
    rng = np.random.default_rng(seed + 1)
    written = 0
    started = time.time()
    with open(path, "wb") as out:
        out.write(header.encode("ascii"))
        while written < count:
            n = min(chunk, count - written)
            u = rng.normal(size=(n, 3))
            u /= np.linalg.norm(u, axis=1, keepdims=True)
            positions, normals = samples(u, waves)
            out.write(np.hstack([positions, normals]).astype("<f4").tobytes())
            written += n
            if sys.stderr.isatty() or written == count:
                rate = written / max(time.time() - started, 1e-9)
                print(f"\r{written:,} / {count:,} points ({rate:,.0f}/s)", end="", file=sys.stderr)
    print(file=sys.stderr)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--points", type=int, required=True, help="number of samples")
    parser.add_argument("--out", required=True, help="binary PLY to write")
    parser.add_argument("--octaves", type=int, default=13, help="octaves of detail (13)")
    parser.add_argument("--waves", type=int, default=4, help="plane waves per octave (4)")
    parser.add_argument(
        "--amplitude", type=float, default=0.05, help="first octave's relative amplitude (0.05)"
    )
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--chunk", type=int, default=1 << 16, help="points per chunk (2^16)")
    args = parser.parse_args()
    if args.points < 1 or args.octaves < 1 or args.waves < 1 or args.chunk < 1:
        parser.error("--points, --octaves, --waves and --chunk must be positive")
    waves = make_waves(args.octaves, args.waves, args.amplitude, args.seed)
    # r(u) = 1 + h(u) is a graph over the sphere: closed and without folds while r > 0.
    if max_height(waves) >= 1.0:
        parser.error(
            "the radius could reach 0 (the amplitudes sum to 1 or more): lower --amplitude"
        )
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    description = (
        f"--octaves {args.octaves} --waves {args.waves} "
        f"--amplitude {args.amplitude} --seed {args.seed}"
    )
    write(args.out, args.points, waves, args.seed, args.chunk, description)


if __name__ == "__main__":
    main()
