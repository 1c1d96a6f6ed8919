// render.comp: pass "frame". One invocation per output pixel: ray-traces the analytic spheres and
// rectangles with `ss` x `ss` sub-pixel samples at (k + 0.5)/ss (box filter), plus one ray through
// the pixel centre for the AOVs (normal, n.v, object), exactly pbrcheck.camera.primary_rays.
// Row 0 of the images is the top of the picture (gl_GlobalInvocationID.y = row).
//
// SHADING_MATERIAL:: the README material model: split-sum specular prefiltered(r, lod) (F0 A + B),
//   diffuse (1 - metallic) base (1 - F0) Kd(n.v) E(n)/pi, exact BRDF for point lights. With
//   IBL_RUNTIME the specular is runtime importance sampling of the environment instead (the same
//   integrand, without the split sum's v = n = r and product split: pbrcheck explain's v=n=r row).
// SHADING_ARTICLE000:: article 000's PBR.frag (listings 1 and 4, with their mistakes).
// SHADING_ARTICLE001:: runtime importance sampling of the environment (article 001).
// SHADING_ARTICLE002:: article 002's lerp composition with EnvBRDFApprox.
layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;
#include "env.glsl"
#include "sampling.glsl"
#include "ibl.glsl"
#include "energy.glsl"

layout(rgba32f, binding = 0) writeonly uniform image2D out_color;   // rgb, coverage
layout(rgba32f, binding = 1) writeonly uniform image2D out_aov;     // N.xyz, NdotV (centre ray)
layout(r32f, binding = 2) writeonly uniform image2D out_object;     // object id, -1 background

struct Obj { vec4 a; vec4 b; vec4 c; vec4 d; vec4 e; vec4 f; };
// a: centre.xyz, type (0 sphere, 1 rectangle); b: normal.xyz, radius; c: tangent.xyz, size.x;
// d: bitangent.xyz, size.y; e: base_color.rgb, metallic; f: roughness, specular, id, 0
layout(std430, binding = 0) readonly buffer Objects { Obj objs[]; };
layout(std430, binding = 1) readonly buffer Lights { vec4 lights[]; };  // position, intensity pairs
uniform int n_objects;
uniform int n_lights;
uniform vec3 cam_origin;
uniform vec3 cam_right;    // right * tan_x
uniform vec3 cam_up;       // true_up * tan_y
uniform vec3 cam_forward;
uniform ivec2 image_size;
uniform int ss;

uniform samplerCube prefiltered;
uniform samplerCube irradiance_cube;
uniform samplerCube env_cube;      // radiance cube with box-filtered mips (runtime sampling)
uniform sampler2D dfg_lut;
uniform sampler2D kd_lut;
uniform vec3 sh[9];
uniform float max_lod;
uniform float cube_log2;
uniform float env_face_size;
uniform int runtime_samples;
uniform float min_roughness;
uniform float lod_override;   // >= 0: every prefiltered lookup at this level (fit-lod's scan)

const float T_EPS = 1e-4;

bool intersect(int k, vec3 o, vec3 d, out float t) {
    Obj ob = objs[k];
    t = 1e30;
    if (ob.a.w < 0.5) {
        vec3 oc = o - ob.a.xyz;
        float b = dot(oc, d);
        float c = dot(oc, oc) - ob.b.w * ob.b.w;
        float disc = b * b - c;
        if (disc < 0.0) return false;
        float s = sqrt(disc);
        float t0 = -b - s;
        if (t0 < T_EPS) t0 = -b + s;
        if (t0 < T_EPS) return false;
        t = t0;
        return true;
    }
    float den = dot(d, ob.b.xyz);
    if (abs(den) < 1e-12) return false;
    float t0 = dot(ob.a.xyz - o, ob.b.xyz) / den;
    if (t0 < T_EPS) return false;
    vec3 q = o + t0 * d - ob.a.xyz;
    if (abs(dot(q, ob.c.xyz)) > 0.5 * ob.c.w || abs(dot(q, ob.d.xyz)) > 0.5 * ob.d.w) return false;
    t = t0;
    return true;
}

int trace(vec3 o, vec3 d, out float tbest) {
    tbest = 1e30;
    int hit = -1;
    for (int k = 0; k < n_objects; ++k) {
        float t;
        if (intersect(k, o, d, t) && t < tbest) { tbest = t; hit = k; }
    }
    return hit;
}

