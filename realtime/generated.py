"""GLSL generated from the registries (:mod:`pbrcheck.registry`, :mod:`realtime.registry`): the
switches' named constants (:func:`glsl_defines`: ``#define GEOMETRY_SMITH_GGX_CORRELATED 0``; a shader
switches with ``#if GEOMETRY == GEOMETRY_SMITH_GGX_CORRELATED``, the caller selects with
:meth:`pbrcheck.registry.Registry.select`) and the dispatch functions that call each member's GLSL
function (:func:`glsl_generated`), included by the shaders by name (:func:`realtime.gl.assemble`).
``pbrcheck shaders --dump DIR`` writes them beside the shader files (:mod:`realtime.commands`).

API
---
:func:`glsl_defines`, :func:`glsl_generated`, :func:`lobe_members_include`.
"""

from __future__ import annotations

from pbrcheck.lights import glsl_light_constants
from pbrcheck.lodmap import LOD_MAPPINGS
from pbrcheck.registry import NDFS, Registry

from .registry import LOBE_REGISTRIES, REGISTRIES, ROLE_REGISTRIES, SHADINGS, TERM_REGISTRIES, role_reads


def glsl_defines() -> dict[str, int]:
    """Every registry's named constants and the light types' (prepended to every shader by :func:`realtime.gl.assemble`)."""
    out: dict[str, int] = {}
    for r in REGISTRIES.values():
        out.update(r.constants())
    out.update(glsl_light_constants())  # the light types (pbrcheck.lights.LIGHT_TYPES)
    return out


def _lod_dispatch() -> str:
    """``lod_from_roughness`` and ``roughness_from_lod``, each calling the selected mapping's
    ``lod`` / ``roughness`` role functions (``realtime/shaders/lod.glsl``). ``fitted`` reads through
    ``LOD_FITTED(r)`` (a ``#define`` of the fitted expression, frame pass only) and bakes nothing."""
    lines = ["// Generated from pbrcheck.lodmap.LOD_MAPPINGS: do not edit.",
             "float lod_from_roughness(float r, float max_lod, float cube_log2) {"]
    for i, e in enumerate(LOD_MAPPINGS):
        kw = "#if" if i == 0 else "#elif"
        lines.append(f"{kw} LOD_MAPPING == {LOD_MAPPINGS.constant(e.name)}")
        if e.extra["builtin"]:
            lines.append(f"    return {e.roles['lod'].glsl}(r, max_lod, cube_log2);")
        else:
            lines.append("    return min(LOD_FITTED(r), max_lod);")
    lines += ["#endif", "}", "",
              "// The inverse: the roughness each prefiltered level is baked at (built-in mappings only;",
              "// a fitted mapping reads the chain its file names, baked with that built-in mapping).",
              "float roughness_from_lod(float lod, float max_lod, float cube_log2) {",
              "    if (max_lod <= 0.0) return 0.0;"]
    first = True
    for e in LOD_MAPPINGS:
        if not e.extra["builtin"]:
            continue
        lines.append(f"{'#if' if first else '#elif'} LOD_MAPPING == {LOD_MAPPINGS.constant(e.name)}")
        lines.append(f"    return {e.roles['roughness'].glsl}(lod, max_lod, cube_log2);")
        first = False
    lines += ["#else", "    return -1.0;  // not a baking mapping", "#endif", "}", ""]
    return "\n".join(lines)


def _switch_lines(registry: Registry, body) -> list[str]:
    """``#if``/``#elif`` on ``registry``'s switch, one branch per member with the lines
    ``body(entry)``, and an ``#error`` for a value no member has."""
    lines = []
    for i, e in enumerate(registry):
        lines.append(f"#{'if' if i == 0 else 'elif'} {registry.define} == {registry.constant(e.name)}")
        lines += body(e)
    return lines + ["#else", f"#error {registry.define} names no member of its registry", "#endif"]


def _terms_dispatch() -> str:
    """``ndf_term``, ``geometry_term`` and ``fresnel_term``: the user's hook where the frame pass
    defines it (hooks.glsl), else the selected member's GLSL function at its width."""
    lines = ["// Generated from pbrcheck.registry (NDFS, GEOMETRIES, FRESNELS): do not edit.",
             "// Each term function is the selected member's GLSL function (brdf.glsl), called with the",
             "// member's width (alpha_from_roughness, k_schlick_ibl, k_schlick_direct) of roughness."]
    for define, (registry, signature, hook) in TERM_REGISTRIES.items():
        params = [p.split()[-1] for p in signature[signature.index("(") + 1:-1].split(",")]

        def call(e, params=params):
            args = [f"{e.term.glsl_width}({p})" if p == "roughness" and e.term.glsl_width else p for p in params]
            return [f"    return {e.term.glsl}({', '.join(args)});"]

        lines += ["", f"#ifndef {define}", f"#define {define} {registry.constant(registry.names[0])}", "#endif",
                  signature + " {", f"#ifdef HOOK_{hook[5:hook.index('(')]}", f"    return {hook};",
                  *["#el" + line[1:] if i == 0 else line for i, line in enumerate(_switch_lines(registry, call))],
                  "}"]
    return "\n".join(lines) + "\n"


def _sampling_dispatch() -> str:
    """``sample_ndf(u, alpha)``: a half vector drawn from the selected NDF's ``D (n.h)`` (its term's
    ``glsl_sample``)."""
    lines = ["// Generated from pbrcheck.registry.NDFS: do not edit.",
             "vec3 sample_ndf(vec2 u, float alpha) {",
             *_switch_lines(NDFS, lambda e: [f"    return {e.term.glsl_sample}(u, alpha);"]), "}", ""]
    return "\n".join(lines)


