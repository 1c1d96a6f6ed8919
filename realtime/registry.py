"""The real-time renderer's registries and switches (:mod:`pbrcheck.registry`'s :class:`Registry`).

The real-time-only closed lists: the compositions (:data:`SHADINGS`) and the image-based lighting's
switches (:data:`IRRADIANCES`, :data:`IRRADIANCE_METHODS`, :data:`DFGS`), which have no numpy or
Dr.Jit counterpart; and the GLSL side of every list: each GLSL switch's registry
(:data:`REGISTRIES`, whose members' named constants :func:`realtime.generated.glsl_defines`
prepends to every shader), the term registries' generated dispatch functions with their hooks
(:data:`TERM_REGISTRIES`) and the role registries' (:data:`ROLE_REGISTRIES`). The lists whose members
have numpy twins in the core (terms, LOD mappings, energy compensations, sampling strategies,
occlusions, specular anti-aliasing) stay in :mod:`pbrcheck.registry`, which the core's twins read.

API
---
:data:`SHADINGS`, :data:`IRRADIANCES`, :data:`IRRADIANCE_METHODS`, :data:`DFGS`, :data:`TERM_REGISTRIES`,
:data:`ROLE_REGISTRIES`, :data:`REGISTRIES`, :func:`role_reads`.
"""

from __future__ import annotations

from pbrcheck.energy import ENERGY_COMPENSATIONS
from pbrcheck.lodmap import LOD_MAPPINGS
from pbrcheck.occlusion import HORIZON_OCCLUSIONS, SPECULAR_OCCLUSIONS
from pbrcheck.registry import FRESNELS, GEOMETRIES, MULTISCATTERS, NDFS, Entry, Registry, switch
from pbrcheck.sampling import LUT_SAMPLINGS, RUNTIME_SAMPLINGS
from pbrcheck.specular_aa import SPECULAR_AAS

#: Each composition ``requires`` the specular image-based lighting it has (``ibl`` option): article
#: 001 is runtime sampling only, articles 000 and 002 split sum only, the material model has both.
#: ``extra["hooks"]``: the composition whose pieces shader hooks replace (docs/hooks.md);
#: ``extra["seeded"]``: its ``shade_<name>`` takes the pixel seed (it may sample at run time). Each
#: composition's GLSL functions are ``shade_<name>`` and ``light_brdf_<name>`` (shading.glsl), called
#: by the generated ``shade_composition`` / ``light_brdf`` (``shading_dispatch.glsl``).
SHADINGS = Registry("SHADING", applies_to=(
    "the real-time renderer's compositions (shading.glsl: shade_<name> and light_brdf_<name> each, dispatch "
    "generated); the reference renders one material model (pbrcheck.brdf, reference.bsdf)"), entries=[
    Entry("material", "README's material model", extra={"hooks": True, "seeded": True}),
    Entry("article000", "article 000 (Drevicky 2018)", requires={"ibl": ("splitsum",)}, extra={"seeded": False}),
    Entry("article001", "article 001 (runtime importance sampling)", requires={"ibl": ("runtime",)},
          extra={"seeded": True}),
    Entry("article002", "article 002 (EnvBRDFApprox, SH9)", requires={"ibl": ("splitsum",)}, extra={"seeded": False}),
])

_REALTIME_ONLY = "a switch of the real-time renderer's own passes ({}); no numpy or Dr.Jit counterpart"


IRRADIANCES = switch("IRRADIANCE", _REALTIME_ONLY.format("irradiance.comp, sh9.comp"), convolution="cube convolution of the environment (E(n) / pi per texel)",
                      sh9="9 spherical-harmonic coefficients, Ramamoorthi & Hanrahan 2001 (article 002)")
IRRADIANCE_METHODS = switch("IRRADIANCE_METHOD", _REALTIME_ONLY.format("irradiance.comp"), texel_sum="sum over every source texel, weighted by its solid angle",
                             polar_steps="article 000's uniform polar / azimuth steps")
