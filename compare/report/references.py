"""Both references side by side for every external renderer: single scattering and the random walk.

The reference's default microfacet model scatters once (Smith); engines such as three.js,
Filament, EEVEE, Godot and Bevy add a multiple-scattering energy compensation. Against the
single-scattering reference such an engine shows an "error" on rough metals that is in fact the
reference's missing physics. This section measures every external renderer (``ext:NAME``) on every
scene of the report against both references:

- the single-scattering reference (``[brdf] multiscatter = "none"``): the image the scene's own
  section compares against (its trusted-verdict spp, from the render cache);
- the random-walk reference (``[brdf] multiscatter = "random_walk"``, Heitz et al. 2016;
  docs/reference.md), rendered through :mod:`compare.renderers` with the cache, at the same spp
  capped at :data:`RANDOM_WALK_MAX_SPP` (the walk costs ~4.6x a single-scattering render; its own
  variance channels decide the within-noise flags, so a lower spp only widens them).

The share of an engine's error that is the reference's physics is ``1 - relmse_rw / relmse_ss``
(``relmse``: compare/metrics.py): near 1 when the engine matches the true multiple-scattering BSDF
and differs from the single-scattering one only there; negative when the walk is further from it.

A scene whose BRDF has no random walk (``brdf.ndf`` / ``brdf.geometry`` outside
:data:`pbrcheck.registry.MULTISCATTER_GEOMETRY`) gets a row saying so; a display-referred engine
(``png-srgb``) is compared in display space as everywhere in the report.

API
---
- :func:`random_walk_scene` -- the scene with the random walk, or the reason it has none.
- :func:`single_scattering_scene` -- the scene with ``multiscatter = "none"``.
- :func:`measure_references` -- one :class:`ReferencePair` per external renderer of one scene.
- :func:`references_sections` -- the report section (``[]`` without an external renderer) and
  ``OUT/<scene>/references.json``.

References: Heitz, Hanika, d'Eon, Dachsbacher, "Multiple-Scattering Microfacet BSDFs with the Smith
Model", SIGGRAPH 2016; Kulla and Conty, "Revisiting Physically Based Shading at Imageworks",
SIGGRAPH 2017 course; Fdez-Agueera, JCGT 8(1), 2019 (three.js's compensation).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

from pbrcheck.fmt import TABLE_DIGITS, format_value
from pbrcheck.jsonio import write_json_atomic
from pbrcheck.registry import MULTISCATTER_GEOMETRY
from pbrcheck.gltf_objects import AssetOptions
from pbrcheck.scene import Scene, load_scene

from .. import renderers
from ..metrics import compare_images
from .section import Section, Table

#: Most samples per pixel of the random-walk reference in the report (a random-walk render costs
#: ~4.6x a single-scattering one: docs/reference.md, "Cost").
RANDOM_WALK_MAX_SPP = 256
#: The metrics shown for each reference (the gate's three).
REFERENCE_METRICS = ("relmse", "flip_mean", "delta_e_itp_mean")


def _fmt(v) -> str:
    return format_value(v, TABLE_DIGITS)


def single_scattering_scene(scene: Scene) -> Scene:
    """``scene`` with ``[brdf] multiscatter = "none"`` (itself when it already is)."""
    if scene.brdf.multiscatter == "none":
        return scene
    return replace(scene, brdf=replace(scene.brdf, multiscatter="none"))


def random_walk_scene(scene: Scene) -> tuple[Scene | None, str]:
    """(``scene`` with ``multiscatter = "random_walk"``, "") or (None, why it has no random walk)."""
    if scene.assets:
        # The textured material of glTF assets is single-scattering (pbrcheck.scene refuses
        # multiscatter beside an asset): a "walk" render would be the single one again.
        return None, "no random walk for glTF assets (their textured material is single-scattering)"
    need = MULTISCATTER_GEOMETRY.get(scene.brdf.ndf)
    if need is None:
        return None, f"no random walk for ndf = {scene.brdf.ndf} (only {', '.join(MULTISCATTER_GEOMETRY)})"
    if scene.brdf.geometry != need:
        return None, f"the random walk for ndf = {scene.brdf.ndf} needs geometry = {need} (the scene has " \
                     f"{scene.brdf.geometry})"
    if scene.brdf.multiscatter == "random_walk":
        return scene, ""
    return replace(scene, brdf=replace(scene.brdf, multiscatter="random_walk")), ""


@dataclass
class ReferencePair:
    """One external renderer on one scene against both references (``vs_random_walk`` None with
    ``note`` when the scene has no random walk)."""

    scene: str
    renderer: str
    vs_single: dict
    within_single: dict
    vs_random_walk: dict | None = None
    within_random_walk: dict = field(default_factory=dict)
    spp_single: int = 0
    spp_random_walk: int = 0
    note: str = ""

    @property
    def share(self) -> float | None:
        """``1 - relmse_rw / relmse_ss``: the share of the error that is the reference's physics."""
        if not self.vs_random_walk:
            return None
        a, b = self.vs_single.get("relmse"), self.vs_random_walk.get("relmse")
        if a is None or b is None or a <= 0:
            return None
        return 1.0 - b / a

    def to_dict(self) -> dict:
        return {"scene": self.scene, "renderer": self.renderer, "spp_single": self.spp_single,
                "spp_random_walk": self.spp_random_walk, "vs_single": self.vs_single,
                "within_noise_single": self.within_single, "vs_random_walk": self.vs_random_walk,
                "within_noise_random_walk": self.within_random_walk, "share_of_error_from_reference": self.share,
                "note": self.note}


