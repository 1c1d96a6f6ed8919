"""Image comparison: valid-pixel masking, per-pixel error maps and their summaries.

Notation: ``r`` is the reference, ``t`` the test image, both linear RGB; every mean below is over
the *valid* pixels (see :func:`pixel_classes`) and over the three RGB channels, ``eps`` is
:data:`REL_EPS`.

* ``mean_abs`` = mean |t - r|
* ``rmse``     = sqrt(mean (t - r)^2)
* ``relmse``   = mean (t - r)^2 / (r^2 + eps)
* ``smape``    = mean |t - r| / (|t| + |r| + eps)
* ``rel_p50``, ``rel_p95``, ``rel_p99``, ``rel_max``: percentiles (linear interpolation) and the
  maximum of |t - r| / (r + eps) over valid pixels and channels
* ``psnr``     = 10 log10(peak^2 / mean (t - r)^2), ``peak`` = the 99.9th percentile of the
  reference's luminance Y = 0.2126 R + 0.7152 G + 0.0722 B over valid pixels (a robust "white":
  the plain maximum of an HDR image is a sun or a firefly). +inf for identical images (``null``
  in JSON).
* ``flip_mean``: mean over valid pixels of the HDR-FLIP error map (NVIDIA flip-evaluator, default
  67 pixels per degree, ACES tone mapper). FLIP is spatial, so it is evaluated on the whole image
  and only then averaged over the valid pixels. Negative radiance is clipped to 0 first.
* ``delta_e_itp_mean``, ``delta_e_itp_p95``: ITU-R BT.2124 Delta E_ITP per valid pixel: linear
  sRGB/Rec.709 is converted to Rec.2020, scaled so that 1.0 = :data:`ITP_NITS_PER_UNIT` cd/m2,
  negatives clipped to 0, encoded as ICtCp (SMPTE ST 2084 / PQ) and compared
  (``720 sqrt(dI^2 + (dT/2)^2 + dP^2)``); mean and 95th percentile.

Display-referred images (an external renderer that can only give 8-bit sRGB, ``output =
"png-srgb"``, metadata ``display_referred = "1"``): both images are compared in display space, the
reference clamped to [0, 1] and sRGB-encoded as the engine did, without the noise floor;
``summary["space"]`` is ``display-referred`` (else ``linear``).

FLIP maps are memoized per process by content (:data:`MAP_MEMO_SIZE`) and, where the caller asks
(``compare_images(..., flip_cache=True)``: the report), kept on disk by content. flip-evaluator
runs on OpenMP threads; unless the environment says otherwise they wait passively
(:data:`FLIP_OMP_WAIT_POLICY`): libgomp's default spins a waiting thread, which on a busy 2-core
machine costs ~30 % more CPU per map for the same map (measured: 0.62 against 0.43 CPU-s).

Noise floor (when the reference has ``variance.R/G/B``, the variance of its pixel estimate):
``mean_variance`` = mean of the variance channels over valid pixels; ``mse_corrected`` =
mean (t - r)^2 - mean_variance (an unbiased estimate of the squared error against the converged
image when ``t`` is noise-free). For the per-metric flag every metric is also evaluated on a
simulated pair ``(r, r + sqrt(2 var) z)`` with a fixed-seed standard normal ``z``: the difference
two independent renders with the reference's variance would show. A metric is flagged
``within_noise`` when its value is no worse than :data:`NOISE_EXPLAINS_FACTOR` times that simulated
value (for ``psnr``, higher is better: no lower than the simulated value less
10 log10(NOISE_EXPLAINS_FACTOR) dB).

A noisy image under test (a Monte Carlo engine: ``variance.R/G/B`` channels on the test, the
variance of its pixel estimate, from the renderer contract's variance image or its N independent
renders, docs/renderers.md): its own noise is not its error. With ``v_t`` that variance and ``t`` an
unbiased estimate, ``E[(t - r)^2] = (mu_t - r)^2 + v_t`` for a fixed ``r``, so every squared metric
subtracts the expected contribution exactly as ``mse_corrected`` subtracts the reference's:
``relmse`` = mean ((t - r)^2 - v_t) / (r^2 + eps), ``rmse`` = sqrt(max(mean (t - r)^2 - mean v_t, 0))
and ``psnr`` from that MSE (each clipped at 0; over every mask: objects, materials, NdotV bins).
``summary["test_noise"]`` says so (``mean_variance``, ``relmse`` of the noise alone, the raw
``metrics_raw``, and which metrics were corrected: :data:`TEST_NOISE_CORRECTED`); the others
(``mean_abs``, ``smape``, percentiles, FLIP, Delta E_ITP) have no closed form and stay raw, and
their ``within_noise`` flags carry the test's noise: the simulated pair is
``(r, r + sqrt(2 var + v_t) z)``, its squared metrics corrected by ``v_t`` like the test's.
``mse_corrected`` subtracts both variances. Without a test variance nothing changes. A test's
variance is subtracted when the test carries :data:`TEST_VARIANCE_META` (the renderer contract's
mark) or the caller asks (``subtract_test_noise=True``); a pbrcheck reference compared as a test keeps
its raw figures unless asked (the convergence study compares them with its variance prediction).

The metric registry :data:`METRICS` (name -> :class:`Metric`: reduction, better direction, noise
power) is the one place a metric's properties live: the comparator computes its entries, the gate
(:mod:`compare.gate`) validates budgets and scales noise with it, the report's tables list it.
"""

