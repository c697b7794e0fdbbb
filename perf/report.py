#!/usr/bin/env python3
"""Regenerates perf/README.md: raypack beside Embree on the same rays, build times, and
global illumination beside Mitsuba 3.

    python3 perf/report.py                    # everything; writes perf/README.md
    python3 perf/report.py --quick --out /tmp/p.md   # small sizes, one round: checks the script
    python3 perf/report.py --only bench --scene bunny   # one section, one scene (to stdout)
    python3 perf/report.py --only bench --kind spd,model --out /tmp/p.md   # some kinds
    python3 perf/report.py --list             # the scenes and their kinds

Standard library only (the generated scenes' perf/make_scene.py needs numpy). The suite
covers every kind of scene (KINDS): architecture interiors, isolated models, a
heightfield terrain, a triangle soup, Haines' SPD scenes, a large scene of 5M triangles
and the Cornell box; the generated ones are written as OBJ into the cache folder the
first time they are needed. It builds raypack (`cargo build --release`) unless `--raypack
PATH` names a binary; builds the Embree harness (../shared/peers/embree beside the
repository, or `--embree DIR`) into the cache folder when libembree-dev is installed, and
without it measures raypack alone and says so on the page; writes the ray sets with the
harness's `gen` (both tracers then trace the same rays) into the cache folder
(~/.cache/raypack-perf, or `--cache DIR`), never into the repository. Every command runs
under a timeout. The GI section comes from perf/gi_vs_mitsuba.py, run as its own
process.

A run with `--only`, `--scene` or `--kind` measures part of the suite and prints its
page on standard output (or writes `--out FILE`); only a whole run writes
perf/README.md. A page written to a file gets the ratio plot beside it as suite.svg.
"""

import argparse
import datetime
import json
import math
import os
import platform
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import tomllib
import xml.sax.saxutils
from pathlib import Path

# The suite, one row per scene. `name` labels the row and is raypack's scene argument
# (a name of the scenes folder's cameras.toml); the row's OBJ and camera are that
# table's. A row can instead carry its own: `obj` (relative to the scenes folder, or
# with `{cache}` for a file made here), `eye`, `target`, `up`, `vfov_deg`, `raypack` (the
# scene argument raypack gets, e.g. the OBJ's path) and `make` (a command that writes the
# OBJ when it is missing; `{cache}`, `{raypack}`, `{repo}` and `{python}`, the interpreter
# running this script, are filled in), e.g.
#   {"name": "grid500", "obj": "{cache}/grid500.obj", "raypack": "{cache}/grid500.obj",
#    "make": "python3 {repo}/perf/grid_obj.py 500 {cache}/grid500.obj",
#    "eye": [0.5, 0.5, 2.0], "target": [0.5, 0.5, 0.0], "up": [0, 1, 0], "vfov_deg": 60},
# Instead of `eye` and `target`, `frame` [x, y, z] looks at the centre of the OBJ's
# bounds from that direction, from where the bounding sphere just fills the vertical
# field of view (raypack's framing of the SPD scenes, src/scene/spd.rs). `light` [x, y,
# z] is the point light of the shadow set (the harness's `gen --light`; without it, the
# harness's rule). `kind` groups the rows (KINDS) for `--kind` and the summary. A file
# made here is made once: delete it from the cache folder when its generator changes.
SPD_MAKE = "{raypack} rays spd:%s --obj {cache}/scenes/spd-%s.obj"
SCENES = [
    {"name": "sponza", "kind": "interior"},
    {"name": "conference", "kind": "interior"},
    {"name": "bunny", "kind": "model"},
    # A 2.3 m lumpy statue seen from 3.7 m at chest height, and a torus knot; both stand
    # in empty space, like a scanned model.
    {"name": "statue", "kind": "model", "obj": "{cache}/scenes/statue.obj",
     "raypack": "{cache}/scenes/statue.obj",
     "make": "{python} {repo}/perf/make_scene.py statue {cache}/scenes/statue.obj",
     "eye": [1.0, 1.5, 3.6], "target": [0.0, 1.13, 0.0], "up": [0, 1, 0], "vfov_deg": 45},
    {"name": "knot", "kind": "model", "obj": "{cache}/scenes/knot.obj",
     "raypack": "{cache}/scenes/knot.obj",
     "make": "{python} {repo}/perf/make_scene.py knot {cache}/scenes/knot.obj",
     "eye": [0.0, -6.0, 9.0], "target": [0.0, 0.0, 0.0], "up": [0, 0, 1], "vfov_deg": 40},
    # 1 km of hills: the eye 30 m above a hillside in one corner, looking across to the
    # far corner and the sky above it; a low sun off to the left casts long shadows.
    {"name": "terrain", "kind": "terrain", "obj": "{cache}/scenes/terrain.obj",
     "raypack": "{cache}/scenes/terrain.obj",
     "make": "{python} {repo}/perf/make_scene.py terrain {cache}/scenes/terrain.obj",
     "eye": [985.0, 70.0, 15.0], "target": [0.0, 40.0, 1000.0], "up": [0, 1, 0],
     "vfov_deg": 50, "light": [-500.0, 300.0, 500.0]},
    {"name": "soup", "kind": "soup", "obj": "{cache}/scenes/soup.obj",
     "raypack": "{cache}/scenes/soup.obj",
     "make": "{python} {repo}/perf/make_scene.py soup {cache}/scenes/soup.obj",
     "eye": [2.6, 1.9, 3.4], "target": [0.0, 0.0, 0.0], "up": [0, 1, 0], "vfov_deg": 45},
    # Haines' SPD at raypack's default sizes, written as OBJ by raypack (spheres as UV
    # spheres of 8 rings), so both tracers trace the same triangles; the balls' published
    # view, the others raypack's framing of their bounds.
    {"name": "spd_balls", "kind": "spd", "obj": "{cache}/scenes/spd-balls.obj",
     "raypack": "{cache}/scenes/spd-balls.obj", "make": SPD_MAKE % ("balls:4", "balls"),
     "eye": [2.1, 1.3, 1.7], "target": [0.0, 0.0, 0.0], "up": [0, 0, 1], "vfov_deg": 45},
    {"name": "spd_gears", "kind": "spd", "obj": "{cache}/scenes/spd-gears.obj",
     "raypack": "{cache}/scenes/spd-gears.obj", "make": SPD_MAKE % ("gears:4", "gears"),
     "frame": [-0.6, -1.0, 1.1], "up": [0, 0, 1], "vfov_deg": 45},
    {"name": "spd_mount", "kind": "spd", "obj": "{cache}/scenes/spd-mount.obj",
     "raypack": "{cache}/scenes/spd-mount.obj", "make": SPD_MAKE % ("mount:6", "mount"),
     "frame": [-1.0, -0.8, 0.6], "up": [0, 0, 1], "vfov_deg": 45},
    {"name": "spd_rings", "kind": "spd", "obj": "{cache}/scenes/spd-rings.obj",
     "raypack": "{cache}/scenes/spd-rings.obj", "make": SPD_MAKE % ("rings:7", "rings"),
     "frame": [-1.0, -0.7, 0.8], "up": [0, 0, 1], "vfov_deg": 45},
    {"name": "spd_tetra", "kind": "spd", "obj": "{cache}/scenes/spd-tetra.obj",
     "raypack": "{cache}/scenes/spd-tetra.obj", "make": SPD_MAKE % ("tetra:6", "tetra"),
     "frame": [0.9, -1.0, 0.55], "up": [0, 0, 1], "vfov_deg": 45},
    {"name": "spd_tree", "kind": "spd", "obj": "{cache}/scenes/spd-tree.obj",
     "raypack": "{cache}/scenes/spd-tree.obj", "make": SPD_MAKE % ("tree:11", "tree"),
     "frame": [-0.3, -1.0, 0.35], "up": [0, 0, 1], "vfov_deg": 45},
    # The terrain's landscape on 1,600 x 1,600 vertices: the same view, five times the
    # triangles.
    {"name": "terrain5m", "kind": "large", "obj": "{cache}/scenes/terrain5m.obj",
     "raypack": "{cache}/scenes/terrain5m.obj",
     "make": "{python} {repo}/perf/make_scene.py terrain5m {cache}/scenes/terrain5m.obj",
     "eye": [985.0, 70.0, 15.0], "target": [0.0, 40.0, 1000.0], "up": [0, 1, 0],
     "vfov_deg": 50, "light": [-500.0, 300.0, 500.0]},
    {"name": "cornell_box", "kind": "box"},
]
# The kinds of scene, in the order of the summary.
KINDS = {
    "interior": "architecture interiors",
    "model": "isolated models",
    "terrain": "heightfield terrain",
    "soup": "triangle soup",
    "spd": "SPD scenes",
    "large": "large (5M+ triangles)",
    "box": "Cornell box",
}

