"""The real-time renderer's registries and switches (:mod:`pbrcheck.registry`'s :class:`Registry`).

The real-time-only closed lists: the compositions (:data:`SHADINGS`) and the image-based lighting's
switches (:data:`IRRADIANCES`, :data:`IRRADIANCE_METHODS`, :data:`DFGS`), which have no numpy or
Dr.Jit counterpart; the real-time approximations whose entries hold their numpy role functions
(:data:`RUNTIME_SAMPLINGS`, :data:`ENERGY_COMPENSATIONS`, :data:`SPECULAR_OCCLUSIONS`,
:data:`HORIZON_OCCLUSIONS`, :data:`SPECULAR_AAS`: the functions are the core's, the choice among them
and the real-time options a member requires are the renderer's; the numpy dispatch by name is
:mod:`realtime.dispatch`); and the GLSL side of every list: each GLSL switch's registry
(:data:`REGISTRIES`, whose members' named constants :func:`realtime.generated.glsl_defines`
prepends to every shader), the term registries' generated dispatch functions with their hooks
(:data:`TERM_REGISTRIES`) and the role registries' (:data:`ROLE_REGISTRIES`). The lists the core
itself reads stay there: the scene's terms (:mod:`pbrcheck.registry`), the LOD mappings
(:data:`pbrcheck.lodmap.LOD_MAPPINGS`: a fitted mapping's file names its chain) and the DFG LUT's
strategies (:data:`pbrcheck.sampling.LUT_SAMPLINGS`, which the reference's LUT bake shares).

API
---
:data:`SHADINGS`, :data:`IRRADIANCES`, :data:`IRRADIANCE_METHODS`, :data:`DFGS`, :data:`RUNTIME_SAMPLINGS`,
:data:`ENERGY_COMPENSATIONS`, :data:`SPECULAR_OCCLUSIONS`, :data:`HORIZON_OCCLUSIONS`, :data:`SPECULAR_AAS`,
:data:`TERM_REGISTRIES`,
:data:`ROLE_REGISTRIES`, :data:`REGISTRIES`, :func:`role_reads`; the lobes' approximations (issue 36):
:data:`COAT_ATTENUATIONS`, :data:`COAT_IBLS`, :data:`SHEEN_DFGS`, :data:`SHEEN_SCALINGS`,
:data:`ANISOTROPY_BENDS`, :data:`IRIDESCENCES`, :data:`LOBE_REGISTRIES`, :data:`LOBE_LUTS` (the ``fitted`` members
of SHEEN_DFGS and ANISOTROPY_BENDS are ``pbrcheck fit-lobes``' AD fits, their entries holding
:mod:`realtime.fitted_lobes`' GLSL as ``extra["glsl"]``); transmission's
(issue 37): :data:`TRANSMISSION_LODS`, :data:`TRANSMISSION_SOURCES` (defined in :mod:`realtime.transmission`).
"""

from __future__ import annotations

from pbrcheck.energy import (energy_direct_filament, energy_direct_kulla_conty, energy_ms_fdez_aguera,
                             energy_ms_kulla_conty, energy_scale_filament)
from pbrcheck.lodmap import LOD_MAPPINGS
from pbrcheck.occlusion import horizon_occlusion_marmoset, specular_occlusion_gtso, specular_occlusion_lagarde
from pbrcheck.registry import (FRESNELS, GEOMETRIES, MULTISCATTERS, NDFS, REALTIME_APPROXIMATION, Entry, Registry,
                               role, switch)
from pbrcheck.sampling import (LUT_SAMPLINGS, runtime_estimate_ndf, runtime_estimate_vndf, runtime_half_vector_beckmann,
                               runtime_half_vector_ggx, runtime_half_vector_vndf)
from pbrcheck.specular_aa import specular_aa_prefiltered, specular_aa_screen_space, specular_aa_toksvig

from . import fitted_lobes as _fitted
from . import lobes as _lobes
from .transmission import TRANSMISSION_LODS, TRANSMISSION_SOURCES  # noqa: F401  (issue 37 item 2: the opaque-pass framebuffer's read)

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

