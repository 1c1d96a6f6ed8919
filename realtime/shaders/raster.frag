// raster.frag: pass "raster". Shades the rasterized surface with shading.glsl's shade(), included
// unchanged (every preset, option, hook and energy compensation applies), plus glTF 2.0's material
// inputs (Khronos glTF 2.0 specification, section 3.9): base colour = factor x texture (sRGB
// decoded at upload) x COLOR_0; metallic = factor x texture.B, roughness = factor x texture.G;
// normal = normalize(TBN ((2 t - 1) (scale, scale, 1))) with B = w cross(N, T) (MikkTSpace frame,
// the loader's tangents); emissive = factor x texture (sRGB), added to the outgoing radiance;
// occlusion = 1 + strength (texture.R - 1) on the image-based light (occlusion.glsl);
// alpha = base colour's alpha: MASK discards below alpha_cutoff, BLEND writes (radiance, alpha)
// for the host's blending. Double-sided back faces flip N, T and B (spec 3.9.5).
// AOV_PASS (a #define): writes the interpolated geometric normal, its n.v and the object id at
// the pixel centre instead of shading. SPECULAR_AA (specular_aa.glsl) widens the roughness by the
// normals' variance: the normal map's mip-filtered length (toksvig), the geometric normal's screen
// derivatives (screen_space), the slope variance baked beside the normal map's mips, tex_normal_var
// (prefiltered). HOOK_SPECULAR_AA (a user hook, realtime/hooks.py) replaces it on normal-mapped
// fragments, given the mip-filtered length and normal_map_lod(). ALPHA_TO_COVERAGE (option alpha_to_coverage): MASK writes the sharpened alpha
// (coverage.glsl) for the host's GL_SAMPLE_ALPHA_TO_COVERAGE instead of discarding.
// TRANSMISSION (defined only where the scene draws a transmissive material, realtime/transmission.py):
// transmission.glsl's screen-space refraction and diffuse transmission replace the dielectric diffuse (see main).
// UNLIT_MATERIALS (defined only where the scene draws a KHR_materials_unlit material): a material
// with unlit != 0 writes its base colour (factor x texture x COLOR_0) as the radiance, unshaded
// (KHR_materials_unlit; alpha as for a lit material).
#include "env.glsl"
#include "shading.glsl"
#include "specular_aa.glsl"
#include "coverage.glsl"
#include "texcoord.glsl"
#ifndef ALPHA_TO_COVERAGE
#define ALPHA_TO_COVERAGE 0
#endif
#ifndef UNLIT_MATERIALS
#define UNLIT_MATERIALS 0
#endif

in vec3 v_pos;
in vec3 v_nrm;
in vec4 v_tan;
in vec2 v_uv0;
in vec2 v_uv1;
in vec4 v_col;

uniform vec3 cam_origin;
uniform vec4 base_factor;
uniform float metallic_factor;
uniform float roughness_factor;
uniform float specular_f0;        // dielectric F0 from the ior
uniform vec3 emissive_factor;
uniform int alpha_mode;           // 0 OPAQUE, 1 MASK, 2 BLEND
uniform float alpha_cutoff;
uniform float normal_scale;
uniform int flip_backface;        // glTF doubleSided: back faces shade with the flipped frame
uniform float object_id;
#if UNLIT_MATERIALS
uniform int unlit;                // KHR_materials_unlit: 1 for an unlit material
#endif

