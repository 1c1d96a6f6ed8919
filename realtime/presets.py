"""Options of the real-time renderer and the presets that group them.

Every approximation choice is an option (``--set key=value``); a preset is a complete set of
values. ``default`` is the most accurate split-sum this project makes (see docs/realtime.md for the
measurements behind it); the article presets reproduce ``../shared/articles`` 000, 001 and 002,
their mistakes included.

API
---
:class:`Option` (with its default and the bakes it affects), :data:`OPTIONS`, :data:`PRESETS`,
:class:`RealtimeOptions` (the typed, frozen, validated options of one render; attribute access only),
:func:`resolve_options`, :func:`parse_value`, :func:`parse_sets`, :func:`overrides_from_args`,
:func:`split_preset`, :func:`fitted_mapping`, :class:`OptionError`, :data:`SHADER_SEP`,
:data:`OPTION_REGISTRIES`, :data:`DEFERRED`, :data:`MULTISAMPLES`, :func:`unmet_requirements`,
:func:`check_requirements`; the bakes' cache keys: :data:`BAKES`, :data:`CUBE_BAKES`,
:func:`bake_options`, :func:`bake_inputs` (:class:`BakeInputs`), :func:`bake_key`.
"""

from __future__ import annotations

import copy
import json
from dataclasses import dataclass, field, fields, make_dataclass
from dataclasses import replace as _replace
from pathlib import Path

from pbrcheck.errors import PbrcheckError
from pbrcheck.lodmap import BUILTIN_LOD_MAPPINGS, LOD_MAPPINGS, LodMapping
from pbrcheck.registry import FRESNELS, GEOMETRIES, NDFS, Entry
from pbrcheck.sampling import LUT_SAMPLINGS

from .transmission import TRANSMISSION_LODS, TRANSMISSION_SOURCES
from .registry import (ANISOTROPY_BENDS, COAT_ATTENUATIONS, COAT_IBLS, DFGS, ENERGY_COMPENSATIONS, HORIZON_OCCLUSIONS,
                       IRIDESCENCES, IRRADIANCE_METHODS, IRRADIANCES, RUNTIME_SAMPLINGS, SHADINGS, SHEEN_DFGS,
                       SHEEN_SCALINGS, SPECULAR_AAS, SPECULAR_OCCLUSIONS)


#: Separates a preset from a shader hook file in a renderer name: ``default+hooks/ue4.glsl``.
SHADER_SEP = "+"


class OptionError(PbrcheckError):
    """A bad ``--set`` key or value, or an unknown preset; names the option."""


@dataclass(frozen=True)
class Option:
    """One real-time option: its kind (int, float, bool, choice, file), help, choices and bounds, its
    ``default`` (the ``default`` preset's value, the base of every other preset) and the ``bakes`` it
    affects (:data:`BAKES`: every baked artifact's cache key is derived from the options naming it,
    :func:`bake_inputs`); a value other than ``off`` ``requires`` values of other options as a
    registry member does (:attr:`pbrcheck.registry.Entry.requires`; :func:`check_requirements`
    enforces both)."""
    name: str
    kind: str                      # "int", "float", "bool", "choice", "file"
    help: str
    choices: tuple = ()
    lo: float | None = None
    hi: float | None = None
    power_of_two: bool = False
    requires: dict = field(default_factory=dict)
    off: object = None
    default: object = None
    bakes: tuple[str, ...] = ()


#: Every artifact the real-time renderer bakes once per process and keeps (:mod:`realtime.render`,
#: :mod:`realtime.raster`): its cache key holds the values of exactly the options whose
#: :attr:`Option.bakes` name it (:func:`bake_inputs`, :func:`bake_key`), so an option cannot be
#: forgotten in a key (a bake reading an option it does not declare raises).
BAKES = ("env_cube", "irradiance", "sh9", "prefilter", "dfg_lut", "kd_lut", "material_texture", "normal_variance",
         "sheen_lut", "charlie_prefilter")
#: The bakes of the environment cube and of what is filtered from it (they read its size and format).
CUBE_BAKES = ("env_cube", "irradiance", "sh9", "prefilter", "charlie_prefilter")

#: The ``msaa`` values that multisample (alpha-to-coverage needs one: a single sample has no coverage to dither).
MULTISAMPLES = (2, 4, 8)
#: Choices of texture_sampling and normal_sampling (raster pipeline): the mip chain, or level 0 only.
TEXTURE_SAMPLINGS = ("mip", "lod0")

#: Choices of the G-term options: the scene's own, or any registered term.
GEOMETRY_CHOICES = ("scene", *GEOMETRIES.names)

