// irradiance.comp: pass "irradiance" (convolution). Writes E(n)/pi per cube texel (radiance units,
// so diffuse = albedo x value). METHOD 0: sum over every texel of the source cube level with its
// solid angle (exact up to the source's resolution); the source texels' directions, solid angles and
// radiances come from irradiance_texels.comp (computed once, not once per output texel). METHOD 1:
// article 000's uniform polar/azimuth stepping (`irradiance_step` radians), pi * mean(L cos sin) as in its EnvToIrradiance.frag.
layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;
#include "env.glsl"
layout(IMAGE_FORMAT, binding = 0) writeonly uniform imageCube out_cube;
uniform samplerCube src_cube;
uniform int face_size;
uniform int src_size;
uniform float src_lod;
uniform float step_size;
#if IRRADIANCE_METHOD == IRRADIANCE_METHOD_TEXEL_SUM
struct SourceTexel { vec4 dir_sa; vec4 radiance; };  // irradiance_texels.comp's layout
layout(std430, binding = 0) readonly buffer Texels { SourceTexel texels[]; };
#endif

void main() {
    ivec3 g = ivec3(gl_GlobalInvocationID);
    if (g.x >= face_size || g.y >= face_size) return;
    vec3 n = cube_dir(g.z, (vec2(g.xy) + 0.5) / float(face_size));
    vec3 acc = vec3(0.0);
#if IRRADIANCE_METHOD == IRRADIANCE_METHOD_TEXEL_SUM
    // Every texel of every face, in face, row, column order (irradiance_texels.comp's index).
    int count = 6 * src_size * src_size;
    for (int t = 0; t < count; ++t) {
        vec4 ds = texels[t].dir_sa;
        float c = dot(ds.xyz, n);
        if (c > 0.0)
            acc += texels[t].radiance.rgb * (c * ds.w);
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
