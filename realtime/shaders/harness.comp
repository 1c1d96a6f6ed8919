// harness.comp: runs one GLSL expression of the shader library on arrays (realtime/glsl_harness.py).
// Inputs: a[i], b[i] (8 floats per element); output: vec4 per element. hooks.glsl: the prototypes
// of a hook file the harness appends (its HOOK_<NAME> defined), none otherwise.
layout(local_size_x = 64) in;
#include "sampling.glsl"
#include "ibl.glsl"
#include "env.glsl"
#include "energy.glsl"
#include "lights.glsl"
#include "occlusion.glsl"
#include "specular_aa.glsl"
#include "coverage.glsl"
#include "texcoord.glsl"
#include "lobes_coat.glsl"
#include "lobes_sheen.glsl"
#include "lobes_anisotropy.glsl"
#include "lobes_iridescence.glsl"
#include "lobes_material.glsl"
#include "transmission_forms.glsl"
#include "hooks.glsl"
layout(std430, binding = 0) readonly buffer InA { vec4 a_in[]; };
layout(std430, binding = 1) readonly buffer InB { vec4 b_in[]; };
layout(std430, binding = 2) writeonly buffer Out { vec4 out_v[]; };
uniform int count;

vec4 _pad(float x) { return vec4(x, 0.0, 0.0, 0.0); }
vec4 _pad(vec2 x) { return vec4(x, 0.0, 0.0); }
vec4 _pad(vec3 x) { return vec4(x, 0.0); }
vec4 _pad(vec4 x) { return x; }

void main() {
    int i = int(gl_GlobalInvocationID.x);
    if (i >= count) return;
    vec4 a = a_in[i];
    vec4 b = b_in[i];
    uint idx = uint(i);
//@HARNESS@
}
