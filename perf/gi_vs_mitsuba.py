#!/usr/bin/env python3
"""raypack's path tracer beside Mitsuba 3's on a list of scenes: render time, mean squared
error against a high-sample Mitsuba reference, and efficiency 1 / (time x MSE).

    python3 perf/gi_vs_mitsuba.py            # every scene: 256x192, 3 rounds, 2 threads
    python3 perf/gi_vs_mitsuba.py --quick    # small and fast: checks the script
    python3 perf/gi_vs_mitsuba.py --scene sponza_sky,spheres   # some scenes

The scenes (SCENES) are raypack scene files of scenes/gi, and Mitsuba's scene is
translated from the same file, so both render one description:
- `cornell_box`: the benchmark Cornell box of ../shared/scenes (OBJ with `o`/`usemtl`
  groups and an MTL) lit by its light;
- `sponza_sky`: Crytek Sponza, every surface grey Lambertian of reflectance 0.5, lit only
  by a uniform sky of radiance 1 (raypack's `background`, Mitsuba's `constant` emitter);
- `spheres`: the Cornell box with an ideal mirror sphere, a clear glass sphere and a
  glossy gold sphere (Mitsuba's `conductor` of material "none", `dielectric` and
  `roughconductor` of material "none" with GGX roughness).

Both use the camera of the scene file (vertical fov: Mitsuba's `fov_axis` y), box pixel
filter, and the same path tracer: next-event estimation with MIS,
no depth limit, Russian roulette from the fourth path vertex with probability
min(0.95, max channel of the throughput) (src/render/path.rs, `survives` in
src/render/gi.rs; Mitsuba's `rr_depth` counts the vertices from 1, so it is 4; its
roulette divides out the eta^2 of refraction, so the two agree inside glass too). Each
renderer draws its samples its own default way: raypack from Owen-scrambled Sobol points
(`--sampler sobol`), Mitsuba from independent ones (its `independent` sampler, as the
reference); both sample the sky directly, raypack by a cosine-weighted direction about
the normal, Mitsuba uniformly over the sphere.

The translation follows raypack's lobes (scenes/README.md, "Global illumination";
src/render/bsdf.rs), one lobe per material, with the weights scaled down together when
they sum to more than 1:
- Lambertian of reflectance `diffuse * color`: `twosided` `diffuse` (raypack shades both
  sides with the geometric normal; Mitsuba gets `face_normals`);
- ideal mirror of reflectance `reflection * color` (`glossiness` 0): `twosided`
  `conductor` of material "none" and that `specular_reflectance`;
- glossy reflection (`reflection` with `glossiness` g > 0), raypack's GGX perfect
  conductor of roughness `g / sqrt(1 + g^2)`: `twosided` `roughconductor` of material
  "none", `distribution` "ggx" and that `alpha`, which evaluates the same microfacet
  model (Smith's separable shadowing-masking);
- smooth dielectric (`refraction`, `ior`): `dielectric` of `int_ior` ior in air. Both
  reflect with the exact unpolarised Fresnel factor; Mitsuba scales transmitted radiance
  by eta^2, raypack does not, which is the same on closed objects (a path enters and
  leaves), so glass must be closed (spheres) and absorb nothing;
- emission (`emission`; an MTL's `Ke`, or a `Ka` above 1 as the Cornell light's `Ka 20
  20 20`): a one-sided `area` emitter along the winding normal.
MTL materials are Lambertian of albedo `Kd` (raypack's reading, src/scene/obj/mod.rs).
Faces are split into triangle fans as raypack splits them, written per material into
the cache folder as the OBJs Mitsuba loads. Anything else a scene file can say is
refused rather than approximated: raypack's specular lobe is a normalised Phong lobe,
which Mitsuba 3 has no plugin for, so it is left out, as are mixtures of lobes,
textures, `[[lights]]`, planes, boxes and mesh transforms.

Mitsuba runs in child processes of this script (under timeouts), `llvm_ad_rgb` when
its LLVM loads (DRJIT_LIBLLVM_PATH, by default the libLLVM.so.22 of the Rust toolchain),
else `scalar_rgb`. The references are cached in ~/.cache/raypack-perf/gi (or `--cache`);
each scene's `reference_spp` is 32 times its `spp`, so a reference's own error is 1/32
of a render's. Standard library only, apart from Mitsuba itself.
"""

import argparse
import array
import glob
import hashlib
import importlib.util
import json
import math
import os
import statistics
import sys
import tempfile
import time
import tomllib
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from report import (REPO, RunError, cache_folder, log, raypack_binary, run,  # noqa: E402
                    scenes_folder, split_list)

