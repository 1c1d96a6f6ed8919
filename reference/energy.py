"""Multiple-scattering energy compensations in Dr.Jit: the twins of :mod:`pbrcheck.energy` (same
function names, same formulas; ``realtime/shaders/energy.glsl`` is the third language).

Each member of :data:`realtime.registry.ENERGY_COMPENSATIONS` has its role functions
(``energy_scale_<name>``, ``energy_ms_<name>``, ``energy_direct_<name>``); this module's :data:`ROLES` holds their Dr.Jit twins by member (:func:`energy_scale`, :func:`energy_ms`,
:func:`energy_direct` loop the registry), so the reference can evaluate a compensation exactly as
the real-time renderer does, e.g. the compensated albedo of a single-scattering lobe
(:func:`specular_albedo_compensated`). Arguments are Dr.Jit arrays (``mi.Float`` or ``mi.Color3f``
for ``F0`` and ``f_spec``); ``A``, ``B`` are the split sum's DFG terms at F0 = 1, ``El`` the
directional albedo ``A + B`` at n.l, ``roughness`` perceptual. References: Filament documentation
sec. 4.7.2; C. Fdez-Agüera, JCGT 8(1) 2019, eq. 9-13; C. Kulla, A. Conty, SIGGRAPH 2017 course,
slides 16-22 (as cited in :mod:`pbrcheck.energy`).

API
---
:func:`F_avg_Schlick`, :func:`energy_filament`, :func:`ms_fdez_aguera`, :func:`ms_kulla_conty`,
:func:`f_ms_kulla_conty`, :func:`kc_eavg`, :func:`energy_scale_filament`, :func:`energy_direct_filament`,
:func:`energy_ms_fdez_aguera`, :func:`energy_ms_kulla_conty`, :func:`energy_direct_kulla_conty`,
:func:`energy_scale`, :func:`energy_ms`, :func:`energy_direct`, :func:`specular_albedo_compensated`, :data:`ROLES`.
"""

from __future__ import annotations

import math

import pbrcheck  # noqa: F401  (sets DRJIT_LIBLLVM_PATH before drjit loads)
from pbrcheck.energy import KC_EAVG, KC_EAVG_SIZE

import drjit as dr
import mitsuba as mi


def F_avg_Schlick(F0):
    """``F0 + (1 - F0) / 21`` [Kulla-Conty 2017 slide 20; Fdez-Agüera 2019 eq. 11]."""
    return F0 + (1.0 - F0) / 21.0


def energy_filament(F0, Ess):
    """Filament's scale of the specular lobe ``1 + F0 (1 / Ess - 1)``."""
    return 1.0 + F0 * (1.0 / dr.maximum(Ess, 1e-4) - 1.0)


def ms_fdez_aguera(F0, A, B):
    """Fdez-Agüera 2019 eq. 9-13: ``Fms Ems`` (times E(n)/pi)."""
    FssEss = F0 * A + B
    Ems = 1.0 - (A + B)
    Favg = F_avg_Schlick(F0)
    return FssEss * Favg / (1.0 - Ems * Favg) * Ems


def ms_kulla_conty(F0, Ess, Eavg):
    """Kulla-Conty 2017: ``F_ms (1 - E(mu_o))``, ``F_ms = Favg^2 E_avg / (1 - Favg (1 - E_avg))``."""
    Favg = F_avg_Schlick(F0)
    return Favg * Favg * Eavg / (1.0 - Favg * (1.0 - Eavg)) * (1.0 - Ess)


def f_ms_kulla_conty(F0, Ev, El, Eavg):
    """Kulla-Conty 2017 slide 18: ``F_ms (1 - E(mu_o)) (1 - E(mu_i)) / (pi (1 - E_avg))``."""
    Favg = F_avg_Schlick(F0)
    Fms = Favg * Favg * Eavg / (1.0 - Favg * (1.0 - Eavg))
    return Fms * (1.0 - Ev) * (1.0 - El) / (math.pi * dr.maximum(1.0 - Eavg, 1e-6))


def kc_eavg(roughness):
    """E_avg(roughness) from :data:`pbrcheck.energy.KC_EAVG`, linear between its entries."""
    table = mi.Float(KC_EAVG)
    x = dr.clip(roughness, 0.0, 1.0) * float(KC_EAVG_SIZE - 1)
    i = dr.minimum(mi.UInt32(dr.floor(x)), KC_EAVG_SIZE - 2)
    lo, hi = dr.gather(mi.Float, table, i), dr.gather(mi.Float, table, i + 1)
    return dr.lerp(lo, hi, x - mi.Float(i))


# ---- the registry members' role functions (realtime.registry.ENERGY_COMPENSATIONS) ---------------

def energy_scale_filament(F0, A, B):
    return energy_filament(F0, A + B)


def energy_direct_filament(f_spec, F0, A, B, El, roughness):
    return (energy_filament(F0, A + B) - 1.0) * f_spec


def energy_ms_fdez_aguera(F0, A, B, roughness):
    return ms_fdez_aguera(F0, A, B)


def energy_ms_kulla_conty(F0, A, B, roughness):
    return ms_kulla_conty(F0, A + B, kc_eavg(roughness))


def energy_direct_kulla_conty(f_spec, F0, A, B, El, roughness):
    return f_ms_kulla_conty(F0, A + B, El, kc_eavg(roughness))


#: The reference's table of :data:`realtime.registry.ENERGY_COMPENSATIONS` (keyed by its members; the
#: reference may not import the real-time renderer): each member's Dr.Jit role
#: functions by role (``tests/test_registry.py``: the registry's members and roles, each the twin of
#: the member's numpy function of the same name).
ROLES = {"none": {}, "filament": {"energy_scale": energy_scale_filament, "energy_direct": energy_direct_filament},
         "fdez_aguera": {"energy_ms": energy_ms_fdez_aguera},
         "kulla_conty": {"energy_ms": energy_ms_kulla_conty, "energy_direct": energy_direct_kulla_conty}}


def _role(role: str, compensation: str):
    """The member's Dr.Jit function for ``role`` (:data:`ROLES`), None where the member has not that role."""
    if compensation not in ROLES:
        raise ValueError(f"unknown energy compensation {compensation!r} (one of {', '.join(ROLES)})")
    return ROLES[compensation].get(role)


def energy_scale(F0, A, B, compensation: str):
    """The split sum's specular factor: the member's ``energy_scale_<name>``, else 1."""
    f = _role("energy_scale", compensation)
    return dr.zeros(type(F0), dr.width(F0)) + 1.0 if f is None else f(F0, A, B)


def energy_ms(F0, A, B, roughness, compensation: str):
    """The multiply scattered albedo added times E(n)/pi: the member's ``energy_ms_<name>``, else 0."""
    f = _role("energy_ms", compensation)
    return dr.zeros(type(F0), dr.width(F0)) if f is None else f(F0, A, B, roughness)


def energy_direct(f_spec, F0, A, B, El, roughness, compensation: str):
    """Added to a point light's single-scattering BRDF: the member's ``energy_direct_<name>``, else 0."""
    f = _role("energy_direct", compensation)
    return dr.zeros(type(f_spec), dr.width(f_spec)) if f is None else f(f_spec, F0, A, B, El, roughness)


def specular_albedo_compensated(F0, A, B, roughness, compensation: str):
    """Directional albedo of the compensated lobe under a white furnace: ``(F0 A + B) scale + ms``."""
    return (F0 * A + B) * energy_scale(F0, A, B, compensation) + energy_ms(F0, A, B, roughness, compensation)
