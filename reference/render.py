"""The reference renderer: Mitsuba 3 with the project's BSDF, two estimators, AOVs and variance.

Every render goes through ``mi.render`` with the integrator ``pbrcheck_reference``
(:mod:`reference.integrator`; ``moments = True``) and a Mitsuba ``perspective`` sensor that
reproduces :mod:`pbrcheck.camera` (:func:`reference.integrator.sensor_dict`).

Integrators (``mode``)
----------------------
* ``local`` (default): the first hit only. Per camera sample it takes one environment sample
  (Mitsuba's envmap importance sampling) and one BSDF sample, combined with multiple importance
  sampling (power heuristic; a delta lobe takes weight 1), with **no visibility tests**, plus every
  point light without a shadow ray (``f cos * I / d^2``, exact, no noise). Camera rays that miss see
  the environment. This is the integral real-time image-based lighting approximates.
* ``path``: Mitsuba's ``path`` integrator (``max_depth``, shadows and interreflections) with the same
  BSDF and emitters, called from the same integrator on the same camera rays.

Camera: horizontal fov, row 0 at the top, ``x_ndc = 2 (j + sx) / W - 1``, ``y_ndc = 1 - 2 (i + sy) /
H`` with ``(sx, sy)`` uniform in the pixel: a box pixel filter; the sensor's rays are those of
:func:`pbrcheck.camera.primary_rays` (tested).

Variance: per-pixel moments. Each pixel's ``spp`` samples give the unbiased sample variance ``s^2``;
the variance of the pixel estimate (the mean) is ``s^2 / spp`` (``variance.R/G/B``).

AOVs (``N.X/Y/Z``, ``NdotV``, ``object``) come from the ray through the pixel centre (what a
rasterizer sees at that pixel), ``coverage`` is the fraction of the box-filter samples that hit
geometry.

glTF assets: their primitives are Mitsuba meshes with the textured ``pbr_textured`` BSDF
(:mod:`reference.textured`), shape ids ``object<k>`` like every object.

API: :func:`render_reference` (cached), :func:`render_uncached`, :func:`scene_dict`,
:func:`load_mitsuba_scene`, :func:`load_integrator`, :func:`reference_cache_key`,
:data:`REFERENCE_CODE_VERSION`.
"""

from __future__ import annotations

import time

import numpy as np

import pbrcheck
from pbrcheck.cache import Cache, cache_key
from pbrcheck.environment import EnvMap, load_environment, scene_hash
from pbrcheck.errors import BackendError
from pbrcheck.exr import Image
from pbrcheck.progress import Progress
from pbrcheck.scene import Plane, Scene, Sphere, plane_frame

from .variant import ensure_variant

# Bump when a change of this package changes the pixels: it is part of every cache key.
REFERENCE_CODE_VERSION = "2"  # 2: rendered by mi.render with pbrcheck_reference
MODES = ("local", "path")
DEFAULT_MAX_DEPTH = 8
VARIANCE_METHOD = "per-pixel moments: unbiased sample variance of the spp samples / spp"
AOV_METHOD = "N, NdotV, object: pixel-centre ray; coverage: fraction of box-filter samples hitting geometry"


def _mi():
    ensure_variant()
    # Local: the variant must be set before Mitsuba's variant-specific names are used.
    import drjit as dr
    import mitsuba as mi

    return mi, dr


# ------------------------------------------------------------------------------------------------
# Scene translation
# ------------------------------------------------------------------------------------------------

def shape_id(index: int) -> str:
    return f"object{index}"


def environment_emitter_dict(env: EnvMap) -> dict | None:
    """Mitsuba ``envmap`` from the shared :class:`EnvMap` (same pixels, scale and rotation), or None
    for an all-black environment (Mitsuba cannot importance-sample zero radiance)."""
    mi, _ = _mi()
    if env.max_radiance <= 0:
        return None
    return {"type": "envmap", "bitmap": mi.Bitmap(np.ascontiguousarray(env.data, dtype=np.float32)),
            "scale": float(env.scale),
            "to_world": mi.ScalarTransform4f().rotate([0.0, 1.0, 0.0], float(env.rotation))}


