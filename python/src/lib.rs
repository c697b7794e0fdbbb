//! `raypack._raypack`: the compiled half of the Python package. It takes arrays that the
//! Python half (`raypack/__init__.py`) has already given their dtype, layout and shape,
//! checks their values through the library, and traces with the GIL released on rayon's
//! pool. Everything a user reads (docstrings, type hints, argument handling) is in the
//! Python half; this file only moves numbers.

use numpy::prelude::*;
use numpy::{PyArray1, PyArray2, PyArray3, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rayon::prelude::*;
use raypack::accel::bvh::Bvh;
use raypack::accel::kdtree::KdTree;
use raypack::accel::{Accel, BATCH_RAYS, Mode};
use raypack::geom::Geometry;
use raypack::glam::{DVec3, Vec3};
use raypack::ray::{Hit, Ray};
use raypack::rayset::trace::Query;
use raypack::rayset::{standard, trace};
use raypack::render::gi::{GiScene, render_gi};
use raypack::render::path::PathTracer;
use raypack::render::photon::{PhotonMapper, PhotonSettings};
use raypack::render::sample::SamplerKind;
use raypack::render::tiles;
use raypack::scene::catalog;
use raypack::scene::file::MAX_PIXELS;
use raypack::scene::{Camera, View};
use raypack::simd::Isa;
use raypack::studio::{self, MAX_GI_SPP, Source, Staged, StudioError};
use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

create_exception!(
    _raypack,
    Error,
    PyValueError,
    "Bad input to raypack: a mesh, ray array, scene file or camera it cannot use. The \
     message is the library's and names the entry, file or field."
);

/// The library's error as a Python exception (`raypack.Error`, a `ValueError`).
fn error(e: impl std::fmt::Display) -> PyErr {
    Error::new_err(e.to_string())
}

/// A scene (its geometry, materials, lights and camera) and the accelerator its rays
/// take, built once.
#[pyclass(module = "raypack._raypack", frozen)]
struct Scene {
    /// The scene as `raypack render` would render it; its `view` is the camera the
    /// scene came with (cameras.toml, a scene file) or one that frames it.
    staged: Staged,
    /// Why [`render`] refuses the scene (a generated `spd:` scene), if it does.
    not_renderable: Option<String>,
    /// The kd-tree: built with the scene when it answers the queries, else at the
    /// first render (the renderers walk the kd-tree).
    tree: OnceLock<KdTree>,
    /// The 8-wide BVH when the scene was made with `accel="bvh8"` or `"auto"`: it
    /// answers the queries (the same answers, bit for bit).
    bvh: Option<Bvh>,
    /// `accel="auto"`: the races' winners ([`Scene::pick`]).
    auto: Option<Mutex<Wins>>,
    /// The diagonal of the scene's bounds, the scale `auto` judges ray origins by.
    scale: f32,
    /// Each triangle's unit normal, bit for bit [`Geometry::geometric_normal`]'s, so
    /// that a hit's normal costs one read.
    triangle_normals: Vec<Vec3>,
}

/// `accel="auto"`'s record of its races: the winner (0 the kd-tree, 1 the BVH) and the
/// calls since the race, per query and mode, and the last winner per query.
#[derive(Default)]
struct Wins {
    by_kind: HashMap<(Query, Mode), (usize, u32)>,
    last: [usize; 2],
}

/// The rayon pool of `threads` workers (0: the global pool, one per core), kept for the
/// next call with the same count.
fn pool(threads: usize) -> PyResult<Option<Arc<rayon::ThreadPool>>> {
    if threads == 0 {
        return Ok(None);
    }
    static POOLS: OnceLock<Mutex<HashMap<usize, Arc<rayon::ThreadPool>>>> = OnceLock::new();
    let mut pools = POOLS.get_or_init(Default::default).lock().unwrap();
    if let Some(p) = pools.get(&threads) {
        return Ok(Some(p.clone()));
    }
    let p = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
    let p = Arc::new(p);
    pools.insert(threads, p.clone());
    Ok(Some(p))
}

/// Runs `f` on the pool of `threads` workers with the GIL released.
fn on_pool<R: Send>(py: Python<'_>, threads: usize, f: impl FnOnce() -> R + Send) -> PyResult<R> {
    let pool = pool(threads)?;
    Ok(py.detach(|| match pool {
        Some(p) => p.install(f),
        None => f(),
    }))
}

/// The rays of one call: origins and directions `(n, 3)`, `t_min` and `t_max` of length
/// `n` or 1 (one value for every ray). Checked for NaN and infinities before any work.
struct Rays<'a> {
    org: &'a [[f32; 3]],
    dir: &'a [[f32; 3]],
    t_min: &'a [f32],
    t_max: &'a [f32],
}

