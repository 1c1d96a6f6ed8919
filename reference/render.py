"""The reference renderer: Mitsuba 3 with the project's BSDF, two integrators, AOVs and variance.

Integrators
-----------
* ``local`` (default): the first hit only. Per camera sample it takes one environment sample
  (Mitsuba's envmap importance sampling) and one BSDF sample, combined with multiple importance
  sampling (power heuristic; a delta lobe takes weight 1), with **no visibility tests**, plus every
  point light without a shadow ray (``f cos * I / d^2``, exact, no noise). Camera rays that miss see
  the environment. This is the integral real-time image-based lighting approximates.
* ``path``: Mitsuba's ``path`` integrator (``max_depth``, shadows and interreflections) with the same
  BSDF and emitters, called per ray from the same camera rays.

Camera: rays are generated here with :mod:`pbrcheck.camera`'s conventions (horizontal fov, row 0 at
the top, ``x_ndc = 2 (j + sx) / W - 1``, ``y_ndc = 1 - 2 (i + sy) / H``) with ``(sx, sy)`` uniform in
the pixel: a box pixel filter. Mitsuba's sensor is not used, so the pixel centres are by construction
those of :func:`pbrcheck.camera.primary_rays`.

Variance: per-pixel moments. Each pixel's ``spp`` samples give the unbiased sample variance ``s^2``;
the variance of the pixel estimate (the mean) is ``s^2 / spp`` (``variance.R/G/B``).

AOVs (``N.X/Y/Z``, ``NdotV``, ``object``) come from the ray through the pixel centre (what a
rasterizer sees at that pixel), ``coverage`` is the fraction of the box-filter samples that hit
geometry.
"""

from __future__ import annotations

import hashlib
import time

import numpy as np

import pbrcheck
from pbrcheck.cache import Cache, cache_key
from pbrcheck.camera import camera_frame, tan_half_fov
from pbrcheck.environment import EnvMap, load_environment, scene_hash
from pbrcheck.errors import BackendError
from pbrcheck.exr import Image
from pbrcheck.progress import Progress
from pbrcheck.scene import Plane, Scene, Sphere, plane_frame

from .variant import ensure_variant

# Bump when a change of this package changes the pixels: it is part of every cache key.
REFERENCE_CODE_VERSION = "1"
MODES = ("local", "path")
DEFAULT_MAX_DEPTH = 8
# Lanes (rays) per wavefront: bounds memory (~290 MB peak for the path integrator at 2^21) and
# amortizes the per-pass Python tracing of the BSDF calls.
MAX_LANES = 1 << 21
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
    for i, obj in enumerate(scene.objects):
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
# Rays and integrators
# ------------------------------------------------------------------------------------------------

def camera_rays(scene: Scene, pixel, offset):
    """World rays through pixel indices ``pixel`` (row-major, row 0 at the top) at sub-pixel
    ``offset`` (Point2f in [0, 1)^2): :func:`pbrcheck.camera.primary_rays` in Dr.Jit."""
    mi, dr = _mi()
    cam = scene.camera
    r, u, f = camera_frame(cam)
    tx, ty = tan_half_fov(cam)
    W, H = cam.width, cam.height
    i = mi.Float(pixel // W)
    j = mi.Float(pixel % W)
    x = 2.0 * (j + offset.x) / W - 1.0
    y = 1.0 - 2.0 * (i + offset.y) / H
    d = mi.Vector3f(*[float(v) for v in f]) + (x * tx) * mi.Vector3f(*[float(v) for v in r]) \
        + (y * ty) * mi.Vector3f(*[float(v) for v in u])
    return mi.Ray3f(mi.Point3f(*[float(v) for v in cam.origin]), dr.normalize(d))


# Environment and BSDF samples per camera sample in the local estimator (MIS, power heuristic).
ENV_SAMPLES = 1
BSDF_SAMPLES = 1


def _power(a, b):
    return a * a / (a * a + b * b)


def shade_local(mscene, sampler, ray, lights=()):
    """The ``local`` estimator for a wavefront of rays: (radiance Color3f, hit Bool)."""
    mi, dr = _mi()
    si = mscene.ray_intersect(ray)
    hit = si.is_valid()
    env = mscene.environment()
    L = mi.Color3f(0.0)
    if env is not None:
        L += env.eval(si, ~hit)  # misses: si.wi = -ray.d
    ctx = mi.BSDFContext()
    bsdf = si.bsdf(ray)
    if env is not None:
        for _ in range(ENV_SAMPLES):
            # Environment sample, MIS against the BSDF's density (balance over the sample counts).
            ds, em_w = env.sample_direction(si, sampler.next_2d(hit), hit)
            f, bpdf = bsdf.eval_pdf(ctx, si, si.to_local(ds.d), hit & (ds.pdf > 0))
            w = _power(ENV_SAMPLES * ds.pdf, BSDF_SAMPLES * bpdf) / ENV_SAMPLES
            L += dr.select(hit & (ds.pdf > 0), f * em_w * w, 0.0)
        for _ in range(BSDF_SAMPLES):
            # BSDF sample, MIS against the environment's density (delta lobes: weight 1).
            bs, bw = bsdf.sample(ctx, si, sampler.next_1d(hit), sampler.next_2d(hit), hit)
            wo = si.to_world(bs.wo)
            delta = mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta)
            si_e = dr.zeros(mi.SurfaceInteraction3f)
            si_e.wi = -wo
            Le = env.eval(si_e, hit)
            ds2 = dr.zeros(mi.DirectionSample3f)
            ds2.d = wo
            epdf = env.pdf_direction(si, ds2, hit & ~delta)
            w = dr.select(delta, 1.0, _power(BSDF_SAMPLES * bs.pdf, ENV_SAMPLES * epdf)) / BSDF_SAMPLES
            L += dr.select(hit & (bs.pdf > 0), bw * Le * w, 0.0)
    for pos, inten in lights:
        dv = mi.Point3f(*pos) - si.p
        d2 = dr.squared_norm(dv)
        l = dv * dr.rsqrt(d2)
        f = bsdf.eval(ctx, si, si.to_local(l), hit)
        L += dr.select(hit, f * mi.Color3f(*inten) / d2, 0.0)
    return L, hit


