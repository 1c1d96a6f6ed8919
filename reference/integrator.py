"""The reference's estimators as one Mitsuba integrator, ``pbrcheck_reference``, rendered by ``mi.render``.

``{"type": "pbrcheck_reference", "mode": "local" | "path", "max_depth": D, "moments": bool,
"gather_materials": bool}``; a
subclass of ``mi.ad.integrators.common.RBIntegrator``, so ``mi.render(scene, params, ...)`` differentiates it.

* ``mode = "local"``: the first hit only. One environment sample (``env_sampling``, default
  ``"compensated"``: MIS compensation, :mod:`reference.env_sampling`; ``"envmap"``: Mitsuba's envmap
  importance sampling; ``env_candidates`` M > 1: resampled from M, :func:`resampled_estimate`) and one
  BSDF sample, combined by multiple importance sampling (power heuristic; a delta
  lobe takes weight 1), **no visibility tests**; every delta emitter (point, spot, directional light:
  :mod:`reference.lights`) is added exactly through its deterministic ``sample_direction`` (``f cos
  I / d^2``, ``f cos E``), without a shadow ray.
  Camera rays that miss see the environment. This is the integral real-time IBL approximates.
  The environment's radiance, wherever this estimator reads it (misses, BSDF samples, and the
  weight radiance / pdf of an environment sample, Mitsuba's envmap proposal included), is
  :class:`reference.env_radiance.ExactEnvironment`'s exact float32 lookup, the function of
  ``pbrcheck.environment.EnvMap.radiance``: Mitsuba's ``envmap`` ``eval`` interpolates with CUDA's
  hardware texture units (8-bit fractions between texels); its sampling and pdf are kept.
  With ``gather_materials`` (the default) the BSDF of each lane is a :class:`reference.bsdf.MaterialView`:
  every ``pbr_material``'s parameters gathered by the shape hit, the lobes traced once instead of once
  per material (Mitsuba's virtual call); the same maths and samples as the per-instance dispatch.
  Other scenes (glTF assets' ``pbr_textured``, or ``gather_materials`` off) call the BSDFs, and the
  area emitters, through :class:`reference.bsdf.SceneCalls`: a dispatch over the scene's own objects
  (Mitsuba's pointer call traces every live instance of the process), a single textured material
  bound once per hit. Camera rays are traced ``coherent`` (Embree's packet traversal; pixel-major
  lanes) with :data:`LOCAL_RAY_FLAGS`; glTF single-sided back faces are culled
  (:func:`past_back_faces`), MASK / BLEND surfaces passed stochastically (``_first_opaque_hit``).
* ``mode = "path"``: Mitsuba's ``path`` integrator (``max_depth``) with the same BSDF and emitters,
  its ``sample`` called on the same camera rays (primal only).

Output of ``render``:

* ``moments = False`` (the default, and what AD needs): Mitsuba's film, ``(H, W, 3)`` mean radiance,
  exactly :meth:`ADIntegrator.render`.
* ``moments = True, replicates = K > 0`` (a QMC sensor sampler): the same channels from K
  independent replicates (:meth:`ReferenceIntegrator.render_groups`, :func:`replicate_plan`):
  the variance of each pixel mean is ``s^2(Y) / K`` of the replicate means ``Y``.
* ``moments = True`` (the reference renderer): ``(H, W, 7)`` = mean ``R, G, B``, the variance of each
  pixel mean ``variance.R/G/B`` (per-pixel moments: unbiased sample variance of the spp samples over
  spp) and ``coverage`` (the fraction of samples whose camera ray hit geometry). The spp samples of a
  pixel are consecutive lanes (:meth:`sample_rays` orders lanes pixel-major), so the per-pixel sums
  are ``dr.block_sum`` over blocks of spp lanes: float32 within a pass, float64 across passes, of
  ``L - K`` with ``K`` the pixel's first sample, so that ``s2 - s1^2 / n`` does not cancel
  catastrophically in float32 (a constant pixel has variance exactly 0). Passes only where memory
  requires them: at most :func:`max_lanes` lanes (camera samples) per pass, by backend.

Differentiation (``local`` only): detached sampling. Directions, pdfs and MIS weights are computed
without gradients; each contribution carries the gradient of its BSDF value at the detached
direction over the detached pdf (``replace_grad``), which is an unbiased estimator of the gradient of
the same integral (the MIS weights sum to 1 at the current parameters); no reparameterization is
needed because nothing is visible through a discontinuity (there is no visibility). A delta-lobe
sample (mirror limit) carries the gradient of ``F G`` over the detached lobe probability. In
``Backward`` mode it back-propagates ``δL * L``; in ``Forward`` mode it returns ``dL``.

Camera: the scenes' sensor is Mitsuba's ``perspective`` (:func:`sensor_dict`): ``fov_axis = "x"``,
``look_at(origin, target, up)``, box reconstruction filter; its rays through pixel ``(i, j)`` at
offset ``(sx, sy)`` are :func:`pbrcheck.camera.primary_rays`'s (tested), row 0 at the top.

API: :data:`INTEGRATOR_NAME`, :class:`ReferenceIntegrator`, :func:`register`, :func:`sensor_dict`,
:func:`max_lanes`, :func:`pass_sizes`, :func:`pixel_centre_rays`, :func:`camera_rays`,
:func:`replicate_plan`, :func:`replicate_parts`, :func:`multijitter_count_ok`, :func:`culling_table`,
:func:`past_back_faces`, :func:`can_pass`, :data:`LOCAL_RAY_FLAGS`, :data:`MAX_CULLED_LAYERS`, :data:`SAMPLERS`,
:data:`MIN_REPLICATES`, :data:`MOMENT_CHANNELS`, :data:`MIS_HEURISTICS`, :data:`DEFAULT_MIS`,
:func:`resampled_estimate`, :data:`DEFAULT_ENV_CANDIDATES`, :data:`MAX_ENV_CANDIDATES`,
:data:`GEOMETRIC_ROUGHNESS`, :func:`threejs_geometric_roughness` (``[brdf] geometric_roughness``: the
local estimator adds it to each lane's roughness at the first hit, from the camera ray's
differentials and the sensor's world-to-camera transform that ``render`` records).
References: Veach 1997 ch. 9 (MIS, power and balance heuristics); Vicini et al. 2021, "Path Replay
Backpropagation" (detached sampling, ``RBIntegrator``); Mitsuba 3 ``mi.ad.integrators.common``;
Kensler 2013, "Correlated multi-jittered sampling" (``multijitter``); Talbot, Cline and Egbert 2005,
"Importance resampling for global illumination" and Bitterli et al. 2020, "Spatiotemporal reservoir
resampling" (RIS, ``env_candidates``); Owen 2013, *Monte Carlo
theory, methods and examples*, ch. 17 (randomized QMC error from independent replicates); Igehy
1999, "Tracing ray differentials" (the geometric roughness's normal derivative).
"""

from __future__ import annotations

import hashlib
import math

import numpy as np

