// lobes_iridescence.glsl: KHR_materials_iridescence's thin-film Fresnel in RGB as the Sample Viewer
// evaluates it ([Belcour17]: the Airy reflectance's first orders with the phase integrated against
// the CIE matching functions in Fourier space, a Gaussian fit, then to linear Rec. 709). The spec's
// truth integrates per wavelength (pbrcheck.lobes); this is the real-time form. Numpy twins of the same
// names in realtime/lobes.py. Thickness in nm; IORs real; base_f0 the base's RGB normal reflectance.
// Switch (realtime.registry.IRIDESCENCES): belcour_rgb, or none (no film: material_lobes.glsl skips it).
#define IRIDESCENCE_BELCOUR_RGB 0
#define IRIDESCENCE_NONE 1
#ifndef IRIDESCENCE
#define IRIDESCENCE IRIDESCENCE_BELCOUR_RGB
#endif
#include "common.glsl"

// realtime.lobes.IRIDESCENCE_MAX_F0 / IRIDESCENCE_FADE_NM.
const float IRIDESCENCE_MAX_F0 = 0.9999;
const float IRIDESCENCE_FADE_NM = 0.03;

// Source: [Belcour17] eq. 11 and its supplemental's Gaussian fit of the XYZ matching functions'
// Fourier transforms (glTF-Sample-Viewer iridescence.glsl evalSensitivity); XYZ -> Rec. 709 of
// IEC 61966-2-1. Equation: XYZ_k = val_k sqrt(2 pi var_k) cos(pos_k phase + shift) exp(-phase^2 var_k)
// (+ X's second lobe), phase = 2 pi OPD 1e-9, over 1.0685e-7.
vec3 iridescence_sensitivity(float opd, vec3 shift) {
    float phase = 2.0 * PI * opd * 1.0e-9;
    const vec3 val = vec3(5.4856e-13, 4.4201e-13, 5.2481e-13);
    const vec3 pos = vec3(1.6810e+06, 1.7953e+06, 2.2084e+06);
    const vec3 var = vec3(4.3278e+09, 9.3046e+09, 6.6121e+09);
    vec3 xyz = val * sqrt(2.0 * PI * var) * cos(pos * phase + shift) * exp(-phase * phase * var);
    xyz.x += 9.7470e-14 * sqrt(2.0 * PI * 4.5282e+09) * cos(2.2399e+06 * phase + shift.x)
             * exp(-4.5282e+09 * phase * phase);
    xyz /= 1.0685e-7;
    const mat3 XYZ_TO_REC709 = mat3(3.2404542, -0.9692660, 0.0556434,
                                    -1.5371385, 1.8760108, -0.2040259,
                                    -0.4985314, 0.0415560, 1.0572252);
    return XYZ_TO_REC709 * xyz;
}

float iri_schlick(float f0, float c) { return f0 + (1.0 - f0) * pow5(1.0 - c); }
vec3 iri_schlick(vec3 f0, float c) { return f0 + (1.0 - f0) * pow5(1.0 - c); }