def scene_dict(scene: Scene, env: EnvMap | None = None, *, bsdf_override: dict | None = None) -> dict:
    """The Mitsuba scene dictionary (no sensor, no integrator: rays are generated here)."""
    mi, _ = _mi()
    from .bsdf import material_dict  # local: reference.bsdf subclasses mi.BSDF, which needs the variant set

    env = env if env is not None else load_environment(scene)
    d: dict = {"type": "scene"}
    e = environment_emitter_dict(env)
    if e is not None:
        d["environment"] = e
    for k, light in enumerate(scene.lights):
        d[f"light{k}"] = {"type": "point", "position": list(light.position),
                          "intensity": {"type": "rgb", "value": list(light.intensity)}}
    if getattr(scene, "assets", ()):  # glTF primitives: meshes from the decoded buffers (reference.textured)
        from .textured import asset_shapes
        d.update(asset_shapes(scene, shape_id, None if bsdf_override is None else (lambda obj: bsdf_override)))
    for i, obj in enumerate(scene.objects):
        if obj.type == "mesh":
            continue
        bsdf = bsdf_override if bsdf_override is not None else material_dict(obj.material, scene.brdf)
        if isinstance(obj, Sphere):
            d[shape_id(i)] = {"type": "sphere", "center": list(obj.center), "radius": float(obj.radius),
                              "bsdf": bsdf, "id": shape_id(i)}
        elif isinstance(obj, Plane):
            t, b, n = plane_frame(obj.normal)
            m = np.eye(4)
            m[:3, 0] = np.array(t) * obj.size[0] / 2
            m[:3, 1] = np.array(b) * obj.size[1] / 2
            m[:3, 2] = n
            m[:3, 3] = obj.center
            d[shape_id(i)] = {"type": "rectangle", "to_world": mi.ScalarTransform4f(m), "bsdf": bsdf,
                              "id": shape_id(i)}
        else:  # pragma: no cover - the loader expands grids
            raise TypeError(type(obj))
    return d


def load_mitsuba_scene(scene: Scene, env: EnvMap | None = None, **kw):
    mi, _ = _mi()
    return mi.load_dict(scene_dict(scene, env, **kw))


# ------------------------------------------------------------------------------------------------
# Rendering
# ------------------------------------------------------------------------------------------------

def load_integrator(mode: str = "local", max_depth: int | None = None, *, moments: bool = True):
    """The ``pbrcheck_reference`` integrator (:mod:`reference.integrator`) for ``mode``."""
    mi, _ = _mi()
    from .integrator import INTEGRATOR_NAME  # local: subclasses mi.ad, which needs the variant set

    depth = int(max_depth if max_depth is not None else DEFAULT_MAX_DEPTH)
    return mi.load_dict({"type": INTEGRATOR_NAME, "mode": mode, "max_depth": depth, "moments": moments})


def _aovs(mi, dr, mscene, sensor, scene: Scene, shape_index: dict) -> dict[str, np.ndarray]:
    from .integrator import pixel_centre_rays  # local: importing it loads Mitsuba (variant set first)

    W, H = scene.camera.width, scene.camera.height
    ray, _ = pixel_centre_rays(sensor)
    ray = mi.Ray3f(ray)
    si = mscene.ray_intersect(ray)
    hit = si.is_valid()
    n = dr.select(hit, si.sh_frame.n, 0.0)
    ndv = dr.select(hit, dr.clip(dr.dot(si.sh_frame.n, -ray.d), 0.0, 1.0), 0.0)
    obj = mi.Float(-1.0)
    for shape in mscene.shapes():
        idx = shape_index.get(shape.id())
        if idx is not None:
            obj = dr.select(hit & (si.shape == mi.ShapePtr(shape)), float(idx), obj)
    n_np = np.array(n).reshape(3, H, W)
    return {"N.X": n_np[0], "N.Y": n_np[1], "N.Z": n_np[2],
            "NdotV": np.array(ndv).reshape(H, W), "object": np.array(obj).reshape(H, W)}


