"""The package's answers: bit for bit the Rust library's (through the `raypack` command
line on the same rays), the same in every mode and thread count, and in agreement with
an independent ray-triangle test written here in float64."""

from __future__ import annotations

import math
import os
import subprocess
import sys
import threading

import numpy as np
import pytest

import raypack
from conftest import (
    REPO,
    assert_same_hits,
    bits,
    cli_hits,
    rays_at,
    random_mesh,
    read_rays,
    run_raypack,
    write_obj,
)

KNOT = str(REPO / "scenes" / "knot.obj")


def same(a, b) -> bool:
    """Two `Hits` with the same bits in every field."""
    return all(
        np.array_equal(bits(x), bits(y)) if x.dtype == np.float32 else np.array_equal(x, y)
        for x, y in zip(a, b)
    )


def test_arrays_scene_matches_the_rust_library(tmp_path):
    rng = np.random.default_rng(1)
    v, t = random_mesh(rng, 400)
    obj = tmp_path / "soup.obj"
    write_obj(obj, v, t)
    scene = raypack.Scene(v, t)
    assert scene.triangle_count == 400
    o, d = rays_at(rng, 5000, [0, 0, 0], [1, 1, 1])
    t0 = np.zeros(len(o), np.float32)
    t1 = np.where(rng.random(len(o)) < 0.2, 0.5, np.inf).astype(np.float32)
    got = scene.intersect(o, d, t0, t1)
    assert got.hit.sum() > 1000
    assert_same_hits(got, *cli_hits(tmp_path, str(obj), o, d, t0, t1), what="soup")


@pytest.mark.parametrize("mode", ["scalar", "stream", "packet8"])
def test_loaded_scenes_match_the_rust_library(tmp_path, mode):
    for name in (KNOT, str(REPO / "scenes" / "part3.toml")):
        scene = raypack.Scene.load(name)
        lo, hi = scene.bounds
        o, d = rays_at(np.random.default_rng(2), 3000, lo, hi)
        t0 = np.zeros(len(o), np.float32)
        t1 = np.full(len(o), np.inf, np.float32)
        got = scene.intersect(o, d, mode=mode)
        assert got.hit.any()
        assert_same_hits(got, *cli_hits(tmp_path, name, o, d, t0, t1, mode), what=f"{name} {mode}")


@pytest.mark.parametrize("mode", ["scalar", "stream", "packet8", "packet16"])
def test_bvh8_scenes_match_the_rust_library(tmp_path, mode):
    rng = np.random.default_rng(11)
    v, t = random_mesh(rng, 400)
    obj = tmp_path / "soup.obj"
    write_obj(obj, v, t)
    scenes = [(str(obj), raypack.Scene(v, t, accel="bvh8"))]
    scenes += [(n, raypack.Scene.load(n, accel="bvh8")) for n in (KNOT, str(REPO / "scenes" / "part3.toml"))]
    for name, scene in scenes:
        assert scene.accel == "bvh8"
        lo, hi = scene.bounds
        o, d = rays_at(rng, 3000, lo, hi)
        t0 = np.zeros(len(o), np.float32)
        t1 = np.where(rng.random(len(o)) < 0.2, 0.3, np.inf).astype(np.float32)
        got = scene.intersect(o, d, t0, t1, mode=mode)
        assert got.hit.any() and not got.hit.all()
        assert_same_hits(got, *cli_hits(tmp_path, name, o, d, t0, t1, mode), what=f"{name} {mode} bvh8")
        assert np.array_equal(scene.occluded(o, d, t0, t1, mode=mode), got.hit), f"{name} {mode}"


