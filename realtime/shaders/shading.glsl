// shading.glsl: the shading of one surface point, shared by every pipeline that finds hits (the
// compute pass render.comp ray-casts the analytic shapes; a raster pass can include this module
// unchanged). Entry point: vec3 shade(Surface s, uint pixel_seed), the outgoing radiance towards
// s.v. SHADING (a constant of pbrcheck.registry.SHADINGS) picks one composition, one function each,
// through shade_composition() and light_brdf() (shading_dispatch.glsl, generated from the registry):
//
// shade_material:: the README material model: split-sum specular prefiltered(r, lod) (F0 A + B),
//   diffuse (1 - metallic) base (1 - F0) Kd(n.v) E(n)/pi (METALLIC_BLEND_GLTF: 1 - specular, glTF's
//   dielectric F0, in place of 1 - F0), exact BRDF for point lights. With
//   IBL_RUNTIME the specular is runtime importance sampling of the environment instead (the same
//   integrand, without the split sum's v = n = r and product split: pbrcheck explain's v=n=r row).
//   The surface's occlusion scales the diffuse image-based term (glTF 2.0 3.9.4) and
//   specular_occlusion() and horizon_occlusion() (occlusion.glsl) the split-sum specular; the article
//   compositions ignore both. MATERIAL_LOBES (defined only for scenes whose materials use a glTF
//   PBR extension's lobe, realtime.material_lobes): material_lobes.glsl's specular, iridescence,
//   anisotropy, sheen and coat around this composition (docs/realtime.md "Lobes in the renderer").
// shade_article000:: article 000's PBR.frag (listings 1 and 4, with their mistakes).
// shade_article001:: runtime importance sampling of the environment (article 001).
// shade_article002:: article 002's lerp composition with EnvBRDFApprox.
//
// Each composition adds its image-based term and the lights of add_point_lights, the one light loop
// (point, spot and directional lights: lights.glsl), which weights the composition's point-light
// BRDF (light_brdf_<composition>) by the light's irradiance. The including pipeline provides
// `bool occluded(vec3 p, vec3 l, float dist)` (shadow rays, a shadow map, or always false) and
// binds the Lights buffer and the uniforms below.
#include "environment_light.glsl"
#include "energy.glsl"
#include "lights.glsl"
#include "occlusion.glsl"
#ifdef MATERIAL_LOBES
#include "material_lobes.glsl"
#endif

layout(std430, binding = 1) readonly buffer Lights { vec4 lights[]; };  // 3 vec4 per light (lights.glsl)
uniform int n_lights;
uniform sampler2D kd_lut;
uniform float min_roughness;

bool occluded(vec3 p, vec3 l, float dist);

// A surface point as the pipeline found it: world position, unit normal, unit direction towards the
// eye, and the material (README "Material model").
struct Surface {
    vec3 p;
    vec3 n;
    vec3 v;
    vec3 base_color;
    float metallic;
    float roughness;
    float specular;
    float occlusion;   // ambient occlusion of the image-based light, 1: none (glTF occlusionTexture)
    vec3 ng;           // geometric normal (interpolated vertex normal; n without a normal map)
};

// What a composition's image-based term leaves to its point-light BRDF.
struct Shading {
    Surface s;
    float roughness;   // s.roughness clamped to >= min_roughness
    float NoV;         // n.v clamped to [1e-4, 1]
    vec3 r;            // mirror direction 2 (n.v) n - v
    vec3 F0;           // the composition's specular colour at normal incidence
    vec3 F0e;          // material: F0 for the energy compensation (1 with FRESNEL_NONE)
    vec2 AB;           // material (split sum): the DFG terms; article 002: (A, B) of EnvBRDFApprox
    vec3 t;            // article 002: the lerp weight f0 A + B
};

