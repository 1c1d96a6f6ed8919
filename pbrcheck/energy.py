"""Multiple-scattering energy compensation of the specular lobe: the numpy twins of
``realtime/shaders/energy.glsl`` (same function names, tested by the GLSL harness).

Single-scattering microfacet BRDFs lose the energy of the light that bounces more than once between
microfacets: a white metal (F0 = 1) reflects ``E(mu) = A + B < 1`` of a white furnace (A, B: the
split sum's DFG terms at F0 = 1, ``E`` = ``Ess``). Engines add it back with one of these
(``energy_compensation`` option of the real-time renderer; registry
:data:`realtime.registry.ENERGY_COMPENSATIONS`). The truth they approximate is the random walk of
Heitz et al. 2016 (``[brdf] multiscatter = "random_walk"`` in the reference).

* ``filament`` -- Filament's documentation, "Energy loss in specular reflectance" (sec. 4.7.2) and
  its IBL code: the specular lobe is scaled by ``1 + F0 (1 / Ess - 1)`` with ``Ess = A + B`` (in
  Filament's multiscatter DFG form the LUT stores ``dfg.y = A + B`` and the albedo is
  ``mix(dfg.x, dfg.y, F0) = F0 A + B``): :func:`energy_filament`.
* ``fdez_aguera`` -- C. Fdez-Agüera, "A Multiple-Scattering Microfacet Model for Real-Time
  Image-based Lighting", JCGT 8(1) 2019, sec. 3 and listing 1 (eq. 9-13):
  ``FssEss = F0 A + B``, ``Ems = 1 - Ess``, ``Favg = F0 + (1 - F0) / 21``,
  ``Fms = FssEss Favg / (1 - Ems Favg)``; the multiply scattered radiance is ``Fms Ems`` times the
  cosine-weighted irradiance (``E(n) / pi``): :func:`ms_fdez_aguera`. (The paper's roughness-
  dependent Fresnel ``kS`` and its diffuse ``Edss`` are not used: pbrcheck's model has the plain
  Schlick F and the random walk leaves the diffuse term unchanged.)
* ``kulla_conty`` -- C. Kulla, A. Conty, "Revisiting Physically Based Shading at Imageworks",
  SIGGRAPH 2017 course, slides 16-22: the lobe
  ``f_ms(mu_o, mu_i) = (1 - E(mu_o)) (1 - E(mu_i)) / (pi (1 - E_avg))`` with
  ``E_avg = 2 int_0^1 E(mu) mu dmu`` and its Fresnel factor
  ``F_ms = Favg^2 E_avg / (1 - Favg (1 - E_avg))``. Under a constant environment the lobe reflects
  ``F_ms (1 - E(mu_o))`` exactly; for image-based lighting the environment is taken as its
  irradiance (``int (1 - E(mu_i)) L cos dw_i ~ (1 - E_avg) E(n)``), so the multiply scattered
  radiance is ``F_ms (1 - E(mu_o)) E(n) / pi``: :func:`ms_kulla_conty`.

Each member of the registry holds its role functions here (``energy_scale_<name>``,
``energy_ms_<name>``, ``energy_direct_<name>``; a member without a role is the identity there); the
dispatch by name in numpy (:mod:`realtime.dispatch`), in Dr.Jit (:mod:`reference.energy`) and in the
generated GLSL loops over it.

Point lights (``energy_direct``): Filament scales its direct specular lobe by the same factor;
Kulla-Conty add their lobe ``f_ms`` (:func:`f_ms_kulla_conty`, ``E(mu_i)`` from the DFG terms at
n.l); Fdez-Agüera's paper covers image-based lighting only (nothing added). The compensation needs
the split sum's DFG terms: ``shading = material`` and ``ibl = splitsum`` only.

Tables (Kulla-Conty): ``E(mu)`` is the DFG LUT's ``A + B`` (its axes: column i at
``n.v = (i + 0.5) / N``, row j at ``roughness = (j + 0.5) / N``); ``E_avg(roughness)`` is
:data:`KC_EAVG`, ``KC_EAVG_SIZE`` values at ``roughness = j / (KC_EAVG_SIZE - 1)``, linear in
between (:func:`kc_eavg`), baked by :func:`bake_kc_eavg` from :func:`pbrcheck.brdf.specular_dfg`
(GGX, height-correlated Smith: the random walk's microsurface) with ``KC_EAVG_MU_NODES``
Gauss-Legendre nodes in ``mu``. The same numbers are in ``energy.glsl`` (tested equal).

API
---
:func:`F_avg_Schlick`, :func:`energy_filament`, :func:`ms_fdez_aguera`, :func:`ms_kulla_conty`,
:func:`f_ms_kulla_conty`, :func:`kc_eavg`; the registry members' role functions
:func:`energy_scale_filament`, :func:`energy_direct_filament`, :func:`energy_ms_fdez_aguera`,
:func:`energy_ms_kulla_conty`, :func:`energy_direct_kulla_conty` (held by the entries of
:data:`realtime.registry.ENERGY_COMPENSATIONS`; the dispatch by name ``energy_scale``, ``energy_ms``,
``energy_direct``, ``specular_albedo_compensated`` is :mod:`realtime.dispatch`'s); :func:`bake_kc_eavg`,
:data:`KC_EAVG`, :data:`KC_EAVG_SIZE`, :data:`SCENE_COMPENSATION`. Dr.Jit twins of the same names:
:mod:`reference.energy`.
"""