impl<'a> Rays<'a> {
    fn new(
        org: &'a PyReadonlyArray2<'_, f32>,
        dir: &'a PyReadonlyArray2<'_, f32>,
        t_min: &'a PyReadonlyArray1<'_, f32>,
        t_max: &'a PyReadonlyArray1<'_, f32>,
    ) -> PyResult<Rays<'a>> {
        let rays = Rays {
            org: rows(org)?,
            dir: rows(dir)?,
            t_min: t_min.as_slice()?,
            t_max: t_max.as_slice()?,
        };
        let n = rays.org.len();
        if rays.dir.len() != n {
            return Err(error(format!(
                "origins has {n} rays and directions {}",
                rays.dir.len()
            )));
        }
        for (name, t) in [("t_min", rays.t_min), ("t_max", rays.t_max)] {
            if t.len() != n && t.len() != 1 {
                return Err(error(format!(
                    "{name} has {} values for {n} rays (give one, or one per ray)",
                    t.len()
                )));
            }
        }
        Ok(rays)
    }

    fn len(&self) -> usize {
        self.org.len()
    }

    /// The error naming the first ray that breaks a rule of [`Rays::fill`]: finite
    /// origins and directions, `t_min` a number and `t_max` not NaN. Called once a chunk
    /// was found bad.
    fn bad_ray(&self) -> PyErr {
        let bad = (0..self.len()).into_par_iter().find_first(|&i| {
            let finite = |v: &[f32; 3]| v.iter().all(|x| x.is_finite());
            let (t0, t1) = self.t(i);
            !(finite(&self.org[i]) && finite(&self.dir[i]) && t0.is_finite() && !t1.is_nan())
        });
        let i = bad.expect("a chunk had a bad ray");
        let (t0, t1) = self.t(i);
        error(format!(
            "ray {i}: origin {:?}, direction {:?}, t_min {t0}, t_max {t1}: origins and \
             directions must be finite, t_min a finite number and t_max a number \
             (inf for no limit)",
            self.org[i], self.dir[i]
        ))
    }

    #[inline]
    fn t(&self, i: usize) -> (f32, f32) {
        let pick = |t: &[f32]| if t.len() == 1 { t[0] } else { t[i] };
        (pick(self.t_min), pick(self.t_max))
    }

    /// Rays `first..first + len` into `out`; false when one of them breaks a rule of
    /// [`Rays::bad_ray`] (checked here, on rays already in cache, not in a pass of its
    /// own).
    fn fill(&self, first: usize, out: &mut Vec<Ray>, len: usize) -> bool {
        out.clear();
        out.extend((first..first + len).map(|i| {
            let (t0, t1) = self.t(i);
            Ray::new(
                Vec3::from_array(self.org[i]),
                Vec3::from_array(self.dir[i]),
                t0,
                t1,
            )
        }));
        out.iter().fold(true, |ok, r| {
            ok & r.org.is_finite() & r.dir.is_finite() & r.t_min.is_finite() & !r.t_max.is_nan()
        })
    }
}

