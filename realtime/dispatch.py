"""numpy dispatch by name over the real-time registries (:mod:`realtime.registry`): each function is
the twin of the generated GLSL dispatch function of the same name (``energy_dispatch.glsl``, ...) and
calls the selected member's numpy role function (:attr:`pbrcheck.registry.Entry.roles`), or returns
the list's identity for a member without that role; the GLSL harness compares the two
(``tests/test_energy.py``, ``tests/test_realtime_sampling.py``, ``tests/test_registry.py``).

API
---
:func:`energy_scale`, :func:`energy_ms`, :func:`energy_direct`, :func:`specular_albedo_compensated`,
:func:`runtime_half_vector`, :func:`runtime_estimate`, :func:`specular_occlusion`,
:func:`horizon_occlusion`, :func:`specular_aa`.
"""

from __future__ import annotations

import numpy as np

from pbrcheck.registry import member_role

from .registry import (ENERGY_COMPENSATIONS, HORIZON_OCCLUSIONS, RUNTIME_SAMPLINGS, SPECULAR_AAS,
                       SPECULAR_OCCLUSIONS)


def _role(name: str, compensation: str):
    """The member's numpy function for the role ``name``, None where the member has not that role
    (its identity); ValueError naming an unknown compensation."""
    try:
        r = member_role(ENERGY_COMPENSATIONS, compensation, name, "energy compensation")
    except KeyError:
        raise ValueError(f"unknown energy compensation {compensation!r} (one of {', '.join(ENERGY_COMPENSATIONS.names)})") from None
    return None if r is None else r.numpy


def energy_scale(F0, A, B, compensation: str):
    """Factor of the split sum's specular term ``prefiltered (F0 A + B)``: the member's
    ``energy_scale_<name>``, 1 for a member without one."""
    f = _role("energy_scale", compensation)
    return np.ones(np.broadcast_shapes(np.shape(F0), np.shape(A))) if f is None else f(F0, A, B)


def energy_ms(F0, A, B, roughness, compensation: str):
    """Multiply scattered albedo added times ``E(n) / pi``: the member's ``energy_ms_<name>``, 0 for a
    member without one."""
    f = _role("energy_ms", compensation)
    return np.zeros(np.broadcast_shapes(np.shape(F0), np.shape(A))) if f is None else f(F0, A, B, roughness)


def energy_direct(f_spec, F0, A, B, El, roughness, compensation: str):
    """What the compensation adds to the single-scattering BRDF for a point light: the member's
    ``energy_direct_<name>`` (Filament's ``(scale - 1) f_spec``, Kulla-Conty's lobe), 0 for a member
    without one (``fdez_aguera``: image-based lighting only; ``none``)."""
    f = _role("energy_direct", compensation)
    if f is None:
        return np.zeros(np.broadcast_shapes(np.shape(F0), np.shape(A), np.shape(f_spec)))
    return f(f_spec, F0, A, B, El, roughness)


def specular_albedo_compensated(F0, A, B, roughness, compensation: str):
    """Directional albedo of the compensated specular lobe under a white furnace (E(n)/pi = 1):
    ``(F0 A + B) energy_scale + energy_ms``."""
    F0 = np.asarray(F0, dtype=np.float64)
    ss = F0 * A + B
    return ss * energy_scale(F0, A, B, compensation) + energy_ms(F0, A, B, roughness, compensation)


def runtime_half_vector(u, vt, alpha, sampling: str):
    """The runtime strategy ``sampling``'s half vector (KeyError for an unknown one)."""
    return RUNTIME_SAMPLINGS[sampling].roles["runtime_half_vector"].numpy(u, vt, alpha)


def runtime_estimate(F, G, L, NoV, NoH, VoH, alpha, sampling: str):
    """The runtime strategy ``sampling``'s estimate of one sample."""
    return RUNTIME_SAMPLINGS[sampling].roles["runtime_estimate"].numpy(F, G, L, NoV, NoH, VoH, alpha)


def specular_occlusion(NoV, ao, roughness, method: str):
    """The specular occlusion factor of ``method``: its registry entry's ``specular_occlusion_<name>``
    (:data:`realtime.registry.SPECULAR_OCCLUSIONS`), 1 for ``none``; KeyError for an unknown method."""
    r = member_role(SPECULAR_OCCLUSIONS, method, "specular_occlusion", "specular occlusion")
    if r is None:
        return np.ones(np.broadcast(np.asarray(NoV), np.asarray(ao), np.asarray(roughness)).shape)
    return r.numpy(NoV, ao, roughness)


def horizon_occlusion(RoNg, method: str):
    """The horizon occlusion factor of ``method``: its registry entry's ``horizon_occlusion_<name>``
    (:data:`realtime.registry.HORIZON_OCCLUSIONS`), 1 for ``none``; KeyError for an unknown method."""
    r = member_role(HORIZON_OCCLUSIONS, method, "horizon_occlusion", "horizon occlusion")
    if r is None:
        return np.ones(np.shape(RoNg))
    return r.numpy(RoNg)


def specular_aa(roughness, normal_length, variance, dn2, method: str):
    """The filtered perceptual roughness of ``method``: its registry entry's ``specular_aa_<name>``
    (:data:`realtime.registry.SPECULAR_AAS`) of the inputs it reads (:attr:`~pbrcheck.registry.Role.args`),
    the roughness unchanged for ``none``; KeyError for an unknown method."""
    r = member_role(SPECULAR_AAS, method, "specular_aa", "specular anti-aliasing")
    inputs = {"roughness": roughness, "normal_length": normal_length, "variance": variance, "dn2": dn2}
    if r is None:
        return np.broadcast_to(np.asarray(roughness, np.float64),
                               np.broadcast(*(np.asarray(x) for x in inputs.values())).shape)
    return r.numpy(*(inputs[a] for a in r.args))
