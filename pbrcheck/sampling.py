"""Sampling in numpy: the twins of ``realtime/shaders/sampling.glsl`` (same names, same formulas).

Tangent space: z is the normal. ``u`` is (..., 2) in [0, 1)^2. References as in :mod:`pbrcheck.brdf`
plus [Dammertz12] H. Dammertz, "Hammersley Points on the Hemisphere", 2012.

The runtime importance sampling's strategies (:data:`realtime.registry.RUNTIME_SAMPLINGS`): each
member's ``runtime_half_vector_<name>`` and its ``runtime_estimate_*``, dispatched by
:func:`realtime.dispatch.runtime_half_vector` / ``runtime_estimate``. The DFG LUT's sampling strategies
(:data:`LUT_SAMPLINGS`): each member's
``lut_half_vector_<name>`` and ``lut_weight_<name>`` (the GLSL NDF switch is the ``ndf`` argument
here), the dispatch :func:`lut_half_vector` / :func:`lut_weight` looping the registry, and
:func:`dfg_lut_texel`, the numpy twin of ``dfg_lut.comp``'s texel (same points, same estimator).

API
---
:func:`radical_inverse`, :func:`hammersley`, :func:`sample_GGX`, :func:`sample_Beckmann`,
:func:`sample_BlinnPhong`, :func:`sample_GGX_VNDF`, :func:`pdf_GGX_VNDF`, :func:`sample_cosine`,
:func:`sample_ndf`, :func:`lut_half_vector_vndf`, :func:`lut_weight_vndf`, :func:`lut_half_vector_ndf`,
:func:`lut_weight_ndf`, :func:`lut_half_vector`, :func:`lut_weight`, :func:`dfg_lut_texel`,
:func:`runtime_half_vector_beckmann`, :func:`runtime_half_vector_ggx`, :func:`runtime_half_vector_vndf`,
:func:`runtime_estimate_ndf`, :func:`runtime_estimate_vndf`; the registry :data:`LUT_SAMPLINGS` (its entries
holding these role functions; the reference's LUT bake shares it) and :func:`lut_sampling_for`. Dr.Jit twins of the same names: :mod:`reference.sampling`.
"""

from __future__ import annotations

import numpy as np

from .brdf import COS_EPS, MIN_ALPHA, D_GGX, G1_SmithGGX, alpha_from_roughness, geometry_term
from .terms import GGX, Beckmann, BlinnPhong
from .registry import NDFS, Entry, Registry, role


def radical_inverse(i):
    """[Dammertz12]: van der Corput radical inverse in base 2 (32-bit bit reversal)."""
    i = np.asarray(i, dtype=np.uint64) & np.uint64(0xFFFFFFFF)
    x = np.zeros_like(i)
    for b in range(32):
        x |= ((i >> np.uint64(b)) & np.uint64(1)) << np.uint64(31 - b)
    return x.astype(np.float64) * 2.0 ** -32


def hammersley(i, n):
    """[Dammertz12]: ``(i / n, radical_inverse(i))``, shape (..., 2)."""
    i = np.asarray(i)
    return np.stack([i.astype(np.float64) / float(n), radical_inverse(i)], axis=-1)


#: The NDFs' samplers of ``D (n.h)`` (their term classes', :mod:`pbrcheck.terms`), by their GLSL twins' names.
sample_GGX, sample_Beckmann, sample_BlinnPhong = GGX.sample, Beckmann.sample, BlinnPhong.sample