/// An `(n, 3)` C-contiguous array as rows.
fn rows<'a>(a: &'a PyReadonlyArray2<'_, f32>) -> PyResult<&'a [[f32; 3]]> {
    let flat = a.as_slice()?;
    if a.shape()[1] != 3 {
        return Err(error("expected an (n, 3) array"));
    }
    Ok(flat.as_chunks::<3>().0)
}

/// The per-ray outputs of `intersect`, in arrays the caller hands to numpy.
struct HitArrays {
    t: Vec<f32>,
    prim: Vec<i64>,
    u: Vec<f32>,
    v: Vec<f32>,
    normal: Vec<f32>,
}

/// Mutable views of one chunk of [`HitArrays`]' five arrays.
type HitChunk<'a> = (
    &'a mut [f32],
    &'a mut [i64],
    &'a mut [f32],
    &'a mut [f32],
    &'a mut [f32],
);

/// Ray origins and directions as two `(n, 3)` arrays.
type RayArrays<'py> = (Bound<'py, PyArray2<f32>>, Bound<'py, PyArray2<f32>>);

type HitTuple<'py> = (
    Bound<'py, PyArray1<f32>>,
    Bound<'py, PyArray1<i64>>,
    Bound<'py, PyArray1<f32>>,
    Bound<'py, PyArray1<f32>>,
    Bound<'py, PyArray2<f32>>,
);

impl HitArrays {
    /// Writes `hits` (of `rays`) into the arrays' chunk views.
    fn write(scene: &Scene, hits: &[Hit], rays: &[Ray], (t, prim, u, v, normal): HitChunk<'_>) {
        for (i, h) in hits.iter().enumerate() {
            t[i] = h.t;
            u[i] = h.u;
            v[i] = h.v;
            prim[i] = if h.is_hit() { h.prim as i64 } else { -1 };
        }
        // A miss keeps the zero normal the arrays start with ([`HitArrays::of`]).
        for ((h, r), n) in hits.iter().zip(rays).zip(normal.as_chunks_mut::<3>().0) {
            if h.is_hit() {
                *n = scene.normal(h.prim, r, h.t).to_array();
            }
        }
    }

    /// The answers for `n` rays, chunk by chunk: `trace(first, hits, rays)` fills a
    /// chunk's hits and its rays (for the normals), or fails on a bad chunk, which
    /// stops the work.
    fn of(
        scene: &Scene,
        n: usize,
        trace: impl Fn(usize, &mut [Hit], &mut Vec<Ray>) -> Result<(), BadChunk> + Sync,
    ) -> Result<HitArrays, BadChunk> {
        let mut out = HitArrays {
            t: vec![0.0; n],
            prim: vec![0; n],
            u: vec![0.0; n],
            v: vec![0.0; n],
            normal: vec![0.0; 3 * n],
        };
        let b = BATCH_RAYS;
        out.t
            .par_chunks_mut(b)
            .zip(out.prim.par_chunks_mut(b))
            .zip(out.u.par_chunks_mut(b))
            .zip(out.v.par_chunks_mut(b))
            .zip(out.normal.par_chunks_mut(3 * b))
            .enumerate()
            .try_for_each_init(
                || (Vec::with_capacity(b), vec![Hit::MISS; b]),
                |(rays, hits), (chunk, ((((t, prim), u), v), normal))| {
                    let hits = &mut hits[..t.len()];
                    trace(chunk * b, hits, rays)?;
                    HitArrays::write(scene, hits, rays, (t, prim, u, v, normal));
                    Ok(())
                },
            )?;
        Ok(out)
    }

