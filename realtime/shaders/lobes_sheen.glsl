// lobes_sheen.glsl: the engines' real-time forms of KHR_materials_sheen's image-based term and albedo
// scaling, the Charlie NDF's sampler for the Charlie-prefiltered cube, and the lookup of the sheen LUT
// (sheen_lut.comp). Every function has a numpy twin of the same name in realtime/lobes.py.
// alpha = sheenRoughness^2 throughout (the spec's convention); E = the sheen LUT's texel at
// (n.v, sheen roughness): R = int D_Charlie V_Charlie n.l dl (the spec's albedo), G = int D_Charlie
// V_Neubelt n.l dl (Filament's DFG.z; the Sample Viewer's Charlie LUT as glTF-IBL-Sampler bakes it now),
// B = G with an older glTF-IBL-Sampler's alpha = roughness (not squared) and V clamped to 1.
// Switches (members of realtime.registry.SHEEN_DFGS / SHEEN_SCALINGS, by index):
#define SHEEN_DFG_LUT_CHARLIE 0
#define SHEEN_DFG_LUT_NEUBELT 1
#define SHEEN_DFG_LUT_IBL_SAMPLER_LEGACY 2
#define SHEEN_DFG_THREEJS 3
#define SHEEN_DFG_PLAYCANVAS 4
#define SHEEN_DFG_FITTED 5
#define SHEEN_SCALING_LUT 0
#define SHEEN_SCALING_FILAMENT 1
#define SHEEN_SCALING_THREEJS 2
#ifndef SHEEN_DFG
#define SHEEN_DFG SHEEN_DFG_LUT_NEUBELT
#endif
#ifndef SHEEN_SCALING
#define SHEEN_SCALING SHEEN_SCALING_LUT
#endif
#include "ibl.glsl"

// The sheen LUT (sheen_lut.comp; realtime.lobes.SHEEN_LUT_CONVENTIONS): N x N RGBA, column i n.v = (i + 0.5)/N,
// row j sheen roughness = (j + 0.5)/N, row 0 smoothest; R = E_charlie, G = E_neubelt, B = E_ibl_sampler.
uniform sampler2D sheen_lut;

// The smallest sheen alpha evaluated (realtime.lobes.SHEEN_MIN_ALPHA): exponent 1/alpha <= 1e3.
const float SHEEN_MIN_ALPHA = 1e-3;
// three.js's constant sheen albedo (realtime.lobes.THREEJS_SHEEN_ALBEDO).
const float THREEJS_SHEEN_ALBEDO = 0.157;

// Source: [Estevez17] eq. 2; KHR_materials_sheen README. Equation: D = (2 + 1/alpha) sin^(1/alpha) / (2 pi).
// sin^2 is written (1 - n.h)(1 + n.h), exact as n.h -> 1.
float D_Charlie(float NoH, float alpha) {
    float a = max(alpha, SHEEN_MIN_ALPHA);
    float sin2 = max((1.0 - NoH) * (1.0 + NoH), 0.0);
    return (2.0 + 1.0 / a) * pow(sin2, 0.5 / a) / (2.0 * PI);
}

// Source: [Estevez17] Table 1 and eq. 3: L(x) = a / (1 + b x^c) + d x + e, coefficients blended by
// t = (1 - alpha)^2 between the smooth and rough fits.
float charlie_L(float x, float alpha) {
    float t = (1.0 - max(alpha, SHEEN_MIN_ALPHA));
    t *= t;
    float a = mix(21.5473, 25.3245, t);
    float b = mix(3.82987, 3.32435, t);
    float c = mix(0.19823, 0.16801, t);
    float d = mix(-1.97760, -1.27393, t);
    float e = mix(-4.32054, -4.85967, t);
    return a / (1.0 + b * pow(x, c)) + d * x + e;
}

// Source: [Estevez17] eq. 4. Equation: Lambda = exp(L(c)) for c < 0.5, exp(2 L(0.5) - L(1 - c)) above.
float charlie_lambda(float c, float alpha) {
    return exp(c < 0.5 ? charlie_L(c, alpha) : 2.0 * charlie_L(0.5, alpha) - charlie_L(1.0 - c, alpha));
}