// Texture slots: 0 baseColor, 1 metallicRoughness, 2 normal, 3 emissive.
uniform sampler2D tex_base;
uniform sampler2D tex_mr;
uniform sampler2D tex_normal;
uniform sampler2D tex_emissive;
uniform ivec4 tex_has;            // per slot: 1 when the material has the texture
uniform ivec4 tex_set;            // per slot: TEXCOORD_n
uniform mat3 tex_xf[4];           // per slot: KHR_texture_transform (identity when absent)
uniform ivec4 tex_mirror;         // per slot: bit 0 S, bit 1 T mirrored repeat (folded here)
// The occlusion texture (R channel, glTF occlusionTexture; has 0 where option occlusion_texture is off).
uniform sampler2D tex_occlusion;
uniform int ao_has;
uniform int ao_set;
uniform mat3 ao_xf;
uniform int ao_mirror;
uniform float ao_strength;
// specular_aa = prefiltered: var(s_x) + var(s_y) of the normal map's slopes per mip (R), read with the
// normal map's coordinates.
uniform sampler2D tex_normal_var;
#ifdef TRANSMISSION
#include "transmission.glsl"
#endif
#ifdef MATERIAL_LOBES
// The glTF PBR extensions' lobes (material_lobes.glsl), in lobe programs only: the material's factor
// rows (realtime.material_lobes.LOBE_ROW_LAYOUT; row 3's w the film's thickness minimum) and its lobe
// textures, slot k of realtime.material_lobes.LOBE_TEXTURE_SLOTS (clearcoat R, clearcoatRoughness G,
// clearcoatNormal, sheenColor RGB (sRGB), sheenRoughness A, specular A, specularColor RGB (sRGB),
// anisotropy RG direction B strength, iridescence R, iridescenceThickness G), each with its texCoord,
// KHR_texture_transform and mirror folds as the core slots.
#define LOBE_SLOTS 10
uniform vec4 lobe_p0;
uniform vec4 lobe_p1;
uniform vec4 lobe_p2;
uniform vec4 lobe_p3;
uniform float lobe_coat_normal_scale;
uniform sampler2D tex_lobe[LOBE_SLOTS];
uniform int lobe_has[LOBE_SLOTS];
uniform int lobe_set[LOBE_SLOTS];
uniform mat3 lobe_xf[LOBE_SLOTS];
uniform int lobe_mirror[LOBE_SLOTS];
#define LOBE_SLOT(k, fallback) lookup(tex_lobe[k], lobe_has[k], lobe_set[k], lobe_xf[k], lobe_mirror[k], fallback, TEXTURE_LOD0 != 0)
#endif

#if AOV_PASS
layout(location = 0) out vec4 out_aov;     // N.xyz, NdotV
layout(location = 1) out vec4 out_obj;     // object id, 0, 0, 1 (covered)
#else
layout(location = 0) out vec4 out_color;   // radiance, alpha (coverage)
#endif

// No shadow rays in the raster pipeline (option shadows is refused with it).
bool occluded(vec3 p, vec3 l, float dist) { return false; }

// Trilinear (and anisotropic where the texture has it) lookup of slot k, derivatives of the
// unfolded coordinates so the mip level does not jump at a mirror fold. lod0: bilinear at level 0
// only, as the reference reads textures (TEXTURE_LOD0 for the material textures, NORMAL_LOD0 for
// the normal map: options texture_sampling, normal_sampling = lod0).
vec4 lookup(sampler2D t, int has, int set, mat3 xf, int mirror, vec4 fallback, bool lod0) {
    if (has == 0) return fallback;
    vec2 uv = set == 0 ? v_uv0 : v_uv1;
    uv = (xf * vec3(uv, 1.0)).xy;
    vec2 dx = dFdx(uv), dy = dFdy(uv);
    if ((mirror & 1) != 0) uv.x = wrap_mirror(uv.x);
    if ((mirror & 2) != 0) uv.y = wrap_mirror(uv.y);
    return lod0 ? textureLod(t, uv, 0.0) : textureGrad(t, uv, dx, dy);
}

#ifdef HOOK_SPECULAR_AA
// The level textureGrad reads the normal map at (slot 2): textureQueryLod of the unfolded coordinates
// (their derivatives are lookup()'s), 0 with NORMAL_LOD0. Feeds hook_specular_aa only.
float normal_map_lod() {
    if (NORMAL_LOD0 != 0) return 0.0;
    vec2 uv = tex_set[2] == 0 ? v_uv0 : v_uv1;
    return textureQueryLod(tex_normal, (tex_xf[2] * vec3(uv, 1.0)).xy).y;
}
#endif

vec4 slot(sampler2D t, int k, vec4 fallback) {
    bool lod0 = k == 2 ? NORMAL_LOD0 != 0 : TEXTURE_LOD0 != 0;
    return lookup(t, tex_has[k], tex_set[k], tex_xf[k], tex_mirror[k], fallback, lod0);
}