# The standard sets of RAYS.md; shadow rays are any-hit queries for both tracers.
SETS = ["primary", "shadow", "diffuse"]
# Embree's stream context per set: coherent for the camera and shadow sets, incoherent
# for diffuse rays (the faster choice for each, ../shared/peers/embree/README.md).
EMBREE_COHERENT = {"primary": "yes", "shadow": "yes", "diffuse": "no"}
EMBREE_KERNELS = ["single", "packet4", "packet8", "stream"]

FULL = {"rounds": 3, "repeat": 3, "width": 1024, "height": 768, "builds": 3}
QUICK = {"rounds": 1, "repeat": 2, "width": 256, "height": 192, "builds": 1}

REPO = Path(__file__).resolve().parent.parent
README = REPO / "perf" / "README.md"


class RunError(Exception):
    """A command failed or ran out of time; the message names it."""


def log(msg):
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def run(cmd, timeout, **kw):
    """`cmd`'s standard output; RunError when it fails or takes longer than `timeout` s."""
    cmd = [str(c) for c in cmd]
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, **kw)
    except subprocess.TimeoutExpired:
        raise RunError(f"{' '.join(cmd)}: no answer after {timeout} s") from None
    except FileNotFoundError:
        raise RunError(f"{cmd[0]}: not found") from None
    if p.returncode != 0:
        tail = (p.stderr or p.stdout).strip().splitlines()[-5:]
        raise RunError(f"{' '.join(cmd)}: exit {p.returncode}: {' / '.join(tail)}")
    return p.stdout


def load_average():
    """The 1-minute load average."""
    try:
        return float(Path("/proc/loadavg").read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return float("nan")


class LoadSampler:
    """Samples the 1-minute load average every 10 s while the measurements run."""

    def __init__(self):
        self.samples = [load_average()]
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self.loop, daemon=True)
        self.thread.start()

    def loop(self):
        while not self.stop.wait(10):
            self.samples.append(load_average())

    def range(self):
        self.stop.set()
        xs = [x for x in self.samples + [load_average()] if not math.isnan(x)]
        return (min(xs), max(xs)) if xs else (float("nan"), float("nan"))


def cache_folder(arg):
    if arg:
        path = Path(arg)
    else:
        base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
        path = Path(base) / "raypack-perf"
    path.mkdir(parents=True, exist_ok=True)
    return path.resolve()


def scenes_folder(arg):
    """--scenes, else $RAYPACK_SCENES, else ../shared/scenes beside the repository."""
    path = Path(arg or os.environ.get("RAYPACK_SCENES") or REPO.parent / "shared" / "scenes")
    if not (path / "cameras.toml").is_file():
        sys.exit(f"report.py: {path}/cameras.toml not found (give --scenes DIR)")
    return path.resolve()


def build_raypack(timeout=3600):
    """Builds raypack in release mode; returns the binary."""
    log("cargo build --release")
    run(["cargo", "build", "--release", "--bin", "raypack"], timeout, cwd=REPO)
    return REPO / "target" / "release" / "raypack"


def raypack_binary(arg):
    if arg:
        path = Path(arg).resolve()
        if not os.access(path, os.X_OK):
            sys.exit(f"report.py: --raypack {path}: not an executable")
        return path
    return build_raypack()


def cpu_description():
    """CPU model (with its family and model numbers, which tell one generation of a
    vendor's name from the next), logical cores and the widest vector ISA of the flags
    in /proc/cpuinfo."""
    model, flags, numbers = platform.processor() or platform.machine(), set(), {}
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            key, _, value = line.partition(":")
            key = key.strip()
            if key == "model name":
                model = value.strip()
            elif key in ("cpu family", "model") and key not in numbers:
                numbers[key] = value.strip()
            elif key == "flags":
                flags = set(value.split())
    except OSError:
        pass
    if len(numbers) == 2:
        model += f" (family {numbers['cpu family']}, model {numbers['model']})"
    if "avx512f" in flags:
        isa = "AVX-512F"
    elif {"avx2", "fma"} <= flags:
        isa = "AVX2+FMA"
    elif flags:
        isa = "baseline (no AVX2+FMA)"
    else:
        isa = "unknown"
    return model, os.cpu_count() or 1, isa


def git_state():
    """Short commit and whether the working tree had changes."""
    try:
        commit = run(["git", "-C", REPO, "rev-parse", "--short", "HEAD"], 30).strip()
        dirty = bool(run(["git", "-C", REPO, "status", "--porcelain"], 30).strip())
    except RunError:
        return "unknown", False
    return commit, dirty


def fmt_vec(v):
    return ",".join(repr(float(x)) for x in v)


