"""`raypack.render` against `raypack render` on the same scene and options: the same
image bit for bit (PFM holds the float32 radiance), in every integrator and mode."""

from __future__ import annotations

import numpy as np
import pytest

import raypack
from conftest import REPO, bits, random_mesh, run_raypack, write_obj

KNOT = str(REPO / "scenes" / "knot.obj")


def read_pfm(path) -> np.ndarray:
    """A colour PFM as `(height, width, 3)`, row 0 at the top (PFM stores bottom up)."""
    data = open(path, "rb").read()
    header, rest = data.split(b"\n", 3)[:3], data.split(b"\n", 3)[3]
    assert header[0] == b"PF"
    w, h = map(int, header[1].split())
    scale = float(header[2])
    dtype = "<f4" if scale < 0 else ">f4"
    return np.frombuffer(rest, dtype=dtype, count=w * h * 3).reshape(h, w, 3)[::-1]


def cli_image(tmp_path, scene, *args) -> np.ndarray:
    out = tmp_path / "cli.pfm"
    run_raypack("render", scene, "-o", out, *map(str, args))
    return read_pfm(out)


@pytest.mark.parametrize(
    "scene, kwargs, flags",
    [
        (KNOT, dict(width=64, height=48, spp=4), ["--width", 64, "--height", 48, "--spp", 4]),
        (str(REPO / "scenes" / "part3.toml"), dict(width=80, height=60), ["--width", 80, "--height", 60]),
        (KNOT, dict(width=48, height=32, spp=2, integrator="path", seed=7),
         ["--width", 48, "--height", 32, "--spp", 2, "--integrator", "path", "--seed", 7]),
        (KNOT, dict(width=48, height=32, spp=2, integrator="path", sampler="independent"),
         ["--width", 48, "--height", 32, "--spp", 2, "--integrator", "path", "--sampler", "independent"]),
        (KNOT, dict(width=32, height=32, spp=1, integrator="photon", photons=5000, sky=0.5),
         ["--width", 32, "--height", 32, "--spp", 1, "--integrator", "photon", "--photons", 5000, "--sky", 0.5]),
        (KNOT, dict(width=40, height=24, eye=[3, 2, 6], target=[0, 0, 0], up=[0, 1, 0], vfov=35),
         ["--width", 40, "--height", 24, "--eye", "3,2,6", "--target", "0,0,0", "--up", "0,1,0", "--vfov", 35]),
    ],
)
def test_render_is_the_command_lines_image(tmp_path, scene, kwargs, flags):
    got = raypack.render(raypack.Scene.load(scene), **kwargs)
    want = cli_image(tmp_path, scene, *flags)
    assert got.shape == want.shape and got.dtype == np.float32
    assert np.array_equal(bits(got), bits(want))
    assert got.max() > 0.05, "the image is black"


def test_a_mesh_from_arrays_renders_as_its_obj_file(tmp_path):
    v, t = random_mesh(np.random.default_rng(3), 300)
    obj = tmp_path / "soup.obj"
    write_obj(obj, v, t)
    for integrator, flags in (("whitted", []), ("path", ["--spp", 2])):
        kwargs = dict(width=32, height=32, integrator=integrator, spp=2 if flags else None)
        got = raypack.render(raypack.Scene(v, t), **kwargs)
        want = cli_image(tmp_path, str(obj), "--width", 32, "--height", 32, "--integrator", integrator, *flags)
        assert np.array_equal(bits(got), bits(want)), integrator


def test_every_mode_and_thread_count_renders_the_same_image():
    scene = raypack.Scene.load(KNOT)
    for integrator in ("whitted", "path"):
        want = raypack.render(scene, 32, 24, 1, integrator, mode="scalar", threads=1)
        for mode in ("packet", "packet4", "stream", "tile64"):
            got = raypack.render(scene, 32, 24, 1, integrator, mode=mode)
            assert np.array_equal(bits(got), bits(want)), (integrator, mode)


def test_a_bvh8_scene_renders_the_kdtree_image():
    kd, bvh = raypack.Scene.load(KNOT), raypack.Scene.load(KNOT, accel="bvh8")
    for integrator in ("whitted", "path"):
        want = raypack.render(kd, 24, 16, 1, integrator)
        got = raypack.render(bvh, 24, 16, 1, integrator)
        assert np.array_equal(bits(got), bits(want)), integrator


def test_bad_render_options():
    scene = raypack.Scene.load(KNOT)
    with pytest.raises(raypack.Error, match="spp 3: the Whitted tracer takes a square"):
        raypack.render(scene, 8, 8, spp=3)
    with pytest.raises(raypack.Error, match="spp 70000: the path and photon integrators take 1 to 65536"):
        raypack.render(scene, 8, 8, spp=70000, integrator="path")
    with pytest.raises(ValueError, match="spp must be a positive integer"):
        raypack.render(scene, 8, 8, spp=0, integrator="path")
    with pytest.raises(ValueError, match="integrator must be one of"):
        raypack.render(scene, 8, 8, integrator="radiosity")
    with pytest.raises(ValueError, match="sampler must be one of sobol, independent"):
        raypack.render(scene, 8, 8, integrator="path", sampler="halton")
    with pytest.raises(ValueError, match="sampler applies to integrator='path' and 'photon'"):
        raypack.render(scene, 8, 8, sampler="independent")
    with pytest.raises(ValueError, match="max_bounces applies to integrator='path'"):
        raypack.render(scene, 8, 8, max_bounces=3)
    with pytest.raises(raypack.Error, match="an image has 1 to"):
        raypack.render(scene, 100000, 100000)
    with pytest.raises(raypack.Error, match="sky .*finite and >= 0"):
        raypack.render(scene, 8, 8, integrator="path", sky=[1, -1, 1])
    with pytest.raises(raypack.Error, match="up is parallel"):
        raypack.render(scene, 8, 8, eye=[0, 5, 0], target=[0, 0, 0], up=[0, 1, 0])
    with pytest.raises(raypack.Error, match="spd:balls:1: render takes a scene file"):
        raypack.render(raypack.Scene.load("spd:balls:1"), 8, 8)
    with pytest.raises(ValueError, match="scene: expected a raypack.Scene"):
        raypack.render("knot.obj", 8, 8)
