"""Why do two images differ? Known convention mismatches, each undone in turn and ranked.

An external renderer that disagrees with the reference by 30 % has either an approximation error
or a *convention* mismatch: a flipped image, sRGB data read as linear, an environment rotated by a
quarter turn, roughness used as alpha, ... Each hypothesis below is a transform that undoes one such
mismatch; :func:`diagnose` applies each, measures the error that remains and ranks them by how much
of the error each one removes, against the reference's own noise. The likely cause must reduce the
error over the bulk of the pixels too (all but the worst :data:`BULK_OUTLIERS`): a mismatch
moves every pixel, while a handful of outliers (sun glints an unconverged reference misses) can
carry most of a relative MSE that a fitted exposure or a compressive transform then "explains".

Hypotheses
----------
Image space (the test image is transformed; no render):

- ``flip_vertical``, ``flip_horizontal``: rows or columns reversed (row 0 at the bottom, GL style).
- ``srgb_as_linear``: the test holds sRGB-encoded values read as linear; undone by the sRGB EOTF.
- ``linear_as_srgb``: linear values decoded as sRGB once more; undone by the sRGB OETF.
- ``exposure``: a global factor ``k``, fitted in closed form to minimise the relative MSE:
  ``k = sum(w t r) / sum(w t^2)`` with ``w = 1 / (r^2 + eps)``; named only where ``k`` agrees
  with the median of the per-pixel ratios ``r / t`` (:data:`EXPOSURE_CONSISTENCY`).
- ``hdr_clamp``: the test clamps radiance at a level ``c``, fitted as the test's maximum; the
  reference is clamped at ``c`` (a clamp cannot be undone, so the reference is brought to it).
- ``swap_rb``: red and blue channels exchanged (BGR readback).
- ``premultiplied_alpha``: the test's colour is premultiplied by coverage (transparent background):
  the reference is multiplied by its coverage AOV.

Scene space (``scene`` given: the reference is re-rendered under the hypothesis, through the cache,
at the reference image's own spp (capped at MAX_HYPOTHESIS_SPP) and seed):

- ``env_rotate_90``, ``env_rotate_180``, ``env_rotate_270``: the environment rotated about +Y.
- ``env_mirror_u``: the environment mirrored in u (``x -> -x`` in Mitsuba's mapping). Neither for a
  constant environment (the same rotated or mirrored: skipped, no re-render).
- ``roughness_as_alpha``: the test uses roughness as alpha (GGX alpha = r, not r^2), i.e. the
  reference with roughness ``sqrt(r)``; ``roughness_squared_twice``: alpha = r^4, roughness ``r^2``.
- ``diffuse_times_pi``, ``diffuse_over_pi``: the Lambert term off by pi: the base colour of every
  dielectric (``metallic = 0``, whose F0 is ``specular`` whatever the base colour) scaled by pi or
  1/pi; partial metals are left alone (their F0 depends on the base colour).
- ``light_units_4pi``, ``light_units_over_4pi``: point- and spot-light intensity off by 4 pi (power
  in W read as W/sr or the reverse): every point and spot light's intensity scaled, the scene
  file's and the glTF assets' (``KHR_lights_punctual``; an edited asset light enters the scene's
  content hash, :meth:`pbrcheck.scene.Scene.content_dict`). Directional lights (an irradiance, no 4
  pi) are left alone. Only for scenes with a point or spot light; the skip says which lights the
  scene has.
- ``multiple_scattering``: not a convention but a model difference engines commonly have: the
  renderer compensates the energy of multiple scattering between microfacets (three.js, Filament,
  ...); the reference re-rendered with ``[brdf] multiscatter = "random_walk"`` (Heitz et al. 2016).
  Named "a model difference" in the verdict. Only for GGX or Beckmann with its height-correlated Smith term;
  on glTF assets too (the walk per shading point, reference/textured.py) and under the clearcoat, sheen
  and specular lobes (the walk as their base, reference/lobe_bsdf.py); not beside anisotropy or
  iridescence (:func:`compare.lobes.no_random_walk`).
- ``metallic_blend``: also a model difference: the renderer mixes metallic as glTF 2.0 Appendix B
  does (``mix(dielectric_brdf, metal_brdf, metallic)``, the diffuse under the dielectric's own
  Fresnel) where the scene uses pbrcheck's F0 mix, or the reverse; the reference re-rendered with the
  other ``[brdf] metallic_blend``. Only where something is partially metallic (the blends agree at 0
  and 1); on glTF assets too.

Lobe departures (kind ``lobe``; ``scene`` given, and only for a scene whose objects carry the lobe):
one per engine form of :data:`compare.lobe_findings.DEPARTURES` that pbrcheck's real-time renderer
has a twin of (a member of :data:`realtime.registry.LOBE_REGISTRIES`), named ``lobe:<departure>``:
the reference plus what the form changes in the twin (``RT(member) - RT(spec's member)`` on the
:data:`LOBE_TWIN_PRESET` preset), or the twin's image where the spec defines no image-based form to
difference against. A departure from the specification, named so in the verdict; skipped, saying
why, while the real-time renderer does not take the family as an option, for a form only punctual
lights see in a scene without one, and on a display-referred pair.

Decision
--------
The error is the relative MSE (:mod:`compare.metrics`) over every pixel, covered or not (the
background is part of the contract, and flips and alpha show at silhouettes), less the expected
contribution of the reference's (or the re-render's) own variance, so that a noisy re-render does
not count against its hypothesis, and of a Monte Carlo engine's own (the renderer contract's
variance, :data:`compare.metrics.TEST_VARIANCE_META`), moved with a flip and scaled with an exposure.
The table says so (:data:`ERROR_LABEL`) and why ``pbrcheck compare`` prints another relmse for the
same pair (valid object pixels only, raw: :data:`ERROR_NOTE`). A display-referred pair (a
``png-srgb`` engine, its ``display_referred`` flag) is compared in display space like
``compare`` does, without the sRGB transfer hypotheses. The noise
error is the same measure on a simulated pair ``(r, r + sqrt(2 var) z)`` (the reference's variance
channels; 0 without them). A hypothesis is the *likely cause* when it leaves at most
:data:`LIKELY_REMAINING` of the error and the error before it was not already within
:data:`~compare.metrics.NOISE_EXPLAINS_FACTOR` of the noise; the best-ranked such hypothesis is
named, otherwise "no convention mismatch found".

API
---
- :class:`Hypothesis`, :data:`HYPOTHESES` -- every hypothesis (name, kind, description, the transform or
  scene edit, where it applies), in table order; :func:`hypothesis` -- one by name; :func:`offered`
  -- whether a hypothesis is in a scene's table (a ``lobe`` one: the scene carries its lobe). Adding a
  hypothesis is one entry of :data:`HYPOTHESES`.
- :func:`diagnose` -- rank the hypotheses for a (reference, test) pair; returns :class:`Diagnosis`.
- :func:`apply_image_hypothesis` -- the transform of one image-space hypothesis (also used by the
  tests to plant a mismatch).
- :func:`hypothesis_scene` -- the scene of one scene-space hypothesis that is a scene edit.
- :func:`table_markdown` -- the table and the verdict line.
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from pbrcheck.environment import load_environment, texel_directions
from pbrcheck.errors import PbrcheckError
from pbrcheck.exr import Image, write_exr
from pbrcheck.fmt import format_value
from pbrcheck.lights import DirectionalLight
from pbrcheck.progress import Progress
from pbrcheck.registry import MULTISCATTER_GEOMETRY
from pbrcheck.scene import Environment, Scene

from .. import renderers
from ..maps import srgb_oetf
from ..metrics import (NOISE_EXPLAINS_FACTOR, NOISE_SEED, REL_EPS, TEST_VARIANCE_META, display_referred,
                       is_display_referred, validate_pair)

#: A hypothesis "explains" the difference when undoing it leaves at most this fraction of the error
#: (the error at least halves). Generous enough that a correct image's residual approximation error
#: is never explained by a fitted exposure (measured: the default preset's exposure fit removes ~5 %).
LIKELY_REMAINING = 0.5
#: The fitted exposure must differ from 1 by more than this to be reported as a mismatch (a 2 %
#: global factor is an approximation's bias, not a convention).
EXPOSURE_MIN_DEVIATION = 0.02
#: A convention mismatch moves the bulk of the image, not a handful of pixels: the likely cause must
#: also reduce the error over the pixels outside this worst fraction (by each pixel's share of the
#: error before; a model difference such as multiple scattering reduces it less than the whole
#: image's, only on rough metals). A few outliers can carry most of a relative MSE, and a
#: fitted exposure or a compressive transform removes it there while making the rest worse
#: (measured: DamagedHelmet under royal_esplanade_1k at 200 x 150 against a 16-spp reference that
#: misses sun glints: the 10 worst of 3992 object pixels carry 53-63 % of three engines' absolute
#: difference; exposures of 0.073 (Sample Viewer) and 0.36 (three.js) "removed" 94 % and 67 % of it).
BULK_OUTLIERS = 0.01
#: A global exposure scales every pixel alike: the fitted ``k`` must agree with the median of the
#: per-pixel ratios ``r / t`` (values above REL_EPS in both) within this fraction to be named. A part
#: of the image where the test is much brighter (the Sample Viewer's skybox projection in the
#: background, glints) pulls the relative-MSE fit alone (measured, the DamagedHelmet pair above:
#: k = 0.073 and 0.36 against medians 0.94 and 0.999); a planted factor moves both alike.
EXPOSURE_CONSISTENCY = 0.25
#: Spp of the scene-space re-renders when the reference image does not say its own.
DEFAULT_HYPOTHESIS_SPP = 64
#: Cap on the re-renders' spp when taken from the reference (a 1024-spp reference would make each of
#: the ~8 re-renders as slow as itself; 256 spp keeps their noise well under a mismatch's error).
MAX_HYPOTHESIS_SPP = 256


#: What diagnose's error is (its table's first line): every pixel, less the images' own noise.
ERROR_LABEL = "all pixels, noise-corrected"
#: Why it differs from ``pbrcheck compare``'s relmse for the same pair (printed under it).
ERROR_NOTE = ("(pbrcheck compare's relmse is over the valid pixels only, fully covered object pixels, and "
              "not noise-corrected: the background and silhouettes, where flips and alpha show, count here)")


class DiagnoseError(PbrcheckError):
    """Inputs ``diagnose`` cannot work with (sizes, a scene that does not match the images)."""


@dataclass
class HypothesisRow:
    """One hypothesis: the error after undoing it, the fraction removed, and whether what is left
    is within the reference's noise. ``fitted`` holds a fitted parameter (exposure factor, clamp
    level); ``skipped`` says why a hypothesis was not tested."""

    hypothesis: str
    kind: str
    description: str
    error_after: float | None
    reduction: float | None
    within_noise: bool
    fitted: dict = field(default_factory=dict)
    skipped: str | None = None
    #: The fraction of the error removed over the bulk (the pixels outside the BULK_OUTLIERS worst;
    #: negative: the bulk got worse).
    bulk_reduction: float | None = None


@dataclass
class Diagnosis:
    """Result of :func:`diagnose`: the error before, the noise error, the ranked rows and the verdict."""

    metric: str
    error_before: float
    noise_error: float
    rows: list[HypothesisRow]
    likely: str | None
    line: str
    #: How the pair was compared: ``linear`` or ``display-referred`` (a ``png-srgb`` engine: both
    #: images clamped to [0, 1] and sRGB-encoded, as compare.metrics does; no noise floor).
    space: str = "linear"
    #: The reference mode of the scene-space re-renders (``local`` or ``path``; None: no scene).
    reference_mode: str | None = None

    def to_json(self) -> dict:
        return asdict(self)


# --- transforms -----------------------------------------------------------------------------------


def srgb_eotf(v: np.ndarray) -> np.ndarray:
    """Inverse of :func:`compare.maps.srgb_oetf` (IEC 61966-2-1 decode), extended above 1 by the
    same power law; negatives clip to 0."""
    v = np.clip(v, 0.0, None)
    return np.where(v <= 0.04045, v / 12.92, np.power((v + 0.055) / 1.055, 2.4))


def _fit_exposure(r: np.ndarray, t: np.ndarray) -> float:
    w = 1.0 / (r.astype(np.float64) ** 2 + REL_EPS)
    den = float((w * t * t).sum())
    return float((w * t * r).sum()) / den if den > 0 else 1.0


def _mirrored_environment(scene: Scene, directory: Path) -> Environment:
    """The scene's environment mirrored in u, as a file environment (scale and rotation baked in)."""
    env = load_environment(scene)
    h, w = env.height, env.width
    # The new map has no rotation, so its texel directions are world directions; each texel takes
    # the old radiance function (rotation and scale included) at the direction mirrored in x.
    d = texel_directions(w, h).reshape(-1, 3).copy()
    d[:, 0] = -d[:, 0]
    data = env.radiance(d).reshape(h, w, 3) / env.scale if env.scale > 0 else np.zeros((h, w, 3), np.float32)
    path = directory / "mirrored.exr"
    write_exr(path, Image.from_rgb(np.asarray(data, np.float32)))
    return Environment(type="file", path=str(path), scale=float(env.scale), rotation=0.0)


