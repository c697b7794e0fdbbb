"""raypack from Python: numpy rays in, numpy hits out.

raypack traces rays through a SAH kd-tree with SIMD kernels compiled for SSE2, AVX2 and
AVX-512 in one binary (the widest the CPU runs is chosen at import; ``raypack.isa()``
says which). Every answer is bit for bit the one the Rust library gives, on any number of
threads, in every mode.

    >>> import numpy as np, raypack
    >>> scene = raypack.Scene(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32),
    ...                       np.array([[0, 1, 2]]))
    >>> hits = scene.intersect(np.array([[0.2, 0.2, 1.0]]), np.array([[0.0, 0.0, -1.0]]))
    >>> float(hits.t[0]), int(hits.prim[0])
    (1.0, 0)

Calls that trace release the GIL and run on every core (or ``threads=`` of them).
Bad input raises :class:`raypack.Error`, a ``ValueError`` whose message names the
entry, file or field.
"""

from __future__ import annotations

import math
from typing import NamedTuple, Optional, Sequence, Tuple, Union

import numpy as np

from . import _raypack
from ._raypack import Error

__all__ = ["Error", "Hits", "Scene", "isa", "render", "MODES", "INTEGRATORS", "SAMPLERS", "MAX_GI_SPP"]

#: How rays are handed to the kernels. ``stream`` (one ray per SIMD lane, each on its
#: own walk) suits rays in any order; ``packet`` (the widest packet the CPU runs),
#: ``packet4``/``packet8``/``packet16`` and ``tile64`` suit coherent rays in image order
#: (neighbours in the array are neighbours in space); ``scalar`` is the reference.
#: ``auto``, the default, looks at each chunk of 4096 rays and takes ``packet`` where
#: most groups of neighbouring rays start close together and point the same way (camera
#: rays, shadow rays toward one light), else ``stream``. Every mode gives the same
#: answers.
MODES = ("auto", "stream", "packet", "packet4", "packet8", "packet16", "tile64", "scalar")

#: The renderers of :func:`render`.
INTEGRATORS = ("whitted", "path", "photon")

#: How ``path`` and ``photon`` draw each sample's numbers (:func:`render`'s ``sampler``).
SAMPLERS = ("sobol", "independent")

ArrayLike = Union[np.ndarray, Sequence]


class Hits(NamedTuple):
    """Closest hits, one entry per ray, shaped like the rays' leading dimensions.

    A miss has ``t = inf``, ``prim = -1``, ``u = v = 0`` and a zero normal.
    """

    #: Distance along the ray, in units of the direction's length (``inf``: a miss).
    t: np.ndarray
    #: Triangle index (int64; ``-1``: a miss). For a loaded scene, the primitive id.
    prim: np.ndarray
    #: Barycentric coordinate of the hit toward the triangle's second vertex.
    u: np.ndarray
    #: Barycentric coordinate toward the third vertex: the hit is
    #: ``(1 - u - v) * v0 + u * v1 + v * v2``.
    v: np.ndarray
    #: Unit geometric normal ``normalize(cross(v1 - v0, v2 - v0))``, not flipped toward
    #: the ray; shape ``(..., 3)``.
    normal: np.ndarray

    @property
    def hit(self) -> np.ndarray:
        """``True`` where the ray hit something."""
        return self.prim >= 0


def isa() -> str:
    """The instruction set the kernels run: ``"sse"``, ``"avx2"`` or ``"avx512"``.

    The widest the CPU runs, unless the environment variable ``RAYPACK_ISA`` forces a
    lower one.
    """
    return _raypack.isa()


def _threads(threads: Optional[int]) -> int:
    if threads is None:
        return 0
    if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or threads < 1:
        raise ValueError(f"threads must be a positive integer or None, not {threads!r}")
    return int(threads)


def _mode(mode: str) -> str:
    if mode not in MODES:
        raise ValueError(f"mode must be one of {', '.join(MODES)}, not {mode!r}")
    return mode


