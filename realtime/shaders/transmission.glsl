// transmission.glsl: the engines' screen-space transmission (issue 37 item 2), included by raster.frag
// only where the scene draws a transmissive material (TRANSMISSION, realtime/transmission.py): the
// opaque objects' colour pass, rendered first into transmission_fb (RGBA32F at the colour pass's size,
// GL orientation: row 0 at the bottom, so uv = NDC * 0.5 + 0.5; the full mip chain by glGenerateMipmap,
// a 2x2 box per level), read along the refracted ray.
// Sources: KhronosGroup/glTF-Sample-Viewer source/Renderer/shaders/ibl.glsl (getVolumeTransmissionRay,
// getTransmissionSample, applyIorToRoughness, applyVolumeAttenuation, getIBLVolumeRefraction);
// mrdoob/three.js src/renderers/shaders/ShaderChunk/transmission_pars_fragment.glsl.js (textureBicubic,
// the dispersion's three IORs). numpy twins: realtime/transmission.py.
// TRANSMISSION_LOD: TRANSMISSION_LOD_SAMPLE_VIEWER (textureLod, trilinear) | TRANSMISSION_LOD_THREEJS
// (the same level, B-spline bicubic of floor(lod) and ceil(lod) mixed by fract(lod)).
uniform sampler2D transmission_fb;
uniform vec2 transmission_fb_size;     // (width, height) of level 0
uniform vec3 cam_r;
uniform vec3 cam_u;
uniform vec3 cam_f;
uniform vec2 cam_tan;
// The draw's material (0 transmission: the core material).
uniform float transmission_factor;
uniform float transmission_thickness;      // world units (0: thin-walled: the ray exits where it enters)
uniform vec3 transmission_attenuation_color;
uniform float transmission_attenuation_distance;   // 0: none (glTF's +inf)
uniform float transmission_dispersion;     // 20 / Abbe number (0: none)
uniform float transmission_ior;
// The transmission texture (slot 0, R) and the thickness texture (slot 1, G) with their texCoord,
// KHR_texture_transform and mirror folds (realtime.raster.TRANSMISSION_TEXTURE_SLOTS; white where absent).
uniform sampler2D tmap[2];
uniform int tmap_has[2];
uniform int tmap_set[2];
uniform mat3 tmap_xf[2];
uniform int tmap_mirror[2];
// The fragment's thickness (transmission_thickness x the thickness texture's G), set by raster.frag.
float g_thickness;
uniform float diffuse_transmission_factor;   // KHR_materials_diffuse_transmission (0: none)
uniform vec3 diffuse_transmission_color;

#include "transmission_forms.glsl"

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