void main() {
    vec4 base = base_factor * slot(tex_base, 0, vec4(1.0)) * v_col;
#if ALPHA_TO_COVERAGE && !AOV_PASS
    float coverage = alpha_to_coverage_sharpen(base.a, alpha_cutoff, fwidth(base.a));
    if (alpha_mode == 1 && coverage <= 0.0) discard;
#else
    if (alpha_mode == 1 && base.a < alpha_cutoff) discard;
#endif
    vec3 N = normalize(v_nrm);
    bool back = !gl_FrontFacing && flip_backface != 0;
    if (back) N = -N;
#if defined(SPECULAR_AA_READS_DN2) && !AOV_PASS
    vec3 dndx = dFdx(N), dndy = dFdy(N);
    float dn2 = dot(dndx, dndx) + dot(dndy, dndy);
#else
    float dn2 = 0.0;
#endif
    float normal_length = 1.0, normal_var = 0.0;
    bool normal_mapped = false;
    vec3 v = normalize(cam_origin - v_pos);
#if AOV_PASS
    out_aov = vec4(N, max(dot(N, v), 0.0));
    out_obj = vec4(object_id, 0.0, 0.0, 1.0);
#else
#if UNLIT_MATERIALS
    if (unlit != 0) {
#if ALPHA_TO_COVERAGE
        out_color = vec4(base.rgb, alpha_mode == 2 ? base.a : (alpha_mode == 1 ? coverage : 1.0));
#else
        out_color = vec4(base.rgb, alpha_mode == 2 ? base.a : 1.0);
#endif
        return;
    }
#endif
    vec3 n = N;
    if (tex_has[2] != 0) {
        vec3 T = v_tan.xyz - dot(v_tan.xyz, N) * N;
        if (back) T = -T;
        float lt = length(T);
        if (lt > 1e-8) {
            T /= lt;
            vec3 B = (back ? -v_tan.w : v_tan.w) * cross(N, T);
            vec3 tn = slot(tex_normal, 2, vec4(0.5, 0.5, 1.0, 1.0)).xyz * 2.0 - 1.0;
            normal_mapped = true;
#if defined(SPECULAR_AA_READS_NORMAL_LENGTH) || defined(HOOK_SPECULAR_AA)
            normal_length = length(tn);
#elif defined(SPECULAR_AA_READS_VARIANCE)
            normal_var = slot(tex_normal_var, 2, vec4(0.0)).r * normal_scale * normal_scale;
#endif
            tn.xy *= normal_scale;
            n = normalize(mat3(T, B, N) * tn);
        }
    }
    vec4 mr = slot(tex_mr, 1, vec4(1.0));
    float metallic = clamp(metallic_factor * mr.b, 0.0, 1.0);
    float roughness = clamp(roughness_factor * mr.g, 0.0, 1.0);
#ifdef HOOK_SPECULAR_AA
    if (normal_mapped) roughness = hook_specular_aa(roughness, normal_length, normal_map_lod());
#elif SPECULAR_AA != SPECULAR_AA_NONE
    roughness = specular_aa(roughness, normal_length, normal_var, dn2);
#endif
#ifdef MATERIAL_LOBES
    {
        // the frame of the lobes' textures and directions: the vertex tangent against the interpolated
        // normal (any perpendicular where the mesh has none), B = w (N x T)
        vec3 Tl = v_tan.xyz - dot(v_tan.xyz, N) * N;
        if (back) Tl = -Tl;
        float ltl = length(Tl);
        Tl = ltl > 1e-8 ? Tl / ltl : normalize(cross(abs(N.x) < 0.9 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0), N));
        vec3 Bl = (back ? -v_tan.w : v_tan.w) * cross(N, Tl);
        vec4 p0 = lobe_p0, p1 = lobe_p1, p2 = lobe_p2, p3 = lobe_p3;
        p0.x *= LOBE_SLOT(0, vec4(1.0)).r;
        p0.y *= LOBE_SLOT(1, vec4(1.0)).g;
        p1.rgb *= LOBE_SLOT(3, vec4(1.0)).rgb;
        p0.z *= LOBE_SLOT(4, vec4(1.0)).a;
        p0.w *= LOBE_SLOT(5, vec4(1.0)).a;
        p2.rgb *= LOBE_SLOT(6, vec4(1.0)).rgb;
        vec3 at = LOBE_SLOT(7, vec4(1.0, 0.5, 1.0, 1.0)).rgb;   // absent: direction +X, strength 1
        p1.w *= at.b;
        p3.x *= LOBE_SLOT(8, vec4(1.0)).r;
        if (lobe_has[9] != 0) p3.z = mix(p3.w, p3.z, LOBE_SLOT(9, vec4(1.0)).g);
        vec2 dir = at.rg * 2.0 - 1.0;
        vec3 Ta = dir.x * Tl + dir.y * Bl;
        // KHR_materials_anisotropy rotates counter-clockwise in tangent-bitangent space, toward Bl =
        // h (N x T), h = +-1 the frame's handedness: that is aniso_direction's turn toward N x Ta with
        // the rotation times h (N x Ta = h (dir.x Bl - dir.y Tl), the quarter turn of Ta in (Tl, Bl)),
        // clockwise about N on a mirrored frame (TANGENT w < 0, or its back face); h = 1 leaves p2.w's bits
        p2.w *= (back ? -v_tan.w : v_tan.w) < 0.0 ? -1.0 : 1.0;
        Ta = length(Ta) > 1e-8 ? normalize(Ta) : Tl;
        g_lobes = lobes_from_rows(p0, p1, p2, p3, n, Ta);
        // the coat's normal: clearcoatNormalTexture in the same frame, else the geometric normal (the
        // base's normal map does not reach the coat: KHR_materials_clearcoat)
        if (lobe_has[2] != 0) {
            vec3 tc = LOBE_SLOT(2, vec4(0.5, 0.5, 1.0, 1.0)).xyz * 2.0 - 1.0;
            tc.xy *= lobe_coat_normal_scale;
            g_lobes.coat_n = normalize(mat3(Tl, Bl, N) * tc);
        } else {
            g_lobes.coat_n = N;
        }
    }
