"""Static, offline HTML accuracy report: ``pbrcheck report``.

Layout of ``OUT/``: ``index.html``, ``run.json`` (where the time went) and one folder per scene with
PNGs (tone-mapped reference and real-time images, FLIP and relative-error maps, plots) plus
``metrics.json``. The page uses no external URL: styles and the small scripts (reference/real-time
slider, an image-decode check that sets ``data-images-ok`` on ``<body>``) are inline.

The report by concern: this module holds the configuration (:class:`ReportConfig`), the list of
stages (:func:`report_stages`: the work and the progress bar) and the page (:func:`render_page`, the
Jinja template ``compare/report/templates/report.html``, package data); one scene's measurement is
:mod:`compare.report.scene`, its plots :mod:`compare.report.plots`, the results the template reads
:mod:`compare.report.results`, the stage runner :mod:`compare.report.stages`.

API: :class:`ReportConfig`, :func:`build_report`, :func:`report_stages`, :func:`render_page`,
:func:`hardcases_section`, :func:`default_sweep` (:mod:`compare.report.sweep`).
"""

from __future__ import annotations

import contextlib
import datetime as _dt
from dataclasses import dataclass, field
from pathlib import Path

import jinja2

from pbrcheck import __version__
from pbrcheck.atomic import write_text_atomic
from pbrcheck.errors import PbrcheckError
from pbrcheck.fmt import TABLE_DIGITS, format_value
from pbrcheck.jsonio import write_json_atomic
from pbrcheck.gltf_objects import AssetOptions
from pbrcheck.scene import load_scene

from .. import renderers
from ..corpus.scheduler import open_executor, parse_scheduler
from ..metrics import METRICS
from ..research.fit_roughness import fit_scene
from ..research.hardcases import SPP_CAP as HARDCASE_SPP_CAP
from ..research.hardcases import TABLE_METRICS, run_hardcases, write_hardcases
from ..verdict_spp import MIN_REFERENCE_SPP, VerdictSpp
from .references import REFERENCE_MODES, references_sections
from .research_sections import ResearchSettings, research_parts
from .results import SceneSection
from .runlog import RUN_FILE, RunLog, run_section
from .scene import MATERIAL_METRICS, ReportSettings, SceneWork
from .lobes_section import lobe_sections
from .section import Section, Table
from .stages import ReportStage, run_stages
from .summary import furnace_scene, furnace_section, summary_section
from .sweep import combinations, default_sweep, parse_vary

#: The page's Jinja template (package data of ``compare.report``).
TEMPLATE_PACKAGE, TEMPLATE_DIR, TEMPLATE_NAME = "compare.report", "templates", "report.html"


def _fmt(v) -> str:
    return format_value(v, TABLE_DIGITS)


@dataclass(frozen=True)
class ReportConfig:
    """What ``pbrcheck report`` renders, measures and adds (its options; see :func:`build_report`).

    ``presets``: the renderers under test (default: every real-time preset); ``spp`` the least and
    ``spp_cap`` the most reference spp; ``vary``: ``KEY=V1,V2`` sweeps (every combination; default:
    the main cost knobs one at a time, unless ``sweep`` is off); ``convergence``: the reference's
    convergence study; ``approximations``: the asset approximations (asset scenes); ``furnace``: the white furnace per renderer; ``hardcases`` and ``research``:
    those sections; ``scheduler`` (``local:N``, ``tcp://HOST:PORT``): where the presets' and the sweep's
    renders run; ``cache``: the render and FLIP-map caches; ``progress``: the progress bar."""

    presets: list[str] | None = None
    spp: int = 64
    spp_cap: int | None = None
    vary: list[str] | None = None
    convergence: bool = True
    sweep: bool = True
    approximations: bool = True
    furnace: bool = True
    hardcases: bool = False
    research: bool = False
    scheduler: str | None = None
    cache: bool = True
    progress: bool = True
    #: ``--env`` / ``--size WxH`` of the glTF asset scene arguments (:func:`pbrcheck.scene.load_scene`).
    assets: AssetOptions = field(default_factory=AssetOptions)
    #: The reference mode every renderer is set against (``local``: first hit, no shadows or
    #: interreflection; ``path``: visibility and interreflection); the page states it per scene.
    reference_mode: str = "local"


@dataclass
class _Page:
    """What the stages add to the page besides the scenes: sections before and after them."""
    top: list[Section] = field(default_factory=list)
    extras: list[Section] = field(default_factory=list)