from __future__ import annotations

import hashlib
import os
import importlib.metadata
import json
import math
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pbrcheck.cache import Cache, cache_key
from pbrcheck.errors import CacheError, PbrcheckError
from pbrcheck.exr import ENGINE_VARIANCE_META, RGB, VARIANCE, Image

from .maps import srgb_oetf
from .worktime import work

# --- tolerances and constants (each with its reason) -------------------------------------------

#: Added to denominators of relative metrics: keeps near-black pixels (whose relative error is
#: meaningless) from dominating; 0.01 is 1 % of a diffuse white under unit radiance.
REL_EPS = 0.01
#: A pixel is "fully covered" when its coverage AOV is at least this. Coverage is a mean of
#: per-sample hits; 1e-3 below 1 absorbs float32 rounding of that mean while a pixel missing even
#: one of 256 samples (coverage <= 0.996) already counts as a partial silhouette pixel.
FULL_COVERAGE = 0.999
#: Percentile of the reference luminance used as the PSNR peak: robust against a visible sun or a
#: firefly, which the plain maximum of an HDR image would be.
PSNR_PEAK_PERCENTILE = 99.9
#: Scale of the Delta E_ITP conversion: linear value 1.0 is 100 cd/m2 (SDR reference white).
ITP_NITS_PER_UNIT = 100.0
#: A metric within this factor of its value on a simulated noise-only pair is "explained by the
#: reference's noise". > 1 because the simulated metric is itself a random estimate (tail
#: percentiles and the maximum fluctuate by tens of percent) and the real difference is correlated
#: with the reference's own noise, which the simulation ignores.
NOISE_EXPLAINS_FACTOR = 1.5
#: Seed of the noise simulation (the flag must be deterministic).
NOISE_SEED = 12345
#: Number of equal-width NdotV bins over [0, 1].
NDOTV_BINS = 10
#: Luminance weights (Rec.709 / sRGB primaries), also what FLIP uses.
LUMA = np.array([0.2126, 0.7152, 0.0722])


@dataclass(frozen=True)
class Metric:
    """One image metric, as the comparator computes it and the gate and the report read it.

    ``reduction``: how the per-pixel error becomes one number (the formulas: module docstring).
    ``higher_is_better``: the better direction (``psnr``; every other metric: smaller is better).
    ``noise_power``: the metric of a noise-only pair scales as ``var ** (1 / noise_power)``, i.e. as
    ``spp ** (-1 / noise_power)``: 1 for a metric of squared errors normalised per pixel (``relmse``
    is a mean of ``(t - r)^2 / (r^2 + eps)``: the variance itself, 1 / spp), 2 for one of absolute
    errors or their root (a standard deviation: 1 / sqrt(spp)). The gate's budget-against-noise
    figures (:func:`compare.gate.evaluate.budget_noise`) read it.
    """

    name: str
    reduction: str
    higher_is_better: bool = False
    noise_power: float = 2.0


