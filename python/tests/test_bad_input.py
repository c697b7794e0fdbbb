"""Bad input raises `ValueError` (`raypack.Error` where the library checked the values)
with a message that names what is wrong; nothing reaches the kernels or crashes."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

import raypack
from conftest import REPO

TRI_V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
TRI_T = np.array([[0, 1, 2]])


@pytest.fixture(scope="module")
def tri():
    return raypack.Scene(TRI_V, TRI_T)


def test_error_is_a_value_error():
    assert issubclass(raypack.Error, ValueError)


@pytest.mark.parametrize(
    "vertices, triangles, message",
    [
        (TRI_V[:, :2], TRI_T, r"vertices: expected shape \(n, 3\)"),
        (TRI_V, TRI_T[:, :2], r"triangles: expected shape \(m, 3\)"),
        (TRI_V.reshape(-1), TRI_T, "vertices: expected shape"),
        (TRI_V.astype(complex), TRI_T, "vertices: expected a float32 or float64 array"),
        (TRI_V.astype(str), TRI_T, "vertices: expected a float32 or float64 array"),
        (TRI_V, TRI_T.astype(np.float32), "triangles: expected an integer array"),
        (TRI_V, TRI_T.astype(bool), "triangles: expected an integer array"),
        (np.zeros((0, 3), np.float32), np.zeros((0, 3), int), "the mesh is empty"),
        (TRI_V, np.zeros((0, 3), int), "the mesh is empty"),
    ],
)
def test_bad_mesh_arrays(vertices, triangles, message):
    with pytest.raises(ValueError, match=message):
        raypack.Scene(vertices, triangles)


@pytest.mark.parametrize(
    "value, message",
    [
        (np.nan, "vertex 1: y is NaN"),
        (np.inf, "vertex 1: y is inf"),
        (1e39, "vertex 1: y is 1e[+]39, beyond float32's range"),
    ],
)
def test_non_finite_vertices(value, message):
    v = TRI_V.astype(np.float64)
    v[1, 1] = value
    with pytest.raises(raypack.Error, match=message):
        raypack.Scene(v, TRI_T)


@pytest.mark.parametrize(
    "triangles, message",
    [
        ([[0, 1, 3]], "triangle 0: corner 2 is vertex 3, outside 0..3"),
        ([[0, 1, 2], [-1, 1, 2]], "triangle 1: corner 0 is vertex -1, outside 0..3"),
        (np.array([[0, 1, 2**40]], np.int64), "vertex 1099511627776"),
        (np.array([[0, 1, 2**63 + 5]], np.uint64), "out of range"),
    ],
)
def test_indices_out_of_range(triangles, message):
    with pytest.raises(raypack.Error, match=message):
        raypack.Scene(TRI_V, np.asarray(triangles))


def test_bad_rays(tri):
    o = np.array([[0.2, 0.2, 1.0], [0.3, 0.3, 1.0]], np.float32)
    d = np.array([[0, 0, -1.0], [0, 0, -1.0]], np.float32)
    cases = [
        ((o[:, :2], d), ValueError, r"origins: expected shape \(\.\.\., 3\)"),
        ((o, np.ones((3, 3))), ValueError, "origins has shape"),
        ((o.astype(complex), d), ValueError, "origins: expected a float array"),
        ((o, d.astype(object)), ValueError, "directions: expected a float array"),
        ((o, d, np.zeros(3)), ValueError, r"t_min: expected a number or shape \(2,\)"),
        ((o, d, 0.0, "far"), ValueError, "t_max: expected a number"),
    ]
    for args, kind, message in cases:
        for call in (tri.intersect, tri.occluded):
            with pytest.raises(kind, match=message):
                call(*args)
    for field, index in (("o", 1), ("d", 0)):
        bad_o, bad_d = o.copy(), d.copy()
        (bad_o if field == "o" else bad_d)[index, 2] = np.nan
        with pytest.raises(raypack.Error, match=f"ray {index}: origin"):
            tri.intersect(bad_o, bad_d)
    with pytest.raises(raypack.Error, match="ray 0: .*t_min NaN"):
        tri.occluded(o, d, np.nan)
    with pytest.raises(raypack.Error, match="directions: ray 1: y is 1e[+]40, beyond float32"):
        tri.intersect(o, np.array([[0, 0, -1.0], [0, 1e40, -1.0]]))
    with pytest.raises(raypack.Error, match="ray 1: .*t_max NaN"):
        tri.intersect(o, d, 0.0, np.array([1.0, np.nan]))


def test_degenerate_but_valid_rays_miss(tri):
    # A zero direction and t_min > t_max are usable input that cannot hit.
    h = tri.intersect([[0.2, 0.2, 1.0], [0.2, 0.2, 1.0]], [[0, 0, 0], [0, 0, -1]], [0.0, 5.0], [9.0, 1.0])
    assert list(h.prim) == [-1, -1]
    empty = tri.intersect(np.zeros((0, 3)), np.zeros((0, 3)))
    assert empty.t.shape == (0,) and empty.normal.shape == (0, 3)


def test_bad_options(tri):
    o, d = [[0.2, 0.2, 1.0]], [[0, 0, -1]]
    for threads in (0, -1, 1.5, True, "2"):
        with pytest.raises(ValueError, match="threads must be a positive integer"):
            tri.intersect(o, d, threads=threads)
    with pytest.raises(ValueError, match="mode must be one of"):
        tri.intersect(o, d, mode="fast")
    with pytest.raises(ValueError, match="width must be a positive integer"):
        tri.camera_rays(width=0)
    with pytest.raises(ValueError, match="eye: expected three numbers"):
        tri.trace_image(eye=[1, 2])
    with pytest.raises(raypack.Error, match="up is parallel"):
        tri.camera_rays(eye=[0, 0, 5], target=[0, 0, 0], up=[0, 0, 1], width=4, height=4)
    with pytest.raises(raypack.Error, match="vfov"):
        tri.trace_image(vfov=180, width=4, height=4)
    with pytest.raises(raypack.Error, match="more than"):
        tri.camera_rays(width=100000, height=100000)


def test_bad_scene_files(tmp_path):
    with pytest.raises(raypack.Error, match="no-such-file.obj"):
        raypack.Scene.load(str(tmp_path / "no-such-file.obj"))
    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n")
    with pytest.raises(raypack.Error, match=r"bad\.obj:4: f: index 9 is out of range"):
        raypack.Scene.load(str(bad))
    toml = tmp_path / "bad.toml"
    toml.write_text("[camera]\neye = [0, 0, -5]\ntarget = [0, 0, 0]\nvfov = 'wide'\n")
    with pytest.raises(raypack.Error, match="bad.toml"):
        raypack.Scene.load(str(toml))
    with pytest.raises(raypack.Error, match="no-such-scene"):
        raypack.Scene.load("no-such-scene")


def test_bad_accel():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
    t = np.array([[0, 1, 2]])
    for accel in ("octree", "", None, 8):
        with pytest.raises(ValueError, match="accel must be"):
            raypack.Scene(v, t, accel=accel)
        with pytest.raises(ValueError, match="accel must be"):
            raypack.Scene.load("bunny", accel=accel)


def test_a_bad_raypack_isa_is_refused_at_import():
    env = {**os.environ, "RAYPACK_ISA": "avx9000"}
    out = subprocess.run([sys.executable, "-c", "import raypack"], env=env, capture_output=True, text=True, cwd=REPO)
    assert out.returncode != 0
    assert "RAYPACK_ISA" in out.stderr and "avx9000" in out.stderr
