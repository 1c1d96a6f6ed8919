"""``pbrcheck fit-roughness``: apparent roughness of a real-time preset, through the differentiable
reference.

The real-time image of the scene is the target. Every object's roughness in the reference
(:mod:`reference.diff`: the ``local`` estimator as the differentiable integrator
``pbrcheck_reference``; until REFERENCE_CODE_VERSION 2 Mitsuba's ``prb``, ``max_depth`` 2) is
optimized jointly with Dr.Jit AD and ``mi.ad.Adam`` (the estimator has no visibility, so objects do
not interact and the joint fit is a per-object fit). Each object starts at its own roughness; the result ``r*`` is the
roughness the reference needs to look like the preset. ``r* > r``: the preset looks blurrier than
the material it was given; ``r* < r``: sharper. The per-object loss is the final render's loss over
the object's pixels (object AOV of the real-time image).

The loss is the MSE of ``log(1 + x)``-tone-mapped images, linearized at the *target*::

    L = mean over pixels and channels of (I - T)^2 / (1 + T)^2      (~ mean (log(1+I) - log(1+T))^2)

``T`` is the real-time image (deterministic), so the weights are fixed and ``L`` is a weighted L2:
its gradient from a noisy render is unbiased (the log of a noisy render would not be). Why not the
alternatives, measured on one metal sphere (24 px, 8-degree sun of radiance 60, target = the
reference at r = 0.2, 24 gradients of 16 spp each at r = 0.1 and 48 at r = 0.15):

* plain L2: the sun's highlight (a pixel or two) holds nearly all of the loss and its pixel-sampling
  noise swamps the gradient: mean -0.25, deviation 2.9, 58 % of single gradients point the wrong way
  at r = 0.1 (Adam walked to r* = 0.05). Tone-mapped: 31 % wrong at 0.1, 23 % at 0.15.
* the comparator's relmse, ``(I - T)^2 / (T^2 + REL_EPS)``: 12 % wrong, and the best self-consistency
  (metal sphere at 48 px, targets r = 0.03 ... 0.8: |r* - r| <= 0.020 against 0.045 for the
  tone-mapped loss; dielectrics 0.058 for both), but it weights near-black pixels 100 x, where the real-time image differs from the
  reference for reasons roughness cannot fix (prb's shadow rays let neighbours occlude the environment;
  the real-time image, like the ``local`` reference, has no such visibility): on the
  spheres scene's default preset it gave r = 0.2 -> r* = 0.11, 0.63, 0.70, 0.25 on the four metallic
  rows; the tone-mapped loss gives 0.06, 0.21, 0.28, 0.22 and r = 0.4 -> 0.44 ... 0.52.

Start: the loss is not convex in roughness far from its minimum (same sphere, target r = 0.1: it
rises to r = 0.4 and falls again to r = 0.6), so each object's loss is first scanned over
``SCAN_ROUGHNESS`` and its own roughness (:func:`scan_start`: two independent primal renders per
value, all objects at one value per render, each object's loss over its own pixels: roughness does
not couple objects at this depth). Adam starts at the best value and stays in the scan's range
(:func:`bracket`); the learning rate decays from ``LR`` to ``LR_FINAL`` and r* is the mean of the
last ``AVERAGE_LAST`` iterates (:func:`reference.diff.fit_materials`).
"""

from __future__ import annotations

import math
import time

import numpy as np

from pbrcheck.brdf import DELTA_LOBE_ALPHA
from pbrcheck.environment import scene_hash
from pbrcheck.fmt import TABLE_DIGITS, format_value
from pbrcheck.scene import Scene, scene_from_dict
from reference.diff import fit_materials, load_differentiable_scene, param_key, render_image
from reference.render import _mi, render_uncached

from .. import renderers
from .results import ApparentRoughness, FitRoughnessResult

