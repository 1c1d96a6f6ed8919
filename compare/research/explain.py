"""``pbrcheck explain``: attribute a preset's error to its approximations, by measurement.

The preset is rendered and compared with the reference (:func:`compare.metrics.compare_images`, over
valid pixels). Then one approximation at a time is replaced by its exact (or much more accurate)
counterpart through real-time options (:data:`SOURCES`), the scene re-rendered and re-measured.
A source's *contribution* is ``error(preset) - error(preset with that source made exact)``: positive
when the approximation costs accuracy, near zero when it does not matter here, negative when the
approximation happens to cancel another one. Then every fix is applied at once (``all_exact``) and
every fix but ``v=n=r`` (``all_but_vnr``: the best this split sum can do). Nothing is assumed:
every row is a render. What ``all_exact`` leaves is the reference's own noise (``noise_relmse``, the
relmse its variance alone explains) plus what no option here changes (the diffuse term's split,
texture filtering).

Sources and their exact counterparts:

* ``lut``: DFG term from a 256^2 RG32F LUT at :data:`EXACT_LUT_SAMPLES` samples per texel (replaces a
  small or half-float LUT, or Karis's analytic fit).
* ``prefilter_samples``: :data:`EXACT_PREFILTER_SAMPLES` samples per prefiltered texel, filtered
  importance sampling.
* ``v=n=r``: the split sum's prefiltered lobe assumes v = n = r and splits the integral of a
  product into a product of integrals; replaced by runtime importance sampling of the same
  integrand (the scene's D, G, F; the runtime strategy exact for the scene's NDF, its registry
  entry's ``extra["runtime_sampling"]``: GGX visible normals for a GGX NDF, Beckmann half vectors
  for a Beckmann one; 4096 samples per pixel, mip-filtered lookups) in the material composition. For a
  preset with an article's composition the row also switches to the material composition (only it
  and article 001's have a runtime-sampled specular), so it then includes ``composition``.
* ``lod_mapping``: the built-in mapping that measures best on this scene (or ``--fitted FILE``'s
  fitted mapping when given and better).
* ``irradiance``: cube convolution summing every texel of a 64^2 source into a 64^2 cube.
* ``cube``: a 512^2 float32 environment cube (texel resolution and half-float precision).
* ``geometry``: the scene's own G term, in the frame (point lights, runtime sampling) and in the LUT.
* ``ndf_fresnel``: the scene's own D and F terms.
* ``composition``: the README material model's composition (``shading=material``, correct
  reflection vector, no roughness clamp) instead of an article's.

glTF asset scenes (the raster pipeline) add the approximations engines make on assets
(:data:`ASSET_SOURCES`), each made exact as the reference does it:

* ``texture_filtering``: base colour, metallic-roughness, emissive and occlusion textures read
  bilinearly at level 0 (``texture_sampling=lod0``, as the reference; the supersampling then
  filters) instead of trilinearly through the mip chain.
* ``normal_filtering``: the normal map likewise (``normal_sampling=lod0``, and ``specular_aa=none``):
  unfiltered normals instead of mip-averaged ones (whose shortening loses the roughness they imply)
  and no roughness widened to stand for them.
* ``occlusion``: the occlusion texture off (``occlusion_texture=false``, ``specular_occlusion=none``):
  exact against the ``local`` reference, which has no visibility. Its own truth is the ``path``
  reference: :attr:`ExplainResult.path_truth` measures the preset and the row's options against a
  ``path`` reference at the same spp (``contribution < 0``: the texture brings the image nearer
  what visibility does; the point lights' shadows, which the raster pipeline lacks, are part of
  both errors).
* the split sum is the ``v=n=r`` row (runtime importance sampling of the full integral).

A scene whose objects carry glTF PBR extension lobes (clearcoat, sheen, ...) adds one row per other
real-time form of each lobe (:func:`compare.lobes.lobe_variants`: every member of each lobe family of
:data:`realtime.registry.LOBE_REGISTRIES` the preset takes as an option, read generically, so a
family joins once the renderer takes it), named ``lobe:OPTION=MEMBER`` (:data:`LOBE_ROW_PREFIX`).
Such a row is not an exact counterpart: its contribution is what that engine's form would change
(positive: nearer the truth), and it is left out of ``all_but_vnr`` and ``all_exact`` (two forms of
one lobe do not combine).

What every fix leaves on an asset includes the horizon: the reference cuts light arriving from
below the geometric surface (a normal-mapped normal tilts its hemisphere under it), the real-time
shading integrates it (``horizon_occlusion=marmoset`` approximates the cut; no option makes it exact).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from pbrcheck.atomic import write_text_atomic
from pbrcheck.errors import PbrcheckError
from pbrcheck.fmt import TABLE_DIGITS, format_value, terminal_safe
from pbrcheck.gltf_scene import scene_has_assets
from pbrcheck.jsonio import write_json_atomic
from pbrcheck.lodmap import BUILTIN_LOD_MAPPINGS
from pbrcheck.registry import NDFS
from pbrcheck.scene import Scene

from .. import renderers
from ..lobes import lobe_variants
from ..metrics import REL_EPS, compare_images
from ..verdict_spp import RESEARCH_PROBE, DEFAULT_SPP_CAP, VerdictSpp, reference_for_verdict
from .results import ExplainCombined, ExplainPathTruth, ExplainResult, ExplainRow

#: Reference samples per pixel (command default).
DEFAULT_SPP = 64
#: The metric the contributions are computed on (all metrics are kept in the JSON).
PRIMARY = "relmse"
KEEP = ("relmse", "rmse", "rel_p95", "flip_mean")


#: Samples of the exact counterparts of the prefiltered chain and the DFG LUT. An exact counterpart
#: only has to be exact *here*: its own error 10x below the reference's noise floor (the verdict
#: rule's factor, compare.verdict_spp). Measured on the report's explain (spheres, 64 px, default
#: preset, 4096-spp reference, noise floor relmse 8.1e-5): 8192 / 16384 samples (this module's
#: earlier values) against 2048 / 4096 move every row by at most 8e-6 relmse (the prefilter row
#: -1.1e-5 -> -1.9e-5, the LUT row -2.9e-7 -> +7.6e-7), 10x below that floor, at a quarter of the
#: bakes' time (the two 8192-sample 256^2 chains alone were 14 s of llvmpipe in a report).
EXACT_PREFILTER_SAMPLES = 2048
EXACT_LUT_SAMPLES = 4096

#: Runtime samples per pixel of the exact specular (``v=n=r``): with mip-filtered lookups the
#: estimator's noise at 4096 samples is far below the 64..256-spp reference's.
RUNTIME_SAMPLES = 4096

#: The ``v=n=r`` row's ``runtime_sampling`` for an NDF no runtime strategy is exact for (its NDF
#: entry has no ``extra["runtime_sampling"]``, :data:`pbrcheck.registry.NDFS`): the row is not rendered.
NO_RUNTIME_SAMPLING = "none"

#: The asset sources (module docstring): option overrides that make each exact against ``local``.
ASSET_SOURCES = {
    "texture_filtering": {"texture_sampling": "lod0"},
    "normal_filtering": {"normal_sampling": "lod0", "specular_aa": "none"},
    "occlusion": {"occlusion_texture": False, "specular_occlusion": "none"},
}
#: The asset sources whose truth is the ``path`` reference (:attr:`ExplainResult.path_truth`).
PATH_TRUTH_SOURCES = ("occlusion",)
#: The prefix of a lobe-form row's name (``lobe:coat_ibl=threejs``): another form, not an exact
#: counterpart, so never part of the combined rows.
LOBE_ROW_PREFIX = "lobe:"


def lobe_sources(spec: renderers.RendererSpec, scene: Scene) -> dict[str, dict]:
    """``{"lobe:OPTION=MEMBER": {option: member}}``: the preset's other forms of the lobes the
    scene's objects carry (:func:`compare.lobes.lobe_variants`; none for an external renderer)."""
    return {LOBE_ROW_PREFIX + ",".join(f"{k}={v}" for k, v in over.items()): over
            for over in lobe_variants(spec, scene)}


