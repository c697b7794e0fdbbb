#!/usr/bin/env python3
"""Writes the generated scenes of perf/report.py's suite as OBJ (plain `v` and `f` lines):

    python3 perf/make_scene.py KIND OUT.obj

Kinds:

    statue     270,000 triangles: a closed lumpy body 2.3 m tall, a scanned statue's
               stand-in (a cube-sphere of 6 x 150 x 150 quads pushed out along its
               directions by noise of two scales, wider at the shoulders, a head on top)
    knot        50,000 triangles: a (3, 5) torus knot, a tube of 1,000 x 25 quads (a thin
               closed model in a mostly empty box)
    terrain    999,698 triangles: a 1 km fBm heightfield on 708 x 708 vertices, y up
    terrain5m  5,113,602 triangles: the same landscape on 1,600 x 1,600 vertices
    soup       200,000 triangles: random triangles of sizes 0.01 to 0.3 (log-uniform),
               overlapping in the cube [-1, 1]^3

Deterministic: every random number is a hash of its index and a fixed seed (no RNG
state, no dependence on numpy's generators), so a kind's file is the same from run to
run.
Needs numpy (`pip install numpy`). The file is written under a temporary name, then
renamed, so an interrupted run leaves no partial OBJ behind.
"""

import os
import sys
import time
from pathlib import Path

try:
    import numpy as np
except ImportError:
    sys.exit("make_scene.py: needs numpy (pip install numpy)")

SEED = 20240601


def hash_u64(seed, *keys):
    """A 64-bit hash of integer arrays (broadcast together): splitmix64's finaliser
    over each key in turn."""
    h = np.full(np.broadcast(*keys).shape if keys else (), seed, dtype=np.uint64)
    for k in keys:
        k = np.asarray(k, dtype=np.int64).view(np.uint64)
        z = h ^ (k + np.uint64(0x9E3779B97F4A7C15))
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        h = z ^ (z >> np.uint64(31))
    return h


def uniform(seed, *keys):
    """Uniform floats in [0, 1), one per broadcast key."""
    return (hash_u64(seed, *keys) >> np.uint64(11)).astype(np.float64) * 2.0**-53


def fade(t):
    return t * t * t * (t * (t * 6 - 15) + 10)


def value_noise(seed, p):
    """Value noise in [-1, 1] at points p (..., d), d = 2 or 3: hashed lattice values,
    quintic interpolation."""
    cell = np.floor(p)
    f = fade(p - cell)
    i = cell.astype(np.int64)
    d = p.shape[-1]
    out = 0.0
    for corner in range(1 << d):
        bits = [(corner >> a) & 1 for a in range(d)]
        w = 1.0
        for a in range(d):
            w = w * (f[..., a] if bits[a] else 1 - f[..., a])
        keys = [i[..., a] + bits[a] for a in range(d)]
        out = out + w * (uniform(seed, *keys) * 2 - 1)
    return out


def fbm(seed, p, octaves, gain=0.5, lacunarity=2.0):
    """Fractional Brownian motion: octaves of value noise, normalised to about [-1, 1]."""
    total, amp, norm = 0.0, 1.0, 0.0
    for o in range(octaves):
        total = total + amp * value_noise(seed + 7919 * o, p * lacunarity**o)
        norm += amp
        amp *= gain
    return total / norm


def grid_faces(rows, cols):
    """Two triangles per cell of a rows x cols vertex grid (row-major), counter-clockwise
    seen from +y when rows run along +z and columns along +x."""
    j, i = np.meshgrid(np.arange(rows - 1), np.arange(cols - 1), indexing="ij")
    a = (j * cols + i).ravel()
    b, c, d = a + 1, a + cols, a + cols + 1
    return np.concatenate([np.stack([a, c, b], 1), np.stack([b, c, d], 1)]).astype(np.int64)


def terrain(n, size=1000.0, height=60.0):
    """An n x n heightfield over [0, size]^2 in x and z; heights are one fBm landscape
    whatever n is, so two sizes show the same terrain."""
    t = np.linspace(0.0, size, n)
    z, x = np.meshgrid(t, t, indexing="ij")
    p = np.stack([x, z], -1) * (5.0 / size)
    # The base octaves shape hills; a second, ridged field adds sharper crests.
    h = fbm(SEED, p, 11)
    ridge = 1 - np.abs(fbm(SEED + 1, p * 0.7 + 3.1, 6))
    y = height * (h + 0.6 * ridge**2)
    v = np.stack([x, y, z], -1).reshape(-1, 3)
    f = grid_faces(n, n)
    # Interleave the two halves so each cell's two triangles are neighbours in the file.
    half = len(f) // 2
    f = np.stack([f[:half], f[half:]], 1).reshape(-1, 3)
    return v, f


def cube_sphere(n):
    """Unit directions of a cube-sphere with n x n quads per face (each split in two),
    closed: the vertices of shared edges and corners are one vertex. Returns (dirs, faces)."""
    k = np.arange(n + 1)
    u, w = np.meshgrid(k, k, indexing="ij")
    u, w = u.ravel(), w.ravel()
    full = np.full_like(u, n)
    zero = np.zeros_like(u)
    # Integer points on the six faces of the cube [0, n]^3, each face's (u, w) order
    # chosen so that its triangles (below) face outward.
    faces6 = [
        np.stack([full, u, w], 1), np.stack([zero, w, u], 1),
        np.stack([w, full, u], 1), np.stack([u, zero, w], 1),
        np.stack([u, w, full], 1), np.stack([w, u, zero], 1),
    ]
    pts = np.concatenate(faces6)
    uniq, index = np.unique(pts, axis=0, return_inverse=True)
    index = index.ravel()
    quads = []
    per = (n + 1) ** 2
    for fi in range(6):
        j, i = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
        a = fi * per + (j * (n + 1) + i).ravel()
        b, c, d = a + 1, a + n + 1, a + n + 2
        quads.append(np.stack([a, d, b], 1))
        quads.append(np.stack([a, c, d], 1))
    tri = index[np.concatenate(quads)]
    # Equal-angle warp of the cube's faces, then onto the sphere.
    q = np.tan((uniq / n * 2 - 1) * (np.pi / 4))
    dirs = q / np.linalg.norm(q, axis=1, keepdims=True)
    return dirs, tri