#: Lowest roughness the fit may reach. Below sqrt(DELTA_LOBE_ALPHA) = 0.01 the reference BSDF is a
#: Dirac mirror lobe (reference/bsdf.py) whose value does not depend on roughness: no derivative, and
#: Mitsuba's prb raises when no fitted parameter is attached. A mirror material's r* reads "as sharp
#: as roughness 0.01". 5 % above the threshold: 0.01 squared in float32 is 9.99e-5, still a mirror.
ROUGH_MIN = 1.05 * math.sqrt(DELTA_LOBE_ALPHA)
ITERATIONS = 40
LR = 0.01
#: Final learning rate of the geometric decay: the last iterates move by about this much per step.
LR_FINAL = 0.002
#: r* is the mean of the last iterates (their Monte Carlo jitter averages out).
AVERAGE_LAST = 10
SPP = 16
#: Roughness values of the starting scan (denser where the image changes fastest, at low roughness).
SCAN_ROUGHNESS = (ROUGH_MIN, 0.03, 0.06, 0.1, 0.15, 0.2, 0.27, 0.35, 0.45, 0.57, 0.7, 0.85, 1.0)
#: Samples per pixel of the scan's renders, as a multiple of the fit's spp.
SCAN_SPP_FACTOR = 4
#: A scanned value is "indistinguishable" from the best when its loss is within this many combined
#: standard errors (two-sided 95 %).
SCAN_Z = 1.96


def _weight(t):
    """Per-pixel weight of the fit's loss: the derivative of log(1 + x) at the target, squared."""
    return 1.0 / ((1.0 + t) * (1.0 + t))


def fit_loss(img, target):
    """The fit's loss: mean (I - T)^2 / (1 + T)^2, T the (fixed) target (Dr.Jit tensors)."""

    _, dr = _mi()
    return dr.mean(dr.square(img - target) * _weight(target), axis=None)


def fit_loss_np(img: np.ndarray, target: np.ndarray) -> float:
    """numpy twin of :func:`fit_loss` (for per-object losses over masked pixels)."""
    return float(np.mean((img - target) ** 2 * _weight(target)))


def _object_losses(img: np.ndarray, target: np.ndarray, masks: list[np.ndarray]) -> list[float | None]:
    return [fit_loss_np(img[m], target[m]) if m.any() else None for m in masks]


def unbiased_fit_loss(a: np.ndarray, b: np.ndarray, target: np.ndarray) -> tuple[float, float]:
    """(estimate, standard error) of the fit's loss of the *expected* render against ``target``,
    from two independent renders ``a`` and ``b`` (pixels of one object, (N, 3)).

    ``E[(a - T)(b - T)] = (E[I] - T)^2`` when ``a`` and ``b`` are independent, while the one-render
    ``E[(a - T)^2]`` adds ``Var[I]``, which grows with roughness (the sun's highlight spreads over more
    pixel-sampling noise): measured on a 24-px metal sphere under an 8-degree sun, the 64-spp
    variance in relmse units is 0.00016 at r = 0.02 and 0.00049 at r = 0.08 while the relmse differs
    by 0.0004 between them, so a one-render scan picked r = 0.03 for a target of r = 0.08.

    The standard error is that of the Monte Carlo noise (not the spread over pixels): with
    ``a = mu + e_a``, ``b = mu + e_b`` (independent, variance ``s2``), each term ``(a - T)(b - T)`` has
    variance ``2 (mu - T)^2 s2 + s2^2``. With ``d = (a + b) / 2 - T`` (``E[d^2] = (mu - T)^2 + s2 / 2``)
    and ``(a - b)^2 / 2`` (mean ``s2``, independent of ``d`` for Gaussian noise), ``d^2 (a - b)^2``
    has exactly that mean. The terms are independent across pixels (independent pixel samples)."""
    w = _weight(target)
    terms = (a - target) * (b - target) * w
    d = 0.5 * (a + b) - target
    n = terms.size
    se = float(math.sqrt(np.sum(w * w * d * d * (a - b) ** 2)) / n) if n else math.inf
    return float(terms.mean()), se


