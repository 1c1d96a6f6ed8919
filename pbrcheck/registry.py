"""Registries of pbrcheck's closed lists: one place names every member, Python owns it.

Each closed list is a :class:`Registry` of :class:`Entry`, from which the scene model's accepted
values (:mod:`pbrcheck.scene`), the real-time options' choices (:mod:`realtime.presets`), the
dispatch in each language, the generated GLSL (:mod:`realtime.generated`) and the docs' tables
(checked by ``tests/test_registry.py``) are derived. A scene term's entry holds its numpy class
(:attr:`Entry.term`, :mod:`pbrcheck.terms`), which names its GLSL functions; the reference holds the
Dr.Jit class of the same member (:mod:`reference.terms`). Adding an NDF is one class per language
and one entry here (docs/realtime.md has the worked example). A role registry's member names its
functions per dispatch role (:attr:`Entry.roles`, :class:`Impl`). A member that needs other real-time
options says so (:attr:`Entry.requires`, enforced by :func:`realtime.presets.check_requirements`).
The lists here are those the core's numpy twins read; the real-time renderer's own switches and the
GLSL side of every list are :mod:`realtime.registry`'s.

API
---
:class:`Impl`, :class:`Entry`, :class:`Registry`, :func:`switch`, :data:`NDFS`, :data:`GEOMETRIES`
(``scene=False`` members exist in the real-time renderer only), :data:`FRESNELS`,
:data:`LOD_MAPPINGS`, :data:`BUILTIN_LOD_MAPPINGS`, :data:`RUNTIME_SAMPLINGS`, :data:`LUT_SAMPLINGS`,
:func:`lut_sampling_for`, :data:`ENERGY_COMPENSATIONS`, :data:`SPECULAR_OCCLUSIONS`,
:data:`HORIZON_OCCLUSIONS`, :data:`SPECULAR_AAS`, :data:`MULTISCATTERS`, :data:`MULTISCATTER_GEOMETRY`,
:data:`GEOMETRIC_ROUGHNESSES`, :func:`role_impl`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from . import terms


@dataclass(frozen=True)
class Impl:
    """A role function in the three languages, named alike (``energy_scale_filament``).

    Attributes
    ----------
    numpy : str
        The function in its list's numpy module (:mod:`pbrcheck.energy`, :mod:`pbrcheck.sampling`,
        :mod:`pbrcheck.occlusion`, :mod:`pbrcheck.specular_aa`).
    drjit : str
        Its Dr.Jit twin in :mod:`reference.energy` or :mod:`reference.sampling`, resolved there (the
        core does not import the renderers; ``tests/test_registry.py`` checks that it exists). Empty
        for a real-time approximation the reference does not make (:attr:`Entry.applies_to` says so).
    glsl : str
        The shader function (``energy.glsl``, ``sampling.glsl``, ...), called by the generated dispatch
        (:func:`realtime.generated.glsl_generated`).
    args : tuple of str
        The dispatch function's parameters it reads, in order (empty: all of them); the numpy
        dispatch passes them by these names.
    """

    numpy: str
    drjit: str
    glsl: str
    args: tuple = ()


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
        Per-list data (a LOD mapping's basis coefficients; an NDF's random-walk geometry).
    term : type or None
        The term's numpy class (:mod:`pbrcheck.terms`: NDFs, geometry and Fresnel terms), which names
        its GLSL functions; the reference's Dr.Jit class of the same member is in
        :mod:`reference.terms`' registries (``tests/test_registry.py`` checks both).
    roles : dict of str to Impl
        For a list whose members each implement several dispatch functions
        (:data:`realtime.registry.ROLE_REGISTRIES`: energy compensations, sampling strategies,
        occlusions, specular anti-aliasing): the member's functions by the dispatch
        function's name (``"energy_scale"``), each named alike in the three languages
        (``energy_scale_filament``). A role the member has not is its list's identity there.
    applies_to : str
        Where the member applies, and why a role has no function (``fdez_aguera``: image-based
        lighting only); ``tests/test_registry.py`` requires it of a member missing a role.
    requires : dict of str to tuple of str
        The real-time options the member needs, each with the values it accepts
        (``{"ibl": ("splitsum",)}``); :func:`realtime.presets.resolve_options` refuses any other
        combination with a one-line error naming them.
    """

    name: str
    source: str
    scene: bool = True
    extra: dict = field(default_factory=dict)
    term: type | None = None
    roles: dict = field(default_factory=dict)
    applies_to: str = ""
    requires: dict = field(default_factory=dict)