def sources(o: renderers.RealtimeOptions, *, cube_max: int = 512, samples_scale: float = 1.0, scene_ndf: str = "ggx",
            asset: bool = False) -> dict[str, dict]:
    """Option overrides that make each approximation exact (``samples_scale`` < 1 for tests;
    ``asset``: also :data:`ASSET_SOURCES`)."""
    cube = min(cube_max, 4096)
    levels = max(1, min(cube.bit_length(), o.prefilter_levels + int(math.log2(cube / o.cube_size))))
    irr_src = min(64, o.cube_size)
    s = lambda n: max(16, int(n * samples_scale))  # noqa: E731
    composition = {"shading": "material", "reflect_bug": False, "min_roughness": 0.0}
    ndf = o.ndf if o.ndf != "scene" else scene_ndf
    # Not scaled by samples_scale: fewer samples mean coarser mip-filtered lookups (GPU Gems 3 ch. 20
    # picks the level from the pdf and the sample count), i.e. a blur bias, not just noise.
    vnr = {"ibl": "runtime", "runtime_samples": RUNTIME_SAMPLES, "runtime_lod": True, "runtime_rotate": True,
           "runtime_sampling": NDFS[ndf].extra.get("runtime_sampling", NO_RUNTIME_SAMPLING)}
    if o.shading != "material":
        vnr.update(composition)
    return {
        "lut": {"dfg": "lut", "lut_size": 256 if samples_scale >= 1 else 64, "lut_format": "f32",
                "lut_samples": s(EXACT_LUT_SAMPLES), "lut_sampling": "vndf"},
        "prefilter_samples": {"prefilter_samples": s(EXACT_PREFILTER_SAMPLES), "prefilter_filtered": True,
                              "prefilter_nl_weight": False},
        "v=n=r": vnr,
        "irradiance": {"irradiance": "convolution", "irradiance_method": "texel_sum", "irradiance_size": 64,
                       "irradiance_source_size": irr_src},
        "cube": {"cube_size": cube, "cube_format": "f32",
                 "prefilter_levels": levels,
                 "irradiance_source_size": min(o.irradiance_source_size, cube)},
        "geometry": {"geometry": "scene", "lut_geometry": "scene"},
        "ndf_fresnel": {"ndf": "scene", "fresnel": "scene"},
        "composition": composition,
        **({k: dict(v) for k, v in ASSET_SOURCES.items()} if asset else {}),
    }


