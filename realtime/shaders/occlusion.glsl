// occlusion.glsl: ambient and specular occlusion of the image-based lighting. Numpy twins of the
// same names: pbrcheck/occlusion.py. SPECULAR_OCCLUSION (pbrcheck.registry.SPECULAR_OCCLUSIONS)
// selects specular_occlusion(). ao in [0, 1] (1: unoccluded), roughness perceptual.

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

// The specular occlusion factor of the selected method (1 for none).
float specular_occlusion(float NoV, float ao, float roughness) {
#if SPECULAR_OCCLUSION == SPECULAR_OCCLUSION_LAGARDE
    return specular_occlusion_lagarde(NoV, ao, roughness);
#else
    return 1.0;
#endif
}
