"""The real-time renderer's sampling strategies in Dr.Jit: the twins of :mod:`pbrcheck.sampling`'s
runtime importance sampling (``runtime_half_vector_<name>``, ``runtime_estimate_*``) and DFG LUT
strategies (``lut_half_vector_<name>`` / ``lut_weight_<name>``), same names, same formulas (the GLSL
ones are in ``realtime/shaders/sampling.glsl``), dispatched by this module's tables of :data:`realtime.registry.RUNTIME_SAMPLINGS` and
:data:`pbrcheck.sampling.LUT_SAMPLINGS` (:data:`RUNTIME_ROLES`, :data:`LUT_ROLES`), and
:func:`dfg_lut`, the Dr.Jit bake of
``dfg_lut.comp`` (same points, same estimator) that the reference can use to separate the split
sum's LUT error from its own.

Tangent space, ``z`` = the normal; ``u`` is a ``mi.Point2f`` with GLSL's convention (``u.x`` the
azimuth of an NDF sample). The ``ndf`` strategy draws ``D (n.h)`` by the NDF's sampler, named by its
Dr.Jit class (:mod:`reference.terms`, ``sample_cos``). References: [Heitz18] E. Heitz, "Sampling the GGX Distribution of
Visible Normals", JCGT 7(4) 2018 (listing 1, eq. 17); [Walter07] Walter et al., "Microfacet Models
for Refraction through Rough Surfaces", EGSR 2007 (eq. 35-38); [Karis13] B. Karis, "Real Shading in
Unreal Engine 4", 2013 (eq. 8).

API
---
:func:`sample_GGX`, :func:`sample_Beckmann`, :func:`sample_BlinnPhong`, :func:`sample_ndf`,
:func:`lut_half_vector_vndf`, :func:`lut_weight_vndf`, :func:`lut_half_vector_ndf`,
:func:`lut_weight_ndf`, :func:`lut_half_vector`, :func:`lut_weight`, :func:`dfg_lut`,
:func:`runtime_half_vector_beckmann`, :func:`runtime_half_vector_ggx`, :func:`runtime_half_vector_vndf`,
:func:`runtime_estimate_ndf`, :func:`runtime_estimate_vndf`, :func:`runtime_half_vector`,
:func:`runtime_estimate`, :data:`LUT_ROLES`, :data:`RUNTIME_ROLES`.
"""

from __future__ import annotations

import numpy as np

import pbrcheck  # noqa: F401  (sets DRJIT_LIBLLVM_PATH before drjit loads)
from pbrcheck.brdf import COS_EPS, MIN_ALPHA
from pbrcheck.sampling import hammersley, lut_sampling_for

import drjit as dr
import mitsuba as mi

from . import terms


#: The NDFs' samplers of ``D (n.h)`` in GLSL's ``u`` order (their Dr.Jit classes', reference.terms),
#: by their GLSL twins' names.
sample_GGX, sample_Beckmann, sample_BlinnPhong = terms.GGX.sample_cos, terms.Beckmann.sample_cos, terms.BlinnPhong.sample_cos


def sample_ndf(u, alpha, ndf: str = "ggx"):
    """A half vector from ``D (n.h)`` of ``ndf`` (its Dr.Jit class's ``sample_cos``)."""
    return terms.ndf(ndf).sample_cos(u, alpha)


# ---- the registry members' role functions (pbrcheck.sampling.LUT_SAMPLINGS) ----------------------

def lut_half_vector_vndf(u, v, alpha, ndf: str = "ggx"):
    """[Heitz18] listing 1: GGX visible normals (:meth:`reference.terms.GGX.sample`, ``u.yx``)."""
    return terms.GGX.sample(v, mi.Point2f(u.y, u.x), dr.maximum(alpha, MIN_ALPHA))


def lut_weight_vndf(G, v, h, alpha):
    """[Heitz18] eq. 17: ``G2 / G1(v)``."""
    return G / dr.maximum(terms.G1_SmithGGX(v.z, alpha), COS_EPS)


def lut_half_vector_ndf(u, v, alpha, ndf: str = "ggx"):
    """[Walter07]: a half vector from ``D (n.h)`` (:func:`sample_ndf`)."""
    return sample_ndf(u, alpha, ndf)


def lut_weight_ndf(G, v, h, alpha):
    """[Walter07] eq. 38: ``G (v.h) / ((n.h)(n.v))``."""
    return G * dr.dot(v, h) / dr.maximum(h.z * v.z, COS_EPS)


def lut_half_vector(u, v, alpha, sampling: str, ndf: str = "ggx"):
    """The strategy ``sampling``'s half vector (:data:`LUT_ROLES`; KeyError for an unknown one)."""
    return LUT_ROLES[sampling]["lut_half_vector"](u, v, alpha, ndf)


def lut_weight(G, v, h, alpha, sampling: str):
    """The strategy ``sampling``'s weight of the sample ``h``."""
    return LUT_ROLES[sampling]["lut_weight"](G, v, h, alpha)