def _map_materials(scene: Scene, fn) -> Scene:
    return replace(scene, objects=tuple(replace(o, material=fn(o.material)) for o in scene.objects))


def _scale_dielectric_diffuse(k: float):
    """Scene edit: the base colour of every dielectric scaled by ``k``. A dielectric's F0 is
    ``specular`` whatever its base colour, so this scales exactly its Lambert lobe (values above 1
    are fine for the estimator: nothing clamps them); partial metals are left alone."""
    def edit(scene: Scene, directory: Path) -> tuple[Scene, dict]:
        return _map_materials(scene, lambda m: replace(m, base_color=tuple(k * c for c in m.base_color))
                              if m.metallic == 0 else m), {"factor": k}
    return edit


def _intensity_lights(scene: Scene) -> list:
    """The lights whose ``intensity`` is a radiant intensity (W/sr): point and spot, the scene file's
    and the glTF assets' (``KHR_lights_punctual``), where power and intensity differ by 4 pi; a
    directional light's is an irradiance (W/m^2), with no such factor."""
    return [li for li in scene.lights if not isinstance(li, DirectionalLight)]


def _scale_lights(k: float):
    """Scene edit: every point and spot light's intensity (:func:`_intensity_lights`, the glTF
    assets' included) scaled by ``k``; directional lights unchanged."""
    def edit(scene: Scene, directory: Path) -> tuple[Scene, dict]:
        return replace(scene, lights=tuple(li if isinstance(li, DirectionalLight) else
                                           replace(li, intensity=tuple(k * c for c in li.intensity))
                                           for li in scene.lights)), {"factor": k}
    return edit