def obj_bounds(path):
    """The smallest and largest vertex coordinates of an OBJ file."""
    lo, hi = [math.inf] * 3, [-math.inf] * 3
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                xyz = line.split()[1:4]
                for a in range(3):
                    x = float(xyz[a])
                    lo[a], hi[a] = min(lo[a], x), max(hi[a], x)
    return lo, hi


def framing(obj, direction, vfov_deg):
    """Eye and target looking at the centre of the OBJ's bounds from `direction`, at the
    distance where the bounding sphere just fills the vertical field of view."""
    lo, hi = obj_bounds(obj)
    centre = [(a + b) / 2 for a, b in zip(lo, hi)]
    radius = math.dist(lo, hi) / 2
    dist = radius / math.sin(math.radians(vfov_deg) / 2)
    norm = math.hypot(*direction)
    eye = [round(c + d / norm * dist, 6) for c, d in zip(centre, direction)]
    return eye, [round(c, 6) for c in centre]


def split_list(args):
    """Repeated options whose values may also be comma-separated lists."""
    return [x for a in args for x in a.split(",") if x]


def suite(scenes_dir, cache, raypack, names, kinds=()):
    """The rows of SCENES to measure (all, or those named or of the kinds given),
    resolved: obj path, camera, light, raypack's scene argument. Runs each row's `make`
    when its OBJ is missing."""
    cams = tomllib.loads((scenes_dir / "cameras.toml").read_text())
    known = [r["name"] for r in SCENES]
    for n in names:
        if n not in known:
            sys.exit(f"report.py: --scene {n}: not in the suite ({', '.join(known)})")
    for k in kinds:
        if k not in KINDS:
            sys.exit(f"report.py: --kind {k}: not a kind of the suite ({', '.join(KINDS)})")
    rows = []
    for row in SCENES:
        if (names or kinds) and row["name"] not in names and row["kind"] not in kinds:
            continue
        fill = {"cache": str(cache), "raypack": str(raypack), "repo": str(REPO),
                "python": sys.executable}
        r = dict(cams.get(row["name"], {}))
        r.update({k: (v.format(**fill) if isinstance(v, str) else v) for k, v in row.items()})
        obj = scenes_dir / r["obj"]
        if not obj.is_file() and "make" in r:
            log(f"{row['name']}: {r['make']}")
            obj.parent.mkdir(parents=True, exist_ok=True)
            run(shlex.split(r["make"]), 3600, cwd=REPO)
        if not obj.is_file():
            sys.exit(f"report.py: {row['name']}: {obj} not found")
        if "frame" in r:
            r["eye"], r["target"] = framing(obj, r["frame"], r["vfov_deg"])
        rows.append({
            "name": r["name"],
            "kind": r["kind"],
            "raypack": r.get("raypack", r["name"]),
            "obj": obj,
            "camera": {k: r[k] for k in ("eye", "target", "up", "vfov_deg")},
            "light": r.get("light"),
            "source": scene_source(row),
        })
    return rows


def scene_source(row):
    """Where a row's OBJ comes from, for the page: cameras.toml or its `make`."""
    if "make" not in row:
        return "../shared/scenes (cameras.toml)"
    cmd = row["make"].replace("{python} {repo}/", "python3 ").replace("{raypack}", "raypack")
    return f"`{cmd.replace('{cache}', '$CACHE')}`"


class Embree:
    """The Embree harness, built into the cache folder."""

    def __init__(self, source, cache):
        self.binary = cache / "embree-build" / "embree-anchor"
        log(f"make -C {source} BUILD={self.binary.parent}")
        run(["make", "-C", source, f"BUILD={self.binary.parent}"], 900)
        self.version = "Embree"

    def gen(self, row, out, width, height):
        c = row["camera"]
        run([self.binary, "gen", "--obj", row["obj"], "--eye", fmt_vec(c["eye"]),
             "--target", fmt_vec(c["target"]), "--up", fmt_vec(c["up"]),
             "--vfov", repr(float(c["vfov_deg"])), "--width", width, "--height", height,
             "--out", out] + (["--light", fmt_vec(row["light"])] if row["light"] else []),
            1800)

    def bench(self, obj, rays, query, coherent, repeat, threads=1, build_threads=None,
              build_repeat=1, modes=EMBREE_KERNELS):
        """RESULT and BUILD lines of one harness run, as dicts."""
        cmd = [self.binary, "bench", "--obj", obj, "--rays", rays, "--mode", ",".join(modes),
               "--threads", threads, "--repeat", repeat, "--query", query,
               "--coherent", coherent, "--build-repeat", build_repeat]
        if build_threads:
            cmd += ["--build-threads", build_threads]
        out = run(cmd, 1800)
        results, builds = [], []
        for line in out.splitlines():
            if line.startswith("embree "):
                self.version = "Embree " + line.split()[1].rstrip(":")
            kind, _, rest = line.partition(" ")
            if kind in ("RESULT", "BUILD"):
                d = dict(kv.split("=", 1) for kv in rest.split())
                (results if kind == "RESULT" else builds).append(d)
        return results, builds


def embree_harness(arg, cache):
    """The built harness, or (None, reason)."""
    source = Path(arg) if arg else REPO.parent / "shared" / "peers" / "embree"
    if not (source / "Makefile").is_file():
        return None, f"the Embree harness was not found at {source} (give --embree DIR)"
    header = Path("/usr/include/embree3/rtcore.h")
    if not header.is_file():
        return None, ("Embree 3 is not installed (`apt-get update && apt-get install -y "
                      "libembree-dev`)")
    try:
        return Embree(source.resolve(), cache), None
    except RunError as e:
        return None, f"the Embree harness did not build: {e}"


def ray_sets(row, cache, embree, raypack, width, height):
    """The folder holding the row's three sets at width x height: the harness's `gen`
    files where Embree is there, else raypack's own sets (same rules, RAYS.md)."""
    key = f"{row['name']}-{width}x{height}-{'embree' if embree else 'raypack'}"
    folder = cache / "rays" / key
    stamp = folder / "done.json"
    want = {"obj": str(row["obj"]), "mtime": row["obj"].stat().st_mtime,
            "size": row["obj"].stat().st_size, "camera": row["camera"]}
    if row["light"]:
        want["light"] = row["light"]
    if stamp.is_file() and json.loads(stamp.read_text()) == want:
        return folder
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    log(f"{row['name']}: writing the ray sets ({width}x{height}) into {folder}")
    if embree:
        embree.gen(row, folder, width, height)
    else:
        for s in SETS:
            run([raypack, "rays", row["raypack"], "--set", s, "-o", folder / f"{s}.rays",
                 "--width", width, "--height", height], 1800)
    stamp.write_text(json.dumps(want))
    return folder