MITSUBA_VERSION = "3.9.1"
INSTALL = f"pip install mitsuba=={MITSUBA_VERSION}"
# raypack's Russian roulette starts at path vertex 3 (0 = the camera ray's hit); in
# Mitsuba's `path` the depth after vertex v is v + 1 and roulette runs from rr_depth on.
RR_DEPTH = 4
MAX_DEPTH = -1

# The scenes, in the order they run. `file` is the raypack scene file (relative to the
# repository); `spp` and `reference_spp` are per pixel, `quick_*` those of `--quick`.
# The spheres' caustics (light found through glass or a mirror by BSDF sampling alone)
# make a heavy-tailed estimate: at 16 spp a 32 x 32 block's mean is often several
# "standard errors" low in both renderers, so even `--quick` takes 64 there.
SCENES = [
    {"name": "cornell_box", "title": "Cornell box", "file": "scenes/gi/cornell_box.toml",
     "about": "the benchmark Cornell box lit by its own light, of radiance its MTL's `Ka`",
     "spp": 256, "reference_spp": 8192, "quick_spp": 16, "quick_reference_spp": 512},
    {"name": "sponza_sky", "title": "Sponza under a sky", "file": "scenes/gi/sponza_sky.toml",
     "about": "Crytek Sponza, every surface grey Lambertian of reflectance 0.5, lit only "
              "by a uniform sky of radiance 1",
     "spp": 64, "reference_spp": 2048, "quick_spp": 8, "quick_reference_spp": 256},
    {"name": "spheres", "title": "Cornell box with mirror, glass and glossy spheres",
     "file": "scenes/gi/spheres.toml",
     "about": "the Cornell box with an ideal mirror sphere, a clear glass sphere of "
              "index 1.5 and a glossy gold sphere (GGX, alpha 0.287)",
     "spp": 256, "reference_spp": 8192, "quick_spp": 64, "quick_reference_spp": 2048},
]
FULL = {"width": 256, "height": 192, "rounds": 3}
QUICK = {"width": 128, "height": 96, "rounds": 1}
# The images agree when every channel's mean lies within Z_CHANNEL standard errors of the
# reference's and every 32 x 32 block's within Z_BLOCK.
Z_CHANNEL, Z_BLOCK = 4, 5
# The scene file's keys this script translates; any other is refused.
TOP_KEYS = {"camera", "render", "materials", "meshes", "spheres"}
MATERIAL_DEFAULTS = {"color": [0.8, 0.8, 0.8], "diffuse": 1.0, "specular": 0.0,
                     "shininess": 20.0, "reflection": 0.0, "refraction": 0.0, "ior": 1.5,
                     "absorption": 0.0, "glossiness": 0.0, "emission": [0.0, 0.0, 0.0]}


class SceneError(Exception):
    """A scene file says something this script cannot give Mitsuba alike."""


def read_pfm(path):
    """(width, height, RGB floats top row first) of a colour PFM file."""
    data = Path(path).read_bytes()
    tokens, pos = [], 0
    while len(tokens) < 4:
        while data[pos:pos + 1].isspace():
            pos += 1
        start = pos
        while not data[pos:pos + 1].isspace():
            pos += 1
        tokens.append(data[start:pos].decode())
    pos += 1
    if tokens[0] != "PF":
        raise ValueError(f"{path}: not a colour PFM")
    w, h, scale = int(tokens[1]), int(tokens[2]), float(tokens[3])
    px = array.array("f")
    px.frombytes(data[pos:pos + w * h * 12])
    if (scale > 0) != (sys.byteorder == "big"):
        px.byteswap()
    rows = [px[(h - 1 - y) * w * 3:(h - y) * w * 3] for y in range(h)]
    out = array.array("f")
    for r in rows:
        out.extend(r)
    return w, h, out


def write_pfm(path, w, h, px):
    """Writes RGB floats (top row first) as a little-endian PFM, bottom row first."""
    body = array.array("f")
    for y in range(h - 1, -1, -1):
        body.extend(px[y * w * 3:(y + 1) * w * 3])
    if sys.byteorder == "big":
        body.byteswap()
    Path(path).write_bytes(f"PF\n{w} {h}\n-1.0\n".encode() + body.tobytes())


def mean_image(images):
    n = len(images)
    return array.array("f", (sum(v) / n for v in zip(*images)))


def mse(a, b):
    return sum((x - y) ** 2 for x, y in zip(a, b)) / len(a)


