// raster.vert: pass "raster". Projects world-space vertices with the camera of every renderer
// (pbrcheck.camera: right r, up u, forward f, tan of the half fields of view tx, ty): clip =
// (q.r / tx, q.u / ty, A z + B, z) with q = p - origin, z = q.f, so NDC (x, y) is the ray direction
// (x tx r + y ty u + f) of pbrcheck.camera.primary_rays; window row 0 is the bottom (the host
// flips the rows so that row 0 of the images is the top). Depth: [near, far] of the scene's box.
layout(location = 0) in vec3 in_pos;
layout(location = 1) in vec3 in_nrm;
layout(location = 2) in vec4 in_tan;   // xyz unit tangent, w = handedness (glTF TANGENT)
layout(location = 3) in vec2 in_uv0;
layout(location = 4) in vec2 in_uv1;
layout(location = 5) in vec4 in_col;   // COLOR_0 (linear), 1 where absent

uniform vec3 cam_origin;
uniform vec3 cam_r;
uniform vec3 cam_u;
uniform vec3 cam_f;
uniform vec2 cam_tan;      // (tx, ty)
uniform vec2 depth_ab;     // (A, B): z_clip = A z + B

out vec3 v_pos;
out vec3 v_nrm;
out vec4 v_tan;
out vec2 v_uv0;
out vec2 v_uv1;
out vec4 v_col;

void main() {
    vec3 q = in_pos - cam_origin;
    float z = dot(q, cam_f);
    gl_Position = vec4(dot(q, cam_r) / cam_tan.x, dot(q, cam_u) / cam_tan.y, depth_ab.x * z + depth_ab.y, z);
    v_pos = in_pos;
    v_nrm = in_nrm;
    v_tan = in_tan;
    v_uv0 = in_uv0;
    v_uv1 = in_uv1;
    v_col = in_col;
}