def _to_f32(arr: np.ndarray, what: str) -> np.ndarray:
    """``arr`` rounded to float32, the precision raypack traces in; a finite value that
    float32 cannot hold is an :class:`Error` naming its entry (``what`` names a row)."""
    with np.errstate(over="ignore", invalid="ignore"):
        out = np.ascontiguousarray(arr, dtype=np.float32)
    if arr.dtype.kind == "f" and arr.dtype.itemsize > 4:
        lost = np.isinf(out) & np.isfinite(arr)
        if lost.any():
            i = np.argwhere(lost)[0]
            where = f"{what} {i[0]}" + (f": {'xyz'[i[1]]}" if len(i) > 1 else "")
            raise Error(f"{where} is {float(arr[tuple(i)])!r}, beyond float32's range (raypack traces in float32)")
    return out


def _rows(name: str, a: ArrayLike) -> np.ndarray:
    """``a`` as an array of real numbers of shape ``(..., 3)``, or a ``ValueError``."""
    arr = np.asarray(a)
    if arr.dtype.kind not in "fiu":
        raise ValueError(f"{name}: expected a float array, got dtype {arr.dtype}")
    if arr.ndim < 1 or arr.shape[-1] != 3:
        raise ValueError(f"{name}: expected shape (..., 3), got {arr.shape}")
    return arr


def _limits(name: str, t: Union[float, ArrayLike], lead: Tuple[int, ...]) -> np.ndarray:
    """``t`` as a float32 array of one value or one per ray."""
    arr = np.asarray(t)
    if arr.dtype.kind not in "fiu":
        raise ValueError(f"{name}: expected a number or a float array, got dtype {arr.dtype}")
    if arr.ndim == 0:
        return np.full(1, arr, dtype=np.float32)
    if arr.shape != lead:
        raise ValueError(f"{name}: expected a number or shape {lead}, got {arr.shape}")
    return _to_f32(arr.reshape(-1), f"{name}: ray")


def _vec3(name: str, v: ArrayLike) -> list:
    arr = np.asarray(v, dtype=np.float64)
    if arr.shape != (3,):
        raise ValueError(f"{name}: expected three numbers, got shape {arr.shape}")
    return arr.tolist()


def _size(name: str, n: int) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"{name} must be a positive integer, not {n!r}")
    return int(n)


def _hits(raw, lead: Tuple[int, ...]) -> Hits:
    t, prim, u, v, normal = raw
    return Hits(
        t.reshape(lead), prim.reshape(lead), u.reshape(lead), v.reshape(lead),
        normal.reshape(lead + (3,)),
    )


def _accel(accel: str) -> str:
    if accel not in ("auto", "kdtree", "bvh8"):
        raise ValueError(f'accel must be "auto", "kdtree" or "bvh8", not {accel!r}')
    return accel