def test_bvh8_and_kdtree_give_the_same_bits_in_every_mode():
    kd, bvh = raypack.Scene.load(KNOT, accel="kdtree"), raypack.Scene.load(KNOT, accel="bvh8")
    assert kd.accel == "kdtree"
    lo, hi = kd.bounds
    o, d = rays_at(np.random.default_rng(12), 20000, lo, hi)
    reach = 0.5 * float(np.linalg.norm(hi - lo))
    want = kd.intersect(o, d, mode="scalar", threads=1)
    want_occ = kd.occluded(o, d, 0.0, reach, mode="scalar")
    for mode in raypack.MODES:
        assert same(bvh.intersect(o, d, mode=mode), want), mode
        assert np.array_equal(bvh.occluded(o, d, 0.0, reach, mode=mode), want_occ), mode
    for mode in ("packet", "packet4", "tile64", "stream"):
        assert same(bvh.trace_image(width=40, height=30, mode=mode), kd.trace_image(width=40, height=30)), mode


def test_auto_races_the_trees_and_keeps_their_bits():
    kd, auto = raypack.Scene.load(KNOT, accel="kdtree"), raypack.Scene.load(KNOT)
    assert auto.accel == "auto" and auto.last_accel == ("bvh8", "bvh8")
    assert kd.last_accel == ("kdtree", "kdtree")
    lo, hi = kd.bounds
    # 70,000 rays: enough for a race (65,536); 1,000: the last winner answers.
    o, d = rays_at(np.random.default_rng(13), 70000, lo, hi)
    reach = 0.5 * float(np.linalg.norm(hi - lo))
    want = kd.intersect(o, d, mode="scalar")
    want_occ = kd.occluded(o, d, 0.0, reach, mode="scalar")
    for mode in ("auto", "stream", "packet16", "scalar"):
        assert same(auto.intersect(o, d, mode=mode), want), mode
        assert np.array_equal(auto.occluded(o, d, 0.0, reach, mode=mode), want_occ), mode
        assert set(auto.last_accel) <= {"kdtree", "bvh8"}
        small = auto.intersect(o[:1000], d[:1000], mode=mode)
        assert same(small, kd.intersect(o[:1000], d[:1000], mode="scalar")), mode
    assert same(auto.trace_image(width=40, height=30), kd.trace_image(width=40, height=30))


def test_every_mode_and_thread_count_gives_the_same_bits():
    scene = raypack.Scene.load(KNOT)
    lo, hi = scene.bounds
    o, d = rays_at(np.random.default_rng(3), 20000, lo, hi)
    want = scene.intersect(o, d, mode="scalar", threads=1)
    want_occ = scene.occluded(o, d, 0.0, 0.7 * float(np.linalg.norm(hi - lo)), mode="scalar")
    for mode in raypack.MODES:
        for threads in (None, 1, 3):
            assert same(scene.intersect(o, d, mode=mode, threads=threads), want), mode
            occ = scene.occluded(o, d, 0.0, 0.7 * float(np.linalg.norm(hi - lo)), mode=mode, threads=threads)
            assert np.array_equal(occ, want_occ), mode


def test_occluded_is_a_hit_before_t_max():
    scene = raypack.Scene.load(KNOT)
    lo, hi = scene.bounds
    o, d = rays_at(np.random.default_rng(4), 20000, lo, hi)
    t_max = np.random.default_rng(5).random(len(o)).astype(np.float32) * float(np.linalg.norm(hi - lo))
    h = scene.intersect(o, d, 0.0, t_max)
    occ = scene.occluded(o, d, 0.0, t_max)
    assert occ.dtype == np.bool_
    assert np.array_equal(occ, h.hit)
    assert 0 < occ.sum() < len(occ)


