// specular_aa.glsl: specular anti-aliasing and normal-map filtering, the roughness widened by the
// variance of the normals a pixel covers: alpha'^2 = min(alpha^2 + v, 1), alpha = roughness^2
// (perceptual in, perceptual out). Numpy twins of the same names: pbrcheck/specular_aa.py (its
// docstring derives each variance). SPECULAR_AA (pbrcheck.registry.SPECULAR_AAS) selects
// specular_aa() (dispatch generated from the registry, included at the end); the raster pass (raster.frag) supplies its inputs.

// Equation: min(alpha^2 + v, 1)^(1/4), alpha = roughness^2; roughness itself where v = 0 (a flat
// normal map, a plane's zero derivatives change nothing, to the bit).
float specular_aa_widen(float roughness, float variance) {
    float a = roughness * roughness;
    return variance > 0.0 ? sqrt(sqrt(clamp(a * a + variance, 0.0, 1.0))) : roughness;
}

// Source: Toksvig 2005, "Mipmapping Normal Maps", JGT 10(3): sigma^2 = (1 - L) / L from the length L
// of the mip-filtered normal; 1/s' = 1/s + sigma^2 with s = 2 / alpha^2. Equation: alpha^2 + 2 (1 - L) / L.
float specular_aa_toksvig(float roughness, float normal_length) {
    float L = clamp(normal_length, 1e-4, 1.0);
    return specular_aa_widen(roughness, 2.0 * (1.0 - L) / L);
}

// Source: Kaplanyan et al. 2016, "Filtering Distributions of Normals for Shading Antialiasing";
// Tokuyoshi & Kaplanyan 2019, "Improved Geometric Specular Antialiasing"; Filament's normalFiltering
// (specularAntiAliasingVariance 0.15, specularAntiAliasingThreshold 0.2). Equation: alpha^2 +
// min(2 x 0.15 (|dn/dx|^2 + |dn/dy|^2), 0.2), dn2 = |dn/dx|^2 + |dn/dy|^2 of the geometric normal.
float specular_aa_screen_space(float roughness, float dn2) {
    return specular_aa_widen(roughness, min(2.0 * 0.15 * dn2, 0.2));
}

// Source: Olano & Baker 2010, "LEAN Mapping" (slope second moments), baked per mip beside the normal
// map's chain (pbrcheck.specular_aa.slope_variance_mips). Equation: alpha^2 + var(s_x) + var(s_y).
float specular_aa_prefiltered(float roughness, float variance) {
    return specular_aa_widen(roughness, max(variance, 0.0));
}

// specular_aa(roughness, normal_length, variance, dn2): the selected member's function (roughness
// unchanged for none), and SPECULAR_AA_READS_<INPUT> for the inputs it reads; generated from the registry.
#include "specular_aa_dispatch.glsl"
