// render.comp: pass "frame". One invocation per output pixel: ray-traces the analytic spheres and
// rectangles with `ss` x `ss` sub-pixel samples at (k + 0.5)/ss (box filter), plus one ray through
// the pixel centre for the AOVs (normal, n.v, object), exactly pbrcheck.camera.primary_rays.
// Row 0 of the images is the top of the picture (gl_GlobalInvocationID.y = row). This pass only finds
// the hits: their shading is shading.glsl's shade() (one function per composition), which another
// pipeline includes unchanged; occluded() (shadow rays against the same shapes) is its input here.
layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;
#include "env.glsl"
#include "shading.glsl"

layout(rgba32f, binding = 0) writeonly uniform image2D out_color;   // rgb, coverage
layout(rgba32f, binding = 1) writeonly uniform image2D out_aov;     // N.xyz, NdotV (centre ray)
layout(r32f, binding = 2) writeonly uniform image2D out_object;     // object id, -1 background

struct Obj { vec4 a; vec4 b; vec4 c; vec4 d; vec4 e; vec4 f; };
// a: centre.xyz, type (0 sphere, 1 rectangle); b: normal.xyz, radius; c: tangent.xyz, size.x;
// d: bitangent.xyz, size.y; e: base_color.rgb, metallic; f: roughness, specular, id, 0
layout(std430, binding = 0) readonly buffer Objects { Obj objs[]; };
uniform int n_objects;
#ifdef MATERIAL_LOBES
// 4 vec4 per object (material_lobes.glsl lobes_from_rows; realtime.material_lobes.object_lobe_rows)
layout(std430, binding = 3) readonly buffer ObjectLobes { vec4 obj_lobes[]; };
#endif
#ifdef TRANSMISSION
// 3 vec4 per object (realtime.transmission.object_transmission_rows): (transmission, thickness, dispersion,
// ior), (attenuation colour, attenuation distance), (diffuse transmission colour, its factor).
layout(std430, binding = 4) readonly buffer ObjectTransmission { vec4 obj_trans[]; };
#endif
uniform vec3 cam_origin;
uniform vec3 cam_right;    // right * tan_x
uniform vec3 cam_up;       // true_up * tan_y
uniform vec3 cam_forward;
uniform ivec2 image_size;
// The first pixel of this dispatch: a large frame is dispatched in bands of rows (realtime/render.py,
// frame_bands), so that a signal is honoured between two; a pixel depends on g alone, so the image
// is the same bit for bit however it is cut.
uniform ivec2 tile_origin;
uniform int ss;
#ifdef TRANSMISSION
// Transmission (transmission.glsl, TRANSMISSION_PER_OBJECT, Filament's cube-map refraction: this pipeline
// has no opaque-pass framebuffer), defined only where the scene has a transmissive object.
#include "transmission.glsl"

// The change transmission makes to the radiance of object k's surface s (transmission_change).
vec3 object_transmission(int k, Surface s, uint seed) {
    vec4 r0 = obj_trans[3 * k], r1 = obj_trans[3 * k + 1], r2 = obj_trans[3 * k + 2];
    transmission_factor = r0.x;
    transmission_thickness = r0.y;
    transmission_dispersion = r0.z;
    transmission_ior = r0.w;
    transmission_attenuation_color = r1.rgb;
    transmission_attenuation_distance = r1.w;
    diffuse_transmission_color = r2.rgb;
    diffuse_transmission_factor = r2.w;
    if ((transmission_factor <= 0.0 && diffuse_transmission_factor <= 0.0) || dot(s.n, s.v) <= 0.0) return vec3(0.0);
    g_thickness = transmission_thickness;
    Surface sd = s;
    sd.metallic = 0.0;
    return transmission_change(sd, s.metallic, transmission_factor, seed);
}
#endif

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

// The surface of object k at hit point p (its normal and material), v towards the eye.
Surface surface_at(int k, vec3 p, vec3 v) {
    Obj ob = objs[k];
    vec3 n = normal_at(k, p);
#ifdef MATERIAL_LOBES
    g_lobes = lobes_from_rows(obj_lobes[4 * k], obj_lobes[4 * k + 1], obj_lobes[4 * k + 2], obj_lobes[4 * k + 3], n,
                              ob.a.w < 0.5 ? sphere_tangent(n) : ob.c.xyz);
#endif
    return Surface(p, n, v, ob.e.rgb, ob.e.a, ob.f.x, ob.f.y, 1.0, n);  // no occlusion, no normal map
}

void main() {
    ivec2 g = ivec2(gl_GlobalInvocationID.xy) + tile_origin;
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
#ifdef TRANSMISSION
                Surface s = surface_at(k, p, -d);
                acc += shade(s, seed) + object_transmission(k, s, seed);
#else
                acc += shade(surface_at(k, p, -d), seed);
#endif
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
