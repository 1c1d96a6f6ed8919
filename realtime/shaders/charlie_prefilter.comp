// charlie_prefilter.comp: pass "charlie_prefilter" (realtime.render.charlie_cube), one level of the
// Charlie-prefiltered cube the sheen lobe's image-based term reads (glTF-Sample-Viewer's
// u_CharlieEnvSampler, baked by glTF-IBL-Sampler's Charlie filter). Conventions, stated again at the
// reader (material_lobes.glsl sheen_radiance) and in realtime.lobes.CHARLIE_CUBE_CONVENTIONS:
// level L of `levels` holds the radiance filtered at sheen roughness L / (levels - 1) (the Sample
// Viewer's lod = sheenRoughness (mipCount - 1)), alpha = roughness^2; texel directions cube_dir
// (env.glsl); v = n = r ([Karis13]'s split-sum assumption); `n_samples` Hammersley points through
// sample_Charlie (density D (n.h) over half vectors), l = reflect(-n, h), weighted by n.l (as the
// GGX prefilter's article-000 form and glTF-IBL-Sampler's filter), each read at the source level of
// its pdf (filtered importance sampling, ibl.glsl filtered_is_lod with charlie_prefilter_pdf).
// A texel whose every sample lies below the horizon (sheen roughness 0, alpha at SHEEN_MIN_ALPHA:
// the Charlie lobe is a grazing sliver) stores 0.
layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;
#include "env.glsl"
#include "sampling.glsl"
#include "lobes_sheen.glsl"
layout(IMAGE_FORMAT, binding = 0) writeonly uniform imageCube out_cube;
uniform samplerCube src_cube;
uniform int face_size;
uniform float src_face_size;
uniform float sheen_roughness;
uniform int n_samples;

void main() {
    ivec3 g = ivec3(gl_GlobalInvocationID);
    if (g.x >= face_size || g.y >= face_size) return;
    vec3 n = cube_dir(g.z, (vec2(g.xy) + 0.5) / float(face_size));
    float alpha = sheen_roughness * sheen_roughness;
    vec3 acc = vec3(0.0);
    float wsum = 0.0;
    uint ns = uint(n_samples);
    for (uint i = 0u; i < ns; ++i) {
        vec3 ht = sample_Charlie(hammersley(i, ns), alpha);
        vec3 h = to_world(ht, n);
        vec3 l = 2.0 * dot(n, h) * h - n;
        float NoL = dot(n, l);
        if (NoL <= 0.0) continue;
        float lod = filtered_is_lod(charlie_prefilter_pdf(ht.z, alpha), float(n_samples), src_face_size);
        acc += textureLod(src_cube, l, lod).rgb * NoL;
        wsum += NoL;
    }
    imageStore(out_cube, g, vec4(wsum > 0.0 ? acc / wsum : vec3(0.0), 1.0));
}
