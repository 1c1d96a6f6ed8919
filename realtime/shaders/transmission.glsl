// transmission.glsl: the engines' transmission (issue 37 item 2), included where the scene draws a
// transmissive material (TRANSMISSION, realtime/transmission.py): by raster.frag (one draw's material in
// uniforms) and by render.comp (TRANSMISSION_PER_OBJECT: the hit object's material, set from its rows).
// TRANSMISSION_SOURCE (registry realtime.transmission.TRANSMISSION_SOURCES): what the refracted ray reads.
// * TRANSMISSION_SOURCE_SCREEN (raster only): the opaque objects' colour pass, rendered first into
//   transmission_fb (RGBA32F at the colour pass's size, GL orientation: row 0 at the bottom, so uv = NDC *
//   0.5 + 0.5; the full mip chain by glGenerateMipmap, a 2x2 box per level); the prefiltered environment
//   where the ray leaves the screen.
// * TRANSMISSION_SOURCE_CUBEMAP: Filament's REFRACTION_MODE_CUBEMAP: the prefiltered environment along the
//   refracted direction (solid: a sphere of the thickness; thin: the view ray), at Filament's roughness.
// Sources: KhronosGroup/glTF-Sample-Viewer source/Renderer/shaders/ibl.glsl (getVolumeTransmissionRay,
// getTransmissionSample, applyIorToRoughness, applyVolumeAttenuation, getIBLVolumeRefraction);
// mrdoob/three.js src/renderers/shaders/ShaderChunk/transmission_pars_fragment.glsl.js (textureBicubic,
// the dispersion's three IORs); google/filament shaders/src/surface_light_indirect.fs
// (refractionSolidSphere, refractionThinSphere, evaluateRefraction). numpy twins: realtime/transmission.py.
// TRANSMISSION_LOD: TRANSMISSION_LOD_SAMPLE_VIEWER (textureLod, trilinear) | TRANSMISSION_LOD_THREEJS
// (the same level, B-spline bicubic of floor(lod) and ceil(lod) mixed by fract(lod)).
#ifdef TRANSMISSION_PER_OBJECT
#define TRANSMISSION_PARAM
#else
#define TRANSMISSION_PARAM uniform
#endif
#if TRANSMISSION_SOURCE == TRANSMISSION_SOURCE_SCREEN
uniform sampler2D transmission_fb;
uniform vec2 transmission_fb_size;     // (width, height) of level 0
uniform vec3 cam_r;
uniform vec3 cam_u;
uniform vec3 cam_f;
uniform vec2 cam_tan;
#endif
// The material (0 transmission: the core material): the draw's uniforms, or the hit object's (render.comp).
TRANSMISSION_PARAM float transmission_factor;
TRANSMISSION_PARAM float transmission_thickness;      // world units (0: thin-walled: the ray exits where it enters)
TRANSMISSION_PARAM vec3 transmission_attenuation_color;
TRANSMISSION_PARAM float transmission_attenuation_distance;   // 0: none (glTF's +inf)
TRANSMISSION_PARAM float transmission_dispersion;     // 20 / Abbe number (0: none)
TRANSMISSION_PARAM float transmission_ior;
TRANSMISSION_PARAM float diffuse_transmission_factor;   // KHR_materials_diffuse_transmission (0: none)
TRANSMISSION_PARAM vec3 diffuse_transmission_color;
#ifndef TRANSMISSION_PER_OBJECT
// The transmission texture (slot 0, R) and the thickness texture (slot 1, G) with their texCoord,
// KHR_texture_transform and mirror folds (realtime.raster.TRANSMISSION_TEXTURE_SLOTS; white where absent).
uniform sampler2D tmap[2];
uniform int tmap_has[2];
uniform int tmap_set[2];
uniform mat3 tmap_xf[2];
uniform int tmap_mirror[2];
#endif
// The fragment's thickness (transmission_thickness x the thickness texture's G), set by the includer.
float g_thickness;

#include "transmission_forms.glsl"

#if TRANSMISSION_SOURCE == TRANSMISSION_SOURCE_SCREEN
vec4 bicubic_level(vec2 uv, float lod) {
    vec2 size = vec2(textureSize(transmission_fb, int(lod)));
    vec2 texel = 1.0 / size;
    uv = uv * size + 0.5;
    vec2 iuv = floor(uv), fuv = fract(uv);
    float g0x = bc_g0(fuv.x), g1x = bc_g1(fuv.x), h0x = bc_h0(fuv.x), h1x = bc_h1(fuv.x);
    float h0y = bc_h0(fuv.y), h1y = bc_h1(fuv.y);
    vec2 p0 = (vec2(iuv.x + h0x, iuv.y + h0y) - 0.5) * texel;
    vec2 p1 = (vec2(iuv.x + h1x, iuv.y + h0y) - 0.5) * texel;
    vec2 p2 = (vec2(iuv.x + h0x, iuv.y + h1y) - 0.5) * texel;
    vec2 p3 = (vec2(iuv.x + h1x, iuv.y + h1y) - 0.5) * texel;
    return bc_g0(fuv.y) * (g0x * textureLod(transmission_fb, p0, lod) + g1x * textureLod(transmission_fb, p1, lod))
         + bc_g1(fuv.y) * (g0x * textureLod(transmission_fb, p2, lod) + g1x * textureLod(transmission_fb, p3, lod));
}