bool occluded(vec3 p, vec3 l, float dist) {
#if SHADOWS
    for (int k = 0; k < n_objects; ++k) {
        float t;
        if (intersect(k, p, l, t) && t < dist) return true;
    }
#endif
    return false;
}

vec3 normal_at(int k, vec3 p) {
    Obj ob = objs[k];
    return ob.a.w < 0.5 ? normalize(p - ob.a.xyz) : ob.b.xyz;
}

vec3 irradiance_over_pi(vec3 n) {
#ifdef HOOK_DIFFUSE_IBL
    return hook_diffuse_ibl(n);
#elif IRRADIANCE == IRRADIANCE_SH9
    return sh9_eval(sh, n);
#else
    return textureLod(irradiance_cube, n, 0.0).rgb;
#endif
}

vec2 dfg(float NoV, float roughness) {
#ifdef HOOK_DFG
    return hook_dfg(NoV, roughness);
#elif DFG == DFG_ANALYTIC
    return EnvBRDFApprox(NoV, roughness);
#else
    return dfg_lookup(dfg_lut, NoV, roughness);
#endif
}

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

// Runtime importance sampling of the environment (article 001). RUNTIME_SAMPLING: _BECKMANN
// (the article: Beckmann half vectors for the GGX D), _GGX, _VNDF (GGX visible normals).
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
#if RUNTIME_SAMPLING == RUNTIME_SAMPLING_BECKMANN
        vec3 ht = sample_Beckmann(u, alpha);
#elif RUNTIME_SAMPLING == RUNTIME_SAMPLING_GGX
        vec3 ht = sample_GGX(u, alpha);
#elif RUNTIME_SAMPLING == RUNTIME_SAMPLING_VNDF
        vec3 ht = sample_GGX_VNDF(u.yx, vt, alpha);
#endif
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
#if RUNTIME_SAMPLING == RUNTIME_SAMPLING_VNDF
        acc += F * G / max(G1_SmithGGX(NoV, alpha), COS_EPS) * L;
#else
        // The article's estimator: F G L (v.h) / ((n.h)(n.v)), correct only for pdf = D_GGX (n.h).
        acc += F * G * L * VoH / (NoH * NoV);
#endif
    }
    return acc / float(ns);
}