    fn into_py(self, py: Python<'_>) -> PyResult<HitTuple<'_>> {
        let n = self.t.len();
        Ok((
            self.t.into_pyarray(py),
            self.prim.into_pyarray(py),
            self.u.into_pyarray(py),
            self.v.into_pyarray(py),
            self.normal.into_pyarray(py).reshape([n, 3])?,
        ))
    }
}

/// A mode by name; `auto` (`None`) lets each chunk's rays pick theirs
/// ([`trace::auto_mode`]).
fn parse_mode(mode: &str) -> PyResult<Option<Mode>> {
    match mode {
        "auto" => Ok(None),
        _ => mode.parse::<Mode>().map(Some).map_err(error),
    }
}

fn view_of(eye: [f64; 3], target: [f64; 3], up: [f64; 3], vfov: f64) -> View {
    View {
        eye: DVec3::from_array(eye),
        target: DVec3::from_array(target),
        up: DVec3::from_array(up),
        vfov_deg: vfov,
    }
}

#[pymethods]
impl Scene {
    /// A triangle mesh from `(n, 3)` float32 vertices and `(m, 3)` int64 indices.
    #[staticmethod]
    fn from_arrays(
        py: Python<'_>,
        vertices: PyReadonlyArray2<'_, f32>,
        triangles: PyReadonlyArray2<'_, i64>,
        threads: usize,
        accel: &str,
    ) -> PyResult<Scene> {
        let v = rows(&vertices)?;
        let flat = triangles.as_slice()?;
        if triangles.shape()[1] != 3 {
            return Err(error("triangles: expected an (m, 3) array"));
        }
        let t = flat.as_chunks::<3>().0;
        let geometry = Geometry::from_arrays(v, t).map_err(error)?;
        Scene::build(py, studio::mesh(geometry), None, threads, accel)
    }

    /// A scene file, an OBJ mesh, a benchmark scene's name or an `spd:` scene, as
    /// `raypack` reads them.
    #[staticmethod]
    fn load(py: Python<'_>, scene: &str, threads: usize, accel: &str) -> PyResult<Scene> {
        let loaded = py.detach(|| match studio::load(scene) {
            Err(StudioError::NotRenderable(why)) => {
                // Geometry only: traceable, not renderable.
                let s = catalog::load(scene)?;
                let mut staged = studio::mesh(s.geometry);
                staged.view = s.view;
                staged.scene.camera = Camera::from(&s.view);
                let why = StudioError::NotRenderable(why).to_string();
                Ok::<_, StudioError>((staged, Some(why)))
            }
            staged => Ok((staged?, None)),
        });
        let (staged, not_renderable) = loaded.map_err(error)?;
        Scene::build(py, staged, not_renderable, threads, accel)
    }

    /// The accelerator the queries take: "auto", "kdtree" or "bvh8".
    #[getter(accel)]
    fn accel_name(&self) -> &'static str {
        match (&self.bvh, &self.auto) {
            (_, Some(_)) => "auto",
            (Some(_), None) => "bvh8",
            (None, None) => "kdtree",
        }
    }

    /// The tree that answered the last query of each kind, `(closest, any hit)`:
    /// "kdtree" or "bvh8".
    #[getter]
    fn last_accel(&self) -> (&'static str, &'static str) {
        let name = |q: Query| match (&self.bvh, &self.auto) {
            (Some(_), Some(w))
                if w.lock()
                    .unwrap_or_else(std::sync::PoisonError::into_inner)
                    .last[q as usize]
                    == 0 =>
            {
                "kdtree"
            }
            (Some(_), _) => "bvh8",
            (None, _) => "kdtree",
        };
        (name(Query::Closest), name(Query::Occluded))
    }

    #[getter]
    fn triangle_count(&self) -> usize {
        self.geometry().triangles.len()
    }

    #[getter]
    fn primitive_count(&self) -> u32 {
        self.geometry().prim_count()
    }

