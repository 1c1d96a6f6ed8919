// environment_light.glsl: the environment's light at a shading point, from the baked artifacts of
// realtime/render.py: diffuse irradiance E(n)/pi (cube or SH9), the split sum's prefiltered radiance
// and DFG terms, and runtime importance sampling of the environment cube (article 001). Declares
// the samplers and uniforms it reads; a pipeline that includes it binds them (realtime/render.py
// FRAME_TEXTURE_UNITS). Each hook (hooks.glsl, docs/hooks.md) replaces its built-in piece.
#include "sampling.glsl"
#include "ibl.glsl"

uniform samplerCube prefiltered;
uniform samplerCube irradiance_cube;
uniform samplerCube env_cube;      // radiance cube with box-filtered mips (runtime sampling)
uniform sampler2D dfg_lut;
uniform vec3 sh[9];
uniform float max_lod;
uniform float cube_log2;
uniform float env_face_size;
uniform int runtime_samples;
uniform float lod_override;   // >= 0: every prefiltered lookup at this level (fit-lod's scan)

// Source: Lambert's diffuse term with the baked irradiance. Equation: E(n) / pi, by IRRADIANCE:
// the convolved cube, or [Ramamoorthi01]'s SH9 (sh9_eval).
vec3 irradiance_over_pi(vec3 n) {
#ifdef HOOK_DIFFUSE_IBL
    return hook_diffuse_ibl(n);
#elif IRRADIANCE == IRRADIANCE_SH9
    return sh9_eval(sh, n);
#else
    return textureLod(irradiance_cube, n, 0.0).rgb;
#endif
}

// Source: [Karis13] split sum's second factor. Equation: (A, B) with F0 A + B the specular albedo,
// by DFG: the baked LUT (dfg_lookup) or [Karis14]'s EnvBRDFApprox.
vec2 dfg(float NoV, float roughness) {
#ifdef HOOK_DFG
    return hook_dfg(NoV, roughness);
#elif DFG == DFG_ANALYTIC
    return EnvBRDFApprox(NoV, roughness);
#else
    return dfg_lookup(dfg_lut, NoV, roughness);
#endif
}

// Source: [Karis13] split sum's first factor. Equation: the prefiltered cube at r, level
// lod_from_roughness(roughness) (lod.glsl), or lod_override when it is >= 0.
vec3 prefiltered_radiance(vec3 r, float roughness) {
#ifdef HOOK_LOD
    float lod = lod_override >= 0.0 ? min(lod_override, max_lod) : hook_lod(roughness, max_lod, cube_log2);
#else
    float lod = lod_override >= 0.0 ? min(lod_override, max_lod) : lod_from_roughness(roughness, max_lod, cube_log2);
#endif
    return textureLod(prefiltered, r, lod).rgb;
}

uint hash_u(uint x) {
    x ^= x >> 16; x *= 0x7feb352du; x ^= x >> 15; x *= 0x846ca68bu; x ^= x >> 16;
    return x;
}

// Source: article 001 (runtime importance sampling of the environment); GPU Gems 3 ch. 20 for the
// mip-filtered lookups. Equation: (1/N) sum F G L (v.h) / ((n.h)(n.v)) over half vectors drawn by
// RUNTIME_SAMPLING (pbrcheck.registry.RUNTIME_SAMPLINGS, sampling.glsl: runtime_half_vector and
// runtime_estimate): _BECKMANN (the article: Beckmann half vectors for the GGX D), _GGX, or _VNDF
// (GGX visible normals, estimator F G / G1(v) L).
vec3 runtime_specular(vec3 n, vec3 v, float roughness, vec3 F0, uint pixel_seed) {
    float alpha = alpha_from_roughness(roughness);
    float NoV = max(dot(n, v), 1e-4);
    vec3 acc = vec3(0.0);
    uint ns = uint(runtime_samples);
#if RUNTIME_ROTATE
    uint rot = hash_u(pixel_seed);
#else
    uint rot = 0u;
#endif
    vec3 up = abs(n.z) < 0.999 ? vec3(0.0, 0.0, 1.0) : vec3(1.0, 0.0, 0.0);
    vec3 tx = normalize(cross(up, n));
    vec3 ty = cross(n, tx);
    vec3 vt = vec3(dot(v, tx), dot(v, ty), dot(v, n));
    for (uint i = 0u; i < ns; ++i) {
        // Alchemy-style XOR scrambling of the radical inverse by a per-pixel key.
        vec2 u = vec2(float(i) / float(ns), float(bitfieldReverse(i) ^ rot) * 2.3283064365386963e-10);
        vec3 ht = runtime_half_vector(u, vt, alpha);
        vec3 h = tx * ht.x + ty * ht.y + n * ht.z;
        float VoH = dot(v, h);
        vec3 l = 2.0 * VoH * h - v;
        float NoL = dot(n, l);
        if (NoL <= 0.0 || VoH <= 0.0) continue;
        float NoH = max(ht.z, 1e-6);
        float G = geometry_term(NoV, NoL, roughness);
        vec3 F = fresnel_term(VoH, F0);
#if RUNTIME_LOD
        float pdf = ndf_term(NoH, roughness) * NoH / (4.0 * VoH);
        float lod = filtered_is_lod(pdf, float(ns), env_face_size);
#else
        float lod = 0.0;
#endif
        vec3 L = textureLod(env_cube, l, lod).rgb;
        acc += runtime_estimate(F, G, L, NoV, NoH, VoH, alpha);
    }
    return acc / float(ns);
}