vec3 shade(int k, vec3 p, vec3 n, vec3 v, uint pixel_seed) {
    Obj ob = objs[k];
    vec3 base = ob.e.rgb;
    float metallic = ob.e.a;
    float roughness = max(ob.f.x, min_roughness);
    float spec_level = ob.f.y;
    float NoVr = dot(n, v);
    if (NoVr <= 0.0) return vec3(0.0);  // back side of a one-sided surface
    float NoV = clamp(NoVr, 1e-4, 1.0);
    vec3 r = 2.0 * NoVr * n - v;
    vec3 color = vec3(0.0);

#if SHADING == SHADING_MATERIAL
    vec3 F0 = mix(vec3(spec_level), base, metallic);
#if FRESNEL == FRESNEL_SCHLICK
    vec3 kd = (1.0 - F0) * texture(kd_lut, vec2(NoV, 0.5)).r;
#else
    vec3 kd = vec3(0.0);
#endif
#ifdef HOOK_SPECULAR_IBL
    color += hook_specular_ibl(n, v, roughness, F0);
#elif IBL_RUNTIME
    color += runtime_specular(n, v, roughness, F0, pixel_seed);
#else
    vec2 AB = dfg(NoV, roughness);
#if FRESNEL == FRESNEL_SCHLICK
    vec3 spec_albedo = F0 * AB.x + AB.y;
#else
    vec3 spec_albedo = vec3(AB.x + AB.y);
#endif
#if FRESNEL == FRESNEL_SCHLICK
    vec3 F0e = F0;
#else
    vec3 F0e = vec3(1.0);
#endif
    // Multiple-scattering energy compensation (energy.glsl): a scale of the split sum's specular
    // (Filament) or a multiply scattered albedo times the irradiance (Fdez-Aguera, Kulla-Conty).
#ifdef HOOK_ENERGY_COMPENSATION
    color += prefiltered_radiance(r, roughness) * spec_albedo * hook_energy_compensation(F0e, AB.x, AB.y, roughness);
#else
    color += prefiltered_radiance(r, roughness) * spec_albedo * energy_scale(F0e, AB.x, AB.y);
    color += irradiance_over_pi(n) * energy_ms(F0e, AB.x, AB.y, roughness);
#endif
#endif
    color += (1.0 - metallic) * base * kd * irradiance_over_pi(n);
    for (int i = 0; i < n_lights; ++i) {
        vec3 ld = lights[2 * i].xyz - p;
        float d2 = dot(ld, ld);
        vec3 l = ld * inversesqrt(d2);
        float NoL = dot(n, l);
        if (NoL <= 0.0 || occluded(p, l, sqrt(d2))) continue;
        vec3 f = brdf_eval(n, v, l, base, metallic, roughness, spec_level);
#if defined(HOOK_ENERGY_COMPENSATION) && !IBL_RUNTIME && !defined(HOOK_SPECULAR_IBL)
        // The user's compensation factor scales the point light's specular lobe as it does the IBL's.
        f += (hook_energy_compensation(F0e, AB.x, AB.y, roughness) - 1.0)
             * brdf_eval(n, v, l, F0, 1.0, roughness, spec_level);
#elif ENERGY_COMPENSATION != ENERGY_COMPENSATION_NONE && !IBL_RUNTIME && !defined(HOOK_SPECULAR_IBL)
        // Multiple scattering for the point light (energy.glsl): brdf_eval with metallic 1 and base
        // F0 is the specular lobe alone. (AB exists with the built-in split sum only.)
        vec2 ABl = dfg(clamp(NoL, 1e-4, 1.0), roughness);
        f += energy_direct(brdf_eval(n, v, l, F0, 1.0, roughness, spec_level), F0e, AB.x, AB.y, ABl.x + ABl.y,
                           roughness);
#endif
        color += f * lights[2 * i + 1].rgb * (NoL / d2);
    }

#elif SHADING == SHADING_ARTICLE000
    // Article 000. Listing 1 (direct): kD = 1 - F (no metallic factor), + 0.001 in the denominator,
    // G with k = (roughness + 1)^2 / 8. Listing 4 (IBL): F = F_Schlick(n.v), kD = (1 - F)(1 - metallic),
    // specular = prefiltered x (F A + B) (F, not F0).
    vec3 F0 = mix(vec3(spec_level), base, metallic);
    float alpha = alpha_from_roughness(roughness);
    for (int i = 0; i < n_lights; ++i) {
        vec3 ld = lights[2 * i].xyz - p;
        float d2 = dot(ld, ld);
        vec3 l = ld * inversesqrt(d2);
        float LdotN = max(dot(n, l), 0.0);
        if (LdotN <= 0.0 || occluded(p, l, sqrt(d2))) continue;
        vec3 h = normalize(l + v);
        vec3 Li = lights[2 * i + 1].rgb / d2;
        vec3 fLambert = base / PI;
        float D = D_GGX(max(dot(n, h), 0.0), alpha);
        vec3 F = F_Schlick(max(dot(v, h), 0.0), F0);
        float G = G_SchlickGGX(NoV, LdotN, k_schlick_direct(roughness));
        vec3 fCT = (D * F * G) / (4.0 * NoV * LdotN + 0.001);
        vec3 kD = 1.0 - F;
        color += (kD * fLambert + fCT) * Li * LdotN;
    }
    vec3 F = F_Schlick(NoV, F0);
    vec3 kD = (1.0 - F) * (1.0 - metallic);
    vec3 indirectDiffuse = irradiance_over_pi(n) * base;
    vec2 envBRDF = dfg(NoV, roughness);
    vec3 indirectSpecular = prefiltered_radiance(r, roughness) * (F * envBRDF.x + envBRDF.y);
    color += kD * indirectDiffuse + indirectSpecular;

#elif SHADING == SHADING_ARTICLE001
    // Article 001: F0 clamped to [0.02, 0.99], roughness >= min_roughness (0.01), runtime-sampled
    // specular, diffuse = irradiance x base / pi (our irradiance cube already holds E / pi).
    vec3 F0 = clamp(mix(vec3(spec_level), base, metallic), 0.02, 0.99);
    color += runtime_specular(n, v, roughness, F0, pixel_seed);
    color += (1.0 - metallic) * base * irradiance_over_pi(n);
    for (int i = 0; i < n_lights; ++i) {
        vec3 ld = lights[2 * i].xyz - p;
        float d2 = dot(ld, ld);
        vec3 l = ld * inversesqrt(d2);
        float NoL = dot(n, l);
        if (NoL <= 0.0 || occluded(p, l, sqrt(d2))) continue;
        vec3 h = normalize(l + v);
        float NoH = max(dot(n, h), 0.0);
        float VoH = max(dot(v, h), 0.0);
#if FRESNEL == FRESNEL_SCHLICK
        vec3 F = F_Schlick(VoH, F0);
#elif SHADING == SHADING_ARTICLE002
        vec3 F = vec3(1.0);
#endif
        vec3 fs = ndf_term(NoH, roughness) * geometry_term(NoV, NoL, roughness) * F / (4.0 * NoV * NoL);
        color += ((1.0 - metallic) * base / PI + fs) * lights[2 * i + 1].rgb * (NoL / d2);
    }

#else
    // Article 002: f0 = max(albedo x metalness, 0.04); output = lerp(diffuse, specular, EnvBRDFApprox).
    vec3 f0 = max(base * metallic, vec3(0.04));
#if REFLECT_BUG
    vec3 rr = v - 2.0 * dot(n, v) * n;   // reflect(v, n) with v towards the eye: -r (the article's)
#else
    vec3 rr = r;
#endif
    vec3 diffuse = base * irradiance_over_pi(n) * (1.0 - metallic);
    vec3 specular = prefiltered_radiance(rr, roughness);
    vec2 AB = dfg(NoV, roughness);
    vec3 t = f0 * AB.x + AB.y;
    color += mix(diffuse, specular, t);
    for (int i = 0; i < n_lights; ++i) {
        vec3 ld = lights[2 * i].xyz - p;
        float d2 = dot(ld, ld);
        vec3 l = ld * inversesqrt(d2);
        float NoL = dot(n, l);
        if (NoL <= 0.0 || occluded(p, l, sqrt(d2))) continue;
        // D_Approx (appendix), UE4 mobile's fitted Phong lobe: rcp_a2 exp2(c RoL - c).
        float a = roughness * roughness;
        float a2 = max(a * a, 1e-8);
        float c = 0.72134752 / a2 + 0.39674113;
        float Dap = exp2(c * dot(r, l) - c) / a2;
        color += ((1.0 - metallic) * base / PI + t * Dap / PI) * lights[2 * i + 1].rgb * (NoL / d2);
    }
#endif
    return color;
}