def _within(cmp) -> dict:
    noise = cmp.summary["noise"]
    return {m: bool(noise and noise["within_noise"].get(m)) for m in REFERENCE_METRICS}


def measure_references(scene: Scene, externals: list[renderers.RendererSpec], spp: int, *, progress=None,
                       context: renderers.RenderContext = renderers.DIRECT) -> list[ReferencePair]:
    """Every renderer of ``externals`` on ``scene`` against the single-scattering reference at
    ``spp`` and the random-walk one at ``min(spp, RANDOM_WALK_MAX_SPP)`` (both through
    :mod:`compare.renderers` with the cache; the external images from the clients' cache)."""
    ss = renderers.render_reference(single_scattering_scene(scene), spp=int(spp), use_cache=True, progress=False)
    rw_scene, why = random_walk_scene(scene)
    rw_spp = min(int(spp), RANDOM_WALK_MAX_SPP)
    rw = None if rw_scene is None else renderers.render_reference(rw_scene, spp=rw_spp, use_cache=True,
                                                                  progress=False)
    out = []
    for spec in externals:
        name = spec.text
        img = renderers.render_under_test(scene, spec, progress=False, context=context)
        c1 = compare_images(ss, img, scene=scene, ref_name="single-scattering reference", test_name=name,
                            flip_cache=context.flip_cache)
        pair = ReferencePair(scene.name, name, {m: c1.metrics.get(m) for m in REFERENCE_METRICS}, _within(c1),
                             spp_single=int(spp), note=why)
        if rw is not None:
            c2 = compare_images(rw, img, scene=scene, ref_name="random-walk reference", test_name=name,
                                flip_cache=context.flip_cache)
            pair.vs_random_walk = {m: c2.metrics.get(m) for m in REFERENCE_METRICS}
            pair.within_random_walk = _within(c2)
            pair.spp_random_walk = rw_spp
        out.append(pair)
        if progress is not None:
            progress.update(1, f"{scene.name}: {name} against both references")
    return out


def _cell(metrics: dict | None, within: dict, m: str) -> str:
    if metrics is None:
        return "-"
    return ("\u2248" if within.get(m) else "") + _fmt(metrics.get(m))


def references_sections(scene_args: list, scene_sections, presets: list[renderers.RendererSpec], out_dir: Path,
                        progress=None, context: renderers.RenderContext = renderers.DIRECT,
                        assets: AssetOptions | None = None) -> list:
    """The report's "both references" section (``[]`` when ``presets`` name no external renderer).

    ``scene_args`` are the report's scene arguments and ``scene_sections`` its
    :class:`~compare.report.results.SceneSection` s, in the same order (their ``verdict.spp``, else
    ``spp``, is the single-scattering reference's spp; ``assets``: an asset argument's ``--env`` and
    ``--size``). Writes ``OUT/<section id>/references.json``."""
    externals = [p for p in presets if p.external]
    if not externals:
        return []
    pairs = []
    for arg, sec in zip(scene_args, scene_sections):
        scene = load_scene(arg, assets)
        spp = sec.verdict.spp if getattr(sec, "verdict", None) is not None else int(sec.spp)
        got = measure_references(scene, externals, spp, progress=progress, context=context)
        write_json_atomic(Path(out_dir) / sec.id / "references.json", [p.to_dict() for p in got], indent=1)
        pairs += got
    headers = ["scene", "renderer"]
    for m in REFERENCE_METRICS:
        headers += [f"{m} vs single", f"{m} vs random walk"]
    headers += ["share of relmse from the reference's physics", "reference spp (single / walk)", "note"]
    rows = []
    for p in pairs:
        row = [p.scene, p.renderer]
        for m in REFERENCE_METRICS:
            row += [_cell(p.vs_single, p.within_single, m), _cell(p.vs_random_walk, p.within_random_walk, m)]
        share = p.share
        row += ["-" if share is None else f"{100 * share:.0f} %",
                f"{p.spp_single} / {p.spp_random_walk}" if p.vs_random_walk else f"{p.spp_single} / -", p.note]
        rows.append(row)
    note = ("Every external renderer against both references: the single-scattering reference (the scene as "
            "written, [brdf] multiscatter = \"none\", the reference of the sections below) and the random-walk "
            "reference ([brdf] multiscatter = \"random_walk\": the true multiple-scattering microfacet BSDF of "
            "Heitz et al. 2016, docs/reference.md). Engines that compensate the energy of multiple scattering "
            "(three.js, Filament, ...) lose accuracy against the first only because the reference lacks that "
            "physics; the share column is 1 - relmse(walk) / relmse(single), the part of the engine's error "
            "that is the reference's model. \u2248: within the reference's own Monte Carlo noise. The walk is "
            f"rendered at the scene's reference spp, at most {RANDOM_WALK_MAX_SPP}. Files: "
            "SCENE/references.json.")
    return [Section("references", "External renderers against both references", note,
                    [Table("", headers, rows)])]


__all__ = ["RANDOM_WALK_MAX_SPP", "REFERENCE_METRICS", "ReferencePair", "measure_references", "random_walk_scene",
           "references_sections", "single_scattering_scene"]