def bracket(scan: list[list[float]]) -> tuple[float, list[float]]:
    """(start, [lo, hi]) from a scan ``[[r, loss, se], ...]`` sorted by ``r``.

    ``start`` is the value with the lowest upper confidence bound ``loss + SCAN_Z se``, not the lowest
    estimate: the minimum of noisy estimates favours the noisiest (measured: a dielectric's r = 0.03
    scored -0.00016 +- 0.0029, a firefly, against 0.00004 +- 0.0003 at the target's r = 0.2). The run of
    neighbours whose loss is within ``SCAN_Z`` combined standard errors of the start's is what this
    image size and sample count cannot tell apart; ``[lo, hi]`` extends it to the first value on
    either side that the scan does tell apart (the loss is unimodal around its minimum in every case
    measured), so it holds the minimum even between grid values."""
    if not scan:
        raise ValueError("bracket: empty scan")
    b = min(range(len(scan)), key=lambda j: scan[j][1] + SCAN_Z * scan[j][2])

    def close(j):
        return scan[j][1] <= scan[b][1] + SCAN_Z * math.hypot(scan[j][2], scan[b][2])

    lo = hi = b
    while lo > 0 and close(lo - 1):
        lo -= 1
    while hi < len(scan) - 1 and close(hi + 1):
        hi += 1
    return scan[b][0], [scan[max(lo - 1, 0)][0], scan[min(hi + 1, len(scan) - 1)][0]]


def scan_renders(ms, params, keys: list[str], candidates: list[float], *, spp: int) -> list[tuple]:
    """``[(r, a, b), ...]``: two independent primal renders (H, W, 3) per candidate roughness ``r``, every
    object set to it at once (roughness does not couple objects at this depth). They depend on the
    scene and not on the target, so one scan serves every preset fitted on the same scene and size
    (:func:`run_fit_roughness`'s ``scan_cache``)."""
    mi, _ = _mi()
    out = []
    for j, g in enumerate(candidates):
        for k in keys:
            params[k] = mi.Float(g)
        params.update()
        a = render_image(ms, params, spp=spp, seed=50_000 + 2 * j)
        b = render_image(ms, params, spp=spp, seed=50_001 + 2 * j)
        out.append((g, a, b))
    return out


def scan_start(ms, params, keys: list[str], target: np.ndarray, masks: list[np.ndarray], own: list[float], *,
               spp: int, grid=SCAN_ROUGHNESS, renders: list[tuple] | None = None) -> list[dict]:
    """Per object, the unbiased loss (:func:`unbiased_fit_loss`) of every value among ``grid`` and the
    object's own roughness (:func:`scan_renders`, or ``renders`` already made for those values), and
    its :func:`bracket`. Returns per object ``{"start", "range": [lo, hi], "scan": [[r, loss, se], ...]}``
    (``range`` None for an object with no pixels)."""

    candidates = sorted({float(g) for g in grid} | set(own))
    if renders is None or [r[0] for r in renders] != candidates:
        renders = scan_renders(ms, params, keys, candidates, spp=spp)
    table: list[list[list[float]]] = [[] for _ in keys]
    for g, a, b in renders:
        for i, m in enumerate(masks):
            if m.any():
                table[i].append([g, *unbiased_fit_loss(a[m], b[m], target[m])])
    out = []
    for i, rows in enumerate(table):
        if rows:
            start, rng = bracket(rows)
            # The range as the float32 values the fit clamps its parameter to (Dr.Jit's Float): a
            # bound such as 0.0105 is 0.010499999858 in float32, and the fitted value clamped there
            # must read as inside the range it reports.
            rng = [float(np.float32(x)) for x in rng]
            out.append({"start": start, "range": rng, "scan": rows})
        else:
            out.append({"start": own[i], "range": None, "scan": []})
    return out


