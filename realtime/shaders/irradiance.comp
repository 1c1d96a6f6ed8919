// irradiance.comp: pass "irradiance" (convolution). Writes E(n)/pi per cube texel (radiance units,
// so diffuse = albedo x value). METHOD 0: sum over every texel of the source cube level with its
// solid angle (exact up to the source's resolution). METHOD 1: article 000's uniform polar/azimuth
// stepping (`irradiance_step` radians), pi * mean(L cos sin) as in its EnvToIrradiance.frag.
layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;
#include "env.glsl"
layout(IMAGE_FORMAT, binding = 0) writeonly uniform imageCube out_cube;
uniform samplerCube src_cube;
uniform int face_size;
uniform int src_size;
uniform float src_lod;
uniform float step_size;

void main() {
    ivec3 g = ivec3(gl_GlobalInvocationID);
    if (g.x >= face_size || g.y >= face_size) return;
    vec3 n = cube_dir(g.z, (vec2(g.xy) + 0.5) / float(face_size));
    vec3 acc = vec3(0.0);
#if IRRADIANCE_METHOD == IRRADIANCE_METHOD_TEXEL_SUM
    for (int f = 0; f < 6; ++f)
        for (int y = 0; y < src_size; ++y)
            for (int x = 0; x < src_size; ++x) {
                vec3 d = cube_dir(f, (vec2(x, y) + 0.5) / float(src_size));
                float c = dot(d, n);
                if (c > 0.0)
                    acc += textureLod(src_cube, d, src_lod).rgb * (c * cube_texel_solid_angle(ivec2(x, y), src_size));
            }
    acc /= PI;
#else
    float count = 0.0;
    for (float phi = 0.0; phi < 2.0 * PI; phi += step_size)
        for (float theta = 0.0; theta < 0.5 * PI; theta += step_size) {
            vec3 t = vec3(sin(theta) * cos(phi), sin(theta) * sin(phi), cos(theta));
            acc += textureLod(src_cube, to_world(t, n), src_lod).rgb * cos(theta) * sin(theta);
            count += 1.0;
        }
    acc = PI * acc / count;
#endif
    imageStore(out_cube, g, vec4(acc, 1.0));
}
