// env_to_cube.comp: pass "env_cube". Evaluates the scene's radiance function (env.glsl) at every
// texel centre of face `gl_GlobalInvocationID.z` of a cube level. Faces in GL order +X,-X,+Y,-Y,+Z,-Z.
layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;
#include "env.glsl"
layout(IMAGE_FORMAT, binding = 0) writeonly uniform imageCube out_cube;
uniform int face_size;

void main() {
    ivec3 g = ivec3(gl_GlobalInvocationID);
    if (g.x >= face_size || g.y >= face_size) return;
    vec2 st = (vec2(g.xy) + 0.5) / float(face_size);
    vec3 L = env_radiance(cube_dir(g.z, st));
    imageStore(out_cube, g, vec4(L, 1.0));
}