def _rotate_environment(deg: float):
    """Scene edit: the environment rotated by ``deg`` more about +Y."""
    def edit(scene: Scene, directory: Path) -> tuple[Scene, dict]:
        env = scene.environment
        return replace(scene, environment=replace(env, rotation=(env.rotation + deg) % 360.0)), {}
    return edit


def _edit_materials(fn):
    """Scene edit: ``fn`` applied to every object's material."""
    return lambda scene, directory: (_map_materials(scene, fn), {})


def _image(fn):
    """Image transform ``(r, t) -> (r', t')`` with no fitted parameter."""
    return lambda r, t, coverage: (*fn(r, t), {})


def _exposure(r, t, coverage):
    k = _fit_exposure(r, t)
    lit = (r > REL_EPS) & (t > REL_EPS)
    median = float(np.median(r[lit] / t[lit])) if lit.any() else k
    return r, t * k, {"factor": k, "median_ratio": median}


def _names_exposure(fitted: dict) -> bool:
    """An exposure fit is a cause when it is not an approximation's bias (more than
    EXPOSURE_MIN_DEVIATION from 1) and the pixels agree (within EXPOSURE_CONSISTENCY of their median ratio)."""
    k, median = fitted["factor"], fitted["median_ratio"]
    return abs(k - 1.0) > EXPOSURE_MIN_DEVIATION and abs(k / median - 1.0) <= EXPOSURE_CONSISTENCY


