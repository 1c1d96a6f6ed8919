// prefilter_samples.comp: pass "prefilter", the sample table of one level. The half vectors of
// prefilter.comp depend on the sample and the level's roughness only (v = n = r: tangent space is the
// same for every texel), so they are computed once a level instead of once per texel: invocation i
// writes sample_GGX(hammersley(i, n_samples), alpha) and, with FILTERED, its source level
// filtered_is_lod(D / 4, ...) (GPU Gems 3 ch. 20), the very expressions prefilter.comp read before.
layout(local_size_x = 64) in;
#include "env.glsl"
#include "sampling.glsl"
#include "ibl.glsl"
layout(std430, binding = 0) writeonly buffer Samples { vec4 samples[]; };  // half vector.xyz, lod
uniform float src_face_size;
uniform float level;
uniform float max_lod;
uniform float cube_log2;
uniform int n_samples;

void main() {
    uint i = gl_GlobalInvocationID.x;
    uint ns = uint(n_samples);
    if (i >= ns) return;
    float alpha = alpha_from_roughness(roughness_from_lod(level, max_lod, cube_log2));
    vec3 ht = sample_GGX(hammersley(i, ns), alpha);
#if FILTERED
    // v = n: pdf_l = D (n.h) / (4 v.h) = D / 4.
    float lod = filtered_is_lod(D_GGX(ht.z, alpha) * 0.25, float(ns), src_face_size);
#else
    float lod = 0.0;
#endif
    samples[i] = vec4(ht, lod);
}