def sample_GGX_VNDF(u, v, alpha):
    """[Heitz18] listing 1: visible normals of GGX seen from ``v`` (..., 3), tangent space."""
    u = np.asarray(u, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    a = max(float(alpha), MIN_ALPHA) if np.ndim(alpha) == 0 else np.maximum(alpha, MIN_ALPHA)[..., None]
    vh = np.concatenate([a * v[..., 0:1], a * v[..., 1:2], v[..., 2:3]], axis=-1)
    vh = vh / np.linalg.norm(vh, axis=-1, keepdims=True)
    lensq = vh[..., 0] ** 2 + vh[..., 1] ** 2
    safe = np.where(lensq > 0, lensq, 1.0)
    t1 = np.where((lensq > 0)[..., None], np.stack([-vh[..., 1], vh[..., 0], np.zeros_like(lensq)], -1)
                  / np.sqrt(safe)[..., None], np.array([1.0, 0.0, 0.0]))
    t2 = np.cross(vh, t1)
    r = np.sqrt(u[..., 0])
    phi = 2 * np.pi * u[..., 1]
    p1, p2 = r * np.cos(phi), r * np.sin(phi)
    s = 0.5 * (1.0 + vh[..., 2])
    p2 = (1.0 - s) * np.sqrt(np.maximum(1.0 - p1 * p1, 0.0)) + s * p2
    nh = p1[..., None] * t1 + p2[..., None] * t2 + np.sqrt(np.maximum(0.0, 1.0 - p1 * p1 - p2 * p2))[..., None] * vh
    h = np.concatenate([a * nh[..., 0:1], a * nh[..., 1:2], np.maximum(0.0, nh[..., 2:3])], axis=-1)
    return h / np.linalg.norm(h, axis=-1, keepdims=True)


def pdf_GGX_VNDF(v, h, alpha):
    """[Heitz18] eq. 3: ``G1(v) max(0, v.h) D_GGX(h) / (n.v)``."""
    v = np.asarray(v, dtype=np.float64)
    h = np.asarray(h, dtype=np.float64)
    return (G1_SmithGGX(v[..., 2], alpha) * np.maximum(np.sum(v * h, -1), 0.0) * D_GGX(h[..., 2], alpha)
            / np.maximum(v[..., 2], COS_EPS))


def sample_cosine(u):
    """Malley's method: cosine-weighted hemisphere, pdf = cos / pi."""
    u = np.asarray(u, dtype=np.float64)
    r = np.sqrt(u[..., 1])
    phi = 2 * np.pi * u[..., 0]
    return np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.maximum(1.0 - u[..., 1], 0.0))], -1)


def sample_ndf(u, alpha, ndf: str = "ggx"):
    """A half vector drawn from ``D (n.h)`` of the NDF ``ndf`` (its registry entry's term's ``sample``)."""
    return NDFS[ndf].term.sample(u, alpha)


# ---- the DFG LUT's sampling strategies (LUT_SAMPLINGS) --------------------------

def lut_half_vector_vndf(u, v, alpha, ndf: str = "ggx"):
    """[Heitz18]: GGX visible normals seen from ``v`` (the GLSL passes ``u.yx``)."""
    u = np.asarray(u, dtype=np.float64)
    return sample_GGX_VNDF(u[..., ::-1], v, alpha)


def lut_weight_vndf(G, v, h, alpha):
    """[Heitz18] eq. 17: the weight ``G2 / G1(v)``."""
    return np.asarray(G) / np.maximum(G1_SmithGGX(np.asarray(v)[..., 2], alpha), COS_EPS)


def lut_half_vector_ndf(u, v, alpha, ndf: str = "ggx"):
    """[Walter07]: a half vector from ``D (n.h)`` of ``ndf`` (:func:`sample_ndf`)."""
    return sample_ndf(u, alpha, ndf)


def lut_weight_ndf(G, v, h, alpha):
    """[Walter07] eq. 38: the weight ``G (v.h) / ((n.h)(n.v))``."""
    v, h = np.asarray(v, dtype=np.float64), np.asarray(h, dtype=np.float64)
    return np.asarray(G) * np.sum(v * h, -1) / np.maximum(h[..., 2] * v[..., 2], COS_EPS)


#: The DFG LUT's sampling strategies (realtime/shaders/dfg_lut.comp): each draws the half vector
#: (``lut_half_vector_<name>``) and weighs the sample (``lut_weight_<name>``, the estimator of
#: ``f_s cos / pdf`` up to the Fresnel factor); numpy in :mod:`pbrcheck.sampling`, Dr.Jit in
#: :mod:`reference.sampling`, GLSL in ``sampling.glsl``. ``extra["ndfs"]``: the NDFs it is defined for
#: (another NDF bakes with ``ndf``, :func:`lut_sampling_for`).
LUT_SAMPLINGS = Registry("LUT_SAMPLING", [
    Entry("vndf", "GGX visible normals, Heitz 2018 (GGX NDF only)", extra={"ndfs": ("ggx",)},
          roles={"lut_half_vector": role(lut_half_vector_vndf), "lut_weight": role(lut_weight_vndf)},
          applies_to="the GGX NDF only (its visible normals); other NDFs bake with ndf"),
    Entry("ndf", "half vectors drawn from the NDF, Walter et al. 2007", extra={"ndfs": None},
          roles={"lut_half_vector": role(lut_half_vector_ndf), "lut_weight": role(lut_weight_ndf)}, applies_to="every NDF (its own D (n.h) sampler)"),
])


