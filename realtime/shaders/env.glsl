// env.glsl: the scene's ONE radiance function (pbrcheck.environment.EnvMap.radiance) and cube
// texel directions. Both renderers see the same light: the cube bake evaluates this per texel.
#include "common.glsl"

uniform sampler2D env_equirect;   // (W, H) RGB32F, row 0 = theta 0 (+Y); read with texelFetch only
uniform ivec2 env_size;           // (W, H)
uniform vec3 env_rot0;            // columns of R (rotation about +Y): d_local_j = dot(d, R[:, j])
uniform vec3 env_rot1;
uniform vec3 env_rot2;
uniform float env_scale;

// Source: Mitsuba 3 envmap eval, as pbrcheck.environment.lookup_equirect. Equation:
// u = atan2(x, -z) / 2pi - 0.5 / W (wrapped), v = acos(y) / pi; bilinear on rows theta = pi r / (H-1)
// with column W a copy of column 0.
// IEEE atan2 including signed zeros (numpy's arctan2(+-0, -0) = +-pi; llvmpipe's atan returns 0).
float atan2_ieee(float y, float x) {
    if (y == 0.0 && x == 0.0) {
        bool xneg = (floatBitsToUint(x) & 0x80000000u) != 0u;
        bool yneg = (floatBitsToUint(y) & 0x80000000u) != 0u;
        float r = xneg ? PI : 0.0;
        return yneg ? -r : r;
    }
    return atan(y, x);
}

vec3 env_radiance(vec3 d_world) {
    vec3 d = normalize(d_world);
    vec3 dl = vec3(dot(d, env_rot0), dot(d, env_rot1), dot(d, env_rot2));
    int W = env_size.x;
    int H = env_size.y;
    float u = atan2_ieee(dl.x, -dl.z) / (2.0 * PI);
    float v = acos(clamp(dl.y, -1.0, 1.0)) / PI;
    u = u - 0.5 / float(W);
    u = u - floor(u);
    v = v - floor(v);
    float x = u * float(W);
    float y = v * float(H - 1);
    int ix = min(int(x), W - 1);
    int iy = min(int(y), H - 2);
    float wx = x - float(ix);
    float wy = y - float(iy);
    int ix1 = (ix + 1) % W;
    vec3 v00 = texelFetch(env_equirect, ivec2(ix, iy), 0).rgb;
    vec3 v10 = texelFetch(env_equirect, ivec2(ix1, iy), 0).rgb;
    vec3 v01 = texelFetch(env_equirect, ivec2(ix, iy + 1), 0).rgb;
    vec3 v11 = texelFetch(env_equirect, ivec2(ix1, iy + 1), 0).rgb;
    vec3 v0 = (1.0 - wx) * v00 + wx * v10;
    vec3 v1 = (1.0 - wx) * v01 + wx * v11;
    return ((1.0 - wy) * v0 + wy * v1) * env_scale;
}

// Source: OpenGL 4.5 core, table 8.19 (cube map face selection), inverted. Faces in GL order
// +X, -X, +Y, -Y, +Z, -Z (layer = face); texel (x, y) at s = (x + 0.5) / size, t = (y + 0.5) / size.
vec3 cube_dir(int face, vec2 st) {
    float a = 2.0 * st.x - 1.0;
    float b = 2.0 * st.y - 1.0;
    vec3 d;
    if (face == 0) d = vec3(1.0, -b, -a);
    else if (face == 1) d = vec3(-1.0, -b, a);
    else if (face == 2) d = vec3(a, 1.0, b);
    else if (face == 3) d = vec3(a, -1.0, -b);
    else if (face == 4) d = vec3(a, -b, 1.0);
    else d = vec3(-a, -b, -1.0);
    return normalize(d);
}

// Solid angle of cube texel (x, y) of a face of `size` texels: the area-element integral
// atan(ab / sqrt(a^2 + b^2 + 1)) evaluated at the four corners.
float _cube_area(float a, float b) { return atan(a * b, sqrt(a * a + b * b + 1.0)); }
float cube_texel_solid_angle(ivec2 xy, int size) {
    float inv = 1.0 / float(size);
    float a0 = 2.0 * float(xy.x) * inv - 1.0, a1 = a0 + 2.0 * inv;
    float b0 = 2.0 * float(xy.y) * inv - 1.0, b1 = b0 + 2.0 * inv;
    return _cube_area(a0, b0) - _cube_area(a0, b1) - _cube_area(a1, b0) + _cube_area(a1, b1);
}