def test_camera_rays_are_the_primary_set_of_rays_md(tmp_path):
    scene = raypack.Scene.load(KNOT)
    cam = scene.camera
    o, d = scene.camera_rays(width=32, height=48)
    assert o.shape == d.shape == (48, 32, 3)
    path = tmp_path / "p.rays"
    args = ["rays", KNOT, "--set", "primary", "--width", "32", "--height", "48", "-o", path]
    run_raypack(*args)
    po, pd, t0, t1, w, h = read_rays(path)
    assert (w, h) == (32, 48)
    # RAYS.md's packet order: 2x2 quads, row-major in 16x16 tiles, tiles row-major.
    i = np.arange(w * h)
    tile, quad, lane = i // 256, (i % 256) // 4, i % 4
    x = (tile % (w // 16)) * 16 + (quad % 8) * 2 + lane % 2
    y = (tile // (w // 16)) * 16 + (quad // 8) * 2 + lane // 2
    assert np.array_equal(bits(o[y, x]), bits(po)) and np.array_equal(bits(d[y, x]), bits(pd))
    assert np.allclose(o[0, 0], cam["eye"])
    # The centre pixel looks at the target.
    o2, d2 = scene.camera_rays(width=1, height=1)
    f = np.subtract(cam["target"], cam["eye"])
    assert np.allclose(d2[0, 0], f / np.linalg.norm(f), atol=1e-6)


@pytest.mark.parametrize("size", [(1, 1), (37, 23), (64, 48)])
def test_trace_image_is_intersect_of_the_camera_rays(size):
    w, h = size
    scene = raypack.Scene.load(KNOT)
    o, d = scene.camera_rays(width=w, height=h)
    want = scene.intersect(o, d)
    assert want.t.shape == (h, w) and want.normal.shape == (h, w, 3)
    for mode in ("packet", "packet4", "tile64", "stream", "scalar"):
        got = scene.trace_image(width=w, height=h, mode=mode)
        assert same(got, want), mode


def test_leading_shapes_and_scalar_limits_are_kept():
    scene = raypack.Scene.load(KNOT)
    o, d = scene.camera_rays(width=16, height=16)
    h = scene.intersect(o.astype(np.float64), d.astype(np.float64))
    assert h.t.shape == (16, 16) and h.prim.dtype == np.int64
    assert scene.occluded(o[0, 0], d[0, 0]).shape == ()
    # One origin for every direction broadcasts, numpy's way.
    assert same(scene.intersect(o[0, 0], d), h)
    flat = scene.intersect(o.reshape(-1, 3), d.reshape(-1, 3), t_min=np.zeros(256), t_max=math.inf)
    assert same(tuple(a.reshape(-1) for a in h[:4]), tuple(a.reshape(-1) for a in flat[:4]))


def moller_trumbore(o, d, v0, v1, v2, t_min, t_max):
    """Closest hits in float64, one triangle at a time over all rays: (t, prim, u, v)."""
    n = len(o)
    best_t = np.full(n, np.inf)
    best_p = np.full(n, -1)
    best_u, best_v = np.zeros(n), np.zeros(n)
    for j in range(len(v0)):
        e1, e2 = v1[j] - v0[j], v2[j] - v0[j]
        p = np.cross(d, e2)
        det = p @ e1
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            inv = 1.0 / det
            s = o - v0[j]
            u = (s * p).sum(1) * inv
            q = np.cross(s, e1)
            v = (d * q).sum(1) * inv
            t = (q @ e2) * inv
            ok = (det != 0) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > t_min) & (t < t_max) & (t < best_t)
        best_t[ok], best_p[ok], best_u[ok], best_v[ok] = t[ok], j, u[ok], v[ok]
    return best_t, best_p, best_u, best_v


def test_small_meshes_agree_with_an_independent_ray_triangle_test():
    rng = np.random.default_rng(6)
    cube_v = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], np.float32)
    cube_t = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                       [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    meshes = [(cube_v, cube_t), random_mesh(rng, 60), random_mesh(rng, 200)]
    for v, t in meshes:
        scene = raypack.Scene(v, t)
        o, d = rays_at(rng, 4000, v.min(0), v.max(0))
        h = scene.intersect(o, d)
        tri = v.astype(np.float64)[t]
        rt, rp, ru, rv = moller_trumbore(o.astype(np.float64), d.astype(np.float64),
                                         tri[:, 0], tri[:, 1], tri[:, 2], 0.0, np.inf)
        # Rays within rounding of an edge or of a second, nearly as close triangle may
        # go either way; everywhere else the two must agree.
        margin = np.minimum(np.minimum(ru, rv), 1 - ru - rv)
        clear = (rp < 0) | (margin > 1e-4)
        both = clear & (rp >= 0)
        assert clear.mean() > 0.9
        assert np.array_equal(h.hit[clear], rp[clear] >= 0)
        # Same triangle, or another at the same distance (a soup overlaps itself).
        close = np.isclose(h.t[both], rt[both], rtol=1e-4, atol=1e-5)
        assert close.all()
        assert np.mean(h.prim[both] == rp[both]) > 0.99
        assert np.allclose(h.u[both & (h.prim == rp)], ru[both & (h.prim == rp)], atol=1e-4)
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        with np.errstate(invalid="ignore"):
            n /= np.linalg.norm(n, axis=1, keepdims=True)
        hit = h.hit & np.isfinite(n[np.maximum(h.prim, 0)]).all(1)
        assert np.allclose(h.normal[hit], n[h.prim[hit]], atol=1e-5)
        assert np.all(h.normal[~h.hit] == 0) and np.all(np.isinf(h.t[~h.hit]))


def test_threads_calling_at_once_get_their_own_answers():
    scene = raypack.Scene.load(KNOT)
    lo, hi = scene.bounds
    sets = [rays_at(np.random.default_rng(10 + k), 30000, lo, hi) for k in range(4)]
    want = [scene.intersect(o, d) for o, d in sets]
    got = [None] * 4

    def work(k):
        got[k] = scene.intersect(*sets[k], threads=2)

    threads = [threading.Thread(target=work, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert all(same(g, w) for g, w in zip(got, want))


def test_isa_names_the_kernels_in_use():
    assert raypack.isa() in ("sse", "avx2", "avx512")


def test_every_instruction_set_gives_the_same_bits(tmp_path):
    """The kernels of each set this CPU runs (RAYPACK_ISA, read at import, so one
    interpreter per set) give the bits of the set in use here."""
    scene = raypack.Scene.load(KNOT)
    lo, hi = scene.bounds
    o, d = rays_at(np.random.default_rng(8), 20000, lo, hi)
    np.save(tmp_path / "o.npy", o)
    np.save(tmp_path / "d.npy", d)
    code = (
        "import sys, numpy as np, raypack\n"
        f"s = raypack.Scene.load({KNOT!r})\n"
        f"o, d = np.load({str(tmp_path / 'o.npy')!r}), np.load({str(tmp_path / 'd.npy')!r})\n"
        "for mode in ('stream', 'packet4', 'packet8', 'packet16', 'tile64'):\n"
        "    h = s.intersect(o, d, mode=mode)\n"
        "    np.savez(sys.argv[1] + mode, *h, occ=s.occluded(o, d, 0.0, 1.0, mode=mode))\n"
        "print(raypack.isa())\n"
    )
    want = scene.intersect(o, d, mode="scalar")
    want_occ = scene.occluded(o, d, 0.0, 1.0, mode="scalar")
    ran = []
    for isa in ("sse", "avx2", "avx512"):
        out = subprocess.run(
            [sys.executable, "-c", code, str(tmp_path / isa)],
            env={**os.environ, "RAYPACK_ISA": isa}, capture_output=True, text=True,
        )
        if out.returncode != 0:
            # Refused only because this CPU lacks the set, and said so.
            assert "RAYPACK_ISA" in out.stderr and isa != "sse", out.stderr
            continue
        assert out.stdout.strip() == isa
        ran.append(isa)
        for mode in ("stream", "packet4", "packet8", "packet16", "tile64"):
            got = np.load(str(tmp_path / isa) + mode + ".npz")
            assert same(tuple(got[f"arr_{k}"] for k in range(5)), want), (isa, mode)
            assert np.array_equal(got["occ"], want_occ), (isa, mode)
    assert "sse" in ran and raypack.isa() in ran
