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

// ---- the direct lights' anisotropic GGX (KHR_materials_anisotropy README "Implementation") -------------
// Under a point, spot or directional light the base's specular lobe is the README's anisotropic GGX
// itself (no bend: a light has a half vector), in the frame of the IBL path and the reference: t the
// anisotropy direction (aniso_direction of the tangent), b = n x t, alpha = max(r^2, MIN_ALPHA) along b.

// Source: KHR_materials_anisotropy README (alpha_t = mix(alpha, 1, anisotropyStrength^2)), written as the
// truth writes mix (pbrcheck.lobes.AnisotropicGGX, reference.lobe_bsdf). Equation: alpha (1 - s^2) + s^2.
float aniso_alpha_t(float alpha, float s) {
    float s2 = s * s;
    return alpha * (1.0 - s2) + 1.0 * s2;
}

// Source: KHR_materials_anisotropy README D_GGX_anisotropic ([Heitz14] eq. 85). Equation: a2 = at ab,
// f = (ab t.h, at b.h, a2 n.h), w2 = a2 / f.f, D = a2 w2^2 / pi (= 1 / (pi at ab ((t.h/at)^2 + (b.h/ab)^2
// + (n.h)^2)^2)); 0 for n.h <= 0. f.f >= (a2 n.h)^2 >= 1e-28 at the alpha floor: a normal float32.
float D_GGX_anisotropic(float NoH, float ToH, float BoH, float at, float ab) {
    float a2 = at * ab;
    vec3 f = vec3(ab * ToH, at * BoH, a2 * NoH);
    float w2 = a2 / dot(f, f);
    return NoH > 0.0 ? a2 * w2 * w2 / PI : 0.0;
}

// Source: KHR_materials_anisotropy README V_GGX_anisotropic (the height-correlated Smith [Heitz14] eq. 99
// with the anisotropic Lambda of eq. 86, divided by 4 (n.v)(n.l)), without the README's real-time clamp
// to 1 (saturate): the truth (pbrcheck.lobes.AnisotropicGGX.brdf) has none, and the clamp only bites at
// grazing on a near mirror. Equation: 0.5 / ((n.l) |(at t.v, ab b.v, n.v)| + (n.v) |(at t.l, ab b.l, n.l)|).
float V_GGX_anisotropic(float NoV, float NoL, float ToV, float BoV, float ToL, float BoL, float at, float ab) {
    float GGXV = NoL * length(vec3(at * ToV, ab * BoV, NoV));
    float GGXL = NoV * length(vec3(at * ToL, ab * BoL, NoL));
    return 0.5 / max(GGXV + GGXL, COS_EPS);
}

// A light's anisotropic specular lobe without Fresnel, D V (the BRDF's D G / (4 (n.v)(n.l))), at
// alpha (= max(roughness^2, MIN_ALPHA)) and strength s; n, t unit and orthogonal, b = n x t; 0 below
// either horizon.
float aniso_specular_dv(vec3 n, vec3 t, vec3 b, vec3 v, vec3 l, float alpha, float s) {
    float NoV = dot(n, v);
    float NoL = dot(n, l);
    if (NoV <= 0.0 || NoL <= 0.0) return 0.0;
    vec3 h = v + l;
    h = h / max(length(h), COS_EPS);
    float at = aniso_alpha_t(alpha, s);
    return D_GGX_anisotropic(clamp(dot(n, h), 0.0, 1.0), dot(t, h), dot(b, h), at, alpha)
           * V_GGX_anisotropic(NoV, NoL, dot(t, v), dot(b, v), dot(t, l), dot(b, l), at, alpha);
}