// Source: README "Material model" (brdf_eval), with the split sum's energy compensation
// (energy.glsl) or the user's hook_energy_compensation scaling the specular lobe as for the IBL.
vec3 light_brdf_material(Shading c, vec3 l, float NoL) {
    Surface s = c.s;
#ifdef LOBE_SPECULAR
    vec3 f = lobes_brdf_eval(s.n, s.v, l, s.base_color, s.metallic, c.roughness, s.specular);
#elif defined(LOBE_ANISOTROPY) || defined(LOBE_IRIDESCENCE)
    // the anisotropic GGX / the thin film where present (material_lobes.glsl), brdf_eval's bits elsewhere
    vec3 f = lobes_light_active() ? lobes_brdf_eval(s.n, s.v, l, s.base_color, s.metallic, c.roughness, s.specular)
                                  : brdf_eval(s.n, s.v, l, s.base_color, s.metallic, c.roughness, s.specular);
#else
    vec3 f = brdf_eval(s.n, s.v, l, s.base_color, s.metallic, c.roughness, s.specular);
#endif
    // The specular lobe alone (metallic 1, F0 = c.F0) that the compensation scales: with an anisotropy or
    // a film present, the lobes' (their anisotropic GGX, their film over c.F0), brdf_eval's otherwise.
#if defined(LOBE_ANISOTROPY) || defined(LOBE_IRIDESCENCE)
#define LIGHT_SPEC_LOBE (lobes_light_active() ? lobes_brdf_eval(s.n, s.v, l, c.F0, 1.0, c.roughness, s.specular) : brdf_eval(s.n, s.v, l, c.F0, 1.0, c.roughness, s.specular))
#else
#define LIGHT_SPEC_LOBE brdf_eval(s.n, s.v, l, c.F0, 1.0, c.roughness, s.specular)
#endif
#if defined(HOOK_ENERGY_COMPENSATION) && !IBL_RUNTIME && !defined(HOOK_SPECULAR_IBL)
    // The user's compensation factor scales the point light's specular lobe as it does the IBL's.
    f += (hook_energy_compensation(c.F0e, c.AB.x, c.AB.y, c.roughness) - 1.0)
         * LIGHT_SPEC_LOBE;
#elif ENERGY_COMPENSATION != ENERGY_COMPENSATION_NONE && !IBL_RUNTIME && !defined(HOOK_SPECULAR_IBL)
    // Multiple scattering for the point light (energy.glsl): brdf_eval with metallic 1 and base
    // F0 is the specular lobe alone. (AB exists with the built-in split sum only.)
    vec2 ABl = dfg(clamp(NoL, 1e-4, 1.0), c.roughness);
    f += energy_direct(LIGHT_SPEC_LOBE, c.F0e, c.AB.x, c.AB.y, ABl.x + ABl.y, c.roughness);
#endif
#undef LIGHT_SPEC_LOBE
    return f;
}

// Source: article 000, listing 1 (direct): kD = 1 - F (no metallic factor), + 0.001 in the
// denominator, G with k = (roughness + 1)^2 / 8. Equation: kD base / pi + D F G / (4 (n.v)(n.l) + 0.001).
vec3 light_brdf_article000(Shading c, vec3 l, float NoL) {
    Surface s = c.s;
    vec3 h = normalize(l + s.v);
    vec3 fLambert = s.base_color / PI;
    float D = D_GGX(max(dot(s.n, h), 0.0), alpha_from_roughness(c.roughness));
    vec3 F = F_Schlick(max(dot(s.v, h), 0.0), c.F0);
    float G = G_SchlickGGX(c.NoV, NoL, k_schlick_direct(c.roughness));
    vec3 fCT = (D * F * G) / (4.0 * c.NoV * NoL + 0.001);
    vec3 kD = 1.0 - F;
    return kD * fLambert + fCT;
}

// Source: article 001 (Cook-Torrance with the selected D, G, F). Equation:
// (1 - metallic) base / pi + D G F / (4 (n.v)(n.l)), F0 clamped to [0.02, 0.99].
vec3 light_brdf_article001(Shading c, vec3 l, float NoL) {
    Surface s = c.s;
    vec3 h = normalize(l + s.v);
    float NoH = max(dot(s.n, h), 0.0);
    float VoH = max(dot(s.v, h), 0.0);
    vec3 F = fresnel_term(VoH, c.F0);
    vec3 fs = ndf_term(NoH, c.roughness) * geometry_term(c.NoV, NoL, c.roughness) * F / (4.0 * c.NoV * NoL);
    return (1.0 - s.metallic) * s.base_color / PI + fs;
}

// Source: article 002, appendix: D_Approx, UE4 mobile's fitted Phong lobe rcp_a2 exp2(c RoL - c),
// weighted by the lerp weight t = f0 A + B. Equation: (1 - metallic) base / pi + t D_Approx / pi.
vec3 light_brdf_article002(Shading c, vec3 l, float NoL) {
    Surface s = c.s;
    float a = c.roughness * c.roughness;
    float a2 = max(a * a, 1e-8);
    float k = 0.72134752 / a2 + 0.39674113;
    float Dap = exp2(k * dot(c.r, l) - k) / a2;
    return (1.0 - s.metallic) * s.base_color / PI + c.t * Dap / PI;
}

