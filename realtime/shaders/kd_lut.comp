// kd_lut.comp: pass "kd_lut". Texel i = n.v (i + 0.5)/N: Kd = int (1 - (1 - v.h)^5) cos(l) / pi dl,
// the diffuse albedo of the material model per unit (1 - F0)(1 - metallic) base_color
// (pbrcheck.brdf.diffuse_albedo with F0 = 0); cosine-weighted Hammersley points.
layout(local_size_x = 64) in;
#include "sampling.glsl"
layout(r32f, binding = 0) writeonly uniform image2D out_lut;
uniform int lut_size;
uniform int n_samples;

void main() {
    int i = int(gl_GlobalInvocationID.x);
    if (i >= lut_size) return;
    float NoV = (float(i) + 0.5) / float(lut_size);
    vec3 v = vec3(sqrt(1.0 - NoV * NoV), 0.0, NoV);
    float acc = 0.0;
    uint ns = uint(n_samples);
    for (uint k = 0u; k < ns; ++k) {
        vec2 u = hammersley(k, ns);
        u.x += 0.5 / float(ns);
        vec3 l = sample_cosine(u);
        vec3 h = normalize(v + l);
        acc += 1.0 - pow5(1.0 - clamp(dot(v, h), 0.0, 1.0));
    }
    imageStore(out_lut, ivec2(i, 0), vec4(acc / float(ns), 0.0, 0.0, 0.0));
}