def statue():
    dirs, f = cube_sphere(150)
    # An upright body: an ellipsoid 0.5 x 1 x 0.35 m (half-axes), wider at the shoulders,
    # lumps of two scales, a head on top.
    radius = 1 / np.sqrt((dirs[:, 0] / 0.5) ** 2 + (dirs[:, 1] / 1.0) ** 2
                         + (dirs[:, 2] / 0.35) ** 2)
    lumps = 0.30 * fbm(SEED + 11, dirs * 1.6 + 5.0, 3)
    detail = 0.05 * fbm(SEED + 12, dirs * 14.0 + 9.0, 4)
    shoulders = 1 + 0.35 * np.abs(dirs[:, 0]) * np.exp(-(dirs[:, 1] - 0.45) ** 2 / 0.02)
    head = 0.3 * np.exp(-np.sum((dirs - [0.0, 1.0, 0.0]) ** 2, axis=1) / 0.05)
    r = radius * shoulders * np.exp(lumps + detail) + head
    v = dirs * r[:, None] + [0.0, 1.0, 0.0]
    v[:, 1] -= v[:, 1].min()
    return v, f


def knot(p=3, q=5, segments=1000, sides=25, major=2.0, minor=0.9, tube=0.3):
    """A (p, q) torus knot swept by a circle; the frame points away from the torus' core
    circle (raypack::scene::generate::torus_knot_obj's), so the tube closes on itself."""
    t = np.arange(segments) * (2 * np.pi / segments)

    def curve(t):
        r = major + minor * np.cos(q * t)
        return np.stack([r * np.cos(p * t), r * np.sin(p * t), minor * np.sin(q * t)], -1)

    c = curve(t)
    tangent = curve(t + 1e-4) - curve(t - 1e-4)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    core = np.stack([major * np.cos(p * t), major * np.sin(p * t), 0 * t], -1)
    n = c - core
    n -= tangent * np.sum(n * tangent, axis=1, keepdims=True)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    b = np.cross(tangent, n)
    a = np.arange(sides) * (2 * np.pi / sides)
    v = (c[:, None] + tube * (np.cos(a)[None, :, None] * n[:, None]
                              + np.sin(a)[None, :, None] * b[:, None])).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(segments), np.arange(sides), indexing="ij")
    i, j = i.ravel(), j.ravel()
    v00 = i * sides + j
    v01 = i * sides + (j + 1) % sides
    v10 = (i + 1) % segments * sides + j
    v11 = (i + 1) % segments * sides + (j + 1) % sides
    f = np.stack([np.stack([v00, v11, v10], 1), np.stack([v00, v01, v11], 1)], 1).reshape(-1, 3)
    return v, f


def soup(count=200_000, smallest=0.01, largest=0.3):
    idx = np.arange(count)
    centre = np.stack([uniform(SEED + 21, idx, a) * 2 - 1 for a in range(3)], -1)
    size = np.exp(np.log(smallest) + uniform(SEED + 22, idx) * np.log(largest / smallest))
    corners = np.stack([
        np.stack([uniform(SEED + 23, idx, 3 * k + a) * 2 - 1 for a in range(3)], -1)
        for k in range(3)], 1)
    v = (centre[:, None] + size[:, None, None] * corners).reshape(-1, 3)
    f = np.arange(3 * count).reshape(-1, 3)
    return v, f


KINDS = {
    "statue": statue,
    "knot": knot,
    "terrain": lambda: terrain(708),
    "terrain5m": lambda: terrain(1600),
    "soup": soup,
}


def write_obj(path, v, f, comment, chunk=200_000):
    """`v` and `f` lines (1-based), the text made by block formatting of whole arrays."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f"{path.name}.tmp.{os.getpid()}")
    try:
        with open(tmp, "w") as out:
            out.write(f"# {comment}: {len(v)} vertices, {len(f)} triangles\n")
            for a in range(0, len(v), chunk):
                block = v[a:a + chunk]
                out.write(("v %.6f %.6f %.6f\n" * len(block)) % tuple(block.ravel().tolist()))
            f = f + 1
            for a in range(0, len(f), chunk):
                block = f[a:a + chunk]
                out.write(("f %d %d %d\n" * len(block)) % tuple(block.ravel().tolist()))
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def main():
    if len(sys.argv) != 3 or sys.argv[1] not in KINDS:
        sys.exit(f"usage: make_scene.py {{{','.join(KINDS)}}} OUT.obj")
    kind, out = sys.argv[1], sys.argv[2]
    start = time.time()
    v, f = KINDS[kind]()
    made = time.time()
    write_obj(out, v, f, f"perf/make_scene.py {kind}")
    lo, hi = v.min(axis=0), v.max(axis=0)
    print(f"{out}: {kind}, {len(f):,} triangles, {len(v):,} vertices; bounds "
          f"[{', '.join(f'{x:.3f}' for x in lo)}] to [{', '.join(f'{x:.3f}' for x in hi)}]; "
          f"made in {made - start:.1f} s, written in {time.time() - made:.1f} s")


if __name__ == "__main__":
    main()