    #[getter]
    fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        let b = self.geometry().bounds();
        (b.min.to_array(), b.max.to_array())
    }

    /// `(eye, target, up, vfov_deg)` of the scene's camera.
    #[getter]
    fn camera(&self) -> ([f64; 3], [f64; 3], [f64; 3], f64) {
        let v = &self.staged.view;
        (
            v.eye.to_array(),
            v.target.to_array(),
            v.up.to_array(),
            v.vfov_deg,
        )
    }

    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.staged
            .warnings
            .iter()
            .map(ToString::to_string)
            .collect()
    }

    /// Closest hits through the stream kernel (`mode` "stream") or any other mode.
    #[allow(clippy::too_many_arguments)]
    fn intersect<'py>(
        &self,
        py: Python<'py>,
        origins: PyReadonlyArray2<'py, f32>,
        directions: PyReadonlyArray2<'py, f32>,
        t_min: PyReadonlyArray1<'py, f32>,
        t_max: PyReadonlyArray1<'py, f32>,
        threads: usize,
        mode: &str,
    ) -> PyResult<HitTuple<'py>> {
        let mode = parse_mode(mode)?;
        let rays = Rays::new(&origins, &directions, &t_min, &t_max)?;
        let out = on_pool(py, threads, || {
            let accel = self.pick(&rays, Query::Closest, mode)?;
            HitArrays::of(self, rays.len(), |first, hits, buf| {
                let mode = self.chunk(&rays, mode, first, hits.len(), buf)?;
                trace::intersect_into(accel, buf, trace::Order::Any, mode, hits);
                Ok(())
            })
        })?;
        match out {
            Ok(out) => out.into_py(py),
            Err(BadChunk) => Err(rays.bad_ray()),
        }
    }

    /// Any-hit answers, `True` where something lies between `t_min` and `t_max`.
    #[allow(clippy::too_many_arguments)]
    fn occluded<'py>(
        &self,
        py: Python<'py>,
        origins: PyReadonlyArray2<'py, f32>,
        directions: PyReadonlyArray2<'py, f32>,
        t_min: PyReadonlyArray1<'py, f32>,
        t_max: PyReadonlyArray1<'py, f32>,
        threads: usize,
        mode: &str,
    ) -> PyResult<Bound<'py, PyArray1<bool>>> {
        let mode = parse_mode(mode)?;
        let rays = Rays::new(&origins, &directions, &t_min, &t_max)?;
        let out = on_pool(py, threads, || {
            let accel = self.pick(&rays, Query::Occluded, mode)?;
            let mut out = vec![false; rays.len()];
            out.par_chunks_mut(BATCH_RAYS)
                .enumerate()
                .try_for_each_init(
                    || Vec::with_capacity(BATCH_RAYS),
                    |buf, (chunk, occluded)| {
                        let first = chunk * BATCH_RAYS;
                        let mode = self.chunk(&rays, mode, first, occluded.len(), buf)?;
                        trace::occluded_into(accel, buf, trace::Order::Any, mode, occluded);
                        Ok(())
                    },
                )
                .map(|()| out)
        })?;
        match out {
            Ok(out) => Ok(out.into_pyarray(py)),
            Err(BadChunk) => Err(rays.bad_ray()),
        }
    }

    /// The camera rays of RAYS.md, row-major: `(origins, directions)`, each `(h * w, 3)`.
    #[allow(clippy::too_many_arguments)]
    fn camera_rays<'py>(
        &self,
        py: Python<'py>,
        eye: [f64; 3],
        target: [f64; 3],
        up: [f64; 3],
        vfov: f64,
        width: u32,
        height: u32,
    ) -> PyResult<RayArrays<'py>> {
        let view = view_of(eye, target, up, vfov);
        let (org, dir) = py
            .detach(|| {
                let rays = standard::camera_rays(&view, width, height)?;
                let org: Vec<f32> = rays
                    .par_iter()
                    .flat_map_iter(|r| r.org.to_array())
                    .collect();
                let dir: Vec<f32> = rays
                    .par_iter()
                    .flat_map_iter(|r| r.dir.to_array())
                    .collect();
                Ok::<_, raypack::rayset::RaySetError>((org, dir))
            })
            .map_err(error)?;
        let n = org.len() / 3;
        Ok((
            org.into_pyarray(py).reshape([n, 3])?,
            dir.into_pyarray(py).reshape([n, 3])?,
        ))
    }

    /// Closest hits of the camera rays, traced as an image in pixel blocks, row-major.
    #[allow(clippy::too_many_arguments)]
    fn trace_image<'py>(
        &self,
        py: Python<'py>,
        eye: [f64; 3],
        target: [f64; 3],
        up: [f64; 3],
        vfov: f64,
        width: u32,
        height: u32,
        threads: usize,
        mode: &str,
    ) -> PyResult<HitTuple<'py>> {
        let mode = parse_mode(mode)?.unwrap_or_else(Mode::native_packet);
        let view = view_of(eye, target, up, vfov);
        let out = on_pool(py, threads, || {
            let (rays, hits, pick) =
                trace::trace_image_faster(&self.accels(), &view, width, height, mode)?;
            if let Some(wins) = &self.auto {
                let mut w = wins
                    .lock()
                    .unwrap_or_else(std::sync::PoisonError::into_inner);
                w.last[Query::Closest as usize] = pick;
            }
            let out = HitArrays::of(self, hits.len(), |first, out, buf| {
                out.copy_from_slice(&hits[first..first + out.len()]);
                buf.clear();
                buf.extend_from_slice(&rays[first..first + out.len()]);
                Ok(())
            });
            Ok::<_, raypack::rayset::RaySetError>(out.expect("nothing stops an image"))
        })?
        .map_err(error)?;
        out.into_py(py)
    }
}

