#!/usr/bin/env python3
"""raypack's Python package beside Open3D's RaycastingScene (and embreex, Embree from
Python, when it imports): the rays per second a Python user gets from each, on the same
rays, the same triangles and the same number of threads.

Why: perf/README.md compares the Rust library with Embree in C++. From Python, what
counts is the whole call as a user makes it, from the numpy arrays they hold (origins,
directions, t_min, t_max) to numpy answers, so each timed call includes building the
arrays that library needs:

- raypack: ``scene.intersect(o, d, t_min, t_max, threads=T)`` (closest hits: t, prim,
  u, v, normal) and ``scene.occluded(...)`` (shadow rays); nothing to build. Its
  kernels are the package's default, ``mode="auto"`` (packets where neighbouring rays
  are coherent, streams elsewhere) unless --mode says otherwise.
- Open3D: ``cast_rays(Tensor.from_numpy(np.hstack([o, d])), nthreads=T)`` and
  ``test_occlusions(rays, tnear=0, tfar=1, nthreads=T)``, then ``.numpy()`` of every
  output. ``cast_rays`` has no tnear/tfar (it traces [0, inf)) and ``test_occlusions``
  takes one tnear/tfar for all rays, so a shadow ray's own t_max is passed by scaling
  its direction by t_max and tracing t in (0, 1): the scaling is timed too.
- embreex: ``EmbreeScene.run(o, d, dists, query=..., output=1)`` traces one ray after
  another on the calling thread with the GIL released, and has no thread option: the
  script splits the rays into 16 chunks per thread and runs them on a pool of T Python
  threads (one call on the main thread when T = 1). Its tnear is always 0; ``dists``
  is the per-ray tfar (t_max for shadow rays; for closest hits a fresh array of inf,
  since run() writes the hit distances into it).

Both peers use Embree with the ROBUST scene flag (Open3D sets it; embreex's default).
The standard ray sets start every ray at t = 0 (the generator offsets the origins) and
closest-hit sets end at t = inf, which the peers' fixed tnear/tfar need; the script
checks it. Building the scenes is not timed. Each rate is the median over --repeat
rounds after one warm-up call; within a round the libraries take turns, in an order that
rotates from round to round. The warm-up answers give the agreement check: the fraction
of rays on which raypack and the peer agree on hit/miss and on the primitive id (shadow
rays: on occluded or not).

    /work/venv-peers/bin/pip install ./python    # raypack into a venv with open3d, embreex
    /work/venv-peers/bin/python perf/python_vs_open3d.py --quick    # bunny, 1 round
    /work/venv-peers/bin/python perf/python_vs_open3d.py --write perf/python.md

Ray sets come from ``target/release/raypack rays SCENE --set SET`` (built with cargo if
missing), written to a temporary folder or kept in --rays-dir. Scenes are read from
$RAYPACK_SCENES, else ../shared/scenes beside the repository. Needs numpy, open3d and
raypack; embreex is optional.
"""

import argparse
import datetime
import importlib.metadata
import os
import re
import shlex
import statistics
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import open3d as o3d
import raypack

sys.path.insert(0, str(Path(__file__).resolve().parent))
from report import cpu_description  # noqa: E402  (one reading of /proc/cpuinfo for every page)

try:
    from embreex.mesh_construction import TriangleMesh as EmbreeTriangleMesh
    from embreex.rtcore_scene import EmbreeScene
except ImportError as err:  # optional peer
    EmbreeScene, EMBREEX_MISSING = None, str(err)
else:
    EMBREEX_MISSING = None

REPO = Path(__file__).resolve().parent.parent
SCENES = Path(os.environ.get("RAYPACK_SCENES") or REPO.parent / "shared" / "scenes").resolve()
BINARY = REPO / "target" / "release" / "raypack"
SETS = ("primary", "shadow", "diffuse")
CLOSEST = {"primary": True, "diffuse": True, "shadow": False}
O3D_INVALID = o3d.t.geometry.RaycastingScene.INVALID_ID  # 4294967295
EMBREEX_CHUNKS_PER_THREAD = 16