def _hdr_clamp(r, t, coverage):
    c = float(np.max(t))
    return np.minimum(r, c), t, {"level": c}


def _premultiplied(r, t, coverage):
    cov = np.ones(r.shape[:2], np.float32) if coverage is None else coverage
    return r * cov[..., None], t, {}


def _always(ref: Image, scene: Scene | None) -> None:
    return None


def _needs_linear(ref: Image, scene: Scene | None) -> str | None:
    """A transfer hypothesis means nothing on a display-referred pair: the engine's sRGB encoding
    is its contract (``output = "png-srgb"``), and the reference is encoded the same way."""
    if is_display_referred(ref):
        return "the pair is display-referred (png-srgb): the sRGB transfer is the engine's contract, not a mismatch"
    return None


def _needs_coverage(ref: Image, scene: Scene | None) -> str | None:
    return None if ref.channels.get("coverage") is not None else "the reference has no coverage AOV"


def _needs_intensity_lights(ref: Image, scene: Scene) -> str | None:
    """Where the 4 pi of point- and spot-light units can be tested: why not otherwise."""
    if _intensity_lights(scene):
        return None
    assets = bool(getattr(scene, "assets", ()))
    if scene.lights:
        whose = " (the glTF assets' included)" if assets else ""
        return (f"the scene's lights{whose} are directional only: "
                "an irradiance (W/m^2, lux), with no 4 pi between power and intensity")
    if assets:
        return ("neither the scene file nor its glTF assets (KHR_lights_punctual) have a punctual light: only "
                "the environment lights it")
    return "the scene has no punctual light: only the environment lights it"


def _needs_varying_environment(ref: Image, scene: Scene) -> str | None:
    """A constant environment is the same rotated or mirrored: nothing to test (and no re-render)."""
    if scene.environment.type == "constant":
        return "the environment is constant: rotated or mirrored it is the same"
    return None


def _needs_dielectric(ref: Image, scene: Scene) -> str | None:
    return None if any(o.material.metallic == 0 for o in scene.objects) else "the scene has no dielectric object"


def _analytic_materials(ref: Image, scene: Scene) -> str | None:
    """glTF asset scenes' textured material reads the glTF material, not the objects' factors."""
    if getattr(scene, "assets", ()):
        return ("glTF asset materials (textures, the single-scattering pbr_textured) are not changed by this "
                "hypothesis yet")
    return None


def _both(*rules):
    """The first reason any of ``rules`` gives to skip (``None`` where all apply)."""
    def applies(ref: Image, scene: Scene | None) -> str | None:
        return next((why for why in (rule(ref, scene) for rule in rules) if why is not None), None)
    return applies


def _needs_partial_metal(ref: Image, scene: Scene) -> str | None:
    """The metallic blends differ only at 0 < metallic < 1 (a glTF asset: wherever a metallic texture
    or factor is fractional, so always tested there)."""
    if getattr(scene, "assets", ()) or any(0.0 < o.material.metallic < 1.0 for o in scene.objects):
        return None
    return "no partially metallic object: the two metallic blends agree at metallic 0 and 1"


def _other_blend(scene: Scene, directory: Path) -> tuple[Scene, dict]:
    """Scene edit: the other ``[brdf] metallic_blend`` (the engine's, if it is not the scene's)."""
    other = "gltf" if scene.brdf.metallic_blend == "f0" else "f0"
    return replace(scene, brdf=replace(scene.brdf, metallic_blend=other)), {}


def _needs_single_scattering_pair(ref: Image, scene: Scene) -> str | None:
    if scene.brdf.multiscatter != "none":
        return "the reference already scatters multiply"
    from ..lobes import no_random_walk
    lobes = no_random_walk(scene)
    if lobes is not None:
        return lobes
    if MULTISCATTER_GEOMETRY.get(scene.brdf.ndf) != scene.brdf.geometry:
        return ("the random walk needs ndf = ggx with geometry = smith_ggx_correlated or beckmann with "
                "smith_beckmann_correlated")
    return None