#: The metric registry, in table order: name -> :class:`Metric`. The comparator computes exactly
#: these (:func:`summarize`), budgets may name only these, the report's tables show them.
METRICS: dict[str, Metric] = {m.name: m for m in (
    Metric("mean_abs", "mean |t - r|"),
    Metric("rmse", "sqrt(mean (t - r)^2)"),
    Metric("relmse", "mean (t - r)^2 / (r^2 + eps)", noise_power=1.0),
    Metric("smape", "mean |t - r| / (|t| + |r| + eps)"),
    Metric("rel_p50", "50th percentile of |t - r| / (r + eps)"),
    Metric("rel_p95", "95th percentile of |t - r| / (r + eps)"),
    Metric("rel_p99", "99th percentile of |t - r| / (r + eps)"),
    Metric("rel_max", "max |t - r| / (r + eps)"),
    Metric("psnr", "10 log10(peak^2 / mean (t - r)^2)", higher_is_better=True),
    Metric("flip_mean", "mean HDR-FLIP"),
    Metric("delta_e_itp_mean", "mean Delta E_ITP"),
    Metric("delta_e_itp_p95", "95th percentile of Delta E_ITP"),
)}
#: The relative MSE: the metric the gate's baseline comparison measures per region (compare.baseline).
RELMSE = METRICS["relmse"]
#: Names of the metrics where larger means better (read off :data:`METRICS`).
HIGHER_IS_BETTER = frozenset(m.name for m in METRICS.values() if m.higher_is_better)
#: The metrics from which the variance of a noisy image under test is subtracted (module docstring):
#: those that are means of squared differences (``psnr`` through its MSE).
TEST_NOISE_CORRECTED = ("relmse", "rmse", "psnr")
#: Metadata key of a test image whose variance channels are its engine's own noise (set by the
#: renderer contract, clients/run.py: its value says how the variance was obtained); such a test's
#: variance is subtracted by default.
TEST_VARIANCE_META = ENGINE_VARIANCE_META


class ComparisonError(PbrcheckError):
    """Two images that cannot be compared (size mismatch, NaN, missing channel, no valid pixel)."""


# --- input validation ---------------------------------------------------------------------------


def validate_pair(ref: Image, test: Image, ref_name: str = "reference", test_name: str = "test") -> None:
    """Raise :class:`ComparisonError` (one line) unless both images can be compared."""
    for img, name in ((ref, ref_name), (test, test_name)):
        missing = [c for c in RGB if c not in img.channels]
        if missing:
            raise ComparisonError(f"{name}: missing channel(s) {', '.join(missing)} "
                                  f"(has {', '.join(sorted(img.channels)) or 'none'})")
    if ref.shape != test.shape:
        (h1, w1), (h2, w2) = ref.shape, test.shape
        raise ComparisonError(f"size mismatch: {ref_name} is {w1}x{h1}, {test_name} is {w2}x{h2}")
    for img, name in ((ref, ref_name), (test, test_name)):
        for c in RGB + VARIANCE + ("object", "coverage", "NdotV"):
            a = img.channels.get(c)
            if a is not None and not np.all(np.isfinite(a)):
                n = int(np.count_nonzero(~np.isfinite(a)))
                raise ComparisonError(f"{name}: channel {c} has {n} NaN/Inf pixel(s)")


# --- masking ------------------------------------------------------------------------------------


def _classes_one(img: Image):
    """(covered, background) masks of one image, or None when it has neither AOV."""
    obj = img.channels.get("object")
    cov = img.channels.get("coverage")
    if obj is None and cov is None:
        return None
    hit = (obj >= 0) if obj is not None else (cov > 0)
    if cov is None:
        return hit, ~hit
    return hit & (cov >= FULL_COVERAGE), ~hit & (cov <= 0)


