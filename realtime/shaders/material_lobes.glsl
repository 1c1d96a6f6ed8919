// material_lobes.glsl: the glTF PBR extensions' lobes in the material composition (shading.glsl
// shade_material), compiled only into the programs of scenes whose materials use a lobe
// (realtime.material_lobes.lobe_defines, Filament's MATERIAL_HAS_* style): MATERIAL_LOBES and one
// LOBE_<NAME> per lobe used (LOBE_CLEARCOAT, LOBE_SHEEN, LOBE_SPECULAR, LOBE_ANISOTROPY,
// LOBE_IRIDESCENCE); a program without them keeps none of this file past the preprocessor (realtime.gl
// expands the #include textually inside shading.glsl's #ifdef), and its source is the one it had
// before the lobes existed. Each lobe's engine forms are realtime.registry.LOBE_REGISTRIES'
// switches (lobes_*.glsl; COAT_IBL, COAT_ATTENUATION, SHEEN_DFG, SHEEN_SCALING, ANISOTROPY_BEND,
// IRIDESCENCE) and SHEEN_RADIANCE (below), from the options of realtime/presets.py.
//
// The pipeline fills g_lobes before shade(): the ray-cast pass from its ObjectLobes buffer
// (render.comp, realtime.material_lobes.object_lobe_rows), the raster pass from the draw's
// uniforms and lobe textures (raster.frag). Every lobe at its neutral value leaves the material
// composition's result bit for bit (each term is skipped, or reduces to x * 1 + 0).
//
// Forms (docs/realtime.md "Lobes in the renderer"):
// - specular (KHR_materials_specular): dielectric F0 = min(F0_ior specularColor, 1) specularFactor,
//   F90 = specularFactor (F90 = 1 for metals: mix(F90, 1, metallic)); the split sum F0 A + F90 B;
//   with glTF's blend the diffuse under 1 - max3(dielectric F0).
// - iridescence: the split sum's Fresnel mix(F0, F_iri(n.v), k) A + F90 B (the Sample Viewer's
//   getIBLRadianceGGXIridescence form), F_iri = iridescence_fresnel(1, film ior, n.v, d, F0).
// - anisotropy: the prefiltered lookup along aniso_reflection(n, t, b, v, s, r) (ANISOTROPY_BEND).
// - sheen: base sheen_scaling(c, E) + c sheen_dfg(n.v, r_s, E) L_sheen, E the sheen LUT at
//   (n.v, r_s), L_sheen by SHEEN_RADIANCE.
// - clearcoat: base coat_attenuation(n_c.v, n_c.v, k, F0_c) + coat_ibl_weight(n_c.v, r_c, k, F0_c, A, B)
//   prefiltered(reflect(-v, n_c), r_c) (image-based light has no half vector: the voh form reads n.v).
// Point lights: the base's BRDF (lobes_brdf_eval) with KHR_materials_specular's F0 / F90, the
// anisotropic GGX of KHR_materials_anisotropy (aniso_specular_dv: the README's D and height-correlated
// V at alpha_t = mix(alpha, 1, s^2) along the direction, alpha along n x t) and iridescence's thin-film
// Fresnel at v.h over the dielectric's and the metal's F0 (iridescence_light_fresnel); the sheen's and
// the coat's lobes (lobes_add_light) layered as the image-based terms.
#define SHEEN_RADIANCE_CHARLIE 0
#define SHEEN_RADIANCE_GGX 1
#define SHEEN_RADIANCE_IRRADIANCE 2
#define SHEEN_RADIANCE_NORMAL_ROUGHEST 3
#ifndef SHEEN_RADIANCE
#define SHEEN_RADIANCE SHEEN_RADIANCE_CHARLIE
#endif
#include "lobes_material.glsl"
#ifdef LOBE_CLEARCOAT
#include "lobes_coat.glsl"
#endif
#ifdef LOBE_SHEEN
#include "lobes_sheen.glsl"
#endif
#ifdef LOBE_ANISOTROPY
#include "lobes_anisotropy.glsl"
#endif
#ifdef LOBE_IRIDESCENCE
#include "lobes_iridescence.glsl"
#endif

// One shading point's lobe parameters (world-space directions).
struct MaterialLobes {
    float clearcoat;
    float clearcoat_roughness;
    vec3 coat_n;               // the coat's normal (the geometric / interpolated normal; clearcoatNormalTexture in raster)
    vec3 sheen_color;
    float sheen_roughness;
    float specular_factor;
    vec3 specular_color;
    float anisotropy;          // strength in [0, 1]
    vec3 aniso_t;              // the anisotropy direction (tangent rotated by the rotation), unit
    float iridescence;
    float iridescence_ior;
    float iridescence_thickness;   // nm
};
MaterialLobes g_lobes;
// The point lights' sheen and coat lobes, summed by shading.glsl add_point_lights (lobes_add_light) and
// layered by lobes_layer; shade_material zeroes them (lobes_begin) before its lights.
vec3 g_lobe_sheen_light;
vec3 g_lobe_coat_light;

