// prefilter.comp: pass "prefilter", one level of the specular mip chain. Karis's split-sum first sum
// with v = n = r, `n_samples` Hammersley points through sample_GGX at the level's roughness
// (roughness_from_lod), optional N.L weighting (article 000) and optional filtered importance
// sampling (source level from the pdf, GPU Gems 3 ch. 20). The half vectors and source levels are
// the level's sample table (prefilter_samples.comp: the same for every texel, computed once a level).
layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;
#include "env.glsl"
#include "sampling.glsl"
#include "ibl.glsl"
layout(IMAGE_FORMAT, binding = 0) writeonly uniform imageCube out_cube;
layout(std430, binding = 0) readonly buffer Samples { vec4 samples[]; };  // prefilter_samples.comp
uniform samplerCube src_cube;
uniform int face_size;
uniform float level;
uniform float max_lod;
uniform float cube_log2;
uniform int n_samples;

void main() {
    ivec3 g = ivec3(gl_GlobalInvocationID);
    if (g.x >= face_size || g.y >= face_size) return;
    vec3 n = cube_dir(g.z, (vec2(g.xy) + 0.5) / float(face_size));
    float r = roughness_from_lod(level, max_lod, cube_log2);
    float alpha = alpha_from_roughness(r);
    if (alpha < DELTA_LOBE_ALPHA) {
        imageStore(out_cube, g, vec4(textureLod(src_cube, n, 0.0).rgb, 1.0));
        return;
    }
    vec3 acc = vec3(0.0);
    float wsum = 0.0;
    uint ns = uint(n_samples);
    for (uint i = 0u; i < ns; ++i) {
        vec4 s = samples[i];
        vec3 h = to_world(s.xyz, n);
        vec3 l = 2.0 * dot(n, h) * h - n;
        float NoL = dot(n, l);
        if (NoL <= 0.0) continue;
#if FILTERED
        float lod = s.w;
#else
        float lod = 0.0;  // a constant level: the compiler keeps its cheaper fetch
#endif
#if NL_WEIGHT
        float w = NoL;
#else
        float w = 1.0;
#endif
        acc += textureLod(src_cube, l, lod).rgb * w;
        wsum += w;
    }
    imageStore(out_cube, g, vec4(acc / max(wsum, 1e-20), 1.0));
}