def report_stages(scenes: list[str], works: list[SceneWork], st: ReportSettings, cfg: ReportConfig, out_dir: Path,
                  page: _Page) -> list[ReportStage]:
    """Every stage of the report, in order: each scene's (:meth:`SceneWork.stages`), the summary and
    furnace, both references, then the research and hard-case sections. Their steps are the progress
    bar's total (:mod:`compare.report.stages`)."""
    presets = st.presets
    sections = lambda: [w.section for w in works]  # noqa: E731  (filled in as the scenes' stages run)
    n_ext = sum(st.spec(p).external for p in presets)

    def summary(prog):
        page.top += [summary_section(sections())]
        if cfg.furnace:
            page.top.append(furnace_section([st.spec(p) for p in presets], st.spp, prog, context=st.context))

    def references(prog):  # ext:NAME against both references
        page.top += references_sections(scenes, sections(), [st.spec(p) for p in presets], out_dir, prog,
                                        context=st.context, assets=cfg.assets, mode=cfg.reference_mode)


    def hardcases(prog):
        # The shipped shaders' robustness: real-time presets only (an external engine's hard cases
        # cost a browser start each; `pbrcheck hardcases --presets ext:NAME` runs them on their own).
        page.extras.append(hardcases_section(out_dir / "hardcases", [p for p in presets if not st.spec(p).external],
                                             cfg.progress, context=st.context))

    def lobes(prog):  # after the summary: one section per lobe the scenes carry
        page.top += lobe_sections([(w.scene.name, w.lobes) for w in works if w.lobes])

    out = [s for w in works for s in w.stages()]
    out += [ReportStage("summary and furnace", len(presets) if cfg.furnace else 0, summary)]
    if any(w.has_lobes for w in works):   # a report without lobe scenes keeps its stages
        out.append(ReportStage("lobe sections", 0, lobes, record=False))
    out += [ReportStage("both references", len(scenes) * n_ext, references)]
    if cfg.research:  # at the first scene's trusted-verdict spp (the reference its sections compare against)
        parts = research_parts(scenes[0], out_dir / "research", presets, report_spp=lambda: works[0].verdict.spp,
                               st=ResearchSettings(assets=cfg.assets),
                               progress=cfg.progress, context=st.context)
        out += [ReportStage(name, 0, lambda prog, make=make: page.extras.append(make())) for name, make in parts]
    if cfg.hardcases:
        out.append(ReportStage("hard cases", 0, hardcases))
    return out


def hardcases_section(out_dir: Path, presets: list[str] | None = None, progress: bool = False, *,
                      context: renderers.RenderContext = renderers.DIRECT) -> Section:
    """The hard-case report section (rendered small: 32 px, 16 spp, 64^2 cubes)."""
    settings = {"size": 32, "spp": 16, "cube_size": 64, "presets": presets}
    rows = run_hardcases(size=32, spp=16, cube_size=64, presets=presets, progress=progress, context=context)
    write_hardcases(rows, out_dir, settings)
    bad = sum(not r.finite for r in rows)
    return Section("hardcases", "Hard cases",
                   f"Edge-of-model scenes (pbrcheck hardcases --size 32 --spp 16 --cube-size 64). "
                   f"{'All outputs finite.' if not bad else f'{bad} output(s) NON-FINITE or failed.'} "
                   f"Error of each preset against the case's reference: {settings['spp']} spp or more, up to "
                   f"{HARDCASE_SPP_CAP}, until its noise floor is 10x below the presets' smallest error "
                   f"(per case: {_hardcase_spps(rows)}).",
                   [Table("", ["case", "renderer", "preset", "finite", *TABLE_METRICS, "note"],
                          [[r.case, r.renderer, r.preset or "-", "yes" if r.finite else "NO",
                            *[_fmt((r.metrics or {}).get(k)) for k in TABLE_METRICS], r.error or ""]
                           for r in rows])])


def _hardcase_spps(rows) -> str:
    out = []
    for r in rows:
        if r.preset is None and r.reference_spp:
            v = VerdictSpp(**r.reference_spp)
            out.append(f"{r.case} {v.spp}" + ((" noise-limited (heavy tails)" if v.heavy_tails else " noise-limited")
                                             if v.noise_limited else ""))
    return ", ".join(out) or "n/a"