def _roles_dispatch(define: str) -> str:
    """Each role's dispatch function of the role registry ``define`` (:data:`ROLE_REGISTRIES`): the
    selected member's role function called with the dispatch's parameters, or the identity for a
    member without that role."""
    registry, _, default, roles = ROLE_REGISTRIES[define]
    lines = [f"// Generated from the registry {define}S (realtime.registry.ROLE_REGISTRIES): do not edit.",
             f"#ifndef {define}", f"#define {define} {registry.constant(default)}", "#endif"]
    for role, (signature, identity) in roles.items():
        params = _params(signature)

        def body(e, role=role, identity=identity, params=params):
            if role not in e.roles:
                return [f"    return {identity};"]
            return [f"    return {e.roles[role].glsl}({', '.join(e.roles[role].args or params)});"]

        lines += ["", signature + " {", *_switch_lines(registry, body), "}"]
        reads = _reads_lines(registry, role, signature)
        if reads:
            lines[4:4] = ["", "// The inputs the selected member reads (a pass computes only these).", *reads]
    return "\n".join(lines) + "\n"


def _params(signature: str) -> list[str]:
    """The parameter names of a GLSL signature."""
    return [p.split()[-1] for p in signature[signature.index("(") + 1:-1].split(",")]


def _reads_lines(registry: Registry, role: str, signature: str) -> list[str]:
    """``#define <SWITCH>_READS_<PARAM>`` for each parameter the selected member's ``role`` function
    reads (:attr:`~pbrcheck.registry.Role.args`), where some member reads fewer than all: empty otherwise."""
    if not any(role in e.roles and e.roles[role].args for e in registry):
        return []
    params = _params(signature)
    return _switch_lines(registry, lambda e: [f"#define {registry.define}_READS_{p.upper()} 1" for p in params
                                              if role_reads(registry, e.name, role, p)])


def _shading_dispatch() -> str:
    """``light_brdf`` (a point light's BRDF) and ``shade_composition`` (the outgoing radiance): the
    selected composition's ``light_brdf_<name>`` / ``shade_<name>`` (:data:`SHADINGS`; the pixel seed
    to a composition with ``extra["seeded"]``)."""
    def shade(e):
        return [f"    return shade_{e.name}(c{', pixel_seed' if e.extra['seeded'] else ''});"]

    lines = ["// Generated from realtime.registry.SHADINGS: do not edit.",
             "vec3 light_brdf(Shading c, vec3 l, float NoL) {",
             *_switch_lines(SHADINGS, lambda e: [f"    return light_brdf_{e.name}(c, l, NoL);"]), "}", "",
             "vec3 shade_composition(Shading c, uint pixel_seed) {", *_switch_lines(SHADINGS, shade), "}", ""]
    return "\n".join(lines)


def lobe_members_include(shader: str) -> str:
    """The include name of the GLSL the members of lobe file ``shader``'s registries hold
    (``lobes_sheen.glsl`` -> ``lobes_sheen_members.glsl``)."""
    return shader.replace(".glsl", "_members.glsl")


def _lobe_members(shader: str) -> str:
    """The GLSL held by the members (``Entry.extra["glsl"]``) of the lobe registries of ``shader``
    (:data:`realtime.registry.LOBE_REGISTRIES`), each inside ``#if SWITCH == SWITCH_MEMBER``: compiled only
    into the programs that select it."""
    lines = [f"// Generated from realtime.registry.LOBE_REGISTRIES ({shader}'s members' own GLSL): do not edit."]
    for define, (registry, include, _, _) in LOBE_REGISTRIES.items():
        for e in registry:
            if include == shader and "glsl" in e.extra:
                lines += [f"#if {define} == {registry.constant(e.name)}", e.extra["glsl"].strip("\n"), "#endif"]
    return "\n".join(lines) + "\n"


def glsl_generated() -> dict[str, str]:
    """Generated GLSL sources by include name: ``lod_dispatch.glsl`` (:func:`_lod_dispatch`),
    ``terms_dispatch.glsl`` (:func:`_terms_dispatch`), ``sampling_dispatch.glsl``
    (:func:`_sampling_dispatch`), ``shading_dispatch.glsl`` (:func:`_shading_dispatch`), and each role
    registry's (:func:`_roles_dispatch`): ``energy_dispatch.glsl``, ``runtime_sampling_dispatch.glsl``,
    ``dfg_sampling_dispatch.glsl``, ``specular_occlusion_dispatch.glsl``,
    ``horizon_occlusion_dispatch.glsl``, ``specular_aa_dispatch.glsl``; and each lobe file's members' own
    GLSL (:func:`_lobe_members`): ``lobes_sheen_members.glsl``, ``lobes_anisotropy_members.glsl``, ...."""
    out = {"lod_dispatch.glsl": _lod_dispatch(), "terms_dispatch.glsl": _terms_dispatch(),
           "sampling_dispatch.glsl": _sampling_dispatch(), "shading_dispatch.glsl": _shading_dispatch()}
    out.update({include: _roles_dispatch(define) for define, (_, include, _, _) in ROLE_REGISTRIES.items()})
    out.update({lobe_members_include(shader): _lobe_members(shader)
                for shader in sorted({include for _, include, _, _ in LOBE_REGISTRIES.values()})})
    return out