def channel_means(px):
    n = len(px) // 3
    return [sum(px[c::3]) / n for c in range(3)]


def deviation(img, ref, w, h, block=32):
    """How far `img` lies from `ref` in standard errors of the mean of their
    difference: per channel over the image, and the largest over blocks of block x block
    pixels and channels."""

    def z(diffs):
        n = len(diffs)
        m = sum(diffs) / n
        var = sum((d - m) ** 2 for d in diffs) / max(n - 1, 1)
        return m / math.sqrt(var / n) if var > 0 else 0.0

    diff = [a - b for a, b in zip(img, ref)]
    whole = [z(diff[c::3]) for c in range(3)]
    worst, blocks = 0.0, 0
    for by in range(0, h, block):
        for bx in range(0, w, block):
            blocks += 1
            for c in range(3):
                d = [diff[(y * w + x) * 3 + c]
                     for y in range(by, min(by + block, h)) for x in range(bx, min(bx + block, w))]
                worst = max(worst, abs(z(d)))
    return whole, worst, blocks


def mean_difference(img, ref):
    """(img's mean over all pixels and channels - ref's) / ref's, and its standard error.
    The channels of a pixel come from the same paths, so the error is taken over pixels
    (independent in both renderers) of their channels' mean."""
    n = len(img) // 3
    d = [(img[3 * i] + img[3 * i + 1] + img[3 * i + 2]
          - ref[3 * i] - ref[3 * i + 1] - ref[3 * i + 2]) / 3 for i in range(n)]
    base = sum(ref) / len(ref)
    if base <= 0:
        return 0.0, 0.0
    return statistics.fmean(d) / base, statistics.stdev(d) / math.sqrt(n) / base


def rooted(path, scenes_dir):
    """`path` (a mesh of a scene file) moved into `scenes_dir` when it lies in the
    shared scenes folder beside the repository and `--scenes` names another."""
    shared = (REPO.parent / "shared" / "scenes").resolve()
    path = path.resolve()
    if scenes_dir != shared and path.is_relative_to(shared):
        return scenes_dir / path.relative_to(shared)
    return path


def material(raw, where):
    """A raypack material of the scene file (or an MTL's) with its defaults, checked to
    be one Mitsuba can have alike: the fields `kind` ("diffuse", "mirror", "glossy",
    "glass" or "black"), `weight` (the lobe's, scaled down as raypack does), `ior`,
    `alpha` (the glossy lobe's GGX roughness), `emission`."""
    unknown = set(raw) - set(MATERIAL_DEFAULTS)
    if unknown:
        raise SceneError(f"{where}: {', '.join(sorted(unknown))}: not translated for Mitsuba")
    m = dict(MATERIAL_DEFAULTS, **raw)
    color = [float(c) for c in m["color"]]
    if m["specular"] > 0:
        raise SceneError(f"{where}: specular: raypack's normalised Phong lobe has no "
                         "Mitsuba 3 plugin")
    g = float(m["glossiness"])
    lobes = {"diffuse": [m["diffuse"] * c for c in color],
             "glossy" if g > 0 else "mirror": [m["reflection"] * c for c in color],
             "glass": [float(m["refraction"])] * 3}
    total = max(sum(w[c] for w in lobes.values()) for c in range(3))
    if total > 1:
        lobes = {k: [x / total for x in w] for k, w in lobes.items()}
    present = [k for k, w in lobes.items() if max(w) > 0]
    if len(present) > 1:
        raise SceneError(f"{where}: a mixture of lobes ({', '.join(present)}): only one "
                         "lobe per material is translated")
    if "glass" in present and m["absorption"] * max(1 - c for c in color) > 0:
        raise SceneError(f"{where}: absorption: Beer's law inside glass is not translated")
    kind = present[0] if present else "black"
    return {"kind": kind, "weight": lobes.get(kind, [0.0] * 3), "ior": float(m["ior"]),
            "alpha": g / math.sqrt(1 + g * g), "emission": [float(e) for e in m["emission"]]}


def mitsuba_bsdf(m):
    """Mitsuba's BSDF for a `material`."""
    rgb = {"type": "rgb", "value": m["weight"]}
    if m["kind"] == "glass":
        bsdf = {"type": "dielectric", "int_ior": m["ior"], "ext_ior": 1.0}
        if m["weight"] != [1.0] * 3:
            bsdf["specular_reflectance"] = bsdf["specular_transmittance"] = rgb
        return bsdf
    if m["kind"] == "mirror":
        inner = {"type": "conductor", "material": "none", "specular_reflectance": rgb}
    elif m["kind"] == "glossy":
        inner = {"type": "roughconductor", "material": "none", "distribution": "ggx",
                 "alpha": m["alpha"], "sample_visible": True, "specular_reflectance": rgb}
    else:
        inner = {"type": "diffuse", "reflectance": rgb}
    return {"type": "twosided", "bsdf": inner}


