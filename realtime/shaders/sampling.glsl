// sampling.glsl: low-discrepancy points and importance sampling of each NDF. Every function has a
// numpy twin of the same name in pbrcheck/sampling.py. Tangent space: z = the normal.
#include "brdf.glsl"

// Source: [Dammertz12] "Hammersley points on the hemisphere". Equation: radical inverse in base 2,
// bits reversed: phi_2(i) = sum_k b_k 2^-(k+1).
float radical_inverse(uint i) { return float(bitfieldReverse(i)) * 2.3283064365386963e-10; }

// Source: [Dammertz12]. Equation: x_i = (i / N, phi_2(i)).
vec2 hammersley(uint i, uint n) { return vec2(float(i) / float(n), radical_inverse(i)); }

// Source: [Walter07] eq. 35, 36 in Karis's cosine form [Karis13] p. 4.
// Equation: phi = 2 pi u.x, cos(theta_h) = sqrt((1 - u.y) / (1 + (alpha^2 - 1) u.y)); pdf_h = D_GGX(h) (n.h).
vec3 sample_GGX(vec2 u, float alpha) {
    float a2 = max(alpha, MIN_ALPHA);
    a2 *= a2;
    float phi = 2.0 * PI * u.x;
    float c2 = (1.0 - u.y) / max(1.0 + (a2 - 1.0) * u.y, COS_EPS);
    float ct = sqrt(clamp(c2, 0.0, 1.0));
    // sin^2 = 1 - c2 = a2 u.y / (1 + (a2 - 1) u.y), accurate for tiny alpha.
    float st = sqrt(clamp(a2 * u.y / max(1.0 + (a2 - 1.0) * u.y, COS_EPS), 0.0, 1.0));
    return vec3(st * cos(phi), st * sin(phi), ct);
}

// Source: [Walter07] eq. 28. Equation: tan^2(theta_h) = -alpha^2 log(1 - u.y), phi = 2 pi u.x;
// pdf_h = D_Beckmann(h) (n.h).
vec3 sample_Beckmann(vec2 u, float alpha) {
    float a2 = max(alpha, MIN_ALPHA);
    a2 *= a2;
    float phi = 2.0 * PI * u.x;
    float t2 = -a2 * log(max(1.0 - u.y, 1e-12));
    float ct = inversesqrt(1.0 + t2);
    float st = sqrt(t2) * ct;
    return vec3(st * cos(phi), st * sin(phi), ct);
}

// Source: [Walter07] sec. 5.2. Equation: cos(theta_h) = (1 - u.y)^(1 / (n + 2)), phi = 2 pi u.x;
// pdf_h = D_BlinnPhong(h) (n.h).
vec3 sample_BlinnPhong(vec2 u, float alpha) {
    float n = blinn_phong_exponent(alpha);
    float phi = 2.0 * PI * u.x;
    // e = log(cos^2) = 2 log(1 - u.y) / (n + 2); sin^2 = -expm1(e), by its series when e is tiny
    // (1 - cos^2 would round to 0 in float32 for n ~ 2e14).
    float e = 2.0 * log(max(1.0 - u.y, 1e-12)) / (n + 2.0);
    float st2 = e > -1e-3 ? -e * (1.0 + 0.5 * e) : 1.0 - exp(e);
    float ct = sqrt(max(1.0 - st2, 0.0));
    float st = sqrt(max(st2, 0.0));
    return vec3(st * cos(phi), st * sin(phi), ct);
}

// Source: [Heitz18] listing 1 (GGX visible normals). Equation: h ~ D_v(h) = G1(v) max(0, v.h) D(h) / (n.v).
vec3 sample_GGX_VNDF(vec2 u, vec3 v, float alpha) {
    float a = max(alpha, MIN_ALPHA);
    vec3 vh = normalize(vec3(a * v.x, a * v.y, v.z));
    float lensq = vh.x * vh.x + vh.y * vh.y;
    vec3 t1 = lensq > 0.0 ? vec3(-vh.y, vh.x, 0.0) * inversesqrt(lensq) : vec3(1.0, 0.0, 0.0);
    vec3 t2 = cross(vh, t1);
    float r = sqrt(u.x);
    float phi = 2.0 * PI * u.y;
    float p1 = r * cos(phi);
    float p2 = r * sin(phi);
    float s = 0.5 * (1.0 + vh.z);
    p2 = (1.0 - s) * sqrt(max(1.0 - p1 * p1, 0.0)) + s * p2;
    vec3 nh = p1 * t1 + p2 * t2 + sqrt(max(0.0, 1.0 - p1 * p1 - p2 * p2)) * vh;
    return normalize(vec3(a * nh.x, a * nh.y, max(0.0, nh.z)));
}