def render_page(scenes: list[SceneSection], top: list[Section], extras: list[Section]) -> str:
    """The HTML page (``templates/report.html``) of the scene sections, with ``top`` before and
    ``extras`` after them."""
    env = jinja2.Environment(loader=jinja2.PackageLoader(TEMPLATE_PACKAGE, TEMPLATE_DIR), autoescape=True,
                             undefined=jinja2.StrictUndefined)
    return env.get_template(TEMPLATE_NAME).render(
        scenes=scenes, top=top, extras=extras, metric_names=METRICS, material_metrics=MATERIAL_METRICS, fmt=_fmt,
        version=__version__,
        generated=_dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"))


def _validated(scenes: list[str], cfg: ReportConfig) -> tuple[list[str], dict, dict | None]:
    """The presets, each parsed once (name -> :class:`compare.renderers.RendererSpec`), and the parsed
    ``vary``; raises before anything is rendered or written."""
    presets = list(cfg.presets) if cfg.presets is not None else renderers.preset_names()
    if not presets:
        raise PbrcheckError("report: no preset to compare")
    if cfg.reference_mode not in REFERENCE_MODES:
        raise PbrcheckError(f"report: --reference-mode must be one of {', '.join(REFERENCE_MODES)}, "
                            f"not {cfg.reference_mode!r}")
    if cfg.spp < MIN_REFERENCE_SPP:
        raise PbrcheckError(f"report: --spp must be >= {MIN_REFERENCE_SPP}, got {cfg.spp}")
    vary_d = parse_vary(cfg.vary) if cfg.vary else None
    for s in scenes:
        load_scene(s, cfg.assets)
    specs = {p: renderers.RendererSpec.parse(p) for p in presets}
    for spec in specs.values():
        renderers.check_backend_limits(spec)
    for combo in combinations(vary_d) if vary_d else []:
        renderers.check_backend_limits(specs[presets[0]].with_options(**combo))
    if cfg.scheduler:
        parse_scheduler(cfg.scheduler)
    return presets, specs, vary_d


def _prefetch_jobs(scenes: list[str], specs: dict, cfg: ReportConfig) -> list:
    """The external renderers' images, in the order the sections use them (rendered in a background
    thread while this process renders the presets, references and maps)."""
    ext = [r for r in specs.values() if r.external]
    if cfg.scheduler:
        return []
    jobs = [(load_scene(s, cfg.assets), p) for s in scenes for p in ext]
    jobs += [(furnace_scene(), p) for p in ext] if cfg.furnace else []
    if cfg.research:  # fit-roughness's targets (the first scene at its fit size)
        jobs += [(fit_scene(load_scene(scenes[0], cfg.assets), ResearchSettings().fitrough_size), p) for p in ext]
    return jobs


def build_report(scenes: list[str], out_dir: Path, config: ReportConfig = ReportConfig(), *,
                 extras: list[Section] | None = None) -> Path:
    """Render, compare and write ``out_dir/index.html`` as ``config`` says; returns its path.

    ``spp`` is the least reference spp of a scene; more are rendered (powers of two, at most
    ``spp_cap``; default: as many as render in :data:`compare.verdict_spp.DEFAULT_TIME_BUDGET_S`
    seconds per scene at the measured speed) until the reference's noise
    floor is :data:`compare.verdict_spp.NOISE_FLOOR_FACTOR` times below the smallest error of the
    presets against it, else the section says "noise-limited"; the rule's outcome is in the
    provenance table and ``metrics.json`` (``reference_spp``).
    ``hardcases``: add the hard-case section (:mod:`compare.research.hardcases`, 32 px, 16 spp, 64^2 cubes;
    its JSON and table go to ``out_dir/hardcases``). ``research``: add the LOD fit (before / after),
    the error decomposition and the apparent-roughness sections for the first scene
    (:mod:`compare.report.research_sections`; files under ``out_dir/research``). ``extras``: further
    :class:`~compare.report.section.Section` s. The page opens with the summary (one row per
    renderer and scene) and, with ``furnace``, the white furnace per renderer
    (:mod:`compare.report.summary`), a section per glTF PBR extension lobe the scenes carry
    (:mod:`compare.report.lobes_section`), then every external renderer against both the single-scattering
    and the random-walk reference (:mod:`compare.report.references`). ``scheduler``: the presets'
    and the sweep's renders run there (:mod:`compare.corpus.renderlist`). ``cache``: real-time renders
    come from the content-addressed cache where their scene, options, shader and code are unchanged
    (a caching :class:`compare.renderers.RenderContext`; their timings are those measured when
    rendered), and HDR-FLIP maps from the disk where both images are unchanged
    (``compare_images(..., flip_cache=True)``).

    Raises
    ------
    PbrcheckError
        No preset, ``spp`` below 2, an unknown scene, preset or swept option: raised before anything
        is rendered or written."""
    cfg = config
    presets, specs, vary_d = _validated(scenes, cfg)
    spec = parse_scheduler(cfg.scheduler) if cfg.scheduler else None
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    page = _Page(extras=list(extras or []))
    log = RunLog()
    with renderers.prefetch_external(_prefetch_jobs(scenes, specs, cfg)) as prefetched, \
            (open_executor(spec) if spec else contextlib.nullcontext()) as ex:
        st = ReportSettings(presets, cfg.spp, vary_d, cfg.convergence, cfg.sweep, executor=ex,
                            approximations=cfg.approximations, specs=specs, assets=cfg.assets,
                            reference_mode=cfg.reference_mode,
                            spp_cap=None if cfg.spp_cap is None else int(cfg.spp_cap),
                            context=renderers.RenderContext(cache=cfg.cache, prefetch=prefetched,
                                                            flip_cache=cfg.cache))
        works = [SceneWork(s, out_dir, st) for s in scenes]
        run_stages(report_stages(scenes, works, st, cfg, out_dir, page), "report", enabled=cfg.progress, log=log)
    run = log.to_dict()
    write_json_atomic(out_dir / RUN_FILE, run, indent=1)
    page.extras.append(run_section(run))
    index = out_dir / "index.html"
    write_text_atomic(index, render_page([w.section for w in works], page.top, page.extras))
    return index


__all__ = ["ReportConfig", "build_report", "default_sweep", "hardcases_section", "render_page", "report_stages"]
