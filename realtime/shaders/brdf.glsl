// brdf.glsl: BRDF terms. Every function has a numpy twin of the same name in pbrcheck/brdf.py;
// tests/test_realtime_glsl.py runs both on the same grids. Cosines are clamped by the caller to
// [0, 1]; alpha is the GGX width roughness^2.
#include "common.glsl"
#include "hooks.glsl"

// Source: [Karis13] p. 3. Equation: alpha = roughness^2, clamped to MIN_ALPHA.
float alpha_from_roughness(float roughness) {
    return max(roughness * roughness, MIN_ALPHA);
}

// Source: [Walter07] eq. 33 (GGX / Trowbridge-Reitz).
// Equation: D = alpha^2 / (pi ((n.h)^2 (alpha^2 - 1) + 1)^2).
// The denominator is written (1 - n.h)(1 + n.h) + (n.h)^2 alpha^2, exact in float32 as n.h -> 1.
float D_GGX(float NoH, float alpha) {
    float a2 = max(alpha, MIN_ALPHA);
    a2 *= a2;
    float d = (1.0 - NoH) * (1.0 + NoH) + NoH * NoH * a2;
    return NoH > 0.0 ? a2 / (PI * d * d) : 0.0;
}

// Source: [Walter07] eq. 25 (Beckmann).
// Equation: D = exp(-tan^2(theta_h) / alpha^2) / (pi alpha^2 cos^4(theta_h)).
float D_Beckmann(float NoH, float alpha) {
    float a2 = max(alpha, MIN_ALPHA);
    a2 *= a2;
    float c2 = max(NoH * NoH, COS_EPS);
    float tan2 = max((1.0 - NoH) * (1.0 + NoH), 0.0) / c2;
    float v = exp(-tan2 / a2) / (PI * a2 * c2 * c2);
    return NoH > 0.0 ? v : 0.0;
}

// Source: [Walter07] sec. 5.2. Equation: n = 2 / alpha^2 - 2 (the Phong exponent of a Beckmann alpha).
float blinn_phong_exponent(float alpha) {
    float a2 = max(alpha, MIN_ALPHA);
    a2 *= a2;
    return max(2.0 / a2 - 2.0, 0.0);
}

// Source: [Walter07] eq. 30 (normalized Blinn-Phong). Equation: D = (n + 2) / (2 pi) (n.h)^n.
float D_BlinnPhong(float NoH, float alpha) {
    float n = blinn_phong_exponent(alpha);
    float v = (n + 2.0) / (2.0 * PI) * pow(clamp(NoH, 0.0, 1.0), n);
    return NoH > 0.0 ? v : 0.0;
}

// Source: [Heitz14] eq. 72. Equation: Lambda = (sqrt(alpha^2 + (1 - alpha^2) c^2) / c - 1) / 2.
float Lambda_GGX(float NoX, float alpha) {
    float c = max(NoX, COS_EPS);
    float a2 = max(alpha, MIN_ALPHA);
    a2 *= a2;
    return 0.5 * (sqrt(a2 + (1.0 - a2) * c * c) / c - 1.0);
}

// Source: [Heitz14] eq. 43 with eq. 72. Equation: G1 = 2 c / (c + sqrt(alpha^2 + (1 - alpha^2) c^2)).
float G1_SmithGGX(float NoX, float alpha) {
    float c = clamp(NoX, 0.0, 1.0);
    float a2 = max(alpha, MIN_ALPHA);
    a2 *= a2;
    return 2.0 * c / max(c + sqrt(a2 + (1.0 - a2) * c * c), COS_EPS);
}

// Source: [Heitz14] eq. 98 (separable Smith). Equation: G = G1(v) G1(l).
float G_SmithGGX(float NoV, float NoL, float alpha) {
    return G1_SmithGGX(NoV, alpha) * G1_SmithGGX(NoL, alpha);
}

// Source: [Heitz14] eq. 99 (height-correlated Smith).
// Equation: G = 2 (n.v)(n.l) / ((n.l) sqrt(a2 + (1-a2)(n.v)^2) + (n.v) sqrt(a2 + (1-a2)(n.l)^2)).
float G_SmithGGXCorrelated(float NoV, float NoL, float alpha) {
    float v = clamp(NoV, 0.0, 1.0);
    float l = clamp(NoL, 0.0, 1.0);
    float a2 = max(alpha, MIN_ALPHA);
    a2 *= a2;
    float den = l * sqrt(a2 + (1.0 - a2) * v * v) + v * sqrt(a2 + (1.0 - a2) * l * l);
    return 2.0 * v * l / max(den, COS_EPS);
}

// Source: Numerical Recipes in C (2nd ed.) sec. 6.2, erfcc (fractional error < 1.2e-7) without its
// exp(-z^2) factor. Equation: erfcx(z) = exp(z^2) erfc(z) = t exp(P(t)), t = 1 / (1 + z / 2), z >= 0.
float erfcx_nr(float z) {
    float t = 1.0 / (1.0 + 0.5 * max(z, 0.0));
    float p = -1.26551223 + t * (1.00002368 + t * (0.37409196 + t * (0.09678418 + t * (
        -0.18628806 + t * (0.27886807 + t * (-1.13520398 + t * (1.48851587 + t * (
        -0.82215223 + t * 0.17087277))))))));
    return t * exp(p);
}

// Source: [Heitz14] eq. 80. Equation: Lambda = (erf(a) - 1) / 2 + exp(-a^2) / (2 a sqrt(pi)),
// a = c / (alpha sqrt(1 - c^2)); computed as exp(-a^2) (1 / (a sqrt(pi)) - erfcx(a)) / 2 (no
// cancellation of erf(a) - 1; GLSL has no erf).
float Lambda_Beckmann(float NoX, float alpha) {
    float c = clamp(NoX, COS_EPS, 1.0);
    float s = sqrt(max(1.0 - c * c, 0.0));
    float a = clamp(c / max(max(alpha, MIN_ALPHA) * s, 1e-30), 1e-20, 1e15);
    return max(0.5 * exp(-a * a) * (0.5641895835 / a - erfcx_nr(a)), 0.0);
}