// The selected composition's point-light BRDF light_brdf_<name> (defined with shade_composition
// in shading_dispatch.glsl, generated from pbrcheck.registry.SHADINGS, included below).
vec3 light_brdf(Shading c, vec3 l, float NoL);

// The one light loop: color + sum over the unoccluded lights above the horizon of f(l) I (n.l) / d^2
// (point), the same times spot_attenuation (spot), f(l) E (n.l) with l = -direction (directional);
// f the composition's point-light BRDF. A directional light's shadow ray is unbounded.
vec3 add_point_lights(vec3 color, Shading c) {
    for (int i = 0; i < n_lights; ++i) {
        vec4 pos_type = lights[3 * i];
        vec4 intensity = lights[3 * i + 1];
        vec4 dir = lights[3 * i + 2];
        vec3 l;
        float d2;
        if (int(pos_type.w) == LIGHT_DIRECTIONAL) {
            l = -dir.xyz;
            d2 = 1.0;
        } else {
            vec3 ld = pos_type.xyz - c.s.p;
            d2 = dot(ld, ld);
            l = ld * inversesqrt(d2);
        }
        float NoL = dot(c.s.n, l);
        bool far = int(pos_type.w) == LIGHT_DIRECTIONAL;
        if (NoL <= 0.0 || occluded(c.s.p, l, far ? LIGHT_FAR : sqrt(d2))) continue;
        vec3 I = intensity.rgb;
        if (int(pos_type.w) == LIGHT_SPOT) I *= spot_attenuation(dot(dir.xyz, -l), intensity.w, dir.w);
        vec3 f = light_brdf(c, l, NoL);
        color += f * I * (NoL / d2);
#ifdef MATERIAL_LOBES
        lobes_add_light(c.s.n, c.s.v, l, I / d2);   // the sheen's and the coat's lobes (material_lobes.glsl)
#endif
    }
    return color;
}

vec3 shade_material(Shading c, uint pixel_seed) {
    Surface s = c.s;
    vec3 color = vec3(0.0);
#ifdef MATERIAL_LOBES
    // the lobes (material_lobes.glsl): KHR_materials_specular's dielectric F0 / F90, the anisotropic
    // lookup direction
    vec3 diel_f0;
    float diel_f90;
    lobes_begin();
    lobes_dielectric(s.specular, diel_f0, diel_f90);
    c.F0 = mix(diel_f0, s.base_color, s.metallic);
    float F90 = specular_f90_blend(diel_f90, s.metallic);
    c.r = lobes_reflection(c.r, s.n, s.v, c.roughness);
#else
    c.F0 = mix(vec3(s.specular), s.base_color, s.metallic);
#endif
#if FRESNEL == FRESNEL_SCHLICK
#ifdef METALLIC_BLEND_GLTF
    // glTF's blend (brdf.glsl): the diffuse under the dielectric's own Fresnel, F0 = specular
#ifdef MATERIAL_LOBES
    // KHR_materials_specular: the diffuse under 1 - max3 of the dielectric's F0 (= specular when neutral)
    vec3 kd = (1.0 - vec3(lobes_max3(diel_f0))) * texture(kd_lut, vec2(c.NoV, 0.5)).r;
#else
    vec3 kd = (1.0 - vec3(s.specular)) * texture(kd_lut, vec2(c.NoV, 0.5)).r;
#endif
#else
    vec3 kd = (1.0 - c.F0) * texture(kd_lut, vec2(c.NoV, 0.5)).r;
#endif
    c.F0e = c.F0;
#else
    vec3 kd = vec3(0.0);
    c.F0e = vec3(1.0);
#endif
#ifdef HOOK_SPECULAR_IBL
    color += hook_specular_ibl(s.n, s.v, c.roughness, c.F0);
#elif IBL_RUNTIME
    color += runtime_specular(s.n, s.v, c.roughness, c.F0, pixel_seed);
#else
    c.AB = dfg(c.NoV, c.roughness);
#if FRESNEL == FRESNEL_SCHLICK && defined(MATERIAL_LOBES)
    vec3 spec_albedo = lobes_spec_albedo(c.F0, F90, c.NoV, c.AB);
#elif FRESNEL == FRESNEL_SCHLICK
    vec3 spec_albedo = c.F0 * c.AB.x + c.AB.y;
#else
    vec3 spec_albedo = vec3(c.AB.x + c.AB.y);
#endif
    // Multiple-scattering energy compensation (energy.glsl): a scale of the split sum's specular
    // (Filament) or a multiply scattered albedo times the irradiance (Fdez-Aguera, Kulla-Conty).
    // Specular occlusion (occlusion.glsl) of the image-based specular from the ambient occlusion,
    // and the horizon occlusion of a normal-mapped reflection below the geometric normal's horizon.
    float so = specular_occlusion(c.NoV, s.occlusion, c.roughness) * horizon_occlusion(dot(c.r, s.ng));
#ifdef HOOK_ENERGY_COMPENSATION
    color += prefiltered_radiance(c.r, c.roughness) * spec_albedo
             * hook_energy_compensation(c.F0e, c.AB.x, c.AB.y, c.roughness) * so;
#else
    color += prefiltered_radiance(c.r, c.roughness) * spec_albedo * energy_scale(c.F0e, c.AB.x, c.AB.y) * so;
    color += irradiance_over_pi(s.n) * energy_ms(c.F0e, c.AB.x, c.AB.y, c.roughness) * so;
#endif
#endif
    // glTF 2.0 (3.9.4): the occlusion texture scales the indirect diffuse light.
    color += (1.0 - s.metallic) * s.base_color * kd * irradiance_over_pi(s.n) * s.occlusion;
#ifdef MATERIAL_LOBES
    // sheen and coat over the lit base (material_lobes.glsl)
    return lobes_layer(add_point_lights(color, c), s.n, s.v, c.NoV);
#else
    return add_point_lights(color, c);
#endif
}

