// lobes_anisotropy.glsl: the engines' bent normal / bent reflection for KHR_materials_anisotropy's
// image-based lighting: a prefiltered (isotropic) cube read along a direction bent toward the plane
// the stretched lobe spans. Every function has a numpy twin of the same name in realtime/lobes.py.
// Arguments: n the shading normal, t the anisotropy direction (tangent rotated by the extension's
// rotation), b = n x t, v the view direction, s the strength (anisotropyStrength; Filament's and
// Babylon's signed anisotropy), r the perceptual roughness.
// Switches (members of realtime.registry.ANISOTROPY_BENDS, by index):
#define ANISOTROPY_BEND_SAMPLE_VIEWER 0
#define ANISOTROPY_BEND_THREEJS 1
#define ANISOTROPY_BEND_FILAMENT 2
#define ANISOTROPY_BEND_BABYLON 3
#define ANISOTROPY_BEND_FITTED 4
#ifndef ANISOTROPY_BEND
#define ANISOTROPY_BEND ANISOTROPY_BEND_SAMPLE_VIEWER
#endif
#include "common.glsl"

// Source: [McAuley15] (Far Cry 4): the normal of the plane holding the grain direction d that faces v
// most. Equation: (d x v) x d (length |d x v|, not normalized).
vec3 mcauley_normal(vec3 d, vec3 v) {
    return cross(cross(d, v), d);
}

// The Sample Viewer's and three.js's weight of n against the bent plane's normal: (1 - s (1 - r))^4.
float aniso_bend_weight(float s, float r) {
    float w = 1.0 - s * (1.0 - r);
    w *= w;
    return w * w;
}

// The registry members' own GLSL (realtime/fitted_lobes.py's weight table and reader for
// ANISOTROPY_BEND_FITTED), inside #if on the switch: generated from the entries' extra["glsl"].
#include "lobes_anisotropy_members.glsl"

// Source: glTF-Sample-Viewer ibl.glsl getIBLRadianceAnisotropy (called with anisotropicB).
// Equation: normalize(mix((b x v) x b, n, (1 - s (1 - r))^4)), the plane's normal unnormalized.
vec3 aniso_bent_normal_sample_viewer(vec3 n, vec3 t, vec3 b, vec3 v, float s, float r) {
    return normalize(mix(mcauley_normal(b, v), n, aniso_bend_weight(s, r)));
}

// Source: three.js getIBLAnisotropyRadiance. Equation: as the Sample Viewer's with the plane's normal
// normalized first: normalize(mix(normalize((b x v) x b), n, (1 - s (1 - r))^4)).
vec3 aniso_bent_normal_threejs(vec3 n, vec3 t, vec3 b, vec3 v, float s, float r) {
    return normalize(mix(normalize(mcauley_normal(b, v)), n, aniso_bend_weight(s, r)));
}

// Source: Filament sec. 5.3.6, light_indirect.fs getReflectedVector. Equation: d = s >= 0 ? b : t;
// normalize(mix(n, (d x v) x d, |s| saturate(5 r))).
vec3 aniso_bent_normal_filament(vec3 n, vec3 t, vec3 b, vec3 v, float s, float r) {
    vec3 d = s >= 0.0 ? b : t;
    return normalize(mix(n, mcauley_normal(d, v), abs(s) * saturate(5.0 * r)));
}

// Source: Babylon.js pbrHelperFunctions getAnisotropicBentNormals (ANISOTROPIC_LEGACY), [McAuley15].
// Equation: d = s >= 0 ? b : t; normalize(mix(n, (normalize(d) x v) x d, |s|)).
vec3 aniso_bent_normal_babylon(vec3 n, vec3 t, vec3 b, vec3 v, float s, float r) {
    vec3 d = s >= 0.0 ? b : t;
    return normalize(mix(n, mcauley_normal(normalize(d), v), abs(s)));
}

// The lookup directions: reflect(-v, bent normal) = 2 (v.n) n - v.
vec3 aniso_reflection_sample_viewer(vec3 n, vec3 t, vec3 b, vec3 v, float s, float r) {
    return normalize(reflect(-v, aniso_bent_normal_sample_viewer(n, t, b, v, s, r)));
}

vec3 aniso_reflection_filament(vec3 n, vec3 t, vec3 b, vec3 v, float s, float r) {
    return normalize(reflect(-v, aniso_bent_normal_filament(n, t, b, v, s, r)));
}

vec3 aniso_reflection_babylon(vec3 n, vec3 t, vec3 b, vec3 v, float s, float r) {
    return normalize(reflect(-v, aniso_bent_normal_babylon(n, t, b, v, s, r)));
}

#if ANISOTROPY_BEND == ANISOTROPY_BEND_FITTED
// Source: pbrcheck fit-lobes (docs/research.md): the Sample Viewer's bent normal with the weight fitted by
// AD. Equation: normalize(mix((b x v) x b, n, aniso_bend_weight_fitted(s, r))).
vec3 aniso_bent_normal_fitted(vec3 n, vec3 t, vec3 b, vec3 v, float s, float r) {
    return normalize(mix(mcauley_normal(b, v), n, aniso_bend_weight_fitted(s, r)));
}

vec3 aniso_reflection_fitted(vec3 n, vec3 t, vec3 b, vec3 v, float s, float r) {
    return normalize(reflect(-v, aniso_bent_normal_fitted(n, t, b, v, s, r)));
}
#endif

// Source: three.js envmap_physical_pars_fragment getIBLRadiance (every lookup, isotropic or not).
// Equation: normalize(mix(reflect(-v, n), n, r^2)).
vec3 threejs_reflection(vec3 n, vec3 v, float r) {
    return normalize(mix(reflect(-v, n), n, r * r));
}

// Source: three.js getIBLAnisotropyRadiance: its bent normal, then its lean of every lookup.
vec3 aniso_reflection_threejs(vec3 n, vec3 t, vec3 b, vec3 v, float s, float r) {
    return threejs_reflection(aniso_bent_normal_threejs(n, t, b, v, s, r), v, r);
}

// Dispatch on ANISOTROPY_BEND.
vec3 aniso_reflection(vec3 n, vec3 t, vec3 b, vec3 v, float s, float r) {
#if ANISOTROPY_BEND == ANISOTROPY_BEND_THREEJS
    return aniso_reflection_threejs(n, t, b, v, s, r);
#elif ANISOTROPY_BEND == ANISOTROPY_BEND_FILAMENT
    return aniso_reflection_filament(n, t, b, v, s, r);
#elif ANISOTROPY_BEND == ANISOTROPY_BEND_BABYLON
    return aniso_reflection_babylon(n, t, b, v, s, r);
#elif ANISOTROPY_BEND == ANISOTROPY_BEND_FITTED
    return aniso_reflection_fitted(n, t, b, v, s, r);
#else
    return aniso_reflection_sample_viewer(n, t, b, v, s, r);
#endif
}