# The modes of `raypack bench --accel bvh8` the report times, each its own column
# `bvh8-MODE`.
BVH_MODES = ["packet8", "packet16", "stream"]


def raypack_bench(raypack, row, folder, repeat, tmp):
    """raypack's rates on the folder's sets, one thread, every mode: {set: {mode: rate}},
    hit counts per set, the report's machine line."""
    out = Path(tmp) / "bench.json"
    # `bench` makes its own sets before it reads the folder's; 16x16 keeps that cheap.
    run([raypack, "bench", row["raypack"], "--rays", folder, "--sets", ",".join(SETS),
         "--modes", "all", "--threads", 1, "--repeat", repeat, "--width", 16,
         "--height", 16, "--json", out], 3600)
    report = json.loads(out.read_text())
    rates, hits = {}, {}
    for r in report["results"]:
        rates.setdefault(r["set"], {})[r["mode"]] = r["mrays_median"]
        hits[r["set"]] = int(r["checksum"].split(":")[0])
    # The 8-wide BVH's packet and stream modes, the other accelerator a user may pick;
    # its answers are the kd-tree's (bench fails on a checksum that differs between
    # modes).
    bvh_out = Path(tmp) / "bench-bvh8.json"
    run([raypack, "bench", row["raypack"], "--rays", folder, "--sets", ",".join(SETS),
         "--modes", ",".join(BVH_MODES), "--accel", "bvh8", "--threads", 1, "--repeat", repeat,
         "--width", 16, "--height", 16, "--json", bvh_out], 3600)
    for r in json.loads(bvh_out.read_text())["results"]:
        rates[r["set"]]["bvh8-" + r["mode"]] = r["mrays_median"]
        if int(r["checksum"].split(":")[0]) != hits[r["set"]]:
            raise SystemExit(f"{row['name']} {r['set']}: the BVH's hit count differs from the kd-tree's")
    return rates, hits, report


def measure_traversal(rows, raypack, embree, cache, cfg):
    """Alternated rounds per scene: raypack's modes and Embree's kernels on the same
    files. Returns per (scene, set) the per-round rates of every mode and kernel."""
    data = []
    for row in rows:
        folder = ray_sets(row, cache, embree, raypack, cfg["width"], cfg["height"])
        entry = {"scene": row["name"], "kind": row["kind"], "sets": {}, "triangles": None}
        for s in SETS:
            entry["sets"][s] = {"raypack": [], "embree": [], "rays": None,
                                "hits_raypack": None, "hits_embree": None}
        for rnd in range(cfg["rounds"]):
            order = ["raypack", "embree"] if rnd % 2 == 0 else ["embree", "raypack"]
            for who in order:
                if who == "raypack":
                    log(f"{row['name']}: round {rnd + 1}/{cfg['rounds']}: raypack")
                    with tempfile.TemporaryDirectory() as tmp:
                        rates, hits, rep = raypack_bench(raypack, row, folder, cfg["repeat"], tmp)
                    entry["triangles"] = rep["triangles"]
                    entry["simd"] = rep["machine"]["simd"]
                    for s in SETS:
                        e = entry["sets"][s]
                        e["raypack"].append(rates[s])
                        e["hits_raypack"] = hits[s]
                        e["rays"] = next(r["rays"] for r in rep["results"] if r["set"] == s)
                elif embree:
                    log(f"{row['name']}: round {rnd + 1}/{cfg['rounds']}: Embree")
                    for s in SETS:
                        query = "occluded" if s == "shadow" else "intersect"
                        results, _ = embree.bench(row["obj"], folder / f"{s}.rays", query,
                                                  EMBREE_COHERENT[s], cfg["repeat"])
                        e = entry["sets"][s]
                        e["embree"].append({r["mode"]: float(r["median"]) for r in results})
                        e["hits_embree"] = int(results[0]["hits"])
        data.append(entry)
    return data


def best(rounds):
    """The mode with the highest median over rounds, and that median."""
    modes = rounds[0].keys()
    med = {m: statistics.median(r[m] for r in rounds) for m in modes}
    mode = max(med, key=med.get)
    return mode, med[mode]


def geomean(xs):
    xs = [x for x in xs if x > 0]
    return math.exp(sum(map(math.log, xs)) / len(xs)) if xs else float("nan")


def summarise_traversal(data):
    """Rows of the table: best mode and kernel per (scene, set), the ratio (median over
    rounds of raypack's best mode over Embree's best kernel in the same round)."""
    rows = []
    for entry in data:
        for s in SETS:
            e = entry["sets"][s]
            rmode, rrate = best(e["raypack"])
            row = {"scene": entry["scene"], "kind": entry["kind"],
                   "triangles": entry["triangles"], "set": s,
                   "rays": e["rays"], "raypack_mode": rmode, "raypack": rrate,
                   "raypack_all": {m: statistics.median(r[m] for r in e["raypack"])
                                   for m in e["raypack"][0]},
                   "hits_raypack": e["hits_raypack"], "hits_embree": e["hits_embree"]}
            if e["embree"]:
                emode, erate = best(e["embree"])
                row.update({
                    "embree_mode": emode, "embree": erate,
                    "embree_all": {m: statistics.median(r[m] for r in e["embree"])
                                   for m in e["embree"][0]},
                    "ratio": statistics.median(a[rmode] / b[emode]
                                               for a, b in zip(e["raypack"], e["embree"])),
                })
            rows.append(row)
    return rows


def measure_builds(rows, raypack, embree, cache, cfg):
    """raypack's build on 1 and 2 threads (`info`, median of `builds`) beside Embree's
    high-quality build on 1 and 2 threads (the harness's BUILD line), alternated."""
    out = []
    for row in rows:
        r = {"scene": row["name"]}
        for threads in (1, 2):
            log(f"{row['name']}: build, {threads} thread(s)")
            with tempfile.TemporaryDirectory() as tmp:
                j = Path(tmp) / "info.json"
                run([raypack, "info", row["raypack"], "--threads", threads, "--repeat",
                     cfg["builds"], "--json", j] + (["--occupancy"] if threads == 2 else []),
                    1800)
                info = json.loads(j.read_text())
            r[f"raypack_{threads}"] = info["build_seconds"]["median"]
            if threads == 2 and info.get("occupancy"):
                r["serial"] = info["occupancy"]["serial_fraction"]
                r["amdahl_16"] = info["occupancy"]["amdahl_16"]
            r.update({"triangles": info["triangles"], "builder": info["builder"],
                      "nodes": info["nodes"], "sah": info["sah"]["cost"],
                      "bytes": info["memory"]["total"]["bytes"]})
            if embree:
                folder = ray_sets(row, cache, embree, raypack, cfg["width"], cfg["height"])
                _, builds = embree.bench(row["obj"], folder / "primary.rays", "intersect",
                                         "yes", 1, build_threads=threads,
                                         build_repeat=cfg["builds"], modes=["single"])
                for b in builds:
                    r[f"embree_{b['quality']}_{threads}"] = float(b["median_s"])
        out.append(r)
    return out