from __future__ import annotations

import numpy as np

from . import brdf as _brdf

#: Entries of the E_avg table, at roughness j / (KC_EAVG_SIZE - 1).
KC_EAVG_SIZE = 17
#: Gauss-Legendre nodes in mu of the E_avg bake.
KC_EAVG_MU_NODES = 32

#: E_avg(roughness) of GGX with the height-correlated Smith term: bake_kc_eavg() (tests re-bake it).
KC_EAVG = (
    1.0000000, 0.9999079, 0.9988651, 0.9952562, 0.9872503, 0.9731154, 0.9514348, 0.9212760, 0.8823234,
    0.8349606, 0.7802779, 0.7199813, 0.6562014, 0.5912315, 0.5272513, 0.4660994, 0.4091371,
)

#: ``energy_compensation = "scene"`` (the default preset): the compensation matching the scene's
#: ``[brdf] multiscatter``. For ``random_walk`` the best by measurement (``pbrcheck energy``,
#: docs/research.md): filament has the lowest mean albedo error over roughness x F0 x n.v (0.0047
#: against 0.0060 fdez_aguera, 0.0064 kulla_conty, 0.066 none) and the lowest FLIP on the spheres
#: scene against the random_walk reference (flip_mean 0.054 against 0.076, 0.057, 0.135; relmse
#: 0.0039 against 0.0054, 0.0038 (kulla_conty, within the 128-spp reference's noise), 0.020).
SCENE_COMPENSATION = {"none": "none", "random_walk": "filament"}


def F_avg_Schlick(F0):
    """Hemispherical average of Schlick's Fresnel, ``2 int F(mu) mu dmu = F0 + (1 - F0) / 21``
    [Kulla-Conty 2017 slide 20; Fdez-Agüera 2019 eq. 11]."""
    F0 = np.asarray(F0, dtype=np.float64)
    return F0 + (1.0 - F0) / 21.0


def energy_filament(F0, Ess):
    """Filament's multiple-scattering scale of the specular lobe: ``1 + F0 (1 / Ess - 1)``."""
    F0 = np.asarray(F0, dtype=np.float64)
    Ess = np.maximum(np.asarray(Ess, dtype=np.float64), 1e-4)
    return 1.0 + F0 * (1.0 / Ess - 1.0)


def ms_fdez_aguera(F0, A, B):
    """Fdez-Agüera 2019 eq. 9-13: the multiply scattered albedo ``Fms Ems`` (times E(n)/pi)."""
    F0 = np.asarray(F0, dtype=np.float64)
    A = np.asarray(A, dtype=np.float64)
    B = np.asarray(B, dtype=np.float64)
    FssEss = F0 * A + B
    Ems = 1.0 - (A + B)
    Favg = F_avg_Schlick(F0)
    Fms = FssEss * Favg / (1.0 - Ems * Favg)
    return Fms * Ems


