"""Shared helpers of the Python package's tests: the `raypack` command line (the Rust
API's answers, bit for bit), the RAYS.md file formats, and small meshes and rays.

The command line is `$RAYPACK_BIN`, else `target/release/raypack` of this repository
(`cargo build --release` makes it); without it the tests that need it fail, naming it.
"""

from __future__ import annotations

import os
import pathlib
import struct
import subprocess

import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]


def raypack_bin() -> pathlib.Path:
    path = pathlib.Path(os.environ.get("RAYPACK_BIN", REPO / "target" / "release" / "raypack"))
    if not path.is_file():
        pytest.fail(f"{path}: the raypack command line is missing; run `cargo build --release` first")
    return path


def run_raypack(*args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    """Runs the command line from the repository root and fails the test on an error."""
    out = subprocess.run(
        [str(raypack_bin()), *map(str, args)],
        cwd=REPO,
        capture_output=True,
        text=True,
        env={**os.environ, **(env or {})},
    )
    if out.returncode != 0:
        pytest.fail(f"raypack {' '.join(map(str, args))} failed:\n{out.stderr}")
    return out


def write_rays(path, o, d, t0, t1, width=0, height=0):
    """A RAYS.md rays file: records `ox oy oz tmin dx dy dz tmax`."""
    n = len(o)
    rec = np.empty((n, 8), dtype="<f4")
    rec[:, 0:3], rec[:, 3], rec[:, 4:7], rec[:, 7] = o, t0, d, t1
    with open(path, "wb") as f:
        f.write(b"RAYS0001" + struct.pack("<QII", n, width, height) + rec.tobytes())


def read_rays(path):
    data = pathlib.Path(path).read_bytes()
    assert data[:8] == b"RAYS0001"
    n, width, height = struct.unpack_from("<QII", data, 8)
    rec = np.frombuffer(data, dtype="<f4", offset=24).reshape(n, 8)
    return rec[:, 0:3], rec[:, 4:7], rec[:, 3], rec[:, 7], width, height


def read_hits(path):
    """A RAYS.md hits file as `(t, prim, u, v)`, prim as uint32 (0xFFFFFFFF: a miss)."""
    data = pathlib.Path(path).read_bytes()
    assert data[:8] == b"HITS0001"
    (n,) = struct.unpack_from("<Q", data, 8)
    rec = np.frombuffer(data, dtype="<u4", offset=16).reshape(n, 4)
    return rec[:, 0].view("<f4"), rec[:, 1], rec[:, 2].view("<f4"), rec[:, 3].view("<f4")


def cli_hits(tmp_path, scene: str, o, d, t0, t1, mode="scalar"):
    """The closest hits of `raypack trace` (the Rust library's) for these rays."""
    rays, hits = tmp_path / "q.rays", tmp_path / "q.hits"
    write_rays(rays, o, d, t0, t1)
    run_raypack("trace", scene, "--rays", rays, "-o", hits, "--mode", mode)
    return read_hits(hits)


def bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float32).view(np.uint32)


def assert_same_hits(got, want_t, want_prim, want_u, want_v, what=""):
    """Python `Hits` against a hits file's records, bit for bit (a miss is -1 here and
    0xFFFFFFFF there; its t is inf in both)."""
    prim = np.where(want_prim == 0xFFFFFFFF, -1, want_prim.astype(np.int64))
    assert np.array_equal(got.prim.reshape(-1), prim), f"{what}: primitive ids differ"
    for name, g, w in (("t", got.t, want_t), ("u", got.u, want_u), ("v", got.v, want_v)):
        hit = prim >= 0
        assert np.array_equal(bits(g.reshape(-1))[hit], bits(w)[hit]), f"{what}: {name} differs"
    assert np.all(np.isinf(got.t.reshape(-1)[prim < 0])), f"{what}: a miss's t is not inf"


def random_mesh(rng: np.random.Generator, n: int):
    """`n` random triangles in the unit cube, some tiny, some sharing vertices."""
    v = rng.random((3 * n, 3)).astype(np.float32)
    t = rng.integers(0, 3 * n, size=(n, 3))
    return v, t


def rays_at(rng: np.random.Generator, n: int, lo, hi, scale=2.0):
    """Rays from a box around [lo, hi] aimed at random points inside it, with
    axis-parallel and +-0.0 directions and origins on the box's planes mixed in."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    c, r = (lo + hi) / 2, (hi - lo) / 2 * scale
    o = c + r * (rng.random((n, 3)) * 2 - 1)
    target = lo + (hi - lo) * rng.random((n, 3))
    d = target - o
    axis = rng.integers(0, 3, n)
    k = n // 8
    d[:k] = 0.0
    d[np.arange(k), axis[:k]] = rng.choice([-1.0, 1.0], k)
    d[k : 2 * k, 0] = -0.0
    o[2 * k : 3 * k, 1] = lo[1]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return o.astype(np.float32), d.astype(np.float32)


def write_obj(path, v, t):
    with open(path, "w") as f:
        for x in v:
            f.write("v %r %r %r\n" % tuple(float(c) for c in x))
        for a, b, c in t:
            f.write(f"f {a + 1} {b + 1} {c + 1}\n")
