#!/usr/bin/env python3
"""raypack's path tracer beside Mitsuba 3's on the benchmark Cornell box: render time,
mean squared error against a high-sample Mitsuba reference, and efficiency
1 / (time x MSE).

    python3 perf/gi_vs_mitsuba.py            # 256x192, 256 spp, 2 threads, 3 rounds
    python3 perf/gi_vs_mitsuba.py --quick    # small and fast: checks the script

Both render the scene of ../shared/scenes/cornell_box (OBJ with `o`/`usemtl` groups and
an MTL) with the camera of cameras.toml (vertical fov), box pixel filter, independent
samples, and the same path tracer: next-event estimation with MIS, no depth limit,
Russian roulette from the fourth path vertex with probability min(0.95, max channel of
the throughput) (src/render/path.rs, `survives` in src/render/gi.rs; Mitsuba's
`rr_depth` counts the vertices from 1, so it is 4). Materials follow raypack's reading
of the MTL (src/scene/obj/mod.rs): `Kd` is the Lambertian reflectance (raypack shades
both sides: `twosided` in Mitsuba) and the emission is `Ke`, or without it a `Ka` with a
component above 1 (the light's `Ka 20 20 20`), one-sided along the winding normal.

Mitsuba runs in a child process of this script (under a timeout), `llvm_ad_rgb` when
its LLVM loads (DRJIT_LIBLLVM_PATH, by default the libLLVM.so.22 of the Rust toolchain),
else `scalar_rgb`. The reference is cached in ~/.cache/raypack-perf/gi (or `--cache`).
Standard library only, apart from Mitsuba itself.
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
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from report import RunError, cache_folder, log, raypack_binary, run, scenes_folder  # noqa: E402

MITSUBA_VERSION = "3.9.1"
INSTALL = f"pip install mitsuba=={MITSUBA_VERSION}"
# raypack's Russian roulette starts at path vertex 3 (0 = the camera ray's hit); in
# Mitsuba's `path` the depth after vertex v is v + 1 and roulette runs from rr_depth on.
RR_DEPTH = 4
MAX_DEPTH = -1

FULL = {"width": 256, "height": 192, "spp": 256, "reference_spp": 8192, "rounds": 3}
QUICK = {"width": 128, "height": 96, "spp": 16, "reference_spp": 512, "rounds": 1}


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


def cornell_scene(scenes_dir, name, cache):
    """The scene as Mitsuba gets it: one triangle OBJ per material (fans, as raypack
    splits faces) written into the cache, with Kd and emission; and the camera."""
    cams = tomllib.loads((scenes_dir / "cameras.toml").read_text())
    cam = cams[name]
    obj = scenes_dir / cam["obj"]
    text = obj.read_text()
    mtl_files = [obj.parent / line.split(None, 1)[1].strip()
                 for line in text.splitlines() if line.startswith("mtllib ")]
    materials, current = {}, None
    for mtl in mtl_files:
        for line in mtl.read_text().splitlines():
            f = line.split()
            if not f:
                continue
            if f[0] == "newmtl":
                current = materials.setdefault(f[1], {})
            elif f[0] in ("Kd", "Ka", "Ke") and current is not None:
                current[f[0]] = [float(x) for x in f[1:4]]
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
            tris = groups.setdefault(mat, [])
            tris += [(idx[0], idx[k], idx[k + 1]) for k in range(1, len(idx) - 1)]
    key = hashlib.sha256(text.encode() + b"".join(m.read_bytes() for m in mtl_files))
    folder = cache / "gi" / f"{name}-{key.hexdigest()[:12]}"
    folder.mkdir(parents=True, exist_ok=True)
    shapes = []
    for i, (mat, tris) in enumerate(groups.items()):
        m = materials.get(mat, {}) if mat else {}
        kd = m.get("Kd", [0.8, 0.8, 0.8])
        ka = m.get("Ka")
        emission = m.get("Ke") or (ka if ka and max(ka) > 1 else [0.0, 0.0, 0.0])
        used = sorted({v for t in tris for v in t})
        remap = {v: k + 1 for k, v in enumerate(used)}
        path = folder / f"{i:02d}_{mat or 'default'}.obj"
        lines = [f"v {verts[v][0]!r} {verts[v][1]!r} {verts[v][2]!r}" for v in used]
        lines += [f"f {remap[a]} {remap[b]} {remap[c]}" for a, b, c in tris]
        path.write_text("\n".join(lines) + "\n")
        shapes.append({"file": str(path), "kd": kd, "emission": emission,
                       "material": mat or "default", "triangles": len(tris)})
    camera = {k: cam[k] for k in ("eye", "target", "up", "vfov_deg")}
    return {"shapes": shapes, "camera": camera, "key": key.hexdigest()}


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
    for i, s in enumerate(spec["scene"]["shapes"]):
        shape = {"type": "obj", "filename": s["file"], "face_normals": True,
                 "bsdf": {"type": "twosided", "bsdf": {
                     "type": "diffuse", "reflectance": {"type": "rgb", "value": s["kd"]}}}}
        if max(s["emission"]) > 0:
            shape["emitter"] = {"type": "area",
                                "radiance": {"type": "rgb", "value": s["emission"]}}
        scene[f"shape_{i}"] = shape
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
        return self.child({"scene": scene, "width": cfg["width"], "height": cfg["height"],
                           "spp": spp, "seeds": seeds, "out": str(out), "warmup": warmup},
                          timeout)


def reference(mitsuba, scene, cfg, cache, timeout):
    """A Mitsuba image of cfg["reference_spp"] samples per pixel, cached by everything
    that goes into it."""
    spp = cfg["spp"]
    passes = max(1, cfg["reference_spp"] // spp)
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


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--child", help=argparse.SUPPRESS)
    ap.add_argument("--quick", action="store_true", help="small image, few samples, one round")
    ap.add_argument("--raypack", help="the raypack binary (default: cargo build --release)")
    ap.add_argument("--scenes", help="the benchmark scenes (default ../shared/scenes)")
    ap.add_argument("--scene", default="cornell_box", help="a scene of cameras.toml")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--variant", help="Mitsuba variant (default llvm_ad_rgb, else scalar_rgb)")
    ap.add_argument("--cache", help="reference and meshes (default ~/.cache/raypack-perf)")
    ap.add_argument("--timeout", type=int, default=1800, help="seconds per render process")
    ap.add_argument("--json", help="also write the results as JSON here")
    args = ap.parse_args()
    if args.child:
        return mitsuba_child(args.child)

    cfg = QUICK if args.quick else FULL

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
    scene = cornell_scene(scenes_dir, args.scene, cache)
    try:
        mitsuba = Mitsuba(args.threads, args.variant)
    except RunError as e:
        return finish({"error": f"Mitsuba does not run: {e}"}, 1)
    ref, ref_spp = reference(mitsuba, scene, cfg, cache, 4 * args.timeout)
    w, h, spp = cfg["width"], cfg["height"], cfg["spp"]
    rp_cmd = (f"raypack render {args.scene} --integrator path --spp {spp} --width {w} "
              f"--height {h} --threads {args.threads} -o OUT.pfm")
    runs = {"raypack": [], "mitsuba": []}
    with tempfile.TemporaryDirectory() as tmp:
        for rnd in range(cfg["rounds"]):
            order = ["raypack", "mitsuba"] if rnd % 2 == 0 else ["mitsuba", "raypack"]
            for who in order:
                out = Path(tmp) / f"{who}-{rnd}.pfm"
                log(f"GI round {rnd + 1}/{cfg['rounds']}: {who}")
                if who == "raypack":
                    j = Path(tmp) / "render.json"
                    run([raypack, "render", args.scene, "--integrator", "path", "--spp", spp,
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
    result = {
        "conditions": {
            "scene": args.scene, "width": w, "height": h, "spp": spp,
            "threads": args.threads, "raypack_command": rp_cmd,
            "mitsuba_version": mitsuba.version, "variant": mitsuba.variant,
            "max_depth": "unlimited" if MAX_DEPTH < 0 else MAX_DEPTH, "rr_depth": RR_DEPTH,
            "rr_note": "from the fourth path vertex", "rounds": cfg["rounds"],
            "reference_spp": ref_spp,
        },
        "reference_means": channel_means(ref),
    }
    notes = []
    for who, label in (("raypack", "raypack"), ("mitsuba", f"Mitsuba {mitsuba.variant}")):
        rs = runs[who]
        seconds = statistics.median(r["seconds"] for r in rs)
        err = statistics.median(r["mse"] for r in rs)
        img = mean_image([r["image"] for r in rs]) if len(rs) > 1 else rs[0]["image"]
        whole, worst, blocks = deviation(img, ref, w, h)
        result[who] = {"label": label, "seconds": seconds, "mse": err,
                       "efficiency": 1.0 / (seconds * err), "means": channel_means(img),
                       "seconds_all": [r["seconds"] for r in rs],
                       "mse_all": [r["mse"] for r in rs],
                       "z_channels": whole, "z_worst_block": worst, "blocks": blocks}
        notes.append((label, whole, worst, blocks))
    a, b = result["raypack"], result["mitsuba"]
    result["ratios"] = {"time": a["seconds"] / b["seconds"], "mse": a["mse"] / b["mse"],
                        "efficiency": a["efficiency"] / b["efficiency"]}
    agree = all(max(abs(z) for z in whole) < 4 and worst < 5 for _, whole, worst, _ in notes)
    parts = [f"{label}: channel means {', '.join(f'{z:+.1f}' for z in whole)} standard errors "
             f"from the reference's, largest over {blocks} blocks of 32x32 pixels "
             f"{worst:.1f}" for label, whole, worst, blocks in notes]
    verdict = ("The images agree within noise" if agree else
               "**The images do not agree within noise** (a limit of 4 standard errors per "
               "channel, 5 per block, is passed)")
    result["agreement"] = (f"{verdict} (mean of the rounds' images against the reference): "
                           + "; ".join(parts) + ".")
    print(f"Cornell box {w}x{h}, {spp} spp, {args.threads} threads; reference {ref_spp} spp "
          f"({mitsuba.variant})")
    for who in ("raypack", "mitsuba"):
        r = result[who]
        print(f"  {r['label']:<22} time {r['seconds']:.3f} s  MSE {r['mse']:.6f}  "
              f"efficiency {r['efficiency']:.3f}")
    q = result["ratios"]
    print(f"  raypack / Mitsuba: time {q['time']:.3f}, MSE {q['mse']:.3f}, "
          f"efficiency {q['efficiency']:.3f}")
    print("  " + result["agreement"])
    return finish(result)


if __name__ == "__main__":
    try:
        sys.exit(main())
    except RunError as e:
        sys.exit(f"gi_vs_mitsuba.py: {e}")