class Registry:
    """A closed list: ordered members with a GLSL switch name.

    Parameters
    ----------
    define : str
        The GLSL switch (``"GEOMETRY"``); each member's constant is ``DEFINE_NAME`` upper-cased.
    entries : sequence of Entry
        The members, in a fixed order (their GLSL constant is their index).
    applies_to : str
        For a list whose members carry no implementations in the three languages (neither
        :attr:`Entry.term` nor :attr:`Entry.roles`): where it applies and why (a switch of one
        renderer's own code); ``tests/test_registry.py`` requires it of such a list.
    """

    def __init__(self, define: str, entries, applies_to: str = ""):
        self.define = define
        self.entries = tuple(entries)
        self.applies_to = applies_to
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


def _roles(member: str, *roles: str, **shared: str) -> dict[str, Impl]:
    """``{role: Impl}`` of a member whose role functions are named ``<role>_<member>`` in the three
    languages (``energy_scale_filament``); ``shared``: ``role="<role>_<other>"`` for a function
    several members share (``runtime_estimate_ndf``)."""
    out = {r: Impl(f"{r}_{member}", f"{r}_{member}", f"{r}_{member}") for r in roles}
    out.update({r: Impl(fn, fn, fn) for r, fn in shared.items()})
    return out


#: ``extra["runtime_sampling"]``: the runtime sampling strategy (:data:`RUNTIME_SAMPLINGS`) exact for
#: its D (``pbrcheck explain``'s ``v=n=r`` row; absent: none is); ``extra["walk_geometry"]``: the
#: height-correlated Smith term of the multiple-scattering random walk's first bounce
#: (:data:`MULTISCATTER_GEOMETRY`; absent: no walk for this NDF).
NDFS = Registry("NDF", [
    Entry("ggx", "GGX / Trowbridge-Reitz, Walter et al. 2007 eq. 33", term=terms.GGX,
          extra={"runtime_sampling": "vndf", "walk_geometry": "smith_ggx_correlated"}),
    Entry("beckmann", "Beckmann, Walter et al. 2007 eq. 25", term=terms.Beckmann,
          extra={"runtime_sampling": "beckmann", "walk_geometry": "smith_beckmann_correlated"}),
    Entry("blinn_phong", "normalized Blinn-Phong, Walter et al. 2007 eq. 30 with n = 2/alpha^2 - 2",
          term=terms.BlinnPhong),
])

GEOMETRIES = Registry("GEOMETRY", [
    Entry("smith_ggx_correlated", "height-correlated Smith GGX, Heitz 2014 eq. 99", term=terms.SmithGGXCorrelated),
    Entry("smith_ggx", "separable Smith GGX G1(l) G1(v), as Mitsuba's roughconductor", term=terms.SmithGGX),
    Entry("schlick_ggx_ibl", "Schlick-GGX with k = alpha/2, Karis 2013", term=terms.SchlickGGXIBL),
    Entry("schlick_ggx_direct", "Schlick-GGX with k = (roughness+1)^2/8, Karis 2013", term=terms.SchlickGGXDirect),
    Entry("schlick_beckmann", "Schlick's approximation of Smith-Beckmann, k = alpha sqrt(2/pi) (article 001's "
                              "catalogue), real time only", scene=False, term=terms.SchlickBeckmann),
    Entry("smith_beckmann_correlated", "height-correlated Smith Beckmann, Heitz 2014 eq. 99 with eq. 80",
          term=terms.SmithBeckmannCorrelated),
])

FRESNELS = Registry("FRESNEL", [
    Entry("schlick", "Schlick 1994 eq. 15", term=terms.Schlick),
    Entry("none", "F = 1 (also removes the diffuse term)", term=terms.NoFresnel),
])

