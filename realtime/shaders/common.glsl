// common.glsl: constants shared by every shader; the values mirror pbrcheck/brdf.py.
const float PI = 3.14159265358979;
// Smallest alpha the terms evaluate with (pbrcheck.brdf.MIN_ALPHA): alpha^2 = 1e-14 is a normal float32.
const float MIN_ALPHA = 1e-7;
// Guard for divisions by cosines that reach 0 at grazing angles (pbrcheck.brdf.COS_EPS).
const float COS_EPS = 1e-8;
// Below this alpha a lobe is treated as a mirror (pbrcheck.brdf.DELTA_LOBE_ALPHA).
const float DELTA_LOBE_ALPHA = 1e-4;

float saturate(float x) { return clamp(x, 0.0, 1.0); }
float pow5(float x) { float x2 = x * x; return x2 * x2 * x; }

// Orthonormal frame around n (tangent, bitangent, n): maps a tangent-space vector (z = n) to world.
vec3 to_world(vec3 t, vec3 n) {
    vec3 up = abs(n.z) < 0.999 ? vec3(0.0, 0.0, 1.0) : vec3(1.0, 0.0, 0.0);
    vec3 tx = normalize(cross(up, n));
    vec3 ty = cross(n, tx);
    return tx * t.x + ty * t.y + n * t.z;
}