// Source: KHR_materials_sheen README (V_Sheen), [Estevez17]. Equation: 1 / ((1 + Lambda(v) + Lambda(l)) 4 n.v n.l).
float V_Charlie(float NoV, float NoL, float alpha) {
    float den = (1.0 + charlie_lambda(NoV, alpha) + charlie_lambda(NoL, alpha)) * 4.0 * NoV * NoL;
    return 1.0 / max(den, COS_EPS);
}

// Source: [Neubelt13]; Filament sec. 4.12.2 (V_Neubelt), PlayCanvas lightSheen (sheenV).
// Equation: 1 / (4 (n.l + n.v - n.l n.v)).
float V_Neubelt(float NoV, float NoL) {
    return 1.0 / max(4.0 * (NoL + NoV - NoL * NoV), COS_EPS);
}

// Source: glTF-Sample-Viewer's IBL sampler (Charlie distribution); derivation: D (n.h) integrates to 1
// and sin theta's CDF is s^(2 + 1/alpha). Equation: sin theta = u.y^(alpha / (2 alpha + 1)), phi = 2 pi u.x.
// Returns h in tangent space (z = n).
vec3 sample_Charlie(vec2 u, float alpha) {
    float a = max(alpha, SHEEN_MIN_ALPHA);
    float s = pow(u.y, a / (2.0 * a + 1.0));
    float c = sqrt(max(1.0 - s * s, 0.0));
    float phi = 2.0 * PI * u.x;
    return vec3(s * cos(phi), s * sin(phi), c);
}

// Source: as sample_Charlie; prefilter convention n = v = r ([Karis13]) makes v.h = n.h.
// Equation: pdf_l = D (n.h) / (4 v.h) = D / 4 (ibl.glsl filtered_is_lod picks the source mip from it).
float charlie_prefilter_pdf(float NoH, float alpha) {
    return D_Charlie(NoH, alpha) / 4.0;
}

// Source: Enterprise PBR Shading Model (Dassault Systemes), the sheen DG fit three.js (IBLSheenBRDF) and
// PlayCanvas (reflectionSheen) ship. Equation: exp(a n.v + b) + (r < 0.25 ? 0 : 0.1 (r - 0.25)),
// a = r < 0.25 ? -339.2 r^2 + 161.4 r - 25.9 : -8.48 r^2 + 14.3 r - 9.95,
// b = r < 0.25 ? 44.0 r^2 - 23.7 r + 3.26 : 1.97 r^2 - 3.27 r + 0.72.
float sheen_dg_fit(float NoV, float r) {
    float r2 = r * r;
    float a = r < 0.25 ? -339.2 * r2 + 161.4 * r - 25.9 : -8.48 * r2 + 14.3 * r - 9.95;
    float b = r < 0.25 ? 44.0 * r2 - 23.7 * r + 3.26 : 1.97 * r2 - 3.27 * r + 0.72;
    return exp(a * NoV + b) + (r < 0.25 ? 0.0 : 0.1 * (r - 0.25));
}

// Source: three.js lights_physical_pars_fragment IBLSheenBRDF (times the irradiance).
// Equation: saturate(DG / pi).
float sheen_dfg_threejs(float NoV, float roughness, vec3 E) {
    return saturate(sheen_dg_fit(NoV, roughness) / PI);
}

// Source: PlayCanvas reflectionSheen.js (times the environment at the normal, roughest level).
// Equation: saturate(DG).
float sheen_dfg_playcanvas(float NoV, float roughness, vec3 E) {
    return saturate(sheen_dg_fit(NoV, roughness));
}

// Source: KHR_materials_sheen README (albedo E by the spec's V). Equation: E.r.
float sheen_dfg_lut_charlie(float NoV, float roughness, vec3 E) {
    return E.x;
}