def pixel_classes(ref: Image, test: Image) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(valid, edge, background) boolean masks, disjoint and covering the image.

    *valid*: fully covered object pixels in every image that has ``object``/``coverage`` AOVs, and,
    when both have ``object``, the same object in both. *background*: no object in either image.
    *edge*: the rest (partly covered silhouette pixels, or pixels where the images disagree about
    which object is seen). When neither image has AOVs, every pixel is valid.
    """
    shape = ref.shape
    cls = [c for c in (_classes_one(ref), _classes_one(test)) if c is not None]
    if not cls:
        return np.ones(shape, bool), np.zeros(shape, bool), np.zeros(shape, bool)
    valid = np.logical_and.reduce([c[0] for c in cls])
    background = np.logical_and.reduce([c[1] for c in cls])
    if "object" in ref.channels and "object" in test.channels:
        valid &= np.rint(ref.channels["object"]) == np.rint(test.channels["object"])
    background &= ~valid
    edge = ~(valid | background)
    return valid, edge, background


# --- per-pixel maps -----------------------------------------------------------------------------


def _flip_exposures(ref_rgb: np.ndarray) -> tuple[float, float]:
    """HDR-FLIP's own start/stop exposures (ACES, t = 0.85: log2(x_max / Y_max) and
    log2(x_max / Y_median)), made safe for a black or constant reference, where flip-evaluator
    would exit the process ("start exposure must be smaller than stop exposure")."""
    tc = (0.6 * 0.6 * 2.51, 0.6 * 0.03, 0.0, 0.6 * 0.6 * 2.43, 0.6 * 0.59, 0.14)
    t = 0.85
    a, b, c = tc[0] - t * tc[3], tc[1] - t * tc[4], tc[2] - t * tc[5]
    x_max = (-b + math.sqrt(b * b - 4.0 * a * c)) / (2.0 * a)
    y = ref_rgb.reshape(-1, 3) @ LUMA.astype(np.float32)
    y_max = max(float(y.max()), 1e-6)
    y_med = min(max(float(np.median(y)), 1e-6), y_max)
    start, stop = math.log2(x_max / y_max), math.log2(x_max / y_med)
    if not stop > start + 1e-3:
        stop = start + 1.0
    return start, stop


#: Per-pixel maps kept per process by the content of their inputs (FLIP and Delta E ITP are the
#: comparator's costly parts, ~1 s per 360 x 300 pair on a CPU; a report compares many pairs twice:
#: the reference-spp rule and the final comparison, a preset and its research section).
MAP_MEMO_SIZE = 48
_map_memo: dict = {}
#: Cache namespace of HDR-FLIP maps on disk (``$PBRCHECK_CACHE/flip``), used with ``flip_cache=True``.
FLIP_NAMESPACE = "flip"
#: Part of every FLIP cache key: bump when the way a map is computed here changes (the exposure
#: range of :func:`_flip_exposures`, the clipping of :func:`flip_map`); flip-evaluator's own
#: version is in the key too.
FLIP_CODE_VERSION = 1
#: ``OMP_WAIT_POLICY`` of flip-evaluator's OpenMP threads, set before its first import unless the
#: environment sets it (the maps are the same either way; only the CPU spent waiting differs).
FLIP_OMP_WAIT_POLICY = "PASSIVE"
#: FLIP maps this process read from the disk store (``hit``), computed and stored (``miss``) and
#: computed without it (``off``); per-process memo hits are not counted.
FLIP_STORE_COUNTS: Counter = Counter()


def _digest(kind: str, a: np.ndarray, b: np.ndarray) -> str:
    """SHA-256 of ``kind`` and the dtype, shape and bytes of ``a`` and ``b``."""
    h = hashlib.sha256(kind.encode())
    for x in (a, b):
        x = np.ascontiguousarray(x)
        h.update(f"{x.dtype}{x.shape}".encode())
        h.update(x.tobytes())
    return h.hexdigest()


def _memo(kind: str, a: np.ndarray, b: np.ndarray, fn, key: str | None = None):
    """``fn()`` memoized by ``kind`` and the bytes of ``a`` and ``b`` (or ``key``, their
    :func:`_digest`, when the caller has it); a copy is returned."""
    key = key or _digest(kind, a, b)
    hit = _map_memo.pop(key, None)
    if hit is None:
        hit = fn()
        if len(_map_memo) >= MAP_MEMO_SIZE:
            _map_memo.pop(next(iter(_map_memo)))
    _map_memo[key] = hit  # most recently used last
    return hit.copy()


def flip_map(ref_rgb: np.ndarray, test_rgb: np.ndarray, *, cache: bool = False) -> np.ndarray:
    """HDR-FLIP error map (H, W) in [0, 1]. Inputs are validated here because flip-evaluator calls
    ``sys.exit`` on bad input: (H, W, 3), finite; passed as contiguous float32, clipped to >= 0.
    Memoized by content (:data:`MAP_MEMO_SIZE`). ``cache``: also kept on disk by content
    (:class:`pbrcheck.cache.Cache` namespace :data:`FLIP_NAMESPACE`): the key is the SHA-256 of both
    images' bytes, shape and dtype, the exposure range, flip-evaluator's version and
    :data:`FLIP_CODE_VERSION`, so a re-run of a report whose images did not change reads its maps
    (a FLIP map is ~0.3-0.6 s of both cores at 360 x 300, ~180 per report); without it every map is
    computed (tests measure the metric, not a file)."""
    if ref_rgb.shape != test_rgb.shape or ref_rgb.ndim != 3 or ref_rgb.shape[2] != 3:
        raise ComparisonError(f"FLIP needs two (H, W, 3) images, got {ref_rgb.shape} and {test_rgb.shape}")
    if not (np.all(np.isfinite(ref_rgb)) and np.all(np.isfinite(test_rgb))):
        raise ComparisonError("FLIP input has NaN/Inf")
    r = np.ascontiguousarray(np.clip(ref_rgb, 0.0, None), dtype=np.float32)
    t = np.ascontiguousarray(np.clip(test_rgb, 0.0, None), dtype=np.float32)
    digest = _digest("flip", r, t)
    store = Cache(FLIP_NAMESPACE) if cache else None
    return _memo("flip", r, t, lambda: _stored_flip_map(r, t, digest, store), key=digest)


def _flip_version() -> str:
    try:
        return importlib.metadata.version("flip-evaluator")
    except importlib.metadata.PackageNotFoundError:  # an unpackaged build: its module's file
        return str(getattr(_import_flip(), "__file__", "unknown"))


def _import_flip():
    """flip-evaluator, imported with :data:`FLIP_OMP_WAIT_POLICY` (libgomp reads it once, at load)."""
    os.environ.setdefault("OMP_WAIT_POLICY", FLIP_OMP_WAIT_POLICY)
    import flip_evaluator  # local: only the FLIP map needs it (a heavy native module)

    return flip_evaluator


def _stored_flip_map(r: np.ndarray, t: np.ndarray, digest: str, store: Cache | None) -> np.ndarray:
    """:func:`_flip_map`, read from / written to the disk ``store`` when there is one. A store that
    cannot be written is not an error (the map is returned; the next run computes it)."""
    if store is None:
        FLIP_STORE_COUNTS["off"] += 1
        return _flip_map(r, t)
    exposures = _flip_exposures(r)
    key = cache_key(kind="hdr-flip", inputs=digest, exposures=exposures, flip=_flip_version(), code=FLIP_CODE_VERSION)
    img = store.get(key)
    if img is not None and "flip" in img.channels and img.channels["flip"].shape == r.shape[:2]:
        FLIP_STORE_COUNTS["hit"] += 1
        return np.asarray(img.channels["flip"], np.float32)
    FLIP_STORE_COUNTS["miss"] += 1
    err = _flip_map(r, t)
    try:
        store.put(key, Image({"flip": err}, {"kind": "HDR-FLIP map", "exposures": json.dumps(exposures)}))
    except CacheError:
        pass
    return err


def _flip_map(r: np.ndarray, t: np.ndarray) -> np.ndarray:
    flip_evaluator = _import_flip()
    start, stop = _flip_exposures(r)
    with work("flip"):
        err, _, _ = flip_evaluator.evaluate(r, t, "HDR", applyMagma=False, computeMeanError=False,
                                            parameters={"startExposure": start, "stopExposure": stop})
    return np.asarray(err, dtype=np.float32).reshape(r.shape[:2])


def ictcp(rgb: np.ndarray) -> np.ndarray:
    """Linear sRGB (1.0 = 100 cd/m2) to ICtCp (BT.2100 PQ) via Rec.2020, negatives clipped."""
    import colour  # local: colour-science takes ~1 s to import; only Delta E ITP needs it

    rgb2020 = colour.RGB_to_RGB(rgb.astype(np.float64), colour.RGB_COLOURSPACES["sRGB"],
                                colour.RGB_COLOURSPACES["ITU-R BT.2020"])
    rgb2020 = np.clip(rgb2020, 0.0, None) * ITP_NITS_PER_UNIT
    return colour.RGB_to_ICtCp(rgb2020)


def delta_e_itp_map(ref_rgb: np.ndarray, test_rgb: np.ndarray) -> np.ndarray:
    """Per-pixel ITU-R BT.2124 Delta E_ITP (colour-science ``delta_E_ITP``); memoized by content."""
    import colour  # local: see ictcp

    return _memo("itp", ref_rgb, test_rgb,
                 lambda: colour.difference.delta_E_ITP(ictcp(ref_rgb), ictcp(test_rgb)).astype(np.float32))


@dataclass
class PixelMaps:
    """Per-pixel quantities from which every metric is a reduction."""

    ref: np.ndarray            # (H, W, 3)
    test: np.ndarray           # (H, W, 3)
    diff: np.ndarray           # t - r
    rel: np.ndarray            # |t - r| / (r + eps)
    flip: np.ndarray | None    # (H, W)
    dE: np.ndarray | None      # (H, W)
    #: (H, W, 3) variance of the test's pixel estimate (a Monte Carlo engine), subtracted from the
    #: squared metrics (:data:`TEST_NOISE_CORRECTED`); None: a noise-free test.
    test_var: np.ndarray | None = None
    y_ref: np.ndarray = field(init=False)

    def __post_init__(self):
        self.y_ref = self.ref @ LUMA.astype(np.float32)


def pixel_maps(ref_rgb: np.ndarray, test_rgb: np.ndarray, *, flip: bool = True, itp: bool = True,
               flip_cache: bool = False, test_var: np.ndarray | None = None) -> PixelMaps:
    """Per-pixel maps of two (H, W, 3) linear images: the signed difference ``t - r``, the relative
    error ``|t - r| / (r + REL_EPS)``, the reference luminance and (optionally) HDR-FLIP (kept on
    disk with ``flip_cache``: :func:`flip_map`) and Delta E ITP. ``test_var``: the test's per-pixel
    variance (a noisy test), which :func:`summarize` subtracts from the squared metrics."""
    r = ref_rgb.astype(np.float64)
    t = test_rgb.astype(np.float64)
    d = t - r
    rel = np.abs(d) / (r + REL_EPS)
    return PixelMaps(ref=r, test=t, diff=d, rel=rel,
                     flip=flip_map(ref_rgb, test_rgb, cache=flip_cache) if flip else None,
                     dE=delta_e_itp_map(ref_rgb, test_rgb) if itp else None,
                     test_var=None if test_var is None else np.clip(test_var.astype(np.float64), 0.0, None))


def _f(x) -> float:
    return float(x)


def summarize(m: PixelMaps, mask: np.ndarray, *, peak: float | None = None) -> dict[str, float | None]:
    """Every metric of :data:`METRICS` over ``mask`` (see the module docstring for formulas); with
    ``m.test_var`` the squared ones (:data:`TEST_NOISE_CORRECTED`) less the test's own noise."""
    n = int(mask.sum())
    if n == 0:
        return {k: None for k in METRICS}
    r, t, d = m.ref[mask], m.test[mask], m.diff[mask]
    sq = d * d
    if m.test_var is not None:  # E[(t - r)^2] = (mu_t - r)^2 + v_t: the engine's noise is not its error
        sq = sq - m.test_var[mask]
    mse = max(_f(sq.mean()), 0.0)
    rel = m.rel[mask]
    if peak is None:
        peak = psnr_peak(m, mask)
    out: dict[str, float | None] = {
        "mean_abs": _f(np.abs(d).mean()),
        "rmse": math.sqrt(mse),
        "relmse": max(_f((sq / (r * r + REL_EPS)).mean()), 0.0),
        "smape": _f((np.abs(d) / (np.abs(t) + np.abs(r) + REL_EPS)).mean()),
    }
    p50, p95, p99 = np.percentile(rel, [50, 95, 99])
    out.update(rel_p50=_f(p50), rel_p95=_f(p95), rel_p99=_f(p99), rel_max=_f(rel.max()))
    out["psnr"] = (math.inf if mse == 0 else 10.0 * math.log10(peak * peak / mse)) if peak > 0 else None
    out["flip_mean"] = _f(m.flip[mask].mean()) if m.flip is not None else None
    if m.dE is not None:
        de = m.dE[mask]
        out["delta_e_itp_mean"] = _f(de.mean())
        out["delta_e_itp_p95"] = _f(np.percentile(de, 95))
    else:
        out["delta_e_itp_mean"] = out["delta_e_itp_p95"] = None
    return out