def run_gi(raypack, args, cfg_quick, cache):
    """perf/gi_vs_mitsuba.py's JSON, or a dict saying why there is none."""
    with tempfile.TemporaryDirectory() as tmp:
        j = Path(tmp) / "gi.json"
        cmd = [sys.executable, REPO / "perf" / "gi_vs_mitsuba.py", "--raypack", raypack,
               "--json", j, "--cache", cache]
        if args.scenes:
            cmd += ["--scenes", args.scenes]
        if cfg_quick:
            cmd.append("--quick")
        log("GI: " + " ".join(str(c) for c in cmd[1:]))
        try:
            run(cmd, 7200)
        except RunError as e:
            if j.is_file():
                return json.loads(j.read_text())
            return {"error": str(e)}
        return json.loads(j.read_text())


def table(header, rows, align):
    align = (list(align) + ["l"] * len(header))[:len(header)]
    lines = ["| " + " | ".join(header) + " |",
             "| " + " | ".join("---:" if a == "r" else "---" for a in align) + " |"]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(lines)


def plural(n, noun):
    return f"{n} {noun}" + ("" if n == 1 else "s")


def f2(x):
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.2f}"


def secs(x):
    if x is None:
        return "-"
    return f"{x:.3f} s" if x >= 0.01 else f"{x * 1000:.2f} ms"


# A (scene, set) pair is at Embree's rate from GOOD up, and well behind it below POOR.
GOOD, POOR = 1.0, 0.8
SET_COLOURS = {"primary": "#4e79a7", "shadow": "#e15759", "diffuse": "#59a14f"}


def ratio_groups(trav):
    """(label, pairs) for the whole suite, each set and each kind of scene, the pairs
    being the rows of `trav` with a ratio."""
    pairs = [r for r in trav if "ratio" in r]
    groups = [("whole suite", pairs)]
    groups += [(f"{s} sets", [r for r in pairs if r["set"] == s]) for s in SETS]
    groups += [(label, [r for r in pairs if r["kind"] == k]) for k, label in KINDS.items()]
    return [(label, rs) for label, rs in groups if rs]


def ratio_summary(trav, plot):
    """The summary of the ratios: geometric means and counts per group, the pairs below
    POOR, and the plot's link."""
    body = []
    for label, rs in ratio_groups(trav):
        ratios = [r["ratio"] for r in rs]
        body.append([label, len(ratios), f"**{geomean(ratios):.2f}**",
                     sum(x >= GOOD for x in ratios), sum(x < POOR for x in ratios)])
    out = [f"raypack / Embree by group of (scene, set) pairs: the geometric mean of the "
           f"ratios, and how many pairs reach Embree's rate (ratio {GOOD:.2f} or more) or "
           f"stay below {POOR:.2f} of it:", ""]
    out += [table(["pairs", "count", "geometric mean", f">= {GOOD:.2f}", f"< {POOR:.2f}"],
                  body, ["l", "r", "r", "r", "r"]), ""]
    poor = [f"{r['scene']} {r['set']} ({r['ratio']:.2f})" for r in trav
            if "ratio" in r and r["ratio"] < POOR]
    out += [f"Below {POOR:.2f}: {', '.join(poor) or 'none'}.", ""]
    if plot:
        out += [f"![raypack / Embree per scene and set, lines at {GOOD:.1f} and {POOR:.1f}]"
                f"({plot})", ""]
    return out


def suite_svg(trav):
    """A bar chart, as SVG text, of raypack / Embree per (scene, set), one colour per set,
    with lines at GOOD and POOR; None when no pair has a ratio."""
    pairs = {(r["scene"], r["set"]): r["ratio"] for r in trav if "ratio" in r}
    if not pairs:
        return None
    scenes = list(dict.fromkeys(scene for scene, _ in pairs))
    bar, gap, left, right, top, bottom, plot_h = 10, 12, 40, 12, 40, 72, 220
    group = len(SETS) * bar + gap
    width = max(left + right + len(scenes) * group, 540)
    height = top + plot_h + bottom
    steps = math.ceil(max([1.2] + list(pairs.values())) * 1.05 / 0.2)
    ymax = steps * 0.2

    def y(v):
        return top + plot_h * (1 - min(v, ymax) / ymax)

    esc = xml.sax.saxutils.escape
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
           f'viewBox="0 0 {width} {height}" font-family="sans-serif" font-size="11">',
           f'<rect width="{width}" height="{height}" fill="white"/>',
           f'<text x="{left}" y="14" font-size="12">raypack / Embree, Mrays/s of the best '
           'mode over the best kernel, one thread</text>']
    x = left
    for s in SETS:
        out.append(f'<rect x="{x}" y="22" width="10" height="10" fill="{SET_COLOURS[s]}"/>'
                   f'<text x="{x + 14}" y="31">{s}</text>')
        x += 80
    for i in range(steps + 1):
        v = i * 0.2
        out.append(f'<line x1="{left}" x2="{width - right}" y1="{y(v):.1f}" y2="{y(v):.1f}" '
                   f'stroke="#e8e8e8"/><text x="{left - 4}" y="{y(v) + 4:.1f}" '
                   f'text-anchor="end">{v:.1f}</text>')
    x = left + gap / 2
    for scene in scenes:
        for s in SETS:
            if (scene, s) in pairs:
                v = pairs[(scene, s)]
                out.append(f'<rect x="{x:.1f}" y="{y(v):.1f}" width="{bar - 1}" '
                           f'height="{y(0) - y(v):.1f}" fill="{SET_COLOURS[s]}">'
                           f'<title>{esc(scene)} {s}: {v:.2f}</title></rect>')
            x += bar
        centre = x - len(SETS) * bar / 2
        out.append(f'<text transform="translate({centre:.1f},{y(0) + 12:.1f}) rotate(-40)" '
                   f'text-anchor="end">{esc(scene)}</text>')
        x += gap
    for v, dash in ((GOOD, ""), (POOR, ' stroke-dasharray="5,3"')):
        out.append(f'<line x1="{left}" x2="{width - right}" y1="{y(v):.1f}" y2="{y(v):.1f}" '
                   f'stroke="#222" stroke-width="1.2"{dash}/>')
    out.append(f'<line x1="{left}" x2="{width - right}" y1="{y(0):.1f}" y2="{y(0):.1f}" '
               'stroke="#222"/>')
    out.append("</svg>")
    return "\n".join(out) + "\n"