// The lobe parameters of one object from its 4 packed rows (realtime.material_lobes.LOBE_ROW_LAYOUT):
// p0 = (clearcoat, clearcoat_roughness, sheen_roughness, specular_factor), p1 = (sheen_color, anisotropy
// strength), p2 = (specular_color, anisotropy rotation), p3 = (iridescence, ior, thickness nm, 0);
// n the shading normal, T the tangent (realtime.material_lobes: spheres (-n.y, n.x, 0) normalized, +X at the
// poles, Mitsuba's sphere dp/du; planes plane_frame's tangent). The direction is T rotated by the rotation
// counter-clockwise toward B = n x T (KHR_materials_anisotropy).
MaterialLobes lobes_from_rows(vec4 p0, vec4 p1, vec4 p2, vec4 p3, vec3 n, vec3 T) {
    MaterialLobes m;
    m.clearcoat = p0.x;
    m.clearcoat_roughness = p0.y;
    m.coat_n = n;
    m.sheen_color = p1.rgb;
    m.sheen_roughness = p0.z;
    m.specular_factor = p0.w;
    m.specular_color = p2.rgb;
    m.anisotropy = p1.w;
    m.aniso_t = aniso_direction(T, n, p2.w);
    m.iridescence = p3.x;
    m.iridescence_ior = p3.y;
    m.iridescence_thickness = p3.z;
    return m;
}

float lobes_max3(vec3 c) { return max(max(c.x, c.y), c.z); }

#ifdef LOBE_SHEEN
uniform samplerCube charlie_cube;   // charlie_prefilter.comp: level L at sheen roughness L / charlie_max_lod
uniform float charlie_max_lod;

// The radiance the sheen's image-based weight multiplies (SHEEN_RADIANCE, from the SHEEN_DFG member's
// extra["radiance"] and option sheen_cube): the Charlie cube at lod = r_s charlie_max_lod (Sample Viewer),
// the GGX-prefiltered cube at the sheen roughness (Filament), the irradiance E(n) (three.js), the
// prefiltered cube along n at its roughest level (PlayCanvas).
vec3 sheen_radiance(vec3 n, vec3 r, float sr) {
#if SHEEN_RADIANCE == SHEEN_RADIANCE_GGX
    return prefiltered_radiance(r, sr);
#elif SHEEN_RADIANCE == SHEEN_RADIANCE_IRRADIANCE
    return PI * irradiance_over_pi(n);
#elif SHEEN_RADIANCE == SHEEN_RADIANCE_NORMAL_ROUGHEST
    return textureLod(prefiltered, n, max_lod).rgb;
#else
    return textureLod(charlie_cube, r, sr * charlie_max_lod).rgb;
#endif
}
#endif

// The dielectric F0 (RGB) and F90 of KHR_materials_specular from the core material's F0 (s.specular).
void lobes_dielectric(float f0_ior, out vec3 f0, out float f90) {
#ifdef LOBE_SPECULAR
    f0 = specular_dielectric_f0(f0_ior, g_lobes.specular_factor, g_lobes.specular_color);
    f90 = g_lobes.specular_factor;
#else
    f0 = vec3(f0_ior);
    f90 = 1.0;
#endif
}

// The split sum's specular albedo with the lobes' Fresnel: F A + F90 B, F = F0 or the iridescent mix.
vec3 lobes_spec_albedo(vec3 F0, float F90, float NoV, vec2 AB) {
#if defined(LOBE_IRIDESCENCE) && IRIDESCENCE != IRIDESCENCE_NONE
    float k = iridescence_factor(g_lobes.iridescence, g_lobes.iridescence_thickness);
    if (k > 0.0) {
        vec3 Fi = iridescence_fresnel(1.0, g_lobes.iridescence_ior, NoV, g_lobes.iridescence_thickness, F0);
        F0 = iridescence_mix(F0, Fi, k);
    }
#endif
#ifdef LOBE_SPECULAR
    return split_sum_albedo_f90(F0, F90, AB.x, AB.y);
#else
    return F0 * AB.x + AB.y;   // F90 = 1: the core's split sum, term for term
#endif
}

#ifdef LOBE_ANISOTROPY
// The anisotropy direction projected into the plane of the shading normal n (unit): t of the frame
// (t, n x t, n) both the bent lookup and the lights' anisotropic GGX use.
vec3 lobes_aniso_tangent(vec3 n) {
    return normalize(g_lobes.aniso_t - dot(g_lobes.aniso_t, n) * n);
}
#endif

