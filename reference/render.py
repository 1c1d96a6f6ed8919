"""The reference renderer: Mitsuba 3 with the project's BSDF, two estimators, AOVs and variance.

Every render goes through ``mi.render`` with the integrator ``pbrcheck_reference``
(:mod:`reference.integrator`; ``moments = True``) and a Mitsuba ``perspective`` sensor that
reproduces :mod:`pbrcheck.camera` (:func:`reference.integrator.sensor_dict`).

Integrators (``mode``)
----------------------
* ``local`` (default): the first hit only. Per camera sample it takes one environment sample
  (MIS compensation, :mod:`reference.env_sampling`) and one BSDF sample, combined with multiple importance
  sampling (power heuristic; a delta lobe takes weight 1), with **no visibility tests**, plus every
  punctual light without a shadow ray (``f cos * I / d^2``, the spot's glTF attenuation, ``f cos E``
  for a directional light: exact, no noise; :mod:`reference.lights`). Camera rays that miss see
  the environment. This is the integral real-time image-based lighting approximates.
* ``path``: Mitsuba's ``path`` integrator (``max_depth``, shadows and interreflections) with the same
  BSDF and emitters, called from the same integrator on the same camera rays.

Camera: horizontal fov, row 0 at the top, ``x_ndc = 2 (j + sx) / W - 1``, ``y_ndc = 1 - 2 (i + sy) /
H`` with ``(sx, sy)`` uniform in the pixel: a box pixel filter; the sensor's rays are those of
:func:`pbrcheck.camera.primary_rays` (tested).

Samplers and variance (``sampler``, ``adaptive``; docs/reference.md):

* ``independent``: per-pixel moments. Each pixel's ``spp`` samples give the unbiased sample variance
  ``s^2``; the variance of the pixel estimate (the mean) is ``s^2 / spp`` (``variance.R/G/B``).
* ``qmc`` (default): randomized QMC (Mitsuba's ``multijitter``) as K independent replicates
  (:func:`reference.integrator.replicate_plan`, K = 16 or 32); the estimate is the mean of the K
  replicate means ``Y_r``, its variance ``s^2(Y) / K`` (unbiased, K - 1 degrees of freedom).
* ``adaptive`` (default, ``qmc`` at >= :data:`ADAPTIVE_MIN_SPP` spp): a pilot render at ``spp / 8``
  sets each pixel's spp (:func:`adaptive_allocation`, Neyman: proportional to its standard
  deviation, mean ``spp``); the final replicates, on seeds of their own, alone make the image, the
  pilot is discarded, so the stopping rule does not bias the estimate (Kirk & Arvo 1991).

AOVs (``N.X/Y/Z``, ``NdotV``, ``object``) come from the ray through the pixel centre (what a
rasterizer sees at that pixel), ``coverage`` is the fraction of the box-filter samples that hit
geometry.

glTF assets: their primitives are Mitsuba meshes with the textured ``pbr_textured`` BSDF
(:mod:`reference.textured`), shape ids ``object<k>`` like every object.

API: :func:`render_reference` (cached), :func:`render_uncached`, :func:`check_budget` (pixels, samples), :func:`scene_dict`,
:func:`load_mitsuba_scene`, :func:`load_integrator`, :func:`reference_cache_key`,
:func:`adaptive_allocation`, :func:`lean_plan`, :data:`LEAN_OUTPUTS`, :func:`check_sampler`, :func:`geometric_roughness_image`, :data:`REFERENCE_CODE_VERSION`,
:data:`ASSET_CODE_VERSION`, :data:`LOBE_CODE_VERSION`, :func:`scene_uses_lobes`,
:data:`SAMPLER_NAMES`, :data:`DEFAULT_SAMPLER`, :data:`DEFAULT_ADAPTIVE`.
References: Kensler 2013, "Correlated multi-jittered sampling" (Pixar tech memo 13-01); Kirk &
Arvo 1991, "Unbiased sampling techniques for image synthesis" (SIGGRAPH); Neyman 1934 (optimal
allocation); Owen 2013, *Monte Carlo theory, methods and examples*, ch. 8 (stratification) and 17
(randomized QMC, replicates).
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

from .variant import backend_identity, ensure_variant

# Bump when a change of this package changes the pixels: it is part of every cache key.
# 2: rendered by mi.render with pbrcheck_reference; 3: samplers, replicates, adaptive; 4: the
# environment sampled by MIS compensation (reference.env_sampling)
REFERENCE_CODE_VERSION = "4"
#: Bump when a change of this package changes the pixels of scenes holding glTF assets only: part of
#: their cache keys alone, so that analytic scenes' cached renders stay valid. 2: single-sided back
#: faces culled (path: volpath), the emissive texture's texCoord set. 3: the glTF tangent and its sign
#: read (they were zeros: Mitsuba's frame, wrong on mirrored UVs).
ASSET_CODE_VERSION = "3"
#: Bump when a change of reference/lobe_bsdf.py changes the pixels of scenes whose materials use the
#: glTF extensions' lobes: part of their cache keys alone (:func:`scene_uses_lobes`). 1: the lobes
#: rendered (they were left out).
LOBE_CODE_VERSION = "1"


#: Bump when a change of reference/transmission.py changes the pixels of scenes holding a glTF
#: transmissive material that :class:`reference.transmission.TexturedTransmissive` renders: part of
#: their cache keys alone (:func:`transmission_cache_parts`). 1: the textures read per hit (they
#: rendered opaque). 2: KHR_materials_iridescence's film on the interface, its textures read per hit
#: (IridescenceSuzanne's glass rendered opaque before).
TEXTURED_TRANSMISSION_CODE_VERSION = "2"
#: The same for scenes holding a MASK / BLEND transmissive glTF material (:func:`transmission_cache_parts`):
#: 1: their coverage applied (a null pass-through; they rendered opaque, the alpha cut lost).
ALPHA_TRANSMISSION_CODE_VERSION = "1"
#: The same for scenes holding a transmissive glTF material with KHR_materials_iridescence (constant
#: factors too) or a transmissive analytic object with ``iridescence > 0`` (:func:`transmission_cache_parts`):
#: 1: the film on the interface (it was left out).
IRIDESCENT_TRANSMISSION_CODE_VERSION = "1"


def transmission_cache_parts(scene) -> dict:
    """``{"textured_transmission_code": TEXTURED_TRANSMISSION_CODE_VERSION}`` where an asset of
    ``scene`` has a material that the textured transmissive BSDF renders, and
    ``{"alpha_transmission_code": ALPHA_TRANSMISSION_CODE_VERSION}`` where one has a MASK / BLEND
    transmissive material the reference renders, ``{"iridescent_transmission_code":
    IRIDESCENT_TRANSMISSION_CODE_VERSION}`` where a transmissive material it renders (an asset's or an
    analytic object's) has an iridescent film; ``{}`` for other scenes (their keys unchanged; hook,
    issue 37). Here, not in reference.transmission, because a cache key is
    computed before Mitsuba's variant is set (a cache hit never sets it), and that module's classes
    derive from Mitsuba's."""
    from pbrcheck.transmission_params import has_varying, reference_renders

    mats = [m for inst in getattr(scene, "assets", ()) for m in inst.asset.materials if reference_renders(m)]
    out = {}
    if any(has_varying(m) for m in mats):
        out["textured_transmission_code"] = TEXTURED_TRANSMISSION_CODE_VERSION
    if any(m.alpha_mode != "OPAQUE" for m in mats):   # MASK / BLEND transmissive (they rendered opaque)
        out["alpha_transmission_code"] = ALPHA_TRANSMISSION_CODE_VERSION
    analytic = [o.material for o in getattr(scene, "objects", ()) if getattr(o, "type", "") in ("sphere", "plane")]
    if (any(getattr(m, "iridescence", None) is not None and m.iridescence.active for m in mats)
            or any(getattr(m, "iridescence", 0.0) > 0.0 and (m.transmission > 0.0 or m.diffuse_transmission > 0.0)
                   for m in analytic)):
        out["iridescent_transmission_code"] = IRIDESCENT_TRANSMISSION_CODE_VERSION
    return out