// Source: Filament light_indirect.fs (sheenDFG = DFG.z), glTF-Sample-Viewer ibl.glsl getIBLRadianceCharlie
// (u_CharlieLUT.b, glTF-IBL-Sampler filter.frag LUT_CharlieUniform): D_Charlie at alpha = roughness^2,
// V_Neubelt. Equation: E.g.
float sheen_dfg_lut_neubelt(float NoV, float roughness, vec3 E) {
    return E.y;
}

// Source: glTF-IBL-Sampler lib/source/shaders/filter.frag (commit 203dccf, older): its LUT called D_Charlie
// with the perceptual roughness as alpha (not squared) and V_Ashikhmin clamped to 1 (the integral it
// meant; its estimator, a uniform-sampling weight on Charlie-sampled half vectors, is not reproduced).
// Equation: E.b.
float sheen_dfg_lut_ibl_sampler_legacy(float NoV, float roughness, vec3 E) {
    return E.z;
}

// The registry members' own GLSL (realtime/fitted_lobes.py's table and reader for SHEEN_DFG_FITTED), each
// inside #if on its switch: generated by realtime.generated from the entries' extra["glsl"].
#include "lobes_sheen_members.glsl"

#if SHEEN_DFG == SHEEN_DFG_FITTED
// Source: pbrcheck fit-lobes (docs/research.md): the spec's albedo E fitted by AD as an 8 x 8 table.
// Equation: sheen_albedo_fitted(n.v, r) (bilinear at (sqrt(n.v), r)), in place of E.r.
float sheen_dfg_fitted(float NoV, float roughness, vec3 E) {
    return sheen_albedo_fitted(NoV, roughness);
}
#endif

// The sheen LUT's three channels at (n.v, sheen roughness): ibl.glsl lut_lookup's bilinear reading.
vec3 sheen_lut_lookup(float NoV, float roughness) {
    return lut_lookup(sheen_lut, NoV, roughness).rgb;
}

float max3(vec3 c) { return max(max(c.x, c.y), c.z); }

// Source: KHR_materials_sheen README (albedo scaling), glTF-Sample-Viewer. Equation: 1 - max(c) E.r.
float sheen_scaling_lut(vec3 color, vec3 E) {
    return 1.0 - max3(color) * E.x;
}

// Source: Filament shading_model_standard / light_indirect.fs (sheenScaling). Equation: 1 - max(c) E.g.
float sheen_scaling_filament(vec3 color, vec3 E) {
    return 1.0 - max3(color) * E.y;
}

// Source: three.js lights_fragment_end (sheenEnergyComp). Equation: 1 - 0.157 max(c).
float sheen_scaling_threejs(vec3 color, vec3 E) {
    return 1.0 - THREEJS_SHEEN_ALBEDO * max3(color);
}

// Dispatch on SHEEN_DFG / SHEEN_SCALING.
float sheen_dfg(float NoV, float roughness, vec3 E) {
#if SHEEN_DFG == SHEEN_DFG_LUT_CHARLIE
    return sheen_dfg_lut_charlie(NoV, roughness, E);
#elif SHEEN_DFG == SHEEN_DFG_LUT_NEUBELT
    return sheen_dfg_lut_neubelt(NoV, roughness, E);
#elif SHEEN_DFG == SHEEN_DFG_THREEJS
    return sheen_dfg_threejs(NoV, roughness, E);
#elif SHEEN_DFG == SHEEN_DFG_PLAYCANVAS
    return sheen_dfg_playcanvas(NoV, roughness, E);
#elif SHEEN_DFG == SHEEN_DFG_FITTED
    return sheen_dfg_fitted(NoV, roughness, E);
#else
    return sheen_dfg_lut_ibl_sampler_legacy(NoV, roughness, E);
#endif
}

float sheen_scaling(vec3 color, vec3 E) {
#if SHEEN_SCALING == SHEEN_SCALING_FILAMENT
    return sheen_scaling_filament(color, E);
#elif SHEEN_SCALING == SHEEN_SCALING_THREEJS
    return sheen_scaling_threejs(color, E);
#else
    return sheen_scaling_lut(color, E);
#endif
}
