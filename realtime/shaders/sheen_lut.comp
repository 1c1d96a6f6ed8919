// sheen_lut.comp: pass "sheen_lut" (realtime.lobes.sheen_lut). The sheen LUT, the DFG LUT's conventions:
// texel (column i, row j) = (n.v = (i + 0.5)/N, sheen roughness = (j + 0.5)/N), row 0 smoothest,
// alpha = roughness^2; read with ibl.glsl dfg_lookup (bilinear between texel centres, linear
// extrapolation within half a texel of 0 and 1; lobes_sheen.glsl sheen_lut_lookup). Format LUT_FORMAT
// (rgba16f or rgba32f; A = 0):
// R = E_charlie = int D_Charlie V_Charlie n.l dl (KHR_materials_sheen's directional albedo: its
//     albedo scaling, and the SHEEN_DFG lut_charlie weight),
// G = E_neubelt = int D_Charlie V_Neubelt n.l dl (Filament's DFG.z and the Sample Viewer's Charlie LUT as
//     glTF-IBL-Sampler's LUT_CharlieUniform bakes it: alpha = roughness^2, V unclamped),
// B = E_ibl_sampler_legacy = the same with an older glTF-IBL-Sampler's conventions: alpha = roughness (not
//     squared) and V_Neubelt clamped to [0, 1] (a departure from the spec's alpha = roughness^2).
// Estimator: half vectors by sample_Charlie at each channel's alpha (density D (n.h)), l = reflect(-v, h),
// pdf_l = D (n.h) / (4 v.h), so f n.l / pdf_l = 4 V (n.l)(v.h) / (n.h); Hammersley points with the DFG LUT's
// half-cell offset; R and G share the alpha = roughness^2 samples, B draws its own at alpha = roughness.
layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;
#include "sampling.glsl"
#include "lobes_sheen.glsl"
layout(LUT_FORMAT, binding = 0) writeonly uniform image2D out_lut;
uniform int lut_size;
uniform int n_samples;

void main() {
    ivec2 g = ivec2(gl_GlobalInvocationID.xy);
    if (g.x >= lut_size || g.y >= lut_size) return;
    float NoV = (float(g.x) + 0.5) / float(lut_size);
    float roughness = (float(g.y) + 0.5) / float(lut_size);
    float alpha = roughness * roughness;
    vec3 v = vec3(sqrt(1.0 - NoV * NoV), 0.0, NoV);
    float e_charlie = 0.0, e_neubelt = 0.0, e_ibl_sampler_legacy = 0.0;
    uint ns = uint(n_samples);
    for (uint i = 0u; i < ns; ++i) {
        vec2 u = hammersley(i, ns);
        u.x += 0.5 / float(ns);
        for (int k = 0; k < 2; ++k) {
            vec3 h = sample_Charlie(u, k == 0 ? alpha : roughness);
            float VoH = dot(v, h);
            vec3 l = 2.0 * VoH * h - v;
            float NoL = l.z;
            if (NoL <= 0.0 || VoH <= 0.0 || h.z <= 0.0) continue;
            float w = 4.0 * NoL * VoH / h.z;
            if (k == 0) {
                e_charlie += w * V_Charlie(NoV, NoL, alpha);
                e_neubelt += w * V_Neubelt(NoV, NoL);
            } else {
                e_ibl_sampler_legacy += w * min(V_Neubelt(NoV, NoL), 1.0);
            }
        }
    }
    imageStore(out_lut, g, vec4(e_charlie, e_neubelt, e_ibl_sampler_legacy, 0.0) / float(ns));
}