OPTIONS: dict[str, Option] = {o.name: o for o in [
    Option("shading", "choice", "composition of the terms: material (README model) | article000 | article001 | article002",
           SHADINGS.names, default="material"),
    Option("ibl", "choice", "specular image-based lighting: split-sum prefiltered cube | runtime importance sampling",
           ("splitsum", "runtime"), default="splitsum"),
    Option("cube_size", "int", "face size of the environment cube (texels)", lo=4, hi=4096, power_of_two=True,
           default=256, bakes=CUBE_BAKES),
    Option("cube_format", "choice", "cube texel format (f16 switches to f32 when radiance > 65504)", ("f16", "f32"),
           default="f32", bakes=CUBE_BAKES),
    Option("irradiance", "choice", "diffuse irradiance: cube convolution | SH9 (article 002)", IRRADIANCES.names,
           default="convolution"),
    Option("irradiance_method", "choice", "convolution: sum over source texels | article 000's polar/azimuth steps",
           IRRADIANCE_METHODS.names, default="texel_sum", bakes=("irradiance",)),
    Option("irradiance_size", "int", "face size of the irradiance cube", lo=1, hi=512,
           default=32, bakes=("irradiance",)),
    Option("irradiance_source_size", "int", "face size of the source level the irradiance passes read", lo=1, hi=512,
           power_of_two=True, default=32, bakes=("irradiance", "sh9")),
    Option("irradiance_step", "float", "polar_steps angular step (radians; article 000 uses 0.025)", lo=1e-3, hi=0.5,
           default=0.025, bakes=("irradiance",)),
    Option("prefilter_samples", "int", "GGX Hammersley samples per prefiltered texel", lo=1, hi=1 << 16,
           default=1024, bakes=("prefilter",)),
    Option("prefilter_filtered", "bool", "filtered importance sampling (GPU Gems 3 ch. 20): source mip from the pdf",
           default=True, bakes=("prefilter",)),
    Option("prefilter_nl_weight", "bool", "weight prefilter samples by N.L (article 000)",
           default=False, bakes=("prefilter",)),
    Option("prefilter_levels", "int", "levels in the prefiltered mip chain (level 0 = cube_size)", lo=1, hi=13,
           default=7, bakes=("prefilter",)),
    Option("lod_mapping", "choice", "roughness -> mip level: linear | quadratic | log2 | fitted:FILE.json (pbrcheck "
           "fit-lod's fit; bakes the chain of the mapping it was fitted on)", BUILTIN_LOD_MAPPINGS,
           default="quadratic", bakes=("prefilter",)),
    Option("lod_override", "float", "< 0: off; >= 0: every prefiltered lookup at this mip level, whatever the "
           "roughness (pbrcheck fit-lod's LOD scan)", lo=-1.0, hi=16.0, default=-1.0),
    Option("dfg", "choice", "DFG term: LUT | Karis's analytic EnvBRDFApprox", DFGS.names, default="lut"),
    Option("lut_size", "int", "DFG LUT size N (N x N)", lo=2, hi=1024, default=64, bakes=("dfg_lut", "kd_lut")),
    Option("lut_samples", "int", "samples per DFG LUT texel", lo=1, hi=1 << 16, default=4096, bakes=("dfg_lut",)),
    Option("lut_format", "choice", "DFG LUT format: f16 (RG16F) | f32 (RG32F)", ("f16", "f32"),
           default="f32", bakes=("dfg_lut",)),
    Option("lut_geometry", "choice", "geometry term integrated into the LUT ('scene': the scene's [brdf] geometry)",
           GEOMETRY_CHOICES, default="scene", bakes=("dfg_lut",)),
    Option("lut_sampling", "choice", "LUT sampling: GGX visible normals | NDF half vectors", LUT_SAMPLINGS.names,
           default="vndf", bakes=("dfg_lut",)),
    Option("runtime_samples", "int", "samples per pixel of runtime importance sampling", lo=1, hi=1 << 14, default=64),
    Option("runtime_sampling", "choice", "runtime half-vector distribution (article 001 samples Beckmann for GGX)",
           RUNTIME_SAMPLINGS.names, default="vndf"),
    Option("runtime_lod", "bool", "runtime: mip-filtered environment lookups from the pdf (GPU Gems 3 ch. 20)",
           default=True),
    Option("runtime_rotate", "bool", "runtime: per-pixel XOR scrambling of the Hammersley points", default=True),
    Option("energy_compensation", "choice", "multiple-scattering energy compensation of the split-sum specular "
           "(pbrcheck/energy.py): none | filament | fdez_aguera | kulla_conty | scene (none for a single-scattering "
           "scene, the best measured one for [brdf] multiscatter = random_walk)",
           ("scene", *ENERGY_COMPENSATIONS.names),
           # "scene": compensate exactly when the scene's reference has multiple scattering (pbrcheck energy:
           # filament has the lowest albedo and image error against the random walk; docs/research.md).
           default="scene"),
    Option("ndf", "choice", "D term ('scene': the scene's [brdf] ndf)", ("scene", *NDFS.names),
           default="scene", bakes=("dfg_lut",)),
    Option("geometry", "choice", "G term for direct and runtime lighting ('scene': the scene's)", GEOMETRY_CHOICES,
           default="scene"),
    Option("fresnel", "choice", "F term ('scene': the scene's)", ("scene", *FRESNELS.names), default="scene"),
    Option("min_roughness", "float", "roughness clamp (article 001: 0.01)", lo=0.0, hi=1.0, default=0.0),
    Option("reflect_bug", "bool", "article 002's reflect(v, n) with v towards the eye (looks up -r)", default=False),
    Option("shadows", "bool", "point lights are occluded by the scene's objects (off by default: the "
           "reference's `local` integrator casts no shadow rays, so the default comparison measures "
           "shading approximations only; turn on against `--mode path`)",
           default=False),  # as the reference's `local` integrator (no visibility tests)
    Option("supersample", "int", "s x s samples per pixel, box downsample", lo=1, hi=16, default=4),
    Option("pipeline", "choice", "how hits are found: auto (raster where the scene holds glTF meshes or, without "
           "shadows, a transmissive material; else raycast) | "
           "raycast (the compute pass's exact analytic shapes) | raster (meshes; analytic shapes tessellated)",
           ("auto", "raycast", "raster"), default="auto"),
    Option("occlusion_texture", "bool", "raster: the glTF occlusion texture scales the image-based diffuse light "
           "(glTF 2.0 3.9.4) and feeds specular_occlusion", default=True),
    Option("specular_occlusion", "choice", "occlusion of the split-sum specular from the ambient occlusion: none | "
           "lagarde (Lagarde & de Rousiers 2014, listing 26) | gtso (Jimenez et al. 2016, cone/cone intersection)",
           SPECULAR_OCCLUSIONS.names, default="none"),
    Option("horizon_occlusion", "choice", "fade of normal-mapped reflections below the geometric normal's horizon: "
           "none | marmoset (Russell 2015, Jimenez et al. 2016); no normal map (the ray-cast shapes): no change",
           HORIZON_OCCLUSIONS.names, default="none"),
    Option("specular_aa", "choice", "specular anti-aliasing / normal-map filtering, the roughness widened by the "
           "normals' variance: none | toksvig (Toksvig 2005) | screen_space (Kaplanyan 2016, Tokuyoshi & Kaplanyan "
           "2019, as Filament; raster only) | prefiltered (slope variance baked per normal-map mip); toksvig and "
           "prefiltered change only normal-mapped materials", SPECULAR_AAS.names, default="none"),
    # multisampling is the raster pipeline's (the ray-cast compute pass supersamples)
    Option("msaa", "int", "raster: samples per colour-pass pixel (1: off), on top of supersample's s x s",
           lo=1, hi=8, power_of_two=True, requires={"pipeline": ("raster",)}, off=1, default=1),
    Option("alpha_to_coverage", "bool", "raster: MASK materials write a sharpened alpha to coverage (Golus 2017) "
           "instead of discarding below alphaCutoff; needs msaa > 1", off=False,
           requires={"pipeline": ("raster",), "msaa": MULTISAMPLES}, default=False),
    Option("anisotropy", "float", "raster: maximum anisotropic filtering of material textures (1: trilinear only)",
           lo=1.0, hi=16.0, default=1.0, bakes=("material_texture", "normal_variance")),
    Option("texture_sampling", "choice", "raster: material textures other than the normal map (base colour, "
           "metallic-roughness, emissive, occlusion): mip (trilinear through the mip chain, as engines) | lod0 "
           "(bilinear at level 0 only, as the reference reads them; with supersampling, its filtering)",
           TEXTURE_SAMPLINGS, default="mip"),
    Option("normal_sampling", "choice", "raster: the normal map: mip (trilinear, averaged normals renormalized, as "
           "engines) | lod0 (bilinear at level 0 only, as the reference)", TEXTURE_SAMPLINGS, default="mip"),
    # The glTF PBR extensions' lobes (issue 36; realtime/shaders/material_lobes.glsl): each engine family's
    # form a member of its registry (realtime.registry.LOBE_REGISTRIES); compiled only into the programs
    # of scenes whose materials use the lobe, so these options change nothing else.
    Option("coat_ibl", "choice", "clearcoat: weight of the coat's prefiltered lookup: splitsum (F0 A + B, the DFG "
           "LUT at the coat's roughness) | sample_viewer (Fdez-Aguera k_S) | filament (Fc(n.v), no DFG) | threejs "
           "(EnvBRDFApprox)", COAT_IBLS.names, default="splitsum"),
    Option("coat_attenuation", "choice", "clearcoat: the base's attenuation 1 - clearcoat Fc: nov (the spec, "
           "Filament, three.js) | voh (the Sample Viewer's punctual form; image-based light reads n.v)",
           COAT_ATTENUATIONS.names, default="nov"),
    Option("sheen_dfg", "choice", "sheen: image-based weight: lut_charlie (the spec's albedo E) | lut_neubelt "
           "(Filament's DFG.z, the Sample Viewer's Charlie LUT) | lut_ibl_sampler_legacy | threejs (DG fit / pi "
           "x irradiance) | playcanvas (DG fit x the roughest level along n) | fitted (pbrcheck fit-lobes' AD-fitted "
           "8 x 8 table of the spec's E)", SHEEN_DFGS.names,
           default="lut_charlie"),
    Option("sheen_scaling", "choice", "sheen: the base's albedo scaling: lut (1 - max(c) E, the spec) | "
           "filament (1 - max(c) DFG.z) | threejs (1 - 0.157 max(c))", SHEEN_SCALINGS.names, default="lut"),
    Option("sheen_cube", "choice", "sheen: the radiance a LUT weight multiplies: charlie (the Charlie-prefiltered "
           "cube, Sample Viewer) | ggx (the GGX-prefiltered cube at the sheen roughness, Filament)",
           ("charlie", "ggx"), default="charlie"),
    Option("anisotropy_bend", "choice", "anisotropy: the prefiltered lookup's bent direction: sample_viewer | "
           "threejs | filament | babylon | fitted (the Sample Viewer's bend with pbrcheck fit-lobes' AD-fitted weight)",
           ANISOTROPY_BENDS.names, default="sample_viewer"),
    Option("iridescence", "choice", "iridescence: the thin-film Fresnel: belcour_rgb (Belcour & Barla 2017 in "
           "RGB, the Sample Viewer's) | none (no film, as an engine without the extension)", IRIDESCENCES.names,
           default="belcour_rgb"),
    # Transmission (issue 37 item 2; realtime/transmission.py, shaders/transmission.glsl): compiled only into
    # the raster programs of scenes with a transmissive material, so it changes nothing else.
    Option("transmission_lod_bias", "float", "transmission: levels added to the transmission_lod rule's level "
           "(clamped at 0; no engine's: compare.transmission_split's LOD scan)", lo=-16.0, hi=16.0, default=0.0),
    Option("transmission_lod", "choice", "transmission: the opaque-pass framebuffer's read along the refracted "
           "ray: sample_viewer (textureLod at log2(width) applyIorToRoughness, trilinear) | threejs (the same "
           "level, textureBicubic)", TRANSMISSION_LODS.names, default="sample_viewer"),
    Option("transmission_source", "choice", "transmission: what the refracted ray reads: screen (the opaque-pass "
           "framebuffer, the cube off screen; raster) | cubemap (Filament's cube-map refraction: the prefiltered "
           "cube along the ray leaving the object); the ray-cast pipeline always reads the cube",
           TRANSMISSION_SOURCES.names, default="screen"),
    Option("sheen_lut_size", "int", "sheen LUT size N (N x N; realtime.lobes.SHEEN_LUT_CONVENTIONS)", lo=2, hi=512,
           default=32, bakes=("sheen_lut",)),
    Option("sheen_lut_samples", "int", "Charlie samples per sheen LUT texel", lo=1, hi=1 << 16, default=4096,
           bakes=("sheen_lut",)),
    Option("charlie_size", "int", "face size of the Charlie-prefiltered cube (sheen)", lo=4, hi=1024,
           power_of_two=True, default=64, bakes=("charlie_prefilter",)),
    Option("charlie_levels", "int", "levels of the Charlie-prefiltered cube (level L at sheen roughness "
           "L / (levels - 1))", lo=2, hi=11, default=6, bakes=("charlie_prefilter",)),
    Option("charlie_samples", "int", "Charlie samples per texel of the Charlie-prefiltered cube", lo=1, hi=1 << 14,
           default=512, bakes=("charlie_prefilter",)),
    Option("tonemap", "choice", "display images only (EXR stays linear): none | aces (article 002's fit)",
           ("none", "aces"), default="none"),
    Option("exposure", "float", "display exposure multiplier (before the tone map)", lo=0.0, hi=1e6, default=1.0),
    Option("shader", "file", "shader hook file (docs/hooks.md): its hook_* functions replace built-in pieces of "
           "the frame pass ('': none; needs shading = material)", default=""),
]}