#: Runtime importance sampling of the environment (article 001, environment_light.glsl): each
#: strategy's half vector in tangent space (``runtime_half_vector_<name>``) and its estimator of
#: ``F G L (v.h) / ((n.h)(n.v))``-type terms (``runtime_estimate_*``: ``runtime_estimate_ndf``, correct
#: when the half vectors follow the shaded NDF's D (n.h), is the article's, shared by beckmann and ggx); numpy in
#: :mod:`pbrcheck.sampling`, Dr.Jit in :mod:`reference.sampling` (``RUNTIME_ROLES``), GLSL in ``sampling.glsl``.
RUNTIME_SAMPLINGS = Registry("RUNTIME_SAMPLING", [
    Entry("beckmann", "Beckmann half vectors (article 001 samples them for the GGX D)",
          roles={"runtime_half_vector": role(runtime_half_vector_beckmann), "runtime_estimate": role(runtime_estimate_ndf)},
          applies_to="exact for the Beckmann D it samples; biased for the GGX D article 001 shades with it"),
    Entry("ggx", "GGX half vectors, Walter et al. 2007 eq. 35-36",
          roles={"runtime_half_vector": role(runtime_half_vector_ggx), "runtime_estimate": role(runtime_estimate_ndf)},
          applies_to="any NDF's shading; exact for the GGX D it samples"),
    Entry("vndf", "GGX visible normals, Heitz 2018", roles={"runtime_half_vector": role(runtime_half_vector_vndf),
                 "runtime_estimate": role(runtime_estimate_vndf)},
          applies_to="any NDF's shading; exact for the GGX D (its visible normals, Smith GGX G1)"),
])

_IBL_ONLY = "image-based lighting only"
#: The real-time options a compensation needs: the material composition's split sum.
_SPLIT_SUM_MATERIAL = {"shading": ("material",), "ibl": ("splitsum",)}
#: Multiple-scattering energy compensation of the real-time specular lobe: each member's functions
#: for the split sum's specular factor (``energy_scale_<name>``), the multiply scattered albedo added
#: times the irradiance (``energy_ms_<name>``) and the point lights' added lobe
#: (``energy_direct_<name>``); numpy in :mod:`pbrcheck.energy`, Dr.Jit in :mod:`reference.energy` (``ROLES``),
#: GLSL in ``realtime/shaders/energy.glsl``. They apply with ``shading = material`` and
#: ``ibl = splitsum`` only (they need the split sum's DFG terms, which runtime sampling and the
#: article compositions do not have): each member but ``none`` requires them (:attr:`Entry.requires`).
ENERGY_COMPENSATIONS = Registry("ENERGY_COMPENSATION", [
    Entry("none", "single scattering only", applies_to="nothing is added: scale 1, no lobe"),
    Entry("filament", "Filament's scale 1 + F0 (1 / (A + B) - 1) (Filament documentation sec. 4.7.2)",
          roles={"energy_scale": role(energy_scale_filament), "energy_direct": role(energy_direct_filament)}, requires=_SPLIT_SUM_MATERIAL,
          applies_to="a scale of the split sum's specular and of the point lights' specular lobe"),
    Entry("fdez_aguera", "Fdez-Aguera 2019, JCGT 8(1), eq. 9-13: Fms Ems times the irradiance",
          roles={"energy_ms": role(energy_ms_fdez_aguera)}, requires=_SPLIT_SUM_MATERIAL,
          applies_to=f"{_IBL_ONLY}: the paper has no point-light lobe; no scale (an added albedo)"),
    Entry("kulla_conty", "Kulla & Conty 2017 (SIGGRAPH course): F_ms (1 - E(mu)) times the irradiance, E_avg table",
          roles={"energy_ms": role(energy_ms_kulla_conty), "energy_direct": role(energy_direct_kulla_conty)}, requires=_SPLIT_SUM_MATERIAL,
          applies_to="an added albedo times the irradiance and an added lobe for point lights; no scale"),
])