// Source: [Heitz14] eq. 99 with eq. 80 (height-correlated Smith, Beckmann).
// Equation: G = 1 / (1 + Lambda(v) + Lambda(l)); 0 at n.v = 0 or n.l = 0.
float G_SmithBeckmannCorrelated(float NoV, float NoL, float alpha) {
    float g = 1.0 / (1.0 + Lambda_Beckmann(NoV, alpha) + Lambda_Beckmann(NoL, alpha));
    return (NoV > 0.0 && NoL > 0.0) ? g : 0.0;
}

// Source: [Schlick94] eq. 19 with [Karis13]'s k. Equation: G1 = c / (c (1 - k) + k).
float G1_SchlickGGX(float NoX, float k) {
    float c = clamp(NoX, 0.0, 1.0);
    return c / max(c * (1.0 - k) + k, COS_EPS);
}

// Source: [Karis13] eq. 4. Equation: G = G1_SchlickGGX(v, k) G1_SchlickGGX(l, k).
float G_SchlickGGX(float NoV, float NoL, float k) {
    return G1_SchlickGGX(NoV, k) * G1_SchlickGGX(NoL, k);
}

// Source: [Karis13] eq. 4 footnote (image-based lighting). Equation: k = alpha / 2.
float k_schlick_ibl(float roughness) { return alpha_from_roughness(roughness) / 2.0; }

// Source: [Karis13] eq. 4 (analytic lights, Disney's remapping). Equation: k = (roughness + 1)^2 / 8.
float k_schlick_direct(float roughness) { return (roughness + 1.0) * (roughness + 1.0) / 8.0; }

// Source: Schlick's approximation of Smith-Beckmann, as catalogued by article 001.
// Equation: k = alpha sqrt(2 / pi); G = G1_SchlickGGX(v, k) G1_SchlickGGX(l, k).
float G_SchlickBeckmann(float NoV, float NoL, float alpha) {
    float k = max(alpha, MIN_ALPHA) * 0.7978845608;
    return G1_SchlickGGX(NoV, k) * G1_SchlickGGX(NoL, k);
}

// Source: [Schlick94] eq. 15. Equation: F = F0 + (F90 - F0) (1 - v.h)^5.
float F_Schlick(float VoH, float F0, float F90) {
    return F0 + (F90 - F0) * pow5(1.0 - clamp(VoH, 0.0, 1.0));
}
vec3 F_Schlick(float VoH, vec3 F0, float F90) {
    return F0 + (vec3(F90) - F0) * pow5(1.0 - clamp(VoH, 0.0, 1.0));
}
vec3 F_Schlick(float VoH, vec3 F0) { return F_Schlick(VoH, F0, 1.0); }

// Source: no Fresnel factor (pbrcheck.registry FRESNELS "none"). Equation: F = 1.
vec3 F_None(float VoH, vec3 F0) { return vec3(1.0); }

// Source: Lambert. Equation: f_d = 1 / pi.
float Fd_Lambert() { return 1.0 / PI; }

// The scene's terms, chosen at compile time: NDF, GEOMETRY and FRESNEL are constants of
// pbrcheck.registry (NDF_GGX, GEOMETRY_SMITH_GGX_CORRELATED, FRESNEL_SCHLICK, ...), prepended to
// every shader by realtime/gl.py. ndf_term, geometry_term and fresnel_term (numpy twins of the same
// names in pbrcheck/brdf.py) are generated from the registry's entries: each calls its member's
// function above, or the user's hook_D / hook_G / hook_F.
#include "terms_dispatch.glsl"

// Source: README "Material model" (pbrcheck.brdf.brdf_eval). Equation:
// f = (1 - F(v.h)) (1 - metallic) base_color / pi + D(h) G(l, v) F(v.h) / (4 (n.l)(n.v)); 0 below the horizon.
// METALLIC_BLEND_GLTF (the scene's [brdf] metallic_blend = "gltf", defined by realtime/gl.py): glTF 2.0
// Appendix B, mix(dielectric_brdf, metal_brdf, metallic): the diffuse is weighted by 1 - F of the
// dielectric's own F0 = specular; the specular is F of the mixed F0 in both (Schlick is linear in F0).
vec3 brdf_eval(vec3 n, vec3 v, vec3 l, vec3 base_color, float metallic, float roughness, float specular) {
    float NoV = dot(n, v);
    float NoL = dot(n, l);
    if (NoV <= 0.0 || NoL <= 0.0) return vec3(0.0);
    vec3 h = v + l;
    h = h / max(length(h), COS_EPS);
    float NoH = clamp(dot(n, h), 0.0, 1.0);
    float VoH = clamp(dot(v, h), 0.0, 1.0);
    vec3 F0 = mix(vec3(specular), base_color, metallic);
    vec3 F = fresnel_term(VoH, F0);
    float D = ndf_term(NoH, roughness);
    float G = geometry_term(NoV, NoL, roughness);
    vec3 spec = D * G * F / (4.0 * max(NoV, COS_EPS) * max(NoL, COS_EPS));
#ifdef METALLIC_BLEND_GLTF
    vec3 Fd = fresnel_term(VoH, vec3(specular));
#else
    vec3 Fd = F;
#endif
    vec3 diff = (1.0 - Fd) * (1.0 - metallic) * base_color * Fd_Lambert();
    return diff + spec;
}
