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
  ``geometry_term`` / ``fresnel_term`` call the term's GLSL function; ``sample_ndf`` the NDF's
  sampler; each role registry's dispatch (``energy_scale``, ``runtime_estimate``, ``lut_weight``, ...)
  the member's role function);
* the docs' tables, checked against it by ``tests/test_registry.py``.

Adding a LOD mapping is one :data:`LOD_MAPPINGS` entry, its two GLSL functions in
``realtime/shaders/lod.glsl`` and their numpy twins of the same names in :mod:`pbrcheck.lodmap`.
The term registries (:data:`TERM_REGISTRIES`: NDFs, geometry and Fresnel terms) own their
implementations: each entry's :class:`Impl` names its numpy, Dr.Jit and GLSL functions and its
width; adding a G term is one :data:`GEOMETRIES` entry and its three functions (docs/realtime.md
has the worked example). An NDF also names its GLSL sampler (``extra["sample"]``, numpy twin in
:mod:`pbrcheck.sampling`) and has, under its D function's name without ``D_``, a quadrature pair in
:mod:`pbrcheck.brdf` (``_theta_h_<D>``, ``_cdf_theta_h_<D>``) and a Dr.Jit sampler pair in
:mod:`reference.bsdf` (``sample_h_<D>``, ``pdf_h_<D>``); where they exist, the runtime sampling
strategy exact for it (``extra["runtime_sampling"]``) and the random walk's first-bounce G term
(``extra["walk_geometry"]``, :data:`MULTISCATTER_GEOMETRY`) with the walk's Dr.Jit trio in
:mod:`reference.multiscatter` (``lambda_<D>``, ``D_<D>``, ``sample_vndf_<D>``). A member that needs
other real-time options says so (:attr:`Entry.requires`: an energy compensation the material
composition's split sum, a composition its specular image-based lighting, ``specular_aa =
screen_space`` the raster pipeline); :func:`realtime.presets.check_requirements` enforces it.