def lut_sampling_for(sampling: str, ndf: str) -> str:
    """The LUT sampling strategy used for ``ndf``: ``sampling`` where it is defined for that NDF,
    else ``ndf`` (KeyError for an unknown strategy)."""
    ndfs = LUT_SAMPLINGS[sampling].extra["ndfs"]
    return sampling if ndfs is None or ndf in ndfs else "ndf"



def lut_half_vector(u, v, alpha, sampling: str, ndf: str = "ggx"):
    """The strategy ``sampling``'s half vector (KeyError for an unknown one)."""
    return LUT_SAMPLINGS[sampling].roles["lut_half_vector"].numpy(u, v, alpha, ndf)


def lut_weight(G, v, h, alpha, sampling: str):
    """The strategy ``sampling``'s weight of the sample ``h``."""
    return LUT_SAMPLINGS[sampling].roles["lut_weight"].numpy(G, v, h, alpha)


def dfg_lut_texel(NoV: float, roughness: float, samples: int, geometry: str, ndf: str = "ggx",
                  sampling: str = "vndf") -> tuple[float, float]:
    """``(A, B)`` of ``dfg_lut.comp``'s texel at ``(n.v, roughness)``: the same Hammersley points with
    the half-cell offset, the same strategy and estimator (``sampling`` as the bake uses it for
    ``ndf``, :func:`lut_sampling_for`)."""
    sampling = lut_sampling_for(sampling, ndf)
    alpha = alpha_from_roughness(roughness)
    v = np.array([np.sqrt(1.0 - NoV * NoV), 0.0, NoV])
    u = hammersley(np.arange(samples), samples)
    u[:, 0] += 0.5 / samples
    h = lut_half_vector(u, v, alpha, sampling, ndf)
    VoH = h @ v
    NoL = 2.0 * VoH * h[:, 2] - NoV
    ok = (NoL > 0.0) & (VoH > 0.0)
    G = geometry_term(geometry, np.full(ok.sum(), NoV), NoL[ok], roughness)
    w = lut_weight(G, v, h[ok], alpha, sampling)
    Fc = (1.0 - VoH[ok]) ** 5
    return float(np.sum(w * (1.0 - Fc)) / samples), float(np.sum(w * Fc) / samples)


# ---- runtime importance sampling's strategies (realtime.registry.RUNTIME_SAMPLINGS) ---------------

def runtime_half_vector_beckmann(u, vt, alpha):
    """[Walter07] eq. 28: Beckmann half vectors (article 001, for the GGX D)."""
    return sample_Beckmann(u, alpha)


def runtime_half_vector_ggx(u, vt, alpha):
    """[Walter07] eq. 35-36: GGX half vectors."""
    return sample_GGX(u, alpha)


def runtime_half_vector_vndf(u, vt, alpha):
    """[Heitz18]: GGX visible normals seen from ``vt`` (the GLSL passes ``u.yx``)."""
    return sample_GGX_VNDF(np.asarray(u, dtype=np.float64)[..., ::-1], vt, alpha)


def runtime_estimate_ndf(F, G, L, NoV, NoH, VoH, alpha):
    """Article 001's estimator ``F G L (v.h) / ((n.h)(n.v))`` (exact when ``h`` follows the shaded NDF's ``D (n.h)``)."""
    return np.asarray(F) * G * np.asarray(L) * VoH / (np.asarray(NoH) * NoV)


def runtime_estimate_vndf(F, G, L, NoV, NoH, VoH, alpha):
    """[Heitz18] eq. 17: ``F G L / G1(v)``."""
    return np.asarray(F) * G / np.maximum(G1_SmithGGX(NoV, alpha), COS_EPS) * np.asarray(L)
