"""Where the engines depart from the glTF lobe extensions' text: the findings of issue 36, as data.

Each :class:`Departure` is one form an engine ships for a lobe, read in the engine's own source (the
packages pbrcheck's clients pin, ``clients/<engine>/node_modules``; Filament's shaders are compiled
into its wasm, so its rows cite Filament's documentation and source tree, marked ``documented``),
set against the extension's README. docs/renderers.md's "lobes" table has one row per departure
(``tests/test_lobe_report.py`` checks it), and ``diagnose`` one hypothesis per departure that
names a real-time form (:mod:`compare.research.diagnose`, kind ``lobe``): the reference corrected
by what the form changes, rendered by pbrcheck's real-time twin of it
(:data:`realtime.registry.LOBE_REGISTRIES`):

- with ``against`` (the registry's member that is the spec's own form): the reference plus
  ``RT(member) - RT(against)`` (both on the ``default`` preset, everything else equal);
- without (the spec defines no image-based form to difference against: the coat's and the
  anisotropic lobe's prefiltered lookups): the real-time twin's image itself, ``RT(member)``.

A hypothesis is offered only for a scene whose objects carry its lobe (:func:`compare.lobes.scene_lobes`)
and, for a form that only punctual lights see, a punctual light; it is skipped, saying why, while
the real-time renderer does not take its family as an option (issue 36 item 3 wires them).

API: :class:`Departure`, :data:`DEPARTURES`, :data:`ENGINE_OF_RENDERER`, :func:`departure`.

References (read 2026-11-27): KhronosGroup/glTF ``extensions/2.0/Khronos/KHR_materials_clearcoat``
(``fresnel_coat``: "The layer is weighted with weight*fresnel(ior)" at ``abs(dot(V, normal))``,
``clearcoat_brdf = specular_brdf`` with no Fresnel of its own; "Discussion": ``NdotV`` instead of
``VdotH`` to conserve energy), ``KHR_materials_sheen`` (Charlie NDF and its visibility,
``sheen_albedo_scaling = min(1 - max3(sheenColor) E(VdotN), 1 - max3(sheenColor) E(LdotN))``);
@khronosgroup/gltf-viewer 1.1.0 ``dist/gltf-viewer.module.js`` (pbrShader, iblShader, iblFiltering);
three.js r187 ``src/renderers/shaders/ShaderChunk/lights_physical_pars_fragment.glsl.js``,
``envmap_physical_pars_fragment.glsl.js``, ``ShaderLib/meshphysical.glsl.js``; Babylon.js 9.28.0
``@babylonjs/core/Shaders/ShadersInclude/pbrBlockClearcoat.js``, ``pbrBlockSheen.js``,
``pbrDirectLightingFunctions.js``, ``pbrHelperFunctions.js``; PlayCanvas 2.23.3
``build/playcanvas.mjs`` (chunks ``combineColor``, ``reflectionSheen``, ``getFresnelCC``, the lit
shader's clear-coat reflection); R. Guy, M. Agopian, "Physically Based Rendering in Filament",
sec. 4.9 (clear coat), 4.12.2 (cloth), 5.3.6 (anisotropic IBL), and Filament ``shaders/src``
(``shading_model_standard.fs`` clearCoatLobe, ``light_indirect.fs``).
"""

from __future__ import annotations

from dataclasses import dataclass

from pbrcheck.lobe_params import ANISOTROPY, CLEARCOAT, IRIDESCENCE, SHEEN


@dataclass(frozen=True)
class Departure:
    """One engine form that departs from a lobe's specification.

    ``engines``: ``{engine: "source file: function (what it does)"}``; ``form`` what they compute,
    ``spec`` what the README says, ``departure`` the difference in a phrase; ``switch`` / ``member``
    the real-time registry's family and member that reproduce the form (None: no hypothesis);
    ``against`` the member that is the spec's own form (None: the hypothesis is the twin's image);
    ``punctual``: only punctual lights see the form (the built-in lobe scenes are lit by their
    environment alone)."""

    name: str
    extension: str
    engines: dict
    form: str
    spec: str
    departure: str
    switch: str | None = None
    member: str | None = None
    against: str | None = None
    punctual: bool = False