def fit_roughness(scene: Scene, target_rgb: np.ndarray, object_ids: np.ndarray, *, iterations: int = ITERATIONS,
                  lr: float = LR, spp: int = SPP, start=None,
                  scan: bool = True, scan_cache: dict | None = None) -> tuple[list[ApparentRoughness], list[float]]:
    """Fit every object's reference roughness to ``target_rgb`` (H, W, 3); one row per object.

    Each object starts at ``start[i]`` (default: its own roughness) or, with ``scan``, at the best of
    that and :data:`SCAN_ROUGHNESS` (:func:`scan_start`). ``scan_cache``: a dict shared by fits of the
    same scene (any targets): the scan's renders are made once and kept there (by scene content,
    candidates and spp).

    Returns
    -------
    rows : list of ApparentRoughness
        One per object, in scene order.
    trace : list of float
        The optimizer's whole-image loss per iteration.
    """

    mi, _ = _mi()
    target = np.asarray(target_rgb, np.float32)
    ms, params = load_differentiable_scene(scene, spp=spp)
    keys = [param_key(i, "roughness") for i in range(len(scene.objects))]
    masks = [np.rint(object_ids) == i for i in range(len(scene.objects))]
    own = [float(np.clip(scene.objects[i].material.roughness if start is None else start[i], ROUGH_MIN, 1.0))
           for i in range(len(keys))]
    scans = None
    if scan and keys:
        candidates = sorted({float(g) for g in SCAN_ROUGHNESS} | set(own))
        ck = (scene_hash(scene), tuple(candidates), SCAN_SPP_FACTOR * spp)
        renders = (scan_cache or {}).get(ck)
        if renders is None:
            renders = scan_renders(ms, params, keys, candidates, spp=SCAN_SPP_FACTOR * spp)
            if scan_cache is not None:
                scan_cache[ck] = renders
        scans = scan_start(ms, params, keys, target, masks, own, spp=SCAN_SPP_FACTOR * spp, renders=renders)
    r0 = [sc["start"] for sc in scans] if scans else own
    for k, r in zip(keys, r0):
        params[k] = mi.Float(r)
    params.update()
    # With a scan, Adam stays inside the scan's bracket: where the loss is flat within the noise,
    # stochastic iterates drift towards the roughness whose gradient is least noisy (lower for
    # metals under a sun, higher for dielectrics: measured, a dielectric sphere fitted from 0.03 ended
    # at 0.10 for every target in [0.03, 0.2]); the bracket bounds that drift by what the data tell.
    bounds = {k: (sc["range"][0], sc["range"][1]) if sc["range"] else (ROUGH_MIN, 1.0)
              for k, sc in zip(keys, scans)} if scans else (ROUGH_MIN, 1.0)
    losses = fit_materials(ms, params, keys, target, iterations=iterations, lr=lr,
                           spp=spp, clamp=bounds, loss_fn=fit_loss, lr_final=min(lr, LR_FINAL),
                           average_last=AVERAGE_LAST)
    final = render_image(ms, params, spp=4 * spp, seed=10_000)
    rows = []
    for i, (ob, k, loss) in enumerate(zip(scene.objects, keys, _object_losses(final, target, masks))):
        rows.append(ApparentRoughness(i, ob.name, float(ob.material.roughness), r0[i],
                                      float(np.array(params[k]).ravel()[0]), loss, int(masks[i].sum()),
                                      range=scans[i]["range"] if scans else None,
                                      scan=scans[i]["scan"] if scans else None))
    return rows, list(losses)


def fit_scene(scene: Scene, size: int | None) -> Scene:
    """``scene`` at image height ``size`` (width keeps the aspect; None: as it is): the scene
    :func:`run_fit_roughness` renders the target of and fits."""
    if size is None:
        return scene
    return scene.with_camera(width=max(8, round(size * scene.camera.width / scene.camera.height)), height=int(size))


def run_fit_roughness(scene: Scene, *, preset: str = "default", options: dict | None = None,
                      size: int | None = None, iterations: int = ITERATIONS, lr: float = LR, spp: int = SPP,
                      scan: bool = True, scan_cache: dict | None = None,
                      context: renderers.RenderContext = renderers.DIRECT) -> FitRoughnessResult:
    """The preset's real-time image of ``scene`` (height ``size``) as the target of :func:`fit_roughness`:
    per object ``roughness``, ``start``, ``apparent_roughness``, ``loss`` (:func:`fit_loss` over its
    pixels), ``pixels`` and, with ``scan``, ``range`` and ``scan`` (``[[r, loss, se], ...]``).
    ``scan_cache``: one dict passed to every preset's fit on the same scene shares the scan's renders."""
    scene = fit_scene(scene, size)
    img = renderers.render_under_test(scene, renderers.RendererSpec.parse(preset, options), progress=False,
                                      context=context)
    rows, trace = fit_roughness(scene, img.rgb, img.channels["object"], iterations=iterations, lr=lr, spp=spp,
                                scan=scan, scan_cache=scan_cache)
    return FitRoughnessResult(scene.name, preset, dict(options or {}), iterations, lr, min(lr, LR_FINAL),
                              AVERAGE_LAST, spp, scan, "tone_mse", [scene.camera.width, scene.camera.height],
                              rows, trace)