def log(msg):
    print(msg, file=sys.stderr, flush=True)


# ----------------------------------------------------------------------------- input

@dataclass
class Rays:
    """A ray set as a user holds it: contiguous float32 numpy arrays."""

    origins: np.ndarray  # (n, 3)
    directions: np.ndarray  # (n, 3)
    t_min: np.ndarray  # (n,)
    t_max: np.ndarray  # (n,)

    def __len__(self):
        return len(self.t_min)


def read_rays(path):
    """A .rays file: magic RAYS0001, u64 count, u32 width, u32 height, then per ray
    eight float32 (ox oy oz tmin dx dy dz tmax), little endian."""
    data = Path(path).read_bytes()
    if data[:8] != b"RAYS0001":
        raise ValueError(f"{path}: not a .rays file")
    count = int(np.frombuffer(data, "<u8", 1, 8)[0])
    rec = np.frombuffer(data, "<f4", count * 8, 24).reshape(count, 8)
    c = np.ascontiguousarray
    return Rays(c(rec[:, 0:3]), c(rec[:, 4:7]), c(rec[:, 3]), c(rec[:, 7]))


def ray_file(rays_dir, scene, ray_set):
    """The set's .rays file in rays_dir, written by the raypack CLI if not there."""
    path = Path(rays_dir) / f"{scene}.{ray_set}.rays"
    if not path.is_file():
        if not BINARY.is_file():
            log("building the raypack CLI: cargo build --release")
            subprocess.run(["cargo", "build", "--release"], cwd=REPO, check=True)
        subprocess.run([str(BINARY), "rays", scene, "--set", ray_set, "-o", str(path)],
                       cwd=REPO, check=True, stdout=subprocess.DEVNULL,
                       env=dict(os.environ, RAYPACK_SCENES=str(SCENES)))
    return path


def check_rays(rays, closest):
    """The peers trace from t = 0 (and Open3D's cast_rays to t = inf): say so if a set
    does not fit rather than time something else."""
    if np.any(rays.t_min != 0):
        raise SystemExit("rays with t_min != 0: the peers' tnear is fixed at 0")
    if closest and not np.all(np.isinf(rays.t_max)):
        raise SystemExit("closest-hit rays with finite t_max: Open3D's cast_rays has no tfar")
    if not closest and not np.all(np.isfinite(rays.t_max)):
        raise SystemExit("shadow rays need a finite t_max")


OBJ_LINE = re.compile(r"^(v|f)[ \t]+([^\r\n#]*)", re.M)
SLASH_TAIL = re.compile(r"/\S*")


def read_obj(path):
    """Positions (float32, (n, 3)) and triangles (int64, (m, 3)) of an OBJ file, in
    raypack's order: faces in file order, each fan-triangulated (0,1,2), (0,2,3), ...
    Corners may be ``a``, ``a/b``, ``a//c`` or ``a/b/c``; negative indices count back
    from the last vertex read so far."""
    matches = OBJ_LINE.findall(Path(path).read_text())
    is_vertex = np.array([kind == "v" for kind, _ in matches])
    v_rows = [rest.split()[:3] for kind, rest in matches if kind == "v"]
    vertices = np.array(v_rows, dtype=np.float64).astype(np.float32).reshape(-1, 3)
    faces = [(SLASH_TAIL.sub("", rest) if "/" in rest else rest).split()
             for kind, rest in matches if kind == "f"]
    sizes = np.fromiter(map(len, faces), np.int64, len(faces))
    if np.any(sizes < 3):
        raise ValueError(f"{path}: a face with fewer than 3 corners")
    corners = np.array([c for f in faces for c in f], dtype=np.int64)
    seen = np.cumsum(is_vertex)[~is_vertex]  # vertices read before each face
    seen = np.repeat(seen, sizes)
    corners = np.where(corners > 0, corners - 1, seen + corners)
    if corners.size and (corners.min() < 0 or corners.max() >= len(vertices)):
        raise ValueError(f"{path}: a face index out of range")
    return vertices, fan_triangles(corners, sizes)


