"""Registries of pbrcheck's closed lists: one place names every member, Python owns it.

Each closed list is a :class:`Registry` of :class:`Entry`, from which the scene model's accepted
values (:mod:`pbrcheck.scene`), the real-time options' choices (:mod:`realtime.presets`), the
dispatch in each language, the generated GLSL (:mod:`realtime.generated`) and the docs' tables
(checked by ``tests/test_registry.py``) are derived; an entry holds its functions, never their names.
Here: the scene's lists. A term's entry holds its numpy class (:attr:`Entry.term`,
:mod:`pbrcheck.terms`), which names its GLSL functions; the reference holds the Dr.Jit class of the
same member (:mod:`reference.terms`). Adding an NDF is one class per language and one entry here
(docs/realtime.md has the worked example). A role registry's member holds its :class:`Role`
functions by dispatch role. The real-time renderer's lists (its approximations, whose numpy
functions are the core's, its own switches and the GLSL side of every list) are
:mod:`realtime.registry`'s; two the core reads itself live beside their numpy functions
(:data:`pbrcheck.lodmap.LOD_MAPPINGS`: a fitted mapping's file names its chain;
:data:`pbrcheck.sampling.LUT_SAMPLINGS`: the reference's LUT bake shares it).

API
---
:class:`Role`, :func:`role`, :class:`Entry`, :class:`Registry`, :func:`switch`, :func:`member_role`,
:data:`REALTIME_APPROXIMATION`, :data:`NDFS`, :data:`GEOMETRIES` (``scene=False`` members exist in the
real-time renderer only), :data:`FRESNELS`, :data:`MULTISCATTERS`, :data:`MULTISCATTER_GEOMETRY`,
:data:`GEOMETRIC_ROUGHNESSES`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from . import terms


@dataclass(frozen=True)
class Role:
    """A role function of a member (:attr:`Entry.roles`): its numpy function and its GLSL twin's name.

    Attributes
    ----------
    numpy : callable
        The function, in its list's numpy module (which holds the list: :mod:`pbrcheck.energy`,
        :mod:`pbrcheck.sampling`, :mod:`pbrcheck.occlusion`, :mod:`pbrcheck.specular_aa`,
        :mod:`pbrcheck.lodmap`); its Dr.Jit twin, where the reference has one, is in the reference's
        table of the same member (:mod:`reference.energy`, :mod:`reference.sampling`).
    glsl : str
        The shader function of the same name, called by the generated dispatch
        (:func:`realtime.generated.glsl_generated`; ``tests/test_registry.py`` checks it exists).
    args : tuple of str
        The dispatch function's parameters it reads, in order (empty: all of them); the numpy
        dispatch passes them by these names.
    """

    numpy: Callable
    glsl: str
    args: tuple = ()


def role(fn: Callable, *args: str) -> Role:
    """The :class:`Role` of ``fn``, whose GLSL twin has its name; ``args``: :attr:`Role.args`."""
    return Role(fn, fn.__name__, args)


#: Why the real-time approximations (occlusions, specular anti-aliasing) have no Dr.Jit function:
#: the reference does not approximate, it traces the occlusion and integrates each pixel's normals.
REALTIME_APPROXIMATION = ("a real-time approximation of what the reference computes exactly (it traces the "
                          "occlusion and integrates each pixel's normals): no Dr.Jit function; ")


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
        Per-list data (a LOD mapping's basis coefficients; an NDF's random-walk geometry; a real-time lobe
        member's own GLSL, ``extra["glsl"]``, which :mod:`realtime.generated` compiles only where selected).
    term : type or None
        The term's numpy class (:mod:`pbrcheck.terms`: NDFs, geometry and Fresnel terms), which names
        its GLSL functions; the reference's Dr.Jit class of the same member is in
        :mod:`reference.terms`' registries (``tests/test_registry.py`` checks both).
    roles : dict of str to Role
        For a list whose members each implement several dispatch functions
        (:data:`realtime.registry.ROLE_REGISTRIES`: energy compensations, sampling strategies,
        occlusions, specular anti-aliasing; a LOD mapping's ``lod`` and ``roughness``): the member's functions by the dispatch
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

def switch(define: str, applies_to: str, **members: str) -> Registry:
    """A registry of switch values of one renderer's own code (``applies_to`` says which):
    ``member=source`` keyword pairs, in order."""
    return Registry(define, [Entry(name, source) for name, source in members.items()], applies_to)


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


def member_role(registry: Registry, name: str, role: str, what: str) -> Role | None:
    """Member ``name``'s ``role``, None for a member without it (its list's identity); KeyError
    naming ``what`` (``"specular occlusion"``) and the members for an unknown name."""
    if name not in registry:
        raise KeyError(f"unknown {what} {name!r}; known: {', '.join(registry.names)}")
    return registry[name].roles.get(role)