def _preset(**changes) -> dict:
    """Every option's :attr:`Option.default`, with ``changes``."""
    d = {name: copy.deepcopy(opt.default) for name, opt in OPTIONS.items()}
    d.update(changes)
    return d


PRESETS: dict[str, dict] = {
    "default": _preset(),
    # Article 000 (Drevicky 2018): uniform polar/azimuth irradiance, N.L-weighted prefilter with
    # v = n = r and no source-mip filtering, mip = roughness x max mip, LUT with k = (r+1)^2/8 by GGX
    # half-vector sampling in RG16F, kD = (1 - F(n.v))(1 - metallic), listing 1 for the lights.
    # Cube in RGB16F as its implementation (LearnOpenGL-style) does; LUT size not stated: 128.
    "splitsum_basic": _preset(
        shading="article000", cube_format="f16", irradiance="convolution", irradiance_method="polar_steps",
        irradiance_step=0.025, prefilter_samples=1024, prefilter_filtered=False, prefilter_nl_weight=True,
        prefilter_levels=5, lod_mapping="linear", dfg="lut", lut_size=128, lut_samples=1024, lut_format="f16",
        lut_geometry="schlick_ggx_direct", lut_sampling="ndf", ndf="ggx", geometry="schlick_ggx_direct",
        fresnel="schlick", energy_compensation="none"),
    # Article 001: runtime importance sampling, Beckmann half vectors for the GGX D, mip-filtered
    # lookups, XOR-rotated Hammersley points, F0 clamped to [0.02, 0.99], roughness >= 0.01.
    "runtime_is20": _preset(
        shading="article001", ibl="runtime", runtime_samples=20, runtime_sampling="beckmann", runtime_lod=True,
        runtime_rotate=True, min_roughness=0.01, ndf="ggx", geometry="smith_ggx", fresnel="schlick",
        energy_compensation="none"),
    "runtime_is256": _preset(
        shading="article001", ibl="runtime", runtime_samples=256, runtime_sampling="beckmann", runtime_lod=True,
        runtime_rotate=True, min_roughness=0.01, ndf="ggx", geometry="smith_ggx", fresnel="schlick",
        energy_compensation="none"),
    # Filament's documented IBL (Filament documentation sec. 5.3 "Image based lights"): irradiance
    # as 9 SH coefficients, prefiltered levels at lod = M r (2 - r) (perceptualRoughnessToLod), its
    # DFG LUT (GGX, height-correlated Smith; the multiscatter form mix(dfg.x, dfg.y, F0) = F0 A + B)
    # and its energy compensation 1 + F0 (1 / dfg.y - 1) of the specular lobe.
    # Its lobes (light_indirect.fs, shading_model_standard.fs): the coat's prefiltered radiance times
    # Fc(n.v) coat (no DFG), the base times 1 - coat Fc(n.v); the sheen from the GGX-prefiltered cube at
    # the sheen roughness times DFG.z (the LUT's V_Neubelt channel), the base times 1 - max(c) DFG.z;
    # the anisotropic bent normal mix(n, (d x v) x d, |s| saturate(5 r)); no thin film (Filament's
    # shading model has no iridescence parameter).
    "filament": _preset(
        irradiance="sh9", lod_mapping="quadratic", dfg="lut", lut_geometry="smith_ggx_correlated",
        lut_sampling="vndf", energy_compensation="filament", coat_ibl="filament", coat_attenuation="nov",
        sheen_dfg="lut_neubelt", sheen_scaling="filament", sheen_cube="ggx", anisotropy_bend="filament",
        iridescence="none"),
    # The Khronos glTF Sample Viewer (KhronosGroup/glTF-Sample-Viewer source/Renderer/shaders/ibl.glsl,
    # material_info.glsl, pbr.frag): prefiltered levels at lod = roughness (mipCount - 1) (linear), the
    # GGX LUT (height-correlated Smith), the Fdez-Aguera 2019 single + multiple scattering (k_S A + B with
    # its roughness-dependent Fresnel; FmsEms added to the diffuse); its lobes, as the version the
    # client pins (1.1.0; compare/lobe_findings.py cites each): the coat's prefiltered radiance at the
    # coat's roughness weighted by clearcoat Fc(n_c.v) with no DFG factor (pbrShader main: its VdotH
    # argument is unused), the base times 1 - coat Fc(n.v); the sheen from the Charlie-prefiltered cube
    # times its iblFiltering Charlie LUT (alpha = sheenRoughness, not squared; V_Ashikhmin), the base
    # scaled by the spec's albedo LUT; the bent normal of getIBLRadianceAnisotropy; Belcour & Barla's
    # RGB thin film.
    "sample_viewer": _preset(
        lod_mapping="linear", dfg="lut", lut_geometry="smith_ggx_correlated", lut_sampling="vndf",
        energy_compensation="fdez_aguera", coat_ibl="filament", coat_attenuation="nov",
        sheen_dfg="lut_ibl_sampler_legacy", sheen_scaling="lut", sheen_cube="charlie", anisotropy_bend="sample_viewer",
        iridescence="belcour_rgb", transmission_lod="sample_viewer"),
    # Article 002: EnvBRDFApprox, f0 = max(albedo x metalness, 0.04), lerp(diffuse, specular, ...),
    # SH9 irradiance, radiance mips at roughness x mip count, its reflect(v, n), ACES for display.
    "analytic_mobile": _preset(
        shading="article002", dfg="analytic", irradiance="sh9", lod_mapping="linear", prefilter_nl_weight=False,
        prefilter_filtered=True, reflect_bug=True, tonemap="aces", cube_format="f16", energy_compensation="none"),
}


