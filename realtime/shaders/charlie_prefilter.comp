// charlie_prefilter.comp: pass "charlie_prefilter" (realtime.render.charlie_cube), one level of the
// Charlie-prefiltered cube the sheen lobe's image-based term reads (glTF-Sample-Viewer's
// u_CharlieEnvSampler, baked by glTF-IBL-Sampler's Charlie filter). Conventions, stated again at the
// reader (material_lobes.glsl sheen_radiance) and in realtime.lobes.CHARLIE_CUBE_CONVENTIONS:
// level L of `levels` holds the radiance filtered at sheen roughness L / (levels - 1) (the Sample
// Viewer's lod = sheenRoughness (mipCount - 1)), alpha = roughness^2; texel directions cube_dir
// (env.glsl); v = n = r ([Karis13]'s split-sum assumption); `n_samples` Hammersley points through
// sample_Charlie (density D (n.h) over half vectors; conditioned on n.l > 0, below), l = reflect(-n, h),
// weighted by n.l (as the
// GGX prefilter's article-000 form and glTF-IBL-Sampler's filter), each read at the source level of
// its density (filtered importance sampling, ibl.glsl filtered_is_lod; charlie_prefilter_pdf conditioned).
// At sheen roughness 0 (alpha at SHEEN_MIN_ALPHA, the Charlie lobe a grazing sliver) the conditioned
// half vectors sit at 45 degrees and the texel is the horizon ring about n, weighted by n.l; a texel
// with no weight at all stores the source's radiance along n.
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
    // Only half vectors within 45 degrees of n reflect n above the horizon (n.l = 2 (n.h)^2 - 1): the
    // points are drawn from the Charlie distribution conditioned on that, sin theta_h <= sqrt(1/2), an
    // event of probability p_up = sqrt(1/2)^(2 + 1/alpha): sample_Charlie's inversion with u.y p_up,
    // sin theta_h = sqrt(1/2) u.y^(alpha / (2 alpha + 1)) (written so, p_up never underflows), and the
    // density pdf / p_up = (2 + 1/alpha) / (4 pi) u.y^(1 / (2 alpha + 1)) (each sample's source level).
    // The estimate is a ratio of n.l-weighted sums, so conditioning leaves its expectation; at sheen
    // roughness 1/3 it puts every sample where ~1 % fell before. u.y is offset by half a cell (no
    // sample at u.y = 0, whose density is 0).
    float a = max(alpha, SHEEN_MIN_ALPHA);
    vec3 acc = vec3(0.0);
    float wsum = 0.0;
    uint ns = uint(n_samples);
    for (uint i = 0u; i < ns; ++i) {
        vec2 u = hammersley(i, ns);
        float uy = min(u.y + 0.5 / float(ns), 1.0);
        float st = sqrt(0.5) * pow(uy, a / (2.0 * a + 1.0));
        float phi = 2.0 * PI * u.x;
        vec3 ht = vec3(st * cos(phi), st * sin(phi), sqrt(max(1.0 - st * st, 0.0)));
        float pdf = (2.0 + 1.0 / a) / (4.0 * PI) * pow(uy, 1.0 / (2.0 * a + 1.0));
        vec3 h = to_world(ht, n);
        vec3 l = 2.0 * dot(n, h) * h - n;
        float NoL = dot(n, l);
        if (NoL <= 0.0) continue;
        float lod = filtered_is_lod(pdf, float(n_samples), src_face_size);
        acc += textureLod(src_cube, l, lod).rgb * NoL;
        wsum += NoL;
    }
    imageStore(out_cube, g, vec4(wsum > 0.0 ? acc / wsum : textureLod(src_cube, n, 0.0).rgb, 1.0));
}
