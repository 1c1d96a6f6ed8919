"""The report's opening sections: the summary (one row per renderer and scene) and the white furnace
per renderer.

API
---
- :func:`summary_section` -- relmse, FLIP, Delta E ITP, the within-noise flags and the time of every
  renderer under test (real-time presets and external clients ``ext:NAME``) on every scene, with
  what the time was measured on.
- :func:`furnace_section` -- the built-in ``furnace`` scene at :data:`FURNACE_SIZE` through the
  reference and every renderer: the mean radiance of each sphere (white metal, F0 = 1, roughness 0
  to 1, in a unit white environment). An energy-conserving single-scattering model (the reference)
  loses energy as roughness grows; a renderer that stays at 1.0 adds multiple-scattering energy
  compensation (three.js does, as do Filament and many engines since Kulla & Conty 2017): a model
  difference, measured here, not a shading bug.
- :func:`timed_on` -- the words for what a renderer's time was measured on.

References: Kulla and Conty, "Revisiting Physically Based Shading at Imageworks", SIGGRAPH 2017
course; Fdez-Agueera, "A Multiple-Scattering Microfacet Model for Real-Time Image-based Lighting",
JCGT 8(1), 2019 (what three.js implements).
"""

from __future__ import annotations

import numpy as np

from pbrcheck.fmt import TABLE_DIGITS, format_value
from pbrcheck.scene import load_scene

from .. import renderers
from ..metrics import FULL_COVERAGE
from .section import Section, Table

#: The summary's metrics (the gate's three).
SUMMARY_METRICS = ("relmse", "flip_mean", "delta_e_itp_mean")
#: The furnace is rendered at the CI size (compare/budgets/furnace_ci.toml): cheap, and 5 spheres of
#: ~40 px across are plenty for a mean.
FURNACE_SIZE = (192, 48)
#: A sphere "keeps the energy" when its mean radiance is within this of 1.0 (the white environment).
FURNACE_ENERGY_TOLERANCE = 0.03
#: A renderer exceeds the single-scattering reference "by a model difference" when it is this much
#: brighter on the roughest sphere while keeping the energy.
FURNACE_MODEL_GAP = 0.1


def _fmt(v) -> str:
    return format_value(v, TABLE_DIGITS)


def timed_on(meta: dict) -> str:
    """What a renderer image's timings were measured on: an external client's ``timed_on``, a
    real-time preset's GL renderer, else "unstated"."""
    if meta.get("timed_on"):
        return meta["timed_on"]
    if meta.get("gl_renderer"):
        return f"GL: {meta['gl_renderer']}"
    return "unstated"


def summary_section(scene_sections) -> Section:
    """One row per renderer and scene (``scene_sections``: the report's
    :class:`~compare.report.results.SceneSection` s, whose results carry ``timed_on``)."""
    rows = []
    for s in scene_sections:
        for r in s.presets:
            flags = [m for m in SUMMARY_METRICS if r.within.get(m)]
            total = None if r.frame is None else r.frame + (r.precompute or 0.0)
            label = r.preset if r.space == "linear" else f"{r.preset} ({r.space}: clamp + sRGB, 8-bit)"
            rows.append([s.name, label, *[_fmt(r.metrics.get(m)) for m in SUMMARY_METRICS],
                         ", ".join(flags) if flags else "none", _fmt(total), r.timed_on or "unstated"])
    note = ("Every renderer under test against the reference, on every scene: real-time presets and external "
            "renderers (ext:NAME, docs/renderers.md). Metrics over valid pixels, linear radiance "
            "(docs/compare.md); 'within noise' lists the metrics the reference's own Monte Carlo noise could "
            "explain. Time: seconds, precompute + frame for the real-time presets, the whole run for an "
            "external renderer (export excluded), on the machine stated.")
    return Section("summary", "Summary", note,
                   [Table("", ["scene", "renderer", *SUMMARY_METRICS, "within noise", "time (s)", "timed on"], rows)])


def _sphere_means(img, ids: np.ndarray, covered: np.ndarray, n: int) -> list[float | None]:
    out = []
    for k in range(n):
        m = covered & (ids == k)
        out.append(float(img.rgb[m].mean()) if m.any() else None)
    return out


def furnace_scene():
    """The furnace section's scene: the built-in furnace at :data:`FURNACE_SIZE`."""
    return load_scene("furnace").with_camera(width=FURNACE_SIZE[0], height=FURNACE_SIZE[1])


def furnace_section(presets: list[renderers.RendererSpec], spp: int, progress=None,
                    context: renderers.RenderContext = renderers.DIRECT) -> Section:
    """The white furnace through the reference and every renderer of ``presets`` (rendered in
    ``context``; see the module docstring); one row per renderer: the mean radiance of each sphere,
    roughness 0 to 1."""
    scene = furnace_scene()
    ref = renderers.render_reference(scene, spp=spp, use_cache=True, progress=False)
    ids = np.rint(ref.channels["object"]).astype(np.int64)
    covered = ref.channels["coverage"] >= FULL_COVERAGE if "coverage" in ref.channels else ids >= 0
    n = len(scene.objects)
    rough = [o.material.roughness for o in scene.objects]
    ref_means = _sphere_means(ref, ids, covered, n)
    rows = [["reference (single scattering)", *[_fmt(v) for v in ref_means]]]
    notes = []
    for p in presets:
        img = renderers.render_under_test(scene, p, progress=False, context=context)
        means = _sphere_means(img, ids, covered, n)
        rows.append([p.text, *[_fmt(v) for v in means]])
        if progress is not None:
            progress.update(1, f"furnace: {p.text}")
        last, ref_last = means[-1], ref_means[-1]
        if last is None or ref_last is None:
            continue
        keeps = all(v is not None and abs(v - 1.0) <= FURNACE_ENERGY_TOLERANCE for v in means)
        if keeps and last - ref_last >= FURNACE_MODEL_GAP:
            notes.append(f"{p} keeps the energy at every roughness ({_fmt(last)} at roughness {_fmt(rough[-1])}, "
                         f"reference {_fmt(ref_last)}): it adds multiple-scattering energy compensation, which the "
                         f"single-scattering reference does not model. This is a model difference, measured here, "
                         f"not a shading bug; it accounts for {p}'s error on rough metals.")
    note = ("White metal spheres (F0 = 1) in a unit white environment (the built-in furnace scene at "
            f"{FURNACE_SIZE[0]} x {FURNACE_SIZE[1]}): the mean radiance of each sphere's fully covered pixels. "
            "1.0 means no energy lost. A single-scattering microfacet model loses the energy of light that "
            "bounces more than once between microfacets, more at higher roughness; engines that compensate "
            "(Kulla and Conty 2017; Fdez-Agueera 2019) stay at 1.0. " + " ".join(notes))
    return Section("furnace-per-renderer", "White furnace per renderer", note,
                   [Table("", ["renderer", *[f"roughness {_fmt(r)}" for r in rough]], rows)])
