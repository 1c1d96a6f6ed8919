// hooks.glsl: prototypes of the user hooks (realtime/hooks.py HOOKS, docs/hooks.md). The frame pass
// defines HOOK_<NAME> for every hook the user's file (--shader FILE.glsl) defines; the file itself is
// appended after the entry point, so these prototypes let the built-in code call it. Without a
// define nothing here is declared and the built-in piece is used.
#ifdef HOOK_SPECULAR_IBL
vec3 hook_specular_ibl(vec3 n, vec3 v, float roughness, vec3 F0);
#endif
#ifdef HOOK_DIFFUSE_IBL
vec3 hook_diffuse_ibl(vec3 n);
#endif
#ifdef HOOK_DFG
vec2 hook_dfg(float NoV, float roughness);
#endif
#ifdef HOOK_LOD
float hook_lod(float roughness, float max_lod, float cube_log2);
#endif
#ifdef HOOK_ENERGY_COMPENSATION
vec3 hook_energy_compensation(vec3 F0, float A, float B, float roughness);
#endif
#ifdef HOOK_D
float hook_D(float NoH, float roughness);
#endif
#ifdef HOOK_G
float hook_G(float NoV, float NoL, float roughness);
#endif
#ifdef HOOK_F
vec3 hook_F(float VoH, vec3 F0);
#endif
#ifdef HOOK_SPECULAR_AA
float hook_specular_aa(float roughness, float normal_length, float normal_lod);
#endif