class Scene:
    """Triangles (or a loaded scene) and the accelerator built over them.

    ``Scene(vertices, triangles)`` takes an ``(n, 3)`` float array of vertices (float32
    or float64; float64 is rounded to float32, the precision raypack traces in) and an
    ``(m, 3)`` integer array of vertex indices; triangle ``j`` is primitive ``j``.
    Coordinates must be finite and indices in ``range(n)``, or :class:`Error` names the
    first that is not. The tree is built on ``threads`` workers (``None``: every core).

    ``accel`` picks the tree the queries walk; every choice gives the same answers, bit
    for bit. ``"kdtree"`` (the SAH kd-tree) is usually fastest in interiors, on
    overlapping triangles and on small scenes; ``"bvh8"`` (an 8-wide BVH) on isolated
    models, terrain and scenes of many objects in empty space (perf/README.md in the
    repository), but which one wins also depends on the rays and the CPU. ``"auto"``
    (the default) builds both, at the cost of both trees' memory and build time. A
    query of 65,536 rays or more goes to the tree that won the last race of its kind
    (closest hits or any hit, and the mode its rays take); the first such query of a
    kind, and every 16th after it, runs the race: each tree traces the same 4,096 of its
    rays (16,384 of a query of 262,144 or more), one 16x16 tile's worth at a time spread
    over the query, once to warm up and twice timed on one thread (in turns A, B, then
    A, B, B, A), and the faster answers. A smaller query goes to the last winner of its
    query (:attr:`last_accel`). :func:`render` always walks the kd-tree; a ``"bvh8"``
    scene builds it at its first render.
    """

    def __init__(
        self,
        vertices: ArrayLike,
        triangles: ArrayLike,
        *,
        threads: Optional[int] = None,
        accel: str = "auto",
    ):
        v = np.asarray(vertices)
        t = np.asarray(triangles)
        if v.dtype.kind not in "fiu":
            raise ValueError(f"vertices: expected a float32 or float64 array, got dtype {v.dtype}")
        if t.dtype.kind not in "iu":
            raise ValueError(f"triangles: expected an integer array, got dtype {t.dtype}")
        if v.ndim != 2 or v.shape[1] != 3:
            raise ValueError(f"vertices: expected shape (n, 3), got {v.shape}")
        if t.ndim != 2 or t.shape[1] != 3:
            raise ValueError(f"triangles: expected shape (m, 3), got {t.shape}")
        if t.dtype == np.uint64 and t.size and t.max() > np.iinfo(np.int64).max:
            raise Error(f"triangles: index {t.max()} is out of range for {len(v)} vertices")
        self._scene = _raypack.Scene.from_arrays(
            _to_f32(v, "vertex"),
            np.ascontiguousarray(t, dtype=np.int64),
            _threads(threads),
            _accel(accel),
        )

    @classmethod
    def load(
        cls, scene: str, *, threads: Optional[int] = None, accel: str = "auto"
    ) -> "Scene":
        """A scene as the ``raypack`` command reads one: an OBJ mesh (``.obj``), a scene
        file (``.toml``, its spheres, boxes and planes included), the name of a
        benchmark scene of ``cameras.toml`` (``"sponza"``, ``"bunny"``, ...; found in
        ``$RAYPACK_SCENES`` or ``../shared/scenes``) or a generated scene
        (``"spd:balls:3"``). Its camera is the one it comes with. ``threads`` and
        ``accel`` as for ``Scene(...)``."""
        if not isinstance(scene, str):
            scene = str(scene)
        self = cls.__new__(cls)
        self._scene = _raypack.Scene.load(scene, _threads(threads), _accel(accel))
        self._name = scene
        return self

    @property
    def accel(self) -> str:
        """The tree the queries walk: ``"auto"``, ``"kdtree"`` or ``"bvh8"``."""
        return self._scene.accel

    @property
    def last_accel(self) -> Tuple[str, str]:
        """The tree (``"kdtree"`` or ``"bvh8"``) that answered the last query of each
        kind, ``(closest hits, any hit)``: with ``accel="auto"``, the winner of the last
        race (the BVH before any); else the scene's one tree."""
        return self._scene.last_accel

    @property
    def triangle_count(self) -> int:
        """How many triangles the scene has."""
        return self._scene.triangle_count

    @property
    def primitive_count(self) -> int:
        """Primitives of every kind (a scene file's spheres, boxes and planes too)."""
        return self._scene.primitive_count

    @property
    def bounds(self) -> Tuple[np.ndarray, np.ndarray]:
        """``(min, max)`` corners of the bounded primitives."""
        lo, hi = self._scene.bounds
        return np.array(lo, dtype=np.float32), np.array(hi, dtype=np.float32)

    @property
    def camera(self) -> dict:
        """The scene's camera: ``eye``, ``target``, ``up`` and ``vfov`` (degrees). A
        loaded benchmark scene or scene file brings its own; a mesh gets one that frames
        its bounds."""
        eye, target, up, vfov = self._scene.camera
        return {"eye": eye, "target": target, "up": up, "vfov": vfov}

    @property
    def warnings(self) -> list:
        """What the loader warned about (degenerate triangles, say)."""
        return self._scene.warnings

    def _rays(self, origins, directions, t_min, t_max):
        o, d = _rows("origins", origins), _rows("directions", directions)
        if o.shape != d.shape:
            # One origin for many directions (a camera), or one direction for many
            # origins (a sun): numpy's broadcasting.
            try:
                o, d = np.broadcast_arrays(o, d)
            except ValueError:
                raise ValueError(f"origins has shape {o.shape} and directions {d.shape}") from None
        lead = o.shape[:-1]
        o = _to_f32(o.reshape(-1, 3), "origins: ray")
        d = _to_f32(d.reshape(-1, 3), "directions: ray")
        return o, d, _limits("t_min", t_min, lead), _limits("t_max", t_max, lead), lead

    def intersect(
        self,
        origins: ArrayLike,
        directions: ArrayLike,
        t_min: Union[float, ArrayLike] = 0.0,
        t_max: Union[float, ArrayLike] = math.inf,
        *,
        threads: Optional[int] = None,
        mode: str = "auto",
    ) -> Hits:
        """Closest hit of each ray ``origins[i] + t * directions[i]``,
        ``t_min < t < t_max``.

        ``origins`` and ``directions`` have shape ``(..., 3)`` (float32, or float64
        rounded to float32; one broadcasts against the other, numpy's way); directions need not be unit length (``t`` is in units of
        their length). ``t_min``/``t_max`` are one number or one per ray. Values must be
        finite (``t_max`` may be ``inf``); a zero direction is allowed and misses.
        The answers have the rays' leading shape. ``mode`` picks the kernels
        (:data:`MODES`); all give the same answers.
        """
        o, d, t0, t1, lead = self._rays(origins, directions, t_min, t_max)
        raw = self._scene.intersect(o, d, t0, t1, _threads(threads), _mode(mode))
        return _hits(raw, lead)

    def occluded(
        self,
        origins: ArrayLike,
        directions: ArrayLike,
        t_min: Union[float, ArrayLike] = 0.0,
        t_max: Union[float, ArrayLike] = math.inf,
        *,
        threads: Optional[int] = None,
        mode: str = "auto",
    ) -> np.ndarray:
        """``True`` where anything lies on the ray between ``t_min`` and ``t_max``
        (shadow rays): a bool array of the rays' leading shape. Arguments as
        :meth:`intersect`."""
        o, d, t0, t1, lead = self._rays(origins, directions, t_min, t_max)
        return self._scene.occluded(o, d, t0, t1, _threads(threads), _mode(mode)).reshape(lead)

    def _view(self, eye, target, up, vfov):
        cam = self.camera
        return (
            _vec3("eye", cam["eye"] if eye is None else eye),
            _vec3("target", cam["target"] if target is None else target),
            _vec3("up", cam["up"] if up is None else up),
            float(cam["vfov"] if vfov is None else vfov),
        )

    def camera_rays(
        self,
        eye: Optional[ArrayLike] = None,
        target: Optional[ArrayLike] = None,
        up: Optional[ArrayLike] = None,
        vfov: Optional[float] = None,
        width: int = 1024,
        height: int = 768,
    ) -> Tuple[np.ndarray, np.ndarray]:
        """The pinhole camera's rays through the pixel centres: ``(origins,
        directions)``, each float32 of shape ``(height, width, 3)``, row ``0`` at the
        top. The camera convention is RAYS.md's (``vfov`` in degrees, edge to edge
        vertically); eye, target, up and vfov default to :attr:`camera`."""
        view = self._view(eye, target, up, vfov)
        w, h = _size("width", width), _size("height", height)
        o, d = self._scene.camera_rays(*view, w, h)
        return o.reshape(h, w, 3), d.reshape(h, w, 3)

    def trace_image(
        self,
        eye: Optional[ArrayLike] = None,
        target: Optional[ArrayLike] = None,
        up: Optional[ArrayLike] = None,
        vfov: Optional[float] = None,
        width: int = 1024,
        height: int = 768,
        *,
        threads: Optional[int] = None,
        mode: str = "packet",
    ) -> Hits:
        """Closest hits of :meth:`camera_rays`, shaped ``(height, width)``, traced as
        an image: packets and tiles take blocks of neighbouring pixels, the fast way to
        trace coherent camera rays. The answers are :meth:`intersect`'s of the same rays,
        bit for bit. With ``accel="auto"`` every call races the trees on a sample of
        the image's rays (see :class:`Scene`)."""
        view = self._view(eye, target, up, vfov)
        w, h = _size("width", width), _size("height", height)
        raw = self._scene.trace_image(*view, w, h, _threads(threads), _mode(mode))
        return _hits(raw, (h, w))

    def __repr__(self) -> str:
        return f"raypack.Scene({self.triangle_count} triangles, {self.primitive_count} primitives)"


