"""The report's lobe sections: one per glTF PBR extension lobe that some scene of the report uses
(``KHR_materials_clearcoat``, ``_sheen``, ``_specular``, ``_anisotropy``, ``_iridescence``), none
otherwise (a report without lobe scenes is unchanged).

Per lobe, per scene and per renderer under test (a real-time preset with its lobe forms, or an
engine ``ext:NAME`` with the forms docs/renderers.md's lobes table reads in its source), the error
against the scene's reference over the objects that carry the lobe (:func:`compare.lobes.pooled_metrics`:
pixel-weighted relmse, FLIP, mean |t - r| and rmse; the worst object; and the relmse per value of
each of the lobe's parameters, :func:`compare.lobes.parameter_groups`), then the real-time renderer's
other lobe forms (:func:`compare.lobes.lobe_variants`: each member of each of the lobe's families
the renderer takes as an option, on the first real-time preset), measured the same way. The truth
is whatever the reference renders: the lobe itself once the reference models it
(:data:`pbrcheck.lobe_params.MODELLED_LOBE_EXTENSIONS`), the base material alone before (the note
says which), and an extension the reference does not model is removed from the engines' export too
(:mod:`pbrcheck.unmodelled`), so that until then every row measures the base material.

API: :func:`lobe_rows` (one scene's rows, for ``metrics.json``), :func:`lobe_variant_rows` (the
real-time forms' renders), :func:`lobe_sections` (the page's sections), :func:`forms_of`.
"""

from __future__ import annotations

from pbrcheck.fmt import TABLE_DIGITS, format_value
from pbrcheck.lobe_params import MODELLED_LOBE_EXTENSIONS

from .. import renderers
from ..lobe_findings import DEPARTURES, ENGINE_OF_RENDERER
from ..lobes import LOBE_NAMES, POOLED_METRICS, lobe_families, object_lobes, parameter_groups, pooled_metrics
from ..metrics import compare_images
from ..timings import image_timings
from .section import Section, Table


def _fmt(v) -> str:
    return format_value(v, TABLE_DIGITS)


def forms_of(renderer: str, extension: str, options: dict | None) -> str:
    """The lobe forms of renderer ``renderer`` for ``extension``: a real-time preset's values of the
    lobe's option families (from its image's ``options``), an engine's departures
    (:data:`compare.lobe_findings.DEPARTURES`, by :data:`ENGINE_OF_RENDERER`), else ``as the spec``
    (an engine with no departure found) or ``not an option yet``."""
    engine = ENGINE_OF_RENDERER.get(renderer)
    if engine is not None:
        deps = [d.name for d in DEPARTURES if d.extension == extension and engine in d.engines]
        return ", ".join(deps) if deps else "no departure found"
    fams = [f for f in lobe_families() if f.extension == extension and f.option is not None]
    vals = [f"{f.option}={(options or {}).get(f.option, f.default)}" for f in fams]
    return ", ".join(vals) if vals else "not an option yet"


def _pooled(scene, ext: str, ids, objects: list[dict]) -> dict:
    """:func:`compare.lobes.pooled_metrics` over the lobe's objects, and ``by_parameter``: the relmse
    pooled over each :func:`compare.lobes.parameter_groups` group."""
    return {**pooled_metrics(objects, ids),
            "by_parameter": {k: pooled_metrics(objects, g)["relmse"] for k, g in parameter_groups(scene, ext).items()}}


def lobe_rows(scene, dump: dict) -> dict[str, list[dict]]:
    """``{extension: [row]}`` of one scene: per renderer of ``dump`` (``{renderer: its comparison
    summary with "options"}``, the report's ``metrics.json`` entries) the pooled metrics over the
    objects that carry the lobe, with ``renderer`` and ``forms``. Empty for a scene with no lobe."""
    out: dict[str, list[dict]] = {}
    for ext, ids in object_lobes(scene).items():
        rows = []
        for renderer, summary in dump.items():
            rows.append({"renderer": renderer, "forms": forms_of(renderer, ext, summary.get("options")),
                         **_pooled(scene, ext, ids, summary.get("objects", []))})
        out[ext] = rows
    return out


