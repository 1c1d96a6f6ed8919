// irradiance_texels.comp: pass "irradiance" (convolution, texel_sum), its first step. One invocation
// per texel (x, y) of face f of the source level (src_size^2 texels a face): its direction
// cube_dir(f, ((x, y) + 0.5) / src_size), its solid angle cube_texel_solid_angle and its radiance
// textureLod(src_cube, d, src_lod), written once so that irradiance.comp's sum over every source
// texel for every output texel reads them instead of recomputing them per (output, source) pair
// (the same values, so the same sum). Texel t = (f * src_size + y) * src_size + x.
layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;
#include "env.glsl"
struct SourceTexel { vec4 dir_sa; vec4 radiance; };  // direction.xyz, solid angle; radiance.rgb, 0
layout(std430, binding = 0) writeonly buffer Texels { SourceTexel texels[]; };
uniform samplerCube src_cube;
uniform int src_size;
uniform float src_lod;

void main() {
    ivec3 g = ivec3(gl_GlobalInvocationID);
    if (g.x >= src_size || g.y >= src_size) return;
    vec3 d = cube_dir(g.z, (vec2(g.xy) + 0.5) / float(src_size));
    int t = (g.z * src_size + g.y) * src_size + g.x;
    texels[t].dir_sa = vec4(d, cube_texel_solid_angle(g.xy, src_size));
    texels[t].radiance = vec4(textureLod(src_cube, d, src_lod).rgb, 0.0);
}
