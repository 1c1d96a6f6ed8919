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
  ``lod_<name>`` / ``roughness_<name>``, :mod:`realtime.shaders` ``lod.glsl``);
* the docs' tables, checked against it by ``tests/test_registry.py``.

Adding a LOD mapping is one :data:`LOD_MAPPINGS` entry, its two GLSL functions in
``realtime/shaders/lod.glsl`` and their numpy twins of the same names in :mod:`pbrcheck.lodmap`.

API
---
:class:`Entry`, :class:`Registry`, :data:`NDFS`, :data:`GEOMETRIES` (every G term; ``scene=False``
members exist in the real-time renderer only), :data:`FRESNELS`, :data:`LOD_MAPPINGS`,
:data:`SHADINGS`, :data:`RUNTIME_SAMPLINGS`, :data:`IRRADIANCES`, :data:`IRRADIANCE_METHODS`,
:data:`DFGS`, :data:`LUT_SAMPLINGS`, :data:`MULTISCATTERS`, :data:`MULTISCATTER_GEOMETRY`, :data:`ENERGY_COMPENSATIONS`, :data:`BUILTIN_LOD_MAPPINGS`, :data:`REGISTRIES`, :func:`glsl_defines`,
:func:`glsl_generated`.
"""

from __future__ import annotations

from dataclasses import dataclass, field


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
        Per-list data (a LOD mapping's basis coefficients, a term's numpy twin name).
    """

    name: str
    source: str
    scene: bool = True
    extra: dict = field(default_factory=dict)


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


NDFS = Registry("NDF", [
    Entry("ggx", "GGX / Trowbridge-Reitz, Walter et al. 2007 eq. 33"),
    Entry("beckmann", "Beckmann, Walter et al. 2007 eq. 25"),
    Entry("blinn_phong", "normalized Blinn-Phong, Walter et al. 2007 eq. 30 with n = 2/alpha^2 - 2"),
])

GEOMETRIES = Registry("GEOMETRY", [
    Entry("smith_ggx_correlated", "height-correlated Smith GGX, Heitz 2014 eq. 99"),
    Entry("smith_ggx", "separable Smith GGX G1(l) G1(v), as Mitsuba's roughconductor"),
    Entry("schlick_ggx_ibl", "Schlick-GGX with k = alpha/2, Karis 2013"),
    Entry("schlick_ggx_direct", "Schlick-GGX with k = (roughness+1)^2/8, Karis 2013"),
    Entry("schlick_beckmann", "Schlick's Beckmann approximation (article 000's listing), real time only",
          scene=False),
    Entry("smith_beckmann_correlated", "height-correlated Smith Beckmann, Heitz 2014 eq. 99 with eq. 80"),
])

FRESNELS = Registry("FRESNEL", [
    Entry("schlick", "Schlick 1994 eq. 15"),
    Entry("none", "F = 1 (also removes the diffuse term)"),
])

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

RUNTIME_SAMPLINGS = Registry("RUNTIME_SAMPLING", [
    Entry("beckmann", "Beckmann half vectors (article 001 samples them for the GGX D)"),
    Entry("ggx", "GGX half vectors, Walter et al. 2007 eq. 35-36"),
    Entry("vndf", "GGX visible normals, Heitz 2018"),
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
#: The reference's specular lobe: single scattering, or the multiple-scattering random walk
#: (reference/multiscatter.py; a scene's ``[brdf] multiscatter``).
MULTISCATTERS = _switch("MULTISCATTER", none="single scattering (Smith microfacet BRDF)",
                        random_walk="multiple-scattering random walk on the Smith microsurface, "
                                    "Heitz, Hanika, d'Eon, Dachsbacher 2016")
#: The geometry term the random walk needs for each NDF it is defined for: its first bounce is the
#: height-correlated Smith term of that NDF [Heitz16 sec. 5; Heitz 2014 eq. 99].
MULTISCATTER_GEOMETRY = {"ggx": "smith_ggx_correlated", "beckmann": "smith_beckmann_correlated"}

#: Every registry, by its GLSL switch name.
REGISTRIES = {r.define: r for r in (NDFS, GEOMETRIES, FRESNELS, LOD_MAPPINGS, SHADINGS, RUNTIME_SAMPLINGS,
                                     IRRADIANCES, IRRADIANCE_METHODS, DFGS, LUT_SAMPLINGS, MULTISCATTERS,
                                     ENERGY_COMPENSATIONS)}


def glsl_defines() -> dict[str, int]:
    """Every registry's named constants (prepended to every shader by :func:`realtime.gl.assemble`)."""
    out: dict[str, int] = {}
    for r in REGISTRIES.values():
        out.update(r.constants())
    return out


def glsl_generated() -> dict[str, str]:
    """Generated GLSL sources by include name: ``lod_dispatch.glsl`` defines ``lod_from_roughness``
    and ``roughness_from_lod``, each calling the selected mapping's ``lod_<name>`` /
    ``roughness_<name>`` (``realtime/shaders/lod.glsl``). ``fitted`` reads through ``LOD_FITTED(r)``
    (a ``#define`` of the fitted expression, frame pass only) and bakes nothing."""
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
    return {"lod_dispatch.glsl": "\n".join(lines)}