// Source: [Belcour17] sec. 4 (Airy summation, phase shifts of the two interfaces, m = 1, 2), as the
// Sample Viewer's evalIridescence: Schlick at both interfaces, the film IOR faded in over 0.03 nm, the
// base IOR from its F0, total internal reflection -> 1, negative RGB clamped to 0. Departure: the
// Sample Viewer also clamps R12 R23 below at 1e-5; here only above (1 - R12 R23 > 0), so that a
// zero-thickness film reduces exactly to Schlick's Fresnel of the base.
// Equation: I = R12 + Rs + sum_m (Rs - T121) r123^m 2 S(m OPD, m phi), Rs = T121^2 R23 / (1 - R12 R23),
// OPD = 2 eta2 d cos theta2, phi = (pi - phi12) + phi23.
vec3 iridescence_fresnel(float outside_ior, float film_ior, float cos1, float thickness, vec3 base_f0) {
    float eta2 = mix(outside_ior, film_ior, smoothstep(0.0, IRIDESCENCE_FADE_NM, thickness));
    // Snell: cos^2 theta2 = 1 - k (1 - cos^2 theta1), k = (eta1 / eta2)^2, written (1 - k) + k cos^2 theta1:
    // exact for k = 1 (no film), where 1 - (1 - c^2) loses c^2 < 6e-8 to float32 rounding at grazing.
    float k = (outside_ior / eta2) * (outside_ior / eta2);
    float cos2sq = (1.0 - k) + k * cos1 * cos1;
    if (cos2sq < 0.0) return vec3(1.0);
    float cos2 = sqrt(cos2sq);
    float r0 = (eta2 - outside_ior) / (eta2 + outside_ior);
    float R12 = iri_schlick(r0 * r0, cos1);
    float T121 = 1.0 - R12;
    float phi12 = eta2 < outside_ior ? PI : 0.0;
    float phi21 = PI - phi12;
    vec3 sf0 = sqrt(clamp(base_f0, 0.0, IRIDESCENCE_MAX_F0));
    vec3 base_ior = (1.0 + sf0) / (1.0 - sf0);
    vec3 r1 = (base_ior - eta2) / (base_ior + eta2);
    vec3 R23 = iri_schlick(r1 * r1, cos2);
    vec3 phi23 = vec3(base_ior.x < eta2 ? PI : 0.0, base_ior.y < eta2 ? PI : 0.0, base_ior.z < eta2 ? PI : 0.0);
    float opd = 2.0 * eta2 * thickness * cos2;
    vec3 phi = vec3(phi21) + phi23;
    vec3 R123 = min(R12 * R23, vec3(IRIDESCENCE_MAX_F0));
    vec3 r123 = sqrt(R123);
    vec3 Rs = T121 * T121 * R23 / (1.0 - R123);
    vec3 I = R12 + Rs;
    vec3 Cm = Rs - T121;
    for (int m = 1; m <= 2; ++m) {
        Cm *= r123;
        I += Cm * 2.0 * iridescence_sensitivity(float(m) * opd, float(m) * phi);
    }
    return max(I, vec3(0.0));
}

// Source: glTF-Sample-Viewer's material set-up (a zero film thickness switches iridescence off): at
// thickness 0 the film IOR fades to the outside's, but Schlick's matched interface keeps F90 = 1, so
// iridescence_fresnel is not the base's Fresnel at grazing (up to +0.44 of a base F0 0, near n.v = 0.2): the factor must
// go to 0 instead. Equation: d > 0 ? k : 0.
float iridescence_factor(float k, float thickness) {
    return thickness > 0.0 ? k : 0.0;
}

// Source: glTF-Sample-Viewer (the specular Fresnel mixed by iridescenceFactor). Equation: mix(F, F_iri, k).
vec3 iridescence_mix(vec3 F, vec3 F_iri, float k) {
    return mix(F, F_iri, k);
}

// Source: KHR_materials_iridescence README "Implementation" (dielectric_fresnel and metal_fresnel each
// mixed with the film's reflectance over their own F0), for a point, spot or directional light at its
// half vector: the film at v.h over f0 (the truth's form, pbrcheck.lobes / reference.lobe_bsdf; the
// Sample Viewer and three.js read one film at n.v for every light: docs/realtime.md).
// Equation: mix(f0 + (f90 - f0)(1 - v.h)^5, iridescence_fresnel(1, film_ior, v.h, d, f0), k).
vec3 iridescence_light_fresnel(float VoH, vec3 f0, float f90, float film_ior, float thickness, float k) {
    float c = clamp(VoH, 0.0, 1.0);
    vec3 F = f0 + (vec3(f90) - f0) * pow5(1.0 - c);
    return iridescence_mix(F, iridescence_fresnel(1.0, film_ior, c, thickness, f0), k);
}
