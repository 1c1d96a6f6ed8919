"""One scene of the report: the renderers under test, the reference, the comparisons (and diagnose
for external renderers), the sweep, the reference's convergence study, the plots and the files.

:class:`SceneWork` holds one scene's state and gives its work as :class:`~compare.report.stages.ReportStage` s
(:meth:`SceneWork.stages`); once they have run, :attr:`SceneWork.section` is its
:class:`~compare.report.results.SceneSection`. Files under ``OUT/<scene>/``: ``reference.png``, per
renderer ``rt_``, ``flip_`` and ``rel_`` PNGs (and ``diagnose_*.json`` for an external one), the
plots, ``sweep.csv`` / ``sweep.json`` and ``metrics.json`` (with, for an asset scene, the approximation
rows of :mod:`compare.approximations`: its ``asset_approximations``; for a scene whose objects carry
glTF PBR extension lobes, ``lobes``: :mod:`compare.report.lobes_section`'s rows per lobe).

API: :class:`ReportSettings`, :class:`SceneWork`, :func:`approximation_preset`, :func:`material_rows`,
:func:`unmodelled_banner`, :func:`convergence_spps`, :data:`DIAGNOSE_SPP`,
:data:`CONVERGENCE_FRACTIONS`, :data:`CONVERGENCE_SEED`, :data:`PROVENANCE_SKIP`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

from pbrcheck.jsonio import write_json_atomic
from pbrcheck.gltf_objects import AssetOptions
from pbrcheck.scene import builtin_scene_names, builtin_scene_path, load_scene

from .. import renderers
from ..approximations import approximation_rows
from ..corpus import renderlist
from ..maps import safe_name, write_flip_png, write_rel_png, write_tonemapped
from ..metrics import METRICS, compare_images
from ..research.diagnose import diagnose
from ..verdict_spp import MIN_REFERENCE_SPP, reference_for_verdict
from ..lobes import lobe_variants, object_lobes
from .lobes_section import lobe_rows, lobe_variant_rows
from .plots import plot_convergence, plot_materials, plot_ndotv
from .results import PresetResult, SceneSection
from .stages import ReportStage
from .summary import timed_on as timed_on_text
from .sweep import combinations, default_sweep, image_timings, plot_speed_error, sweep_rows, timed_on, write_table

#: Most samples per pixel of diagnose's scene-space re-renders for an external renderer (10 re-renders
#: per renderer and scene; the hypotheses' errors are orders of magnitude above 64-spp noise, and
#: diagnose subtracts the re-renders' own variance).
DIAGNOSE_SPP = 64
#: Reference spp fractions for the convergence study (error of a lower-spp render with another
#: seed against the full reference).
CONVERGENCE_FRACTIONS = (1 / 16, 1 / 8, 1 / 4, 1 / 2)
#: Seed of the convergence renders: different from the reference's so their noise is independent.
CONVERGENCE_SEED = 1
#: Reference metadata not shown under provenance (internal bookkeeping).
PROVENANCE_SKIP = {"cache_key", "cache"}


#: The metrics the report's per-material table lists (the summary's ``materials``; ``bias`` is
#: compare.metrics.material_bias, the relative signed bias).
MATERIAL_METRICS = ("relmse", "flip_mean", "bias")


def material_rows(preset: str, summary: dict, unmodelled=()) -> list[dict]:
    """The per-material table's rows of one renderer (glTF asset scenes; empty otherwise):
    ``{"preset", "material", "pixels", "metrics": {MATERIAL_METRICS}}``, and ``"unmodelled"`` (the
    features of ``unmodelled``, the scene's :attr:`~pbrcheck.scene.Scene.unmodelled`, that touch one
    of the row's objects) where there are any: the report marks those rows."""
    rows = []
    for m in summary.get("materials", []):
        row = {"preset": preset, "material": m["material"], "pixels": m["pixels"],
               "metrics": {k: m["metrics"].get(k) for k in MATERIAL_METRICS}}
        feats = sorted({u.feature for u in unmodelled if set(u.objects) & set(m.get("objects", ()))})
        if feats:
            row["unmodelled"] = feats
        rows.append(row)
    return rows


def unmodelled_banner(scene) -> list[dict]:
    """The report's banner of a scene using features pbrcheck does not model: per (asset, feature)
    ``{"asset", "feature", "materials"}`` (empty: no banner)."""
    return [{"asset": Path(u.asset).name, "feature": u.feature, "materials": ", ".join(u.materials) or "none"}
            for u in scene.unmodelled]


def convergence_spps(spp: int) -> list[int]:
    """The convergence study's spps below a reference of ``spp`` (:data:`CONVERGENCE_FRACTIONS`)."""
    return sorted({int(spp * f) for f in CONVERGENCE_FRACTIONS if MIN_REFERENCE_SPP <= int(spp * f) < spp})


@dataclass(frozen=True)
class ReportSettings:
    """What every scene section renders: the renderers under test, the reference spp, the sweep
    (``vary``: option -> values, every combination; else the default sweep when ``sweep``), the
    reference convergence study, and how the renderers under test render (``context``).
    ``specs``: each name of ``presets`` parsed once (:class:`compare.renderers.RendererSpec`), what
    every stage renders; the names label the outputs."""

    presets: list[str]
    spp: int
    vary: dict | None = None
    convergence: bool = True
    sweep: bool = True
    executor: object = None  # --scheduler: renders of presets and sweep run as its tasks
    #: Largest reference spp the trusted-verdict rule may choose (compare.verdict_spp); ``spp`` is the
    #: least; None: as many as fit in ``DEFAULT_TIME_BUDGET_S`` of rendering per scene.
    spp_cap: int | None = None
    context: renderers.RenderContext = field(default=renderers.DIRECT)
    #: Asset scenes drawn by a real-time preset: every approximation option against its truth
    #: (compare.approximations; one ``path`` reference at ``spp`` and 13 raster frames).
    approximations: bool = True
    specs: dict = field(default_factory=dict)
    #: ``--env`` / ``--size WxH`` of a glTF asset scene argument (:func:`pbrcheck.scene.load_scene`).
    assets: AssetOptions = field(default_factory=AssetOptions)

    def spec(self, name: str) -> renderers.RendererSpec:
        """The parsed renderer of preset name ``name`` (a name the report was not given: KeyError)."""
        return self.specs[name]
    #: The reference's mode (``local`` or ``path``): the truth every renderer is set against.
    reference_mode: str = "local"

    def combos(self) -> list[dict]:
        """The sweep's option sets (over the first preset)."""
        if self.vary:
            return combinations(self.vary)
        return default_sweep(self.spec(self.presets[0])) if self.sweep else []


class SceneWork:
    """One scene of the report: its stages (:meth:`stages`) and, once they ran, its :attr:`section`."""

    def __init__(self, scene_arg, out_dir: Path, st: ReportSettings):
        self.scene = load_scene(scene_arg, st.assets)
        self.st = st
        self.sid = safe_name(self.scene.name)
        self.sd = Path(out_dir) / self.sid
        self.combos = st.combos()
        self.images: dict = {}
        self.ref = self.verdict = self.noise_floor = None
        self.results: list[PresetResult] = []
        self.objs: dict = {}
        self.bins: dict = {}
        self.speed_rows: list[dict] = []
        self.dump: dict = {}
        self.provenance: list[tuple[str, str]] = []
        self.material_rows: list[dict] = []
        self.sweep_table: list[dict] = []
        self.approx_preset = (approximation_preset(self.scene, [st.spec(p) for p in st.presets])
                              if st.approximations else None)
        self.approx_rows: list[dict] = []
        self.conv: list[dict] = []
        # The glTF PBR extensions' lobes its objects carry (none: no lobe stage, metrics.json unchanged)
        # and the first real-time preset's other lobe forms (compare.lobes.lobe_variants).
        self.has_lobes = bool(object_lobes(self.scene))
        rt = next((st.spec(p) for p in st.presets if not st.spec(p).external), None)
        self.lobe_spec = rt
        self.lobe_variants = lobe_variants(rt, self.scene) if self.has_lobes and rt is not None else []
        self.lobes: dict = {}
        self.section: SceneSection | None = None

    def stages(self) -> list[ReportStage]:
        """The renderers under test first: the reference's spp is chosen so that its noise floor sits
        NOISE_FLOOR_FACTOR below the smallest of their errors (compare.verdict_spp), at most spp_cap;
        then one comparison per renderer, the sweep, the convergence study, the plots and files."""
        n = self.scene.name
        out = [ReportStage(f"{n}: renderers under test", 0, self._render),
               ReportStage(f"{n}: reference", 1, self._reference)]
        out += [ReportStage(f"{n}: comparisons and diagnose", 1, partial(self._measure, p)) for p in self.st.presets]
        if self.has_lobes:
            out.append(ReportStage(f"{n}: lobes", len(self.lobe_variants), self._lobes))
        if self.combos:
            out.append(ReportStage(f"{n}: sweep", len(self.combos), self._sweep))
        if self.approx_preset:
            out.append(ReportStage(f"{n}: asset approximations", 1, self._approximations))
        if self.st.convergence:  # at most one step per fraction (fewer at a low spp)
            out.append(ReportStage(f"{n}: convergence", len(CONVERGENCE_FRACTIONS), self._convergence))
        out.append(ReportStage(f"{n}: plots and files", 0, self._write, record=False))
        return out

    def _mode(self) -> dict:
        """The reference mode as a keyword (none for ``local``, the renderer's default: the calls and
        their cache keys stay those of a report without ``--reference-mode``)."""
        return {} if self.st.reference_mode == "local" else {"mode": self.st.reference_mode}

    def _render(self, prog) -> None:
        self.sd.mkdir(parents=True, exist_ok=True)
        st = self.st
        if st.executor is not None:  # --scheduler: the renders run as the executor's tasks
            imgs = renderlist.render_images(st.executor, self.scene, [st.spec(p) for p in st.presets],
                                            context=st.context)
            self.images = dict(zip(st.presets, imgs))
        else:
            self.images = {p: renderers.render_under_test(self.scene, st.spec(p), progress=False, context=st.context)
                           for p in st.presets}

    def _reference(self, prog) -> None:
        self.ref, self.verdict = reference_for_verdict(self.scene, list(self.images.values()), spp=self.st.spp,
                                                       cap=self.st.spp_cap, **self._mode())
        prog.update(1, f"{self.scene.name}: reference ({self.verdict.spp} spp)")
        write_tonemapped(self.sd / "reference.png", self.ref.rgb)
        self.provenance = _provenance(self.scene, self.ref)
        self.provenance.append(("reference spp rule", self.verdict.provenance()))
        for a in getattr(self.scene, "assets", ()):
            self.provenance.append((f"glTF asset {Path(a.path).name}", f"sha256 {a.content_hash}; extensions used: "
                                    f"{', '.join(a.asset.extensions_used) or 'none'}; ignored: "
                                    f"{', '.join(a.asset.extensions_ignored) or 'none'}"))

    def _measure(self, preset: str, prog) -> None:
        """Compare ``preset``'s image, write its images (and diagnose an external renderer)."""
        scene, ref, sd, sid, img = self.scene, self.ref, self.sd, self.sid, self.images[preset]
        external = self.st.spec(preset).external
        cmp = compare_images(ref, img, scene=scene, ref_name="reference",
                             test_name=preset if external else f"real-time {preset}",
                             flip_cache=self.st.context.flip_cache)
        p = safe_name(preset)
        options = img.meta_json("options", None) if "options" in img.meta else None
        write_tonemapped(sd / f"rt_{p}.png", img.rgb, options)
        write_flip_png(sd / f"flip_{p}.png", cmp)
        write_rel_png(sd / f"rel_{p}.png", cmp)
        pre, frame = image_timings(img)
        noise = cmp.summary["noise"]
        res = PresetResult(preset, cmp.metrics, cmp.summary["pixels"],
                           {m: bool(noise and noise["within_noise"].get(m)) for m in METRICS}, pre, frame,
                           f"{sid}/rt_{p}.png", f"{sid}/flip_{p}.png", f"{sid}/rel_{p}.png",
                           (cmp.metrics["rmse"] or 0.0) ** 2, timed_on_text(img.meta), cmp.summary["space"])
        if external:
            res.diagnosis, res.diagnosis_json = self._diagnose(img, p, res.space)
        if noise is not None:
            self.noise_floor = noise["mean_variance"]
        self.results.append(res)
        self.objs[preset] = {o["id"]: o["metrics"] for o in cmp.summary["objects"]}
        self.bins[preset] = cmp.summary["ndotv"]
        self.speed_rows.append({"preset": preset, "options": {}, "precompute_s": res.precompute, "frame_s": res.frame,
                                **timed_on(img), **cmp.metrics})
        self.dump[preset] = {**cmp.summary, "options": options,
                             "timings": img.meta_json("timings", None) if "timings" in img.meta else None}
        self.provenance.append((f"{preset} options", img.meta.get("options", "")))
        self.material_rows += material_rows(preset, cmp.summary, self.scene.unmodelled)   # glTF assets: per material
        if img.meta_json("shader", None):  # a shader hook file: its path, hash and hooks
            self.provenance.append((f"{preset} shader hooks", img.meta["shader"]))
        prog.update(1, f"{scene.name}: {preset}")

    def _diagnose(self, img, p: str, space: str) -> tuple[str, str]:
        """:func:`compare.research.diagnose.diagnose` of an external renderer's image (scene-space
        hypotheses re-rendered at :data:`DIAGNOSE_SPP` at most); its line and its JSON's path."""
        if space != "linear":
            return "not run: the renderer's output is display-referred (png-srgb)", ""
        ref = self.ref
        d = diagnose(ref, img, self.scene, spp=min(int(ref.meta.get("spp", DIAGNOSE_SPP)), DIAGNOSE_SPP))
        write_json_atomic(self.sd / f"diagnose_{p}.json", d)
        return d.line, f"{self.sid}/diagnose_{p}.json"

    def _lobes(self, prog) -> None:
        """Per lobe the renderers' error over its objects, then the first real-time preset's other
        forms of it (compare.report.lobes_section)."""
        self.lobes = lobe_rows(self.scene, self.dump)
        if self.lobe_variants:
            more = lobe_variant_rows(self.scene, self.ref, self.lobe_spec, self.lobe_variants, progress=prog,
                                     context=self.st.context)
            for ext, rows in more.items():
                self.lobes.setdefault(ext, []).extend(rows)
                self.speed_rows += [{**r, "preset": r["renderer"]} for r in rows]

    def _sweep(self, prog) -> None:
        """The sweep over the cost knobs (from the first preset)."""
        st = self.st
        srows = sweep_rows(self.scene, self.ref, self.combos, spec=st.spec(st.presets[0]), progress=prog,
                           executor=st.executor, context=st.context)
        write_table(self.sd, srows, sorted({k for c in self.combos for k in c}))
        for r in srows:
            label = ",".join(f"{k}={v}" for k, v in r["options"].items())
            self.sweep_table.append({**r, "label": label})
            self.speed_rows.append({**r, "preset": label})

    def _approximations(self, prog) -> None:
        """The asset approximations (compare.approximations) with the first real-time preset, the
        report's reference standing for ``local`` when it is one; references at the report's spp."""
        refs = {"local": self.ref} if self.ref.meta.get("mode", "local") == "local" else {}
        self.approx_rows = approximation_rows(self.scene, self.st.spp, preset=self.approx_preset, references=refs)
        prog.update(1, f"{self.scene.name}: asset approximations")

    def _convergence(self, prog) -> None:
        """MSE of lower-spp renders (another seed) against the reference, with the variance prediction."""
        scene, ref = self.scene, self.ref
        for s in convergence_spps(self.verdict.spp):
            low = renderers.render_reference(scene, spp=s, seed=CONVERGENCE_SEED, use_cache=True, progress=False,
                                             **self._mode())
            c = compare_images(ref, low, noise=False, flip=False, itp=False)  # reads mse and relmse only
            lv = low.variance
            exp = None
            if lv is not None and ref.variance is not None:
                exp = float(lv[c.valid].mean() + ref.variance[c.valid].mean())
            self.conv.append({"spp": s, "mse": (c.metrics["rmse"] or 0.0) ** 2, "relmse": c.metrics["relmse"],
                              "expected": exp})
            prog.update(1, f"{scene.name}: convergence {s} spp")

    def _write(self, prog) -> None:
        """The plots, ``metrics.json`` and :attr:`section`."""
        scene, sd, sid, verdict = self.scene, self.sd, self.sid, self.verdict
        plots = []
        m = plot_materials(sd / "materials.png", scene, self.objs)
        if m:
            plots.append({"title": "Error against roughness and metallic (sphere grid)", "src": f"{sid}/{m}"})
        n = plot_ndotv(sd / "ndotv.png", self.bins)
        if n:
            plots.append({"title": "Error against NdotV", "src": f"{sid}/{n}"})
        sp = plot_speed_error(sd / "speed.png", self.speed_rows, lambda r: r["preset"],
                              f"{scene.name}: speed against error")
        plots.append({"title": "Speed against error (presets" + (" and sweep" if self.sweep_table else "") + ")",
                      "src": f"{sid}/{sp.name}",
                      "note": "Red: Pareto front (no other point is both faster and more accurate)."})
        if self.conv:
            cp = plot_convergence(sd / "convergence.png", self.conv, verdict.spp, self.noise_floor,
                                  {r.preset: r.mse for r in self.results})
            if cp:
                plots.append({"title": "Reference convergence", "src": f"{sid}/{cp}",
                              "note": "If the reference is converged, the renderers' MSE lines lie far above its "
                                      "noise floor."})
        write_json_atomic(sd / "metrics.json", {"scene": scene.name, "presets": self.dump, "convergence": self.conv,
                                                "sweep": self.sweep_table, "reference_spp": verdict.to_dict(),
                                                "asset_approximations": {"preset": self.approx_preset,
                                                                         "rows": self.approx_rows},
                                                **({"lobes": self.lobes} if self.lobes else {})},
                          indent=1)
        self.section = SceneSection(sid, scene.name, scene.description, self.ref.meta.get("spp", self.st.spp),
                                    f"{sid}/reference.png", self.results, plots, self.provenance, self.noise_floor,
                                    self.sweep_table, verdict, self.material_rows, self.approx_preset, self.approx_rows,
                                    unmodelled_banner(scene), self.ref.meta.get("mode", "local"))


def approximation_preset(scene, specs: list[renderers.RendererSpec]) -> str | None:
    """The first real-time preset (of the parsed renderers ``specs``) that draws ``scene`` with the
    raster pipeline, for an asset scene (None otherwise: no asset section)."""
    from pbrcheck.gltf_scene import scene_has_assets
    from realtime.render import resolved_pipeline
    if not scene_has_assets(scene):
        return None
    for r in specs:   # named presets only (not external renderers, not hook files nor overrides)
        if not r.external and not r.overrides and resolved_pipeline(scene, r.options) == "raster":
            return r.name
    return None


def _provenance(scene, ref) -> list[tuple[str, str]]:
    src = scene.source
    if scene.name in builtin_scene_names() and src == str(builtin_scene_path(scene.name)):
        src = f"built-in scene {scene.name} (pbrcheck/scenes/{scene.name}.toml)"  # no machine paths
    out = [("scene source", src)]
    for k in sorted(ref.meta):  # scene hash, spp, mode, seed, variant, versions, seconds...
        if k not in PROVENANCE_SKIP:
            out.append((f"reference {k}", ref.meta[k]))
    return out


__all__ = ["CONVERGENCE_FRACTIONS", "CONVERGENCE_SEED", "DIAGNOSE_SPP", "PROVENANCE_SKIP", "ReportSettings",
           "SceneWork", "approximation_preset", "convergence_spps"]