def run_explain(scene: Scene, *, preset: str = "default", options: dict | None = None, spp: int = DEFAULT_SPP,
                size: int | None = None, fitted: str | None = None, cube_max: int = 512,
                samples_scale: float = 1.0, spp_cap: int | None = DEFAULT_SPP_CAP, path_truth: bool = True,
                only: tuple[str, ...] | None = None, progress: bool = False, context: renderers.RenderContext = renderers.DIRECT) -> ExplainResult:
    """Measure each approximation's contribution to ``preset``'s error on ``scene``.

    Parameters
    ----------
    scene : Scene
        The scene (its point lights stay).
    preset : str, optional
        The renderer under test.
    options : dict, optional
        Option overrides of the baseline.
    spp : int, optional
        Least reference samples per pixel: more (powers of two, at most ``spp_cap``) until the
        reference's noise floor is 10x below the baseline's error (:mod:`compare.verdict_spp`; the
        outcome is the result's ``reference_spp``, ``noise_limited`` at the cap).
    size : int, optional
        Image height in pixels (width keeps the aspect); None: the scene's own.
    fitted : str, optional
        A ``pbrcheck fit-lod`` JSON whose mapping is also tried as the LOD mapping.
    cube_max : int, optional
        Face size of the exact environment cube.
    samples_scale : float, optional
        Scales the exact counterparts' sample counts (< 1 for tests).
    spp_cap : int, optional
        Most reference samples per pixel (None: as many as render in the verdict rule's time budget).
    path_truth : bool, optional
        glTF asset scenes: also measure :data:`PATH_TRUTH_SOURCES` against a ``path`` reference
        (:attr:`ExplainResult.path_truth`).
    only : tuple of str, optional
        Measure these sources only (names of :func:`sources`, ``lod_mapping``); None: every one.
    progress : bool, optional
        Show reference render progress.

    Returns
    -------
    ExplainResult
        The baseline, one :class:`ExplainRow` per source, ``all_but_vnr`` and ``all_exact``.
    """
    base = dict(options or {})
    spec = renderers.RendererSpec.parse(preset, base)  # once: every render below is a variant of it
    o = spec.options
    if size is not None:
        scene = scene.with_camera(width=max(8, int(round(size * scene.camera.width / scene.camera.height))),
                                  height=int(size))
    # The sources first: an unknown name is an error before any render.
    asset = scene_has_assets(scene)
    srcs = {} if spec.external else {**sources(o, cube_max=cube_max, samples_scale=samples_scale,
                                                scene_ndf=scene.brdf.ndf, asset=asset), **lobe_sources(spec, scene)}
    if only is not None and srcs:
        unknown = sorted(set(only) - set(srcs) - {"lod_mapping"})
        if unknown:
            raise PbrcheckError(f"explain: unknown source(s) {', '.join(unknown)} for {scene.source}; sources are: "
                                f"{', '.join([*srcs, 'lod_mapping'])}")
        srcs = {k: v for k, v in srcs.items() if k in only}
    # The baseline first: the reference's spp is chosen so its noise floor sits 10x below its error.
    base_img = renderers.render_under_test(scene, spec, progress=False, context=context)
    ref, verdict = reference_for_verdict(scene, [base_img], spp=spp, cap=spp_cap, mode="local", metric=PRIMARY,
                                         probe=RESEARCH_PROBE, tails=False, progress=progress)
    spp = verdict.spp

    valid = None

    def measure(over: dict, img=None) -> dict:
        nonlocal valid
        img = img if img is not None else renderers.render_under_test(scene, spec.with_options(**over), progress=False,
                                                                      context=context)
        # KEEP has no Delta E ITP: its map is not computed.
        c = compare_images(ref, img, scene=scene, noise=False, itp=False, flip_cache=context.flip_cache)
        if valid is None:
            valid = c.valid  # the baseline's valid pixels, for the noise figure
        return {k: c.metrics[k] for k in KEEP}

    baseline = measure({}, base_img)
    noise_relmse = None
    if ref.variance is not None:
        r64 = ref.rgb.astype(np.float64)
        noise_relmse = float((np.clip(ref.variance, 0, None) / (r64 * r64 + REL_EPS))[valid].mean())
    rows = []
    if spec.external:
        # An external renderer (ext:NAME) has no options to swap for exact counterparts: its
        # error against the reference is the whole result (the baseline).
        return ExplainResult(scene.name, preset, base, spp, [scene.camera.width, scene.camera.height], PRIMARY,
                             baseline, noise_relmse, rows, reference_spp=verdict.to_dict())
    if o.ibl == "runtime":
        # Already runtime sampling: its exact counterpart is the same estimator at many samples in
        # the material composition (composition is then part of this row).
        srcs.pop("lut", None)
    for name, over in srcs.items():
        if over.get("runtime_sampling") == NO_RUNTIME_SAMPLING:
            have = " and ".join(e.name for e in NDFS if "runtime_sampling" in e.extra)
            rows.append(ExplainRow(name, over, None, None,
                                   f"no runtime sampler for the {scene.brdf.ndf} NDF ({have} have one)"))
            continue
        try:
            m = measure(over)
        except PbrcheckError as e:
            rows.append(ExplainRow(name, over, None, None, f"{type(e).__name__}: {e}"))
            continue
        rows.append(ExplainRow(name, over, m, baseline[PRIMARY] - m[PRIMARY]))
    # LOD mapping: the best measured built-in (or the fitted file).
    if o.ibl == "splitsum" and (only is None or "lod_mapping" in only):
        cands = {n: {"lod_mapping": n} for n in BUILTIN_LOD_MAPPINGS}
        if fitted:
            cands["fitted"] = {"lod_mapping": f"fitted:{fitted}"}
        best = None
        for n, over in cands.items():
            m = measure(over)
            if best is None or m[PRIMARY] < best[1][PRIMARY]:
                best = (over, m)
        rows.append(ExplainRow("lod_mapping", best[0], best[1], baseline[PRIMARY] - best[1][PRIMARY]))
    # Every fix at once, and every fix but v=n=r (the best split sum).
    fitted_lod = any(r.source == "lod_mapping" and str(r.options["lod_mapping"]).startswith("fitted:")
                     for r in rows)
    combined = {}
    for label, skip in (("all_but_vnr", ("v=n=r",)), ("all_exact", ())):
        allo = {}
        for r in rows:
            if (r.source in skip or r.metrics is None or (fitted_lod and r.source == "cube")
                    or r.source.startswith(LOBE_ROW_PREFIX)):
                continue  # a fitted mapping holds for its own cube size and mip count only; a lobe form is no fix
            allo.update(r.options)
        if o.ibl == "runtime" and label == "all_but_vnr":
            continue  # a runtime-sampling preset has no split sum to keep
        m = measure(allo)
        combined[label] = ExplainCombined(allo, m, baseline[PRIMARY] - m[PRIMARY])
    truths = None
    if asset and path_truth and any(n in srcs for n in PATH_TRUTH_SOURCES):
        truths = _path_truth(scene, spec, base_img, srcs, spp, context, progress)
    return ExplainResult(scene.name, preset, base, spp, [scene.camera.width, scene.camera.height], PRIMARY,
                         baseline, noise_relmse, rows, **combined, reference_spp=verdict.to_dict(),
                         path_truth=truths)