/// `accel="auto"` races the trees on queries of this many rays or more: the race traces
/// [`BATCH_RAYS`] of them (more of a larger query, `trace::race_rays`) six times (each
/// tree once to warm up, twice timed) on one thread, so below this it would cost more
/// than it could gain.
const RACE_MIN: usize = 16 * BATCH_RAYS;

/// `accel="auto"` races a kind of query again after this many calls (the first of
/// every run of this many), so that a winner follows rays whose kind changes.
const RERACE: u32 = 16;

/// A chunk of rays with a bad value: the work stops and [`Rays::bad_ray`] names it.
#[derive(Debug)]
struct BadChunk;

impl Scene {
    /// Rays `first..first + len` into `buf`, and the mode they are traced in: `mode`,
    /// or for `auto` (`None`) the one [`trace::auto_mode`] picks for them.
    fn chunk(
        &self,
        rays: &Rays,
        mode: Option<Mode>,
        first: usize,
        len: usize,
        buf: &mut Vec<Ray>,
    ) -> Result<Mode, BadChunk> {
        if !rays.fill(first, buf, len) {
            return Err(BadChunk);
        }
        Ok(mode.unwrap_or_else(|| trace::auto_mode(buf, self.scale)))
    }

    /// The geometric normal of a hit on `prim` at `t` along `ray`.
    #[inline]
    fn normal(&self, prim: u32, ray: &Ray, t: f32) -> Vec3 {
        match self.triangle_normals.get(prim as usize) {
            Some(n) => *n,
            None => self.geometry().geometric_normal(prim, ray.at(t)),
        }
    }

    fn geometry(&self) -> &Geometry {
        &self.staged.scene.geometry
    }

    fn build(
        py: Python<'_>,
        staged: Staged,
        not_renderable: Option<String>,
        threads: usize,
        accel: &str,
    ) -> PyResult<Scene> {
        let (kd, bvh, auto) = match accel {
            "kdtree" => (true, false, false),
            "bvh8" => (false, true, false),
            "auto" => (true, true, true),
            _ => {
                return Err(error(format!(
                    "accel {accel:?}: expected \"auto\", \"kdtree\" or \"bvh8\""
                )));
            }
        };
        let geometry = &staged.scene.geometry;
        let (tree, bvh, triangle_normals) = on_pool(py, threads, || {
            let tree = OnceLock::new();
            let (k, b) = rayon::join(
                || kd.then(|| KdTree::build(geometry)),
                || bvh.then(|| Bvh::build(geometry)),
            );
            if let Some(k) = k {
                let _ = tree.set(k);
            }
            (tree, b, geometry.triangle_normals())
        })?;
        Ok(Scene {
            triangle_normals,
            scale: geometry.bounds().diagonal(),
            staged,
            not_renderable,
            tree,
            bvh,
            auto: auto.then(|| {
                Mutex::new(Wins {
                    last: [1, 1],
                    ..Wins::default()
                })
            }),
        })
    }

