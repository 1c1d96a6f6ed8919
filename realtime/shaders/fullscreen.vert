// fullscreen.vert: one triangle covering the viewport (gl_VertexID 0, 1, 2), at the far plane.
void main() {
    vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2);
    gl_Position = vec4(2.0 * p - 1.0, 1.0, 1.0);
}