def render(
    scene: Scene,
    width: Optional[int] = None,
    height: Optional[int] = None,
    spp: Optional[int] = None,
    integrator: str = "whitted",
    *,
    eye: Optional[ArrayLike] = None,
    target: Optional[ArrayLike] = None,
    up: Optional[ArrayLike] = None,
    vfov: Optional[float] = None,
    sky: Optional[Union[float, ArrayLike]] = None,
    seed: Optional[int] = None,
    photons: int = 200_000,
    max_bounces: Optional[int] = None,
    threads: Optional[int] = None,
    mode: str = "packet",
    sampler: str = "sobol",
) -> np.ndarray:
    """Renders ``scene`` as ``raypack render`` does and returns the linear radiance,
    a float32 array of shape ``(height, width, 3)``, row ``0`` at the top; the same
    bits as the command line's PFM or EXR output of the same scene and options.

    ``integrator`` is ``"whitted"`` (the tutorial's ray tracer: ``spp`` a square, 1 to
    256), ``"path"`` (path tracing) or ``"photon"`` (photon mapping with final
    gathering, ``photons`` shot); the last two take ``spp`` from 1 to
    ``raypack.MAX_GI_SPP`` (default 16). The size defaults to the scene's (1024x768 for
    a mesh), the camera to :attr:`Scene.camera`. A mesh is lit as the command line lights
    it: its emissive materials, else a key and a fill light for ``whitted`` and a uniform
    sky of radiance 1 for ``path`` and ``photon`` (``sky``, one value or RGB, sets
    another). ``sampler`` is how ``path`` and ``photon`` draw each sample's numbers:
    ``"sobol"`` (Owen-scrambled Sobol points, the default) or ``"independent"``. The
    image depends on the scene, the options and ``seed``, never on ``threads`` or
    ``mode``.
    """
    if not isinstance(scene, Scene):
        raise ValueError(f"scene: expected a raypack.Scene, got {type(scene).__name__}")
    if integrator not in INTEGRATORS:
        raise ValueError(f"integrator must be one of {', '.join(INTEGRATORS)}, not {integrator!r}")
    if max_bounces is not None and integrator != "path":
        raise ValueError("max_bounces applies to integrator='path' only")
    if sampler not in SAMPLERS:
        raise ValueError(f"sampler must be one of {', '.join(SAMPLERS)}, not {sampler!r}")
    if sampler != "sobol" and integrator == "whitted":
        raise ValueError("sampler applies to integrator='path' and 'photon' only")
    camera = None
    if any(x is not None for x in (eye, target, up, vfov)):
        camera = scene._view(eye, target, up, vfov)
    sky_rgb = None
    if sky is not None:
        arr = np.asarray(sky, dtype=np.float64)
        if arr.shape == ():
            arr = np.full(3, arr)
        if arr.shape != (3,):
            raise ValueError(f"sky: expected one value or three, got shape {arr.shape}")
        sky_rgb = arr.tolist()
    return _raypack.render(
        scene._scene,
        None if width is None else _size("width", width),
        None if height is None else _size("height", height),
        None if spp is None else _size("spp", spp),
        integrator,
        camera,
        sky_rgb,
        None if seed is None else _seed(seed),
        _threads(threads),
        _mode(mode),
        _size("photons", photons),
        None if max_bounces is None else _count("max_bounces", max_bounces),
        sampler,
    )


def _seed(seed: int) -> int:
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < 2**64:
        raise ValueError(f"seed must be an integer in [0, 2**64), not {seed!r}")
    return int(seed)


def _count(name: str, n: int) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
        raise ValueError(f"{name} must be a non-negative integer, not {n!r}")
    return int(n)


#: The most samples per pixel of the path and photon integrators.
MAX_GI_SPP: int = _raypack.MAX_GI_SPP
