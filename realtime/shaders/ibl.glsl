// ibl.glsl: image-based lighting lookups: roughness <-> prefiltered mip level, DFG lookup, Karis's
// analytic EnvBRDFApprox, SH9 irradiance (article 002 form), filtered importance sampling's level.
#include "brdf.glsl"

// LOD_MAPPING: a constant of pbrcheck.registry.LOD_MAPPINGS (LOD_MAPPING_LINEAR, ...); for
// LOD_MAPPING_FITTED the caller #defines LOD_FITTED(r) (frame pass only). lod_from_roughness and
// roughness_from_lod (lod.glsl) dispatch on it.
#ifndef LOD_MAPPING
#define LOD_MAPPING LOD_MAPPING_LINEAR
#endif
#include "lod.glsl"

// DFG lookup. Convention: texel (row j, column i) holds n.v = (i + 0.5)/N, roughness = (j + 0.5)/N,
// row 0 smoothest. Bilinear between texel centres (GL coordinates (s, t) = (n.v, roughness) land on
// them exactly) and, unlike GL's clamp-to-edge, linear extrapolation from the two outermost rows or
// columns for n.v or roughness within half a texel of 0 or 1 (roughness 1 is common in scenes).
// lut_lookup reads every channel (the sheen LUT's three, lobes_sheen.glsl); dfg_lookup the DFG LUT's two.
vec4 lut_lookup(sampler2D lut, float NoV, float roughness) {
    ivec2 size = textureSize(lut, 0);
    vec2 x = vec2(clamp(NoV, 0.0, 1.0), clamp(roughness, 0.0, 1.0)) * vec2(size) - 0.5;
    ivec2 i0 = clamp(ivec2(floor(x)), ivec2(0), max(size - 2, ivec2(0)));
    ivec2 i1 = min(i0 + 1, size - 1);
    vec2 f = x - vec2(i0);
    if (size.x < 2) f.x = 0.0;
    if (size.y < 2) f.y = 0.0;
    vec4 v00 = texelFetch(lut, ivec2(i0.x, i0.y), 0);
    vec4 v10 = texelFetch(lut, ivec2(i1.x, i0.y), 0);
    vec4 v01 = texelFetch(lut, ivec2(i0.x, i1.y), 0);
    vec4 v11 = texelFetch(lut, ivec2(i1.x, i1.y), 0);
    vec4 v0 = mix(v00, v10, f.x);
    vec4 v1 = mix(v01, v11, f.x);
    return max(mix(v0, v1, f.y), vec4(0.0));
}

// The DFG LUT's (A, B): lut_lookup's first two channels.
vec2 dfg_lookup(sampler2D lut, float NoV, float roughness) {
    return lut_lookup(lut, NoV, roughness).rg;
}

// Source: [Karis14] "Physically Based Shading on Mobile" (UE4), quoted by article 002.
// Equation: r = roughness c0 + c1; a004 = min(r.x^2, 2^(-9.28 n.v)) r.x + r.y;
// (A, B) = (-1.04, 1.04) a004 + r.zw. Returns (A, B) so that F0 A + B is the specular albedo.
vec2 EnvBRDFApprox(float NoV, float roughness) {
    const vec4 c0 = vec4(-1.0, -0.0275, -0.572, 0.022);
    const vec4 c1 = vec4(1.0, 0.0425, 1.04, -0.04);
    vec4 r = roughness * c0 + c1;
    float a004 = min(r.x * r.x, exp2(-9.28 * NoV)) * r.x + r.y;
    return vec2(-1.04, 1.04) * a004 + r.zw;
}

// Source: article 002 ("Irradiance as Spherical Harmonic"). Equation: max(sum_i sh_i b_i(n), 0)
// with b = (1, y, z, x, yx, yz, 3z^2 - 1, zx, x^2 - y^2); the coefficients carry the SH constants
// and the clamped-cosine convolution, scaled so the result is E(n) / pi.
vec3 sh9_eval(vec3 sh[9], vec3 n) {
    return max(sh[0] + sh[1] * n.y + sh[2] * n.z + sh[3] * n.x + sh[4] * (n.y * n.x)
               + sh[5] * (n.y * n.z) + sh[6] * (3.0 * n.z * n.z - 1.0) + sh[7] * (n.z * n.x)
               + sh[8] * (n.x * n.x - n.y * n.y), vec3(0.0));
}

// Source: GPU Gems 3 ch. 20 (Colbert, Krivanek), eq. 13. Equation:
// lod = max(0.5 log2(Omega_s / Omega_p) + 1, 0), Omega_s = 1 / (N pdf), Omega_p = 4 pi / (6 w^2).
float filtered_is_lod(float pdf, float n_samples, float face_size) {
    float omega_s = 1.0 / (n_samples * max(pdf, 1e-30));
    float omega_p = 4.0 * PI / (6.0 * face_size * face_size);
    return max(0.5 * log2(omega_s / omega_p) + 1.0, 0.0);
}