def table_markdown(res: FitRoughnessResult) -> str:
    """Per object r, r*, their difference, the range and the loss as a Markdown table."""
    lines = [f"scene {res.scene}, preset {res.preset}", "",
             "| object | roughness r | apparent r* | r* - r | range | loss (tone-mapped MSE) |",
             "| --- | --- | --- | --- | --- | --- |"]
    for r in res.objects:
        loss = format_value(r.loss, TABLE_DIGITS)
        rng = f"[{r.range[0]:.3g}, {r.range[1]:.3g}]" if r.range else "n/a"
        lines.append(f"| {r.name or r.object} | {r.roughness:.3f} | {r.apparent_roughness:.3f} | "
                     f"{r.apparent_roughness - r.roughness:+.3f} | {rng} | {loss} |")
    return "\n".join(lines) + "\n"


#: Roughness values of ``pbrcheck bench fit-roughness`` (the figures in docs/research.md).
SELF_CHECK_ROUGHNESS = (0.03, 0.05, 0.08, 0.1, 0.15, 0.2, 0.3, 0.5, 0.8)


def sphere_under_sun(size: int, roughness: float, *, sun_deg: float = 8.0, sun_radiance: float = 60.0,
                     metallic: float = 1.0, base_color=(0.9, 0.6, 0.3), env_resolution=(512, 256)) -> Scene:
    """One sphere filling a size x size image under a sky with a sun (the self-check's and the tests'
    scene)."""
    return scene_from_dict({
        "camera": {"origin": [0, 0, 4], "fov": 40, "width": int(size), "height": int(size)},
        "environment": {"type": "sky", "sun_direction": [0.3, 0.8, 0.5], "sun_angular_diameter": float(sun_deg),
                        "sun_radiance": [float(sun_radiance)] * 3, "resolution": [int(x) for x in env_resolution]},
        "objects": [{"type": "sphere", "radius": 1.0,
                     "material": {"base_color": [float(c) for c in base_color], "metallic": float(metallic),
                                  "roughness": float(roughness)}}]})


def self_check(*, size: int = 48, sun_deg: float = 8.0, sun_radiance: float = 60.0, metallic: float = 1.0,
               roughness=SELF_CHECK_ROUGHNESS, start: float = 0.5, target_spp: int = 1024) -> dict:
    """Fit roughness against the reference itself: one sphere (base colour 0.9, 0.6, 0.3) under a sky
    with a sun, target = the ``local`` reference at each roughness (``target_spp``), the fit started at
    ``start``. Per roughness: r*, its error, the range and whether it holds the truth; the maximum
    and rms error and the seconds per fit."""
    rows = []
    for r in roughness:
        scene = sphere_under_sun(size, r, sun_deg=sun_deg, sun_radiance=sun_radiance, metallic=metallic)
        target = render_uncached(scene, spp=target_spp, progress=False)
        t0 = time.perf_counter()
        (row,), _ = fit_roughness(scene, target.rgb, target.channels["object"], start=[start])
        lo, hi = row.range
        rows.append({"roughness": float(r), "apparent_roughness": row.apparent_roughness,
                     "error": row.apparent_roughness - float(r), "range": [lo, hi],
                     "truth_in_range": bool(lo <= r <= hi), "seconds": round(time.perf_counter() - t0, 2)})
    err = np.array([x["error"] for x in rows])
    return {"size": int(size), "sun_angular_diameter": float(sun_deg), "sun_radiance": float(sun_radiance),
            "metallic": float(metallic), "start": float(start), "target_spp": int(target_spp), "rows": rows,
            "max_abs_error": float(np.max(np.abs(err))), "rms_error": float(np.sqrt(np.mean(err ** 2))),
            "truth_in_range": sum(x["truth_in_range"] for x in rows)}