// Source: [Heitz18] eq. 3. Equation: pdf_h = G1(v) max(0, v.h) D_GGX(h) / (n.v).
float pdf_GGX_VNDF(vec3 v, vec3 h, float alpha) {
    return G1_SmithGGX(v.z, alpha) * max(dot(v, h), 0.0) * D_GGX(h.z, alpha) / max(v.z, COS_EPS);
}

// Source: Malley's method. Equation: l = (sqrt(u.y) cos(2 pi u.x), sqrt(u.y) sin(2 pi u.x), sqrt(1 - u.y)); pdf = cos / pi.
vec3 sample_cosine(vec2 u) {
    float phi = 2.0 * PI * u.x;
    float r = sqrt(u.y);
    return vec3(r * cos(phi), r * sin(phi), sqrt(max(1.0 - u.y, 0.0)));
}

// sample_ndf (the selected NDF's sampler), generated from pbrcheck.registry.
#include "sampling_dispatch.glsl"

// The DFG LUT's sampling strategies (pbrcheck.registry.LUT_SAMPLINGS, dfg_lut.comp): each member's
// half vector for the view v (tangent space) and its sample's weight, the estimator of
// f_s cos / pdf divided by the Fresnel factor, (D G / (4 n.l n.v)) n.l / pdf_l.
// Source: [Heitz18] listing 1 and eq. 17. Equation: h ~ D_v(h); weight G2 / G1(v).
vec3 lut_half_vector_vndf(vec2 u, vec3 v, float alpha) { return sample_GGX_VNDF(u.yx, v, alpha); }

float lut_weight_vndf(float G, vec3 v, vec3 h, float alpha) {
    return G / max(G1_SmithGGX(v.z, alpha), COS_EPS);
}

// Source: [Walter07] eq. 38 (pdf_l = D (n.h) / (4 v.h)); article 000's ImportanceSampleGGX for ggx.
// Equation: h ~ D(h) (n.h) (sample_ndf); weight G (v.h) / ((n.h)(n.v)).
vec3 lut_half_vector_ndf(vec2 u, vec3 v, float alpha) { return sample_ndf(u, alpha); }

float lut_weight_ndf(float G, vec3 v, vec3 h, float alpha) {
    return G * dot(v, h) / max(h.z * v.z, COS_EPS);
}

// lut_half_vector and lut_weight: LUT_SAMPLING's, generated from pbrcheck.registry.
#include "dfg_sampling_dispatch.glsl"

// Runtime importance sampling's strategies (pbrcheck.registry.RUNTIME_SAMPLINGS,
// environment_light.glsl): each member's half vector (tangent space, vt the view there) and its
// estimator of one sample's F G L term (L the environment's radiance along l).
// Source: [Walter07] eq. 28 (article 001 draws Beckmann half vectors for the GGX D).
vec3 runtime_half_vector_beckmann(vec2 u, vec3 vt, float alpha) { return sample_Beckmann(u, alpha); }

// Source: [Walter07] eq. 35-36.
vec3 runtime_half_vector_ggx(vec2 u, vec3 vt, float alpha) { return sample_GGX(u, alpha); }

// Source: [Heitz18] listing 1.
vec3 runtime_half_vector_vndf(vec2 u, vec3 vt, float alpha) { return sample_GGX_VNDF(u.yx, vt, alpha); }

// Source: article 001 (beckmann, ggx). Equation: F G L (v.h) / ((n.h)(n.v)), exact only when h
// follows the shaded NDF's D (n.h) (article 001 draws Beckmann half vectors for the GGX D).
vec3 runtime_estimate_ndf(vec3 F, float G, vec3 L, float NoV, float NoH, float VoH, float alpha) {
    return F * G * L * VoH / (NoH * NoV);
}

// Source: [Heitz18] eq. 17. Equation: F G L / G1(v).
vec3 runtime_estimate_vndf(vec3 F, float G, vec3 L, float NoV, float NoH, float VoH, float alpha) {
    return F * G / max(G1_SmithGGX(NoV, alpha), COS_EPS) * L;
}

// runtime_half_vector and runtime_estimate: RUNTIME_SAMPLING's, generated from pbrcheck.registry.
#include "runtime_sampling_dispatch.glsl"