def psnr_peak(m: PixelMaps, mask: np.ndarray) -> float:
    """The 99.9th percentile of the reference luminance over ``mask``."""
    return _f(np.percentile(m.y_ref[mask], PSNR_PEAK_PERCENTILE)) if mask.any() else 0.0


def worse(value, bound, *, upper: bool) -> bool:
    """True when ``value`` breaks ``bound``: above it for an upper bound (a gate's ``max``), below it
    for a lower bound (``min``). An undefined value (None, NaN) always breaks it.

    Parameters
    ----------
    value : float or None
        The measured metric.
    bound : float
        The budget.
    upper : bool
        True for an upper bound (``max``), False for a lower bound (``min``).

    Returns
    -------
    bool
        Whether the budget is broken.
    """
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return True
    return value > bound if upper else value < bound


# --- the comparison -----------------------------------------------------------------------------


@dataclass
class Comparison:
    """Result of :func:`compare_images`: ``summary`` is the JSON-able dict; the rest are maps."""

    summary: dict
    maps: PixelMaps
    valid: np.ndarray
    edge: np.ndarray
    background: np.ndarray

    @property
    def metrics(self) -> dict:
        return self.summary["metrics"]

    def worst_objects(self, metric: str, n: int = 3) -> list[dict]:
        objs = [o for o in self.summary["objects"] if o["metrics"].get(metric) is not None]
        sign = -1 if METRICS[metric].higher_is_better else 1
        objs.sort(key=lambda o: sign * o["metrics"][metric], reverse=True)
        return objs[:n]


