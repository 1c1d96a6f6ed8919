// sh9.comp: pass "sh9". Projects every texel of a source cube level onto the 9 real SH basis
// functions (weights: solid angle); one invocation per texel writes 9 vec4 partial sums that the
// host adds in float64. Basis order of article 002: 1, y, z, x, yx, yz, 3z^2-1, zx, x^2-y^2.
layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;
#include "env.glsl"
layout(std430, binding = 0) writeonly buffer Out { vec4 coeffs[]; };
uniform samplerCube src_cube;
uniform int src_size;
uniform float src_lod;

void main() {
    ivec3 g = ivec3(gl_GlobalInvocationID);
    if (g.x >= src_size || g.y >= src_size) return;
    vec3 d = cube_dir(g.z, (vec2(g.xy) + 0.5) / float(src_size));
    vec3 L = textureLod(src_cube, d, src_lod).rgb * cube_texel_solid_angle(g.xy, src_size);
    float b[9] = float[9](1.0, d.y, d.z, d.x, d.y * d.x, d.y * d.z, 3.0 * d.z * d.z - 1.0, d.z * d.x,
                          d.x * d.x - d.y * d.y);
    int base = ((g.z * src_size + g.y) * src_size + g.x) * 9;
    for (int i = 0; i < 9; ++i) coeffs[base + i] = vec4(L * b[i], 0.0);
}