@dataclass(frozen=True)
class Hypothesis:
    """One known mismatch.

    ``kind``: ``"image"`` (``apply(r, t, coverage) -> (r', t', fitted)`` undoes it on the images) or
    ``"scene"`` (``apply(scene, directory) -> (scene', fitted)``: the scene whose reference is the
    image a renderer with the mismatch would make; ``directory`` receives any file it needs).
    ``applies_to(ref, scene)``: ``None`` where it can be tested, else why it is skipped. ``model``: a
    difference of physical model, not of convention (named so in the verdict). ``names_cause(fitted)``:
    whether a result with these fitted parameters may be named the likely cause."""

    name: str
    kind: str
    description: str
    apply: Callable
    applies_to: Callable[[Image, Scene | None], str | None] = _always
    model: bool = False
    #: Whether a result with these fitted parameters may be named the likely cause (an exposure
    #: within EXPOSURE_MIN_DEVIATION of 1 is an approximation's bias, not a convention).
    names_cause: Callable[[dict], bool] = lambda fitted: True
    #: A ``lobe`` hypothesis's extension: offered only for a scene whose objects carry it.
    lobe: str | None = None


#: Every hypothesis, in table order (image space first; scene space only with a scene).
HYPOTHESES: tuple[Hypothesis, ...] = (
    Hypothesis("flip_vertical", "image", "image rows reversed (row 0 at the bottom)",
               _image(lambda r, t: (r, t[::-1]))),
    Hypothesis("flip_horizontal", "image", "image columns reversed", _image(lambda r, t: (r, t[:, ::-1]))),
    Hypothesis("srgb_as_linear", "image", "sRGB-encoded values read as linear",
               _image(lambda r, t: (r, srgb_eotf(t))), _needs_linear),
    Hypothesis("linear_as_srgb", "image", "linear values decoded as sRGB",
               _image(lambda r, t: (r, srgb_oetf(np.clip(t, 0.0, None)))), _needs_linear),
    Hypothesis("exposure", "image", "a global exposure factor", _exposure, names_cause=_names_exposure),
    Hypothesis("hdr_clamp", "image", "radiance clamped at a level", _hdr_clamp),
    Hypothesis("swap_rb", "image", "red and blue channels swapped", _image(lambda r, t: (r, t[..., ::-1]))),
    Hypothesis("premultiplied_alpha", "image", "colour premultiplied by coverage (transparent background)",
               _premultiplied, _needs_coverage),
    *(Hypothesis(f"env_rotate_{deg}", "scene", f"environment rotated {deg} degrees about +Y",
                 _rotate_environment(float(deg)), _needs_varying_environment) for deg in (90, 180, 270)),
    Hypothesis("env_mirror_u", "scene", "environment mirrored in u",
               lambda scene, directory: (replace(scene, environment=_mirrored_environment(scene, directory)), {}),
               _needs_varying_environment),
    Hypothesis("roughness_as_alpha", "scene", "roughness used as alpha (not squared)",
               _edit_materials(lambda m: replace(m, roughness=math.sqrt(m.roughness))), _analytic_materials),
    Hypothesis("roughness_squared_twice", "scene", "roughness squared twice (alpha = r^4)",
               _edit_materials(lambda m: replace(m, roughness=m.roughness ** 2)), _analytic_materials),
    Hypothesis("diffuse_times_pi", "scene", "diffuse multiplied by pi", _scale_dielectric_diffuse(math.pi),
               _both(_analytic_materials, _needs_dielectric)),
    Hypothesis("diffuse_over_pi", "scene", "diffuse divided by pi", _scale_dielectric_diffuse(1 / math.pi),
               _both(_analytic_materials, _needs_dielectric)),
    Hypothesis("light_units_4pi", "scene", "point- and spot-light intensity multiplied by 4 pi",
               _scale_lights(4 * math.pi), _needs_intensity_lights),
    Hypothesis("light_units_over_4pi", "scene", "point- and spot-light intensity divided by 4 pi",
               _scale_lights(1 / (4 * math.pi)), _needs_intensity_lights),
    Hypothesis("multiple_scattering", "scene",
               "the renderer keeps the energy of multiple scattering (energy compensation)",
               lambda scene, directory: (replace(scene, brdf=replace(scene.brdf, multiscatter="random_walk")), {}),
               _needs_single_scattering_pair, model=True),
    Hypothesis("metallic_blend", "scene",
               "the renderer mixes metallic the other way (glTF's mix of two BRDFs, or pbrcheck's F0 mix)",
               _other_blend, _needs_partial_metal, model=True),
)


# --- lobe departures (compare.lobe_findings): kind "lobe" -----------------------------------------

#: The real-time preset whose twin of an engine's lobe form a ``lobe`` hypothesis renders (every
#: other option at its value, so that the difference of two renders is the form's alone).
LOBE_TWIN_PRESET = "default"


def _lobe_family(switch: str):
    from ..lobes import lobe_families
    return next((f for f in lobe_families() if f.switch == switch), None)