def parse_value(name: str, raw) -> object:
    """Validate one option value (strings from the command line, or Python values)."""
    opt = OPTIONS.get(name)
    if opt is None:
        raise OptionError(f"unknown option {name!r}; options are: {', '.join(sorted(OPTIONS))}")
    try:
        if opt.kind == "bool":
            if isinstance(raw, bool):
                v = raw
            elif isinstance(raw, str) and raw.lower() in ("true", "1", "yes", "on"):
                v = True
            elif isinstance(raw, str) and raw.lower() in ("false", "0", "no", "off"):
                v = False
            else:
                raise ValueError
        elif opt.kind == "int":
            if isinstance(raw, bool):
                raise ValueError
            if isinstance(raw, float):
                if not raw.is_integer():
                    raise ValueError
                raw = int(raw)
            v = int(raw)
        elif opt.kind == "float":
            if isinstance(raw, bool):
                raise ValueError
            v = float(raw)
            if v != v or v in (float("inf"), float("-inf")):
                raise ValueError
        elif name == "lod_mapping" and isinstance(raw, LodMapping):
            return raw  # a fitted mapping in memory (pbrcheck fit-lod's, before it is written)
        elif name == "lod_mapping" and isinstance(raw, str) and raw.startswith("fitted:"):
            return _fitted_value(raw)
        elif opt.kind == "file":
            v = str(raw)
            if v and not Path(v).is_file():
                raise OptionError(f"option {name}: no such file {v!r}")
            return v
        else:
            v = str(raw)
            if v not in opt.choices:
                raise ValueError
    except (ValueError, TypeError):
        expect = {"bool": "true | false", "int": "an integer", "float": "a finite number"}.get(
            opt.kind, " | ".join(opt.choices))
        raise OptionError(f"option {name}: expected {expect}, found {raw!r}") from None
    if opt.lo is not None and v < opt.lo or opt.hi is not None and v > opt.hi:
        raise OptionError(f"option {name}: expected a value in [{opt.lo}, {opt.hi}], found {raw!r}")
    if opt.power_of_two and (v & (v - 1)) != 0:
        raise OptionError(f"option {name}: expected a power of two, found {raw!r}")
    return v