def _path_truth(scene: Scene, spec: renderers.RendererSpec, base_img, srcs: dict, spp: int,
                context: renderers.RenderContext, progress: bool) -> list[ExplainPathTruth]:
    """:data:`PATH_TRUTH_SOURCES` against a ``path`` reference of ``spp`` samples per pixel."""
    ref = renderers.render_reference(scene, spp=spp, mode="path", use_cache=True, progress=progress)

    def measure(img) -> dict:
        c = compare_images(ref, img, scene=scene, noise=False, flip_cache=context.flip_cache)
        return {k: c.metrics[k] for k in KEEP}

    before = measure(base_img)
    out = []
    for name in (n for n in PATH_TRUTH_SOURCES if n in srcs):
        over = srcs[name]
        m = measure(renderers.render_under_test(scene, spec.with_options(**over), progress=False, context=context))
        out.append(ExplainPathTruth(name, over, spp, before, m, before[PRIMARY] - m[PRIMARY]))
    return out


#: Labels of the combined rows in the tables.
COMBINED_LABELS = (("all_but_vnr", "all but v=n=r (the best split sum)"), ("all_exact", "all exact"))


def table_markdown(res: ExplainResult) -> str:
    """The decomposition as a Markdown table, with the reference's noise and what is left."""
    def f(v):
        return format_value(v, TABLE_DIGITS)

    b = res.baseline[PRIMARY]
    # the scene's name is a user's (printed on a terminal and written to the .md): no control character
    lines = [f"scene {terminal_safe(res.scene)}, preset {res.preset}: {PRIMARY} {f(b)} against the {res.spp}-spp reference",
             *([f"Reference spp rule: {VerdictSpp(**res.reference_spp).provenance()}"] if res.reference_spp else []),
             "", f"| source made exact | {PRIMARY} after | contribution | share of {PRIMARY} | flip_mean after |",
             "| --- | --- | --- | --- | --- |"]
    extra = [ExplainRow(lab, c.options, c.metrics, c.contribution) for k, lab in COMBINED_LABELS
             if (c := getattr(res, k)) is not None]
    for r in res.sources + extra:
        m = r.metrics or {}
        share = None if r.contribution is None or b <= 0 else 100 * r.contribution / b
        lines.append(f"| {r.source} | {f(m.get(PRIMARY))} | {f(r.contribution)} | "
                     f"{'n/a' if share is None else f'{share:.1f} %'} | {f(m.get('flip_mean'))} |"
                     + (f" {r.error}" if r.error else ""))
    if any(r.source.startswith(LOBE_ROW_PREFIX) for r in res.sources):
        lines += ["", f"{LOBE_ROW_PREFIX}OPTION=MEMBER rows: another real-time form of a lobe the scene carries, not an "
                      "exact counterpart (contribution > 0: that form is nearer the truth); left out of the combined rows."]
    if res.noise_relmse is not None:
        lines += ["", f"The reference's own noise explains relmse {f(res.noise_relmse)} "
                      f"(mean variance / (ref^2 + {REL_EPS}) over valid pixels)."]
        if res.all_exact is not None:
            left = res.all_exact.metrics[PRIMARY] - res.noise_relmse
            rest = ("the diffuse term's split Kd(n.v) E(n), the runtime estimator's own mip filtering, "
                    + ("the horizon (light from below the geometric surface)" if res.path_truth is not None
                       else "texel filtering"))
            lines.append(f"Left after every listed source is exact, above that noise: {f(left)} (sources no "
                         f"option here replaces: {rest}).")
    for t in res.path_truth or ():
        lines += ["", f"Against the {t.spp}-spp path reference (its truth): {t.source} as the preset {PRIMARY} "
                      f"{f(t.baseline[PRIMARY])}, off ({', '.join(f'{k}={v}' for k, v in t.options.items())}) "
                      f"{f(t.metrics[PRIMARY])}: contribution {f(t.contribution)} (negative: the approximation "
                      f"brings the image nearer the path truth)."]
    return "\n".join(lines) + "\n"


def write_explain(res: ExplainResult, out: Path) -> Path:
    """Write ``out`` (JSON) and the table next to it (``.md``); returns ``out``."""
    out = Path(out)
    write_json_atomic(out, res)
    write_text_atomic(out.with_suffix(".md"), table_markdown(res))
    return out