def _lobe_applies(dep):
    """Where departure ``dep``'s hypothesis can be tested: why not otherwise."""
    def applies(ref: Image, scene: Scene) -> str | None:
        if is_display_referred(ref):
            return "the pair is display-referred (png-srgb): the real-time twin's difference is linear radiance"
        if dep.punctual and not scene.lights:
            return "the form acts on punctual lights only and the scene has none"
        fam = _lobe_family(dep.switch)
        if fam is None or fam.option is None:
            return (f"the real-time renderer has no option for {dep.switch} yet (issue 36 item 3): no twin of "
                    "the form to render")
        missing = [m for m in (dep.member, dep.against) if m is not None and m not in fam.members]
        if missing:
            return f"{dep.switch} has no member {', '.join(missing)}"
        return None
    return applies


def _lobe_twin(dep):
    """``apply(scene, r) -> (r', keeps_variance, fitted)``: the reference plus what the form changes
    in the real-time twin (``against`` given), else the twin's image (noise-free)."""
    def apply(scene: Scene, r: np.ndarray) -> tuple[np.ndarray, bool, dict]:
        fam = _lobe_family(dep.switch)
        base = renderers.RendererSpec.parse(LOBE_TWIN_PRESET)

        def twin(member: str) -> np.ndarray:
            img = renderers.render_under_test(scene, base.with_options(**{fam.option: member}), progress=False)
            return img.rgb.astype(np.float64)

        fitted = {"option": f"{fam.option}={dep.member}"}
        if dep.against is None:
            return twin(dep.member), False, fitted
        return r + twin(dep.member) - twin(dep.against), True, {**fitted, "against": dep.against}
    return apply


def _lobe_hypotheses() -> tuple[Hypothesis, ...]:
    from ..lobe_findings import DEPARTURES
    return tuple(Hypothesis(f"lobe:{d.name}", "lobe",
                            f"{d.extension.removeprefix('KHR_materials_')}: {d.form} ({', '.join(d.engines)}; "
                            f"departs from the spec: {d.departure})",
                            _lobe_twin(d), _lobe_applies(d), model=True, lobe=d.extension)
                 for d in DEPARTURES if d.switch is not None and d.member is not None)


HYPOTHESES = HYPOTHESES + _lobe_hypotheses()


def offered(h: Hypothesis, scene: Scene | None) -> bool:
    """Whether ``diagnose`` tests (or lists as skipped) hypothesis ``h`` for ``scene``: image
    hypotheses always, scene-space ones with a scene, a ``lobe`` one only for a scene whose objects
    carry its lobe (:func:`compare.lobes.scene_lobes`): other scenes' tables stay as they were."""
    if h.kind == "image":
        return True
    if scene is None:
        return False
    if h.lobe is None:
        return True
    from ..lobes import scene_lobes
    return h.lobe in scene_lobes(scene)


def hypothesis(name: str, kind: str | None = None) -> Hypothesis:
    """The hypothesis ``name`` (of ``kind`` when given); raises :class:`DiagnoseError` otherwise."""
    for h in HYPOTHESES:
        if h.name == name and kind in (None, h.kind):
            return h
    known = ", ".join(h.name for h in HYPOTHESES if kind in (None, h.kind))
    raise DiagnoseError(f"diagnose: unknown {kind + ' ' if kind else ''}hypothesis {name!r} (known: {known})")


def apply_image_hypothesis(name: str, r: np.ndarray, t: np.ndarray, coverage: np.ndarray | None = None
                           ) -> tuple[np.ndarray, np.ndarray, dict]:
    """Undo image-space mismatch ``name``: returns ``(reference', test', fitted)``.

    ``r``, ``t``: ``(H, W, 3)`` linear RGB; ``coverage``: the reference's coverage AOV (needed by
    ``premultiplied_alpha``). Raises :class:`DiagnoseError` for an unknown name.
    """
    return hypothesis(name, "image").apply(r, t, coverage)


def hypothesis_scene(name: str, scene: Scene, directory: Path) -> Scene:
    """The scene whose reference is the image a renderer with scene-space mismatch ``name`` would make.

    ``directory`` receives any file the hypothesis needs (the mirrored environment).
    """
    return hypothesis(name, "scene").apply(scene, directory)[0]


# --- the measure ----------------------------------------------------------------------------------


def _relmse(r: np.ndarray, t: np.ndarray) -> float:
    r = r.astype(np.float64)
    return float(((t - r) ** 2 / (r * r + REL_EPS)).mean())


#: Image-space hypotheses that only move pixels or channels: the test's variance moves with them.
PERMUTATIONS = ("flip_vertical", "flip_horizontal", "swap_rb")


def _test_variance_after(h: "Hypothesis", r: np.ndarray, t: np.ndarray, t2: np.ndarray, tvar: np.ndarray | None,
                         fitted: dict) -> np.ndarray | None:
    """The variance of the test after hypothesis ``h`` undid its mismatch (``tvar``: a Monte Carlo
    engine's own, :data:`compare.metrics.TEST_VARIANCE_META`): unchanged where ``h`` leaves the
    test alone (scene-space rows, clamps of the reference), moved with the pixels by a permutation,
    times ``k^2`` by an exposure ``k``; None (not subtracted) through a non-linear transfer (sRGB)."""
    if tvar is None or t2 is t:
        return tvar
    if h.name in PERMUTATIONS:
        return h.apply(r, tvar, None)[1]
    if h.name == "exposure":
        return tvar * fitted["factor"] ** 2
    return None