import pbrcheck  # noqa: F401  (sets DRJIT_LIBLLVM_PATH before drjit loads)

import drjit as dr
import mitsuba as mi

# Needs a variant set (reference.variant.ensure_variant imports this module after setting it).
from mitsuba.python.ad.integrators.common import RBIntegrator

from .bsdf import MaterialView, SceneCalls
from .env_radiance import bind_environment, exact_environment
from .env_sampling import DEFAULT_ENV_SAMPLING, ENV_SAMPLING, CompensatedEnvironment, _luminance
from .material_tables import shape_lookup
from .opaque_sampler import Divisor, OpaqueMultijitter

INTEGRATOR_NAME = "pbrcheck_reference"
MODES = ("local", "path")
MOMENT_CHANNELS = ("R", "G", "B", "variance.R", "variance.G", "variance.B", "coverage")
# Camera samples per pass (each a wavefront lane), by Dr.Jit backend. CUDA: 2^26 lanes were the
# fastest measured on an H100 (the table: 2^21 -> 44, 2^24 -> 237, 2^26 -> 435 M samples/s,
# per-pass tracing and launch dominate small passes) and fit its memory (~30 B per lane live).
# LLVM: throughput is flat beyond ~2^20 lanes on a CPU, 2^23 keeps the peak near 1 GB.
MAX_LANES = {"cuda": 1 << 26, "llvm": 1 << 23}
# Mitsuba's perspective sensor starts rays at the near plane; pbrcheck's camera has none.
NEAR_CLIP = 1e-4
FAR_CLIP = 1e7
#: The reference's samplers by name (Mitsuba plugin): ``independent`` (uniform random numbers; the
#: variance channels are per-sample moments) and ``qmc``: randomized quasi-Monte Carlo points,
#: Mitsuba's ``multijitter`` (Kensler 2013, correlated multi-jittered sampling: each pair of
#: dimensions stratified in 2-D and in both 1-D projections, jittered, shuffled per pixel and per
#: dimension; each point uniform, so the estimate is unbiased). The variance channels of a ``qmc``
#: render come from independent replicates (:func:`replicate_plan`). Measured on spheres (72 x 60,
#: 1024 spp, variance of the pixel means over seeds): independent 1.43e-4, ``multijitter`` 4.4e-5,
#: ``ldsampler`` 5.5e-5, ``stratified`` 6.5e-5; at 120 x 100, 4096 spp: 3.3e-5, 9.9e-6, 4.2e-5.
SAMPLERS = {"independent": "independent", "qmc": "multijitter"}
#: Independent randomizations (replicates) of a QMC render: its variance channel is the sample
#: variance of K replicate means over K, with K - 1 degrees of freedom (its own relative standard
#: deviation sqrt(2 / (K - 1)) = 0.37 at 16; a pixel's z is Student-t with K - 1 degrees of freedom:
#: |z| < 1.96 for 93 % of pixels at 16, 91 % at 8).
MIN_REPLICATES = 16


def max_lanes() -> int:
    """Lanes per pass for the current variant's backend."""
    return MAX_LANES["cuda" if mi.variant().startswith("cuda") else "llvm"]