def scene_uses_lobes(scene) -> bool:
    """Whether an analytic object's material sets lobe fields or an asset's material has an active
    lobe extension (what reference.lobe_bsdf renders)."""
    from pbrcheck import lobe_params

    if any(lobe_params.scene_features(o.material) for o in scene.objects if hasattr(o, "material")
           and hasattr(o.material, "clearcoat_roughness")):
        return True
    fields = [f for f, _ in lobe_params.LOBE_EXTENSIONS.values()]
    return any(getattr(m, f, None) is not None and getattr(m, f).active
               for inst in getattr(scene, "assets", ()) for m in inst.asset.materials for f in fields)
MODES = ("local", "path")
DEFAULT_MAX_DEPTH = 8
VARIANCE_METHOD = "per-pixel moments: unbiased sample variance of the spp samples / spp"
REPLICATES_METHOD = ("replicates: unbiased sample variance of the K independent replicate means / K "
                     "(K - 1 degrees of freedom)")
#: The samplers (reference.integrator.SAMPLERS) and the default: ``qmc`` with ``adaptive``.
SAMPLER_NAMES = ("independent", "qmc")
DEFAULT_SAMPLER = "qmc"
DEFAULT_ADAPTIVE = True
#: Adaptive sampling: a pilot of ``spp x ADAPTIVE_PILOT_FRACTION`` spp (at least
#: ``ADAPTIVE_MIN_PILOT``) decides each pixel's spp; only the final passes, independent of the
#: pilot, are averaged (Kirk & Arvo 1991). Below ``ADAPTIVE_MIN_SPP`` the render is uniform.
ADAPTIVE_PILOT_FRACTION = 0.125
ADAPTIVE_MIN_PILOT = 32
ADAPTIVE_MIN_SPP = 256
#: A pixel's final spp lies within [spp / ADAPTIVE_RANGE, spp x ADAPTIVE_RANGE ** 2].
ADAPTIVE_RANGE = 8
#: Share of the uniform allocation in the adaptive one (defensive mixture: no pixel's variance above
#: 1 / ADAPTIVE_DEFENSIVE times the uniform render's). Measured on spheres' variance map (72 x 60,
#: 1024 spp, qmc): the gain of the floor over uniform is 12.4x at 0.25, 10.3x at 0.5 (true sigmas).
ADAPTIVE_DEFENSIVE = 0.5
#: The pilot's per-pixel deviation is dilated by this many pixels (a maximum filter) before the
#: allocation: rare bright samples (a small sun in a mirror) the pilot caught in a pixel are likely
#: in its neighbours, where it missed them.
ADAPTIVE_DILATE = 1
#: The relative metric's epsilon (compare.metrics.REL_EPS; this layer cannot import the comparator):
#: the allocation weighs each pixel by 1 + (1 / (r^2 + eps)) / mean(...), so both the absolute and
#: the relative noise floors fall.
ADAPTIVE_REL_EPS = 0.01
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