def section_scenes(rows, triangles):
    """The suite: one row per scene with its kind, size, camera, light and source."""
    out = ["## Scenes", ""]
    out.append(
        "The rows of `SCENES` (perf/report.py). Cameras are ../shared/RAYS.md's pinhole "
        "(eye, target, up, vertical field of view). A generated scene's OBJ is written once "
        "into the cache folder ($CACHE) by the command shown; raypack and Embree both read "
        "that file. *Light* is the shadow set's point light where the row sets one, else "
        "the harness's rule (../shared/peers/embree/README.md).")
    out.append("")

    def vec(v):
        return "(" + ", ".join(f"{x:g}" for x in v) + ")"

    body = []
    for r in rows:
        c = r["camera"]
        tris = triangles.get(r["name"])
        body.append([r["name"], KINDS[r["kind"]], f"{tris:,}" if tris else "-",
                     f"eye {vec(c['eye'])}, target {vec(c['target'])}, up {vec(c['up'])}, "
                     f"{c['vfov_deg']:g} deg", vec(r["light"]) if r["light"] else "rule",
                     r["source"]])
    out += [table(["scene", "kind", "triangles", "camera", "light", "OBJ"], body,
                  ["l", "l", "r", "l", "l", "l"]), ""]
    return out


def section_bench(trav, embree_note, cfg, quick_flag, plot=None):
    out = ["## Traversal beside Embree", ""]
    modes = list(trav[0]["raypack_all"]) if trav else []
    have_embree = any("embree" in r for r in trav)
    rp = (f"raypack (`raypack bench NAME --rays DIR --modes all --threads 1 --repeat "
          f"{cfg['repeat']}` on the kd-tree, then the same with `--accel bvh8 --modes "
          f"{','.join(BVH_MODES)}`, the columns *bvh8-MODE*)")
    size = f"{cfg['width']}x{cfg['height']}"
    if have_embree:
        out.append(
            f"Mrays/s, one thread, on the same ray files (the Embree harness's `gen`, {size}; "
            f"../shared/RAYS.md). {plural(cfg['rounds'], 'round')}; in each, {rp} and Embree "
            f"(the harness's `bench --mode {','.join(EMBREE_KERNELS)} --threads 1 --repeat "
            f"{cfg['repeat']}`, shadow rays as `--query occluded`) take turns, each rate the "
            f"median of {cfg['repeat']} passes after a warm-up. A rate below is the median "
            "over the rounds; *best* is the mode or kernel with the highest one; the ratio "
            "is the median over rounds of raypack's best mode over Embree's best kernel in "
            "the same round. *Hits* compares the two tracers' hit counts on the set (for "
            "shadow rays: occluded rays).")
    else:
        out.append(
            f"**Embree was not measured:** {embree_note}. raypack's columns alone: Mrays/s, "
            f"one thread, on raypack's own sets (`raypack rays`, {size}, the rules of "
            f"../shared/RAYS.md); {plural(cfg['rounds'], 'round')} of {rp}, each rate the "
            f"median of {cfg['repeat']} passes after a warm-up, then the median over the "
            "rounds; *best* is the mode with the highest one.")
    out.append("")
    header = ["scene", "triangles", "set", "rays", "raypack best", "Mrays/s"]
    if have_embree:
        header += ["Embree best", "Mrays/s", "raypack / Embree", "hits"]
    body = []
    for r in trav:
        line = [r["scene"], f"{r['triangles']:,}", r["set"], f"{r['rays']:,}",
                r["raypack_mode"], f2(r["raypack"])]
        if have_embree:
            same = "same" if r["hits_raypack"] == r["hits_embree"] else (
                f"{r['hits_raypack']:,} vs {r['hits_embree']:,}")
            line += [r["embree_mode"], f2(r["embree"]), f"**{r['ratio']:.2f}**", same]
        body.append(line)
    out += [table(header, body, ["l", "r", "l", "r", "l", "r", "l", "r", "r", "l"]), ""]
    if have_embree:
        out += ratio_summary(trav, plot)
    out += ["Every mode, medians over the rounds (Mrays/s; the best of each tracer in bold):", ""]
    header = ["scene", "set"] + [f"raypack {m}" for m in modes]
    if have_embree:
        header += [f"Embree {k}" for k in EMBREE_KERNELS]
    body = []
    for r in trav:
        line = [r["scene"], r["set"]] + [
            f"**{f2(r['raypack_all'][m])}**" if m == r["raypack_mode"] else f2(r["raypack_all"].get(m))
            for m in modes]
        if have_embree:
            line += [f"**{f2(r['embree_all'][k])}**" if k == r["embree_mode"]
                     else f2(r["embree_all"].get(k)) for k in EMBREE_KERNELS]
        body.append(line)
    out += [table(header, body, ["l", "l"] + ["r"] * (len(header) - 2)), ""]
    out += [f"Reproduce: `python3 perf/report.py{quick_flag} --only bench` (one scene: add "
            "`--scene NAME`; one kind: `--kind KIND`).", ""]
    return out


def section_build(builds, have_embree, cfg, quick_flag):
    out = ["## Build", ""]
    out.append(
        f"Seconds, median of {plural(cfg['builds'], 'build')}, OBJ loading not included. "
        f"raypack: `raypack info NAME --threads T --repeat {cfg['builds']}` (the default "
        "tree flags)." + (
            " Embree: the harness's `BUILD` line (`rtcCommitScene` alone) with "
            "`--build-threads T`, taken right after raypack's." if have_embree else "") +
        " *Tree memory* is raypack's whole tree (`raypack info`'s `memory total`: nodes, "
        "leaf table, index lists, TriAccel records and, where a small scene's stream "
        "queries are flat, the list of primitives they test), also per triangle of the scene. "
        "*Serial part* is the share of the build's work done while fewer than both "
        "threads worked, in the 2-thread builds (`--occupancy`: the build marks which "
        "threads work when, src/accel/occupancy.rs), and *Amdahl 16* the speedup on 16 "
        "threads that Amdahl's law predicts from it, 1 / (f + (1 - f) / 16).")
    out.append("")
    header = ["scene", "triangles", "raypack 1 thread", "raypack 2 threads", "serial part",
              "Amdahl 16"]
    if have_embree:
        header += ["Embree high, 1 thread", "Embree high, 2 threads", "Embree medium, 2 threads"]
    header += ["nodes", "tree memory", "bytes / triangle", "SAH cost"]
    body = []
    for b in builds:
        line = [b["scene"], f"{b['triangles']:,}", secs(b["raypack_1"]), secs(b["raypack_2"]),
                f"{100 * b['serial']:.1f}%" if b.get("serial") is not None else "-",
                f"{b['amdahl_16']:.1f}x" if b.get("amdahl_16") is not None else "-"]
        if have_embree:
            line += [secs(b.get("embree_high_1")), secs(b.get("embree_high_2")),
                     secs(b.get("embree_medium_2"))]
        size = (f"{b['bytes'] / 2**20:.2f} MiB" if b["bytes"] >= 2**20
                else f"{b['bytes'] / 2**10:.2f} KiB")
        line += [f"{b['nodes']:,}", size, f"{b['bytes'] / max(b['triangles'], 1):.1f}",
                 f"{b['sah']:.2f}"]
        body.append(line)
    out += [table(header, body, ["l"] + ["r"] * (len(header) - 1)), ""]
    builder = sorted({b["builder"] for b in builds})
    out += [f"raypack builder: {', '.join(builder)}.", ""]
    out += [f"Reproduce: `python3 perf/report.py{quick_flag} --only build` (one scene: add "
            "`--scene NAME`; one kind: `--kind KIND`).", ""]
    return out