def fan_triangles(corners, sizes):
    """Fan triangulation of faces given as flat corner indices and corner counts."""
    first = np.cumsum(sizes) - sizes  # each face's first corner in `corners`
    tris_per_face = sizes - 2
    face = np.repeat(np.arange(len(sizes)), tris_per_face)
    k = np.arange(tris_per_face.sum()) - np.repeat(np.cumsum(tris_per_face) - tris_per_face,
                                                   tris_per_face)  # 0.. within the face
    base = first[face]
    return np.stack([corners[base], corners[base + k + 1], corners[base + k + 2]], axis=1)


# ----------------------------------------------------------------------------- tracers

class Raypack:
    name = "raypack"

    mode = "auto"  # --mode
    accel = "auto"  # --accel

    def __init__(self, scene_name, vertices, triangles, threads):
        self.scene = raypack.Scene.load(scene_name, accel=self.accel)
        self.threads = threads
        if self.scene.triangle_count != len(triangles):
            raise SystemExit(f"{scene_name}: raypack has {self.scene.triangle_count} "
                             f"triangles, the OBJ reader {len(triangles)}")

    def closest(self, r):
        return self.scene.intersect(r.origins, r.directions, r.t_min, r.t_max,
                                    threads=self.threads, mode=self.mode)

    def occluded(self, r):
        return self.scene.occluded(r.origins, r.directions, r.t_min, r.t_max,
                                   threads=self.threads, mode=self.mode)

    @staticmethod
    def prim_ids(hits):
        return hits.prim


class Open3D:
    name = "Open3D"

    def __init__(self, scene_name, vertices, triangles, threads):
        self.scene = o3d.t.geometry.RaycastingScene(nthreads=threads)
        self.mesh = (vertices, triangles.astype(np.uint32))  # kept alive: shared with Open3D
        self.scene.add_triangles(*map(o3d.core.Tensor.from_numpy, self.mesh))
        self.threads = threads

    def closest(self, r):
        rays = o3d.core.Tensor.from_numpy(np.hstack([r.origins, r.directions]))
        out = self.scene.cast_rays(rays, nthreads=self.threads)
        return {key: value.numpy() for key, value in out.items()}

    def occluded(self, r):
        # One tnear/tfar for all rays: scale each direction by its t_max, trace (0, 1).
        rays = np.hstack([r.origins, r.directions * r.t_max[:, None]])
        out = self.scene.test_occlusions(o3d.core.Tensor.from_numpy(rays),
                                         tnear=0.0, tfar=1.0, nthreads=self.threads)
        return out.numpy()

    @staticmethod
    def prim_ids(out):
        ids = out["primitive_ids"].astype(np.int64)
        ids[ids == O3D_INVALID] = -1
        return ids


class Embreex:
    name = "embreex"

    def __init__(self, scene_name, vertices, triangles, threads):
        self.scene = EmbreeScene(robust=True)  # embreex's default, and Open3D's flag
        self.mesh = EmbreeTriangleMesh(self.scene, vertices, triangles.astype(np.int32))
        self.threads = threads
        self.pool = ThreadPoolExecutor(threads) if threads > 1 else None
        # The first run() commits the scene: do it here, not from several threads.
        self.scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32))

    def _run(self, origins, directions, dists, **kw):
        """run() on chunks of rays on the pool's threads (it releases the GIL)."""
        if self.pool is None:
            return [self.scene.run(origins, directions, dists, **kw)]
        parts = EMBREEX_CHUNKS_PER_THREAD * self.threads
        chunks = zip(np.array_split(origins, parts), np.array_split(directions, parts),
                     np.array_split(dists, parts))
        return list(self.pool.map(lambda c: self.scene.run(*c, **kw), chunks))

    def closest(self, r):
        dists = np.full(len(r), np.inf, np.float32)  # run() writes the hit t into it
        outs = self._run(r.origins, r.directions, dists, query="INTERSECT", output=1)
        if len(outs) == 1:
            return outs[0]
        return {key: np.concatenate([o[key] for o in outs]) for key in outs[0]}

    def occluded(self, r):
        outs = self._run(r.origins, r.directions, r.t_max, query="OCCLUDED")
        return np.concatenate(outs) == 0  # 0: occluded, -1: not

    @staticmethod
    def prim_ids(out):
        return out["primID"].astype(np.int64)  # -1 for a miss

    def close(self):
        if self.pool is not None:
            self.pool.shutdown()