def _fitted_value(raw: str) -> str:
    """``fitted:PATH``: the file must hold a fitted mapping (pbrcheck.lodmap); the path is made absolute."""
    path = Path(raw[len("fitted:"):]).expanduser()
    if not raw[len("fitted:"):]:
        raise OptionError("option lod_mapping: fitted: needs a file, as in fitted:out/fit_lod.json")
    LodMapping.load(path)  # raises LodFitError (a PbrcheckError) naming the file
    return f"fitted:{path.resolve()}"


def fitted_mapping(value):
    """The :class:`pbrcheck.lodmap.LodMapping` of a ``lod_mapping`` value: the value itself when it is
    one, the file's for ``fitted:PATH``, else None (a built-in mapping)."""
    if isinstance(value, LodMapping):
        return value
    if not isinstance(value, str) or not value.startswith("fitted:"):
        return None
    return LodMapping.load(value[len("fitted:"):])


#: The option value a fitted mapping held in memory has in JSON (metadata, cache keys): the file
#: form ``fitted:PATH`` without a path.
IN_MEMORY_FITTED = "fitted:"


class _OptionsBase:
    """Methods of :class:`RealtimeOptions` (attribute access only: ``o.cube_size``)."""

    def as_dict(self) -> dict:
        """Every option's JSON value (``Image.meta["options"]``, cache keys): a fitted mapping held
        in memory is :data:`IN_MEMORY_FITTED`."""
        return {f.name: (IN_MEMORY_FITTED if isinstance(v := getattr(self, f.name), LodMapping) else v)
                for f in fields(self)}

    def replace(self, **changes) -> "RealtimeOptions":
        """A copy with ``changes`` (values as :func:`parse_value` returns them; not re-validated)."""
        return _replace(self, **changes)

    @property
    def fitted(self) -> LodMapping | None:
        """The fitted LOD mapping (held, or read from its ``fitted:PATH`` file), else None."""
        return fitted_mapping(self.lod_mapping)

    @property
    def chain(self) -> str:
        """The built-in mapping whose inverse bakes the prefiltered levels (a fitted mapping's ``chain``)."""
        fm = self.fitted
        return fm.chain if fm is not None else self.lod_mapping

    def __repr__(self) -> str:
        return f"RealtimeOptions({', '.join(f'{k}={v!r}' for k, v in self.as_dict().items())})"