def _object_info(scene, oid: int) -> tuple[str | None, dict | None]:
    if scene is None or not (0 <= oid < len(scene.objects)):
        return None, None
    o = scene.objects[oid]
    mat = o.material
    return o.name, {"base_color": list(mat.base_color), "metallic": mat.metallic,
                    "roughness": mat.roughness, "specular": mat.specular}


def is_display_referred(img: Image) -> bool:
    """Whether ``img`` holds display values (an external renderer's ``png-srgb`` output,
    metadata ``display_referred = "1"``) rather than linear radiance."""
    return img.meta.get("display_referred") == "1"


def display_referred(img: Image) -> Image:
    """``img`` in display space: linear radiance clamped to [0, 1], then the sRGB transfer (what an
    8-bit engine does); an image already display-referred is returned as it is. Variance channels
    are dropped (they describe linear radiance)."""
    if is_display_referred(img):
        return img
    rgb = srgb_oetf(np.clip(img.rgb.astype(np.float64), 0.0, 1.0)).astype(np.float32)
    extra = {k: v for k, v in img.channels.items() if k not in RGB and k not in VARIANCE}
    return Image.from_rgb(rgb, {**img.meta, "display_referred": "1"}, **extra)


def material_bias(m: PixelMaps, mask: np.ndarray) -> float | None:
    """Relative signed bias over ``mask``: ``sum(t - r) / sum(r)`` (every channel; 0 unbiased, > 0 the
    test brighter); None over no pixels or a black reference."""
    if not mask.any():
        return None
    r = float(m.ref[mask].sum())
    return _f(float(m.diff[mask].sum()) / r) if r > REL_EPS else None