// The prefiltered lookup's direction: reflect(-v, n), or the bent reflection of the anisotropy.
vec3 lobes_reflection(vec3 r, vec3 n, vec3 v, float roughness) {
#ifdef LOBE_ANISOTROPY
    if (g_lobes.anisotropy > 0.0) {
        vec3 t = lobes_aniso_tangent(n);
        return aniso_reflection(n, t, cross(n, t), v, g_lobes.anisotropy, roughness);
    }
#endif
    return r;
}

// Whether a light's base BRDF departs from brdf_eval's (lobes_brdf_eval is needed): an anisotropic
// strength or an iridescent film present (without KHR_materials_specular, shading.glsl calls brdf_eval
// elsewhere, so a neutral anisotropy or iridescence keeps the lobe-free program's bits).
bool lobes_light_active() {
    bool on = false;
#ifdef LOBE_ANISOTROPY
    on = on || g_lobes.anisotropy > 0.0;
#endif
#if defined(LOBE_IRIDESCENCE) && IRIDESCENCE != IRIDESCENCE_NONE
    on = on || iridescence_factor(g_lobes.iridescence, g_lobes.iridescence_thickness) > 0.0;
#endif
    return on;
}

// KHR_materials_specular's point-light BRDF (brdf.glsl brdf_eval with the dielectric's RGB F0 and F90):
// f = (1 - Fd)(1 - metallic) base / pi + D G F / (4 (n.l)(n.v)), F = Schlick(v.h; mix(F0_d, base, metallic),
// mix(F90_d, 1, metallic)); Fd = max3 of the dielectric's own Schlick(v.h; F0_d, F90_d) under glTF's
// blend (the README's dielectric_brdf weights the diffuse by 1 - max3(dielectric_fresnel)), F otherwise.
// With an iridescent film, F_d and the metal's F each mixed with the film at v.h over their own F0
// (iridescence_light_fresnel); with an anisotropy, D G / (4 (n.l)(n.v)) is the README's anisotropic
// D V (aniso_specular_dv) in the IBL path's frame (lobes_aniso_tangent).
vec3 lobes_brdf_eval(vec3 n, vec3 v, vec3 l, vec3 base_color, float metallic, float roughness, float f0_ior) {
    float NoV = dot(n, v);
    float NoL = dot(n, l);
    if (NoV <= 0.0 || NoL <= 0.0) return vec3(0.0);
    vec3 f0;
    float f90;
    lobes_dielectric(f0_ior, f0, f90);
    // brdf_eval's operations, term for term (a neutral specular lobe gives its bits)
    vec3 h = v + l;
    h = h / max(length(h), COS_EPS);
    float NoH = clamp(dot(n, h), 0.0, 1.0);
    float VoH = clamp(dot(v, h), 0.0, 1.0);
#if FRESNEL == FRESNEL_SCHLICK
    vec3 F = F_Schlick(VoH, mix(f0, base_color, metallic), specular_f90_blend(f90, metallic));
#else
    vec3 F = fresnel_term(VoH, mix(f0, base_color, metallic));
#endif
    float D = ndf_term(NoH, roughness);
    float G = geometry_term(NoV, NoL, roughness);
    vec3 spec = D * G * F / (4.0 * max(NoV, COS_EPS) * max(NoL, COS_EPS));
#if defined(METALLIC_BLEND_GLTF) && FRESNEL == FRESNEL_SCHLICK
    vec3 Fd = vec3(lobes_max3(F_Schlick(VoH, f0, f90)));
#elif defined(METALLIC_BLEND_GLTF)
    vec3 Fd = fresnel_term(VoH, f0);
#else
    vec3 Fd = F;
#endif
#if defined(LOBE_IRIDESCENCE) && IRIDESCENCE != IRIDESCENCE_NONE && FRESNEL == FRESNEL_SCHLICK
    // KHR_materials_iridescence: the dielectric's and the metal's Fresnel each mixed with the film over
    // its own F0 at v.h, then blended by metallic (a factor 0 or a zero film keeps the lines above' bits)
    float k_iri = iridescence_factor(g_lobes.iridescence, g_lobes.iridescence_thickness);
    if (k_iri > 0.0) {
        vec3 Fd_i = iridescence_light_fresnel(VoH, f0, f90, g_lobes.iridescence_ior, g_lobes.iridescence_thickness, k_iri);
        vec3 Fm_i = iridescence_light_fresnel(VoH, base_color, 1.0, g_lobes.iridescence_ior, g_lobes.iridescence_thickness, k_iri);
        F = mix(Fd_i, Fm_i, metallic);
#ifdef METALLIC_BLEND_GLTF
        Fd = vec3(lobes_max3(Fd_i));
#else
        Fd = F;
#endif
        spec = D * G * F / (4.0 * max(NoV, COS_EPS) * max(NoL, COS_EPS));
    }
#endif
#ifdef LOBE_ANISOTROPY
    // KHR_materials_anisotropy: the README's anisotropic D V in place of D G / (4 (n.v)(n.l)) (strength 0
    // keeps the isotropic terms above, bit for bit)
    if (g_lobes.anisotropy > 0.0) {
        vec3 t = lobes_aniso_tangent(n);
        spec = aniso_specular_dv(n, t, cross(n, t), v, l, alpha_from_roughness(roughness), g_lobes.anisotropy) * F;
    }
#endif
    vec3 diff = (1.0 - Fd) * (1.0 - metallic) * base_color * Fd_Lambert();
    return diff + spec;
}