#endif
    uvec2 px = uvec2(gl_FragCoord.xy);
    uint seed = px.y * 65536u + px.x;
    float ao = occlusion_from_texture(lookup(tex_occlusion, ao_has, ao_set, ao_xf, ao_mirror, vec4(1.0),
                                             TEXTURE_LOD0 != 0).r,
                                      ao_strength);
    vec3 radiance = shade(Surface(v_pos, n, v, base.rgb, metallic, roughness, specular_f0, ao, N), seed);
#ifdef TRANSMISSION
    // KHR_materials_transmission and _diffuse_transmission (transmission.glsl transmission_change): the
    // dielectric diffuse replaced by the light from behind; the textures' factor (R) and thickness (G).
    if ((transmission_factor > 0.0 || diffuse_transmission_factor > 0.0) && dot(n, v) > 0.0) {
        float tf = transmission_factor * lookup(tmap[0], tmap_has[0], tmap_set[0], tmap_xf[0], tmap_mirror[0],
                                                vec4(1.0), TEXTURE_LOD0 != 0).r;
        g_thickness = transmission_thickness * lookup(tmap[1], tmap_has[1], tmap_set[1], tmap_xf[1], tmap_mirror[1],
                                                      vec4(1.0), TEXTURE_LOD0 != 0).g;
        radiance += transmission_change(Surface(v_pos, n, v, base.rgb, 0.0, roughness, specular_f0, ao, N), metallic,
                                        tf, seed);
    }
#endif
    radiance += emissive_factor * slot(tex_emissive, 3, vec4(1.0)).rgb;
#if ALPHA_TO_COVERAGE
    // MASK: the sharpened alpha becomes the sample mask (GL_SAMPLE_ALPHA_TO_ONE then writes alpha 1)
    out_color = vec4(radiance, alpha_mode == 2 ? base.a : (alpha_mode == 1 ? coverage : 1.0));
#else
    out_color = vec4(radiance, alpha_mode == 2 ? base.a : 1.0);
#endif
#endif
}
