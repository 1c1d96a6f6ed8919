// raster_background.frag: pass "raster" background. The environment's radiance along the ray of
// each sample (window coordinates, row 0 at the bottom; see raster.vert), coverage 0.
#include "env.glsl"

uniform vec3 cam_r;
uniform vec3 cam_u;
uniform vec3 cam_f;
uniform vec2 cam_tan;
uniform vec2 target_size;
layout(location = 0) out vec4 out_color;

void main() {
    vec2 ndc = 2.0 * gl_FragCoord.xy / target_size - 1.0;
    vec3 d = normalize(cam_f + ndc.x * cam_tan.x * cam_r + ndc.y * cam_tan.y * cam_u);
    out_color = vec4(env_radiance(d), 0.0);
}