# ----------------------------------------------------------------------------- measuring

def trace(tracer, rays, closest):
    return tracer.closest(rays) if closest else tracer.occluded(rays)


def answers(tracer, result, closest):
    """What the agreement check compares: primitive ids (-1: miss) or occluded flags."""
    return tracer.prim_ids(result) if closest else np.asarray(result, bool)


def measure(tracers, rays, closest, repeat):
    """Median seconds per tracer over `repeat` rounds after a warm-up, and the warm-up
    answers. The tracers take turns within a round; the order rotates each round."""
    warm = {t.name: answers(t, trace(t, rays, closest), closest) for t in tracers}
    times = {t.name: [] for t in tracers}
    for rnd in range(repeat):
        k = rnd % len(tracers)
        for t in tracers[k:] + tracers[:k]:
            start = time.perf_counter()
            trace(t, rays, closest)
            times[t.name].append(time.perf_counter() - start)
    return {name: statistics.median(ts) for name, ts in times.items()}, warm


def run_scene(scene, ray_sets, args, rays_dir):
    """Rows of the table for one scene."""
    vertices, triangles = read_obj(SCENES / scene / f"{scene}.obj")
    log(f"{scene}: {len(triangles):,} triangles")
    kinds = [Raypack, Open3D] + ([Embreex] if EmbreeScene else [])
    tracers = [kind(scene, vertices, triangles, args.threads) for kind in kinds]
    rows = []
    for ray_set in ray_sets:
        rays = read_rays(ray_file(rays_dir, scene, ray_set))
        closest = CLOSEST[ray_set]
        check_rays(rays, closest)
        seconds, warm = measure(tracers, rays, closest, args.repeat)
        row = {"scene": scene, "set": ray_set, "rays": len(rays)}
        # The tree that answered raypack's last call (with accel="auto", its race's winner).
        row["tree"] = tracers[0].scene.last_accel[0 if closest else 1]
        for t in tracers:
            row[t.name] = len(rays) / seconds[t.name] / 1e6
            same = warm[t.name] == warm["raypack"]
            row[f"agree {t.name}"] = (float(np.mean(same)), int(np.sum(~same)))
        log(format_row(row))
        rows.append(row)
    for t in tracers:
        if hasattr(t, "close"):
            t.close()
    return rows


# ----------------------------------------------------------------------------- output

def agreement(fraction_and_differing):
    fraction, differing = fraction_and_differing
    return f"{100 * fraction:.3f}% ({differing:,} differ)"


def format_row(row):
    parts = [f"{row['scene']} {row['set']}: {row['rays']:,} rays, raypack tree {row['tree']}"]
    for name in ("raypack", "Open3D", "embreex"):
        if name in row:
            parts.append(f"{name} {row[name]:.2f} Mrays/s")
    parts.append(f"agree with Open3D {agreement(row['agree Open3D'])}")
    if "embreex" in row:
        parts.append(f"with embreex {agreement(row['agree embreex'])}")
    return ", ".join(parts)


# The package's aim: raypack at least this many times Open3D's rate, per set.
TARGET = {"primary": 2.0, "shadow": 2.0, "diffuse": 1.2}


def verdict(rows):
    """Which rows reach TARGET over Open3D, and which do not."""
    met = [r for r in rows if r["raypack"] / r["Open3D"] >= TARGET.get(r["set"], 0)]
    missed = [r for r in rows if r not in met]
    name = lambda r: f"{r['scene']} {r['set']} {r['raypack'] / r['Open3D']:.2f}"
    aim = ", ".join(f"{k} {v:g}x" for k, v in TARGET.items())
    lines = [f"Aim, over Open3D: {aim}. Reached by {len(met)} of {len(rows)} rows"
             + (f": {'; '.join(map(name, met))}." if met else ".")]
    if missed:
        lines.append(f"Not reached: {'; '.join(map(name, missed))}.")
    return "\n".join(lines)