DFGS = switch("DFG", _REALTIME_ONLY.format("ibl.glsl"), lut="baked DFG LUT (split sum's second factor), Karis 2013",
               analytic="Karis's EnvBRDFApprox fit (mobile, 2014; article 002)")

#: The term registries (their entries hold their term classes, :mod:`pbrcheck.terms`), by GLSL switch, with
#: the GLSL dispatch function each generates, its signature and its user hook.
TERM_REGISTRIES = {"NDF": (NDFS, "float ndf_term(float NoH, float roughness)", "hook_D(NoH, roughness)"),
                   "GEOMETRY": (GEOMETRIES, "float geometry_term(float NoV, float NoL, float roughness)",
                                "hook_G(NoV, NoL, roughness)"),
                   "FRESNEL": (FRESNELS, "vec3 fresnel_term(float VoH, vec3 F0)", "hook_F(VoH, F0)")}

#: The registries whose members implement roles (:attr:`Entry.roles`), by GLSL switch: the generated
#: include, the member selected where a shader leaves the switch undefined, and each role's GLSL
#: dispatch signature and the identity a member without the role returns ("": every member has it).
ROLE_REGISTRIES = {
    "ENERGY_COMPENSATION": (ENERGY_COMPENSATIONS, "energy_dispatch.glsl", "none", {
        "energy_scale": ("vec3 energy_scale(vec3 F0, float A, float B)", "vec3(1.0)"),
        "energy_ms": ("vec3 energy_ms(vec3 F0, float A, float B, float roughness)", "vec3(0.0)"),
        "energy_direct": ("vec3 energy_direct(vec3 f_spec, vec3 F0, float A, float B, float El, float roughness)",
                          "vec3(0.0)")}),
    "RUNTIME_SAMPLING": (RUNTIME_SAMPLINGS, "runtime_sampling_dispatch.glsl", "vndf", {
        "runtime_half_vector": ("vec3 runtime_half_vector(vec2 u, vec3 vt, float alpha)", ""),
        "runtime_estimate": ("vec3 runtime_estimate(vec3 F, float G, vec3 L, float NoV, float NoH, float VoH, float alpha)",
                             "")}),
    "LUT_SAMPLING": (LUT_SAMPLINGS, "dfg_sampling_dispatch.glsl", "vndf", {
        "lut_half_vector": ("vec3 lut_half_vector(vec2 u, vec3 v, float alpha)", ""),
        "lut_weight": ("float lut_weight(float G, vec3 v, vec3 h, float alpha)", "")}),
    "SPECULAR_OCCLUSION": (SPECULAR_OCCLUSIONS, "specular_occlusion_dispatch.glsl", "none", {
        "specular_occlusion": ("float specular_occlusion(float NoV, float ao, float roughness)", "1.0")}),
    "HORIZON_OCCLUSION": (HORIZON_OCCLUSIONS, "horizon_occlusion_dispatch.glsl", "none", {
        "horizon_occlusion": ("float horizon_occlusion(float RoNg)", "1.0")}),
    "SPECULAR_AA": (SPECULAR_AAS, "specular_aa_dispatch.glsl", "none", {
        "specular_aa": ("float specular_aa(float roughness, float normal_length, float variance, float dn2)",
                        "roughness")}),
}
#: Every registry, by its GLSL switch name.
REGISTRIES = {r.define: r for r in (NDFS, GEOMETRIES, FRESNELS, LOD_MAPPINGS, SHADINGS, RUNTIME_SAMPLINGS,
                                     IRRADIANCES, IRRADIANCE_METHODS, DFGS, LUT_SAMPLINGS, MULTISCATTERS,
                                     ENERGY_COMPENSATIONS, SPECULAR_OCCLUSIONS, HORIZON_OCCLUSIONS, SPECULAR_AAS)}


def role_reads(registry: Registry, name: str, role: str, param: str) -> bool:
    """Whether member ``name``'s ``role`` function reads the dispatch parameter ``param`` (its
    :attr:`~pbrcheck.registry.Role.args`, all parameters where empty; False for a member without the role)."""
    r = registry[name].roles.get(role)
    return r is not None and (not r.args or param in r.args)