_PY_TYPES = {"int": int, "float": float, "bool": bool, "choice": str, "file": str}

#: The resolved options of one real-time render, one typed attribute per :data:`OPTIONS` entry
#: (``o.cube_size``), frozen; built by :func:`resolve_options` only (its values are validated).
#: ``lod_mapping`` is a built-in name, ``fitted:PATH``, or a :class:`~pbrcheck.lodmap.LodMapping`.
RealtimeOptions = make_dataclass(
    "RealtimeOptions",
    [(name, "str | LodMapping" if name == "lod_mapping" else _PY_TYPES[opt.kind]) for name, opt in OPTIONS.items()],
    bases=(_OptionsBase,), frozen=True, eq=True, repr=False)
RealtimeOptions.__module__ = __name__
RealtimeOptions.__doc__ = """The resolved options of one real-time render: one typed, read-only attribute per
:data:`OPTIONS` entry (``o.cube_size``), built by :func:`resolve_options`.
``lod_mapping`` is a built-in name, ``fitted:PATH`` or a :class:`~pbrcheck.lodmap.LodMapping` held in
memory; :attr:`fitted` and :attr:`chain` read it, :meth:`as_dict` is the JSON form."""


def split_preset(text: str) -> tuple[str, dict]:
    """``PRESET`` or ``PRESET+FILE.glsl`` (a shader hook file named wherever a preset is,
    :data:`SHADER_SEP`): the preset name and the option overrides the name carries (``{"shader":
    FILE}`` or none). The one parser of that form: callers keep its result
    (:class:`compare.renderers.RendererSpec`), nothing splits a name twice."""
    if SHADER_SEP not in text:
        return text, {}
    preset, shader = text.split(SHADER_SEP, 1)
    if not shader:
        raise OptionError(f"renderer {text!r}: expected PRESET+FILE.glsl, found no file after {SHADER_SEP!r}")
    return preset, {"shader": shader}