def _material_metrics(scene, ids, valid, m, peak) -> list[dict]:
    """Metrics over the pixels of each glTF material (``asset file: material name``; the objects of
    one material pooled): :func:`summarize`'s and ``bias`` (:func:`material_bias`)."""
    groups: dict[str, list[int]] = {}
    for o in scene.objects:
        if o.type == "mesh":
            inst = scene.assets[o.instance]
            key = f"{Path(inst.path).name}: {inst.asset.material(o.gltf_material).name}"
            groups.setdefault(key, []).append(o.id)
    out = []
    for name, oids in groups.items():
        mask = valid & np.isin(ids, oids)
        if mask.any():
            out.append({"material": name, "objects": oids, "pixels": int(mask.sum()),
                        "metrics": {**summarize(m, mask, peak=peak), "bias": material_bias(m, mask)}})
    return out


def compare_images(ref: Image, test: Image, *, scene=None, noise: bool = True,
                   ref_name: str = "reference", test_name: str = "test", flip: bool = True,
                   itp: bool = True, flip_cache: bool = False,
                   subtract_test_noise: bool | None = None) -> Comparison:
    """Compare ``test`` against ``ref``; raises :class:`ComparisonError` when they cannot be.

    When either image is display-referred (an 8-bit ``png-srgb`` engine), both are compared in
    display space (:func:`display_referred`: the same clamp and sRGB transfer applied to the other),
    without the noise floor, and ``summary["space"]`` says ``display-referred`` (else ``linear``).
    ``flip=False`` / ``itp=False``: a caller that reads neither ``flip_mean`` nor ``delta_e_itp_*``
    skips those maps (the costly part of a comparison); those metrics are then None.
    ``flip_cache``: the FLIP maps (the pair's and the noise simulation's) are also kept on disk by
    content (:func:`flip_map`; the report).
    ``subtract_test_noise``: subtract the test's variance channels from the squared metrics (module
    docstring); None (default): when the test carries :data:`TEST_VARIANCE_META` (an external
    Monte Carlo engine's image through the renderer contract).
    """
    space = "linear"
    if is_display_referred(ref) or is_display_referred(test):
        ref, test, noise, space = display_referred(ref), display_referred(test), False, "display-referred"
    validate_pair(ref, test, ref_name, test_name)
    valid, edge, background = pixel_classes(ref, test)
    if not valid.any():
        raise ComparisonError(f"no valid pixel: {int(edge.sum())} edge and {int(background.sum())} "
                              "background pixel(s), no fully covered object pixel in both images")
    # A Monte Carlo engine's own noise (None: a noise-free test, or one whose variance is not to be
    # subtracted: a pbrcheck reference compared as a test keeps its raw figures, the convergence study
    # compares exactly those with its variance prediction).
    if subtract_test_noise is None:
        subtract_test_noise = TEST_VARIANCE_META in test.meta
    tvar = test.variance if subtract_test_noise else None
    m = pixel_maps(ref.rgb, test.rgb, flip=flip, itp=itp, flip_cache=flip_cache, test_var=tvar)
    peak = psnr_peak(m, valid)
    summary: dict = {
        "space": space,
        "size": [ref.shape[1], ref.shape[0]],
        "pixels": {"valid": int(valid.sum()), "edge": int(edge.sum()), "background": int(background.sum())},
        "psnr_peak": peak,
        "metrics": summarize(m, valid, peak=peak),
    }
    if tvar is not None:  # only then: a noise-free test's summary keeps its keys
        summary["test_noise"] = engine_noise(m, valid, peak)
    # Per object (ids from the reference's object AOV, else the test's).
    objects = []
    obj = ref.channels.get("object", test.channels.get("object"))
    if obj is not None:
        ids = np.rint(obj).astype(np.int64)
        for oid in np.unique(ids[valid]):
            mask = valid & (ids == oid)
            name, material = _object_info(scene, int(oid))
            objects.append({"id": int(oid), "name": name, "material": material,
                            "pixels": int(mask.sum()), "metrics": summarize(m, mask, peak=peak)})
    summary["objects"] = objects
    if obj is not None and getattr(scene, "assets", ()):  # glTF assets: per material too
        summary["materials"] = _material_metrics(scene, np.rint(obj).astype(np.int64), valid, m, peak)
    # Error against NdotV (the reference's, else the test's).
    ndv = ref.channels.get("NdotV", test.channels.get("NdotV"))
    bins = []
    if ndv is not None:
        edges = np.linspace(0.0, 1.0, NDOTV_BINS + 1)
        idx = np.clip(np.digitize(np.clip(ndv, 0.0, 1.0), edges[1:-1]), 0, NDOTV_BINS - 1)
        for b in range(NDOTV_BINS):
            mask = valid & (idx == b)
            s = summarize(m, mask, peak=peak)
            bins.append({"lo": float(edges[b]), "hi": float(edges[b + 1]), "pixels": int(mask.sum()),
                         "metrics": {k: s[k] for k in ("mean_abs", "relmse", "smape", "flip_mean",
                                                        "delta_e_itp_mean")}})
    summary["ndotv"] = bins
    summary["noise"] = (noise_floor(ref, m, valid, peak, summary["metrics"], flip_cache=flip_cache)
                        if noise and ref.variance is not None else None)
    return Comparison(summary, m, valid, edge, background)