def table(rows):
    embreex = any("embreex" in r for r in rows)
    head = ["scene", "set", "rays", "raypack tree", "raypack Mrays/s", "Open3D Mrays/s",
            "raypack / Open3D"]
    if embreex:
        head += ["embreex Mrays/s", "raypack / embreex"]
    head += ["agree with Open3D"] + (["agree with embreex"] if embreex else [])
    lines = ["| " + " | ".join(head) + " |",
             "| --- | --- | ---: | --- | " + " | ".join(["---:"] * (len(head) - 4)) + " |"]
    for r in rows:
        cells = [r["scene"], r["set"], f"{r['rays']:,}", r["tree"], f"{r['raypack']:.2f}",
                 f"{r['Open3D']:.2f}", f"**{r['raypack'] / r['Open3D']:.2f}**"]
        if embreex:
            cells += [f"{r['embreex']:.2f}", f"**{r['raypack'] / r['embreex']:.2f}**"]
        cells.append(agreement(r["agree Open3D"]))
        if embreex:
            cells.append(agreement(r["agree embreex"]))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def version(package):
    try:
        return importlib.metadata.version(package)
    except importlib.metadata.PackageNotFoundError:
        return "not installed"


def page(rows, args):
    # The ray folder is a cache: the command reproduces the page without it.
    argv, skip = [], False
    for a in sys.argv[1:]:
        if skip or a.startswith("--rays-dir"):
            skip = a == "--rays-dir"
            continue
        argv.append(a)
    command = shlex.join(["python3", "perf/python_vs_open3d.py", *argv])
    embreex = (f"embreex {version('embreex')}" if EmbreeScene
               else f"embreex not measured ({EMBREEX_MISSING})")
    now = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    return f"""# raypack from Python beside Open3D and embreex

This page is generated by `perf/python_vs_open3d.py`; run it again rather than editing it.

- Date: {now}
- CPU: {cpu_description()[0]}, {os.cpu_count()} logical cores; raypack kernels: `{raypack.isa()}`
- Threads: {args.threads} for every library; {args.repeat} timed round(s) after a warm-up; \
raypack mode `{args.mode}`, accelerator `{args.accel}`
- Versions: raypack {version('raypack')}, open3d {version('open3d')}, {embreex}, \
numpy {np.__version__}, Python {sys.version.split()[0]}
- 1-minute load average at the end: {os.getloadavg()[0]:.2f}

Reproduce (from the repository, after `pip install ./python` into a Python with open3d and embreex):

    {command}

Mrays/s, median over the rounds; the ratios are raypack's rate over the peer's. *Agree*:
the fraction of rays on which the peer's answer is raypack's: the same primitive or both
a miss (closest hits), or the same occluded flag (shadow rays). Ties between triangles
and rays grazing an edge may differ.

{table(rows)}

{verdict(rows)}

## What is timed

One call per library, from the numpy arrays a user holds (float32 origins and directions
of shape (n, 3), t_min and t_max of shape (n,), read from the ray file beforehand) to
numpy answers, so building the arrays each library wants is part of its time:

- raypack: `scene.intersect(o, d, t_min, t_max, threads=T, mode="{args.mode}")` for closest
  hits (t, prim, u, v, normal), `scene.occluded(o, d, t_min, t_max, threads=T,
  mode="{args.mode}")` for shadow rays.
- Open3D {version('open3d')} `RaycastingScene`: `cast_rays(Tensor.from_numpy(np.hstack([o, d])),
  nthreads=T)` and `.numpy()` of its five outputs (t_hit, geometry_ids, primitive_ids,
  primitive_uvs, primitive_normals). `cast_rays` takes no tnear/tfar: it traces [0, inf),
  which is what the closest-hit sets ask (the script checks that t_min = 0 and t_max =
  inf). Shadow rays: `test_occlusions(rays, tnear=0.0, tfar=1.0, nthreads=T)`, where
  `rays` is `np.hstack([o, d * t_max[:, None]])`: the API takes one tfar for all rays,
  so each direction is scaled by its own t_max (timed too).
- embreex: `EmbreeScene.run(o, d, dists, query="INTERSECT", output=1)` (u, v, Ng, tfar,
  primID, geomID), `dists` a fresh array of inf that `run` writes the hit distances into,
  and `run(o, d, t_max, query="OCCLUDED")` (0 where occluded, turned into booleans).
  `run` traces one ray at a time (`rtcIntersect1`/`rtcOccluded1`) with the GIL released
  and has no thread option, so with T > 1 the rays go in {EMBREEX_CHUNKS_PER_THREAD} x T chunks to a
  pool of T Python threads and the answers are concatenated (all timed). Its tnear is
  always 0, its tfar per ray.

Not timed: reading the OBJ and building each library's acceleration structure (raypack:
its accelerator from `raypack.Scene.load(name, accel="{args.accel}")`; Open3D and embreex: Embree's BVH, built
at the first query, which the warm-up call makes). Both peers build with Embree's ROBUST
scene flag. The peers get the triangles of the OBJ in raypack's order (faces in file
order, fan-triangulated), so primitive ids compare one to one.

*raypack tree*: the tree that answered raypack's calls. With `accel="auto"` the scene holds
the kd-tree and the BVH, and the first call of each kind (closest hits or any hit, and the
mode its rays take) races them: each traces the same 4,096 of the call's rays (16,384
of a call of 262,144 or more; runs of 256 spread over the call) once to warm up and
twice timed on one thread (turns A, B, then A, B, B, A), and the faster answers this
call and the next 15 of its kind, when it races again. Here the race falls in the
warm-up call, which is not timed; in a call that races it adds those rays traced six
times on one thread.
"""


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", default="sponza,conference,bunny")
    ap.add_argument("--sets", default=",".join(SETS))
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=5, help="timed rounds after a warm-up")
    ap.add_argument("--mode", default="auto", choices=raypack.MODES,
                    help="raypack's kernels (default stream, the mode for rays in any order)")
    ap.add_argument("--accel", default="auto", choices=("auto", "kdtree", "bvh8"),
                    help="the tree raypack's queries walk (the same answers either way)")
    ap.add_argument("--rays-dir", help="folder to keep the .rays files in and reuse them from")
    ap.add_argument("--quick", action="store_true", help="bunny only, one round")
    ap.add_argument("--write", metavar="PAGE",
                    help="also write a Markdown page, e.g. perf/python.md")
    args = ap.parse_args()
    if args.quick:
        args.scenes, args.repeat = "bunny", 1
    args.scenes = [s for s in args.scenes.split(",") if s]
    args.sets = [s for s in args.sets.split(",") if s]
    bad = [s for s in args.sets if s not in SETS]
    if bad or args.threads < 1 or args.repeat < 1:
        ap.error(f"sets are {', '.join(SETS)}; --threads and --repeat must be >= 1")
    return args


def main():
    args = parse_args()
    Raypack.mode = args.mode
    Raypack.accel = args.accel
    os.environ.setdefault("RAYPACK_SCENES", str(SCENES))  # for raypack.Scene.load(name)
    if EMBREEX_MISSING:
        log(f"embreex not measured: {EMBREEX_MISSING}")
    with tempfile.TemporaryDirectory(prefix="raypack-rays-") as tmp:
        rays_dir = Path(args.rays_dir or tmp)
        rays_dir.mkdir(parents=True, exist_ok=True)
        rows = [row for scene in args.scenes for row in run_scene(scene, args.sets, args, rays_dir)]
    print(table(rows))
    if args.write:
        Path(args.write).write_text(page(rows, args))
        log(f"wrote {args.write}")


if __name__ == "__main__":
    main()
