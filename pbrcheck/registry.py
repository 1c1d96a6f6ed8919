"""Registries of pbrcheck's closed lists: one place names every member, Python owns it.

Each closed list (the scene's NDFs, geometry and Fresnel terms; the real-time renderer's LOD
mappings, shading compositions and runtime samplers) is a :class:`Registry` of :class:`Entry`.
Everything else is derived from it:

* the scene model's accepted values (:mod:`pbrcheck.scene`), the real-time options' choices
  (:mod:`realtime.presets`), the reference BSDF's checks (:mod:`reference.bsdf`), the numpy
  dispatch (:mod:`pbrcheck.brdf`);
* the GLSL ``#define`` lines (:func:`glsl_defines`): each member gets a named constant
  (``#define GEOMETRY_SMITH_GGX_CORRELATED 0``) and a shader switches with
  ``#if GEOMETRY == GEOMETRY_SMITH_GGX_CORRELATED``; the caller selects with
  ``{"GEOMETRY": "GEOMETRY_SMITH_GGX_CORRELATED"}`` (:meth:`Registry.select`);
* generated GLSL dispatch functions where a list maps to one function per member
  (:func:`glsl_generated`: ``lod_from_roughness`` / ``roughness_from_lod`` call the mapping's own
  ``lod_<name>`` / ``roughness_<name>``, :mod:`realtime.shaders` ``lod.glsl``; ``ndf_term`` /
  ``geometry_term`` / ``fresnel_term`` call the term's GLSL function; ``sample_ndf`` and
  ``runtime_half_vector`` the samplers');
* the docs' tables, checked against it by ``tests/test_registry.py``.

Adding a LOD mapping is one :data:`LOD_MAPPINGS` entry, its two GLSL functions in
``realtime/shaders/lod.glsl`` and their numpy twins of the same names in :mod:`pbrcheck.lodmap`.
The term registries (:data:`TERM_REGISTRIES`: NDFs, geometry and Fresnel terms) own their
implementations: each entry's :class:`Impl` names its numpy, Dr.Jit and GLSL functions and its
width; adding a G term is one :data:`GEOMETRIES` entry and its three functions (docs/realtime.md
has the worked example). An NDF also names its GLSL sampler (``extra["sample"]``, numpy twin in
:mod:`pbrcheck.sampling`) and has, under its D function's name without ``D_``, a quadrature pair in
:mod:`pbrcheck.brdf` (``_theta_h_<D>``, ``_cdf_theta_h_<D>``) and a Dr.Jit sampler pair in
:mod:`reference.bsdf` (``sample_h_<D>``, ``pdf_h_<D>``).

API
---
:class:`Impl`, :class:`Entry`, :class:`Registry`, :data:`TERM_REGISTRIES`, :data:`NDFS`, :data:`GEOMETRIES` (every G term; ``scene=False``
members exist in the real-time renderer only), :data:`FRESNELS`, :data:`LOD_MAPPINGS`,
:data:`SHADINGS`, :data:`RUNTIME_SAMPLINGS`, :data:`IRRADIANCES`, :data:`IRRADIANCE_METHODS`,
:data:`DFGS`, :data:`LUT_SAMPLINGS`, :data:`MULTISCATTERS`, :data:`MULTISCATTER_GEOMETRY`, :data:`GEOMETRIC_ROUGHNESSES`, :data:`ENERGY_COMPENSATIONS`, :data:`SPECULAR_OCCLUSIONS`, :data:`BUILTIN_LOD_MAPPINGS`, :data:`REGISTRIES`, :func:`glsl_defines`,
:func:`glsl_generated`.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class Impl:
    """A term's implementation in the three languages, each named by its function's name.

    Attributes
    ----------
    numpy : str
        The ground truth's function in :mod:`pbrcheck.brdf`.
    drjit : str
        The reference BSDF's function, looked up by name in :mod:`reference.bsdf` (which holds
        :mod:`reference.terms`' too) when the reference dispatches: the core does not import the
        renderers; ``tests/test_registry.py`` checks that it exists.
    glsl : str
        The shader function (``realtime/shaders/brdf.glsl``), twin of ``numpy`` of the same name
        and called by the generated dispatch (:func:`glsl_generated`).
    width : str
        The term's width argument as a function of the perceptual roughness, named alike in the
        three languages: ``alpha_from_roughness``, ``k_schlick_ibl``, ``k_schlick_direct``; empty
        for a term without one (Fresnel).
    """

    numpy: str
    drjit: str
    glsl: str
    width: str = ""


@dataclass(frozen=True)
class Entry:
    """One member of a closed list.

    Attributes
    ----------
    name : str
        The value written in scene files and options (``"smith_ggx_correlated"``).
    source : str
        Where the term comes from (publication, equation), for docs and the GLSL comment.
    scene : bool
        False for members only the real-time renderer offers (not a scene's ``[brdf]`` value).
    extra : dict
        Per-list data (a LOD mapping's basis coefficients; an NDF's GLSL sampler ``sample``).
    impl : Impl or None
        The term's functions (NDFs, geometry and Fresnel terms): the numpy, Dr.Jit and GLSL
        dispatch loop over these (:func:`pbrcheck.brdf.geometry_term`,
        :func:`reference.terms.geometry_term`, :func:`glsl_generated`).
    """

    name: str
    source: str
    scene: bool = True
    extra: dict = field(default_factory=dict)
    impl: Impl | None = None


class Registry:
    """A closed list: ordered members with a GLSL switch name.

    Parameters
    ----------
    define : str
        The GLSL switch (``"GEOMETRY"``); each member's constant is ``DEFINE_NAME`` upper-cased.
    entries : sequence of Entry
        The members, in a fixed order (their GLSL constant is their index).
    """

    def __init__(self, define: str, entries):
        self.define = define
        self.entries = tuple(entries)
        self._by_name = {e.name: e for e in self.entries}
        if len(self._by_name) != len(self.entries):
            raise ValueError(f"registry {define}: duplicate member names")

    def __iter__(self):
        return iter(self.entries)

    def __contains__(self, name) -> bool:
        return name in self._by_name

    def __getitem__(self, name: str) -> Entry:
        return self._by_name[name]

    @property
    def names(self) -> tuple[str, ...]:
        """Every member's name, in order."""
        return tuple(e.name for e in self.entries)

    @property
    def scene_names(self) -> tuple[str, ...]:
        """The members a scene file may name (``scene=True``)."""
        return tuple(e.name for e in self.entries if e.scene)

    def constant(self, name: str) -> str:
        """The GLSL constant of member ``name`` (``GEOMETRY_SMITH_GGX``); KeyError if unknown."""
        return f"{self.define}_{self[name].name.upper()}"

    def select(self, name: str) -> dict[str, str]:
        """The ``#define`` that selects member ``name``: ``{"GEOMETRY": "GEOMETRY_SMITH_GGX"}``."""
        return {self.define: self.constant(name)}

    def constants(self) -> dict[str, int]:
        """Every member's GLSL constant and its value (the member's index)."""
        return {self.constant(e.name): i for i, e in enumerate(self.entries)}


_ALPHA = "alpha_from_roughness"

NDFS = Registry("NDF", [
    Entry("ggx", "GGX / Trowbridge-Reitz, Walter et al. 2007 eq. 33", extra={"sample": "sample_GGX"},
          impl=Impl("D_GGX", "D_GGX", "D_GGX", _ALPHA)),
    Entry("beckmann", "Beckmann, Walter et al. 2007 eq. 25", extra={"sample": "sample_Beckmann"},
          impl=Impl("D_Beckmann", "D_Beckmann", "D_Beckmann", _ALPHA)),
    Entry("blinn_phong", "normalized Blinn-Phong, Walter et al. 2007 eq. 30 with n = 2/alpha^2 - 2",
          extra={"sample": "sample_BlinnPhong"}, impl=Impl("D_BlinnPhong", "D_BlinnPhong", "D_BlinnPhong", _ALPHA)),
])

GEOMETRIES = Registry("GEOMETRY", [
    Entry("smith_ggx_correlated", "height-correlated Smith GGX, Heitz 2014 eq. 99",
          impl=Impl("G_SmithGGXCorrelated", "G_SmithGGXCorrelated", "G_SmithGGXCorrelated", _ALPHA)),
    Entry("smith_ggx", "separable Smith GGX G1(l) G1(v), as Mitsuba's roughconductor",
          impl=Impl("G_SmithGGX", "G_SmithGGX", "G_SmithGGX", _ALPHA)),
    Entry("schlick_ggx_ibl", "Schlick-GGX with k = alpha/2, Karis 2013",
          impl=Impl("G_SchlickGGX", "G_SchlickGGX", "G_SchlickGGX", "k_schlick_ibl")),
    Entry("schlick_ggx_direct", "Schlick-GGX with k = (roughness+1)^2/8, Karis 2013",
          impl=Impl("G_SchlickGGX", "G_SchlickGGX", "G_SchlickGGX", "k_schlick_direct")),
    Entry("schlick_beckmann", "Schlick's approximation of Smith-Beckmann, k = alpha sqrt(2/pi) (article 001's "
                              "catalogue), real time only", scene=False,
          impl=Impl("G_SchlickBeckmann", "G_SchlickBeckmann", "G_SchlickBeckmann", _ALPHA)),
    Entry("smith_beckmann_correlated", "height-correlated Smith Beckmann, Heitz 2014 eq. 99 with eq. 80",
          impl=Impl("G_SmithBeckmannCorrelated", "G_SmithBeckmannCorrelated", "G_SmithBeckmannCorrelated", _ALPHA)),
])

FRESNELS = Registry("FRESNEL", [
    Entry("schlick", "Schlick 1994 eq. 15", impl=Impl("F_Schlick", "F_Schlick", "F_Schlick")),
    Entry("none", "F = 1 (also removes the diffuse term)", impl=Impl("F_None", "F_None", "F_None")),
])

#: The registries whose entries carry their implementations (:class:`Impl`), by GLSL switch, with
#: the GLSL dispatch function each generates, its signature and its user hook.
TERM_REGISTRIES = {"NDF": (NDFS, "float ndf_term(float NoH, float roughness)", "hook_D(NoH, roughness)"),
                   "GEOMETRY": (GEOMETRIES, "float geometry_term(float NoV, float NoL, float roughness)",
                                "hook_G(NoV, NoL, roughness)"),
                   "FRESNEL": (FRESNELS, "vec3 fresnel_term(float VoH, vec3 F0)", "hook_F(VoH, F0)")}

#: Roughness -> prefiltered mip level. ``extra["basis"]``: the mapping as coefficients of
#: :data:`pbrcheck.lodmap.BASIS_NAMES` times the last level ``M`` (None: not a member of the fit's
#: family); ``extra["builtin"]``: bakes a prefiltered chain (``fitted`` reads a built-in chain).
LOD_MAPPINGS = Registry("LOD_MAPPING", [
    Entry("linear", "article 000: lod = r M", extra={"builtin": True, "basis": (1, 0, 0, 0, 0, 0)}),
    Entry("quadratic", "Filament's perceptualRoughnessToLod: lod = M r (2 - r)",
          extra={"builtin": True, "basis": (0, 0, 0, 0, 0, 1)}),
    Entry("log2", "UE4's ComputeReflectionCaptureMipFromRoughness (article 002): "
                  "lod = log2(size) - (1 - 1.2 log2 r)", extra={"builtin": True, "basis": None}),
    Entry("fitted", "pbrcheck fit-lod's fitted monotone mapping (lod_mapping=fitted:FILE)",
          extra={"builtin": False, "basis": None}),
])

#: The built-in mappings (each bakes its own prefiltered chain).
BUILTIN_LOD_MAPPINGS = tuple(e.name for e in LOD_MAPPINGS if e.extra["builtin"])

SHADINGS = Registry("SHADING", [
    Entry("material", "README's material model"),
    Entry("article000", "article 000 (Drevicky 2018)"),
    Entry("article001", "article 001 (runtime importance sampling)"),
    Entry("article002", "article 002 (EnvBRDFApprox, SH9)"),
])

#: ``extra["glsl"]``: the half vector's expression in tangent space (``u`` the 2-D point, ``vt`` the
#: view direction in tangent space), generated into ``runtime_half_vector`` (sampling_dispatch.glsl).
RUNTIME_SAMPLINGS = Registry("RUNTIME_SAMPLING", [
    Entry("beckmann", "Beckmann half vectors (article 001 samples them for the GGX D)",
          extra={"glsl": "sample_Beckmann(u, alpha)"}),
    Entry("ggx", "GGX half vectors, Walter et al. 2007 eq. 35-36", extra={"glsl": "sample_GGX(u, alpha)"}),
    Entry("vndf", "GGX visible normals, Heitz 2018", extra={"glsl": "sample_GGX_VNDF(u.yx, vt, alpha)"}),
])

def _switch(define: str, **members: str) -> Registry:
    """A registry of scene-independent switch values: ``member=source`` keyword pairs, in order."""
    return Registry(define, [Entry(name, source) for name, source in members.items()])


IRRADIANCES = _switch("IRRADIANCE", convolution="cube convolution of the environment (E(n) / pi per texel)",
                      sh9="9 spherical-harmonic coefficients, Ramamoorthi & Hanrahan 2001 (article 002)")
IRRADIANCE_METHODS = _switch("IRRADIANCE_METHOD", texel_sum="sum over every source texel, weighted by its solid angle",
                             polar_steps="article 000's uniform polar / azimuth steps")
DFGS = _switch("DFG", lut="baked DFG LUT (split sum's second factor), Karis 2013",
               analytic="Karis's EnvBRDFApprox fit (mobile, 2014; article 002)")
LUT_SAMPLINGS = _switch("LUT_SAMPLING", vndf="GGX visible normals, Heitz 2018 (GGX NDF only)",
                        ndf="half vectors drawn from the NDF, Walter et al. 2007")
#: Multiple-scattering energy compensation of the real-time specular lobe (pbrcheck/energy.py,
#: realtime/shaders/energy.glsl).
ENERGY_COMPENSATIONS = _switch(
    "ENERGY_COMPENSATION", none="single scattering only",
    filament="Filament's scale 1 + F0 (1 / (A + B) - 1) (Filament documentation sec. 4.7.2)",
    fdez_aguera="Fdez-Aguera 2019, JCGT 8(1), eq. 9-13: Fms Ems times the irradiance",
    kulla_conty="Kulla & Conty 2017 (SIGGRAPH course): F_ms (1 - E(mu)) times the irradiance, E_avg table")
#: Specular occlusion of the image-based specular from the ambient occlusion (pbrcheck/occlusion.py,
#: realtime/shaders/occlusion.glsl).
SPECULAR_OCCLUSIONS = _switch(
    "SPECULAR_OCCLUSION", none="the specular image-based term is not occluded",
    lagarde="Lagarde & de Rousiers 2014, Moving Frostbite to PBR, listing 26: "
            "saturate((n.v + ao)^exp2(-16 alpha - 1) - 1 + ao)")
#: The reference's specular lobe: single scattering, or the multiple-scattering random walk
#: (reference/multiscatter.py; a scene's ``[brdf] multiscatter``).
MULTISCATTERS = _switch("MULTISCATTER", none="single scattering (Smith microfacet BRDF)",
                        random_walk="multiple-scattering random walk on the Smith microsurface, "
                                    "Heitz, Hanika, d'Eon, Dachsbacher 2016")
#: The geometry term the random walk needs for each NDF it is defined for: its first bounce is the
#: height-correlated Smith term of that NDF [Heitz16 sec. 5; Heitz 2014 eq. 99].
MULTISCATTER_GEOMETRY = {"ggx": "smith_ggx_correlated", "beckmann": "smith_beckmann_correlated"}

#: A screen-space geometric roughness an engine adds to its roughness, as a reference-only ``[brdf]``
#: option (``geometric_roughness``; not a real-time switch, so not in :data:`REGISTRIES`); the
#: implementation is ``reference.integrator.GEOMETRIC_ROUGHNESS``.
GEOMETRIC_ROUGHNESSES = _switch(
    "GEOMETRIC_ROUGHNESS", none="no geometric roughness",
    threejs="three.js r187 lights_physical_fragment: roughness = min(max(r, floor) + max(max |dFdx n|, "
            "max |dFdy n|), 1), n the view-space normal, derivatives per sample of the engine's raster")

#: Every registry, by its GLSL switch name.
REGISTRIES = {r.define: r for r in (NDFS, GEOMETRIES, FRESNELS, LOD_MAPPINGS, SHADINGS, RUNTIME_SAMPLINGS,
                                     IRRADIANCES, IRRADIANCE_METHODS, DFGS, LUT_SAMPLINGS, MULTISCATTERS,
                                     ENERGY_COMPENSATIONS, SPECULAR_OCCLUSIONS)}


def glsl_defines() -> dict[str, int]:
    """Every registry's named constants (prepended to every shader by :func:`realtime.gl.assemble`)."""
    out: dict[str, int] = {}
    for r in REGISTRIES.values():
        out.update(r.constants())
    return out


def _lod_dispatch() -> str:
    """``lod_from_roughness`` and ``roughness_from_lod``, each calling the selected mapping's
    ``lod_<name>`` / ``roughness_<name>`` (``realtime/shaders/lod.glsl``). ``fitted`` reads through
    ``LOD_FITTED(r)`` (a ``#define`` of the fitted expression, frame pass only) and bakes nothing."""
    lines = ["// Generated from pbrcheck.registry.LOD_MAPPINGS: do not edit.",
             "float lod_from_roughness(float r, float max_lod, float cube_log2) {"]
    for i, e in enumerate(LOD_MAPPINGS):
        kw = "#if" if i == 0 else "#elif"
        lines.append(f"{kw} LOD_MAPPING == {LOD_MAPPINGS.constant(e.name)}")
        if e.extra["builtin"]:
            lines.append(f"    return lod_{e.name}(r, max_lod, cube_log2);")
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
        lines.append(f"    return roughness_{e.name}(lod, max_lod, cube_log2);")
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
    return lines + ["#else", f"#error {registry.define} names no member of pbrcheck.registry", "#endif"]


def _terms_dispatch() -> str:
    """``ndf_term``, ``geometry_term`` and ``fresnel_term``: the user's hook where the frame pass
    defines it (hooks.glsl), else the selected member's GLSL function at its width."""
    lines = ["// Generated from pbrcheck.registry (NDFS, GEOMETRIES, FRESNELS): do not edit.",
             "// Each term function is the selected member's GLSL function (brdf.glsl), called with the",
             "// member's width (alpha_from_roughness, k_schlick_ibl, k_schlick_direct) of roughness."]
    for define, (registry, signature, hook) in TERM_REGISTRIES.items():
        params = [p.split()[-1] for p in signature[signature.index("(") + 1:-1].split(",")]

        def call(e, params=params):
            args = [f"{e.impl.width}({p})" if p == "roughness" and e.impl.width else p for p in params]
            return [f"    return {e.impl.glsl}({', '.join(args)});"]

        lines += ["", f"#ifndef {define}", f"#define {define} {registry.constant(registry.names[0])}", "#endif",
                  signature + " {", f"#ifdef HOOK_{hook[5:hook.index('(')]}", f"    return {hook};",
                  *["#el" + line[1:] if i == 0 else line for i, line in enumerate(_switch_lines(registry, call))],
                  "}"]
    return "\n".join(lines) + "\n"


def _sampling_dispatch() -> str:
    """``sample_ndf(u, alpha)``: a half vector drawn from the selected NDF's ``D (n.h)`` (its entry's
    ``extra["sample"]``); ``runtime_half_vector(u, vt, alpha)``: RUNTIME_SAMPLING's draw."""
    lines = ["// Generated from pbrcheck.registry (NDFS, RUNTIME_SAMPLINGS): do not edit.",
             "#ifndef RUNTIME_SAMPLING", f"#define RUNTIME_SAMPLING {RUNTIME_SAMPLINGS.constant('vndf')}", "#endif",
             "vec3 sample_ndf(vec2 u, float alpha) {",
             *_switch_lines(NDFS, lambda e: [f"    return {e.extra['sample']}(u, alpha);"]), "}", "",
             "vec3 runtime_half_vector(vec2 u, vec3 vt, float alpha) {",
             *_switch_lines(RUNTIME_SAMPLINGS, lambda e: [f"    return {e.extra['glsl']};"]), "}", ""]
    return "\n".join(lines)


def glsl_generated() -> dict[str, str]:
    """Generated GLSL sources by include name: ``lod_dispatch.glsl`` (:func:`_lod_dispatch`),
    ``terms_dispatch.glsl`` (:func:`_terms_dispatch`), ``sampling_dispatch.glsl``
    (:func:`_sampling_dispatch`)."""
    return {"lod_dispatch.glsl": _lod_dispatch(), "terms_dispatch.glsl": _terms_dispatch(),
            "sampling_dispatch.glsl": _sampling_dispatch()}