def noise_floor(ref: Image, m: PixelMaps, valid: np.ndarray, peak: float, metrics: dict, *,
                flip_cache: bool = False) -> dict:
    """Noise floor of the reference and a ``within_noise`` flag per metric (module docstring)."""
    var = np.clip(ref.variance.astype(np.float64), 0.0, None)
    mean_var = _f(var[valid].mean())
    mse = _f((m.diff[valid] ** 2).mean())
    rng = np.random.default_rng(NOISE_SEED)
    # A noisy test adds its own variance to the difference's (independent noises add); its squared
    # metrics subtract it in the simulation as in the measurement (module docstring).
    sim_var = 2.0 * var if m.test_var is None else 2.0 * var + m.test_var
    sim_t = m.ref + np.sqrt(sim_var) * rng.standard_normal(m.ref.shape)
    sim = pixel_maps(m.ref.astype(np.float32), sim_t.astype(np.float32), flip=m.flip is not None,
                     itp=m.dE is not None, flip_cache=flip_cache, test_var=m.test_var)
    sim_metrics = summarize(sim, valid, peak=peak)
    flags = {}
    for k in METRICS:
        flags[k] = _within(k, metrics[k], sim_metrics[k])
    corrected = mse - mean_var
    if m.test_var is not None:
        corrected -= _f(m.test_var[valid].mean())
    return {"mean_variance": mean_var, "mse": mse, "mse_corrected": corrected,
            "factor": NOISE_EXPLAINS_FACTOR, "simulated": sim_metrics, "within_noise": flags}


def engine_noise(m: PixelMaps, valid: np.ndarray, peak: float) -> dict:
    """What the test's own noise contributes over the valid pixels (``m.test_var`` set): its mean
    variance, the relmse it alone adds (``mean v_t / (r^2 + eps)``), the metrics that were corrected
    (:data:`TEST_NOISE_CORRECTED`) and ``metrics_raw``, every metric before the correction."""
    raw = summarize(PixelMaps(m.ref, m.test, m.diff, m.rel, m.flip, m.dE), valid, peak=peak)
    v, r = m.test_var[valid], m.ref[valid]
    return {"mean_variance": _f(v.mean()), "relmse": _f((v / (r * r + REL_EPS)).mean()),
            "corrected": list(TEST_NOISE_CORRECTED), "metrics_raw": raw}


def _within(metric: str, value, sim) -> bool:
    if value is None or sim is None:
        return False
    if METRICS[metric].higher_is_better:
        if math.isinf(value):
            return True
        return value >= sim - 10.0 * math.log10(NOISE_EXPLAINS_FACTOR)
    return value <= NOISE_EXPLAINS_FACTOR * sim
