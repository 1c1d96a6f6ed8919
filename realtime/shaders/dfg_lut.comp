// dfg_lut.comp: pass "dfg_lut". Texel (column i, row j) = (n.v = (i + 0.5)/N, roughness = (j + 0.5)/N),
// row 0 smoothest; R = A (scale of F0), G = B (bias), [Karis13] eq. 8:
// A = int (1 - (1 - v.h)^5) f_s cos dl, B = int (1 - v.h)^5 f_s cos dl, f_s = D G / (4 n.l n.v).
// LUT_SAMPLING (pbrcheck.registry.LUT_SAMPLINGS, sampling.glsl): the half vector lut_half_vector and
// the weight lut_weight of the selected strategy, vndf (GGX visible normals [Heitz18], weight
// G2 / G1(v)) or ndf (NDF half vectors, article 000's ImportanceSampleGGX for ggx, weight
// G (v.h) / ((n.h)(n.v))).
layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;
#include "sampling.glsl"
layout(LUT_FORMAT, binding = 0) writeonly uniform image2D out_lut;
uniform int lut_size;
uniform int n_samples;

void main() {
    ivec2 g = ivec2(gl_GlobalInvocationID.xy);
    if (g.x >= lut_size || g.y >= lut_size) return;
    float NoV = (float(g.x) + 0.5) / float(lut_size);
    float roughness = (float(g.y) + 0.5) / float(lut_size);
    float alpha = alpha_from_roughness(roughness);
    vec3 v = vec3(sqrt(1.0 - NoV * NoV), 0.0, NoV);
    float A = 0.0, B = 0.0;
    uint ns = uint(n_samples);
    for (uint i = 0u; i < ns; ++i) {
        vec2 u = hammersley(i, ns);
        // Cranley-Patterson offset to the cell centre: the i/N coordinate becomes (i + 0.5)/N.
        u.x += 0.5 / float(ns);
        vec3 h = lut_half_vector(u, v, alpha);
        float VoH = dot(v, h);
        vec3 l = 2.0 * VoH * h - v;
        float NoL = l.z;
        if (NoL <= 0.0 || VoH <= 0.0) continue;
        float G = geometry_term(NoV, NoL, roughness);
        float w = lut_weight(G, v, h, alpha);
        float Fc = pow5(1.0 - VoH);
        A += w * (1.0 - Fc);
        B += w * Fc;
    }
    imageStore(out_lut, g, vec4(A / float(ns), B / float(ns), 0.0, 0.0));
}