void main() {
    ivec2 g = ivec2(gl_GlobalInvocationID.xy);
    if (g.x >= image_size.x || g.y >= image_size.y) return;
    vec3 acc = vec3(0.0);
    float covered = 0.0;
    uint seed = uint(g.y * image_size.x + g.x);
    for (int sy = 0; sy < ss; ++sy)
        for (int sx = 0; sx < ss; ++sx) {
            vec2 off = (vec2(sx, sy) + 0.5) / float(ss);
            float x = 2.0 * (float(g.x) + off.x) / float(image_size.x) - 1.0;
            float y = 1.0 - 2.0 * (float(g.y) + off.y) / float(image_size.y);
            vec3 d = normalize(cam_forward + x * cam_right + y * cam_up);
            float t;
            int k = trace(cam_origin, d, t);
            if (k < 0) {
                acc += env_radiance(d);
            } else {
                vec3 p = cam_origin + t * d;
                acc += shade(k, p, normal_at(k, p), -d, seed);
                covered += 1.0;
            }
        }
    float inv = 1.0 / float(ss * ss);
    imageStore(out_color, g, vec4(acc * inv, covered * inv));
    // AOVs at the pixel centre.
    float x = 2.0 * (float(g.x) + 0.5) / float(image_size.x) - 1.0;
    float y = 1.0 - 2.0 * (float(g.y) + 0.5) / float(image_size.y);
    vec3 d = normalize(cam_forward + x * cam_right + y * cam_up);
    float t;
    int k = trace(cam_origin, d, t);
    if (k < 0) {
        imageStore(out_aov, g, vec4(0.0));
        imageStore(out_object, g, vec4(-1.0));
    } else {
        vec3 n = normal_at(k, cam_origin + t * d);
        imageStore(out_aov, g, vec4(n, max(dot(n, -d), 0.0)));
        imageStore(out_object, g, vec4(objs[k].f.z));
    }
}