def mtl_materials(obj, text):
    """The OBJ's MTL materials as raypack reads them: albedo `Kd` (0.8 without it) and
    emission `Ke`, or a `Ka` above 1; the MTL files (for the cache key)."""
    files = [obj.parent / line.split(None, 1)[1].strip()
             for line in text.splitlines() if line.startswith("mtllib ")]
    raw, current = {}, None
    for mtl in files:
        for line in mtl.read_text().splitlines():
            f = line.split()
            if not f:
                continue
            if f[0] == "newmtl":
                current = raw.setdefault(f[1], {})
            elif f[0] in ("Kd", "Ka", "Ke") and current is not None:
                current[f[0]] = [float(x) for x in f[1:4]]
            elif f[0] == "map_Kd" and current is not None:
                current["texture"] = f[-1]
    out = {}
    for name, m in raw.items():
        ka = m.get("Ka")
        emission = m.get("Ke") or (ka if ka and max(ka) > 1 else [0.0, 0.0, 0.0])
        out[name] = {"color": m.get("Kd", MATERIAL_DEFAULTS["color"]), "emission": emission}
        if "texture" in m:
            out[name]["texture"] = m["texture"]
    return out, files


def split_mesh(obj, override, cache):
    """The mesh as triangle OBJs, one per material (fans, as raypack splits faces;
    everything in one when the scene file gives the mesh a `material`), written into
    the cache folder once. Returns the key of the mesh's files and [(material, raw
    material or None for the scene file's, path)]."""
    text = obj.read_text()
    mtls, mtl_files = mtl_materials(obj, text)
    key = hashlib.sha256(text.encode() + b"".join(m.read_bytes() for m in mtl_files))
    verts, groups, mat = [], {}, None
    for line in text.splitlines():
        f = line.split()
        if not f:
            continue
        if f[0] == "v":
            verts.append([float(x) for x in f[1:4]])
        elif f[0] == "usemtl":
            mat = f[1]
        elif f[0] == "f":
            idx = [int(c.split("/")[0]) for c in f[1:]]
            idx = [i - 1 if i > 0 else len(verts) + i for i in idx]
            tris = groups.setdefault(override or mat, [])
            tris += [(idx[0], idx[k], idx[k + 1]) for k in range(1, len(idx) - 1)]
    folder = cache / "gi" / f"{obj.stem}-{key.hexdigest()[:12]}"
    folder.mkdir(parents=True, exist_ok=True)
    parts = []
    for i, (mat, tris) in enumerate(groups.items()):
        name = f"all_{mat}.obj" if override else f"{i:02d}_{mat or 'default'}.obj"
        path = folder / name
        if not path.is_file():
            used = sorted({v for t in tris for v in t})
            remap = {v: k + 1 for k, v in enumerate(used)}
            lines = [f"v {verts[v][0]!r} {verts[v][1]!r} {verts[v][2]!r}" for v in used]
            lines += [f"f {remap[a]} {remap[b]} {remap[c]}" for a, b, c in tris]
            tmp = path.with_name(f"tmp-{os.getpid()}-{name}")
            tmp.write_text("\n".join(lines) + "\n")
            tmp.replace(path)
        if override:
            parts.append((mat, None, path))
        else:
            parts.append((mat or "default", mtls.get(mat, {}) if mat else {}, path))
    return key, parts