def _error(r: np.ndarray, t: np.ndarray, var: np.ndarray | None, w: np.ndarray) -> float:
    """Noise-corrected relative MSE of ``t`` against the estimate ``r`` whose per-pixel variance is
    ``var``, weighted by ``w = 1 / (ref^2 + eps)`` of the *original* reference (fixed for every
    hypothesis). ``E[(t - r)^2] = (t - mu)^2 + var`` for a noise-free ``t``, so subtracting
    ``mean(w var)`` leaves the error against the converged image (clipped at 0): a re-render's own
    noise does not count against the hypothesis it tests. The weight must not depend on the noisy
    ``r`` itself: ``1 / (r^2 + eps)`` of a noisy estimate is largest where it happens to be low, which
    biases the relative error upwards (measured: 6x the variance term on 32-spp spheres_ci)."""
    e = float(((t - r.astype(np.float64)) ** 2 * w).mean())
    if var is not None:
        e -= float((np.clip(var, 0.0, None) * w).mean())
    return max(e, 0.0)


def _noise_error(ref: Image) -> float:
    """Relative MSE of a simulated pair ``(r, r + sqrt(2 var) z)``: what the reference's noise alone
    shows (0 without variance channels)."""
    var = ref.variance
    if var is None:
        return 0.0
    r = ref.rgb.astype(np.float64)
    z = np.random.default_rng(NOISE_SEED).standard_normal(r.shape)
    return _relmse(r, r + np.sqrt(2.0 * np.clip(var, 0.0, None)) * z)


def _within(err: float, noise: float) -> bool:
    return err <= NOISE_EXPLAINS_FACTOR * noise


# --- diagnose -------------------------------------------------------------------------------------


