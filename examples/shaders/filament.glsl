// Filament's image-based-lighting choices as pbrcheck shader hooks (docs/hooks.md).
// Written from the equations published in "Physically Based Rendering in Filament" (Guy & Agopian,
// google.github.io/filament/Filament.html), not from Filament's source:
//   sec. 5.3.4.4 (pre-filtered importance sampling): the mip level of a perceptual roughness r is
//     lod = M r (2 - r)  (perceptualRoughnessToLod; M = the last level of the chain);
//   sec. 4.7.2 (energy loss in specular reflectance): specular *= 1 + F0 (1 / dfg.y - 1), where
//     dfg.y = A + B is the single-scattering directional albedo at F0 = 1 (the DFG LUT's sum).
// Filament's DFG is the split sum's LUT with the height-correlated Smith term, which is pbrcheck's
// built-in LUT (lut_geometry = scene, the scenes' smith_ggx_correlated), so no hook_dfg here; its
// irradiance is 9 SH coefficients: use it with --set irradiance=sh9. With that option this file
// renders what the `filament` preset renders (tests/test_hooks.py checks they are identical).

// lod = M x (2 - x), x = clamp(r, 0, 1): more of the chain for the low roughnesses.
float hook_lod(float roughness, float max_lod, float cube_log2) {
    float x = clamp(roughness, 0.0, 1.0);
    return max_lod * x * (2.0 - x);
}

// 1 + F0 (1 / Ess - 1), Ess = A + B; Ess >= 1e-4 guards the division at the LUT's grazing corner.
vec3 hook_energy_compensation(vec3 F0, float A, float B, float roughness) {
    return 1.0 + F0 * (1.0 / max(A + B, 1e-4) - 1.0);
}