def parse_sets(items) -> dict:
    """``["key=value", ...]`` from ``--set`` into a dict (values still strings)."""
    out = {}
    for it in items or ():
        if "=" not in it:
            raise OptionError(f"--set {it!r}: expected key=value")
        k, v = it.split("=", 1)
        out[k.strip()] = v.strip()
    return out


def overrides_from_args(sets, shader: str | None = None) -> dict:
    """Option overrides of a command line: ``--set KEY=VALUE`` items and ``--shader FILE.glsl``."""
    out = parse_sets(sets)
    if shader:
        out["shader"] = shader
    return out


#: The options whose values are members of a registry, by option name (``scene`` and ``fitted:FILE``
#: values are not members): :func:`resolve_options` checks each chosen member's requirements.
OPTION_REGISTRIES = {"shading": SHADINGS, "irradiance": IRRADIANCES, "irradiance_method": IRRADIANCE_METHODS,
                     "lod_mapping": LOD_MAPPINGS, "dfg": DFGS, "lut_geometry": GEOMETRIES,
                     "lut_sampling": LUT_SAMPLINGS, "runtime_sampling": RUNTIME_SAMPLINGS,
                     "energy_compensation": ENERGY_COMPENSATIONS, "ndf": NDFS, "geometry": GEOMETRIES,
                     "fresnel": FRESNELS, "specular_occlusion": SPECULAR_OCCLUSIONS,
                     "horizon_occlusion": HORIZON_OCCLUSIONS, "specular_aa": SPECULAR_AAS,
                     "coat_ibl": COAT_IBLS, "coat_attenuation": COAT_ATTENUATIONS, "sheen_dfg": SHEEN_DFGS,
                     "sheen_scaling": SHEEN_SCALINGS, "anisotropy_bend": ANISOTROPY_BENDS, "iridescence": IRIDESCENCES,
                     "transmission_lod": TRANSMISSION_LODS, "transmission_source": TRANSMISSION_SOURCES}


#: Option values decided at render time (``auto``: by the scene, :func:`realtime.render.resolved_pipeline`):
#: :func:`resolve_options` leaves a requirement on them to :func:`realtime.render.check_pipeline_options`,
#: which checks it against the resolved value.
DEFERRED = {"pipeline": "auto"}


def unmet_requirements(entry: Entry, values) -> dict[str, tuple[str, ...]]:
    """The requirements of registry member ``entry`` (:attr:`pbrcheck.registry.Entry.requires`) that
    the options ``values`` (a dict or :class:`RealtimeOptions`) do not meet: option -> accepted values."""
    return {k: accepted for k, accepted in entry.requires.items() if _value(values, k) not in accepted}


def _value(values, name: str):
    """Option ``name`` of ``values``: a dict of option values (:func:`resolve_options` while it
    builds one) or a :class:`RealtimeOptions`."""
    return values[name] if isinstance(values, dict) else getattr(values, name)


def check_requirements(values, resolved: dict | None = None) -> None:
    """Raise :class:`OptionError` for the first chosen value whose requirements ``values`` (a dict or
    :class:`RealtimeOptions`, with ``resolved`` values replacing theirs) do not meet: a registry
    member's (:data:`OPTION_REGISTRIES`, :attr:`pbrcheck.registry.Entry.requires`: a composition its
    specular IBL, an energy compensation the material composition's split sum, ``specular_aa =
    screen_space`` the raster pipeline's screen derivatives) and an option's other than off
    (:attr:`Option.requires`: ``msaa`` and ``alpha_to_coverage`` the raster pipeline's multisampling).
    A requirement on a :data:`DEFERRED` value is left to the render, which resolves it."""
    resolved = resolved or {}

    def get(k):
        return resolved.get(k, _value(values, k))

    chosen = [(name, get(name), reg[get(name)].requires) for name, reg in OPTION_REGISTRIES.items()
              if get(name) in reg]
    chosen += [(name, get(name), opt.requires) for name, opt in OPTIONS.items()
               if opt.requires and get(name) != opt.off]
    for name, value, requires in chosen:
        unmet = [k for k, accepted in requires.items() if get(k) not in accepted and DEFERRED.get(k) != get(k)]
        if unmet:
            needs = " and ".join(f"{k}={'|'.join(map(str, v))}" for k, v in requires.items())
            shown = str(value).lower() if isinstance(value, bool) else value
            raise OptionError(f"option {name}: {shown} needs {needs}, found "
                              f"{', '.join(f'{k}={get(k)}' for k in requires)}")