def dfg_lut(size: int, samples: int, geometry: str, ndf: str = "ggx", sampling: str = "vndf") -> np.ndarray:
    """``(size, size, 2)`` float64 array of ``dfg_lut.comp``'s ``(A, B)`` (row j at roughness
    ``(j + 0.5) / size``, column i at n.v ``(i + 0.5) / size``; [Karis13] eq. 8), one lane per texel
    and sample: the same Hammersley points with the half-cell offset and the same estimator."""
    sampling = lut_sampling_for(sampling, ndf)
    j, i, k = np.meshgrid(np.arange(size), np.arange(size), np.arange(samples), indexing="ij")
    pts = hammersley(k.ravel(), samples)
    u = mi.Point2f(mi.Float(pts[:, 0] + 0.5 / samples), mi.Float(pts[:, 1]))
    NoV = mi.Float((i.ravel() + 0.5) / size)
    roughness = mi.Float((j.ravel() + 0.5) / size)
    alpha = dr.maximum(roughness * roughness, MIN_ALPHA)  # pbrcheck.brdf.alpha_from_roughness
    v = mi.Vector3f(dr.sqrt(1.0 - NoV * NoV), 0.0, NoV)
    h = lut_half_vector(u, v, alpha, sampling, ndf)
    VoH = dr.dot(v, h)
    NoL = 2.0 * VoH * h.z - NoV
    G = terms.geometry_term(geometry, NoV, NoL, roughness, alpha)
    w = dr.select((NoL > 0.0) & (VoH > 0.0), lut_weight(G, v, h, alpha, sampling), 0.0)
    Fc = dr.power(1.0 - VoH, 5)
    A = np.asarray(w * (1.0 - Fc), dtype=np.float64).reshape(size, size, samples).sum(-1) / samples
    B = np.asarray(w * Fc, dtype=np.float64).reshape(size, size, samples).sum(-1) / samples
    return np.stack([A, B], axis=-1)


# ---- runtime importance sampling's strategies (realtime.registry.RUNTIME_SAMPLINGS) ---------------

def runtime_half_vector_beckmann(u, vt, alpha):
    """[Walter07] eq. 28: Beckmann half vectors (article 001, for the GGX D)."""
    return sample_Beckmann(u, alpha)


def runtime_half_vector_ggx(u, vt, alpha):
    """[Walter07] eq. 35-36: GGX half vectors."""
    return sample_GGX(u, alpha)


def runtime_half_vector_vndf(u, vt, alpha):
    """[Heitz18] listing 1: GGX visible normals seen from ``vt`` (``u.yx``)."""
    return lut_half_vector_vndf(u, vt, alpha)


def runtime_estimate_ndf(F, G, L, NoV, NoH, VoH, alpha):
    """Article 001's estimator ``F G L (v.h) / ((n.h)(n.v))`` (exact when ``h`` follows the shaded NDF's ``D (n.h)``)."""
    return F * G * L * VoH / (NoH * NoV)


def runtime_estimate_vndf(F, G, L, NoV, NoH, VoH, alpha):
    """[Heitz18] eq. 17: ``F G L / G1(v)``."""
    return F * G / dr.maximum(terms.G1_SmithGGX(NoV, alpha), COS_EPS) * L


#: The reference's tables of :data:`pbrcheck.sampling.LUT_SAMPLINGS` and ``realtime.registry.RUNTIME_SAMPLINGS``: each
#: member's Dr.Jit role functions by role (``tests/test_registry.py``: the registries' members and
#: roles, each the twin of the member's numpy function of the same name).
LUT_ROLES = {"vndf": {"lut_half_vector": lut_half_vector_vndf, "lut_weight": lut_weight_vndf},
             "ndf": {"lut_half_vector": lut_half_vector_ndf, "lut_weight": lut_weight_ndf}}
RUNTIME_ROLES = {"beckmann": {"runtime_half_vector": runtime_half_vector_beckmann, "runtime_estimate": runtime_estimate_ndf},
                 "ggx": {"runtime_half_vector": runtime_half_vector_ggx, "runtime_estimate": runtime_estimate_ndf},
                 "vndf": {"runtime_half_vector": runtime_half_vector_vndf, "runtime_estimate": runtime_estimate_vndf}}


def runtime_half_vector(u, vt, alpha, sampling: str):
    """The runtime strategy ``sampling``'s half vector (:data:`RUNTIME_ROLES`; KeyError for an unknown one)."""
    return RUNTIME_ROLES[sampling]["runtime_half_vector"](u, vt, alpha)


def runtime_estimate(F, G, L, NoV, NoH, VoH, alpha, sampling: str):
    """The runtime strategy ``sampling``'s estimate of one sample."""
    return RUNTIME_ROLES[sampling]["runtime_estimate"](F, G, L, NoV, NoH, VoH, alpha)
