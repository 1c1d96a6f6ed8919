// energy.glsl: multiple-scattering energy compensation of the split sum's specular lobe.
// ENERGY_COMPENSATION: a constant of pbrcheck.registry.ENERGY_COMPENSATIONS, whose members name their
// role functions here (energy_scale_<name>, energy_ms_<name>, energy_direct_<name>); the dispatch
// energy_scale / energy_ms / energy_direct is generated from it (energy_dispatch.glsl). Numpy twins
// of the same names in pbrcheck/energy.py, Dr.Jit twins in reference/energy.py (tests/test_energy.py
// runs them on the same grids). Ess = A + B: the single-scattering directional albedo at F0 = 1.

// Source: Kulla & Conty 2017 slide 20, Fdez-Aguera 2019 eq. 11.
// Equation: Favg = 2 int F(mu) mu dmu = F0 + (1 - F0) / 21 for Schlick's F.
vec3 F_avg_Schlick(vec3 F0) {
    return F0 + (1.0 - F0) / 21.0;
}

// Source: Filament documentation, "Energy loss in specular reflectance" (sec. 4.7.2).
// Equation: specular *= 1 + F0 (1 / Ess - 1) (Filament's dfg.y = A + B).
vec3 energy_filament(vec3 F0, float Ess) {
    return 1.0 + F0 * (1.0 / max(Ess, 1e-4) - 1.0);
}

// Source: Fdez-Aguera 2019, JCGT 8(1), eq. 9-13 (listing 1).
// Equation: FssEss = F0 A + B, Ems = 1 - Ess, Fms = FssEss Favg / (1 - Ems Favg); returns Fms Ems,
// the albedo that multiplies the cosine-weighted irradiance E(n) / pi.
vec3 ms_fdez_aguera(vec3 F0, float A, float B) {
    vec3 FssEss = F0 * A + B;
    float Ems = 1.0 - (A + B);
    vec3 Favg = F_avg_Schlick(F0);
    vec3 Fms = FssEss * Favg / (1.0 - Ems * Favg);
    return Fms * Ems;
}

// Source: Kulla & Conty 2017, "Revisiting Physically Based Shading at Imageworks", slides 16-22.
// Equation: f_ms = (1 - E(mu_o)) (1 - E(mu_i)) / (pi (1 - Eavg)), F_ms = Favg^2 Eavg / (1 - Favg (1 - Eavg));
// under irradiance E(n) the lobe reflects F_ms (1 - E(mu_o)) E(n) / pi: returns F_ms (1 - Ess).
vec3 ms_kulla_conty(vec3 F0, float Ess, float Eavg) {
    vec3 Favg = F_avg_Schlick(F0);
    vec3 Fms = Favg * Favg * Eavg / (1.0 - Favg * (1.0 - Eavg));
    return Fms * (1.0 - Ess);
}

// Kulla-Conty's Eavg(roughness) = 2 int E(mu) mu dmu, baked by pbrcheck.energy.bake_kc_eavg (GGX,
// height-correlated Smith): KC_EAVG_SIZE entries at roughness j / (KC_EAVG_SIZE - 1), linear between.
const int KC_EAVG_SIZE = 17;
const float KC_EAVG[17] = float[17](
    1.0000000, 0.9999079, 0.9988651, 0.9952562, 0.9872503, 0.9731154, 0.9514348, 0.9212760, 0.8823234,
    0.8349606, 0.7802779, 0.7199813, 0.6562014, 0.5912315, 0.5272513, 0.4660994, 0.4091371);

float kc_eavg(float roughness) {
    float x = clamp(roughness, 0.0, 1.0) * float(KC_EAVG_SIZE - 1);
    int i = min(int(floor(x)), KC_EAVG_SIZE - 2);
    return mix(KC_EAVG[i], KC_EAVG[i + 1], x - float(i));
}

// Source: Kulla & Conty 2017 slide 18. Equation: the multiple-scattering lobe for direct light,
// f_ms = F_ms (1 - E(mu_o)) (1 - E(mu_i)) / (pi (1 - Eavg)) (a BRDF value, without the cosine).
vec3 f_ms_kulla_conty(vec3 F0, float Ev, float El, float Eavg) {
    vec3 Favg = F_avg_Schlick(F0);
    vec3 Fms = Favg * Favg * Eavg / (1.0 - Favg * (1.0 - Eavg));
    return Fms * (1.0 - Ev) * (1.0 - El) / (PI * max(1.0 - Eavg, 1e-6));
}

// The members' role functions (pbrcheck.registry.ENERGY_COMPENSATIONS): a member without a role is
// the identity there (scale 1, nothing added).
// Source: Filament sec. 4.7.2. Equation: the split sum's specular factor 1 + F0 (1 / (A + B) - 1).
vec3 energy_scale_filament(vec3 F0, float A, float B) {
    return energy_filament(F0, A + B);
}

// Source: Filament's direct lobe (energyCompensation). Equation: adds (scale - 1) f_spec to the
// single-scattering BRDF of a point light.
vec3 energy_direct_filament(vec3 f_spec, vec3 F0, float A, float B, float El, float roughness) {
    return (energy_filament(F0, A + B) - 1.0) * f_spec;
}

// Source: Fdez-Aguera 2019 eq. 9-13. Equation: adds Fms Ems times E(n) / pi (image-based light only).
vec3 energy_ms_fdez_aguera(vec3 F0, float A, float B, float roughness) {
    return ms_fdez_aguera(F0, A, B);
}

// Source: Kulla & Conty 2017 slides 16-22. Equation: adds F_ms (1 - (A + B)) times E(n) / pi,
// E_avg = kc_eavg(roughness).
vec3 energy_ms_kulla_conty(vec3 F0, float A, float B, float roughness) {
    return ms_kulla_conty(F0, A + B, kc_eavg(roughness));
}

// Source: Kulla & Conty 2017 slide 18. Equation: adds the lobe f_ms (E(mu_o) = A + B, E(mu_i) = El)
// to a point light's BRDF.
vec3 energy_direct_kulla_conty(vec3 f_spec, vec3 F0, float A, float B, float El, float roughness) {
    return f_ms_kulla_conty(F0, A + B, El, kc_eavg(roughness));
}

// energy_scale (the split sum's specular factor), energy_ms (the multiply scattered albedo added
// times E(n) / pi) and energy_direct (added to a point light's BRDF), generated from the registry.
#include "energy_dispatch.glsl"
