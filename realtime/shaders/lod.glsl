// lod.glsl: the built-in roughness <-> prefiltered mip level mappings, one pair of functions per
// member of pbrcheck.registry.LOD_MAPPINGS (numpy twins of the same names: pbrcheck/lodmap.py).
// max_lod: last level of the prefiltered chain (M); cube_log2: log2 of the cube's face size (the
// log2 mapping counts levels from the 1x1 mip). lod_from_roughness / roughness_from_lod dispatch on
// LOD_MAPPING and are generated from the registry (lod_dispatch.glsl).

// Source: article 000 (mip = roughness x max mip). Equation: lod = clamp(r, 0, 1) M.
float lod_linear(float r, float max_lod, float cube_log2) {
    return clamp(r, 0.0, 1.0) * max_lod;
}
// Equation: r = lod / M.
float roughness_linear(float lod, float max_lod, float cube_log2) {
    return lod / max_lod;
}

// Source: Filament's perceptualRoughnessToLod. Equation: lod = M x (2 - x), x = clamp(r, 0, 1).
float lod_quadratic(float r, float max_lod, float cube_log2) {
    float x = clamp(r, 0.0, 1.0);
    return max_lod * x * (2.0 - x);
}
// Equation: r = 1 - sqrt(max(1 - lod / M, 0)).
float roughness_quadratic(float lod, float max_lod, float cube_log2) {
    return 1.0 - sqrt(max(1.0 - lod / max_lod, 0.0));
}

// Source: UE4's ComputeReflectionCaptureMipFromRoughness (quoted by article 002).
// Equation: lod = clamp(log2(size) - (1 - 1.2 log2 r), 0, M); r >= 1e-6 (log2 0 = -inf).
float lod_log2(float r, float max_lod, float cube_log2) {
    float level_from_1x1 = 1.0 - 1.2 * log2(max(r, 1e-6));
    return clamp(cube_log2 - level_from_1x1, 0.0, max_lod);
}
// Equation: r = clamp(2^((lod - log2(size) + 1) / 1.2), 0, 1).
float roughness_log2(float lod, float max_lod, float cube_log2) {
    return clamp(exp2((lod - cube_log2 + 1.0) / 1.2), 0.0, 1.0);
}

#include "lod_dispatch.glsl"
