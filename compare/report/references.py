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

**The model-matched truth** (``pbrcheck report --reference-mode path``): the second reference is
the random walk rendered in the report's reference mode, so in ``path`` mode it carries both
pieces of physics the plain truth lacks (multiple scattering and visibility: shadows and
interreflection), and the share column is the part of each engine's error that is the plain
truth's missing physics. A glTF asset scene has the walk as the analytic ones (per shading
point: the texel's roughness, metallic, base colour and normal; reference/textured.py). The first reference (the plain truth) is always
the single-scattering ``local`` one. The same share per material (glTF assets: per material; other
scenes: per object) is the ``materials`` list of ``references.json`` and the section's second table.
In ``path`` mode the model-matched truth also takes glTF 2.0's metallic blend (``[brdf]
metallic_blend = "gltf"``) where something is partially metallic: every external engine is a glTF
engine (docs/reference.md, "The metallic blend").

A scene with the glTF lobes has the walk under them: the walk is the base's specular and the coat,
sheen and specular lobes layer on it as the extensions write (reference/lobe_bsdf.py), so ClearCoatTest,
SheenCloth, ... are set against the model-matched truth too. A scene whose BRDF has no random walk
(``brdf.ndf`` / ``brdf.geometry`` outside :data:`pbrcheck.registry.MULTISCATTER_GEOMETRY`, or an object
with anisotropy or iridescence: :func:`compare.lobes.no_random_walk`) gets a row saying so; a display-referred engine
(``png-srgb``) is compared in display space as everywhere in the report.

API
---
- :func:`random_walk_scene` -- the scene with the random walk, or the reason it has none.
- :func:`single_scattering_scene` -- the scene with ``multiscatter = "none"``.
- :func:`matched_scene` -- the model-matched truth's scene and the physics it adds, for a mode.
- :func:`measure_references` -- one :class:`ReferencePair` per external renderer of one scene (a
  transmissive scene under a `path` reference mode: both columns the path truth, :func:`local_refusal`).
- :func:`share_of` -- ``1 - matched / plain``.
- :data:`REFERENCE_MODES` -- the reference modes of ``report --reference-mode`` and what each truth has.
- :func:`references_sections` -- the report section (``[]`` without an external renderer) and
  ``OUT/<scene>/references.json``.