def load_scene(entry, scenes_dir, cache, tmp):
    """A scene of SCENES: raypack's scene file (a copy in `tmp` when its meshes move to
    `--scenes`) and Mitsuba's shapes, camera and cache key, translated from it."""
    path = REPO / entry["file"]
    text = path.read_text()
    doc = tomllib.loads(text)
    unknown = set(doc) - TOP_KEYS
    if unknown:
        raise SceneError(f"{path}: {', '.join(sorted(unknown))}: not translated for Mitsuba")
    cam = doc["camera"]
    camera = {"eye": [float(x) for x in cam["eye"]],
              "target": [float(x) for x in cam["target"]],
              "up": [float(x) for x in cam.get("up", [0.0, 1.0, 0.0])],
              "vfov_deg": float(cam.get("vfov", 60.0))}
    table = doc.get("materials", {})

    def named(name, where):
        if name is None:
            return material({}, where)
        if name not in table:
            raise SceneError(f"{path}: {where}: no material {name!r}")
        return material(table[name], f"{path}: materials.{name}")

    meshes = doc.get("meshes", [])
    objs = [rooted(path.parent / mesh["file"], scenes_dir) for mesh in meshes]
    raypack_file = path
    if any(obj != (path.parent / mesh["file"]).resolve() for obj, mesh in zip(objs, meshes)):
        # Every mesh by its absolute path, so the copy may live anywhere.
        for obj, mesh in zip(objs, meshes):
            text = text.replace(json.dumps(mesh["file"]), json.dumps(str(obj)))
        raypack_file = Path(tmp) / f"{entry['name']}.toml"
        raypack_file.write_text(text)
    shapes, used, mesh_keys, overrides = [], {}, [], []
    for i, (mesh, obj) in enumerate(zip(meshes, objs)):
        extra = set(mesh) - {"file", "material"}
        if extra:
            raise SceneError(f"{path}: meshes[{i}]: {', '.join(sorted(extra))}: mesh "
                             "transforms are not translated")
        mesh_key, parts = split_mesh(obj, mesh.get("material"), cache)
        mesh_keys.append(mesh_key)
        overrides.append(mesh.get("material"))
        for name, raw, file in parts:
            m = named(name, f"meshes[{i}]") if raw is None else material(
                raw, f"{obj}: material {name}")
            if raw is None:
                used[name] = table.get(name, {})
            shape = {"type": "obj", "filename": str(file), "face_normals": True,
                     "bsdf": mitsuba_bsdf(m)}
            if max(m["emission"]) > 0:
                shape["emitter"] = {"type": "area",
                                    "radiance": {"type": "rgb", "value": m["emission"]}}
            shapes.append(shape)
    spheres = []
    for i, s in enumerate(doc.get("spheres", [])):
        m = named(s.get("material"), f"spheres[{i}]")
        if s.get("material"):
            used[s["material"]] = table[s["material"]]
        shape = {"type": "sphere", "center": [float(x) for x in s["center"]],
                 "radius": float(s["radius"]), "bsdf": mitsuba_bsdf(m)}
        if max(m["emission"]) > 0:
            shape["emitter"] = {"type": "area",
                                "radiance": {"type": "rgb", "value": m["emission"]}}
        shapes.append(shape)
        spheres.append([shape["center"], shape["radius"], s.get("material")])
    if not shapes:
        raise SceneError(f"{path}: no meshes or spheres")
    sky = [float(x) for x in doc.get("render", {}).get("background", [0.0, 0.0, 0.0])]
    # The key is the meshes' (OBJ and MTL text), then whatever else the scene adds, so a
    # mesh lit by its own MTL keeps the key (and cached reference) it always had.
    key = (mesh_keys[0].copy() if len(mesh_keys) == 1
           else hashlib.sha256(b"".join(k.digest() for k in mesh_keys)))
    extras = {k: v for k, v in (("materials", used), ("spheres", spheres),
                                ("mesh_materials", overrides if any(overrides) else None),
                                ("sky", sky if max(sky) > 0 else None)) if v}
    if extras:
        key.update(json.dumps(extras, sort_keys=True).encode())
    return {"file": raypack_file, "camera": camera, "shapes": shapes,
            "sky": sky if max(sky) > 0 else None, "key": key.hexdigest()}


def mitsuba_child(spec_path):
    """Runs in the child process: renders as the spec says, writes the result JSON."""
    spec = json.loads(Path(spec_path).read_text())
    import drjit as dr
    import mitsuba as mi

    mi.set_variant(spec["variant"])
    dr.set_thread_count(spec["threads"])
    result = {"version": mi.__version__, "variant": spec["variant"]}
    if spec.get("probe"):
        x = mi.Float(1.0) + 1.0
        dr.eval(x)
        Path(spec["result"]).write_text(json.dumps(result))
        return
    cam = spec["scene"]["camera"]
    try:
        to_world = mi.ScalarTransform4f().look_at(origin=cam["eye"], target=cam["target"],
                                                  up=cam["up"])
    except TypeError:
        to_world = mi.ScalarTransform4f.look_at(origin=cam["eye"], target=cam["target"],
                                                up=cam["up"])
    scene = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": MAX_DEPTH, "rr_depth": RR_DEPTH},
        "sensor": {
            "type": "perspective", "fov_axis": "y", "fov": cam["vfov_deg"],
            "to_world": to_world,
            "sampler": {"type": "independent", "sample_count": spec["spp"]},
            "film": {"type": "hdrfilm", "width": spec["width"], "height": spec["height"],
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
        },
    }
    for i, shape in enumerate(spec["scene"]["shapes"]):
        scene[f"shape_{i}"] = shape
    if spec["scene"]["sky"]:
        scene["sky"] = {"type": "constant",
                        "radiance": {"type": "rgb", "value": spec["scene"]["sky"]}}
    sc = mi.load_dict(scene)

    def render(seed):
        start = time.perf_counter()
        img = mi.render(sc, spp=spec["spp"], seed=seed)
        dr.eval(img)
        dr.sync_thread()
        return img, time.perf_counter() - start

    if spec.get("warmup"):
        _, result["warmup_seconds"] = render(spec["seeds"][0] + 7919)
    total, times = None, []
    for seed in spec["seeds"]:
        img, t = render(seed)
        times.append(t)
        total = img if total is None else total + img
    mi.Bitmap(total / len(spec["seeds"])).write(spec["out"])
    result["seconds"] = times
    Path(spec["result"]).write_text(json.dumps(result))


