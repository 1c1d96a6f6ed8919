"""Time to a trusted verdict: choose the reference's spp so that its noise cannot move a verdict.

A reported error is trusted when the reference's noise floor (``mean_variance``, the mean variance
of its pixel estimates; :func:`compare.metrics.noise_floor`) is at least :data:`NOISE_FLOOR_FACTOR`
times below the smallest error reported against it, the squared error corrected for that floor
(``mse_corrected = MSE - mean_variance``, an unbiased estimate of the error against the converged
image). The floor falls as 1 / spp, so from a render at ``spp`` the spp needed is

    spp_needed = spp x NOISE_FLOOR_FACTOR x mean_variance / min(mse_corrected)

rounded up to a power of two (the cache then reuses the renders of other runs) and capped at
``cap``. **Heavy tails** (:func:`floor_tail_rse`): the floor is a mean of per-pixel variance
estimates, each with few degrees of freedom (K - 1 replicates), so it is only as exact as the number
of pixels that carry it: with Kish's effective number ``n_eff = (sum v_i)^2 / sum v_i^2`` of the
per-pixel variances ``v_i`` on the metric's pixels, its relative standard error is at least
``sqrt(2 / (dof n_eff))`` (the Gaussian value of ``Var(s^2) = sigma^4 (2 / dof + kappa / K)``; heavy
tails, excess kurtosis ``kappa > 0``, only add). A pilot whose floor exceeds
:data:`FLOOR_RSE_MAX` is not trusted to choose the spp: the pilot doubles (up to ``cap``) until it
holds; a final that still exceeds it is flagged **noise-limited (heavy tails)**. This is what a
small bright source does (a sun glint hit by one replicate in a few pixels and missed by all in
others: DamagedHelmet under royal_esplanade at 16 spp, whose floor rested on 1.3-5 pixels and was
20x low). **Pilot / final** (:func:`reference_for_verdict`; Kirk & Arvo 1991): that spp is chosen
on *pilot* renders (seed :func:`pilot_seed`, from the least ``spp`` up), and the reference returned
is a *final* render at it on the caller's seed, always accepted. Re-checking the floor on the
render that is returned and re-rendering when it falls short would keep the renders whose floor
came out low by chance (the floor and the error are estimates): the returned floor would be
biased low and the image selected on its own noise. With the decision a function of the pilots
only, the final is an ordinary render at a fixed spp. Its own ratio is reported; below the factor
(at the cap, or short of the pilot's prediction) the verdict is flagged **noise-limited**. Without a ``cap`` it follows from a time
budget: the largest power of two whose render, at the seconds per spp of the first render
(:func:`seconds_per_spp`: on a CPU its CPU time over its threads, so the load of other processes
does not move it), fits in ``time_budget_s`` (at most :data:`HARD_SPP_CAP`). So a GPU, ~50x
faster, reaches the floor where a CPU stops at the cap (spheres at 360 x 300 needs ~10^4 spp
with independent samples: the default preset's corrected MSE is 1.8e-4, the local estimator's
per-sample variance 0.17). Renders go through the seam ``compare.renderers.render_reference``
(cached by spp and seed), so a re-run costs nothing.

API: :data:`NOISE_FLOOR_FACTOR`, :data:`DEFAULT_SPP_CAP`, :class:`VerdictSpp`, :func:`spp_needed`,
:func:`noise_and_error`, :func:`reference_for_verdict`, :func:`pilot_seed`, :func:`verdict_of`,
:func:`cap_for_time`, :func:`seconds_per_spp`, :data:`MIN_REFERENCE_SPP`, :data:`FLOOR_RSE_MAX`,
:func:`floor_tail_rse`, :func:`variance_dof`.
References: Kish 1965, *Survey Sampling* (effective sample size of a weighted mean); the variance of
a sample variance, ``sigma^4 (2 / (n - 1) + kappa / n)`` (e.g. Casella & Berger, *Statistical
Inference*, ex. 5.8); L'Ecuyer & Lemieux 2002, "Recent advances in randomized quasi-Monte
Carlo methods" (K independent RQMC randomizations: a variance estimate with K - 1 degrees of freedom); Zirr, Hanika & Dachsbacher
2018, "Re-weighting firefly samples for improved finite-sample Monte Carlo estimates" (CGF): rare,
huge samples make a low-spp estimate and its sample variance typically too low; their fix re-weights
(biased), here the spp rises instead. Kirk & Arvo 1991, "Unbiased sampling techniques for image synthesis" (SIGGRAPH): a
sample size chosen from the samples being averaged biases the estimate; a pilot whose samples are
not reused does not.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from pbrcheck.exr import Image

from . import renderers
from .metrics import REL_EPS, TEST_VARIANCE_META, is_display_referred, pixel_classes, validate_pair

#: The least reference spp anything may ask for: the reference renderer needs two samples per pixel
#: for its variance channels (the gate's and the report's floor).
MIN_REFERENCE_SPP = 2
#: The reference's noise floor must sit this far below the smallest error reported against it.
NOISE_FLOOR_FACTOR = 10.0
#: Default largest reference spp a verdict may ask for (beyond it: "noise-limited"). 4096 spp of
#: the spheres scene (360 x 300) is about 22 s on 2 CPU cores (19.8 M samples/s) and well under a
#: second on an H100.
DEFAULT_SPP_CAP = 4096
#: Largest spp a time budget may allow (2^16: 7 G samples on spheres; a few seconds on an H100).
HARD_SPP_CAP = 1 << 16
#: Default time budget of one scene's reference in the report (seconds of rendering on this
#: machine's cores, :func:`seconds_per_spp`): 2048 spp of the spheres scene (360 x 300) on 2 CPU
#: cores (noise-limited, flagged), the whole noise floor (~10^4 spp) in a second of an H100.
DEFAULT_TIME_BUDGET_S = 15.0
#: Errors below this (squared radiance) count as "no error": a preset equal to the reference within
#: float32 rounding would otherwise ask for infinite spp.
MIN_TRUSTED_MSE = 1e-9
#: An error sets the spp only when its corrected MSE exceeds this many standard errors of the MSE
#: estimate (else it is 0 within the noise: a one-sided 3-sigma test, 0.1 % false alarms).
ERROR_Z = 3.0
#: Renders at most per verdict, pilots and the final (:func:`reference_for_verdict`).
MAX_STEPS = 3
#: Added (mod 2^32) to the seed for the pilot renders (:func:`pilot_seed`): they never share
#: random numbers with the returned (final) render.
PILOT_SEED_OFFSET = 1 << 31
#: A further pilot when the final spp the pilot asks for is at least this many times its own ...
PILOT_REFINE = 32
#: ... rendered at the final spp over this (an eighth: a pilot costs ~1/8 of the final).
PILOT_RATIO = 8
#: The research commands' ``probe`` (:func:`reference_for_verdict`): an unresolved error is looked
#: for once more at 16x the spp (a quarter of the noise's standard deviation) before "within noise".
RESEARCH_PROBE = 16
#: Largest relative standard error the noise floor may have for a pilot to choose the spp, and for
#: a final to be trusted (:func:`floor_tail_rse`, a lower bound: the Gaussian value). 0.15: at one
#: sigma the 10x goal then holds at >= 8.7x. Measured (docs/compare.md): the built-in spheres,
#: grazing and furnace at their sizes <= 0.070 (33 cached renders, 16-512 spp), spheres_ci at 64 spp
#: 0.10; DamagedHelmet under royal_esplanade (200 x 150) 0.16-0.33 at 16-512 spp, 0.08-0.31 at 1024.
FLOOR_RSE_MAX = 0.15
#: The error measures the rule can put the noise floor below (:func:`noise_and_error`).
VERDICT_METRICS = ("mse", "relmse")


@dataclass
class VerdictSpp:
    """How the reference spp was chosen (JSON via :meth:`to_dict`, one line via :meth:`provenance`)."""
    spp: int
    noise_floor: float | None
    smallest_error: float | None
    ratio: float | None
    noise_limited: bool
    cap: int
    factor: float = NOISE_FLOOR_FACTOR
    steps: list = field(default_factory=list)  # [[spp, noise floor, smallest error, "pilot" or "final"], ...]
    metric: str = "mse"  # the error measure of floor and error (noise_and_error)
    floor_rse: float | None = None  # the final's floor_tail_rse
    heavy_tails: bool = False  # floor_rse > FLOOR_RSE_MAX: the variance channels are not trusted

    def to_dict(self) -> dict:
        return asdict(self)

    def provenance(self) -> str:
        if self.noise_floor is None:
            return f"{self.spp} spp (no variance channels: noise floor unknown)"
        if self.smallest_error is None:
            s = f"{self.spp} spp: noise floor {self.noise_floor:.3g}; no error above it (every renderer within the noise)"
            if self.heavy_tails:
                s += (f"; NOISE-LIMITED (heavy tails): the noise floor rests on a few pixels (its relative "
                      f"standard error >= {self.floor_rse:.2g}, goal <= {FLOOR_RSE_MAX:g})")
            return s
        r = "inf" if self.ratio is None or math.isinf(self.ratio) else f"{self.ratio:.3g}"
        s = (f"{self.spp} spp: noise floor {self.noise_floor:.3g} = smallest error "
             f"{self.smallest_error:.3g} / {r} (goal >= {self.factor:g}"
             + (f"; {self.metric}" if self.metric != "mse" else "") + ")")
        if self.floor_rse is not None:
            s += f"; floor's relative standard error >= {self.floor_rse:.2g} (goal <= {FLOOR_RSE_MAX:g})"
        if not self.noise_limited:
            return s
        if self.heavy_tails:
            return s + (f"; NOISE-LIMITED (heavy tails): the noise floor rests on a few pixels"
                        + (f" at the cap of {self.cap} spp" if self.spp >= self.cap else ""))
        if self.spp >= self.cap:
            return s + f"; NOISE-LIMITED at the cap of {self.cap} spp"
        return s + "; NOISE-LIMITED: the final render fell short of the pilot's prediction"


def spp_needed(spp: int, floor: float, error: float, factor: float = NOISE_FLOOR_FACTOR) -> float:
    """Samples per pixel at which ``floor`` (measured at ``spp``) is ``error / factor``."""
    if floor <= 0:
        return float(spp)
    if error <= MIN_TRUSTED_MSE:
        return math.inf
    return spp * factor * floor / error


def noise_and_error(ref: Image, tests: list[Image], scene=None,
                    metric: str = "mse") -> tuple[float | None, float | None]:
    """(noise floor of ``ref``, smallest corrected error of ``tests`` against it) by the comparator's
    own masks and noise estimate (those of :func:`compare.metrics.noise_floor`, computed without the
    comparator's costly maps; display-referred images are left out). Errors not resolved above the
    noise (corrected error <= :data:`ERROR_Z` standard errors of its estimate) are left out; None
    when no error is.

    ``metric``: ``"mse"`` (squared radiance: the report and the gate) or ``"relmse"`` (each pixel's
    squared error and variance over ``r^2 + REL_EPS``, the comparator's relmse: what explain, fit-lod
    and hardcases report). The relative form weights dark pixels as the reported metric does, so a
    sun's highlight, whose pixel noise dominates the absolute MSE and its standard error, does not
    hide an error the relative metric reports."""
    if metric not in VERDICT_METRICS:
        raise ValueError(f"verdict metric must be one of {VERDICT_METRICS}, not {metric!r}")
    floor, err = None, None
    if ref.variance is None or is_display_referred(ref):
        return None, None
    var = np.clip(ref.variance.astype(np.float64), 0.0, None)
    r64 = ref.rgb.astype(np.float64)
    weight = 1.0 / (r64 * r64 + REL_EPS) if metric == "relmse" else None
    for t in tests:
        if is_display_referred(t):  # an 8-bit engine: compared in display space, no noise floor
            continue
        validate_pair(ref, t)
        valid = pixel_classes(ref, t)[0]
        if not valid.any():
            continue
        # compare.metrics.noise_floor's mean_variance and mse_corrected, without the maps (FLIP)
        v = var[valid] if weight is None else (var * weight)[valid]
        f = float(v.mean())
        d2 = (t.rgb.astype(np.float64) - r64) ** 2
        if TEST_VARIANCE_META in t.meta and t.variance is not None:
            # a Monte Carlo engine's own noise is not its error (compare.metrics, "noisy image under test")
            d2 = d2 - np.clip(t.variance.astype(np.float64), 0.0, None)
        d2 = (d2[valid] if weight is None else (d2 * weight)[valid]).ravel()
        e = float(d2.mean()) - f
        se = float(d2.std() / math.sqrt(max(d2.size, 1)))  # standard error of the MSE estimate
        floor = f if floor is None else max(floor, f)
        if e <= max(MIN_TRUSTED_MSE, ERROR_Z * se):
            # No error resolved above the noise (an exact preset, e.g. the default on the furnace,
            # whose corrected MSE is 0 +- se): more spp can only bound it, never put the floor 10x
            # below it; it does not set the spp (measured: a chance +1e-7 sent the furnace to the cap).
            continue
        err = e if err is None else min(err, e)
    return floor, err


def variance_dof(ref: Image) -> int:
    """Degrees of freedom of ``ref``'s per-pixel variance estimates: K - 1 for K replicates (the
    ``replicates`` header; adaptive renders name two levels, the smaller counts), else spp - 1 (the
    independent sampler's per-sample moments); at least 1."""
    m = ref.meta
    ks = [int(w) for w in str(m.get("replicates", "")).split() if w.isdigit() and int(w) > 0]
    if ks:
        return max(1, min(ks) - 1)
    try:
        return max(1, int(m.get("spp", 2)) - 1)
    except ValueError:
        return 1


def floor_tail_rse(ref: Image, tests: list[Image], metric: str = "mse") -> float | None:
    """Relative standard error of ``ref``'s noise floor over the pixels that carry it, a lower bound:
    ``sqrt(2 / (dof n_eff))`` with ``dof`` = :func:`variance_dof` and ``n_eff = (sum v_i)^2 / sum v_i^2``
    (Kish) of the per-pixel variances ``v_i`` (summed over channels; relmse-weighted for
    ``metric="relmse"``) on each test's valid pixels (those of :func:`noise_and_error`); the largest over
    ``tests``. A floor carried by a few pixels (a sun glint caught by one replicate) is as uncertain
    as those pixels' own variance estimates: above :data:`FLOOR_RSE_MAX` it cannot be trusted. None
    without variance channels or comparable tests."""
    if metric not in VERDICT_METRICS:
        raise ValueError(f"verdict metric must be one of {VERDICT_METRICS}, not {metric!r}")
    if ref.variance is None or is_display_referred(ref):
        return None
    var = np.clip(ref.variance.astype(np.float64), 0.0, None)
    if metric == "relmse":
        r64 = ref.rgb.astype(np.float64)
        var = var / (r64 * r64 + REL_EPS)
    v = var.sum(axis=-1)
    dof = variance_dof(ref)
    out = None
    for t in tests:
        if is_display_referred(t):
            continue
        validate_pair(ref, t)
        valid = pixel_classes(ref, t)[0]
        x = v[valid]
        s2 = float((x * x).sum())
        if not valid.any() or s2 <= 0.0:
            continue
        n_eff = float(x.sum()) ** 2 / s2
        rse = math.sqrt(2.0 / (dof * n_eff))
        out = rse if out is None else max(out, rse)
    return out


def verdict_of(ref: Image, noise: dict | None, factor: float = NOISE_FLOOR_FACTOR) -> VerdictSpp:
    """The verdict rule applied to a fixed reference (a stored EXR): ``noise`` is one comparison's
    ``summary["noise"]`` (:func:`compare.metrics.noise_floor`); ``noise_limited`` when its floor is
    not ``factor`` times below the corrected MSE, with ``steps`` = ``[[spp, floor, error, spp_needed]]``."""
    try:
        spp = int(ref.meta.get("spp", 0))
    except ValueError:
        spp = 0
    if noise is None:
        return VerdictSpp(spp, None, None, None, False, spp, factor, [])
    floor, err = float(noise["mean_variance"]), float(noise["mse_corrected"])
    if err <= MIN_TRUSTED_MSE:  # no error above the noise: see noise_and_error
        return VerdictSpp(spp, floor, None, None, False, spp, factor, [[spp, floor, None, None]])
    ratio = err / floor if floor > 0 else math.inf
    need = spp_needed(spp, floor, err, factor) if spp else math.nan
    return VerdictSpp(spp, floor, err, ratio, bool(ratio < factor), spp, factor, [[spp, floor, err, need]])


def seconds_per_spp(ref: Image, spp: int) -> float:
    """Seconds one spp of ``ref``'s render takes on this machine's cores, NaN when unknown.

    On Dr.Jit's LLVM backend: the render's CPU time over its thread count (``render_cpu_seconds /
    threads``), i.e. its wall time with the cores to itself: the report renders while the
    external renderers' browsers run in the background, and wall time under that load made the
    same scene's budget 1024 spp in one run and 2048 in another (the cap, and so the cached
    reference and the verdict, followed the machine's load). On a GPU, and for an image without
    those fields, the render's wall time (``render_seconds``, else ``seconds``: an older cache entry)."""
    m = ref.meta
    try:
        if str(m.get("variant", "")).startswith("llvm") and "render_cpu_seconds" in m and int(m.get("threads", 0)) > 0:
            return float(m["render_cpu_seconds"]) / int(m["threads"]) / spp
        return float(m.get("render_seconds", m.get("seconds", "nan"))) / spp
    except ValueError:
        return math.nan


def cap_for_time(ref: Image, spp: int, time_budget_s: float) -> int:
    """The largest power-of-two spp (>= ``spp``, <= :data:`HARD_SPP_CAP`) whose render fits in
    ``time_budget_s`` at the :func:`seconds_per_spp` of ``ref`` (rendered at ``spp``)."""
    per = seconds_per_spp(ref, spp)
    if not (per > 0) or not math.isfinite(per):
        return max(int(spp), DEFAULT_SPP_CAP)
    n = 1 << max(0, int(math.floor(math.log2(max(time_budget_s / per, 1.0)))))
    return int(min(max(n, spp), max(HARD_SPP_CAP, spp)))


def pilot_seed(seed: int) -> int:
    """The seed of the verdict rule's pilot renders for a reference of ``seed``: ``seed +``
    :data:`PILOT_SEED_OFFSET` modulo 2^32 (the renderer's seeds are 32-bit), so a pilot never shares
    random numbers with the returned render and repeated runs hit the cache with the same pilots."""
    return (int(seed) + PILOT_SEED_OFFSET) & 0xFFFFFFFF


def _pow2_at_least(x: float) -> int:
    return 1 << max(0, math.ceil(math.log2(max(x, 1.0))))


def reference_for_verdict(scene, tests: list[Image], *, spp: int, cap: int | None = DEFAULT_SPP_CAP,
                          factor: float = NOISE_FLOOR_FACTOR, time_budget_s: float = DEFAULT_TIME_BUDGET_S,
                          metric: str = "mse", probe: int | None = None, tails: bool = True,
                          **kwargs) -> tuple[Image, VerdictSpp]:
    """The reference of ``scene`` at the lowest power-of-two spp >= ``spp`` (at most ``cap``; None:
    :func:`cap_for_time` of ``time_budget_s``) whose noise floor a pilot predicts to lie ``factor``
    times below the smallest error of ``tests``: a **pilot / final** scheme (Kirk & Arvo 1991).

    Pilot: renders on :func:`pilot_seed` ``(seed)``, from ``spp`` up, measure floor and error and
    choose the final spp (``spp_needed`` with 10 % headroom, a power of two, at most ``cap``); a
    further pilot at ``final / PILOT_RATIO`` when the extrapolation spans more than
    :data:`PILOT_REFINE` times the last pilot's spp (at most :data:`MAX_STEPS` renders in all).
    Final: one render at that spp on ``seed`` itself (the render ``pbrcheck reference --spp N --seed
    seed`` makes, shared through the cache), **always returned**: no decision is made on it, so
    it is an ordinary render at a spp chosen independently of its own samples (unbiased, its
    variance channels unbiased). Its own floor and error are what the :class:`VerdictSpp` reports;
    ``noise_limited`` when its ratio falls short of ``factor`` (at the cap, or, rarely, short of
    the pilot's prediction). **Heavy tails**: a pilot whose :func:`floor_tail_rse` exceeds
    :data:`FLOOR_RSE_MAX` decides nothing (not even "no error above the noise"): the next pilot is
    rendered at twice its spp (at most ``cap``; these doublings do not count in :data:`MAX_STEPS`);
    a final above it is ``noise_limited`` with ``heavy_tails`` (its ``floor_rse`` reported).
    ``tails=False``: no such check (``floor_rse`` None): the research commands, whose images
    of 16-64 px (hard cases: 16 x 16 at 4 spp, K = 2) put the bound above the goal by their few pixels
    and one or two degrees of freedom alone, and which have their own ``probe``.

    ``metric``: the error the floor is compared with (:func:`noise_and_error`: ``"mse"`` or ``"relmse"``).
    ``probe``: when the pilot resolves no error above the noise, pilot once more at ``probe`` times
    the spp (at most ``cap``); when that one resolves none either, the final is rendered at the probe's
    spp (the research commands, whose small images start noisy). None: conclude at once (the report
    and the gate). ``kwargs`` go to ``renderers.render_reference`` (``mode``, ``seed``, ``use_cache``, ...).
    ``steps``: ``[spp, floor, error, "pilot" | "final"]`` per render, in order.
    """
    kwargs.setdefault("use_cache", True)
    kwargs.setdefault("progress", False)
    seed = int(kwargs.pop("seed", 0))
    pseed = pilot_seed(seed)
    cur = int(spp)
    steps: list = []
    probed = False
    tail_steps = 0
    while True:  # the pilot: decides the final spp, never returned
        pil = renderers.render_reference(scene, spp=cur, seed=pseed, **kwargs)
        if cap is None:
            cap = cap_for_time(pil, cur, time_budget_s)
        cap = max(int(cap), int(spp))
        floor, err = noise_and_error(pil, tests, scene=scene, metric=metric) if tests else (None, None)
        steps.append([cur, floor, err, "pilot"])
        rse = floor_tail_rse(pil, tests, metric=metric) if tails and tests and floor is not None else None
        if rse is not None and rse > FLOOR_RSE_MAX and cur < cap:
            # Heavy tails: this pilot's floor is too uncertain to choose by (nor its "no error above the
            # noise"); double. Its own budget of renders (doublings up to the cap, ~2x the last pilot's cost).
            tail_steps += 1
            cur = int(min(cur * 2, cap))
            continue
        if (probe and not probed and err is None and floor is not None and math.isfinite(floor) and floor > 0
                and cur < cap and len(steps) - tail_steps < MAX_STEPS - 1):
            probed = True
            cur = int(min(cur * int(probe), cap))
            continue
        if floor is None or err is None or not (math.isfinite(floor) and math.isfinite(err)):
            final = cur  # nothing to set the spp by (a non-finite image is the hard cases' finding)
            break
        need = spp_needed(cur, floor, err, factor)
        if need <= cur:
            final = cur
            break
        # 10 % headroom: the floor and the error are themselves estimates.
        final = int(min(max(_pow2_at_least(min(need * 1.1, float(cap))), cur * 2), cap))
        if final >= PILOT_REFINE * cur and len(steps) - tail_steps < MAX_STEPS - 1:
            cur = final // PILOT_RATIO  # a long extrapolation: pilot again nearer the final
            continue
        break
    ref = renderers.render_reference(scene, spp=final, seed=seed, **kwargs)
    floor, err = noise_and_error(ref, tests, scene=scene, metric=metric) if tests else (None, None)
    steps.append([final, floor, err, "final"])
    rse = floor_tail_rse(ref, tests, metric=metric) if tails and tests and floor is not None else None
    heavy = bool(rse is not None and rse > FLOOR_RSE_MAX)
    if floor is None or err is None or not (math.isfinite(floor) and math.isfinite(err)):
        return ref, VerdictSpp(final, floor, err, None, heavy, cap, factor, steps, metric, rse, heavy)
    ratio = err / floor if floor > 0 else math.inf
    return ref, VerdictSpp(final, floor, err, ratio, bool(ratio < factor) or heavy, cap, factor, steps, metric,
                           rse, heavy)


def noise_floor_of(ref: Image) -> float | None:
    """Mean variance of ``ref``'s pixel estimates over all pixels (None without variance channels)."""
    return None if ref.variance is None else float(np.mean(np.clip(ref.variance, 0.0, None)))
