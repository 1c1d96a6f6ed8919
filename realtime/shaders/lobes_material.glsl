// lobes_material.glsl: the pure terms the material composition's lobes add around the engines' forms
// (material_lobes.glsl): KHR_materials_specular's dielectric F0 / F90 and the split sum with F90, the
// anisotropy direction, the ray-cast sphere's tangent. Numpy twins of the same names in
// realtime/lobes.py (tests/test_realtime_material_lobes.py, grids with the extremes).
#include "common.glsl"

// Source: KHR_materials_specular README "Implementation" / "Interaction with other extensions"
// (pbrcheck.lobes.specular_f0). Equation: min(F0_ior specularColor, 1) specularFactor.
vec3 specular_dielectric_f0(float f0_ior, float factor, vec3 color) {
    return min(f0_ior * color, vec3(1.0)) * factor;
}

// Source: KHR_materials_specular README (dielectric_f90 = specularFactor), blended to the metal's F90 = 1 as
// glTF's mix(dielectric, metal, metallic). Equation: f90 + (1 - f90) metallic (exactly 1 at f90 = 1).
float specular_f90_blend(float f90, float metallic) {
    return f90 + (1.0 - f90) * metallic;
}

// Source: the split sum [Karis13] with Schlick's F90 kept: int (F0 + (F90 - F0)(1 - v.h)^5) f cos =
// F0 A + F90 B (A, B the DFG LUT's). Equation: F0 A + F90 B.
vec3 split_sum_albedo_f90(vec3 F0, float F90, float A, float B) {
    return F0 * A + F90 * B;
}

// Source: KHR_materials_anisotropy README ("anisotropyRotation ... counter-clockwise from the tangent").
// Equation: normalize(cos(rot) T + sin(rot) (n x T)).
vec3 aniso_direction(vec3 T, vec3 n, float rotation) {
    return normalize(cos(rotation) * T + sin(rotation) * cross(n, T));
}

// Source: Mitsuba 3's sphere (dp/du of u = phi / 2 pi about the local z axis), the convention the
// reference's anisotropic spheres use. Equation: normalize(-n.y, n.x, 0); +X where |(-n.y, n.x)| <= 1e-6.
vec3 sphere_tangent(vec3 n) {
    vec3 t = vec3(-n.y, n.x, 0.0);
    float l = length(t);
    return l > 1e-6 ? t / l : vec3(1.0, 0.0, 0.0);
}
