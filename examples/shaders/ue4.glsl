// Unreal Engine 4's shading choices (Karis 2013) as pbrcheck shader hooks (docs/hooks.md).
// Written from the equations published in B. Karis, "Real Shading in Unreal Engine 4", SIGGRAPH
// 2013 course "Physically Based Shading in Theory and Practice", not from Unreal's source:
//   Specular G (eq. 4): Schlick's model with k = alpha / 2 (alpha = r^2), which Karis uses for
//     image-based lighting (analytic lights remap r to (r + 1) / 2 first; this file keeps alpha / 2
//     for both, as the IBL integration does);
//     G1(x) = x / (x (1 - k) + k),  G = G1(n.l) G1(n.v);
//   Fresnel (eq. 5): Schlick's approximation with a spherical-Gaussian exponent,
//     F = F0 + (1 - F0) 2^((-5.55473 v.h - 6.98316) v.h);
//   Prefiltered mip level: the reflection capture's log2 mapping,
//     lod = log2(size) - (1 - 1.2 log2 r), clamped to [0, M].
// Use it with --set lod_mapping=log2 so that the chain is also prefiltered for the log2 mapping
// (hook_lod changes the lookup only; the bake follows the preset's lod_mapping).

float hook_G(float NoV, float NoL, float roughness) {
    float k = roughness * roughness / 2.0;
    float g1v = NoV / (NoV * (1.0 - k) + k);
    float g1l = NoL / (NoL * (1.0 - k) + k);
    return g1v * g1l;
}

vec3 hook_F(float VoH, vec3 F0) {
    float e = exp2((-5.55473 * VoH - 6.98316) * VoH);
    return F0 + (1.0 - F0) * e;
}

// log2(0) = -inf: r >= 1e-6 keeps the level finite (clamped to the sharpest level anyway).
float hook_lod(float roughness, float max_lod, float cube_log2) {
    float level_from_1x1 = 1.0 - 1.2 * log2(max(roughness, 1e-6));
    return clamp(cube_log2 - level_from_1x1, 0.0, max_lod);
}