def section_gi(gi, quick_flag):
    out = ["## Global illumination beside Mitsuba 3", ""]
    if "missing" in gi:
        out += [f"**Not measured:** {gi['missing']}. Install it with `{gi['install']}`, then "
                "run the command below.", ""]
    elif "error" in gi:
        out += [f"**Not measured:** the comparison failed: `{gi['error']}`.", ""]
    else:
        c = gi["conditions"]
        scenes = gi["scenes"]
        out.append(
            "raypack's path tracer and Mitsuba's on the scene files of scenes/gi, each "
            "rendered by raypack from the file and by Mitsuba from the same file as "
            "perf/gi_vs_mitsuba.py translates it (its docstring gives the rules): "
            + "; ".join(f"`{r['scene']}`, {r['about']} (`{r['file']}`)" for r in scenes)
            + ". "
            f"All at {c['width']}x{c['height']}, {c['threads']} threads, box pixel filter, "
            "the file's camera (vertical fov). raypack: "
            f"`{scenes[0].get('raypack_command', 'raypack render FILE --integrator path')}` "
            f"and alike. Mitsuba {c['mitsuba_version']} (`{c['variant']}`): `path` "
            f"integrator, max depth {c['max_depth']}, Russian roulette from depth "
            f"{c['rr_depth']} (raypack's: {c['rr_note']}), `independent` sampler "
            "(raypack: Owen-scrambled Sobol points, its default); "
            "Lambertian surfaces as `twosided` `diffuse`, the mirror as `conductor` of "
            "material \"none\", the glossy sphere as `roughconductor` of material \"none\" "
            "with GGX roughness (raypack's glossy lobe, the same microfacet model), glass as "
            "`dielectric`, lights as `area` emitters, the sky "
            f"as a `constant` emitter. {plural(c['rounds'], 'round')} per scene, the two "
            "renderers taking turns; time is the render alone (scene loading and "
            "acceleration structure excluded; Mitsuba's after a warm-up render that "
            "compiles its kernels), median over rounds; round k uses seed k in both, so "
            "the images, and the MSE, repeat from run to run. MSE is against a Mitsuba "
            "reference of the samples per pixel given (made once by the same script and "
            "kept in its cache folder, outside the repository; mean over pixels and "
            "channels of linear radiance, median over rounds); efficiency is 1 / (time x "
            "MSE), and its ratio above 1 means raypack reaches a given error sooner.")
        out.append("")
        header = ["scene", "spp", "reference spp", "raypack time", "Mitsuba time",
                  "raypack MSE", "Mitsuba MSE", "time ratio", "MSE ratio",
                  "efficiency ratio", "agree"]
        body = []
        for r in scenes:
            if "error" in r:
                body.append([f"`{r['scene']}`"] + ["-"] * 9 + ["not measured"])
                continue
            a, b, q = r["raypack"], r["mitsuba"], r["ratios"]
            body.append([f"`{r['scene']}`", r["spp"], f"{r['reference_spp']:,}",
                         f"{a['seconds']:.2f} s", f"{b['seconds']:.2f} s",
                         f"{a['mse']:.3g}", f"{b['mse']:.3g}", f"{q['time']:.2f}",
                         f"{q['mse']:.2f}", f"**{q['efficiency']:.2f}**",
                         "yes" if r["agree"] else "**no**"])
        if "ratios" in gi:
            q = gi["ratios"]
            body.append(["geometric mean", "", "", "", "", "", "", f"{q['time']:.2f}",
                         f"{q['mse']:.2f}", f"**{q['efficiency']:.2f}**", ""])
        out += [table(header, body, ["l"] + ["r"] * 9 + ["l"]), ""]
        out.append("Ratios are raypack / Mitsuba. Agreement, scene by scene, of each "
                   "renderer's mean image over the rounds with the reference (the mean "
                   "over all pixels as a difference from the reference's, with its "
                   "standard error):")
        out.append("")
        for r in scenes:
            if "error" in r:
                out.append(f"- `{r['scene']}`: not measured: `{r['error']}`")
                continue
            means = "; ".join(
                f"{r[who]['label']} {100 * r[who]['mean_difference']:+.2f}% "
                f"± {100 * r[who]['mean_difference_se']:.2f}%" for who in ("raypack", "mitsuba"))
            out.append(f"- `{r['scene']}`: {r['agreement']} Mean over pixels: {means}.")
        out.append("")
    out += [f"Reproduce: `python3 perf/report.py{quick_flag} --only gi`, or "
            f"`python3 perf/gi_vs_mitsuba.py{quick_flag}` alone (`--scene NAME` for one "
            "scene).", ""]
    return out


# One page per CPU the suite has run on (timings of two CPUs are never mixed on a page):
# the file in perf/ and the CPU it names.
CPU_PAGES = [("README.md", "AMD EPYC Zen 4 with AVX-512"),
             ("zen3.md", "AMD EPYC Zen 3 with AVX2")]