#: Roughness -> prefiltered mip level. ``extra["basis"]``: the mapping as coefficients of
#: :data:`pbrcheck.lodmap.BASIS_NAMES` times the last level ``M`` (None: not a member of the fit's
#: family); ``extra["builtin"]``: bakes a prefiltered chain (``fitted`` reads a built-in chain).
LOD_MAPPINGS = Registry("LOD_MAPPING", applies_to=(
    "the real-time renderer's prefiltered chain only (the reference has none): GLSL lod_<name> / roughness_<name> "
    "(lod.glsl) and numpy twins of the same names (pbrcheck.lodmap)"), entries=[
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

#: Runtime importance sampling of the environment (article 001, environment_light.glsl): each
#: strategy's half vector in tangent space (``runtime_half_vector_<name>``) and its estimator of
#: ``F G L (v.h) / ((n.h)(n.v))``-type terms (``runtime_estimate_*``: ``runtime_estimate_ndf``, correct
#: when the half vectors follow the shaded NDF's D (n.h), is the article's, shared by beckmann and ggx); numpy in
#: :mod:`pbrcheck.sampling`, Dr.Jit in :mod:`reference.sampling`, GLSL in ``sampling.glsl``.
RUNTIME_SAMPLINGS = Registry("RUNTIME_SAMPLING", [
    Entry("beckmann", "Beckmann half vectors (article 001 samples them for the GGX D)",
          roles=_roles("beckmann", "runtime_half_vector", runtime_estimate="runtime_estimate_ndf"),
          applies_to="exact for the Beckmann D it samples; biased for the GGX D article 001 shades with it"),
    Entry("ggx", "GGX half vectors, Walter et al. 2007 eq. 35-36",
          roles=_roles("ggx", "runtime_half_vector", runtime_estimate="runtime_estimate_ndf"),
          applies_to="any NDF's shading; exact for the GGX D it samples"),
    Entry("vndf", "GGX visible normals, Heitz 2018", roles=_roles("vndf", "runtime_half_vector", "runtime_estimate"),
          applies_to="any NDF's shading; exact for the GGX D (its visible normals, Smith GGX G1)"),
])

def switch(define: str, applies_to: str, **members: str) -> Registry:
    """A registry of switch values of one renderer's own code (``applies_to`` says which):
    ``member=source`` keyword pairs, in order."""
    return Registry(define, [Entry(name, source) for name, source in members.items()], applies_to)


#: The DFG LUT's sampling strategies (realtime/shaders/dfg_lut.comp): each draws the half vector
#: (``lut_half_vector_<name>``) and weighs the sample (``lut_weight_<name>``, the estimator of
#: ``f_s cos / pdf`` up to the Fresnel factor); numpy in :mod:`pbrcheck.sampling`, Dr.Jit in
#: :mod:`reference.sampling`, GLSL in ``sampling.glsl``. ``extra["ndfs"]``: the NDFs it is defined for
#: (another NDF bakes with ``ndf``, :func:`lut_sampling_for`).
LUT_SAMPLINGS = Registry("LUT_SAMPLING", [
    Entry("vndf", "GGX visible normals, Heitz 2018 (GGX NDF only)", extra={"ndfs": ("ggx",)},
          roles=_roles("vndf", "lut_half_vector", "lut_weight"),
          applies_to="the GGX NDF only (its visible normals); other NDFs bake with ndf"),
    Entry("ndf", "half vectors drawn from the NDF, Walter et al. 2007", extra={"ndfs": None},
          roles=_roles("ndf", "lut_half_vector", "lut_weight"), applies_to="every NDF (its own D (n.h) sampler)"),
])


def lut_sampling_for(sampling: str, ndf: str) -> str:
    """The LUT sampling strategy used for ``ndf``: ``sampling`` where it is defined for that NDF,
    else ``ndf`` (KeyError for an unknown strategy)."""
    ndfs = LUT_SAMPLINGS[sampling].extra["ndfs"]
    return sampling if ndfs is None or ndf in ndfs else "ndf"


_IBL_ONLY = "image-based lighting only"
#: The real-time options a compensation needs: the material composition's split sum.
_SPLIT_SUM_MATERIAL = {"shading": ("material",), "ibl": ("splitsum",)}
#: Multiple-scattering energy compensation of the real-time specular lobe: each member's functions
#: for the split sum's specular factor (``energy_scale_<name>``), the multiply scattered albedo added
#: times the irradiance (``energy_ms_<name>``) and the point lights' added lobe
#: (``energy_direct_<name>``); numpy in :mod:`pbrcheck.energy`, Dr.Jit in :mod:`reference.energy`,
#: GLSL in ``realtime/shaders/energy.glsl``. They apply with ``shading = material`` and
#: ``ibl = splitsum`` only (they need the split sum's DFG terms, which runtime sampling and the
#: article compositions do not have): each member but ``none`` requires them (:attr:`Entry.requires`).
ENERGY_COMPENSATIONS = Registry("ENERGY_COMPENSATION", [
    Entry("none", "single scattering only", applies_to="nothing is added: scale 1, no lobe"),
    Entry("filament", "Filament's scale 1 + F0 (1 / (A + B) - 1) (Filament documentation sec. 4.7.2)",
          roles=_roles("filament", "energy_scale", "energy_direct"), requires=_SPLIT_SUM_MATERIAL,
          applies_to="a scale of the split sum's specular and of the point lights' specular lobe"),
    Entry("fdez_aguera", "Fdez-Aguera 2019, JCGT 8(1), eq. 9-13: Fms Ems times the irradiance",
          roles=_roles("fdez_aguera", "energy_ms"), requires=_SPLIT_SUM_MATERIAL,
          applies_to=f"{_IBL_ONLY}: the paper has no point-light lobe; no scale (an added albedo)"),
    Entry("kulla_conty", "Kulla & Conty 2017 (SIGGRAPH course): F_ms (1 - E(mu)) times the irradiance, E_avg table",
          roles=_roles("kulla_conty", "energy_ms", "energy_direct"), requires=_SPLIT_SUM_MATERIAL,
          applies_to="an added albedo times the irradiance and an added lobe for point lights; no scale"),
])

#: Why the real-time approximations below have no Dr.Jit function (:attr:`Impl.drjit` empty): the
#: reference does not approximate, it traces the occlusion and integrates each pixel's normals.
_REALTIME_APPROXIMATION = ("a real-time approximation of what the reference computes exactly (it traces the "
                           "occlusion and integrates each pixel's normals): no Dr.Jit function; ")


def _realtime_role(role: str, member: str, *args: str) -> dict[str, Impl]:
    """``{role: Impl}`` of a real-time-only member: numpy and GLSL ``<role>_<member>`` (no Dr.Jit),
    called with the dispatch's parameters ``args`` (all of them where empty)."""
    fn = f"{role}_{member}"
    return {role: Impl(fn, "", fn, args=args)}


#: Specular occlusion of the split sum's image-based specular from the ambient occlusion: each
#: member's ``specular_occlusion_<name>(NoV, ao, roughness)``, numpy in :mod:`pbrcheck.occlusion`,
#: GLSL in ``realtime/shaders/occlusion.glsl`` (dispatch ``specular_occlusion_dispatch.glsl``).
SPECULAR_OCCLUSIONS = Registry("SPECULAR_OCCLUSION", [
    Entry("none", "the specular image-based term is not occluded", applies_to="nothing is occluded: factor 1"),
    Entry("lagarde", "Lagarde & de Rousiers 2014, Moving Frostbite to PBR, listing 26: "
                     "saturate((n.v + ao)^exp2(-16 alpha - 1) - 1 + ao)",
          roles=_realtime_role("specular_occlusion", "lagarde"),
          applies_to=_REALTIME_APPROXIMATION + "the split sum's specular, from the ambient occlusion"),
    Entry("gtso", "Jimenez et al. 2016, Practical Realtime Strategies for Accurate Indirect Occlusion, sec. 6: the "
                  "visibility cone (cos = sqrt(1 - ao)) intersected with the specular cone (cos = exp2(-3.321928 "
                  "alpha^2)), Oat & Sander 2007's cap intersection, over the unoccluded hemisphere's",
          roles=_realtime_role("specular_occlusion", "gtso"),
          applies_to=_REALTIME_APPROXIMATION + "the split sum's specular, from the ambient occlusion"),
])
#: Horizon occlusion of normal-mapped reflections: ``horizon_occlusion_<name>(RoNg)``, numpy in
#: :mod:`pbrcheck.occlusion`, GLSL in ``occlusion.glsl`` (dispatch ``horizon_occlusion_dispatch.glsl``).
HORIZON_OCCLUSIONS = Registry("HORIZON_OCCLUSION", [
    Entry("none", "reflections below the geometric normal's horizon are not faded", applies_to="factor 1"),
    Entry("marmoset", "Russell 2015 (Marmoset), Horizon Occlusion for Normal Mapped Reflections (also Jimenez et "
                      "al. 2016): saturate(1 + 1.3 r.n_g)^2", roles=_realtime_role("horizon_occlusion", "marmoset"),
          applies_to=_REALTIME_APPROXIMATION + "the image-based specular of normal-mapped materials"),
])
#: Specular anti-aliasing / normal-map filtering, the roughness widened by the normals' variance:
#: ``specular_aa_<name>`` of the dispatch inputs it reads (:attr:`Impl.args`), numpy in
#: :mod:`pbrcheck.specular_aa`, GLSL in ``specular_aa.glsl`` (dispatch ``specular_aa_dispatch.glsl``,
#: which also defines ``SPECULAR_AA_READS_<INPUT>`` for the inputs the selected member reads, so
#: that the raster pass computes only those). ``screen_space`` needs the screen derivatives of the
#: normal, which only the raster pipeline has (:attr:`Entry.requires`).
SPECULAR_AAS = Registry("SPECULAR_AA", [
    Entry("none", "no filtering of the normals' variance into the roughness", applies_to="roughness unchanged"),
    Entry("toksvig", "Toksvig 2005, Mipmapping Normal Maps: alpha^2 + 2 (1 - |n|) / |n| from the mip-filtered "
                     "normal's length", roles=_realtime_role("specular_aa", "toksvig", "roughness", "normal_length"),
          applies_to=_REALTIME_APPROXIMATION + "normal-mapped materials' roughness, both pipelines"),
    Entry("screen_space", "Kaplanyan et al. 2016, Tokuyoshi & Kaplanyan 2019 as Filament ships it: alpha^2 + "
                          "min(2 x 0.15 (|dn/dx|^2 + |dn/dy|^2), 0.2) from the geometric normal's screen derivatives",
          roles=_realtime_role("specular_aa", "screen_space", "roughness", "dn2"),
          requires={"pipeline": ("raster",)},
          applies_to=_REALTIME_APPROXIMATION + "the raster pipeline only: it needs the screen derivatives of the "
                     "normal, which the ray-cast compute pass (one invocation per pixel, no neighbours) has not"),
    Entry("prefiltered", "LEAN mapping's slope variance (Olano & Baker 2010) of the normal map, baked per mip beside "
                         "the mip chain: alpha^2 + var(s_x) + var(s_y)",
          roles=_realtime_role("specular_aa", "prefiltered", "roughness", "variance"),
          applies_to=_REALTIME_APPROXIMATION + "normal-mapped materials' roughness, both pipelines"),
])

#: The reference's specular lobe: single scattering, or the multiple-scattering random walk
#: (reference/multiscatter.py; a scene's ``[brdf] multiscatter``).
MULTISCATTERS = switch("MULTISCATTER", "the reference's specular lobe only (reference.multiscatter); the "
                        "real-time renderer approximates it by ENERGY_COMPENSATIONS", none="single scattering (Smith microfacet BRDF)",
                        random_walk="multiple-scattering random walk on the Smith microsurface, "
                                    "Heitz, Hanika, d'Eon, Dachsbacher 2016")
#: The geometry term the random walk needs for each NDF it is defined for (the NDF entry's
#: ``extra["walk_geometry"]``): its first bounce is the height-correlated Smith term of that NDF
#: [Heitz16 sec. 5; Heitz 2014 eq. 99].
MULTISCATTER_GEOMETRY = {e.name: e.extra["walk_geometry"] for e in NDFS if "walk_geometry" in e.extra}

#: A screen-space geometric roughness an engine adds to its roughness, as a reference-only ``[brdf]``
#: option (``geometric_roughness``; not a real-time switch, so not in :data:`realtime.registry.REGISTRIES`); the
#: implementation is ``reference.integrator.GEOMETRIC_ROUGHNESS``.
GEOMETRIC_ROUGHNESSES = switch(
    "GEOMETRIC_ROUGHNESS", "the reference's first hit only (reference.integrator.GEOMETRIC_ROUGHNESS: Dr.Jit, "
    "from the camera rays' differentials); the engines apply their own", none="no geometric roughness",
    threejs="three.js r187 lights_physical_fragment: roughness = min(max(r, floor) + max(max |dFdx n|, "
            "max |dFdy n|), 1), n the view-space normal, derivatives per sample of the engine's raster")


def role_impl(registry: Registry, name: str, role: str, what: str) -> Impl | None:
    """Member ``name``'s ``role`` implementation, None for a member without it (its list's identity);
    KeyError naming ``what`` (``"specular occlusion"``) and the members for an unknown name."""
    if name not in registry:
        raise KeyError(f"unknown {what} {name!r}; known: {', '.join(registry.names)}")
    return registry[name].roles.get(role)
