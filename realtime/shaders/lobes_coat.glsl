// lobes_coat.glsl: the engines' real-time forms of KHR_materials_clearcoat's image-based and layering
// terms. Every function has a numpy twin of the same name in realtime/lobes.py
// (tests/test_realtime_lobes.py). The coat's radiance is the prefiltered cube read at the coat's
// own roughness along reflect(-v, n_coat) (ibl.glsl lod_from_roughness): every engine does that;
// they differ in the weight of that lookup (COAT_IBL) and in the base's attenuation (COAT_ATTENUATION).
// Switches (members of realtime.registry.COAT_IBLS / COAT_ATTENUATIONS, by index):
#define COAT_IBL_FILAMENT 0
#define COAT_IBL_SAMPLE_VIEWER 1
#define COAT_IBL_THREEJS 2
#define COAT_IBL_SPLITSUM 3
#define COAT_ATTENUATION_NOV 0
#define COAT_ATTENUATION_VOH 1
#ifndef COAT_IBL
#define COAT_IBL COAT_IBL_SAMPLE_VIEWER
#endif
#ifndef COAT_ATTENUATION
#define COAT_ATTENUATION COAT_ATTENUATION_NOV
#endif
#include "ibl.glsl"

// Source: KHR_materials_clearcoat README (clearcoat_ior 1.5 -> F0 0.04). Equation: ((ior - 1)/(ior + 1))^2.
float coat_f0(float ior) {
    float r = (ior - 1.0) / (ior + 1.0);
    return r * r;
}

// Source: [Schlick94]. Equation: F0 + (1 - F0)(1 - c)^5.
float coat_fresnel(float c, float f0) {
    return f0 + (1.0 - f0) * pow5(1.0 - c);
}

// Source: KHR_materials_clearcoat README (fresnel_coat at n.v), Filament sec. 4.9.4 (light_indirect.fs
// evaluateClearCoatIBL), three.js (lights_fragment_end: Fcc at dotNVcc). Equation: 1 - coat Fc(n_c.v).
float coat_attenuation_nov(float NoV, float VoH, float coat, float f0) {
    return 1.0 - coat * coat_fresnel(NoV, f0);
}

// Source: glTF-Sample-Viewer (brdf.glsl / functions: the punctual coat BRDF's Fresnel is at v.h).
// Equation: 1 - coat Fc(v.h): the base attenuated by the Fresnel the coat lobe itself uses.
float coat_attenuation_voh(float NoV, float VoH, float coat, float f0) {
    return 1.0 - coat * coat_fresnel(VoH, f0);
}

// Source: Filament sec. 4.9.4, light_indirect.fs: the coat's prefiltered radiance times Fc coat, no DFG
// term. Equation: coat Fc(n.v).
float coat_ibl_weight_filament(float NoV, float roughness, float coat, float f0, float A, float B) {
    return coat * coat_fresnel(NoV, f0);
}

// Source: glTF-Sample-Viewer ibl.glsl getIBLRadianceGGX (e.g. commit 2c3c5a5) at the coat's roughness, with [FdezAguera19]'s
// roughness-dependent Schlick. Equation: coat (k_S A + B), k_S = F0 + (max(1 - r, F0) - F0)(1 - n.v)^5,
// (A, B) = the DFG LUT at (n.v, coat roughness).
float coat_ibl_weight_sample_viewer(float NoV, float roughness, float coat, float f0, float A, float B) {
    float k_s = f0 + (max(1.0 - roughness, f0) - f0) * pow5(1.0 - NoV);
    return coat * (k_s * A + B);
}

// Source: the split sum [Karis13] at the coat's roughness: glTF-Sample-Viewer ibl.glsl getIBLRadianceGGX before
// its Fdez-Aguera form (specularColor * brdf.x + brdf.y). Equation: coat (F0 A + B), (A, B) the DFG LUT.
float coat_ibl_weight_splitsum(float NoV, float roughness, float coat, float f0, float A, float B) {
    return coat * (f0 * A + B);
}

// Source: three.js lights_physical_pars_fragment (clearcoatSpecularIndirect: EnvironmentBRDF = DFGApprox,
// [Karis14]). Equation: coat (F0 A' + B'), (A', B') = EnvBRDFApprox(n.v, coat roughness).
float coat_ibl_weight_threejs(float NoV, float roughness, float coat, float f0, float A, float B) {
    vec2 ab = EnvBRDFApprox(NoV, roughness);
    return coat * (f0 * ab.x + ab.y);
}

// Dispatch on COAT_ATTENUATION / COAT_IBL.
float coat_attenuation(float NoV, float VoH, float coat, float f0) {
#if COAT_ATTENUATION == COAT_ATTENUATION_VOH
    return coat_attenuation_voh(NoV, VoH, coat, f0);
#else
    return coat_attenuation_nov(NoV, VoH, coat, f0);
#endif
}

float coat_ibl_weight(float NoV, float roughness, float coat, float f0, float A, float B) {
#if COAT_IBL == COAT_IBL_FILAMENT
    return coat_ibl_weight_filament(NoV, roughness, coat, f0, A, B);
#elif COAT_IBL == COAT_IBL_THREEJS
    return coat_ibl_weight_threejs(NoV, roughness, coat, f0, A, B);
#elif COAT_IBL == COAT_IBL_SPLITSUM
    return coat_ibl_weight_splitsum(NoV, roughness, coat, f0, A, B);
#else
    return coat_ibl_weight_sample_viewer(NoV, roughness, coat, f0, A, B);
#endif
}