vec3 transmission_fb_read(vec2 uv, float lod) {
#if TRANSMISSION_LOD == TRANSMISSION_LOD_THREEJS
    return mix(bicubic_level(uv, floor(lod)), bicubic_level(uv, ceil(lod)), fract(lod)).rgb;
#else
    return textureLod(transmission_fb, uv, lod).rgb;
#endif
}

// The radiance behind the surface along the refracted ray at one IOR: the ray refract(-v, n, 1 / ior)
// runs the thickness (g_thickness) and exits at p + thickness t, projected into transmission_fb; where that point is
// behind the camera or off the screen, the prefiltered environment along t (at the IOR-scaled roughness).
vec3 transmitted_radiance(vec3 p, vec3 n, vec3 v, float roughness, float ior) {
    ior = max(ior, 1.0);   // a dispersed IOR below 1 would refract from the denser side (no such medium here)
    vec3 t = normalize(refract(-v, n, 1.0 / ior));
    vec3 q = p + t * g_thickness - cam_origin;
    float z = dot(q, cam_f);
    vec2 uv = 0.5 * vec2(dot(q, cam_r) / (cam_tan.x * z), dot(q, cam_u) / (cam_tan.y * z)) + 0.5;
    if (z <= 0.0 || any(lessThan(uv, vec2(0.0))) || any(greaterThan(uv, vec2(1.0))))
        return prefiltered_radiance(t, apply_ior_to_roughness(roughness, ior));
    float lod = transmission_lod(roughness, ior, transmission_fb_size.x);
#ifdef TRANSMISSION_LOD_BIAS
    lod = transmission_lod_biased(lod, TRANSMISSION_LOD_BIAS);   // option transmission_lod_bias (not 0)
#endif
    return transmission_fb_read(uv, lod);
}
#else
// Filament's REFRACTION_MODE_CUBEMAP: the prefiltered environment along the ray leaving the object
// (refraction_direction: solid where the material has a thickness, thin where it has none), at
// Filament's refraction roughness (no blur at IOR 1, the roughness as it is from IOR 1.5).
vec3 transmitted_radiance(vec3 p, vec3 n, vec3 v, float roughness, float ior) {
    ior = max(ior, 1.0);   // a dispersed IOR below 1 would refract from the denser side (no such medium here)
    return prefiltered_radiance(refraction_direction(n, v, ior, g_thickness),
                                filament_refraction_roughness(roughness, ior));
}
#endif

// getIBLVolumeRefraction's value before base colour: the transmitted light, attenuated over the
// thickness, times 1 - (F0 A + B) (the DFG LUT's specular albedo, F90 = 1). Dispersion: three.js's
// three IORs ior -/+ (ior - 1) 0.025 dispersion, one channel each.
vec3 transmission_radiance(vec3 p, vec3 n, vec3 v, float roughness, float f0) {
    vec3 light;
    if (transmission_dispersion > 0.0) {
        vec3 iors = dispersion_iors(transmission_ior, transmission_dispersion);
        light = vec3(transmitted_radiance(p, n, v, roughness, iors.r).r,
                     transmitted_radiance(p, n, v, roughness, iors.g).g,
                     transmitted_radiance(p, n, v, roughness, iors.b).b);
    } else {
        light = transmitted_radiance(p, n, v, roughness, transmission_ior);
    }
    vec2 AB = dfg(clamp(dot(n, v), 1e-4, 1.0), roughness);
    return (1.0 - (f0 * AB.x + AB.y)) * volume_attenuation(g_thickness, transmission_attenuation_color,
                                                            transmission_attenuation_distance) * light;
}

// KHR_materials_diffuse_transmission as the Sample Viewer renders it (pbr.frag): the irradiance from the
// back, E(-n) / pi, times diffuseTransmissionColor and the base colour, attenuated over the thickness
// (a volume), replaces the diffuse in proportion diffuseTransmissionFactor.
vec3 diffuse_transmission_radiance(vec3 n, vec3 base_color) {
    return irradiance_over_pi(-n) * diffuse_transmission_color * base_color
         * volume_attenuation(g_thickness, transmission_attenuation_color, transmission_attenuation_distance);
}

// The change transmission makes to the radiance of surface sd (its base colour and roughness the
// material's, metallic 0; metallic weights the result, the metallic blend): the dielectric diffuse, the
// difference of the composition with and without the base colour (linear in it), is replaced in
// proportion tf by the transmitted light x base colour (the Sample Viewer's mix(f_diffuse, f_transmission,
// T)); punctual lights transmit nothing. Diffuse transmission first replaces the diffuse by the back's
// irradiance, then transmission replaces what remains (the Sample Viewer's order of the two mixes).
// g_thickness is set by the caller.
vec3 transmission_change(Surface sd, float metallic, float tf, uint seed) {
    Surface s0 = sd;
    s0.base_color = vec3(0.0);
    vec3 diffuse = shade(sd, seed) - shade(s0, seed);
    vec3 fd = mix(diffuse, diffuse_transmission_radiance(sd.n, sd.base_color), diffuse_transmission_factor);
    vec3 ft = tf > 0.0 ? transmission_radiance(sd.p, sd.n, sd.v, sd.roughness, sd.specular) * sd.base_color
                       : vec3(0.0);
    return (1.0 - metallic) * (mix(fd, ft, tf) - diffuse);
}