def _seed(seed: int, index: int) -> int:
    h = hashlib.sha256(f"pbrcheck-reference:{seed}:{index}".encode()).digest()
    return int.from_bytes(h[:4], "little")


def _aovs(mi, dr, mscene, scene: Scene, shape_index: dict) -> dict[str, np.ndarray]:
    W, H = scene.camera.width, scene.camera.height
    pixel = dr.arange(mi.UInt32, W * H)
    ray = camera_rays(scene, pixel, mi.Point2f(0.5, 0.5))
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
    integrator = mi.load_dict({"type": "path", "max_depth": depth}) if mode == "path" else None
    lights = [(tuple(map(float, l.position)), tuple(map(float, l.intensity))) for l in scene.lights]
    W, H = scene.camera.width, scene.camera.height
    npix = W * H
    per_pass = max(1, min(spp, MAX_LANES // max(npix, 1)))
    s1 = np.zeros((npix, 3))
    s2 = np.zeros((npix, 3))
    hits = np.zeros(npix)
    sampler = mi.load_dict({"type": "independent"})
    done = 0
    k = 0
    shift = None
    with Progress(f"reference {scene.name} ({mode}, {spp} spp)", total=spp, unit="spp",
                  enabled=progress) as prog:
        while done < spp:
            n = min(per_pass, spp - done)
            lanes = npix * n
            sampler.seed(_seed(seed, k), lanes)
            idx = dr.arange(mi.UInt32, lanes)
            pixel = idx // n
            ray = camera_rays(scene, pixel, sampler.next_2d())
            if mode == "local":
                L, hit = shade_local(mscene, sampler, ray, lights)
            else:
                hit = mscene.ray_test(ray)
                L, _, _ = integrator.sample(mscene, sampler, mi.RayDifferential3f(ray), None, True)
            # Per-pixel sums over this pass's n consecutive lanes (float32 within a pass, float64
            # across), shifted by a per-pixel value K (the first pass's first sample) so that the
            # variance s2 - s1^2/spp does not cancel catastrophically in float32.
            Lc = mi.Color3f(L)
            if shift is None:
                shift = dr.gather(mi.Color3f, Lc, dr.arange(mi.UInt32, npix) * n)
                dr.eval(shift)
            Ld = Lc - dr.gather(mi.Color3f, shift, pixel)
            p1 = dr.block_sum(Ld, n)
            p2 = dr.block_sum(Ld * Ld, n)
            ph = dr.block_sum(dr.select(hit, mi.Float(1.0), 0.0), n)
            dr.eval(p1, p2, ph)
            s1 += np.array(p1, dtype=np.float64).T
            s2 += np.array(p2, dtype=np.float64).T
            hits += np.array(ph, dtype=np.float64)
            done += n
            k += 1
            prog.update(n)
    mean = s1 / spp + np.array(shift, dtype=np.float64).T
    var = np.maximum(s2 - s1 * s1 / spp, 0.0) / (spp - 1) / spp
    shape_index = {shape_id(i): i for i in range(len(scene.objects))}
    ch = {c: mean[:, i].reshape(H, W) for i, c in enumerate("RGB")}
    ch.update({f"variance.{c}": var[:, i].reshape(H, W) for i, c in enumerate("RGB")})
    ch.update(_aovs(mi, dr, mscene, scene, shape_index))
    ch["coverage"] = (hits / spp).reshape(H, W)
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
        "resolution": f"{W}x{H}",
        "seconds": f"{time.perf_counter() - t0:.3f}",
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
