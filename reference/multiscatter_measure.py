"""Measurements of the random walk (:mod:`reference.multiscatter`): its directional albedo over a
grid (``pbrcheck energy``, through :func:`compare.renderers.multiscatter_albedo`) and the BSDF
sampling speed with and without it (``pbrcheck bench multiscatter``).

API
---
:func:`directional_albedo`, :func:`bench_multiscatter`, :data:`ALBEDO_CHUNK_LANES`.
"""

from __future__ import annotations

import math
import time

import numpy as np

from pbrcheck.registry import MULTISCATTER_GEOMETRY

from .variant import ensure_variant

ensure_variant()
import drjit as dr  # noqa: E402
import mitsuba as mi  # noqa: E402

from .multiscatter import query_key, walk_sample  # noqa: E402

#: Lanes per Dr.Jit launch of :func:`directional_albedo` (bounds memory).
ALBEDO_CHUNK_LANES = 1 << 22


def directional_albedo(mu, roughness, F0, *, samples: int = 1 << 16, seed: int = 0, order_max: int | None = None):
    """Directional albedo of the random walk (specular lobe only, grey Schlick ``F0``) at each
    ``(mu, roughness, F0)`` (broadcast numpy arrays): ``(mean, standard error)`` of the walk's exact
    throughput over ``samples`` walks each. ``order_max = 1`` keeps the single-scattering walks only.
    """
    ensure_variant()
    mu, roughness, F0 = np.broadcast_arrays(*[np.asarray(x, dtype=np.float64) for x in (mu, roughness, F0)])
    shape = mu.shape
    mu, roughness, F0 = mu.ravel(), roughness.ravel(), F0.ravel()
    mean = np.zeros(mu.size)
    se = np.zeros(mu.size)
    per = max(1, ALBEDO_CHUNK_LANES // samples)
    for c0 in range(0, mu.size, per):
        idx = np.arange(c0, min(mu.size, c0 + per))
        cfg = np.repeat(idx, samples)
        m = np.clip(mu[cfg], 1e-6, 1.0)
        wi = mi.Vector3f(mi.Float(np.sqrt(1.0 - m * m).astype(np.float32)), mi.Float(np.zeros(m.size, np.float32)),
                         mi.Float(m.astype(np.float32)))
        alpha = mi.Float(np.maximum(roughness[cfg] ** 2, 1e-7).astype(np.float32))
        f0 = mi.Float(F0[cfg].astype(np.float32))
        key = query_key(seed, mi.Float(np.arange(cfg.size, dtype=np.float32) + np.float32(c0 * samples)),
                        mi.Float(cfg.astype(np.float32)))
        _, w, order = walk_sample(wi, alpha, mi.Color3f(f0, f0, f0), key)
        x = np.array(w.x, dtype=np.float64)
        if order_max is not None:
            x = x * (np.array(order) <= order_max)
        x = x.reshape(idx.size, samples)
        mean[idx] = x.mean(1)
        se[idx] = x.std(1) / np.sqrt(samples)
    return mean.reshape(shape), se.reshape(shape)


def bench_multiscatter(*, lanes: int = 1 << 20, roughness: float = 0.5, mu: float = 0.5, repeats: int = 3) -> dict:
    """Samples per second of ``pbr_material.sample`` with ``random_walk`` against single scattering
    (the same material, metal, F0 = 0.9), in one run: the best of ``repeats`` timed launches after
    a warm-up (kernel compilation excluded)."""

    variant = ensure_variant()
    rng = np.random.default_rng(0)
    u = rng.random((3, lanes)).astype(np.float32)
    out = {"variant": variant, "lanes": lanes, "roughness": roughness, "n.v": mu, "repeats": repeats}
    # The Beckmann walk (same material, ndf beckmann + its correlated term): its visible-normal
    # sampler inverts a CDF by bisection (reference/multiscatter.py), the dearest part of a bounce.
    models = {"none": ("none", "ggx"), "random_walk": ("random_walk", "ggx"),
              "random_walk_beckmann": ("random_walk", "beckmann")}
    for name, (ms_name, ndf) in models.items():
        b = mi.load_dict({"type": "pbr_material", "base_color": [0.9, 0.9, 0.9], "metallic": 1.0,
                          "roughness": roughness, "multiscatter": ms_name, "ndf": ndf,
                          "geometry": MULTISCATTER_GEOMETRY[ndf]})
        si = dr.zeros(mi.SurfaceInteraction3f, lanes)
        si.wi = mi.Vector3f(float(math.sqrt(1 - mu * mu)), 0.0, float(mu))
        best = float("inf")
        for k in range(repeats + 1):
            s1 = mi.Float(u[0])
            s2 = mi.Point2f(mi.Float(u[1]), mi.Float(u[2]))
            dr.eval(s1, s2)
            t = time.perf_counter()
            bs, w = b.sample(mi.BSDFContext(), si, s1, s2)
            dr.eval(bs.wo, w)
            dr.sync_thread()
            if k:  # the first launch compiles the kernel
                best = min(best, time.perf_counter() - t)
        mean = float(np.mean(np.array(w.x)))
        out[name] = {"samples_per_s": lanes / best, "seconds": best, "mean_weight": mean}
    out["slowdown"] = out["none"]["samples_per_s"] / out["random_walk"]["samples_per_s"]
    out["slowdown_beckmann"] = out["none"]["samples_per_s"] / out["random_walk_beckmann"]["samples_per_s"]
    return out