_SV = "@khronosgroup/gltf-viewer 1.1.0 dist/gltf-viewer.module.js"
_THREE = "three r187 src/renderers/shaders/"
_BJS = "@babylonjs/core 9.28.0 Shaders/ShadersInclude/"
_PC = "playcanvas 2.23.3 build/playcanvas.mjs"
_FIL = "Filament 1.53.4 (documented; compiled into the wasm): "

#: Every departure found, by lobe (docs/renderers.md's "lobes" table, same order).
DEPARTURES: tuple[Departure, ...] = (
    Departure(
        "coat_fresnel_voh", CLEARCOAT,
        {"three.js": _THREE + "ShaderChunk/lights_physical_pars_fragment.glsl.js: BRDF_GGX_Clearcoat (F_Schlick at dotVH "
                     "inside the coat lobe; the lobe weighted by clearcoat alone, meshphysical.glsl.js)",
         "Babylon.js": _BJS + "pbrDirectLightingFunctions.js: computeClearCoatLighting (fresnelSchlickGGX(VdotH) x "
                       "D_GGX x visibility_Kelemen)",
         "PlayCanvas": _PC + ": the lit shader's clear-coat light loop (getFresnelCC(dot(viewDir, halfDir)))",
         "Filament": _FIL + "shading_model_standard.fs clearCoatLobe (F_Schlick(0.04, 1, LoH) x D x V_Kelemen; "
                     "the base attenuated by 1 - Fcc at LoH too)"},
        "punctual coat lobe with Schlick's Fresnel at v.h (Filament: the base's attenuation too)",
        "clearcoat_brdf = specular_brdf (no Fresnel of its own), weighted by clearcoat Fc(|n_c.v|); the base by "
        "1 - clearcoat Fc(|n_c.v|)",
        "the coat's Fresnel per microfacet (v.h) instead of at n.v, which the README chose so that the simple "
        "layering conserves energy",
        "COAT_ATTENUATION", "voh", "nov", punctual=True),
    Departure(
        "coat_ibl_no_albedo", CLEARCOAT,
        {"Sample Viewer": _SV + ": pbrShader main (clearcoat_brdf = getIBLRadianceGGX(n_c, v, coat roughness); "
                          "mix(color, clearcoat_brdf, clearcoat Fc(n_c.v)))",
         "PlayCanvas": _PC + ": addReflectionCC, then ccReflection *= getFresnelCC(dot(v, n_c))",
         "Filament": _FIL + "light_indirect.fs evaluateClearCoatIBL (prefilteredRadiance x Fc(n.v), no DFG)"},
        "coat image-based lobe = clearcoat Fc(n_c.v) x the prefiltered radiance at the coat's roughness, with no "
        "directional-albedo (DFG) factor",
        "the coat lobe is the Fresnel-free GGX specular_brdf: its integral over the environment carries the lobe's "
        "directional albedo, below 1 and falling with roughness",
        "the rough coat keeps the energy single-scattering GGX loses (brighter than the truth as the coat roughens)",
        "COAT_IBL", "filament"),
    Departure(
        "coat_ibl_split_sum_fresnel", CLEARCOAT,
        {"three.js": _THREE + "ShaderChunk/lights_physical_pars_fragment.glsl.js: RE_IndirectSpecular_Physical "
                     "(clearcoatRadiance x EnvironmentBRDF(n_c, v, F0, F90, coat roughness)), weighted by clearcoat "
                     "alone (ShaderLib/meshphysical.glsl.js)"},
        "coat image-based lobe = clearcoat (F0 A + F90 B) at the coat's roughness (the Karis fit's split sum: "
        "Schlick per microfacet)",
        "weight clearcoat Fc(|n_c.v|) on a Fresnel-free lobe",
        "the coat's Fresnel inside the split sum (per microfacet) instead of the layer weight at n.v; the base's "
        "attenuation 1 - clearcoat Fc(n.v) no longer matches what the coat reflects",
        "COAT_IBL", "threejs"),
    Departure(
        "sheen_scaling_constant", SHEEN,
        {"PlayCanvas": _PC + ": combineColor (sheenScaling = 1 - 0.157 max(sheenColor))"},
        "the base under the sheen scaled by a constant 1 - 0.157 max(sheenColor)",
        "sheen_albedo_scaling = 1 - max3(sheenColor) E(n.v) (image-based), E the sheen lobe's directional albedo",
        "a constant in place of the view- and roughness-dependent albedo E(n.v, sheenRoughness)",
        "SHEEN_SCALING", "threejs", "lut"),
    Departure(
        "sheen_scaling_neubelt", SHEEN,
        {"Filament": _FIL + "sheenScaling = 1 - max3(sheenColor) DFG.z (its DFG LUT's cloth channel: Charlie D, "
                     "Neubelt visibility)",
         "Babylon.js": _BJS + "pbrBlockSheen.js: sheenAlbedoScaling = 1 - max(sheenColor) environmentSheenBrdf.b "
                       "(its BRDF LUT's sheen channel)"},
        "albedo scaling with the albedo of Charlie D and Neubelt's (Ashikhmin's) visibility",
        "E of the sheen BRDF itself: Charlie D with the Charlie (Estevez-Kulla) visibility",
        "another visibility term in the albedo that scales the base",
        "SHEEN_SCALING", "filament", "lut"),
    Departure(
        "sheen_ibl_neubelt_lut", SHEEN,
        {"Filament": _FIL + "light_indirect.fs: sheenColor x sheenDFG (DFG.z) x the GGX-prefiltered cube at the "
                     "sheen roughness",
         "Babylon.js": _BJS + "pbrBlockSheen.js: getSheenReflectanceFromBRDFLookup (sheenColor x its BRDF LUT's .b)"},
        "image-based sheen weight from a LUT of Charlie D with Neubelt's visibility",
        "the sheen BRDF: Charlie D with the Charlie visibility term",
        "another visibility term in the sheen lobe's image-based weight",
        "SHEEN_DFG", "lut_neubelt", "lut_charlie"),
    Departure(
        "sheen_ibl_legacy_lut", SHEEN,
        {"Sample Viewer": _SV + ": iblFiltering LUT() for u_CharlieLUT, read as .b by iblShader getIBLRadianceCharlie "
                          "(D_Charlie(sheenRoughness, NdotH): alpha = roughness, not roughness^2; V_Ashikhmin)"},
        "image-based sheen weight from a LUT of Charlie D at alpha = sheenRoughness with Neubelt's visibility",
        "Charlie D at alpha = sheenRoughness^2 with the Charlie visibility (its punctual D_Charlie squares it: brdf.glsl)",
        "the LUT's sheen roughness is not squared: the image-based sheen is that of a smoother lobe than the "
        "punctual one and the spec's",
        "SHEEN_DFG", "lut_ibl_sampler_legacy", "lut_charlie"),
    Departure(
        "sheen_ibl_fit_irradiance", SHEEN,
        {"three.js": _THREE + "ShaderChunk/lights_physical_pars_fragment.glsl.js: RE_IndirectSpecular_Physical "
                     "(irradiance x sheenColor x IBLSheenBRDF / pi; IBLSheenBRDF: exp(a n.v + b) fit)"},
        "image-based sheen = irradiance E(n) / pi x sheenColor x an exponential fit of the lobe's albedo",
        "the sheen lobe integrated against the environment (a radiance lobe around the reflection, not the "
        "cosine-weighted irradiance)",
        "the irradiance in place of a sheen-prefiltered radiance, and a fit of the albedo",
        "SHEEN_DFG", "threejs", "lut_charlie"),
    Departure(
        "sheen_ibl_fit_normal", SHEEN,
        {"PlayCanvas": _PC + ": reflectionSheen addReflectionSheen (calcReflection(worldNormal, 0) x saturate(DG), "
                       "DG an exponential fit in the sheen gloss, no 1/pi)"},
        "image-based sheen = the environment along n at its roughest level x a fit of the albedo",
        "the sheen lobe integrated against the environment",
        "the roughest radiance along the normal and a fit with no 1/pi",
        "SHEEN_DFG", "playcanvas", "lut_charlie"),
    Departure(
        "aniso_bent_normal", ANISOTROPY,
        {"Sample Viewer": _SV + ": iblShader getIBLRadianceAnisotropy (normalize(mix((b x v) x b, n, "
                          "(1 - s(1 - r))^4)); the lookup at the isotropic roughness: its tangentRoughness is unused)",
         "three.js": _THREE + "ShaderChunk/envmap_physical_pars_fragment.glsl.js: getIBLAnisotropyRadiance (the same "
                     "bent normal)",
         "Babylon.js": _BJS + "pbrHelperFunctions.js: getAnisotropicBentNormals (the same bent normal; glTF materials "
                       "are not in Babylon's legacy mode)",
         "PlayCanvas": _PC + ": the lit shader's anisotropic reflection (mix(anisotropicNormal, n, bendFactor^4))"},
        "one prefiltered lookup along the reflection of a bent normal (McAuley 2015), at the isotropic roughness",
        "the anisotropic GGX of KHR_materials_anisotropy (alpha_t = mix(alpha, 1, strength^2), alpha_b = alpha); "
        "the README defines no image-based form",
        "a single isotropic lookup stands for the stretched lobe",
        "ANISOTROPY_BEND", "sample_viewer"),
    Departure(
        "aniso_bent_normal_filament", ANISOTROPY,
        {"Filament": _FIL + "light_indirect.fs (normalize(mix(n, (d x v) x d, |s| saturate(5 r))), sec. 5.3.6)"},
        "the bent normal blended by |strength| saturate(5 roughness)",
        "the anisotropic GGX of KHR_materials_anisotropy; no image-based form",
        "another bend weight than the Sample Viewer's (Filament's documented form)",
        "ANISOTROPY_BEND", "filament"),
    Departure(
        "iridescence_rgb_nov", IRIDESCENCE,
        {"Sample Viewer": _SV + ": iridescenceShader evalIridescence at NdotV, for punctual lights too",
         "three.js": _THREE + "ShaderChunk/lights_fragment_begin.glsl.js: evalIridescence at dotNVi",
         "Babylon.js": _BJS + "pbrBlockIridescence.js: evalIridescence at the view angle"},
        "Belcour and Barla's thin-film Fresnel through the Fourier-space XYZ fit, in RGB, at n.v",
        "the thin-film Fresnel (the truth: evaluated per wavelength and integrated to RGB)",
        "RGB through the fit instead of the spectral integral; at n.v for every light",
        "IRIDESCENCE", "belcour_rgb"),
)


#: The engine of each built-in client renderer (``ext:NAME``: clients/renderers.toml), as
#: :attr:`Departure.engines` names it.
ENGINE_OF_RENDERER = {"ext:threejs": "three.js", "ext:sample-viewer": "Sample Viewer",
                      "ext:sample-viewer-full": "Sample Viewer", "ext:babylon": "Babylon.js",
                      "ext:filament": "Filament", "ext:playcanvas": "PlayCanvas"}


def departure(name: str) -> Departure:
    """The departure ``name`` (KeyError naming the known ones otherwise)."""
    for d in DEPARTURES:
        if d.name == name:
            return d
    raise KeyError(f"no lobe departure {name!r} (known: {', '.join(d.name for d in DEPARTURES)})")


__all__ = ["DEPARTURES", "Departure", "ENGINE_OF_RENDERER", "departure"]