def llvm_library():
    """DRJIT_LIBLLVM_PATH, else the libLLVM.so.22 of an installed Rust toolchain."""
    if os.environ.get("DRJIT_LIBLLVM_PATH"):
        return os.environ["DRJIT_LIBLLVM_PATH"]
    found = sorted(glob.glob(str(Path.home() / ".rustup/toolchains/*/lib/libLLVM.so.22*")))
    stable = [f for f in found if "stable" in f]
    return (stable or found or [None])[0]


class Mitsuba:
    """Mitsuba in child processes of this script, under timeouts."""

    def __init__(self, threads, variant=None):
        self.threads = threads
        self.env = dict(os.environ)
        llvm = llvm_library()
        if llvm:
            self.env["DRJIT_LIBLLVM_PATH"] = llvm
        self.variant, self.version = None, None
        for v in [variant] if variant else ["llvm_ad_rgb", "scalar_rgb"]:
            try:
                r = self.child({"probe": True, "variant": v}, 300)
                self.variant, self.version = v, r["version"]
                break
            except RunError as e:
                log(f"Mitsuba {v}: {e}")
        if not self.variant:
            raise RunError("no Mitsuba variant runs here")

    def child(self, spec, timeout):
        with tempfile.TemporaryDirectory() as tmp:
            spec = dict(spec, threads=self.threads, result=str(Path(tmp) / "result.json"))
            spec.setdefault("variant", self.variant)
            path = Path(tmp) / "spec.json"
            path.write_text(json.dumps(spec))
            run([sys.executable, __file__, "--child", path], timeout, env=self.env)
            return json.loads(Path(spec["result"]).read_text())

    def render(self, scene, cfg, spp, seeds, out, warmup, timeout):
        mitsuba_scene = {k: scene[k] for k in ("camera", "shapes", "sky")}
        return self.child({"scene": mitsuba_scene, "width": cfg["width"],
                           "height": cfg["height"], "spp": spp, "seeds": seeds,
                           "out": str(out), "warmup": warmup}, timeout)


