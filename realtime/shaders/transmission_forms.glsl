// transmission_forms.glsl: the closed forms of the engines' screen-space transmission (no uniform, no
// texture), included by transmission.glsl and the GLSL harness; numpy twins of the same names in
// realtime/transmission.py (tests/test_realtime_transmission.py compares them on grids).
// applyIorToRoughness (both engines): IOR 1 no blur, 1.5 and above the roughness as it is.
float apply_ior_to_roughness(float roughness, float ior) {
    return roughness * clamp(ior * 2.0 - 2.0, 0.0, 1.0);
}

// Both engines' level: log2(framebuffer width) applyIorToRoughness(r, ior).
float transmission_lod(float roughness, float ior, float width) {
    return log2(width) * apply_ior_to_roughness(roughness, ior);
}

// Option transmission_lod_bias (compare.transmission_split's LOD scan, no engine's): the level moved, clamped at 0.
float transmission_lod_biased(float lod, float bias) {
    return max(lod + bias, 0.0);
}

// three.js's dispersion: the IORs of R, G, B, ior -/+ (ior - 1) 0.025 dispersion.
vec3 dispersion_iors(float ior, float dispersion) {
    float s = (ior - 1.0) * 0.025 * dispersion;
    return vec3(ior - s, ior, ior + s);
}

// Beer-Lambert over the thickness (Sample Viewer applyVolumeAttenuation): c^(t / d) = exp(-sigma_t t).
vec3 volume_attenuation(float t, vec3 c, float d) {
    if (d <= 0.0) return vec3(1.0);
    return pow(c, vec3(t / d));
}

// three.js textureBicubic (N8's mipped bicubic): the cubic B-spline as 4 bilinear taps per level.
float bc_w0(float a) { return (1.0 / 6.0) * (a * (a * (-a + 3.0) - 3.0) + 1.0); }
float bc_w1(float a) { return (1.0 / 6.0) * (a * a * (3.0 * a - 6.0) + 4.0); }
float bc_w2(float a) { return (1.0 / 6.0) * (a * (a * (-3.0 * a + 3.0) + 3.0) + 1.0); }
float bc_w3(float a) { return (1.0 / 6.0) * (a * a * a); }
float bc_g0(float a) { return bc_w0(a) + bc_w1(a); }
float bc_g1(float a) { return bc_w2(a) + bc_w3(a); }
float bc_h0(float a) { return -1.0 + bc_w1(a) / (bc_w0(a) + bc_w1(a)); }
float bc_h1(float a) { return 1.0 + bc_w3(a) / (bc_w2(a) + bc_w3(a)); }

// Filament's refraction roughness (evaluateRefraction): mix(r, 0, saturate(3 / ior - 2)) (IOR 1: 0,
// 1.5 and above: r as it is).
float filament_refraction_roughness(float roughness, float ior) {
    return roughness * (1.0 - clamp(3.0 / ior - 2.0, 0.0, 1.0));
}

// The direction leaving the object (Filament REFRACTION_MODE_CUBEMAP), v towards the eye, ior >= 1.
// Thin (thickness 0, refractionThinSphere): the view ray itself, -v (the slab offsets the ray, not its
// direction, and a cube lookup has no position). Solid (refractionSolidSphere, a sphere of diameter
// thickness): r = refract(-v, n, 1 / ior) enters, runs the chord, and leaves through the normal
// n1 = normalize(dot(n, r) r - n / 2): refract(r, n1, ior); where that is total internal reflection
// (refract's zero vector), r itself.
vec3 refraction_direction(vec3 n, vec3 v, float ior, float thickness) {
    if (thickness <= 0.0) return -v;
    vec3 r = refract(-v, n, 1.0 / ior);
    vec3 n1 = normalize(dot(n, r) * r - n * 0.5);
    vec3 o = refract(r, n1, ior);
    return dot(o, o) > 0.0 ? normalize(o) : r;
}