def diagnose(ref: Image, test: Image, scene: Scene | None = None, *, spp: int | None = None,
             seed: int | None = None, progress: bool = False, mode: str | None = None) -> Diagnosis:
    """Rank the known convention mismatches by how much undoing each reduces the error.

    Parameters
    ----------
    ref, test : Image
        The reference (ideally with ``variance.*`` and ``coverage``) and the image under test, same
        size, linear radiance.
    scene : Scene, optional
        The scene both show; enables the scene-space hypotheses (re-rendered references). Its camera
        size must match the images.
    spp, seed : int, optional
        Samples per pixel and seed of the re-rendered references (default: the reference's own
        ``spp`` capped at :data:`MAX_HYPOTHESIS_SPP` and ``seed``; else :data:`DEFAULT_HYPOTHESIS_SPP`, 0).
    progress : bool
        Progress on stderr.
    mode : str, optional
        Reference mode of the re-renders (``local`` or ``path``; default: the reference image's own
        ``mode``, else ``local``): the truth the engine is set against (``pbrcheck diagnose
        --reference-mode``).

    A display-referred pair (either image's ``display_referred`` flag: a ``png-srgb`` engine) is
    compared in display space as :func:`compare.metrics.compare_images` does (both clamped to
    [0, 1] and sRGB-encoded, the re-renders too; no noise floor), and the sRGB transfer hypotheses
    are skipped (the encoding is the engine's contract).

    Returns
    -------
    Diagnosis
        Rows sorted by the error left (skipped ones last) and the verdict line.

    Raises
    ------
    ComparisonError
        The images cannot be compared (size, channels, NaN).
    DiagnoseError
        The scene's size differs from the images'.
    """
    space = "linear"
    if is_display_referred(ref) or is_display_referred(test):
        ref, test, space = display_referred(ref), display_referred(test), "display-referred"
    validate_pair(ref, test)
    if scene is not None and (scene.camera.height, scene.camera.width) != ref.shape:
        raise DiagnoseError(f"diagnose: scene {scene.name!r} is {scene.camera.width}x{scene.camera.height}, "
                            f"the images are {ref.shape[1]}x{ref.shape[0]}")
    r, t = ref.rgb.astype(np.float64), test.rgb.astype(np.float64)
    var = ref.variance
    # A Monte Carlo engine's own noise (the renderer contract's variance) is subtracted like the
    # reference's: the two variances add (independent noises).
    tvar = test.variance if TEST_VARIANCE_META in test.meta else None
    tvar = None if tvar is None else np.clip(tvar.astype(np.float64), 0.0, None)

    def total(v, tv):
        return v if tv is None else (tv if v is None else np.clip(v, 0.0, None) + tv)

    w = 1.0 / (r * r + REL_EPS)  # the relative-error weight of every row: the reference's
    before = _error(r, t, total(var, tvar), w)
    per_pixel = ((t - r) ** 2 * w).sum(axis=-1)
    bulk = per_pixel <= np.quantile(per_pixel, 1.0 - BULK_OUTLIERS)
    v0 = total(var, tvar)
    before_bulk = _error(r[bulk], t[bulk], None if v0 is None else v0[bulk], w[bulk])
    noise = _noise_error(ref)
    cov = ref.channels.get("coverage")
    if scene is not None:
        spp = spp or min(int(ref.meta.get("spp", DEFAULT_HYPOTHESIS_SPP)), MAX_HYPOTHESIS_SPP)
        seed = int(ref.meta.get("seed", 0)) if seed is None else seed
        mode = mode or ref.meta.get("mode", "local")

    def undo(h: Hypothesis, directory: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, dict]:
        """(reference, test, the reference's variance, fitted) with ``h`` undone: an image transform,
        or the reference re-rendered from ``h``'s scene."""
        if h.kind == "image":
            r2, t2, fitted = h.apply(r, t, cov)
            return r2, t2, var, fitted
        if h.kind == "lobe":
            r2, keeps, fitted = h.apply(scene, r)
            return r2, t, var if keeps else None, fitted
        s2, fitted = h.apply(scene, directory)
        img = renderers.render_reference(s2, spp=spp, mode=mode, seed=seed, progress=False)  # the bar below counts
        if space != "linear":
            img = display_referred(img)  # compared as the pair is; its variance dropped with it
        return img.rgb.astype(np.float64), t, img.variance, fitted

    todo = [h for h in HYPOTHESES if offered(h, scene)]
    rows: list[HypothesisRow] = []
    with Progress("diagnose", total=len(todo), enabled=progress) as bar, \
            tempfile.TemporaryDirectory(prefix="pbrcheck-diagnose-") as tmp:
        for h in todo:
            skipped = h.applies_to(ref, scene)
            if skipped is not None:
                rows.append(HypothesisRow(h.name, h.kind, h.description, None, None, False, {}, skipped))
            else:
                r2, t2, var2, fitted = undo(h, Path(tmp))
                var2 = total(var2, _test_variance_after(h, r, t, t2, tvar, fitted))
                err = _error(r2, t2, var2, w)
                red = 1.0 - err / before if before > 0 else 0.0
                err_bulk = _error(r2[bulk], t2[bulk], None if var2 is None else var2[bulk], w[bulk])
                red_bulk = 1.0 - err_bulk / before_bulk if before_bulk > 0 else 0.0
                rows.append(HypothesisRow(h.name, h.kind, h.description, err, red, _within(err, noise), fitted,
                                          bulk_reduction=red_bulk))
            bar.update(1, h.name)

    tested = sorted((x for x in rows if x.skipped is None), key=lambda x: x.error_after)
    rows = tested + [x for x in rows if x.skipped is not None]
    likely = None
    if not _within(before, noise):
        for x in tested:
            if (x.error_after <= LIKELY_REMAINING * before and x.bulk_reduction > 0.0
                    and hypothesis(x.hypothesis).names_cause(x.fitted)):
                likely = x
                break
    if likely is None:
        line = "no convention mismatch found"
        if _within(before, noise):
            line += " (the difference is within the reference's noise)"
    else:
        fit = "".join(f", {k} {format_value(v)}" for k, v in likely.fitted.items())
        lh = hypothesis(likely.hypothesis)
        kind = ("a departure from the extension's specification (docs/renderers.md, lobes): " if lh.kind == "lobe"
                else "a model difference, not a convention: " if lh.model else "")
        line = (f"likely cause: {kind}{likely.hypothesis} ({likely.description}{fit}): undoing it removes "
                f"{100 * likely.reduction:.0f} % of the error"
                + (", what is left is within the reference's noise" if likely.within_noise else ""))
    return Diagnosis("relmse", before, noise, rows, likely.hypothesis if likely else None, line, space,
                     mode if scene is not None else None)


def table_markdown(d: Diagnosis) -> str:
    """The ranked table (hypothesis, error after, reduction, within noise) and the verdict line."""
    mode = f"; scene-space re-renders in reference mode {d.reference_mode}" if d.reference_mode else ""
    out = [f"error before: relmse {format_value(d.error_before)} ({ERROR_LABEL}; reference noise "
           f"{format_value(d.noise_error)})",
           f"colour space: {d.space}{mode}",
           ERROR_NOTE, "",
           "| hypothesis | kind | error after | reduction | within noise | fitted |",
           "|---|---|---|---|---|---|"]
    for x in d.rows:
        if x.skipped is not None:
            out.append(f"| {x.hypothesis} | {x.kind} | skipped: {x.skipped} | | | |")
            continue
        fit = ", ".join(f"{k} {format_value(v)}" for k, v in x.fitted.items())
        # A hypothesis that makes things worse by more than 2x reads better as a factor.
        red = f"{100 * x.reduction:+.1f} %" if x.reduction >= -1.0 else f"worse x{1.0 - x.reduction:.3g}"
        out.append(f"| {x.hypothesis} | {x.kind} | {format_value(x.error_after)} | {red} | "
                   f"{'yes' if x.within_noise else 'no'} | {fit} |")
    out += ["", d.line, ""]
    return "\n".join(out)


__all__ = ["HYPOTHESES", "Hypothesis", "hypothesis", "offered", "LOBE_TWIN_PRESET", "LIKELY_REMAINING", "Diagnosis", "HypothesisRow", "DiagnoseError",
           "diagnose", "apply_image_hypothesis", "hypothesis_scene", "table_markdown", "srgb_eotf"]