References: Heitz, Hanika, d'Eon, Dachsbacher, "Multiple-Scattering Microfacet BSDFs with the Smith
Model", SIGGRAPH 2016; Kulla and Conty, "Revisiting Physically Based Shading at Imageworks",
SIGGRAPH 2017 course; Fdez-Agueera, JCGT 8(1), 2019 (three.js's compensation).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from pbrcheck.errors import SceneError
from pbrcheck.fmt import TABLE_DIGITS, format_value
from pbrcheck.jsonio import write_json_atomic
from pbrcheck.registry import MULTISCATTER_GEOMETRY
from pbrcheck.gltf_objects import AssetOptions
from pbrcheck.scene import Scene, load_scene

from .. import renderers
from ..lobes import no_random_walk
from ..metrics import REL_EPS, compare_images
from .section import Section, Table

#: Most samples per pixel of the random-walk reference in the report (a random-walk render costs
#: ~4.6x a single-scattering one: docs/reference.md, "Cost").
RANDOM_WALK_MAX_SPP = 256
#: The metrics shown for each reference (the gate's three).
REFERENCE_METRICS = ("relmse", "flip_mean", "delta_e_itp_mean")
#: The reference modes a report may set its renderers against, and what each truth has (the page's words).
REFERENCE_MODES = {
    "local": "first hit only, the environment and the lights unshadowed (no visibility, no interreflection): "
             "the model of a real-time shader",
    "path": "a path tracer's truth: visibility (shadows) and interreflection, up to the reference's max_depth",
}
#: Most materials (or objects) listed per renderer in the per-material share table of the page
#: (all of them are in references.json).
MATERIAL_ROWS_SHOWN = 40


def _fmt(v) -> str:
    return format_value(v, TABLE_DIGITS)


def single_scattering_scene(scene: Scene) -> Scene:
    """``scene`` with ``[brdf] multiscatter = "none"`` (itself when it already is)."""
    if scene.brdf.multiscatter == "none":
        return scene
    return replace(scene, brdf=replace(scene.brdf, multiscatter="none"))


def random_walk_scene(scene: Scene) -> tuple[Scene | None, str]:
    """(``scene`` with ``multiscatter = "random_walk"``, "") or (None, why it has no random walk)."""
    need = MULTISCATTER_GEOMETRY.get(scene.brdf.ndf)
    if need is None:
        return None, f"no random walk for ndf = {scene.brdf.ndf} (only {', '.join(MULTISCATTER_GEOMETRY)})"
    if scene.brdf.geometry != need:
        return None, f"the random walk for ndf = {scene.brdf.ndf} needs geometry = {need} (the scene has " \
                     f"{scene.brdf.geometry})"
    lobes = no_random_walk(scene)
    if lobes is not None:
        return None, lobes
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
    #: What the second (model-matched) reference adds to the plain one: "multiple scattering
    #: (random walk)", "visibility (path)"; empty: no second reference.
    physics: list = field(default_factory=list)
    #: Per material (glTF assets) or object: ``{"material", "pixels", "relmse_plain", "relmse_matched", "share"}``
    #: and, where the references have variance channels, the same less each reference's noise (``*_corrected``).
    materials: list = field(default_factory=list)
    #: relmse against each reference less that reference's own noise (``relmse_plain``, ``relmse_matched``).
    corrected: dict = field(default_factory=dict)

    @property
    def share_corrected(self) -> float | None:
        """:attr:`share` of the noise-corrected relmse (None without variance channels)."""
        return share_of(self.corrected.get("relmse_plain"), self.corrected.get("relmse_matched"))

    @property
    def share(self) -> float | None:
        """``1 - relmse_rw / relmse_ss``: the share of the error that is the reference's physics."""
        if not self.vs_random_walk:
            return None
        return share_of(self.vs_single.get("relmse"), self.vs_random_walk.get("relmse"))

    def to_dict(self) -> dict:
        return {"scene": self.scene, "renderer": self.renderer, "spp_single": self.spp_single,
                "spp_random_walk": self.spp_random_walk, "vs_single": self.vs_single,
                "within_noise_single": self.within_single, "vs_random_walk": self.vs_random_walk,
                "within_noise_random_walk": self.within_random_walk, "share_of_error_from_reference": self.share,
                "note": self.note, "model_matched_physics": self.physics, "materials": self.materials,
                "noise_corrected": {**self.corrected, "share": self.share_corrected}}


def share_of(plain: float | None, matched: float | None) -> float | None:
    """``1 - matched / plain``: the share of an error against the plain truth that its missing
    physics accounts for (None where either is missing or the plain error is 0)."""
    if plain is None or matched is None or plain <= 0:
        return None
    return 1.0 - matched / plain


def reference_noise_relmse(ref, cmp, ids=None) -> float | None:
    """The relmse a reference's own noise adds to a comparison against it, over its valid pixels
    (and objects ``ids``): ``mean var / (r^2 + eps)`` (``E[(t - r)^2] = (t - mu)^2 + var`` for a
    noise-free test); None without variance channels or in display space."""
    if ref.variance is None or cmp.summary["space"] != "linear":
        return None
    mask = cmp.valid
    if ids is not None:
        mask = mask & np.isin(np.rint(ref.channels["object"]), list(ids))
    if not mask.any():
        return None
    r = cmp.maps.ref[mask]
    return float((np.clip(ref.variance[mask], 0.0, None) / (r * r + REL_EPS)).mean())


def _corrected(relmse, noise) -> float | None:
    return None if relmse is None or noise is None else max(relmse - noise, 0.0)


def _per_material(c_plain, c_matched, plain=None, matched=None) -> list[dict]:
    """Per glTF material (else per object) of two comparisons of one engine: relmse against the
    plain and the model-matched truth and the share; with the references ``plain`` and ``matched``
    also each relmse less its reference's own noise (:func:`reference_noise_relmse`) and the share of those."""
    def rows(cmp):
        if cmp.summary.get("materials"):
            return {m["material"]: (m["pixels"], m["metrics"].get("relmse"), m["objects"])
                    for m in cmp.summary["materials"]}
        return {(o["name"] or f"object {o['id']}"): (o["pixels"], o["metrics"].get("relmse"), [o["id"]])
                for o in cmp.summary["objects"]}
    a, b = rows(c_plain), rows(c_matched)
    out = []
    for k in a:
        if k not in b:
            continue
        row = {"material": k, "pixels": a[k][0], "relmse_plain": a[k][1], "relmse_matched": b[k][1],
               "share": share_of(a[k][1], b[k][1])}
        if plain is not None and matched is not None and "object" in plain.channels and "object" in matched.channels:
            cp = _corrected(a[k][1], reference_noise_relmse(plain, c_plain, a[k][2]))
            cm = _corrected(b[k][1], reference_noise_relmse(matched, c_matched, b[k][2]))
            row.update(relmse_plain_corrected=cp, relmse_matched_corrected=cm, share_corrected=share_of(cp, cm))
        out.append(row)
    return out


def _within(cmp) -> dict:
    noise = cmp.summary["noise"]
    return {m: bool(noise and noise["within_noise"].get(m)) for m in REFERENCE_METRICS}


def matched_scene(scene: Scene, mode: str = "local") -> tuple[Scene | None, list[str], str]:
    """(the model-matched truth's scene, the physics it adds to the plain truth, why it lacks some):
    the random walk where the scene has one, and in ``path`` mode visibility and glTF's metallic blend
    (where something is partially metallic) too (an asset scene: no walk); None in ``local`` mode
    without a walk (``local`` keeps the report's figures as they were)."""
    rw_scene, why = random_walk_scene(scene)
    physics = [] if rw_scene is None else ["multiple scattering (random walk)"]
    if mode == "path":
        physics.append("visibility and interreflection (path)")
        if rw_scene is None:
            rw_scene = single_scattering_scene(scene)
        if rw_scene.brdf.metallic_blend != "gltf" and _partially_metallic(scene):
            # every external engine is a glTF engine: glTF 2.0 Appendix B's blend (docs/reference.md)
            rw_scene = replace(rw_scene, brdf=replace(rw_scene.brdf, metallic_blend="gltf"))
            physics.append("glTF's metallic blend")
    return rw_scene, physics, why


def _partially_metallic(scene: Scene) -> bool:
    """Whether the blends can differ: an object with 0 < metallic < 1, or a glTF asset (its metallic
    texture filtered between texels is fractional)."""
    return bool(scene.assets) or any(0.0 < o.material.metallic < 1.0 for o in scene.objects)


def local_refusal(scene: Scene) -> str | None:
    """Why the reference's ``local`` mode refuses ``scene`` (a transmissive object:
    :func:`reference.transmission.check_local`), or None."""
    from reference.render import ensure_variant
    ensure_variant()  # reference.transmission defines Mitsuba plugins at import: a variant first
    from reference.transmission import check_local
    try:
        check_local(scene)
    except SceneError as e:  # the refusal is the reference's one rule; its message is the reason
        return str(e)
    return None


def measure_references(scene: Scene, externals: list[renderers.RendererSpec], spp: int, *, progress=None,
                       context: renderers.RenderContext = renderers.DIRECT, mode: str = "local") -> list[ReferencePair]:
    """Every renderer of ``externals`` on ``scene`` against the single-scattering ``local`` reference at
    ``spp`` (the plain truth) and the model-matched one (:func:`matched_scene`: the random walk,
    rendered in ``mode``) at ``min(spp, RANDOM_WALK_MAX_SPP)`` (both through :mod:`compare.renderers`
    with the cache; the external images from the clients' cache)."""
    # a transmissive scene: the local reference refuses it (reference.transmission.check_local), so
    # under --reference-mode path its plain column is the path truth too (said in the row's note);
    # every other scene renders (and is cached) as before
    refused = local_refusal(scene) if mode != "local" else None
    ss_kw = {"mode": mode} if refused else {}
    ss = renderers.render_reference(single_scattering_scene(scene), spp=int(spp), use_cache=True, progress=False,
                                    **ss_kw)
    rw_scene, physics, why = matched_scene(scene, mode)
    if refused:
        why = ((why + "; ") if why else "") + f"the local reference refuses a transmissive scene: both columns are the {mode} truth"
    rw_spp = min(int(spp), RANDOM_WALK_MAX_SPP)
    kw = {} if mode == "local" else {"mode": mode}  # local: the calls (and cache keys) as before
    rw = None if rw_scene is None else renderers.render_reference(rw_scene, spp=rw_spp, use_cache=True,
                                                                  progress=False, **kw)
    out = []
    for spec in externals:
        name = spec.text
        img = renderers.render_under_test(scene, spec, progress=False, context=context)
        c1 = compare_images(ss, img, scene=scene, ref_name="single-scattering reference", test_name=name,
                            flip_cache=context.flip_cache)
        pair = ReferencePair(scene.name, name, {m: c1.metrics.get(m) for m in REFERENCE_METRICS}, _within(c1),
                             spp_single=int(spp), note=why)
        if rw is not None:
            c2 = compare_images(rw, img, scene=scene, ref_name="model-matched reference", test_name=name,
                                flip_cache=context.flip_cache)
            pair.vs_random_walk = {m: c2.metrics.get(m) for m in REFERENCE_METRICS}
            pair.within_random_walk = _within(c2)
            pair.spp_random_walk = rw_spp
            pair.physics = physics
            pair.materials = _per_material(c1, c2, ss, rw)
            # each relmse less its reference's own noise: a path reference is noisier than a local
            # one at the same spp, which would count against the model-matched truth
            pair.corrected = {"relmse_plain": _corrected(c1.metrics.get("relmse"), reference_noise_relmse(ss, c1)),
                              "relmse_matched": _corrected(c2.metrics.get("relmse"), reference_noise_relmse(rw, c2))}
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
                        assets: AssetOptions | None = None, mode: str = "local") -> list:
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
        got = measure_references(scene, externals, spp, progress=progress, context=context, mode=mode)
        write_json_atomic(Path(out_dir) / sec.id / "references.json", [p.to_dict() for p in got], indent=1)
        pairs += got
    second = "random walk" if mode == "local" else "model-matched (walk, path, blend)"
    headers = ["scene", "renderer"]
    for m in REFERENCE_METRICS:
        headers += [f"{m} vs single", f"{m} vs {second}"]
    headers += ["share of relmse from the reference's physics", f"reference spp (single / {second})", "note"]
    rows = []
    for p in pairs:
        row = [p.scene, p.renderer]
        for m in REFERENCE_METRICS:
            row += [_cell(p.vs_single, p.within_single, m), _cell(p.vs_random_walk, p.within_random_walk, m)]
        share = p.share
        if mode != "local" and p.share_corrected is not None:  # path mode: less each reference's noise
            share = p.share_corrected
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
    tables = [Table("", headers, rows)]
    if mode != "local":
        note = (f"Model-matched truth (--reference-mode {mode}): the second reference is the random walk rendered "
                f"in mode {mode}, {REFERENCE_MODES[mode]} (glTF assets too: the walk per shading point). "
                "The share column is then the part of the engine's error that is the plain truth's missing "
                "physics (single scattering, no visibility, pbrcheck's F0 metallic blend where glTF engines mix two "
                "BRDFs) and the table below gives it per material (glTF assets) or object. The share column "
                "above is computed on each relmse less its reference's own noise (mean var / (r^2 + eps): a path "
                "reference is noisier than a local one at the same spp, which would count against the "
                "model-matched truth); the table gives both. " + note)
        def pct(x):
            return "-" if x is None else f"{100 * x:.0f} %"
        mrows = [[p.scene, p.renderer, m["material"], str(m["pixels"]), _fmt(m["relmse_plain"]), _fmt(m["relmse_matched"]),
                  pct(m["share"]), pct(m.get("share_corrected"))]
                 for p in pairs for m in p.materials[:MATERIAL_ROWS_SHOWN]]
        tables.append(Table("Per material: the share of each engine's error that is the plain truth's missing "
                            "physics (" + ", ".join(sorted({x for p in pairs for x in p.physics})) + ")",
                            ["scene", "renderer", "material / object", "pixels", "relmse vs plain (local, single)",
                             "relmse vs model-matched", "share", "share, less each reference's noise"], mrows))
    return [Section("references", "External renderers against both references", note, tables)]


__all__ = ["RANDOM_WALK_MAX_SPP", "REFERENCE_METRICS", "REFERENCE_MODES", "ReferencePair", "matched_scene",
           "measure_references", "random_walk_scene", "references_sections", "share_of", "single_scattering_scene"]
