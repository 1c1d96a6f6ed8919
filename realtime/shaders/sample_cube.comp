// sample_cube.comp: reads a cube map at given directions and level (tests, diagnostics).
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer In { vec4 dirs[]; };
layout(std430, binding = 1) writeonly buffer Out { vec4 values[]; };
uniform samplerCube cube;
uniform int count;

void main() {
    int i = int(gl_GlobalInvocationID.x);
    if (i >= count) return;
    values[i] = textureLod(cube, dirs[i].xyz, dirs[i].w);
}