def resolve_options(preset: str = "default", overrides: dict | None = None) -> RealtimeOptions:
    """The complete options of ``preset`` (a name of :data:`PRESETS`; a ``PRESET+FILE.glsl`` renderer
    name is split once where it is read, :func:`split_preset`) with ``overrides`` applied and validated."""
    if preset not in PRESETS:
        raise OptionError(f"unknown preset {preset!r}; presets are: {', '.join(PRESETS)}")
    d = copy.deepcopy(PRESETS[preset])
    for k, v in (overrides or {}).items():
        d[k] = parse_value(k, v)
    if d["prefilter_levels"] > d["cube_size"].bit_length():
        raise OptionError(f"option prefilter_levels: at most {d['cube_size'].bit_length()} levels for "
                          f"cube_size {d['cube_size']}, found {d['prefilter_levels']}")
    fm = fitted_mapping(d["lod_mapping"])
    if fm is not None and (fm.cube_size != d["cube_size"] or fm.mip_count != d["prefilter_levels"]):
        what = "the fitted mapping" if isinstance(d["lod_mapping"], LodMapping) else d["lod_mapping"][len("fitted:"):]
        raise OptionError(f"option lod_mapping: {what} was fitted for a "
                          f"{fm.cube_size}^2 cube with {fm.mip_count} mips; this render has cube_size "
                          f"{d['cube_size']} and prefilter_levels {d['prefilter_levels']}")
    # What each chosen registry member and option value requires of the other options (a composition
    # its specular IBL, an energy compensation the material composition's split sum, the raster-only
    # options the raster pipeline; with pipeline=auto the render checks that once it is resolved).
    check_requirements(d)
    if d["shader"] and not SHADINGS[d["shading"]].extra.get("hooks"):
        hooked = "|".join(e.name for e in SHADINGS if e.extra.get("hooks"))
        raise OptionError(f"option shader: hooks replace pieces of shading={hooked}; this preset has "
                          f"shading={d['shading']}")
    if d["irradiance_source_size"] > d["cube_size"]:
        raise OptionError(f"option irradiance_source_size: at most cube_size ({d['cube_size']}), "
                          f"found {d['irradiance_source_size']}")
    if d["pipeline"] == "raster" and d["shadows"]:
        raise OptionError("option shadows: the raster pipeline has no shadow rays (use pipeline=raycast)")
    return RealtimeOptions(**d)


class BakeInputs:
    """The option values one bake reads (:data:`BAKES`), and nothing else: ``i.cube_size`` for a
    declared option (:attr:`Option.bakes`), :class:`AttributeError` naming the option and the bake
    for any other, so a bake that starts reading an option without declaring it fails at its first
    render instead of keying a stale texture. Built by :func:`bake_inputs`; :meth:`key` is its cache key."""

    __slots__ = ("bake", "values")

    def __init__(self, bake: str, values: dict):
        object.__setattr__(self, "bake", bake)
        object.__setattr__(self, "values", dict(values))

    def __getattr__(self, name: str):
        try:
            return self.values[name]
        except KeyError:
            raise AttributeError(f"bake {self.bake!r} reads option {name!r}, which does not list it in "
                                 f"Option.bakes (realtime/presets.py): its cache key would miss it") from None

    def __setattr__(self, name, value):
        raise AttributeError("BakeInputs is read-only")

    def key(self, *context) -> tuple:
        """:func:`bake_key` of these values, with the non-option ``context`` (an environment's hash...)."""
        return bake_key(self.bake, *context, **self.values)


def bake_options(bake: str) -> tuple[str, ...]:
    """The options whose values bake ``bake`` reads (:attr:`Option.bakes`), in :data:`OPTIONS` order."""
    if bake not in BAKES:
        raise KeyError(f"unknown bake {bake!r}; bakes are: {', '.join(BAKES)}")
    return tuple(name for name, opt in OPTIONS.items() if bake in opt.bakes)


def bake_inputs(bake: str, o: RealtimeOptions, **resolved) -> BakeInputs:
    """The values of ``o`` that ``bake`` reads (:func:`bake_options`); ``resolved`` replaces an
    option's value by what the render resolved it to (``cube_format`` f16 switched to f32, the
    scene's geometry for ``lut_geometry = scene``, a fitted mapping's chain), so the key tells
    apart what the bake tells apart. A ``resolved`` name the bake does not read is an error."""
    names = bake_options(bake)
    stray = sorted(set(resolved) - set(names))
    if stray:
        raise KeyError(f"bake {bake!r} does not read option(s) {', '.join(stray)} (Option.bakes)")
    return BakeInputs(bake, {n: resolved[n] if n in resolved else getattr(o, n) for n in names})


def bake_key(bake: str, *context, **values) -> tuple:
    """The process-cache key of ``bake``: ``(bake, *context, values as JSON)``. ``values`` must be
    exactly the bake's options (:func:`bake_options`): a missing or extra one is a :class:`KeyError`,
    so a bake called with plain arguments (``env_cube(env, size, fmt)``) is keyed by the same rule
    as one reading :class:`RealtimeOptions`. ``context`` holds what is not an option (an
    environment's content hash, an image's identity)."""
    names = bake_options(bake)
    if set(values) != set(names):
        missing, extra = sorted(set(names) - set(values)), sorted(set(values) - set(names))
        raise KeyError(f"bake {bake!r} keyed by its options {', '.join(names)}: "
                       f"missing {missing or 'none'}, not its own {extra or 'none'}")
    return (bake, *context, json.dumps(values, sort_keys=True, default=str))