def render_uncached(scene: Scene, *, spp: int = 64, mode: str = "local", seed: int = 0,
                    max_depth: int | None = None, progress: bool = True, env: EnvMap | None = None,
                    mscene=None) -> Image:
    """Render without the cache (see :func:`render_reference`)."""
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, not {mode!r}")
    if spp < 2:
        raise ValueError("spp must be >= 2 (the variance channels need two samples per pixel)")
    t0 = time.perf_counter()
    variant = ensure_variant()
    mi, dr = _mi()
    if variant == "scalar_rgb":  # pragma: no cover - needs a machine without LLVM
        raise BackendError("the reference renders wavefronts and needs llvm_ad_rgb or cuda_ad_rgb; "
                           "install LLVM (libllvm19) for Dr.Jit")
    env = env if env is not None else load_environment(scene)
    if mscene is None:
        mscene = load_mitsuba_scene(scene, env)
    depth = int(max_depth if max_depth is not None else DEFAULT_MAX_DEPTH)
    from .integrator import MOMENT_CHANNELS, pass_sizes, sensor_dict  # local: needs the variant set

    integrator = load_integrator(mode, depth)
    sensor = mi.load_dict(sensor_dict(scene.camera, spp))
    W, H = scene.camera.width, scene.camera.height
    with Progress(f"reference {scene.name} ({mode}, {spp} spp)", total=spp, unit="spp",
                  enabled=progress) as prog:
        integrator.progress = prog.update
        r_wall, r_cpu = time.perf_counter(), time.process_time()
        try:
            out = np.array(mi.render(mscene, sensor=sensor, integrator=integrator, spp=spp, seed=seed),
                           dtype=np.float64)
        finally:
            integrator.progress = None
        # The render alone (no scene load, no AOV pass): its wall time, and the CPU time of this
        # process's threads over it, which other processes sharing the cores do not inflate
        # (compare.verdict_spp.seconds_per_spp sizes the report's reference budget from it).
        r_wall, r_cpu = time.perf_counter() - r_wall, time.process_time() - r_cpu
    ch = {c: out[..., i] for i, c in enumerate(MOMENT_CHANNELS)}
    shape_index = {shape_id(i): i for i in range(len(scene.objects))}
    ch.update(_aovs(mi, dr, mscene, sensor, scene, shape_index))
    import drjit  # already imported by _mi(); local like there
    import mitsuba

    meta = {
        "renderer": "reference",
        "scene": scene.name,
        "scene_hash": scene_hash(scene, env.content_hash),
        "spp": str(spp), "mode": mode, "seed": str(seed),
        "max_depth": str(depth) if mode == "path" else "1 (first hit only)",
        "variant": variant,
        "pbrcheck_version": pbrcheck.__version__,
        "mitsuba_version": mitsuba.__version__,
        "drjit_version": drjit.__version__,
        "reference_code_version": REFERENCE_CODE_VERSION,
        "variance_method": VARIANCE_METHOD,
        "aov_method": AOV_METHOD,
        "pixel_filter": "box",
        "integrator": f"mi.render + pbrcheck_reference (mode {mode})",
        "passes": str(len(pass_sizes(spp, W * H))),
        "resolution": f"{W}x{H}",
        "seconds": f"{time.perf_counter() - t0:.3f}",
        "render_seconds": f"{r_wall:.3f}",
        "render_cpu_seconds": f"{r_cpu:.3f}",
        "threads": str(dr.thread_count()),
    }
    return Image(ch, meta)


def reference_cache_key(scene: Scene, *, spp: int, mode: str, seed: int, max_depth: int | None,
                        env: EnvMap | None = None) -> str:
    env = env if env is not None else load_environment(scene)
    depth = int(max_depth if max_depth is not None else DEFAULT_MAX_DEPTH) if mode == "path" else None
    return cache_key(kind="reference", scene_hash=scene_hash(scene, env.content_hash), spp=int(spp),
                     mode=mode, seed=int(seed), max_depth=depth, code=REFERENCE_CODE_VERSION)


def render_reference(scene: Scene, *, spp: int = 64, mode: str = "local", seed: int = 0,
                     max_depth: int | None = None, use_cache: bool = True, progress: bool = True) -> Image:
    """Render the reference image of ``scene`` (channels R, G, B, variance.*, N.*, NdotV, object,
    coverage; metadata as in the module docstring). Cached in the ``reference`` namespace of
    :class:`pbrcheck.cache.Cache` by scene content (environment pixels included), spp, mode, seed,
    max depth and :data:`REFERENCE_CODE_VERSION`; ``meta["cache"]`` says ``hit`` or ``miss``."""
    env = load_environment(scene)
    cache = Cache("reference") if use_cache else None
    key = None
    if cache is not None:
        key = reference_cache_key(scene, spp=spp, mode=mode, seed=seed, max_depth=max_depth, env=env)
        img = cache.get(key)
        if img is not None:
            img.meta["cache"] = "hit"
            return img
    img = render_uncached(scene, spp=spp, mode=mode, seed=seed, max_depth=max_depth, progress=progress, env=env)
    if cache is not None:
        cache.put(key, img)
        img.meta["cache"] = "miss"
    else:
        img.meta["cache"] = "off"
    return img