void lobes_begin() {
    g_lobe_sheen_light = vec3(0.0);
    g_lobe_coat_light = vec3(0.0);
}

// One light's sheen and coat lobes (direction l, irradiance E at normal incidence): the sheen's
// sheenColor D_Charlie V_Charlie (n.l) (KHR_materials_sheen, every SHEEN_DFG form: the engines' point-light
// sheen is the spec's lobe, their forms differ in the image-based term), the coat's clearcoat Fc D_GGX
// V_GGX (n_c.l) at the coat's alpha (height-correlated Smith), Fc at n_c.v or, with COAT_ATTENUATION_VOH,
// at v.h (the Sample Viewer's punctual coat).
void lobes_add_light(vec3 n, vec3 v, vec3 l, vec3 E) {
#ifdef LOBE_SHEEN
    if (lobes_max3(g_lobes.sheen_color) > 0.0) {
        float NoL = dot(n, l);
        if (NoL > 0.0) {
            vec3 h = normalize(v + l);
            float a = max(g_lobes.sheen_roughness * g_lobes.sheen_roughness, SHEEN_MIN_ALPHA);
            float NoV = clamp(dot(n, v), 1e-4, 1.0);
            g_lobe_sheen_light += g_lobes.sheen_color * (D_Charlie(max(dot(n, h), 0.0), a) * V_Charlie(NoV, NoL, a) * NoL) * E;
        }
    }
#endif
#ifdef LOBE_CLEARCOAT
    if (g_lobes.clearcoat > 0.0) {
        vec3 nc = g_lobes.coat_n;
        float NcoL = dot(nc, l);
        float NcoV = clamp(dot(nc, v), 1e-4, 1.0);
        if (NcoL > 0.0) {
            vec3 h = normalize(v + l);
            float a = alpha_from_roughness(g_lobes.clearcoat_roughness);
#if COAT_ATTENUATION == COAT_ATTENUATION_VOH
            float Fc = coat_fresnel(max(dot(v, h), 0.0), coat_f0(1.5));
#else
            float Fc = coat_fresnel(NcoV, coat_f0(1.5));
#endif
            float f = D_GGX(max(dot(nc, h), 0.0), a) * G_SmithGGXCorrelated(NcoV, NcoL, a) / (4.0 * NcoV * NcoL);
            g_lobe_coat_light += (g_lobes.clearcoat * Fc * f * NcoL) * E;
        }
    }
#endif
}

// The layers above the base: sheen, then the coat over both (KHR_materials_sheen / _clearcoat
// "Layering": coat over sheen over the base). base = the material's outgoing radiance.
vec3 lobes_layer(vec3 base, vec3 n, vec3 v, float NoV) {
    vec3 color = base;
#ifdef LOBE_SHEEN
    if (lobes_max3(g_lobes.sheen_color) > 0.0) {
        float sr = g_lobes.sheen_roughness;
        vec3 E = sheen_lut_lookup(NoV, sr);
        vec3 r = 2.0 * dot(n, v) * n - v;
        color = color * sheen_scaling(g_lobes.sheen_color, E)
                + g_lobes.sheen_color * sheen_dfg(NoV, sr, E) * sheen_radiance(n, r, sr) + g_lobe_sheen_light;
    }
#endif
#ifdef LOBE_CLEARCOAT
    if (g_lobes.clearcoat > 0.0) {
        vec3 nc = g_lobes.coat_n;
        float NcoVr = dot(nc, v);
        float NcoV = clamp(NcoVr, 1e-4, 1.0);
        float cr = g_lobes.clearcoat_roughness;
        float f0 = coat_f0(1.5);   // KHR_materials_clearcoat: the coat's IOR is 1.5
        vec2 AB = dfg(NcoV, cr);
        vec3 rc = 2.0 * NcoVr * nc - v;
        color = color * coat_attenuation(NcoV, NcoV, g_lobes.clearcoat, f0)
                + coat_ibl_weight(NcoV, cr, g_lobes.clearcoat, f0, AB.x, AB.y) * prefiltered_radiance(rc, cr)
                + g_lobe_coat_light;
    }
#endif
    return color;
}