def environment_emitter_dict(env: EnvMap, plugin: str | None = None) -> dict | None:
    """The environment emitter of the shared :class:`EnvMap` (same pixels, scale and rotation):
    ``reference.env_radiance.ENVMAP_PLUGIN`` (Mitsuba's ``envmap`` sampling, the exact radiance
    lookup) unless ``plugin`` names another (``"envmap"``: Mitsuba's own), or None for an all-black
    environment (Mitsuba cannot importance-sample zero radiance)."""
    mi, _ = _mi()
    if env.max_radiance <= 0:
        return None
    from .env_radiance import ENVMAP_PLUGIN  # local: subclasses mi.Emitter (variant set)

    return {"type": plugin or ENVMAP_PLUGIN, "bitmap": mi.Bitmap(np.ascontiguousarray(env.data, dtype=np.float32)),
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
    from .lights import emitter_dict  # local: reference.lights subclasses mi.Emitter (variant set)
    for k, light in enumerate(scene.lights):
        d[f"light{k}"] = emitter_dict(light)
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
        if bsdf_override is None:  # hook (issue 37): a transmissive material's BSDF and interior medium
            from .transmission import shape_fields
            d[shape_id(i)].update(shape_fields(obj, scene.brdf))
    return d


def load_mitsuba_scene(scene: Scene, env: EnvMap | None = None, **kw):
    mi, _ = _mi()
    from .env_radiance import bind_environment

    ms = mi.load_dict(scene_dict(scene, env, **kw))
    bind_environment(ms)  # the shadow rays' length of the environment's samples (path mode)
    return ms


# ------------------------------------------------------------------------------------------------
# Rendering
# ------------------------------------------------------------------------------------------------

def check_sampler(sampler: str) -> str:
    if sampler not in SAMPLER_NAMES:
        raise ValueError(f"sampler must be one of {SAMPLER_NAMES}, not {sampler!r}")
    return sampler


def _dilate(a: np.ndarray, r: int) -> np.ndarray:
    """Maximum over the ``(2 r + 1)^2`` neighbourhood of each pixel of a 2-D array (edge-padded)."""
    if r <= 0:
        return a
    H, W = a.shape
    p = np.pad(a, r, mode="edge")
    out = a.copy()
    for dy in range(2 * r + 1):
        for dx in range(2 * r + 1):
            out = np.maximum(out, p[dy:dy + H, dx:dx + W])
    return out


def adaptive_levels(spp: int) -> list[int]:
    """The per-pixel spp an adaptive render of mean ``spp`` may give: powers of two (a ladder of
    ratio 2: at most a factor sqrt 2 from the ideal, a variance cost of at most 6 % on a pixel) in
    ``[spp / ADAPTIVE_RANGE, spp x ADAPTIVE_RANGE^2]``, at least 32, each rendered as
    :func:`reference.integrator.replicate_plan` says (K = 16 or 32)."""
    lo = max(32, int(spp) // ADAPTIVE_RANGE)
    hi = max(lo, int(spp) * ADAPTIVE_RANGE ** 2)
    levels = [1 << k for k in range(5, 40) if lo <= (1 << k) <= hi]
    return levels or [1 << max(5, (lo - 1).bit_length())]


def adaptive_allocation(mean: np.ndarray, var: np.ndarray, pilot_spp: int, spp: int) -> np.ndarray:
    """Each pixel's final spp (one of :func:`adaptive_levels`) from a pilot's ``(H, W, 3)`` mean
    and variance at ``pilot_spp``: the defensive mixture ``spp_i = spp (beta + (1 - beta) t_i /
    mean(t))``, ``beta`` = :data:`ADAPTIVE_DEFENSIVE`, of the uniform allocation and the Neyman
    allocation ``t_i = sqrt(a_i) sigma_i`` (the minimum of ``sum a_i sigma_i^2 / spp_i`` at a fixed
    total), ``sigma_i^2 = pilot_spp x var_i`` (channel mean; dilated by :data:`ADAPTIVE_DILATE`
    pixels), ``a_i = 1 + w_i / mean(w)``, ``w_i =
    1 / (r_i^2 + ADAPTIVE_REL_EPS)`` (the absolute and the relative floor alike). The mixture
    bounds every pixel's variance by ``1 / beta`` times the uniform render's, also where the pilot
    missed a rare bright sample (a small sun), at the cost of some of the gain. Rounded to the
    nearest level (in log; the defensive part rounded down) and scaled so that the mean is at most
    ``spp``. Flat ``(H W,)`` int array."""
    sigma = np.sqrt(np.clip(var.astype(np.float64), 0, None).mean(-1) * pilot_spp)
    # dilated: a bright feature the pilot caught in one pixel is likely in its neighbours too
    # (a small sun's highlight spans several pixels; the pilot's few samples miss most of them)
    sigma = _dilate(sigma, ADAPTIVE_DILATE).ravel()
    r2 = (mean.astype(np.float64) ** 2).mean(-1).ravel()
    w = 1.0 / (r2 + ADAPTIVE_REL_EPS)
    t = np.sqrt(1.0 + w / w.mean()) * sigma
    t = t / t.mean() if t.mean() > 0 else np.ones_like(t)
    levels = np.array(adaptive_levels(spp), dtype=np.int64)
    logl = np.log(levels)
    floor_level = levels[max(0, np.searchsorted(levels, ADAPTIVE_DEFENSIVE * spp, side="right") - 1)]

    def quantize(lam):
        x = np.log(np.clip(lam * spp * (ADAPTIVE_DEFENSIVE + (1 - ADAPTIVE_DEFENSIVE) * t), levels[0], levels[-1]))
        j = np.clip(np.searchsorted(logl, x), 1, max(len(levels) - 1, 1))
        if len(levels) == 1:
            return np.full(t.shape, levels[0])
        j = np.where(np.abs(logl[j - 1] - x) <= np.abs(logl[j] - x), j - 1, j)
        return np.maximum(levels[j], floor_level)

    lo, hi = 0.0, float(ADAPTIVE_RANGE ** 2 / ADAPTIVE_DEFENSIVE)
    for _ in range(60):  # the largest scale whose quantized mean fits in spp
        mid = 0.5 * (lo + hi)
        if quantize(mid).mean() <= spp:
            lo = mid
        else:
            hi = mid
    return quantize(lo)


#: What :func:`render_uncached` computes for a caller that reads the radiance alone.
LEAN_OUTPUTS = {"error_bars": False, "aovs": False}


def lean_plan(spp: int) -> tuple[int, int]:
    """(K, n) of a ``qmc`` render without error bars: the fewest replicates (1, else 2, ...) whose
    count multijitter takes (:func:`reference.integrator.replicate_plan` with one replicate)."""
    from .integrator import replicate_plan  # local: needs the variant set

    return replicate_plan(int(spp), 1)


def load_integrator(mode: str = "local", max_depth: int | None = None, *, moments: bool = True,
                    sampler: str = "independent", mis: str = "power", env_sampling: str | None = None,
                    env_candidates: int | None = None):
    """The ``pbrcheck_reference`` integrator (:mod:`reference.integrator`) for ``mode``; with the
    ``qmc`` sampler its variance channels come from replicates (``MIN_REPLICATES``); ``mis``: the
    local estimator's MIS heuristic (``reference.integrator.MIS_HEURISTICS``); ``env_sampling``:
    its environment proposal (``reference.env_sampling.ENV_SAMPLING``; None: the default);
    ``env_candidates``: the env sample resampled from that many (RIS,
    ``reference.integrator.resampled_estimate``; None: ``DEFAULT_ENV_CANDIDATES``)."""
    mi, _ = _mi()
    from .env_sampling import DEFAULT_ENV_SAMPLING, ENV_SAMPLING  # local: imports Mitsuba
    from .integrator import (DEFAULT_ENV_CANDIDATES, INTEGRATOR_NAME, MAX_ENV_CANDIDATES,  # local: needs the variant set
                             MIN_REPLICATES, MIS_HEURISTICS)

    if mis not in MIS_HEURISTICS:
        raise ValueError(f"{INTEGRATOR_NAME}: mis must be one of {tuple(MIS_HEURISTICS)}, not {mis!r}")
    if env_sampling is not None and env_sampling not in ENV_SAMPLING:
        raise ValueError(f"{INTEGRATOR_NAME}: env_sampling must be one of {ENV_SAMPLING}, not {env_sampling!r}")

    m = int(env_candidates if env_candidates is not None else DEFAULT_ENV_CANDIDATES)
    if not 1 <= m <= MAX_ENV_CANDIDATES:
        raise ValueError(f"{INTEGRATOR_NAME}: env_candidates must be in [1, {MAX_ENV_CANDIDATES}], not {m}")
    depth = int(max_depth if max_depth is not None else DEFAULT_MAX_DEPTH)
    return mi.load_dict({"type": INTEGRATOR_NAME, "mode": mode, "max_depth": depth, "moments": moments,
                         "replicates": 0 if sampler == "independent" else MIN_REPLICATES, "mis": mis,
                         "env_sampling": env_sampling or DEFAULT_ENV_SAMPLING,
                         "env_candidates": m})


def _aovs(mi, dr, mscene, sensor, scene: Scene, shape_index: dict) -> dict[str, np.ndarray]:
    from .integrator import culling_table, past_back_faces, pixel_centre_rays  # local: loads Mitsuba (variant set first)
    from .material_tables import shape_lookup

    W, H = scene.camera.width, scene.camera.height
    ray, _ = pixel_centre_rays(sensor)
    ray = mi.Ray3f(ray)
    si = mscene.ray_intersect(ray)
    # glTF single-sided back faces are culled (the estimators' rule)
    si, hit = past_back_faces(mscene, ray, si, si.is_valid(), culling_table(mscene))
    n = dr.select(hit, si.sh_frame.n, 0.0)
    ndv = dr.select(hit, dr.clip(dr.dot(si.sh_frame.n, -ray.d), 0.0, 1.0), 0.0)
    # the object id by a lookup table from the shape's registry id (a kernel input: the same kernel
    # for every scene, where a select per shape baked the scene's ids into it)
    shapes = list(mscene.shapes())
    if shapes:
        lut = shape_lookup(mscene, [float(shape_index.get(s.id(), -1)) for s in shapes], mi.Float, -1.0)
        obj = dr.select(hit, dr.gather(mi.Float, lut, dr.reinterpret_array(mi.UInt32, si.shape), hit), -1.0)
    else:   # a scene without shapes
        obj = dr.full(mi.Float, -1.0, W * H)
    dr.eval(n, ndv, obj)   # one kernel for the five channels (each conversion alone would trace its own)
    # channel by channel: a Color3f's numpy conversion packs it in a kernel whose offsets are literals
    return {"N.X": np.array(n.x).reshape(H, W), "N.Y": np.array(n.y).reshape(H, W), "N.Z": np.array(n.z).reshape(H, W),
            "NdotV": np.array(ndv).reshape(H, W), "object": np.array(obj).reshape(H, W)}


def geometric_roughness_image(scene: Scene) -> np.ndarray:
    """``(H, W)``: the roughness ``[brdf] geometric_roughness`` adds at each pixel centre (before
    ``min(., 1)``; 0 where the camera ray misses), by the local estimator's own function
    (:data:`reference.integrator.GEOMETRIC_ROUGHNESS`) on the pixel centres' ray differentials."""
    ensure_variant()
    mi, dr = _mi()
    from .integrator import GEOMETRIC_ROUGHNESS, sensor_dict  # local: needs the variant set

    name, ss = scene.brdf.geometric_roughness, scene.brdf.geometric_roughness_supersample
    W, H = scene.camera.width, scene.camera.height
    if name == "none":
        return np.zeros((H, W))
    mscene = load_mitsuba_scene(scene)
    sensor = mi.load_dict(sensor_dict(scene.camera, 2))
    idx = dr.arange(mi.UInt32, W * H)
    y = idx // W
    pos = mi.Vector2f(mi.Float(idx - y * W), mi.Float(y)) + 0.5
    ray, _ = sensor.sample_ray_differential(0.0, 0.0, pos * dr.rcp(mi.ScalarVector2f(W, H)), mi.Vector2f(0.0))
    si = mscene.ray_intersect(mi.Ray3f(ray), mi.RayFlags.All | mi.RayFlags.dNSdUV, True)
    g = GEOMETRIC_ROUGHNESS[name](si, ray, ss, sensor.world_transform().inverse())
    return np.array(g, dtype=np.float64).reshape(H, W)


def check_budget(scene: Scene, spp: int) -> None:
    """The reference's resource budgets (:mod:`pbrcheck.limits`), before any work: the image's pixels
    (``reference_pixels``, ``--max-reference-pixels``) and its samples, spp x width x height
    (``samples``, ``--max-samples``; an adaptive render's mean spp is ``spp``). Raises
    :class:`pbrcheck.limits.LimitError` (exit 2)."""
    from pbrcheck.limits import check

    W, H = scene.camera.width, scene.camera.height
    check("reference_pixels", W * H, scene.source, f"reference image of {W}x{H}")
    check("samples", int(spp) * W * H, scene.source, f"reference samples ({spp} spp x {W}x{H} pixels)")


def render_uncached(scene: Scene, *, spp: int = 64, mode: str = "local", seed: int = 0,
                    max_depth: int | None = None, progress: bool = True, env: EnvMap | None = None,
                    mscene=None, sampler: str = DEFAULT_SAMPLER, adaptive: bool = DEFAULT_ADAPTIVE,
                    mis: str = "power", env_sampling: str | None = None, env_candidates: int | None = None,
                    error_bars: bool = True, aovs: bool = True) -> Image:
    """Render without the cache (see :func:`render_reference`). ``error_bars`` False (``qmc``
    only): no variance channels, the final image one QMC sequence per pixel where multijitter takes
    the count (:func:`lean_plan`: lower variance, no replicate accumulation; other samples than the
    default's); ``aovs`` False: no AOV pass (``N.*``, ``NdotV``, ``object``): what a caller that
    reads the radiance alone needs (:data:`LEAN_OUTPUTS`). ``mis``: the local estimator's MIS
    heuristic, ``env_sampling``: its environment proposal (``reference.env_sampling``),
    ``env_candidates``: RIS of the env sample (:func:`load_integrator`), all for measurements only
    (not part of the cache key: :func:`render_reference` always renders the defaults,
    ``reference.integrator.DEFAULT_MIS``, ``reference.env_sampling.DEFAULT_ENV_SAMPLING`` and
    ``reference.integrator.DEFAULT_ENV_CANDIDATES``)."""
    check_sampler(sampler)
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, not {mode!r}")
    if spp < 2:
        raise ValueError("spp must be >= 2 (the variance channels need two samples per pixel)")
    check_budget(scene, spp)
    t0 = time.perf_counter()
    variant = ensure_variant()
    from .lobe_bsdf import check_scene as check_lobe_model
    check_lobe_model(scene)  # the glTF lobes' [brdf] needs, a typed error before Mitsuba builds a plugin
    if mode == "local":  # hook (issue 37): the first-hit estimator refuses transmissive materials
        from .transmission import check_local
        check_local(scene)
    mi, dr = _mi()
    if variant == "scalar_rgb":  # pragma: no cover - needs a machine without LLVM
        raise BackendError("the reference renders wavefronts and needs llvm_ad_rgb or cuda_ad_rgb; "
                           "install LLVM (libllvm19) for Dr.Jit")
    env = env if env is not None else load_environment(scene)
    if mscene is None:
        mscene = load_mitsuba_scene(scene, env)
    depth = int(max_depth if max_depth is not None else DEFAULT_MAX_DEPTH)
    from .integrator import MIN_REPLICATES, MOMENT_CHANNELS, pass_sizes, replicate_plan, sensor_dict  # variant set

    integrator = load_integrator(mode, depth, sampler=sampler, mis=mis, env_sampling=env_sampling,
                                 env_candidates=env_candidates)
    sensor = mi.load_dict(sensor_dict(scene.camera, spp, sampler))
    W, H = scene.camera.width, scene.camera.height
    adaptive = bool(adaptive) and sampler == "qmc" and spp >= ADAPTIVE_MIN_SPP
    pilot_spp, levels = 0, None
    if adaptive:
        pilot_spp = max(ADAPTIVE_MIN_PILOT, int(spp * ADAPTIVE_PILOT_FRACTION))
        pilot_spp -= pilot_spp % MIN_REPLICATES
    with Progress(f"reference {scene.name} ({mode}, {sampler}{' adaptive' if adaptive else ''}, {spp} spp)",
                  total=spp + pilot_spp, unit="spp", enabled=progress) as prog:
        integrator.progress = prog.update
        r_wall, r_cpu = time.perf_counter(), time.process_time()
        lean = not error_bars and sampler == "qmc"
        try:
            if not adaptive and lean:
                out = np.array(integrator.render_groups(mscene, sensor, [(None, *lean_plan(spp), 0)], seed, W, H,
                                                        variance=False), dtype=np.float64)
            elif not adaptive:
                out = np.array(mi.render(mscene, sensor=sensor, integrator=integrator, spp=spp, seed=seed),
                               dtype=np.float64)
            else:
                # The pilot (streams 0 ..: a uniform qmc render at pilot_spp) decides the allocation;
                # the final groups draw from streams of their own and alone make the image.
                pilot = np.array(mi.render(mscene, sensor=sensor, integrator=integrator, spp=pilot_spp,
                                           seed=seed), dtype=np.float64)
                alloc = adaptive_allocation(pilot[..., :3], pilot[..., 3:6], pilot_spp, spp)
                levels = np.unique(alloc)
                plan = lean_plan if lean else replicate_plan
                groups = [(np.flatnonzero(alloc == lv), *plan(int(lv)), (g + 1) << 20)
                          for g, lv in enumerate(levels)]
                out = np.array(integrator.render_groups(mscene, sensor, groups, seed, W, H, variance=not lean),
                               dtype=np.float64)
        finally:
            integrator.progress = None
        # The render alone (no scene load, no AOV pass): its wall time, and the CPU time of this
        # process's threads over it, which other processes sharing the cores do not inflate
        # (compare.verdict_spp.seconds_per_spp sizes the report's reference budget from it).
        r_wall, r_cpu = time.perf_counter() - r_wall, time.process_time() - r_cpu
    ch = {c: out[..., i] for i, c in enumerate(MOMENT_CHANNELS)
          if error_bars or sampler != "qmc" or not c.startswith("variance.")}
    if aovs:
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
        **({"asset_code_version": ASSET_CODE_VERSION} if getattr(scene, "assets", ()) else {}),
        **({"lobe_code_version": LOBE_CODE_VERSION} if scene_uses_lobes(scene) else {}),
        **transmission_cache_parts(scene),   # hook (issue 37): textured transmissive assets
        "sampler": sampler,
        "variance_method": VARIANCE_METHOD if sampler == "independent" else REPLICATES_METHOD,
        "aov_method": AOV_METHOD,
        "pixel_filter": "box",
        "integrator": f"mi.render + pbrcheck_reference (mode {mode})",
        "passes": (str(len(pass_sizes(spp, W * H))) if sampler == "independent"
                   else "replicates share passes as memory allows"),
        "resolution": f"{W}x{H}",
        "seconds": f"{time.perf_counter() - t0:.3f}",
        "render_seconds": f"{r_wall:.3f}",
        "render_cpu_seconds": f"{r_cpu:.3f}",
        "threads": str(dr.thread_count()),
    }
    meta["outputs"] = "+".join(["radiance", "coverage"] + (["variance"] if "variance.R" in ch else [])
                               + (["aovs"] if aovs else []))
    if sampler == "qmc":
        K, n = (lean_plan if lean else replicate_plan)(spp) if not adaptive else (None, 0)
        meta["replicates"] = str(K) if K else ("1 or 2 by level (no error bars)" if lean else "16 or 32 by level")
        meta["adaptive"] = "off"
        if not adaptive:
            meta["samples_per_replicate"] = str(n)
        else:
            meta["adaptive"] = (f"pilot {pilot_spp} spp (discarded); final spp per pixel "
                                f"{int(alloc.min())}..{int(alloc.max())}, mean {alloc.mean():.1f} "
                                f"({len(levels)} levels)")
            meta["pilot_spp"] = str(pilot_spp)
            meta["mean_spp"] = f"{alloc.mean():.3f}"
    return Image(ch, meta)


def reference_cache_key(scene: Scene, *, spp: int, mode: str, seed: int, max_depth: int | None,
                        env: EnvMap | None = None, sampler: str = DEFAULT_SAMPLER,
                        adaptive: bool = DEFAULT_ADAPTIVE) -> str:
    env = env if env is not None else load_environment(scene)
    depth = int(max_depth if max_depth is not None else DEFAULT_MAX_DEPTH) if mode == "path" else None
    adaptive = bool(adaptive) and sampler == "qmc" and int(spp) >= ADAPTIVE_MIN_SPP
    assets = {"asset_code": ASSET_CODE_VERSION} if getattr(scene, "assets", ()) else {}
    if scene_uses_lobes(scene):
        assets["lobe_code"] = LOBE_CODE_VERSION
    assets.update(transmission_cache_parts(scene))   # hook (issue 37): textured transmissive assets
    return cache_key(kind="reference", scene_hash=scene_hash(scene, env.content_hash), spp=int(spp),
                     mode=mode, seed=int(seed), max_depth=depth, code=REFERENCE_CODE_VERSION,
                     sampler=check_sampler(sampler), adaptive=adaptive, backend=backend_identity(), **assets)


def render_reference(scene: Scene, *, spp: int = 64, mode: str = "local", seed: int = 0,
                     max_depth: int | None = None, use_cache: bool = True, progress: bool = True,
                     sampler: str = DEFAULT_SAMPLER, adaptive: bool = DEFAULT_ADAPTIVE) -> Image:
    """Render the reference image of ``scene`` (channels R, G, B, variance.*, N.*, NdotV, object,
    coverage; metadata as in the module docstring). Cached in the ``reference`` namespace of
    :class:`pbrcheck.cache.Cache` by scene content (environment pixels included), spp, mode, seed,
    max depth, sampler, :data:`REFERENCE_CODE_VERSION` and the backend (Mitsuba variant and the
    Mitsuba and Dr.Jit versions, :func:`reference.variant.backend_identity`); ``meta["cache"]`` says
    ``hit`` or ``miss``.
    The budgets (:func:`check_budget`) are checked first."""
    check_budget(scene, spp)
    env = load_environment(scene)
    cache = Cache("reference") if use_cache else None
    key = None
    if cache is not None:
        key = reference_cache_key(scene, spp=spp, mode=mode, seed=seed, max_depth=max_depth, env=env,
                                  sampler=sampler, adaptive=adaptive)
        img = cache.get(key)
        if img is not None:
            img.meta["cache"] = "hit"
            return img
    img = render_uncached(scene, spp=spp, mode=mode, seed=seed, max_depth=max_depth, progress=progress, env=env,
                          sampler=sampler, adaptive=adaptive)
    if cache is not None:
        cache.put(key, img)
        img.meta["cache"] = "miss"
    else:
        img.meta["cache"] = "off"
    return img