    /// The kd-tree, built now if the scene was made without it.
    fn kd(&self) -> &KdTree {
        self.tree.get_or_init(|| KdTree::build(self.geometry()))
    }

    /// The trees a query may take: the one the scene was made with, or for `auto` the
    /// kd-tree and the BVH.
    fn accels(&self) -> Vec<&dyn Accel> {
        match (&self.bvh, self.auto.is_some()) {
            (Some(bvh), true) => vec![self.kd(), bvh],
            (Some(bvh), false) => vec![bvh],
            (None, _) => vec![self.kd()],
        }
    }

    /// The accelerator for a `query` of `rays` traced in `mode` (`None`: each chunk's
    /// own). For `auto`, a query of [`RACE_MIN`] rays or more whose kind (query, and
    /// the mode of a sample of its rays) has not been raced, or not in [`RERACE`]
    /// calls, goes to whichever tree traces the sample sooner ([`trace::faster`]);
    /// others to the winner of their kind's last race, or of their query's.
    fn pick(&self, rays: &Rays, query: Query, mode: Option<Mode>) -> Result<&dyn Accel, BadChunk> {
        let accels = self.accels();
        let Some(wins) = &self.auto else {
            return Ok(accels[0]);
        };
        let lock = || {
            wins.lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner)
        };
        if rays.len() < RACE_MIN {
            return Ok(accels[lock().last[query as usize]]);
        }
        let mut sample = Vec::with_capacity(trace::race_rays(rays.len()));
        let mut buf = Vec::new();
        for r in trace::race_ranges(rays.len()) {
            if !rays.fill(r.start, &mut buf, r.len()) {
                return Err(BadChunk);
            }
            sample.extend_from_slice(&buf);
        }
        let kind = (
            query,
            mode.unwrap_or_else(|| trace::auto_mode(&sample, self.scale)),
        );
        let known = lock().by_kind.get(&kind).copied();
        // The race runs without the lock held.
        let (win, calls) = match known {
            Some((win, calls)) if calls % RERACE != 0 => (win, calls + 1),
            _ => (
                trace::faster(&accels, &sample, trace::Order::Any, query, kind.1),
                1,
            ),
        };
        let mut wins = lock();
        wins.by_kind.insert(kind, (win, calls));
        wins.last[query as usize] = win;
        Ok(accels[win])
    }
}

/// The camera override of [`render`]: `(eye, target, up, vfov_deg)`.
type CameraArgs = ([f64; 3], [f64; 3], [f64; 3], f64);

