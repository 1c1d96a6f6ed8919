// occlusion.glsl: ambient and specular occlusion of the image-based lighting. Numpy twins of the
// same names: pbrcheck/occlusion.py. SPECULAR_OCCLUSION (pbrcheck.registry.SPECULAR_OCCLUSIONS)
// selects specular_occlusion(), HORIZON_OCCLUSION (HORIZON_OCCLUSIONS) horizon_occlusion(), both
// dispatches generated from the registry (included at the end). ao in
// [0, 1] (1: unoccluded), roughness perceptual, alpha = roughness^2.

// Source: glTF 2.0 specification 3.9.4 (occlusionTexture.strength). Equation: 1 + strength (r - 1).
float occlusion_from_texture(float texel_r, float strength) {
    return 1.0 + strength * (texel_r - 1.0);
}

// Source: Lagarde & de Rousiers 2014, "Moving Frostbite to PBR", 4.10.2, listing 26 (alpha = the
// GGX width, roughness^2). Equation: saturate((n.v + ao)^exp2(-16 alpha - 1) - 1 + ao).
float specular_occlusion_lagarde(float NoV, float ao, float roughness) {
    float alpha = roughness * roughness;
    return clamp(pow(NoV + ao, exp2(-16.0 * alpha - 1.0)) - 1.0 + ao, 0.0, 1.0);
}

// Source: Oat & Sander 2007, "Ambient Aperture Lighting", the approximation Jimenez et al. 2016 use.
// Equation: the fraction of cap 2 inside cap 1 (apertures r1 = acos(c1), r2 = acos(c2), axes
// d = acos(cd) apart): min(1, (1 - c1) / (1 - c2)) x (1 if min(r1, r2) <= max(r1, r2) - d, 0 if
// r1 + r2 <= d, else smoothstep(x)), x = 1 - (d - |r1 - r2|) / (r1 + r2 - |r1 - r2|).
float cone_cone_intersection(float cos_cap1, float cos_cap2, float cos_distance) {
    float r1 = acos(clamp(cos_cap1, -1.0, 1.0));
    float r2 = acos(clamp(cos_cap2, -1.0, 1.0));
    float d = acos(clamp(cos_distance, -1.0, 1.0));
    // min(1, .) rather than a branch on c2 >= c1: two caps of zero size (c1 = c2 = 1, e.g. ao = 0
    // against a mirror lobe whose cos_s rounds to 1 in float32) overlap by 0, not 1.
    float ratio = min(1.0, (1.0 - cos_cap1) / max(1.0 - cos_cap2, 1e-30));
    if (min(r1, r2) <= max(r1, r2) - d) return ratio;
    if (r1 + r2 <= d) return 0.0;
    float delta = abs(r1 - r2);
    float x = 1.0 - clamp((d - delta) / max(r1 + r2 - delta, 1e-4), 0.0, 1.0);
    return ratio * x * x * (3.0 - 2.0 * x);
}

// Source: Jimenez, Wu, Pesce, Jarabo 2016, "Practical Realtime Strategies for Accurate Indirect
// Occlusion" (GTSO), sec. 6; the specular cone's aperture as Filament's SpecularAO_Cones fits it.
// Equation: I(sqrt(1 - ao)) / I(0), I(c) = cone_cone_intersection(c, exp2(-3.321928 alpha^2), n.v)
// (bent normal = shading normal; over the unoccluded hemisphere's so that ao = 1 gives 1).
float specular_occlusion_gtso(float NoV, float ao, float roughness) {
    float alpha = roughness * roughness;
    float cos_s = exp2(-3.321928 * alpha * alpha);
    float occluded = cone_cone_intersection(sqrt(max(1.0 - ao, 0.0)), cos_s, NoV);
    float unoccluded = cone_cone_intersection(0.0, cos_s, NoV);
    // The branch, not the division, gives exactly 1 where nothing is occluded: NVIDIA divides as
    // x * rcp(y), so x / x can be 1 - 2^-24 (measured on an H100).
    return occluded >= unoccluded ? 1.0 : clamp(occluded / max(unoccluded, 1e-6), 0.0, 1.0);
}

// Source: Russell 2015 (Marmoset), "Horizon Occlusion for Normal Mapped Reflections"; Jimenez et
// al. 2016. Equation: saturate(1 + 1.3 r.n_g)^2, n_g the geometric (interpolated vertex) normal.
float horizon_occlusion_marmoset(float RoNg) {
    float h = clamp(1.0 + 1.3 * RoNg, 0.0, 1.0);
    return h * h;
}

// specular_occlusion(NoV, ao, roughness) and horizon_occlusion(RoNg), RoNg = dot(r, n_g): the
// selected member's function (1 for none), generated from the registry.
#include "specular_occlusion_dispatch.glsl"
#include "horizon_occlusion_dispatch.glsl"