def ms_kulla_conty(F0, Ess, Eavg):
    """Kulla-Conty 2017: ``F_ms (1 - E(mu_o))`` with ``F_ms = Favg^2 E_avg / (1 - Favg (1 - E_avg))``
    (times E(n)/pi)."""
    F0 = np.asarray(F0, dtype=np.float64)
    Ess = np.asarray(Ess, dtype=np.float64)
    Eavg = np.asarray(Eavg, dtype=np.float64)
    Favg = F_avg_Schlick(F0)
    Fms = Favg * Favg * Eavg / (1.0 - Favg * (1.0 - Eavg))
    return Fms * (1.0 - Ess)


def f_ms_kulla_conty(F0, Ev, El, Eavg):
    """Kulla-Conty 2017's multiple-scattering lobe for direct light (a BRDF value, no cosine):
    ``F_ms (1 - E(mu_o)) (1 - E(mu_i)) / (pi (1 - E_avg))``."""
    F0 = np.asarray(F0, dtype=np.float64)
    Eavg = np.asarray(Eavg, dtype=np.float64)
    Favg = F_avg_Schlick(F0)
    Fms = Favg * Favg * Eavg / (1.0 - Favg * (1.0 - Eavg))
    return Fms * (1.0 - np.asarray(Ev)) * (1.0 - np.asarray(El)) / (np.pi * np.maximum(1.0 - Eavg, 1e-6))


def kc_eavg(roughness):
    """E_avg(roughness) from :data:`KC_EAVG`: linear between its entries at ``j / (size - 1)``."""
    r = np.clip(np.asarray(roughness, dtype=np.float64), 0.0, 1.0)
    return np.interp(r, np.linspace(0.0, 1.0, KC_EAVG_SIZE), np.asarray(KC_EAVG))


# ---- the registry members' role functions (realtime.registry.ENERGY_COMPENSATIONS) ---------------

def energy_scale_filament(F0, A, B):
    """Filament: the split sum's specular factor ``1 + F0 (1 / (A + B) - 1)``."""
    return energy_filament(F0, np.asarray(A) + np.asarray(B))


def energy_direct_filament(f_spec, F0, A, B, El, roughness):
    """Filament's direct lobe: adds ``(scale - 1) f_spec`` to a point light's BRDF."""
    return (energy_filament(F0, np.asarray(A) + np.asarray(B)) - 1.0) * np.asarray(f_spec)


def energy_ms_fdez_aguera(F0, A, B, roughness):
    """Fdez-Agüera: adds ``Fms Ems`` times ``E(n) / pi`` (:func:`ms_fdez_aguera`)."""
    return ms_fdez_aguera(F0, A, B)


def energy_ms_kulla_conty(F0, A, B, roughness):
    """Kulla-Conty: adds ``F_ms (1 - (A + B))`` times ``E(n) / pi``, ``E_avg`` from :func:`kc_eavg`."""
    return ms_kulla_conty(F0, np.asarray(A) + np.asarray(B), kc_eavg(roughness))


def energy_direct_kulla_conty(f_spec, F0, A, B, El, roughness):
    """Kulla-Conty: adds the lobe :func:`f_ms_kulla_conty` (``E(mu_o) = A + B``, ``E(mu_i) = El``)."""
    return f_ms_kulla_conty(F0, np.asarray(A) + np.asarray(B), El, kc_eavg(roughness))


def bake_kc_eavg(size: int = KC_EAVG_SIZE, mu_nodes: int = KC_EAVG_MU_NODES) -> np.ndarray:
    """``E_avg(r_j) = 2 int_0^1 E(mu) mu dmu`` at ``r_j = j / (size - 1)`` (Gauss-Legendre in mu,
    ``E = A + B`` of :func:`pbrcheck.brdf.specular_dfg`, GGX and height-correlated Smith)."""
    x, w = np.polynomial.legendre.leggauss(mu_nodes)
    mu = 0.5 * (x + 1.0)
    w = 0.5 * w
    out = np.empty(size)
    for j, r in enumerate(np.linspace(0.0, 1.0, size)):
        E = np.array([sum(_brdf.specular_dfg(m, r)) for m in mu])
        out[j] = 2.0 * np.sum(w * E * mu)
    return out