/// Renders `scene` as `raypack render` does (same lights, sky, defaults and image, bit
/// for bit) and returns the linear radiance, row 0 at the top.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
fn render<'py>(
    py: Python<'py>,
    scene: &Scene,
    width: Option<u32>,
    height: Option<u32>,
    spp: Option<u32>,
    integrator: &str,
    camera: Option<CameraArgs>,
    sky: Option<[f32; 3]>,
    seed: Option<u64>,
    threads: usize,
    mode: &str,
    photons: u32,
    max_bounces: Option<u32>,
    sampler: &str,
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    if let Some(why) = &scene.not_renderable {
        return Err(error(why));
    }
    let sampler = match sampler {
        "sobol" => SamplerKind::Sobol,
        "independent" => SamplerKind::Independent,
        _ => {
            return Err(error(format!(
                "sampler {sampler:?}: expected sobol or independent"
            )));
        }
    };
    let mode = parse_mode(mode)?.unwrap_or_else(Mode::native_packet);
    let mut staged = scene.staged.clone();
    if let Some((eye, target, up, vfov)) = camera {
        let view = view_of(eye, target, up, vfov);
        // The camera is checked as the ray sets check it (finite, up not along the view).
        standard::camera_rays(&view, 1, 1).map_err(error)?;
        staged.scene.camera = Camera::from(&view);
    }
    let s = &mut staged.scene.settings;
    let (w, h) = (width.unwrap_or(s.width), height.unwrap_or(s.height));
    if w == 0 || h == 0 || w as u64 * h as u64 > MAX_PIXELS {
        return Err(error(format!(
            "width {w} x height {h}: an image has 1 to {MAX_PIXELS} pixels"
        )));
    }
    (s.width, s.height) = (w, h);
    if let Some(seed) = seed {
        s.seed = seed;
    }
    if let Some(sky) = sky
        && !(sky.iter().all(|c| c.is_finite() && *c >= 0.0))
    {
        return Err(error(format!(
            "sky {sky:?}: values must be finite and >= 0"
        )));
    }
    let film = match integrator {
        "whitted" => {
            if let Some(spp) = spp {
                s.antialias = studio::whitted_antialias(s.antialias, spp).ok_or_else(|| {
                    error(format!(
                        "spp {spp}: the Whitted tracer takes a square number of samples per \
                         pixel, 1 to 256 (1, 4, 9, 16, ...)"
                    ))
                })?;
            }
            let mut scene_w = staged.scene;
            on_pool(py, threads, || {
                if staged.source == Source::Mesh {
                    studio::light_mesh(&mut scene_w, scene.kd())?;
                }
                Ok::<_, raypack::rayset::RaySetError>(
                    tiles::render(&scene_w, scene.kd(), mode, &|| {}).film,
                )
            })?
            .map_err(error)?
        }
        "path" | "photon" => {
            let spp = spp.unwrap_or(16);
            if !(1..=MAX_GI_SPP).contains(&spp) {
                return Err(error(format!(
                    "spp {spp}: the path and photon integrators take 1 to {MAX_GI_SPP} samples per pixel"
                )));
            }
            let (environment, _) = studio::gi_environment(&staged, sky.map(Vec3::from_array));
            let gi_scene = &staged.scene;
            on_pool(py, threads, || {
                let mut gi = GiScene::new(gi_scene, scene.kd(), environment, max_bounces);
                gi.sampler = sampler;
                if integrator == "path" {
                    let tracer = PathTracer::new(gi);
                    render_gi(gi_scene, &tracer, spp, mode, &|| {}).film
                } else {
                    let settings = PhotonSettings {
                        photons,
                        seed: gi_scene.settings.seed,
                        ..PhotonSettings::default()
                    };
                    let mapper = PhotonMapper::new(gi, settings);
                    render_gi(gi_scene, &mapper, spp, mode, &|| {}).film
                }
            })?
        }
        _ => {
            return Err(error(format!(
                "integrator {integrator:?}: expected whitted, path or photon"
            )));
        }
    };
    let (w, h) = (film.width as usize, film.height as usize);
    let flat: Vec<f32> = film.pixels.iter().flat_map(|p| p.to_array()).collect();
    flat.into_pyarray(py).reshape([h, w, 3])
}

/// The instruction set the kernels run: `sse`, `avx2` or `avx512`.
#[pyfunction]
fn isa() -> &'static str {
    Isa::in_use().name()
}

#[pymodule]
fn _raypack(m: &Bound<'_, PyModule>) -> PyResult<()> {
    // A bad RAYPACK_ISA is refused at import, as the command line refuses it at start.
    Isa::from_env().map_err(error)?;
    m.add("Error", m.py().get_type::<Error>())?;
    m.add_class::<Scene>()?;
    m.add_function(wrap_pyfunction!(isa, m)?)?;
    m.add_function(wrap_pyfunction!(render, m)?)?;
    m.add("MAX_GI_SPP", MAX_GI_SPP)?;
    Ok(())
}