#: Specular occlusion of the split sum's image-based specular from the ambient occlusion: each
#: member's ``specular_occlusion_<name>(NoV, ao, roughness)``, numpy in :mod:`pbrcheck.occlusion`,
#: GLSL in ``realtime/shaders/occlusion.glsl`` (dispatch ``specular_occlusion_dispatch.glsl``).
SPECULAR_OCCLUSIONS = Registry("SPECULAR_OCCLUSION", [
    Entry("none", "the specular image-based term is not occluded", applies_to="nothing is occluded: factor 1"),
    Entry("lagarde", "Lagarde & de Rousiers 2014, Moving Frostbite to PBR, listing 26: "
                     "saturate((n.v + ao)^exp2(-16 alpha - 1) - 1 + ao)",
          roles={"specular_occlusion": role(specular_occlusion_lagarde)},
          applies_to=REALTIME_APPROXIMATION + "the split sum's specular, from the ambient occlusion"),
    Entry("gtso", "Jimenez et al. 2016, Practical Realtime Strategies for Accurate Indirect Occlusion, sec. 6: the "
                  "visibility cone (cos = sqrt(1 - ao)) intersected with the specular cone (cos = exp2(-3.321928 "
                  "alpha^2)), Oat & Sander 2007's cap intersection, over the unoccluded hemisphere's",
          roles={"specular_occlusion": role(specular_occlusion_gtso)},
          applies_to=REALTIME_APPROXIMATION + "the split sum's specular, from the ambient occlusion"),
])
#: Horizon occlusion of normal-mapped reflections: ``horizon_occlusion_<name>(RoNg)``, numpy in
#: :mod:`pbrcheck.occlusion`, GLSL in ``occlusion.glsl`` (dispatch ``horizon_occlusion_dispatch.glsl``).
HORIZON_OCCLUSIONS = Registry("HORIZON_OCCLUSION", [
    Entry("none", "reflections below the geometric normal's horizon are not faded", applies_to="factor 1"),
    Entry("marmoset", "Russell 2015 (Marmoset), Horizon Occlusion for Normal Mapped Reflections (also Jimenez et "
                      "al. 2016): saturate(1 + 1.3 r.n_g)^2", roles={"horizon_occlusion": role(horizon_occlusion_marmoset)},
          applies_to=REALTIME_APPROXIMATION + "the image-based specular of normal-mapped materials"),
])
#: Specular anti-aliasing / normal-map filtering, the roughness widened by the normals' variance:
#: ``specular_aa_<name>`` of the dispatch inputs it reads (:attr:`~pbrcheck.registry.Role.args`), numpy in
#: :mod:`pbrcheck.specular_aa`, GLSL in ``specular_aa.glsl`` (dispatch ``specular_aa_dispatch.glsl``,
#: which also defines ``SPECULAR_AA_READS_<INPUT>`` for the inputs the selected member reads, so
#: that the raster pass computes only those). ``screen_space`` needs the screen derivatives of the
#: normal, which only the raster pipeline has (:attr:`Entry.requires`).
SPECULAR_AAS = Registry("SPECULAR_AA", [
    Entry("none", "no filtering of the normals' variance into the roughness", applies_to="roughness unchanged"),
    Entry("toksvig", "Toksvig 2005, Mipmapping Normal Maps: alpha^2 + 2 (1 - |n|) / |n| from the mip-filtered "
                     "normal's length", roles={"specular_aa": role(specular_aa_toksvig, "roughness", "normal_length")},
          applies_to=REALTIME_APPROXIMATION + "normal-mapped materials' roughness, both pipelines"),
    Entry("screen_space", "Kaplanyan et al. 2016, Tokuyoshi & Kaplanyan 2019 as Filament ships it: alpha^2 + "
                          "min(2 x 0.15 (|dn/dx|^2 + |dn/dy|^2), 0.2) from the geometric normal's screen derivatives",
          roles={"specular_aa": role(specular_aa_screen_space, "roughness", "dn2")},
          requires={"pipeline": ("raster",)},
          applies_to=REALTIME_APPROXIMATION + "the raster pipeline only: it needs the screen derivatives of the "
                     "normal, which the ray-cast compute pass (one invocation per pixel, no neighbours) has not"),
    Entry("prefiltered", "LEAN mapping's slope variance (Olano & Baker 2010) of the normal map, baked per mip beside "
                         "the mip chain: alpha^2 + var(s_x) + var(s_y)",
          roles={"specular_aa": role(specular_aa_prefiltered, "roughness", "variance")},
          applies_to=REALTIME_APPROXIMATION + "normal-mapped materials' roughness, both pipelines"),
])

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