// Article 000, listing 4 (IBL): F = F_Schlick(n.v), kD = (1 - F)(1 - metallic),
// specular = prefiltered x (F A + B) (F, not F0); the lights first (listing 1).
vec3 shade_article000(Shading c) {
    Surface s = c.s;
    c.F0 = mix(vec3(s.specular), s.base_color, s.metallic);
    vec3 color = add_point_lights(vec3(0.0), c);
    vec3 F = F_Schlick(c.NoV, c.F0);
    vec3 kD = (1.0 - F) * (1.0 - s.metallic);
    vec3 indirectDiffuse = irradiance_over_pi(s.n) * s.base_color;
    vec2 envBRDF = dfg(c.NoV, c.roughness);
    vec3 indirectSpecular = prefiltered_radiance(c.r, c.roughness) * (F * envBRDF.x + envBRDF.y);
    return color + (kD * indirectDiffuse + indirectSpecular);
}

// Article 001: F0 clamped to [0.02, 0.99], roughness >= min_roughness (0.01), runtime-sampled
// specular, diffuse = irradiance x base / pi (our irradiance cube already holds E / pi).
vec3 shade_article001(Shading c, uint pixel_seed) {
    Surface s = c.s;
    c.F0 = clamp(mix(vec3(s.specular), s.base_color, s.metallic), 0.02, 0.99);
    vec3 color = runtime_specular(s.n, s.v, c.roughness, c.F0, pixel_seed);
    color += (1.0 - s.metallic) * s.base_color * irradiance_over_pi(s.n);
    return add_point_lights(color, c);
}

// Article 002: f0 = max(albedo x metalness, 0.04); output = lerp(diffuse, specular, EnvBRDFApprox).
vec3 shade_article002(Shading c) {
    Surface s = c.s;
    c.F0 = max(s.base_color * s.metallic, vec3(0.04));
#if REFLECT_BUG
    vec3 rr = s.v - 2.0 * dot(s.n, s.v) * s.n;   // reflect(v, n) with v towards the eye: -r (the article's)
#else
    vec3 rr = c.r;
#endif
    vec3 diffuse = s.base_color * irradiance_over_pi(s.n) * (1.0 - s.metallic);
    vec3 specular = prefiltered_radiance(rr, c.roughness);
    c.AB = dfg(c.NoV, c.roughness);
    c.t = c.F0 * c.AB.x + c.AB.y;
    return add_point_lights(mix(diffuse, specular, c.t), c);
}

// light_brdf and shade_composition: the selected composition's functions (generated).
#include "shading_dispatch.glsl"

// The outgoing radiance of surface point s towards s.v (0 on the back side of a one-sided
// surface); pixel_seed decorrelates runtime sampling between pixels.
vec3 shade(Surface s, uint pixel_seed) {
    float NoVr = dot(s.n, s.v);
    if (NoVr <= 0.0) return vec3(0.0);  // back side of a one-sided surface
    Shading c;
    c.s = s;
    c.roughness = max(s.roughness, min_roughness);
    c.NoV = clamp(NoVr, 1e-4, 1.0);
    c.r = 2.0 * NoVr * s.n - s.v;
    c.F0 = c.F0e = vec3(0.0);
    c.AB = vec2(0.0);
    c.t = vec3(0.0);
    return shade_composition(c, pixel_seed);
}
