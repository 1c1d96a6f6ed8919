// lights.glsl: the scene's punctual lights (pbrcheck/lights.py has the conventions; numpy twin of the
// same name: pbrcheck.lights.spot_attenuation). LIGHT_POINT, LIGHT_SPOT, LIGHT_DIRECTIONAL are the
// indices of pbrcheck.lights.LIGHT_TYPES (prepended to every shader with the registry's constants).
// Lights buffer (shading.glsl), 3 vec4 per light: position.xyz, type; intensity.rgb (W/sr; W/m^2 for
// a directional light), cos(outer cone); direction.xyz (where the light shines: the spot's axis,
// the directional light's travel; unit), cos(inner cone).

// The length of a directional light's shadow ray (occluded(p, l, dist)): unbounded in practice.
#define LIGHT_FAR 3.0e38

// Source: KHR_lights_punctual, "Inner and Outer Cone Angles" (its recommended implementation).
// Equation: saturate(cd scale + offset)^2, scale = 1 / max(0.001, cos_inner - cos_outer),
// offset = -cos_outer scale; cd = cos of the angle between the spot's axis and light -> point.
float spot_attenuation(float cd, float cos_outer, float cos_inner) {
    float scale = 1.0 / max(0.001, cos_inner - cos_outer);
    float offset = -cos_outer * scale;
    float a = clamp(cd * scale + offset, 0.0, 1.0);
    return a * a;
}