The role registries (:data:`ROLE_REGISTRIES`: energy compensations, runtime and DFG LUT sampling
strategies) own theirs one function per role (:attr:`Entry.roles`, one name in numpy, Dr.Jit and
GLSL; :attr:`Entry.applies_to` says where a member applies and why a role is missing); adding a
compensation or a strategy is one entry and its role functions in :mod:`pbrcheck.energy` /
:mod:`pbrcheck.sampling`, :mod:`reference.energy` / :mod:`reference.sampling` and ``energy.glsl`` /
``sampling.glsl``. The real-time approximations (:data:`SPECULAR_OCCLUSIONS`,
:data:`HORIZON_OCCLUSIONS`, :data:`SPECULAR_AAS`) are role registries too, with numpy
(:mod:`pbrcheck.occlusion`, :mod:`pbrcheck.specular_aa`) and GLSL functions and no Dr.Jit one
(:attr:`Impl.drjit` empty; the entry's ``applies_to`` says why: the reference traces the occlusion
and integrates each pixel's normals); a role function reading fewer than all of its dispatch's
inputs names them (:attr:`Impl.args`), and the generated dispatch defines ``<SWITCH>_READS_<INPUT>``
for the selected member (:func:`role_reads` in Python). The compositions' GLSL dispatch
(``shade_composition`` / ``light_brdf`` calling ``shade_<name>`` / ``light_brdf_<name>``) is
generated from :data:`SHADINGS` (``shading_dispatch.glsl``). A list whose members have no implementations says where it applies
(:attr:`Registry.applies_to`).

API
---
:class:`Impl`, :class:`Entry`, :class:`Registry`, :data:`TERM_REGISTRIES`, :data:`NDFS`, :data:`GEOMETRIES` (every G term; ``scene=False``
members exist in the real-time renderer only), :data:`FRESNELS`, :data:`LOD_MAPPINGS`,
:data:`SHADINGS`, :data:`RUNTIME_SAMPLINGS`, :data:`IRRADIANCES`, :data:`IRRADIANCE_METHODS`,
:data:`DFGS`, :data:`LUT_SAMPLINGS`, :func:`lut_sampling_for`, :data:`MULTISCATTERS`, :data:`MULTISCATTER_GEOMETRY`, :data:`GEOMETRIC_ROUGHNESSES`, :data:`ENERGY_COMPENSATIONS`, :data:`SPECULAR_OCCLUSIONS`, :data:`HORIZON_OCCLUSIONS`, :data:`SPECULAR_AAS`, :data:`BUILTIN_LOD_MAPPINGS`, :data:`REGISTRIES`,
:data:`ROLE_REGISTRIES`, :func:`role_impl`, :func:`role_reads`, :func:`glsl_defines`, :func:`glsl_generated`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from . import terms
from .lights import glsl_light_constants


@dataclass(frozen=True)
class Impl:
    """A term's implementation in the three languages, each named by its function's name.

    Attributes
    ----------
    numpy : str
        The ground truth's function in :mod:`pbrcheck.brdf` (a role's: in its list's numpy module,
        :mod:`pbrcheck.energy` or :mod:`pbrcheck.sampling`).
    drjit : str
        The reference BSDF's function, looked up by name in :mod:`reference.bsdf` (which holds
        :mod:`reference.terms`' too; a role's in :mod:`reference.energy` or :mod:`reference.sampling`)
        when the reference dispatches: the core does not import the renderers;
        ``tests/test_registry.py`` checks that it exists. Empty for a real-time approximation the
        reference does not make (the entry's :attr:`Entry.applies_to` says so).
    glsl : str
        The shader function (``realtime/shaders/brdf.glsl``; a role's in ``energy.glsl`` or
        ``sampling.glsl``), twin of ``numpy`` of the same name and called by the generated dispatch
        (:func:`glsl_generated`).
    width : str
        The term's width argument as a function of the perceptual roughness, named alike in the
        three languages: ``alpha_from_roughness``, ``k_schlick_ibl``, ``k_schlick_direct``; empty
        for a term without one (Fresnel).
    args : tuple of str
        A role function's arguments: the dispatch function's parameters it reads, in order (empty:
        all of them); the numpy dispatch passes them by these names.
    """

    numpy: str
    drjit: str
    glsl: str
    width: str = ""
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
        Per-list data (a LOD mapping's basis coefficients; an NDF's GLSL sampler ``sample``).
    term : type or None
        The term's numpy class (:mod:`pbrcheck.terms`: NDFs, geometry and Fresnel terms), which names
        its GLSL functions; the reference's Dr.Jit class of the same entry is
        :data:`reference.terms.TERMS`' (``tests/test_registry.py`` checks both).
    roles : dict of str to Impl
        For a list whose members each implement several dispatch functions (:data:`ROLE_REGISTRIES`:
        energy compensations, DFG LUT sampling strategies): the member's functions by the dispatch
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
        :attr:`Entry.impl` nor :attr:`Entry.roles`): where it applies and why (a switch of one
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

#: The registries whose entries carry their implementations (:class:`Impl`), by GLSL switch, with
#: the GLSL dispatch function each generates, its signature and its user hook.
TERM_REGISTRIES = {"NDF": (NDFS, "float ndf_term(float NoH, float roughness)", "hook_D(NoH, roughness)"),
                   "GEOMETRY": (GEOMETRIES, "float geometry_term(float NoV, float NoL, float roughness)",
                                "hook_G(NoV, NoL, roughness)"),
                   "FRESNEL": (FRESNELS, "vec3 fresnel_term(float VoH, vec3 F0)", "hook_F(VoH, F0)")}

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

#: Each composition ``requires`` the specular image-based lighting it has (``ibl`` option): article
#: 001 is runtime sampling only, articles 000 and 002 split sum only, the material model has both.
#: ``extra["hooks"]``: the composition whose pieces shader hooks replace (docs/hooks.md);
#: ``extra["seeded"]``: its ``shade_<name>`` takes the pixel seed (it may sample at run time). Each
#: composition's GLSL functions are ``shade_<name>`` and ``light_brdf_<name>`` (shading.glsl), called
#: by the generated ``shade_composition`` / ``light_brdf`` (``shading_dispatch.glsl``).
SHADINGS = Registry("SHADING", applies_to=(
    "the real-time renderer's compositions (shading.glsl: shade_<name> and light_brdf_<name> each, dispatch "
    "generated); the reference renders one material model (pbrcheck.brdf, reference.bsdf)"), entries=[
    Entry("material", "README's material model", extra={"hooks": True, "seeded": True}),
    Entry("article000", "article 000 (Drevicky 2018)", requires={"ibl": ("splitsum",)}, extra={"seeded": False}),
    Entry("article001", "article 001 (runtime importance sampling)", requires={"ibl": ("runtime",)},
          extra={"seeded": True}),
    Entry("article002", "article 002 (EnvBRDFApprox, SH9)", requires={"ibl": ("splitsum",)}, extra={"seeded": False}),
])

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

def _switch(define: str, applies_to: str, **members: str) -> Registry:
    """A registry of switch values of one renderer's own code (``applies_to`` says which):
    ``member=source`` keyword pairs, in order."""
    return Registry(define, [Entry(name, source) for name, source in members.items()], applies_to)


_REALTIME_ONLY = "a switch of the real-time renderer's own passes ({}); no numpy or Dr.Jit counterpart"


IRRADIANCES = _switch("IRRADIANCE", _REALTIME_ONLY.format("irradiance.comp, sh9.comp"), convolution="cube convolution of the environment (E(n) / pi per texel)",
                      sh9="9 spherical-harmonic coefficients, Ramamoorthi & Hanrahan 2001 (article 002)")
IRRADIANCE_METHODS = _switch("IRRADIANCE_METHOD", _REALTIME_ONLY.format("irradiance.comp"), texel_sum="sum over every source texel, weighted by its solid angle",
                             polar_steps="article 000's uniform polar / azimuth steps")
DFGS = _switch("DFG", _REALTIME_ONLY.format("ibl.glsl"), lut="baked DFG LUT (split sum's second factor), Karis 2013",
               analytic="Karis's EnvBRDFApprox fit (mobile, 2014; article 002)")



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

#: The registries whose members implement roles (:attr:`Entry.roles`), by GLSL switch: the generated
#: include, the member selected where a shader leaves the switch undefined, and each role's GLSL
#: dispatch signature and the identity a member without the role returns ("": every member has it).
ROLE_REGISTRIES = {
    "ENERGY_COMPENSATION": (ENERGY_COMPENSATIONS, "energy_dispatch.glsl", "none", {
        "energy_scale": ("vec3 energy_scale(vec3 F0, float A, float B)", "vec3(1.0)"),
        "energy_ms": ("vec3 energy_ms(vec3 F0, float A, float B, float roughness)", "vec3(0.0)"),
        "energy_direct": ("vec3 energy_direct(vec3 f_spec, vec3 F0, float A, float B, float El, float roughness)",
                          "vec3(0.0)")}),
    "RUNTIME_SAMPLING": (RUNTIME_SAMPLINGS, "runtime_sampling_dispatch.glsl", "vndf", {
        "runtime_half_vector": ("vec3 runtime_half_vector(vec2 u, vec3 vt, float alpha)", ""),
        "runtime_estimate": ("vec3 runtime_estimate(vec3 F, float G, vec3 L, float NoV, float NoH, float VoH, float alpha)",
                             "")}),
    "LUT_SAMPLING": (LUT_SAMPLINGS, "dfg_sampling_dispatch.glsl", "vndf", {
        "lut_half_vector": ("vec3 lut_half_vector(vec2 u, vec3 v, float alpha)", ""),
        "lut_weight": ("float lut_weight(float G, vec3 v, vec3 h, float alpha)", "")}),
    "SPECULAR_OCCLUSION": (SPECULAR_OCCLUSIONS, "specular_occlusion_dispatch.glsl", "none", {
        "specular_occlusion": ("float specular_occlusion(float NoV, float ao, float roughness)", "1.0")}),
    "HORIZON_OCCLUSION": (HORIZON_OCCLUSIONS, "horizon_occlusion_dispatch.glsl", "none", {
        "horizon_occlusion": ("float horizon_occlusion(float RoNg)", "1.0")}),
    "SPECULAR_AA": (SPECULAR_AAS, "specular_aa_dispatch.glsl", "none", {
        "specular_aa": ("float specular_aa(float roughness, float normal_length, float variance, float dn2)",
                        "roughness")}),
}
#: The reference's specular lobe: single scattering, or the multiple-scattering random walk
#: (reference/multiscatter.py; a scene's ``[brdf] multiscatter``).
MULTISCATTERS = _switch("MULTISCATTER", "the reference's specular lobe only (reference.multiscatter); the "
                        "real-time renderer approximates it by ENERGY_COMPENSATIONS", none="single scattering (Smith microfacet BRDF)",
                        random_walk="multiple-scattering random walk on the Smith microsurface, "
                                    "Heitz, Hanika, d'Eon, Dachsbacher 2016")
#: The geometry term the random walk needs for each NDF it is defined for (the NDF entry's
#: ``extra["walk_geometry"]``): its first bounce is the height-correlated Smith term of that NDF
#: [Heitz16 sec. 5; Heitz 2014 eq. 99].
MULTISCATTER_GEOMETRY = {e.name: e.extra["walk_geometry"] for e in NDFS if "walk_geometry" in e.extra}

#: A screen-space geometric roughness an engine adds to its roughness, as a reference-only ``[brdf]``
#: option (``geometric_roughness``; not a real-time switch, so not in :data:`REGISTRIES`); the
#: implementation is ``reference.integrator.GEOMETRIC_ROUGHNESS``.
GEOMETRIC_ROUGHNESSES = _switch(
    "GEOMETRIC_ROUGHNESS", "the reference's first hit only (reference.integrator.GEOMETRIC_ROUGHNESS: Dr.Jit, "
    "from the camera rays' differentials); the engines apply their own", none="no geometric roughness",
    threejs="three.js r187 lights_physical_fragment: roughness = min(max(r, floor) + max(max |dFdx n|, "
            "max |dFdy n|), 1), n the view-space normal, derivatives per sample of the engine's raster")

#: Every registry, by its GLSL switch name.
REGISTRIES = {r.define: r for r in (NDFS, GEOMETRIES, FRESNELS, LOD_MAPPINGS, SHADINGS, RUNTIME_SAMPLINGS,
                                     IRRADIANCES, IRRADIANCE_METHODS, DFGS, LUT_SAMPLINGS, MULTISCATTERS,
                                     ENERGY_COMPENSATIONS, SPECULAR_OCCLUSIONS, HORIZON_OCCLUSIONS, SPECULAR_AAS)}


def glsl_defines() -> dict[str, int]:
    """Every registry's named constants and the light types' (prepended to every shader by :func:`realtime.gl.assemble`)."""
    out: dict[str, int] = {}
    for r in REGISTRIES.values():
        out.update(r.constants())
    out.update(glsl_light_constants())  # the light types (pbrcheck.lights.LIGHT_TYPES)
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
    lines = [f"// Generated from pbrcheck.registry.{define}S (ROLE_REGISTRIES): do not edit.",
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
    reads (:attr:`Impl.args`), where some member reads fewer than all: empty otherwise."""
    if not any(role in e.roles and e.roles[role].args for e in registry):
        return []
    params = _params(signature)
    return _switch_lines(registry, lambda e: [f"#define {registry.define}_READS_{p.upper()} 1" for p in params
                                              if role_reads(registry, e.name, role, p)])


def role_reads(registry: Registry, name: str, role: str, param: str) -> bool:
    """Whether member ``name``'s ``role`` function reads the dispatch parameter ``param`` (its
    :attr:`Impl.args`, all parameters where empty; False for a member without the role)."""
    impl = registry[name].roles.get(role)
    return impl is not None and (not impl.args or param in impl.args)


def role_impl(registry: Registry, name: str, role: str, what: str) -> Impl | None:
    """Member ``name``'s ``role`` implementation, None for a member without it (its list's identity);
    KeyError naming ``what`` (``"specular occlusion"``) and the members for an unknown name."""
    if name not in registry:
        raise KeyError(f"unknown {what} {name!r}; known: {', '.join(registry.names)}")
    return registry[name].roles.get(role)


def _shading_dispatch() -> str:
    """``light_brdf`` (a point light's BRDF) and ``shade_composition`` (the outgoing radiance): the
    selected composition's ``light_brdf_<name>`` / ``shade_<name>`` (:data:`SHADINGS`; the pixel seed
    to a composition with ``extra["seeded"]``)."""
    def shade(e):
        return [f"    return shade_{e.name}(c{', pixel_seed' if e.extra['seeded'] else ''});"]

    lines = ["// Generated from pbrcheck.registry.SHADINGS: do not edit.",
             "vec3 light_brdf(Shading c, vec3 l, float NoL) {",
             *_switch_lines(SHADINGS, lambda e: [f"    return light_brdf_{e.name}(c, l, NoL);"]), "}", "",
             "vec3 shade_composition(Shading c, uint pixel_seed) {", *_switch_lines(SHADINGS, shade), "}", ""]
    return "\n".join(lines)


def glsl_generated() -> dict[str, str]:
    """Generated GLSL sources by include name: ``lod_dispatch.glsl`` (:func:`_lod_dispatch`),
    ``terms_dispatch.glsl`` (:func:`_terms_dispatch`), ``sampling_dispatch.glsl``
    (:func:`_sampling_dispatch`), ``shading_dispatch.glsl`` (:func:`_shading_dispatch`), and each role
    registry's (:func:`_roles_dispatch`): ``energy_dispatch.glsl``, ``runtime_sampling_dispatch.glsl``,
    ``dfg_sampling_dispatch.glsl``, ``specular_occlusion_dispatch.glsl``,
    ``horizon_occlusion_dispatch.glsl``, ``specular_aa_dispatch.glsl``."""
    out = {"lod_dispatch.glsl": _lod_dispatch(), "terms_dispatch.glsl": _terms_dispatch(),
           "sampling_dispatch.glsl": _sampling_dispatch(), "shading_dispatch.glsl": _shading_dispatch()}
    out.update({include: _roles_dispatch(define) for define, (_, include, _, _) in ROLE_REGISTRIES.items()})
    return out