def pass_sizes(spp: int, npix: int, lanes: int | None = None) -> list[int]:
    """Samples per pixel of each pass: as few passes as ``lanes`` allows, of near-equal sizes (at most
    two distinct sizes, so at most two kernels), summing to ``spp``; also under Mitsuba's 2^32."""
    lanes = min(int(lanes or max_lanes()), (1 << 32) - 1)
    per = max(1, min(spp, lanes // max(npix, 1)))
    k = -(-spp // per)
    base, extra = divmod(spp, k)
    return [base + (1 if i < extra else 0) for i in range(k)]


def multijitter_count_ok(n: int) -> bool:
    """Whether Mitsuba's ``multijitter`` takes ``n`` samples per pixel as they are (its grid is
    ``floor(sqrt n)`` wide; other counts it rounds up)."""
    n = int(n)
    return n >= 1 and n % math.isqrt(n) == 0


def replicate_plan(spp: int, replicates: int = MIN_REPLICATES, count_ok=multijitter_count_ok) -> tuple[int, int]:
    """(K, n): a QMC render of ``spp`` samples per pixel as K independent replicates of n samples
    each, ``spp = K n``: the smallest K in ``[replicates, 2 replicates]`` dividing ``spp`` with a
    count n the sampler takes (``count_ok``; for powers of two: K = 16 or 32); below ``2 x
    replicates`` spp, n = 2 (or 1 for an odd spp); else n = 1 and K = spp (independent samples:
    per-sample moments). ``ValueError`` below 2 spp."""
    spp = int(spp)
    if spp < 2:
        raise ValueError(f"spp must be >= 2 (the variance channels need two replicates); got {spp}")
    for K in range(int(replicates), 2 * int(replicates) + 1):
        if spp % K == 0 and spp // K >= 2 and count_ok(spp // K):
            return K, spp // K
    if spp < 2 * int(replicates) and spp % 2 == 0 and spp >= 4:
        return spp // 2, 2
    return spp, 1


def replicate_parts(n: int, npix: int, lanes: int | None = None) -> int:
    """Passes one replicate of ``n`` samples per pixel takes (a power of two dividing ``n``, each
    pass at most ``lanes`` camera samples, unless one sample per pixel exceeds it)."""
    lanes = min(int(lanes or max_lanes()), (1 << 32) - 1)
    parts = 1
    while npix * n // parts > lanes and n % (parts * 2) == 0:
        parts *= 2
    return parts


def pass_seed(seed: int, index: int) -> int:
    """The sampler seed of pass ``index`` of a render with ``seed``: ``seed`` itself for the first
    (so a one-pass moments render draws the samples of the film render, ``moments = False``), then
    independent streams."""
    if index == 0:
        return int(seed) & 0xFFFFFFFF
    h = hashlib.sha256(f"pbrcheck-reference:{int(seed)}:{int(index)}".encode()).digest()
    return int.from_bytes(h[:4], "little")


def sensor_dict(camera, spp: int = 16, sampler: str = "independent") -> dict:
    """Mitsuba ``perspective`` sensor reproducing :mod:`pbrcheck.camera` (horizontal fov, look_at,
    box filter, pixel centres at ``(j + 0.5) / W``, row 0 at the top); ``sampler``: a key of
    :data:`SAMPLERS` (``"qmc"``: Mitsuba's ``ldsampler``) or a Mitsuba sampler plugin name."""
    return {
        "type": "perspective", "fov_axis": "x", "fov": float(camera.fov),
        "near_clip": NEAR_CLIP, "far_clip": FAR_CLIP,
        "to_world": mi.ScalarTransform4f().look_at(origin=[float(v) for v in camera.origin],
                                                   target=[float(v) for v in camera.target],
                                                   up=[float(v) for v in camera.up]),
        # qmc: a count multijitter takes as it is (else it logs a warning on stdout); the moments
        # render sets each replicate's own count
        "sampler": {"type": SAMPLERS.get(sampler, sampler),
                    "sample_count": int(spp) if sampler == "independent" else replicate_plan(max(int(spp), 2))[1]},
        "film": {"type": "hdrfilm", "width": int(camera.width), "height": int(camera.height),
                 "rfilter": {"type": "box"}, "pixel_format": "rgb"},
    }


def pixel_centre_rays(sensor, offset=(0.5, 0.5)):
    """(ray, pixel index) of one ray per pixel at sub-pixel ``offset``, row-major, row 0 at the top."""
    size = sensor.film().crop_size()
    W, H = int(size[0]), int(size[1])
    idx = dr.arange(mi.UInt32, W * H)
    # the resolution opaque: one kernel for every image size (issue 39: compiled kernels per report)
    y = Divisor(W).div(idx)
    iw, ih = (dr.opaque(mi.Float, float(np.float32(1.0) / np.float32(v))) for v in (W, H))
    x = idx - y * dr.opaque(mi.UInt32, W)
    pos = mi.Point2f((mi.Float(x) + offset[0]) * iw, (mi.Float(y) + offset[1]) * ih)
    ray, _ = sensor.sample_ray(0.0, 0.5, pos, mi.Point2f(0.5))
    return ray, idx


def camera_rays(sensor, sampler, per_pixel: int, pixels=None):
    """Camera rays of a wavefront of ``per_pixel`` consecutive lanes per pixel, pixel-major (as
    ``RBIntegrator.sample_rays``, but with ``per_pixel`` lanes per pixel where the sampler's
    ``sample_count`` may be larger: one replicate of a QMC render over several passes), and their
    weights; ``pixels``: the row-major indices (``mi.UInt32``) of the pixels to sample, None for
    all; box filter, no border, no aperture, no motion blur (:func:`sensor_dict`)."""
    film = sensor.film()
    size = film.crop_size()
    m = int(size[0]) * int(size[1]) if pixels is None else dr.width(pixels)
    # per_pixel opaque: one kernel for every count (an adaptive render's levels)
    idx = Divisor(per_pixel).div(dr.arange(mi.UInt32, m * per_pixel))
    if pixels is not None:
        idx = dr.gather(mi.UInt32, pixels, idx)
    y = idx // int(size[0])
    x = idx - y * int(size[0])
    pos = mi.Vector2f(mi.Float(x), mi.Float(y)) + sampler.next_2d()
    scale = dr.rcp(mi.ScalarVector2f(size))
    ray, weight = sensor.sample_ray_differential(time=sensor.shutter_open(), sample1=0.0,
                                                 sample2=pos * scale, sample3=mi.Vector2f(0.0))
    return ray, weight


def _power(a, b):
    """Power heuristic weight of a sample with density a against b (Veach 1997 eq. 9.13)."""
    a2, b2 = a * a, b * b
    return dr.select(a2 + b2 > 0, a2 / (a2 + b2), 0.0)


def _balance(a, b):
    """Balance heuristic weight of a sample with density a against b (Veach 1997 eq. 9.10)."""
    return dr.select(a + b > 0, a / (a + b), 0.0)


#: The MIS heuristics of the local estimator (property ``mis``), name -> weight function of the
#: two densities. Measured (docs/reference.md, ``pbrcheck bench reference`` ``variance_reduction``):
#: the balance heuristic's floor is 0-3 % below the power heuristic's on spheres and on a real HDR
#: environment (1.5-8 % on a 48 x 40 crop), within the CPU-time noise per second and not worth a new
#: REFERENCE_CODE_VERSION (every cached and committed reference), so the default stays the power heuristic.
MIS_HEURISTICS = {"power": _power, "balance": _balance}
DEFAULT_MIS = "power"


#: Candidates of the environment sample (integrator property ``env_candidates``): 1 is the plain
#: sample of the proposal; M > 1 resamples one of M (:func:`resampled_estimate`). Measured
#: (docs/reference.md, ``pbrcheck bench reference`` ``variance_reduction``, ``ris4``): M = 4 divides
#: the variance by 1.19 on spheres, 1.23 furnace, 1.68 grazing, 1.09 royal_esplanade at ~2x the CPU
#: seconds (efficiency 0.52-0.85; M = 2 and 8 no better), so the default stays the plain sample.
DEFAULT_ENV_CANDIDATES = 1
#: The most candidates a render may ask for (each one a BSDF evaluation traced into the kernel).
MAX_ENV_CANDIDATES = 64


def resampled_estimate(estimate, M: int, u):
    """Resampled importance sampling (RIS; Talbot, Cline and Egbert 2005, "Importance resampling
    for global illumination"; Bitterli et al. 2020, "Spatiotemporal reservoir resampling", eq. 6)
    of one MIS-weighted environment sample.

    ``estimate()`` draws one candidate ``x_j`` from the environment proposal ``p`` and returns its
    one-sample estimate ``c_j = w_e(x_j) f(x_j) Le(x_j) / p(x_j)`` (``w_e`` the default's MIS
    weight, a function of the direction alone). With the target ``p^(x) = w_e(x) Y(f(x) Le(x))``
    (``Y`` the luminance, positive wherever ``w_e f Le`` is not zero) the resampling weight of a
    candidate is ``r_j = p^(x_j) / p(x_j) = Y(c_j)``; one candidate ``y`` is chosen with probability
    ``r_y / sum r`` (weighted reservoir sampling, one uniform ``u`` rescaled at each step) and the
    estimate is ``(w_e f Le)(y) / p^(y) x (1 / M) sum_j r_j = c_y / Y(c_y) x mean(r)``; 0 where
    every ``r_j`` is 0. It is unbiased for ``int w_e f Le`` (Talbot 2005, sec. 3: ``p^ > 0``
    wherever the integrand is not zero, ``p > 0`` wherever ``p^`` is: the proposal is defensive),
    and ``M = 1`` is the plain estimate itself. The MIS weight is the default's, computed from the
    proposal's own density ``p`` (not the RIS sample's, which has no closed form): the two weights
    still sum to 1 at every direction, so the env and BSDF estimates stay an exact partition of the
    integral; the RIS sample's approximate density ``p^(y) / mean(r)`` (Talbot 2005's MIS with the
    effective pdf) depends on the other candidates, and a weight built from it need not sum to 1
    with the BSDF sample's, which would bias the sum. Under AD, ``c_y`` carries the BSDF's
    gradient and the weights ``r`` are detached (detached sampling: the selection is part of the
    sampling, so the estimate's gradient is unbiased for the gradient of the same integral)."""
    wsum = mi.Float(0.0)
    chosen = mi.Color3f(0.0)
    for _ in range(int(M)):
        c = estimate()
        r = _luminance(dr.detach(c))
        wsum += r
        q = dr.select(wsum > 0, r / wsum, 0.0)
        take = (r > 0) & (u < q)
        chosen = dr.select(take, c, chosen)
        # u stays uniform on [0, 1) given the choice so far
        u = dr.select(take, u / dr.maximum(q, 1e-30), (u - q) / dr.maximum(1.0 - q, 1e-30))
        u = dr.clip(u, 0.0, 1.0 - 2.0 ** -24)
    y = _luminance(dr.detach(chosen))
    return dr.select(y > 0, chosen * (wsum / (M * dr.maximum(y, 1e-30))), 0.0)


#: The differentials' step (1 / this of a pixel) of the geometric roughness's normal derivative.
GEO_DIFFERENTIAL_STEP = 64.0


def threejs_geometric_roughness(si, ray, supersample: int, to_view):
    """three.js r187's screen-space geometric roughness (lights_physical_fragment.glsl.js)::

        vec3 dxy = max( abs( dFdx( nonPerturbedNormal ) ), abs( dFdy( nonPerturbedNormal ) ) );
        float geometryRoughness = max( max( dxy.x, dxy.y ), dxy.z );

    with the view-space normal differentiated over one sample of the engine's raster (``1 /
    supersample`` of a pixel), to first order through the camera ray's differentials (Igehy 1999,
    "Tracing ray differentials"): ``dn/dx = dn/du du/dx + dn/dv dv/dx``. ``si`` needs
    ``RayFlags.dNSdUV``; ``to_view``: the world-to-camera transform (three.js's view axes up to
    sign, and the sign does not matter here). Returns a Float per lane (0 where the ray has no
    differentials or missed)."""
    from .textured import uv_normal_partials   # a mesh's dn_du / dn_dv per texture uv (issue 40, model helper)
    si = uv_normal_partials(si)
    # Mitsuba's differentials are finite (the neighbouring pixel's ray, intersected with the
    # tangent plane): steps of +-1 / GEO_DIFFERENTIAL_STEP pixel, centred, make them the derivative
    dndx, dndy = mi.Vector3f(0.0), mi.Vector3f(0.0)
    for sign in (1.0, -1.0):
        rd = mi.RayDifferential3f(mi.Ray3f(ray))  # (copying a RayDifferential3f drops its differentials)
        rd.o_x, rd.o_y, rd.d_x, rd.d_y = ray.o_x, ray.o_y, ray.d_x, ray.d_y
        rd.has_differentials = ray.has_differentials
        rd.scale_differential(sign / GEO_DIFFERENTIAL_STEP)
        si.compute_uv_partials(rd)
        k = sign * GEO_DIFFERENTIAL_STEP / (2.0 * supersample)
        dndx += (si.dn_du * si.duv_dx.x + si.dn_dv * si.duv_dx.y) * k
        dndy += (si.dn_du * si.duv_dy.x + si.dn_dv * si.duv_dy.y) * k
    dxy = dr.maximum(dr.abs(to_view @ mi.Vector3f(dndx)), dr.abs(to_view @ mi.Vector3f(dndy)))
    return dr.select(si.is_valid(), dr.maximum(dr.maximum(dxy.x, dxy.y), dxy.z), 0.0)


#: The implementations of ``[brdf] geometric_roughness`` (pbrcheck.registry.GEOMETRIC_ROUGHNESSES):
#: name -> function(si, ray, supersample, to_view) -> the roughness added per lane.
GEOMETRIC_ROUGHNESS = {"threejs": threejs_geometric_roughness}


#: What the estimators' ray_intersect computes: Mitsuba's RayFlags.All less the normals' UV
#: derivatives (dNSdUV, dNGdUV), which nothing here reads (the shading frame, spawned rays and the
#: BSDFs use p, n, uv, dp_du/dp_dv and sh_frame); a mesh's interaction skips their gathers and solve.
LOCAL_RAY_FLAGS = int(mi.RayFlags.Minimal | mi.RayFlags.UV | mi.RayFlags.dPdUV | mi.RayFlags.ShadingFrame)
#: Most culled back faces (glTF single-sided) a ray passes before it stops at the last one.
MAX_CULLED_LAYERS = 16


def culling_table(scene):
    """Lookup shape registry id -> 1 where the shape's BSDF culls back faces
    (:func:`reference.textured.culls_back_faces`), or None where no shape does."""
    from .textured import culls_back_faces

    flags = [int(culls_back_faces(s.bsdf())) for s in scene.shapes()]
    if not any(flags):
        return None
    return shape_lookup(scene, flags)


def can_pass(bsdf) -> bool:
    """Whether a ray can pass a surface of ``bsdf`` in the local estimator: a glTF material with
    alphaMode MASK or BLEND (:func:`reference.textured.has_alpha`) or single-sided (its back faces
    culled, :func:`reference.textured.culls_back_faces`). Others (OPAQUE double-sided, analytic
    materials) have ``eval_null_transmission`` 0 everywhere."""
    from .textured import culls_back_faces, has_alpha

    return has_alpha(bsdf) or culls_back_faces(bsdf)


def past_back_faces(scene, ray, si, hit, lut):
    """(si, hit) of the first surface along ``ray`` that is not a culled back face (glTF
    ``doubleSided`` false, :func:`culling_table` ``lut``; None: ``si`` as it is): a symbolic loop
    (each lane traces on only while it stands on such a face, at most :data:`MAX_CULLED_LAYERS`
    times; no random numbers)."""
    if lut is None:
        return si, hit
    from .textured import back_face

    def culled(si, hit):
        return hit & (dr.gather(mi.UInt32, lut, dr.reinterpret_array(mi.UInt32, si.shape), hit) > 0) & back_face(si)

    def body(ray, si, hit, i):
        go = culled(si, hit)
        ray = dr.select(go, si.spawn_ray(ray.d), ray)
        si2 = scene.ray_intersect(ray, LOCAL_RAY_FLAGS, mi.Bool(True), go)
        return ray, dr.select(go, si2, si), dr.select(go, si2.is_valid(), hit), i + 1

    _, si, hit, _ = dr.while_loop((mi.Ray3f(ray), si, mi.Bool(hit), mi.UInt32(0)),
                                  lambda ray, si, hit, i: culled(si, hit) & (i < MAX_CULLED_LAYERS), body)
    return si, hit


class ReferenceIntegrator(RBIntegrator):
    """The ``local`` and ``path`` estimators with per-pixel moments (see the module docstring)."""

    def __init__(self, props):
        super().__init__(props)
        self.mode = str(props.get("mode", "local"))
        if self.mode not in MODES:
            raise ValueError(f"{INTEGRATOR_NAME}: mode must be one of {MODES}, not {self.mode!r}")
        self.moments = bool(props.get("moments", False))
        self.mis = str(props.get("mis", DEFAULT_MIS))
        if self.mis not in MIS_HEURISTICS:
            raise ValueError(f"{INTEGRATOR_NAME}: mis must be one of {tuple(MIS_HEURISTICS)}, not {self.mis!r}")
        # the environment's proposal (reference.env_sampling): Mitsuba's envmap sampling or compensated
        self.env_sampling = str(props.get("env_sampling", DEFAULT_ENV_SAMPLING))
        if self.env_sampling not in ENV_SAMPLING:
            raise ValueError(f"{INTEGRATOR_NAME}: env_sampling must be one of {ENV_SAMPLING}, "
                             f"not {self.env_sampling!r}")
        self._env_proposal = None  # (the emitter, its CompensatedEnvironment)
        self._env_exact = None  # (the emitter, its ExactEnvironment: the radiance the estimator reads)
        # the environment sample resampled from this many candidates (RIS; 1: the plain sample)
        self.env_candidates = int(props.get("env_candidates", DEFAULT_ENV_CANDIDATES))
        if not 1 <= self.env_candidates <= MAX_ENV_CANDIDATES:
            raise ValueError(f"{INTEGRATOR_NAME}: env_candidates must be in [1, {MAX_ENV_CANDIDATES}], "
                             f"not {self.env_candidates}")
        # > 0: the variance channels from independent replicates of the sensor's sampler (a QMC
        # sampler's samples are not independent), at least this many (replicate_plan); 0: per-sample moments
        self.replicates = int(props.get("replicates", 0))
        # the local estimator's replicates draw from OpaqueMultijitter (a multijitter sensor only)
        self.opaque_sampler = bool(props.get("opaque_sampler", True))
        # render_groups' passes replayed by dr.freeze (reference.frozen; opt-in: no gain measured on the CPU)
        self.freeze = bool(props.get("freeze", False))
        self._frozen = None  # the frozen pass (dr.freeze), made on first use
        self._warm = None  # the shapes of the scene whose caches a traced pass filled
        # local: the BSDFs' parameters gathered per lane, the lobes traced once (bsdf.MaterialView)
        self.gather_materials = bool(props.get("gather_materials", True))
        self._table = None  # (the scene's shapes, MaterialView.table(scene))
        self._switch = None  # (the scene's shapes, {kind: SceneCalls.table(scene, kind)})
        self.path = None
        self._volpath = None
        self.max_depth_value = int(props.get("max_depth", 8))
        if self.mode == "path":
            self.path = mi.load_dict({"type": "path", "max_depth": self.max_depth_value})
        # Called as progress(samples_per_pixel_done) after each pass of a moments render.
        self.progress = None
        # The sensor's world-to-camera transform, set by render() ([brdf] geometric_roughness).
        self._to_view = None

    def to_string(self):
        return (f"ReferenceIntegrator[mode={self.mode}, max_depth={self.max_depth}, moments={self.moments}, "
                f"replicates={self.replicates}, mis={self.mis}, env_sampling={self.env_sampling}, "
                f"env_candidates={self.env_candidates}]")

    # ---- estimators ------------------------------------------------------------------------------
    def _bsdf(self, scene, si, ray, hit):
        """The BSDF of each lane: a :class:`reference.bsdf.MaterialView` (one trace of the lobes for
        every material) where the scene's materials allow it, else Mitsuba's per-instance dispatch."""
        if self.gather_materials:
            # Keyed by the scene's shapes (the same Python objects on every call), not by the scene:
            # a differentiable scene holds this integrator, so holding the scene would be a cycle
            # Python cannot collect (Mitsuba objects take no weak references).
            shapes = scene.shapes()
            if (self._table is None or len(self._table[0]) != len(shapes)
                    or any(a is not b for a, b in zip(self._table[0], shapes))):
                self._table = (tuple(shapes), MaterialView.table(scene))
            if self._table[1] is not None:
                return MaterialView.gather(self._table[1], si, hit)
        table = self._dispatch(scene)
        # no shapes (an environment alone): every lane missed; Mitsuba's null BSDF pointers give zeros
        return SceneCalls(table, si, hit) if table[1] else si.bsdf(ray)

    def _dispatch(self, scene, kind: str = "bsdf"):
        """:meth:`reference.bsdf.SceneCalls.table` of ``scene`` for ``kind``, kept while its shapes
        are the same (keyed by them, as ``_table``): ``"bsdf"``, ``"emitter"``, ``"cull"``
        (:func:`culling_table`) or ``"null"`` (the BSDFs a ray can pass, :func:`can_pass`; the opaque
        ones outside every call)."""
        shapes = scene.shapes()
        if (self._switch is None or len(self._switch[0]) != len(shapes)
                or any(a is not b for a, b in zip(self._switch[0], shapes))):
            self._switch = (tuple(shapes), {})
        if kind not in self._switch[1]:
            if kind == "cull":
                self._switch[1][kind] = culling_table(scene)
            elif kind == "null":
                self._switch[1][kind] = SceneCalls.table(scene, "bsdf", keep=can_pass)
            else:
                self._switch[1][kind] = SceneCalls.table(scene, kind)
        return self._switch[1][kind]

    #: Most surfaces a camera ray passes through (glTF alpha) before the local estimator stops.
    MAX_NULL_LAYERS = 8

    @staticmethod
    def has_null_bsdfs(scene) -> bool:
        """Whether a shape's BSDF can be passed through (a Null component: glTF MASK / BLEND, culled
        back faces)."""
        return any(mi.has_flag(s.bsdf().flags(), mi.BSDFFlags.Null) for s in scene.shapes())

    @staticmethod
    def has_alpha_bsdfs(scene) -> bool:
        """Whether a shape's BSDF has a stochastic opacity (glTF MASK / BLEND)."""
        from .textured import has_alpha
        return any(has_alpha(s.bsdf()) for s in scene.shapes())

    def _first_opaque_hit(self, scene, sampler, ray, si, hit):
        """Continue the ray through each hit with probability ``eval_null_transmission`` (one sample per
        layer), up to :data:`MAX_NULL_LAYERS`; a ray still passing through after that stops at its last
        hit; returns the interaction where it stopped.

        A symbolic loop (one kernel still): a lane iterates only while it passes through surfaces, so
        a lane that stops at its first hit (an OPAQUE primitive, or a MASK texel that is there) or
        misses pays one layer, not :data:`MAX_NULL_LAYERS`. The transmission is called on the BSDFs
        a ray can pass only (:func:`can_pass`: glTF MASK / BLEND, single-sided; the others' is 0,
        given without a call). The random numbers are those of the unrolled layers it replaces
        (``next_1d(going)`` once per layer, :data:`MAX_NULL_LAYERS` times per lane): a lane's
        remaining layers draw with an empty mask after the loop (a sample dimension each, no random
        state consumed), so every later dimension and every image is the same, bit for bit (checked
        under the independent and the multijitter samplers)."""
        null = self._dispatch(scene, "null")
        layers = self.MAX_NULL_LAYERS

        def body(sampler, ray, si, hit, going, i):
            t = mi.Float(SceneCalls(null, si, going).eval_null_transmission(si, going).x)
            u = sampler.next_1d(going)
            through = going & (u < t)
            ray = dr.select(through, si.spawn_ray(ray.d), ray)
            si2 = scene.ray_intersect(ray, LOCAL_RAY_FLAGS, mi.Bool(True), through)
            si = dr.select(through, si2, si)
            hit = dr.select(through, si2.is_valid(), hit)
            return sampler, ray, si, hit, through & hit, i + 1

        # going: lanes still deciding (a lane that stopped at a surface keeps it); i: layers drawn
        sampler, _, si, hit, _, i = dr.while_loop(
            (sampler, mi.Ray3f(ray), si, mi.Bool(hit), mi.Bool(hit), mi.UInt32(0)),
            lambda sampler, ray, si, hit, going, i: going & (i < layers), body)

        def pad(sampler, i):
            sampler.next_1d(mi.Bool(False))
            return sampler, i + 1

        dr.while_loop((sampler, i), lambda sampler, i: i < layers, pad)
        return si, hit

    @staticmethod
    def has_area_emitters(scene) -> bool:
        return any(mi.has_flag(e.flags(), mi.EmitterFlags.Surface) for e in scene.emitters())

    def _geometric(self, scene, bsdf, ray, hit):
        """``bsdf`` with ``[brdf] geometric_roughness`` added to its roughness per lane (then at most
        1), or ``bsdf`` itself when the scene's materials name none."""
        from .textured import GeometricCalls, calls_geometric   # glTF assets (issue 40, model helper's hook)
        geo = bsdf.geometric if isinstance(bsdf, MaterialView) else calls_geometric(bsdf)
        if geo is None or geo[0] == "none":
            return bsdf
        if self._to_view is None or not isinstance(ray, mi.RayDifferential3f):
            raise ValueError(f"{INTEGRATOR_NAME}: [brdf] geometric_roughness needs the camera's ray "
                             "differentials (render through the integrator's render())")
        # the normal's derivatives (dNSdUV) only where asked: the same hit, intersected again
        si_n = scene.ray_intersect(mi.Ray3f(ray), mi.RayFlags.All | mi.RayFlags.dNSdUV, mi.Bool(True), hit)
        g = GEOMETRIC_ROUGHNESS[geo[0]](si_n, ray, geo[1], self._to_view)
        if not isinstance(bsdf, MaterialView):   # the textured materials' calls (reference.textured)
            return GeometricCalls(bsdf, dr.detach(g))
        return bsdf.with_roughness(dr.minimum(bsdf.roughness + dr.detach(g), 1.0))

    def _compensated(self, env):
        """The ``compensated`` proposal of ``env`` (built once per emitter), or None: Mitsuba's own."""
        if env is None or self.env_sampling != "compensated":
            return None
        if self._env_proposal is None or self._env_proposal[0] is not env:
            exact = self._exact(env)
            self._env_proposal = (env, CompensatedEnvironment(env, (exact.H, 2 * exact.H), exact))
        return self._env_proposal[1]

    def _exact(self, env):
        """The exact radiance lookup of ``env`` (:mod:`reference.env_radiance`; built once per emitter)."""
        if self._env_exact is None or self._env_exact[0] is not env:
            self._env_exact = (env, exact_environment(env))
        return self._env_exact[1]

    def local_radiance(self, scene, sampler, ray, active, grad: bool = False):
        """(L, hit) of the local estimator for a wavefront of rays; ``grad``: attach the BSDF values
        to the AD graph (detached sampling, module docstring)."""
        camera_ray = ray
        ray = mi.Ray3f(ray)
        si = scene.ray_intersect(ray, LOCAL_RAY_FLAGS, mi.Bool(True), active)  # coherent: camera rays, pixel-major lanes (Embree packets)
        hit = active & si.is_valid()
        if self.has_alpha_bsdfs(scene):  # glTF MASK / BLEND: the first hit that is there (stochastic; culled back faces too)
            si, hit = self._first_opaque_hit(scene, sampler, ray, si, hit)
        else:  # glTF single-sided back faces: culled (deterministic)
            si, hit = past_back_faces(scene, ray, si, hit, self._dispatch(scene, "cull"))
        env = scene.environment()
        bind_environment(scene)
        L = mi.Color3f(0.0)
        if env is not None:
            exact = self._exact(env)  # the environment's radiance (never Mitsuba's eval: CUDA textures)
            L += exact.radiance(-si.wi, active & ~hit)  # misses: si.wi = -ray.d
        if self.has_area_emitters(scene):  # emissive surfaces (glTF emission) seen at the first hit
            L += dr.select(hit, SceneCalls(self._dispatch(scene, "emitter"), si, hit).eval(si, hit), 0.0)
        ctx = mi.BSDFContext()
        mis = MIS_HEURISTICS[self.mis]
        if self.has_null_bsdfs(scene):  # the surface is there (decided above): shade it as opaque
            ctx.type_mask = int(mi.BSDFFlags.All) & ~int(mi.BSDFFlags.Null)
        with dr.resume_grad(when=grad):  # the gathered parameters carry their instances' gradients
            bsdf = self._geometric(scene, self._bsdf(scene, si, ray, hit), camera_ray, hit)
        proposal = self._compensated(env)
        if env is not None:
            # Environment sample, MIS against the BSDF's density: the one-sample estimate of the
            # proposal's direction, or of the one resampled from env_candidates of them (RIS).
            def env_estimate():
                if proposal is None:
                    # Mitsuba's proposal and pdf; the weight is the exact radiance over that pdf
                    ds, _ = env.sample_direction(si, sampler.next_2d(hit), hit)
                    e_d, e_pdf = ds.d, ds.pdf
                    em_w = dr.select(e_pdf > 0, exact.radiance(e_d, hit) / e_pdf, 0.0)
                else:
                    e_d, e_pdf, em_w = proposal.sample(sampler.next_2d(hit), hit)
                ok = hit & (e_pdf > 0)
                with dr.resume_grad(when=grad):
                    f, bpdf = bsdf.eval_pdf(ctx, si, si.to_local(e_d), ok)
                    w = mis(e_pdf, dr.detach(bpdf))
                    return dr.select(ok, f * em_w * w, 0.0)

            with dr.resume_grad(when=grad):  # (outside it, the sum would drop the estimate's gradient)
                if self.env_candidates == 1:
                    L += env_estimate()
                else:
                    L += resampled_estimate(env_estimate, self.env_candidates, sampler.next_1d(hit))
            # BSDF sample, MIS against the environment's density (delta lobes: weight 1).
            u1, u2 = sampler.next_1d(hit), sampler.next_2d(hit)
            bs, bw = bsdf.sample(ctx, si, u1, u2, hit)
            wo_w = si.to_world(bs.wo)
            delta = mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta)
            Le = exact.radiance(wo_w, hit)
            ds2 = dr.zeros(mi.DirectionSample3f)
            ds2.d = wo_w
            epdf = (env.pdf_direction(si, ds2, hit & ~delta) if proposal is None
                    else proposal.pdf(wo_w, hit & ~delta))
            w = dr.select(delta, 1.0, mis(bs.pdf, epdf))
            ok = hit & (bs.pdf > 0)
            if grad:
                with dr.resume_grad():
                    f_b = bsdf.eval(ctx, si, bs.wo, ok & ~delta)
                    bs_g, bw_g = bsdf.sample(ctx, si, u1, u2, ok & delta)  # mirror: wo fixed
                    pdf0 = dr.detach(bs.pdf)
                    inv = dr.select(pdf0 > 0, dr.rcp(pdf0), 0.0)
                    g = dr.select(delta, bw_g * bs_g.pdf, f_b) * inv
                    bw = dr.replace_grad(bw, g)
                    L += dr.select(ok, bw * Le * w, 0.0)
            else:
                L += dr.select(ok, bw * Le * w, 0.0)
        for emitter in scene.emitters():
            if not mi.has_flag(emitter.flags(), mi.EmitterFlags.Delta):
                continue
            # A punctual light (reference.lights): deterministic direction, weight I / d^2 (a spot's
            # times its glTF attenuation) or E (directional), no shadow ray.
            ds, Li = emitter.sample_direction(si, mi.Point2f(0.5), hit)
            with dr.resume_grad(when=grad):
                f = bsdf.eval(ctx, si, si.to_local(ds.d), hit)
                L += dr.select(hit & (ds.pdf > 0), f * Li, 0.0)
        return L, hit

    def radiance(self, scene, sampler, ray, active):
        """(L, hit) of this integrator's mode (primal)."""
        if self.mode == "local":
            return self.local_radiance(scene, sampler, ray, active)
        cull = self._dispatch(scene, "cull")
        if cull is None:
            hit = scene.ray_test(mi.Ray3f(ray), active)
        else:  # coverage: culled back faces are not there
            si = scene.ray_intersect(mi.Ray3f(ray), LOCAL_RAY_FLAGS, mi.Bool(True), active)
            _, hit = past_back_faces(scene, ray, si, active & si.is_valid(), cull)
            # a kernel of its own: traced into the path integrator's kernel, the loop's copy of the
            # shapes' compute_surface_interaction call was emitted twice (Dr.Jit 1.5: LLVM "invalid
            # redefinition of function")
            dr.eval(hit)
        path = self.path
        from .transmission import has_interior_media   # hook (issue 37): Beer-Lambert inside volumes
        if self.has_null_bsdfs(scene) or has_interior_media(scene):  # shadow rays through glTF cut-outs: volpath's null interfaces
            if self._volpath is None:
                self._volpath = mi.load_dict({"type": "volpath", "max_depth": self.max_depth_value})
            path = self._volpath
        bind_environment(scene)  # (its samples' shadow rays span the scene's bounding sphere)
        L, _, _ = path.sample(scene, sampler, ray, None, active)
        return mi.Color3f(L), hit

    def sample(self, mode, scene, sampler, ray, depth=None, δL=None, δaovs=None, state_in=None,
               active=True, **kwargs):
        active = mi.Bool(active)
        if mode == dr.ADMode.Primal:
            L, hit = self.radiance(scene, sampler, ray, active)
            return L, hit, [], None
        if self.mode != "local":
            raise NotImplementedError(f"{INTEGRATOR_NAME}: derivatives need mode='local'")
        L, hit = self.local_radiance(scene, sampler, ray, active, grad=True)
        with dr.resume_grad():
            attached = dr.grad_enabled(L)  # False when no parameter of the BSDFs is differentiated
            if mode == dr.ADMode.Backward:
                if attached:
                    dr.backward_from(δL * L)
                return mi.Color3f(0.0), hit, [], None
            return (dr.forward_to(L) if attached else mi.Color3f(0.0)), hit, [], None

    # ---- rendering -------------------------------------------------------------------------------
    def render(self, scene, sensor=0, seed=0, spp=0, develop=True, evaluate=True):
        if isinstance(sensor, int):
            sensor = scene.sensors()[sensor]
        self._to_view = sensor.world_transform().inverse()
        if not self.moments:
            return super().render(scene, sensor, seed, spp, develop, evaluate)
        seed = int(seed[0] if isinstance(seed, (tuple, list)) else seed)
        spp = int(spp) or int(sensor.sampler().sample_count())
        if spp < 2:
            raise ValueError("spp must be >= 2 (the variance channels need two samples per pixel)")
        size = sensor.film().crop_size()
        W, H = int(size[0]), int(size[1])
        npix = W * H
        if self.replicates > 0:
            return self._render_replicates(scene, sensor, seed, spp, W, H)
        F64 = dr.float64_array_t(mi.Float)
        with dr.suspend_grad():
            s1 = [dr.zeros(F64, npix) for _ in range(3)]
            s2 = [dr.zeros(F64, npix) for _ in range(3)]
            hits = dr.zeros(F64, npix)
            shift = None
            done = 0
            for k, n in enumerate(pass_sizes(spp, npix)):
                sampler = sensor.sampler().clone()
                sampler.set_sample_count(n)
                sampler.set_samples_per_wavefront(n)
                sampler.seed(pass_seed(seed, k), npix * n)
                ray, weight, _ = self.sample_rays(scene, sensor, sampler)
                L, hit = self.radiance(scene, sampler, ray, mi.Bool(True))
                L = mi.Color3f(L * weight)
                hit = mi.Bool(hit)
                # One kernel for the estimator's outputs: a gather from an unevaluated L would
                # evaluate each channel in a kernel of its own, each re-running the whole
                # estimator (measured: 3 x 1.4 s + 0.2 s for the hits, against 1.5 s at once).
                dr.eval(L, hit)
                pixel = dr.arange(mi.UInt32, npix * n) // n
                if shift is None:
                    # K = each pixel's first sample (so a constant pixel has s1 = s2 = 0 exactly).
                    shift = dr.gather(mi.Color3f, L, dr.arange(mi.UInt32, npix) * n)
                    dr.eval(shift)
                d = L - dr.gather(mi.Color3f, shift, pixel)
                p1 = dr.block_sum(d, n)
                p2 = dr.block_sum(d * d, n)
                ph = dr.block_sum(dr.select(hit, mi.Float(1.0), 0.0), n)
                for c in range(3):
                    s1[c] += F64(p1[c])
                    s2[c] += F64(p2[c])
                hits += F64(ph)
                dr.eval(s1, s2, hits)
                done += n
                if self.progress is not None:
                    self.progress(n)
            out = dr.zeros(mi.Float, npix * len(MOMENT_CHANNELS))
            base = dr.arange(mi.UInt32, npix) * len(MOMENT_CHANNELS)
            for c in range(3):
                mean = s1[c] / spp + F64(shift[c])
                var = dr.maximum(s2[c] - s1[c] * s1[c] / spp, 0.0) / ((spp - 1) * spp)
                dr.scatter(out, mi.Float(mean), base + c)
                dr.scatter(out, mi.Float(var), base + 3 + c)
            dr.scatter(out, mi.Float(hits / spp), base + 6)
            return mi.TensorXf(out, (H, W, len(MOMENT_CHANNELS)))

    def _estimate(self, scene, sensor, sampler, per: int, ids):
        """(L x weight, hit) of one pass of :meth:`render_groups`: ``per`` lanes per pixel of ``ids``."""
        ray, weight = camera_rays(sensor, sampler, per, ids)
        L, hit = self.radiance(scene, sampler, ray, mi.Bool(True))
        # A scene that cannot emit (black environment, no light) makes L a width-1 literal and
        # block_sum would then return one block, not one per pixel: widen to the rays' width
        # (adding a zero literal changes no value).
        lanes_now = dr.width(ray.o)
        return mi.Color3f(L * weight) + dr.zeros(mi.Color3f, lanes_now), mi.Bool(hit) | dr.zeros(mi.Bool, lanes_now)

    def _pass(self, scene, sensor, sampler, per: int, ids):
        """:meth:`_estimate`, traced, or with ``freeze`` (property; opt-in) replayed by ``dr.freeze``
        (:mod:`reference.frozen`) once a traced pass has filled this integrator's caches for the
        scene's shapes; ``per`` and the wavefront's width are part of the recording's key (a
        Python-int size is baked into it)."""
        shapes = tuple(scene.shapes())
        if not self.freeze or self._warm is None or len(self._warm) != len(shapes) or any(
                a is not b for a, b in zip(self._warm, shapes)):
            out = self._estimate(scene, sensor, sampler, per, ids)
            self._warm = shapes if self.freeze else None
            return out
        if self._frozen is None:
            self._frozen = dr.freeze(lambda scene, sensor, sampler, per, ids, width, state:
                                     self._estimate(scene, sensor, sampler, per, ids))
        from .frozen import pass_state

        state = pass_state(self, scene, sensor)
        return self._frozen(scene, sensor, sampler, per, ids, dr.width(ids) * per, state)

    def _replicate_sampler(self, sensor, n: int):
        """The sampler of a replicate of ``n`` samples: the sensor's, or, for the local estimator
        and a ``multijitter`` sensor, :class:`reference.opaque_sampler.OpaqueMultijitter` (the same
        samples, bit for bit, with the count opaque: one kernel for every count, property
        ``opaque_sampler``; the ``path`` mode hands its sampler to Mitsuba's C++ integrator)."""
        base = sensor.sampler()
        if self.mode == "local" and self.opaque_sampler and base.class_name() == "MultijitterSampler":
            if not multijitter_count_ok(n):
                raise ValueError(f"{INTEGRATOR_NAME}: multijitter does not take {n} samples per pixel as they are")
            return OpaqueMultijitter(n)
        sampler = base.clone()
        sampler.set_sample_count(n)
        if int(sampler.sample_count()) != n:
            raise ValueError(f"{INTEGRATOR_NAME}: the sampler takes {int(sampler.sample_count())} "
                             f"samples per pixel, not the replicate's {n}")
        return sampler

    def _render_replicates(self, scene, sensor, seed, spp, W, H):
        """Moments render from K independent replicates of ``spp / K`` samples (:func:`replicate_plan`)."""
        K, n = replicate_plan(spp, self.replicates)
        return self.render_groups(scene, sensor, [(None, K, n, 0)], seed, W, H)

    def render_groups(self, scene, sensor, groups, seed, W, H, variance: bool = True):
        """``(H, W, 7)`` moments (:data:`MOMENT_CHANNELS`) from independent replicates, by groups of
        pixels: ``groups`` = ``[(pixels, K, n, stream), ...]``, ``pixels`` a numpy array of pixel
        indices (row-major; None: every pixel), rendered as K replicates of n samples each.

        The replicates of a group share wavefronts: a pass holds R of them (as many as
        :func:`max_lanes` allows), laid out replicate-major, pixel, then sample, so that each
        (replicate, pixel) is a sequence of its own of the sensor's sampler, which permutes and
        jitters every sequence independently (Mitsuba's ``compute_per_sequence_seed``: a hash of the
        pass seed and the sequence index); pass c is seeded :func:`pass_seed` ``(seed, stream + c)``
        (distinct streams never share samples). A replicate too large for one pass is split in
        :func:`replicate_parts` passes (``advance`` between them: one point set). The pixel means
        ``Y_r`` of the replicates give the estimate ``mean(Y)`` and its variance ``s^2(Y) / K``,
        unbiased because the replicates are i.i.d. A pixel in no group is 0 with variance 0 and
        coverage 0. ``variance`` False (no error bars asked for): K may be 1, the variance channels
        are 0."""
        self._to_view = sensor.world_transform().inverse()
        npix = W * H
        nch = len(MOMENT_CHANNELS)
        out = np.zeros((npix, nch))
        lanes = max_lanes()
        with dr.suspend_grad():
            for pixels, K, n, stream in groups:
                if K < (2 if variance else 1):
                    raise ValueError(f"{INTEGRATOR_NAME}: a replicate render needs K >= 2 replicates, not {K}")
                pix = np.arange(npix, dtype=np.uint32) if pixels is None else np.asarray(pixels, dtype=np.uint32)
                m = len(pix)
                if m == 0:
                    continue
                R = max(1, min(K, lanes // max(m * n, 1)))
                parts = 1 if R > 1 else replicate_parts(n, m, lanes)
                per = n // parts
                y = np.zeros((3, K, m))
                hits = np.zeros(m)
                for c, r0 in enumerate(range(0, K, R)):
                    r1 = min(K, r0 + R)
                    ids = mi.UInt32(np.tile(pix, r1 - r0))
                    sampler = self._replicate_sampler(sensor, n)
                    sampler.set_samples_per_wavefront(per)
                    sampler.seed(pass_seed(seed, stream + c), (r1 - r0) * m * per)
                    for j in range(parts):
                        if j:
                            sampler.advance()
                        L, hit = self._pass(scene, sensor, sampler, per, ids)
                        dr.eval(L, hit)  # one kernel (see render)
                        # channel by channel: a Color3f's block sum first packs its three arrays into
                        # one buffer in a kernel whose offsets are literals (one compile per pass size)
                        p1 = [dr.block_sum(L[c], per) for c in range(3)]
                        ph = dr.block_sum(dr.select(hit, mi.Float(1.0), 0.0), per)
                        dr.eval(p1, ph)
                        y[:, r0:r1, :] += np.stack([np.array(p, dtype=np.float64) for p in p1]).reshape(3, r1 - r0, m)
                        hits += np.array(ph, dtype=np.float64).reshape(r1 - r0, m).sum(0)
                        if self.progress is not None:
                            self.progress(per * m * (r1 - r0) / npix)
                y /= n
                out[pix, 0:3] = y.mean(1).T
                if variance:
                    out[pix, 3:6] = y.var(1, ddof=1).T / K
                out[pix, 6] = hits / (K * n)
            return mi.TensorXf(mi.Float(out.ravel().astype(np.float32)), (H, W, nch))


_REGISTERED: set[str] = set()


def register() -> None:
    """Register ``pbrcheck_reference`` for the current Mitsuba variant (idempotent)."""
    v = mi.variant()
    if v not in _REGISTERED:
        mi.register_integrator(INTEGRATOR_NAME, lambda props: ReferenceIntegrator(props))
        _REGISTERED.add(v)