# ---- the glTF PBR extensions' lobes: the engines' real-time approximations (issue 36 item 3) ----
# Each family's members hold their numpy functions (realtime.lobes) and GLSL twins of the same name
# (realtime/shaders/lobes_*.glsl); each lobe file defines its switch's constants (by member index,
# tests/test_realtime_lobes.py checks them against these lists) and a dispatch on the switch. They are
# not in REGISTRIES (whose constants every program gets: a lobe-free program's source must not change):
# the material composition calls them through material_lobes.glsl, compiled only into the programs of
# scenes whose materials use a lobe (realtime.material_lobes), each switch an option of realtime.presets.
# A member may hold GLSL of its own as an object (extra["glsl"]: the fitted members' tables, whose text
# realtime/fitted_lobes.py generates): realtime.generated writes it into <lobe file>_members.glsl inside
# "#if SWITCH == SWITCH_MEMBER", so only the programs that select the member compile it.
_LOBE = "the real-time form of a lobe the reference evaluates exactly (pbrcheck.lobes): no Dr.Jit function; "
#: The base's attenuation under the coat: ``coat_attenuation(NoV, VoH, coat, f0)``.
COAT_ATTENUATIONS = Registry("COAT_ATTENUATION", [
    Entry("nov", "KHR_materials_clearcoat README (fresnel_coat at n.v); Filament sec. 4.9.4; three.js: "
                 "1 - coat Fc(n_c.v)", roles={"coat_attenuation": role(_lobes.coat_attenuation_nov)},
          applies_to=_LOBE + "image-based and punctual light alike"),
    Entry("voh", "glTF-Sample-Viewer's punctual coat BRDF (its Fresnel at v.h): 1 - coat Fc(v.h)",
          roles={"coat_attenuation": role(_lobes.coat_attenuation_voh)},
          applies_to=_LOBE + "punctual lights (image-based lighting has no half vector: the Sample Viewer uses n.v there)"),
])
#: The weight of the coat's prefiltered lookup (at the coat's roughness, along reflect(-v, n_coat)):
#: ``coat_ibl_weight(NoV, roughness, coat, f0, A, B)``, (A, B) the DFG LUT at the coat's roughness.
COAT_IBLS = Registry("COAT_IBL", [
    Entry("filament", "Filament sec. 4.9.4 (light_indirect.fs): coat Fc(n.v), no DFG",
          roles={"coat_ibl_weight": role(_lobes.coat_ibl_weight_filament)}, applies_to=_LOBE + "image-based"),
    Entry("sample_viewer", "glTF-Sample-Viewer ibl.glsl getIBLRadianceGGX (commit 2c3c5a5) at the coat's roughness: coat (k_S A + B), "
                           "k_S = F0 + (max(1 - r, F0) - F0)(1 - n.v)^5 (Fdez-Aguera 2019)",
          roles={"coat_ibl_weight": role(_lobes.coat_ibl_weight_sample_viewer)}, applies_to=_LOBE + "image-based"),
    Entry("threejs", "three.js clearcoatSpecularIndirect: coat (F0 A' + B'), (A', B') = EnvBRDFApprox (Karis 2014)",
          roles={"coat_ibl_weight": role(_lobes.coat_ibl_weight_threejs)}, applies_to=_LOBE + "image-based"),
    Entry("splitsum", "the split sum at the coat's roughness, coat (F0 A + B), Karis 2013 (glTF-Sample-Viewer's ibl.glsl "
                      "before its Fdez-Aguera form)",
          roles={"coat_ibl_weight": role(_lobes.coat_ibl_weight_splitsum)}, applies_to=_LOBE + "image-based"),
])
#: The sheen lobe's image-based weight ``sheen_dfg(NoV, roughness, E)`` (E: the sheen LUT's three channels);
#: ``extra["radiance"]``: what the engine multiplies it with.
SHEEN_DFGS = Registry("SHEEN_DFG", [
    Entry("lut_charlie", "the sheen LUT's R: int D_Charlie V_Charlie n.l (the spec's own albedo; Estevez & Kulla 2017)",
          roles={"sheen_dfg": role(_lobes.sheen_dfg_lut_charlie)}, extra={"radiance": "charlie_cube"},
          applies_to=_LOBE + "image-based"),
    Entry("lut_neubelt", "the sheen LUT's G, int D_Charlie V_Neubelt n.l (alpha = roughness^2): Filament's sheenDFG = "
                         "DFG.z, glTF-Sample-Viewer getIBLRadianceCharlie's u_CharlieLUT (glTF-IBL-Sampler "
                         "LUT_CharlieUniform)",
          roles={"sheen_dfg": role(_lobes.sheen_dfg_lut_neubelt)}, extra={"radiance": "charlie_cube"},
          applies_to=_LOBE + "image-based (times the Charlie-prefiltered cube; Filament reads its GGX-prefiltered "
                             "cube at the sheen roughness instead)"),
    Entry("lut_ibl_sampler_legacy", "an older glTF-IBL-Sampler's Charlie LUT (filter.frag, commit 203dccf): the sheen "
                                    "LUT's B, D_Charlie at alpha = roughness (not squared), V_Neubelt clamped to 1",
          roles={"sheen_dfg": role(_lobes.sheen_dfg_lut_ibl_sampler_legacy)}, extra={"radiance": "charlie_cube"},
          applies_to=_LOBE + "image-based (times the Charlie-prefiltered cube)"),
    Entry("threejs", "three.js IBLSheenBRDF: saturate(DG / pi), the Enterprise PBR DG fit",
          roles={"sheen_dfg": role(_lobes.sheen_dfg_threejs)}, extra={"radiance": "irradiance"},
          applies_to=_LOBE + "image-based (times the irradiance E(n), not a prefiltered radiance)"),
    Entry("playcanvas", "PlayCanvas reflectionSheen: saturate(DG), the same fit without 1 / pi",
          roles={"sheen_dfg": role(_lobes.sheen_dfg_playcanvas)}, extra={"radiance": "normal_roughest"},
          applies_to=_LOBE + "image-based (times the environment along n at the roughest level)"),
    Entry("fitted", "pbrcheck fit-lobes: the spec's albedo E (int D_Charlie V_Charlie n.l) as an 8 x 8 table fitted "
                    "by AD to the quadrature, read at (sqrt(n.v), roughness) (realtime/fitted_lobes.py)",
          roles={"sheen_dfg": role(_lobes.sheen_dfg_fitted)},
          extra={"radiance": "charlie_cube", "glsl": _fitted.SHEEN_ALBEDO_GLSL},
          applies_to=_LOBE + "image-based (times the Charlie-prefiltered cube); pbrcheck's fit, no engine's form"),
])
#: The layering of the base under the sheen: ``sheen_scaling(color, E)``.
SHEEN_SCALINGS = Registry("SHEEN_SCALING", [
    Entry("lut", "KHR_materials_sheen README: 1 - max(sheenColor) E(n.v), E the sheen LUT's R (albedo scaling LUT)",
          roles={"sheen_scaling": role(_lobes.sheen_scaling_lut)}, applies_to=_LOBE + "the base under the sheen"),
    Entry("filament", "Filament sheenScaling: 1 - max(sheenColor) DFG.z (the LUT's G)",
          roles={"sheen_scaling": role(_lobes.sheen_scaling_filament)}, applies_to=_LOBE + "the base under the sheen"),
    Entry("threejs", "three.js sheenEnergyComp: 1 - 0.157 max(sheenColor)",
          roles={"sheen_scaling": role(_lobes.sheen_scaling_threejs)}, applies_to=_LOBE + "the base under the sheen"),
])
#: The anisotropic image-based lookup's direction ``aniso_reflection(n, t, b, v, s, r)``.
ANISOTROPY_BENDS = Registry("ANISOTROPY_BEND", [
    Entry("sample_viewer", "glTF-Sample-Viewer ibl.glsl getIBLRadianceAnisotropy: normalize(mix((b x v) x b, n, "
                           "(1 - s(1 - r))^4)), McAuley 2015", roles={"aniso_reflection": role(_lobes.aniso_reflection_sample_viewer)},
          applies_to=_LOBE + "image-based"),
    Entry("threejs", "three.js getIBLAnisotropyRadiance: the Sample Viewer's bent normal with (b x v) x b normalized, "
                     "then the reflection leaned to it by r^2", roles={"aniso_reflection": role(_lobes.aniso_reflection_threejs)},
          applies_to=_LOBE + "image-based"),
    Entry("filament", "Filament sec. 5.3.6: normalize(mix(n, (d x v) x d, |s| saturate(5 r))), d = b (s >= 0) or t",
          roles={"aniso_reflection": role(_lobes.aniso_reflection_filament)}, applies_to=_LOBE + "image-based"),
    Entry("babylon", "Babylon.js getAnisotropicBentNormals (ANISOTROPIC_LEGACY): normalize(mix(n, (d x v) x d, |s|))",
          roles={"aniso_reflection": role(_lobes.aniso_reflection_babylon)}, applies_to=_LOBE + "image-based"),
    Entry("fitted", "pbrcheck fit-lobes: the Sample Viewer's bent normal normalize(mix((b x v) x b, n, w)) with w(s, r) "
                    "a 5 x 5 table fitted by AD to the spec's anisotropic GGX under test environments "
                    "(realtime/fitted_lobes.py)", roles={"aniso_reflection": role(_lobes.aniso_reflection_fitted)},
          extra={"glsl": _fitted.ANISO_BEND_WEIGHT_GLSL},
          applies_to=_LOBE + "image-based; pbrcheck's fit, no engine's form"),
])
#: The iridescent Fresnel ``iridescence_fresnel(outside_ior, film_ior, cos1, thickness, base_f0)``.
IRIDESCENCES = Registry("IRIDESCENCE", [
    Entry("belcour_rgb", "Belcour & Barla 2017, RGB through the Fourier-space XYZ fit, as glTF-Sample-Viewer evaluates it",
          roles={"iridescence_fresnel": role(_lobes.iridescence_fresnel)},
          applies_to=_LOBE + "the specular Fresnel: image-based at n.v, point lights at v.h (the truth integrates per "
                             "wavelength)"),
    Entry("none", "no thin film: the base's Fresnel (an engine without a thin-film term: Filament's shading model has none)",
          applies_to=_LOBE + "nothing: the iridescent materials render as their base"),
])
#: The lobe families, by switch: the registry, its shader file, the default member and each role's
#: GLSL dispatch signature.
LOBE_REGISTRIES = {
    "COAT_ATTENUATION": (COAT_ATTENUATIONS, "lobes_coat.glsl", "nov", {
        "coat_attenuation": "float coat_attenuation(float NoV, float VoH, float coat, float f0)"}),
    "COAT_IBL": (COAT_IBLS, "lobes_coat.glsl", "sample_viewer", {
        "coat_ibl_weight": "float coat_ibl_weight(float NoV, float roughness, float coat, float f0, float A, float B)"}),
    "SHEEN_DFG": (SHEEN_DFGS, "lobes_sheen.glsl", "lut_neubelt", {
        "sheen_dfg": "float sheen_dfg(float NoV, float roughness, vec3 E)"}),
    "SHEEN_SCALING": (SHEEN_SCALINGS, "lobes_sheen.glsl", "lut", {
        "sheen_scaling": "float sheen_scaling(vec3 color, vec3 E)"}),
    "ANISOTROPY_BEND": (ANISOTROPY_BENDS, "lobes_anisotropy.glsl", "sample_viewer", {
        "aniso_reflection": "vec3 aniso_reflection(vec3 n, vec3 t, vec3 b, vec3 v, float s, float r)"}),
    "IRIDESCENCE": (IRIDESCENCES, "lobes_iridescence.glsl", "belcour_rgb", {
        "iridescence_fresnel": "vec3 iridescence_fresnel(float outside_ior, float film_ior, float cos1, "
                               "float thickness, vec3 base_f0)"}),
}
#: The lobes' LUT bakes, with the conventions stated at both ends (the shader's header, the reader).
#: The bake and read-back are named, not held (realtime.lobe_luts imports realtime.gl, which imports this).
LOBE_LUTS = {"sheen_lut": {"shader": "sheen_lut.comp", "bake": "realtime.lobe_luts.sheen_lut",
                           "read": "realtime.lobe_luts.read_sheen_lut", "reader_glsl": "sheen_lut_lookup (lobes_sheen.glsl)",
                           "reader_numpy": _lobes.sheen_lut_lookup,
                           **_lobes.SHEEN_LUT_CONVENTIONS},
             "charlie_prefilter": {"shader": "charlie_prefilter.comp", "bake": "realtime.render.charlie_cube",
                                   "read": "realtime.render.sample_cube",
                                   "reader_glsl": "sheen_radiance (material_lobes.glsl)", "reader_numpy": None,
                                   **_lobes.CHARLIE_CUBE_CONVENTIONS}}