def reference(mitsuba, scene, cfg, spp, reference_spp, cache, timeout):
    """A Mitsuba image of `reference_spp` samples per pixel, in passes of `spp`, cached
    by everything that goes into it."""
    passes = max(1, reference_spp // spp)
    key = hashlib.sha256(json.dumps([scene["key"], scene["camera"], cfg["width"],
                                     cfg["height"], spp, passes, MAX_DEPTH, RR_DEPTH,
                                     mitsuba.version]).encode()).hexdigest()[:16]
    path = cache / "gi" / f"reference-{cfg['width']}x{cfg['height']}-{spp * passes}spp-{key}.pfm"
    if not path.is_file():
        log(f"Mitsuba reference: {passes} passes of {spp} spp into {path}")
        tmp = path.with_name(f"tmp-{os.getpid()}-{path.name}")
        mitsuba.render(scene, cfg, spp, [1000 + i for i in range(passes)], tmp, False, timeout)
        tmp.replace(path)
    return read_pfm(path)[2], spp * passes


def measure(entry, scene, mitsuba, raypack, cfg, args, cache, tmp):
    """One scene's rounds, the two renderers taking turns; its entry of the JSON."""
    w, h, rounds = cfg["width"], cfg["height"], cfg["rounds"]
    spp = entry["quick_spp"] if args.quick else entry["spp"]
    ref_spp = entry["quick_reference_spp"] if args.quick else entry["reference_spp"]
    ref, ref_spp = reference(mitsuba, scene, cfg, spp, ref_spp, cache, 4 * args.timeout)
    shown = scene["file"].relative_to(REPO) if scene["file"].is_relative_to(REPO) else scene["file"]
    rp_cmd = (f"raypack render {shown} --integrator path --spp {spp} --width {w} "
              f"--height {h} --threads {args.threads} -o OUT.pfm")
    runs = {"raypack": [], "mitsuba": []}
    for rnd in range(rounds):
        order = ["raypack", "mitsuba"] if rnd % 2 == 0 else ["mitsuba", "raypack"]
        for who in order:
            out = Path(tmp) / f"{entry['name']}-{who}-{rnd}.pfm"
            log(f"GI {entry['name']} round {rnd + 1}/{rounds}: {who}")
            if who == "raypack":
                j = Path(tmp) / "render.json"
                run([raypack, "render", scene["file"], "--integrator", "path", "--spp", spp,
                     "--width", w, "--height", h, "--threads", args.threads,
                     "--seed", rnd + 1, "-o", out, "--json", j], args.timeout)
                seconds = json.loads(j.read_text())["render_seconds"]
            else:
                r = mitsuba.render(scene, cfg, spp, [rnd + 1], out, True, args.timeout)
                seconds = r["seconds"][0]
            iw, ih, px = read_pfm(out)
            if (iw, ih) != (w, h):
                raise RunError(f"{who}: image is {iw}x{ih}, not {w}x{h}")
            runs[who].append({"seconds": seconds, "image": px, "mse": mse(px, ref)})
    result = {"scene": entry["name"], "title": entry["title"], "about": entry["about"],
              "file": entry["file"], "width": w, "height": h, "spp": spp, "reference_spp": ref_spp, "raypack_command": rp_cmd,
              "reference_means": channel_means(ref)}
    notes, agree = [], True
    for who, label in (("raypack", "raypack"), ("mitsuba", f"Mitsuba {mitsuba.variant}")):
        rs = runs[who]
        seconds = statistics.median(r["seconds"] for r in rs)
        err = statistics.median(r["mse"] for r in rs)
        img = mean_image([r["image"] for r in rs]) if len(rs) > 1 else rs[0]["image"]
        whole, worst, blocks = deviation(img, ref, w, h)
        rel, rel_se = mean_difference(img, ref)
        result[who] = {"label": label, "seconds": seconds, "mse": err,
                       "efficiency": 1.0 / (seconds * err), "means": channel_means(img),
                       "mean_difference": rel, "mean_difference_se": rel_se,
                       "seconds_all": [r["seconds"] for r in rs],
                       "mse_all": [r["mse"] for r in rs],
                       "z_channels": whole, "z_worst_block": worst, "blocks": blocks}
        agree = agree and max(abs(z) for z in whole) < Z_CHANNEL and worst < Z_BLOCK
        notes.append(f"{label}: channel means {', '.join(f'{z:+.1f}' for z in whole)} "
                     f"standard errors from the reference's, largest over {blocks} blocks "
                     f"of 32x32 pixels {worst:.1f}")
    a, b = result["raypack"], result["mitsuba"]
    result["ratios"] = {"time": a["seconds"] / b["seconds"], "mse": a["mse"] / b["mse"],
                        "efficiency": a["efficiency"] / b["efficiency"]}
    verdict = ("The images agree within noise" if agree else
               "**The images do not agree within noise** (a limit of "
               f"{Z_CHANNEL} standard errors per channel, {Z_BLOCK} per block, is passed)")
    result["agree"] = agree
    result["agreement"] = (f"{verdict} (mean of the rounds' images against the reference): "
                           + "; ".join(notes) + ".")
    return result


def print_scene(r, threads, variant):
    print(f"{r['title']} ({r['scene']}) {r['width']}x{r['height']}, {r['spp']} spp, "
          f"{threads} threads; reference {r['reference_spp']} spp ({variant})")
    for who in ("raypack", "mitsuba"):
        g = r[who]
        print(f"  {g['label']:<22} time {g['seconds']:8.3f} s  MSE {g['mse']:.4e}  "
              f"efficiency {g['efficiency']:.4g}  mean {100 * g['mean_difference']:+.2f}% "
              f"± {100 * g['mean_difference_se']:.2f}% of the reference's")
    q = r["ratios"]
    print(f"  raypack / Mitsuba: time {q['time']:.3f}, MSE {q['mse']:.3f}, "
          f"efficiency {q['efficiency']:.3f}")
    print("  " + r["agreement"])


def geomean(xs):
    return math.exp(statistics.fmean(math.log(x) for x in xs))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--child", help=argparse.SUPPRESS)
    ap.add_argument("--quick", action="store_true", help="small image, few samples, one round")
    ap.add_argument("--raypack", help="the raypack binary (default: cargo build --release)")
    ap.add_argument("--scenes", help="the benchmark scenes (default ../shared/scenes): where "
                    "the scene files' meshes of ../shared/scenes are read from")
    ap.add_argument("--scene", action="append", default=[],
                    help="only this scene (repeatable, or a comma-separated list): "
                    + ", ".join(s["name"] for s in SCENES))
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--variant", help="Mitsuba variant (default llvm_ad_rgb, else scalar_rgb)")
    ap.add_argument("--cache", help="references and meshes (default ~/.cache/raypack-perf)")
    ap.add_argument("--timeout", type=int, default=1800, help="seconds per render process")
    ap.add_argument("--json", help="also write the results as JSON here")
    args = ap.parse_args()
    if args.child:
        return mitsuba_child(args.child)

    cfg = QUICK if args.quick else FULL
    names = split_list(args.scene)
    known = [s["name"] for s in SCENES]
    for n in names:
        if n not in known:
            ap.error(f"--scene {n}: not one of {', '.join(known)}")
    entries = [s for s in SCENES if not names or s["name"] in names]

    def finish(result, code=0):
        if args.json:
            Path(args.json).write_text(json.dumps(result, indent=1))
        return code

    if importlib.util.find_spec("mitsuba") is None:
        print(f"Mitsuba 3 is not installed: {INSTALL}", file=sys.stderr)
        return finish({"missing": "Mitsuba 3 is not installed", "install": INSTALL}, 3)
    scenes_dir = scenes_folder(args.scenes)
    cache = cache_folder(args.cache)
    raypack = raypack_binary(args.raypack)
    try:
        mitsuba = Mitsuba(args.threads, args.variant)
    except RunError as e:
        return finish({"error": f"Mitsuba does not run: {e}"}, 1)
    result = {
        "conditions": {
            "width": cfg["width"], "height": cfg["height"], "threads": args.threads,
            "mitsuba_version": mitsuba.version, "variant": mitsuba.variant,
            "max_depth": "unlimited" if MAX_DEPTH < 0 else MAX_DEPTH, "rr_depth": RR_DEPTH,
            "rr_note": "from the fourth path vertex", "rounds": cfg["rounds"],
            "agreement_limits": {"channel": Z_CHANNEL, "block": Z_BLOCK},
        },
        "scenes": [],
    }
    code = 0
    with tempfile.TemporaryDirectory() as tmp:
        for entry in entries:
            try:
                scene = load_scene(entry, scenes_dir, cache, tmp)
                r = measure(entry, scene, mitsuba, raypack, cfg, args, cache, tmp)
            except (RunError, SceneError, OSError) as e:
                log(f"GI {entry['name']}: {e}")
                result["scenes"].append({"scene": entry["name"], "title": entry["title"],
                                         "about": entry["about"], "file": entry["file"],
                                         "error": str(e)})
                code = 1
                continue
            result["scenes"].append(r)
            print_scene(r, args.threads, mitsuba.variant)
            print()
    done = [r for r in result["scenes"] if "ratios" in r]
    if done:
        result["ratios"] = {k: geomean([r["ratios"][k] for r in done])
                            for k in ("time", "mse", "efficiency")}
        print(f"raypack / Mitsuba, {cfg['width']}x{cfg['height']}, {args.threads} threads:")
        print(f"  {'scene':<12} {'spp':>5} {'time':>7} {'MSE':>7} {'efficiency':>10}  agree")
        for r in done:
            q = r["ratios"]
            print(f"  {r['scene']:<12} {r['spp']:>5} {q['time']:>7.3f} {q['mse']:>7.3f} "
                  f"{q['efficiency']:>10.3f}  {'yes' if r['agree'] else 'NO'}")
        q = result["ratios"]
        print(f"  {'geomean':<12} {'':>5} {q['time']:>7.3f} {q['mse']:>7.3f} "
              f"{q['efficiency']:>10.3f}")
    for r in result["scenes"]:
        if "error" in r:
            print(f"{r['scene']}: not measured: {r['error']}")
    return finish(result, code)


if __name__ == "__main__":
    try:
        sys.exit(main())
    except RunError as e:
        sys.exit(f"gi_vs_mitsuba.py: {e}")