def lobe_variant_rows(scene, ref, spec: renderers.RendererSpec, variants: list[dict], *, progress=None,
                      context: renderers.RenderContext = renderers.DIRECT) -> dict[str, list[dict]]:
    """The real-time forms ``variants`` (``[{option: member}]`` of :func:`compare.lobes.lobe_variants`)
    rendered on ``spec`` and compared with ``ref``: ``{extension: [row]}`` pooled over the lobe's
    objects, each row with ``renderer`` (the preset and the form), ``forms``, ``precompute_s`` and
    ``frame_s``."""
    lobes = object_lobes(scene)
    ext_of = {f.option: f.extension for f in lobe_families() if f.option is not None}
    out: dict[str, list[dict]] = {}
    for v in variants:
        img = renderers.render_under_test(scene, spec.with_options(**v), progress=False, context=context)
        cmp = compare_images(ref, img, scene=scene, noise=False, itp=False, flip_cache=context.flip_cache)
        pre, frame = image_timings(img)
        label = ",".join(f"{k}={val}" for k, val in v.items())
        for opt in v:
            ext = ext_of.get(opt)
            if ext in lobes:
                out.setdefault(ext, []).append({"renderer": f"{spec.text} + {label}", "forms": label,
                                                "precompute_s": pre, "frame_s": frame,
                                                **_pooled(scene, ext, lobes[ext], cmp.summary["objects"])})
        if progress is not None:
            progress.update(1, f"{scene.name}: {label}")
    return out


def _truth_note(ext: str) -> str:
    if ext in MODELLED_LOBE_EXTENSIONS:
        return ("The truth is the reference's lobe, as the extension's README defines it (docs/reference.md). ")
    return (f"pbrcheck does not model {ext} yet: the reference renders the base material alone and the engines' "
            "export has the extension removed (pbrcheck.unmodelled), so every row measures the base material; "
            "the rows become the lobe's once both renderers model it. ")


def lobe_sections(scenes: list[tuple[str, dict[str, list[dict]]]]) -> list[Section]:
    """One :class:`~compare.report.section.Section` per lobe some scene has, in
    :data:`compare.lobes.LOBE_NAMES`' order; ``scenes``: ``[(scene name, {extension: rows})]``
    (:func:`lobe_rows` merged with :func:`lobe_variant_rows`)."""
    out = []
    headers = ["scene", "renderer", "forms", "objects", "pixels", *POOLED_METRICS, "worst object (relmse)"]
    for ext, name in LOBE_NAMES.items():
        rows = []
        for scene, by in scenes:
            for r in by.get(ext, []):
                w = r.get("worst")
                rows.append([scene, r["renderer"], r["forms"], str(r["objects"]), str(r["pixels"]),
                             *[_fmt(r.get(k)) for k in POOLED_METRICS],
                             "-" if w is None else f"{w['name'] or w['id']} ({_fmt(w['relmse'])})"])
        if not rows:
            continue
        note = (f"Every renderer against the reference over the pixels of the objects that carry {ext} "
                "(pixel-weighted: relmse, FLIP and mean |t - r| are the means over those pixels, rmse from their "
                "MSE), then the real-time renderer's other forms of the lobe (each member of the lobe's option "
                "families, on the first real-time preset). Forms: a preset's lobe options; an engine's departures "
                "from the spec as read in its source (docs/renderers.md, the lobes table; diagnose names one when "
                "it explains the error). " + _truth_note(ext))
        tables = [Table("", headers, rows)]
        keys = list(dict.fromkeys(k for _, by in scenes for r in by.get(ext, []) for k in r.get("by_parameter", {})))
        if keys:   # the grid's rows and columns: where along each parameter the error lies
            tables.append(Table("relmse by parameter value (objects pooled per value)", ["scene", "renderer", *keys],
                                [[scene, r["renderer"], *[_fmt(r.get("by_parameter", {}).get(k)) for k in keys]]
                                 for scene, by in scenes for r in by.get(ext, [])]))
        out.append(Section(f"lobe-{name}", f"Lobe: {name} ({ext})", note, tables))
    return out


__all__ = ["forms_of", "lobe_rows", "lobe_sections", "lobe_variant_rows"]