def page(meta, parts):
    out = ["# raypack performance", ""]
    out.append(
        f"This page is generated: `{meta['command']}` measured everything on it in one run "
        f"(about {plural(meta['minutes'], 'minute')}) and wrote it; run `python3 "
        "perf/report.py` again to bring it up to date rather than editing it. Each table "
        "names the command that reproduces it. The session notes of earlier rounds, with "
        "the experiments behind the code, are history in [log/](log/); the kernels per "
        "instruction set and a default build beside a native one: [isa.md](isa.md). "
        "The same suite on each CPU it has run on, one page each: "
        + ", ".join(f"[{cpu}]({name})" for name, cpu in CPU_PAGES) + ".")
    out.append("")
    out.append("## Machine and run")
    out.append("")
    dirty = ", with uncommitted changes" if meta["dirty"] else ", clean working tree"
    lo, hi = meta["load"]
    busy = hi > 0.5 + meta["cores"] / 2
    out += [
        f"- Date: {meta['date']}",
        f"- Commit: `{meta['commit']}`{dirty}",
        f"- CPU: {meta['cpu']}, {meta['cores']} logical cores; vector ISA from "
        f"/proc/cpuinfo: {meta['isa']}; raypack (a default build, no `-C target-cpu`) ran "
        f"its {meta.get('simd', '(not reported: no bench run)')} kernels",
        f"- Peers: {meta['peers']}",
        f"- 1-minute load average, sampled through the run: {lo:.2f} to {hi:.2f} on "
        f"{meta['cores']} cores" + (
            ". Other processes were running beside the measurements, so absolute rates "
            "are lower and noisier than on an idle machine; the ratios, taken within "
            "one round, are the figures to compare." if busy else "."),
    ]
    if meta["quick"]:
        out.append("- **Quick run** (`--quick`: small images, one round): for checking the "
                   "script, not for reading.")
    out.append("")
    for p in parts:
        out += p
    out += ["## Reproduce", "",
            "From the repository, with `../shared/scenes` and `../shared/peers/embree` "
            "beside it:", "",
            "    apt-get update && apt-get install -y libembree-dev   # Embree 3 for the harness",
            "    pip install mitsuba==3.9.1                            # the GI comparison",
            "    pip install numpy                                     # perf/make_scene.py",
            "    python3 perf/report.py                                # writes perf/README.md",
            "",
            "`--quick` checks the script in a few minutes; `--only bench|build|gi`, "
            "`--scene NAME` and `--kind KIND` (repeatable, or comma-separated lists; "
            "`--list` names them) measure part of the suite and print the page "
            "(or `--out FILE`); `--raypack PATH` skips the build; `--embree DIR`, "
            "`--scenes DIR` and `--cache DIR` move the inputs and the ray files "
            "(default cache ~/.cache/raypack-perf, which also holds the generated scenes, "
            "about 0.5 GB). The scenes are the rows of `SCENES` at the top of "
            "perf/report.py.", ""]
    return "\n".join(out).rstrip() + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="small sizes, one round")
    ap.add_argument("--only", choices=["bench", "build", "gi"], action="append",
                    help="measure only this section (repeatable)")
    ap.add_argument("--scene", action="append", default=[],
                    help="only this scene (repeatable, or a comma-separated list)")
    ap.add_argument("--kind", action="append", default=[],
                    help=f"only the scenes of this kind (repeatable, or a comma-separated "
                    f"list): {', '.join(KINDS)}")
    ap.add_argument("--list", action="store_true",
                    help="print the suite's scenes and kinds, measure nothing")
    ap.add_argument("--out", help="write the page here (default: perf/README.md for a "
                    "whole run, standard output otherwise)")
    ap.add_argument("--raypack", help="the raypack binary (default: cargo build --release)")
    ap.add_argument("--embree", help="the Embree harness's folder")
    ap.add_argument("--scenes", help="the benchmark scenes (default ../shared/scenes)")
    ap.add_argument("--cache", help="ray files and builds (default ~/.cache/raypack-perf)")
    args = ap.parse_args()

    names, kinds = split_list(args.scene), split_list(args.kind)
    if args.list:
        for row in SCENES:
            print(f"{row['name']:<12} {row['kind']:<9} {KINDS[row['kind']]}")
        return
    start = time.time()
    cfg = QUICK if args.quick else FULL
    only = set(args.only or ["bench", "build", "gi"])
    whole = not args.only and not names and not kinds
    out_path = args.out or (str(README) if whole else "-")
    commit, dirty = git_state()
    loads = LoadSampler()
    scenes_dir = scenes_folder(args.scenes)
    cache = cache_folder(args.cache)
    raypack = raypack_binary(args.raypack)
    rows = suite(scenes_dir, cache, raypack, names, kinds)
    embree, embree_note = (None, "not needed")
    if only & {"bench", "build"}:
        embree, embree_note = embree_harness(args.embree, cache)
        if not embree:
            log(f"Embree: {embree_note}")
    model, cores, isa = cpu_description()
    meta = {"date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
            "commit": commit, "dirty": dirty, "cpu": model, "cores": cores, "isa": isa,
            "quick": args.quick,
            "command": " ".join(["python3 perf/report.py"] + [shlex.quote(a) for a in sys.argv[1:]])}
    quick_flag = " --quick" if args.quick else ""
    parts = []
    peers = []
    triangles = {}
    # The plot goes beside the page (perf/suite.svg beside perf/README.md).
    plot = Path(out_path).with_name("suite.svg") if out_path != "-" else None
    svg = None
    if "bench" in only:
        data = measure_traversal(rows, raypack, embree, cache, cfg)
        meta["simd"] = next((d["simd"] for d in data if "simd" in d), None) or "unknown"
        trav = summarise_traversal(data)
        svg = suite_svg(trav)
        if svg and not plot:
            log("no plot on standard output: give --out FILE to have it beside the page")
        parts.append(section_bench(trav, embree_note, cfg, quick_flag,
                                   plot.name if svg and plot else None))
        triangles.update({d["scene"]: d["triangles"] for d in data})
    if "build" in only:
        builds = measure_builds(rows, raypack, embree, cache, cfg)
        parts.append(section_build(builds, embree is not None, cfg, quick_flag))
        triangles.update({b["scene"]: b["triangles"] for b in builds})
    if triangles:
        parts.insert(0, section_scenes(rows, triangles))
    if embree:
        peers.append(f"{embree.version} (Debian's libembree-dev) through "
                     "../shared/peers/embree, built with `-O3 -march=native`")
    elif only & {"bench", "build"}:
        peers.append(f"Embree not measured: {embree_note}")
    if "gi" in only:
        gi = run_gi(raypack, args, args.quick, cache)
        if "conditions" in gi:
            peers.append(f"Mitsuba {gi['conditions']['mitsuba_version']} "
                         f"(`{gi['conditions']['variant']}`)")
        parts.append(section_gi(gi, quick_flag))
    meta["peers"] = "; ".join(peers) or "none"
    meta["load"] = loads.range()
    meta["minutes"] = max(1, round((time.time() - start) / 60))
    text = page(meta, parts)
    if out_path == "-":
        sys.stdout.write(text)
    else:
        if svg:
            tmp = plot.with_name(plot.name + f".tmp.{os.getpid()}")
            tmp.write_text(svg)
            tmp.replace(plot)
            log(f"wrote {plot}")
        tmp = Path(out_path).with_name(Path(out_path).name + f".tmp.{os.getpid()}")
        tmp.write_text(text)
        tmp.replace(out_path)
        log(f"wrote {out_path}")


if __name__ == "__main__":
    try:
        main()
    except RunError as e:
        sys.exit(f"report.py: {e}")
