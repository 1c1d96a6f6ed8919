"""The report's research sections: LOD fit (before / after), error decomposition, apparent roughness,
multiple-scattering energy compensations (``energy``).

Each section runs the command of the same name (:mod:`compare.research.fit_lod`,
:mod:`compare.research.explain`, :mod:`compare.research.fit_roughness`) on one scene at a reduced
size, writes its JSON / Markdown / GLSL under ``OUT/research/`` and returns a report
:class:`~compare.report.section.Section` built from the command's typed result. Sizes are stated in each section's note; they are chosen so the
three together take a few minutes on two CPU cores.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pbrcheck.fmt import TABLE_DIGITS, format_value
from pbrcheck.jsonio import write_json_atomic
from pbrcheck.lodmap import LodMapping, builtin_lod
from pbrcheck.progress import Progress
from pbrcheck.lodmap import BUILTIN_LOD_MAPPINGS
from pbrcheck.scene import load_scene

from .. import renderers
from ..maps import pyplot, save_figure
from ..metrics import compare_images
from ..research import energy as _energy
from ..research.explain import COMBINED_LABELS, PRIMARY, run_explain, write_explain
from ..research.fit_lod import run_fit_lod
from ..research.fit_roughness import run_fit_roughness
from ..research.results import ApparentRoughness
from ..verdict_spp import VerdictSpp
from .section import Section, Table

@dataclass(frozen=True)
class ResearchSettings:
    """Sizes of the research runs. ``options``: real-time option overrides applied to every render
    of every section (empty for the report: the presets as shipped; tests shrink the cubes)."""

    #: fit-lod: image height of the scan and reference spp. The fit is for the preset's own cube
    #: size and mip count, so the fitted mapping applies to the full-size report render unchanged.
    fitlod_size: int = 64
    fitlod_spp: int = 128
    #: explain: image height and reference spp (the noise this leaves is printed with the table).
    explain_size: int = 64
    explain_spp: int = 256
    #: fit-roughness: image height (the reference is re-rendered at every Adam step) and steps.
    fitrough_size: int = 48
    fitrough_iterations: int = 40
    options: dict = field(default_factory=dict)
    #: explain's exact counterparts at this fraction of their sample counts (1 in the report)
    samples_scale: float = 1.0
    cube_max: int = 512
    #: energy: walks per albedo grid point, the images' reference spp, height and scenes.
    energy_samples: int = 1 << 16
    energy_spp: int = 128
    energy_size: int = 64
    energy_scenes: tuple = ("furnace", "spheres")


def _fmt(v) -> str:
    return format_value(v, TABLE_DIGITS)


def _rule(d: dict | None) -> str:
    """One line of how a research command's reference spp was chosen (compare.verdict_spp)."""
    return VerdictSpp(**d).provenance() if d else "n/a"


def _pct(part, whole) -> str:
    if part is None or whole is None or not whole:
        return "n/a"
    return f"{100.0 * part / whole:+.1f} %"


def fit_lod_section(scene_name: str, out_dir: Path, *, preset: str = "default", report_spp: int,
                    st: ResearchSettings = ResearchSettings(), progress: bool = False,
                    context: renderers.RenderContext = renderers.DIRECT) -> Section:
    """``pbrcheck fit-lod`` on ``scene_name``, then the report scene rendered by ``preset`` before
    (its own mapping) and after (``lod_mapping=fitted:FILE``) against the report's reference."""
    scene = load_scene(scene_name)
    out = out_dir / "fit_lod.json"
    opts = dict(st.options)
    res = run_fit_lod(scene, preset=preset, options=opts, spp=st.fitlod_spp, size=st.fitlod_size, out=out,
                      progress=progress, context=context)
    o = renderers.resolve_options(preset, opts)
    own = o["lod_mapping"]
    # Before / after on the report's own render (full size, point lights on, report spp).
    ref = renderers.render_reference(scene, spp=report_spp, use_cache=True, progress=False)
    # The table reads ``keys`` only (no Delta E ITP: its map is not computed).
    before = compare_images(ref, renderers.render_under_test(scene, preset, opts, context=context), noise=False,
                            itp=False, flip_cache=context.flip_cache).metrics
    after = compare_images(ref, renderers.render_under_test(scene, preset, {**opts, "lod_mapping": f"fitted:{out}"},
                                                            context=context), noise=False, itp=False,
                           flip_cache=context.flip_cache).metrics
    m = res.mappings
    keys = ("relmse", "rmse", "flip_mean", "rel_p95")
    t_maps = Table(f"Every mapping on the fit scene ({res.size[0]} x {res.size[1]}, point lights "
                   f"removed, {res.spp}-spp reference; spp rule: {_rule(res.reference_spp)})",
                   ["mapping", "chain", "relmse (render)", "vs the preset's own"],
                   [[k, res.chain if k == "fitted" else k, _fmt(v.relmse),
                     _pct(v.relmse - m[own].relmse, m[own].relmse)] for k, v in m.items()])
    t_ba = Table(f"Before / after on the report's render of {scene.name} ({scene.camera.width} x "
                 f"{scene.camera.height}, lights on, {report_spp}-spp reference)",
                 ["preset", "lod_mapping", *keys],
                 [[preset, f"{own} (before)", *[_fmt(before[k]) for k in keys]],
                  [preset, f"fitted on the {res.chain} chain (after)", *[_fmt(after[k]) for k in keys]]])
    t_chain = Table("Scan prediction per chain (interpolated scan; the chosen chain has the lowest)",
                    ["chain", "fit's predicted relmse", "chain's own mapping, predicted"],
                    [[c, _fmt(v.predicted_relmse), _fmt(v.builtin_predicted_relmse)] for c, v in res.chains.items()])
    names = ("fitted", *BUILTIN_LOD_MAPPINGS)
    t_opt = Table("Optimal LOD per roughness (scan minimum refined by a parabola) and the mappings",
                  ["roughness", "optimal LOD", "relmse at optimum", *names],
                  [[f"{s.roughness:.3g}", f"{s.lod:.2f}", _fmt(s.relmse), *[f"{m[k].lod[i]:.2f}" for k in names]]
                   for i, s in enumerate(res.samples)])
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    rr = np.linspace(0, 1, 201)
    fm = LodMapping.from_json(m["fitted"].to_json())
    M, cube_log2 = o["prefilter_levels"] - 1, float(np.log2(o["cube_size"]))
    colour = {k: f"C{i}" for i, k in enumerate(BUILTIN_LOD_MAPPINGS)}  # a chain's line and its optima alike
    for k in BUILTIN_LOD_MAPPINGS:
        ax.plot(rr, builtin_lod(k, rr, M, cube_log2), lw=1, color=colour[k], label=f"{k} (relmse {_fmt(m[k].relmse)})")
    ax.plot(rr, fm(rr), "k-", lw=2, label=f"fitted, {res.chain} chain (relmse {_fmt(m['fitted'].relmse)})")
    for c, v in res.chains.items():
        ax.plot([s.roughness for s in res.samples], v.optimal_lod, "o", ms=5, mfc="none",
                color=colour[c], label=f"optimal LOD on the {c} chain")
    ax.set_xlabel("roughness")
    ax.set_ylabel("prefiltered LOD")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    plot = save_figure(fig, out_dir / "fit_lod.png")
    return Section("fit-lod", f"LOD fit: roughness -> prefiltered level ({scene.name}, preset {preset})",
                   f"pbrcheck fit-lod {scene.name} --size {st.fitlod_size} --spp {st.fitlod_spp} --preset {preset}: "
                   f"each roughness read at every level of each built-in chain (step {res.lod_step}), "
                   f"a smooth monotone mapping fitted to the measured error, every mapping rendered. "
                   f"Files: research/fit_lod.json, research/fit_lod.glsl.",
                   [t_ba, t_maps, t_chain, t_opt],
                   [{"title": "LOD against roughness", "src": f"research/{plot}"}])


def explain_section(scene_name: str, out_dir: Path, *, preset: str = "default",
                    st: ResearchSettings = ResearchSettings(), progress: bool = False,
                    context: renderers.RenderContext = renderers.DIRECT) -> Section:
    """``pbrcheck explain`` of ``preset`` on ``scene_name`` (with the LOD fit's file when present)."""
    res = run_explain(load_scene(scene_name), preset=preset, options=dict(st.options), spp=st.explain_spp,
                      size=st.explain_size, cube_max=st.cube_max, samples_scale=st.samples_scale,
                      fitted=str(out_dir / "fit_lod.json") if (out_dir / "fit_lod.json").exists() else None,
                      progress=progress, context=context)
    write_explain(res, out_dir / f"explain_{preset}.json")
    b = res.baseline[PRIMARY]
    rows = [["(preset as shipped)", "", _fmt(b), "", "", _fmt(res.baseline["flip_mean"])]]
    for r in res.sources:
        mm = r.metrics or {}
        opts = ", ".join(f"{k}={v}" for k, v in r.options.items())
        rows.append([r.source, opts if not r.error else r.error, _fmt(mm.get(PRIMARY)),
                     _fmt(r.contribution), _pct(r.contribution, b), _fmt(mm.get("flip_mean"))])
    for k, lab in COMBINED_LABELS:
        c = getattr(res, k)
        if c is not None:
            rows.append([lab, "", _fmt(c.metrics[PRIMARY]), _fmt(c.contribution),
                         _pct(c.contribution, b), _fmt(c.metrics["flip_mean"])])
    noise = res.noise_relmse
    left = None if noise is None or res.all_exact is None else res.all_exact.metrics[PRIMARY] - noise
    return Section(f"explain-{preset}", f"Error decomposition ({scene_name}, preset {preset})",
                   (f"pbrcheck explain {scene_name} --preset {preset} --size {st.explain_size} --spp {st.explain_spp}: "
                     f"one approximation at a time made exact, the scene re-rendered; contribution = relmse "
                     f"of the preset - relmse with that source exact. Reference spp rule: {_rule(res.reference_spp)}. "
                     f"The {res.spp}-spp reference's own "
                     f"noise explains relmse {_fmt(noise)}; what all-exact leaves above it ({_fmt(left)}) "
                     f"comes from what no option replaces (the diffuse split Kd(n.v) E(n), the runtime "
                     f"estimator's mip filtering, texel filtering). "
                    f"Files: research/explain_{preset}.json, .md."),
                   [Table("", ["source made exact", "options", f"{PRIMARY} after", "contribution", "share",
                               "flip_mean after"], rows)], [])


def fit_roughness_section(scene_name: str, out_dir: Path, presets: list[str], *,
                          st: ResearchSettings = ResearchSettings(), progress: bool = False,
                          context: renderers.RenderContext = renderers.DIRECT) -> Section:
    """``pbrcheck fit-roughness`` of every preset on ``scene_name``: plot and table of r* against r."""
    scene = load_scene(scene_name)
    results = {}
    scans: dict = {}  # the scan's renders do not depend on the preset: made once for all of them
    with Progress("fit-roughness", total=len(presets), enabled=progress) as prog:
        for p in presets:
            results[p] = run_fit_roughness(scene, preset=p, options=dict(st.options), size=st.fitrough_size,
                                           iterations=st.fitrough_iterations, scan_cache=scans,
                                           context=context)
            prog.update(1, p)
    write_json_atomic(out_dir / "fit_roughness.json", results)
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2), sharey=True)
    metallic = [o.material.metallic for o in scene.objects]
    for ax, (lab, sel) in zip(axes, (("metals (metallic >= 0.5)", lambda m: m >= 0.5),
                                     ("dielectrics (metallic < 0.5)", lambda m: m < 0.5))):
        ax.plot([0, 1], [0, 1], color="gray", lw=1, ls="--", label="r* = r")
        n = max(len(results), 1)
        for i, (p, res) in enumerate(results.items()):
            obj = [o for o in res.objects if sel(metallic[o.object])]
            if not obj:
                continue
            # Presets side by side at each roughness; the bar is the scan's range (what this image
            # size and sample count cannot tell apart).
            x = np.array([o.roughness for o in obj]) + 0.012 * (i - (n - 1) / 2)
            y = np.array([o.apparent_roughness for o in obj])
            rng = [o.range or [o.apparent_roughness] * 2 for o in obj]
            err = np.array([[max(yy - r[0], 0.0) for yy, r in zip(y, rng)], [max(r[1] - yy, 0.0) for yy, r in zip(y, rng)]])
            ax.errorbar(x, y, yerr=err, fmt="o", ms=3.5, lw=0.8, capsize=1.5, color=f"C{i}", alpha=0.75, label=p)
        ax.set_title(lab, fontsize=9)
        ax.set_xlabel("material roughness r")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("apparent roughness r* (reference fitted to the preset)")
    axes[0].legend(fontsize=7)
    plot = save_figure(fig, out_dir / "fit_roughness.png")
    # Table: per preset and material roughness, the mean r* over the metal and the dielectric objects
    # with the hull of their ranges, and the mean final loss.
    rough = sorted({round(o.material.roughness, 6) for o in scene.objects})
    rows = []
    for p, res in results.items():
        for r in rough:
            obj = [o for o in res.objects if round(o.roughness, 6) == r]
            loss = [o.loss for o in obj if o.loss is not None]
            rows.append([p, f"{r:.3g}", _r_star([o for o in obj if metallic[o.object] >= 0.5]),
                         _r_star([o for o in obj if metallic[o.object] < 0.5]),
                         _fmt(float(np.mean(loss))) if loss else "n/a"])
    return Section("fit-roughness", f"Apparent roughness ({scene.name})",
                   (f"pbrcheck fit-roughness {scene.name} --size {st.fitrough_size} --preset P: each object's "
                     f"roughness in the differentiable reference fitted to the preset's image: a scan of "
                     f"the loss (MSE of log(1 + x) tone-mapped images, linearized at the preset's image; "
                     f"unbiased) over roughness picks the start and a range, then Adam (lr 0.01 -> 0.002, "
                     f"mean of the last 10 of {st.fitrough_iterations} steps) refines within the range. r* > r: the preset looks rougher than its "
                     f"material; r* < r: sharper. The range (bars; brackets in the table) spans the "
                     f"roughness values this image size and sample count cannot tell apart: wide where "
                     f"roughness only moves a weak specular (dielectrics, low roughness). Against the "
                     f"reference itself (48 px metal sphere, 8-degree sun) r* is within 0.013 of the truth "
                    f"for r in [0.15, 0.8], 0.045 below (docs/research.md). File: research/fit_roughness.json."),
                   [Table("Mean r* per material roughness [hull of the objects' ranges]",
                          ["preset", "roughness r", "r* (metals)", "r* (dielectrics)",
                           "final loss (tone-mapped MSE, mean)"], rows)],
                   [{"title": "Apparent against material roughness", "src": f"research/{plot}"}])


def _r_star(objs: list[ApparentRoughness]) -> str:
    """Mean r* of some objects and the hull of their ranges, e.g. ``0.213 [0.15, 0.27]``."""
    if not objs:
        return "n/a"
    txt = _fmt(float(np.mean([o.apparent_roughness for o in objs])))
    rng = [o.range for o in objs if o.range]
    if rng:
        txt += f" [{min(r[0] for r in rng):.3g}, {max(r[1] for r in rng):.3g}]"
    return txt


def energy_section(out_dir: Path, *, preset: str = "default", st: ResearchSettings = ResearchSettings(),
                   progress: bool = False, context: renderers.RenderContext = renderers.DIRECT) -> Section:
    """``pbrcheck energy``: every energy compensation against the reference's random walk (albedo
    grid, furnace and spheres images against both references)."""
    res = _energy.run_energy(samples=st.energy_samples, scenes=st.energy_scenes, preset=preset,
                             options=dict(st.options), spp=st.energy_spp, size=st.energy_size, out_dir=out_dir,
                             progress=progress, context=context)
    paths = _energy.write_energy(res, out_dir)
    t_sum = Table(f"Directional albedo (specular, grey F0) against the random walk: {len(res.roughness)} roughness "
                  f"x {len(res.f0)} F0 x {len(res.nov)} n.v, {res.samples} walks each",
                  ["compensation", "max abs error", "mean abs error", "mean signed error", "worst (r, F0, n.v)"],
                  [[x.compensation, _fmt(x.max_abs), _fmt(x.mean_abs), _fmt(x.mean_signed),
                    f"{x.worst['roughness']:.3g}, {x.worst['f0']:.3g}, {x.worst['nov']:.3g}: {_fmt(x.worst['error'])}"]
                   for x in res.summaries])
    t_rough = Table("Max |albedo error| per roughness (over F0 and n.v)",
                    ["roughness", *[x.compensation for x in res.summaries]],
                    [[f"{r:.3g}", *[_fmt(x.max_abs_per_roughness[i]) for x in res.summaries]]
                     for i, r in enumerate(res.roughness)])
    metrics = _energy.IMAGE_METRICS
    t_img = Table(f"Images ({preset}, {st.energy_spp}-spp references, height {st.energy_size}): against the "
                  f"random_walk reference | against the single-scattering reference",
                  ["scene", "render", *[f"{m} (walk)" for m in metrics], *[f"{m} (single)" for m in metrics]],
                  [[r.scene, r.compensation, *[_fmt(r.vs_random_walk.get(m)) if r.vs_random_walk else "-" for m in metrics],
                    *[_fmt(r.vs_single.get(m)) if r.vs_single else "-" for m in metrics]] for r in res.images])
    tables = [t_sum, t_rough, t_img]
    fr = [r for r in res.images if r.sphere_means]
    if fr:
        tables.append(Table("Furnace: mean radiance of each sphere (white metal in a white environment: 1 is exact)",
                            ["render", *[f"sphere {k}" for k in range(len(fr[0].sphere_means))]],
                            [[r.compensation, *[_fmt(v) for v in r.sphere_means]] for r in fr]))
    images = [{"title": "Albedo against the random walk", "src": f"research/{paths['plot'].name}"}]
    images += [{"title": f"{r.scene}: {r.compensation}", "src": f"research/{r.png}"} for r in res.images if r.png]
    return Section("energy", "Multiple scattering: energy compensations against the random walk",
                   (f"pbrcheck energy --samples {st.energy_samples} --spp {st.energy_spp} --size {st.energy_size}: "
                    f"the truth is the reference's multiple-scattering random walk (Heitz et al. 2016, "
                    f"[brdf] multiscatter = random_walk). Albedo: each compensation's formula (pbrcheck/energy.py) "
                    f"on the exact DFG terms, against the walk's mean throughput. Images: the real-time preset "
                    f"with each energy_compensation against both references; an engine's 'error' against the "
                    f"single-scattering reference is partly the reference's missing physics. Lowest mean "
                    f"albedo error: {res.best()}. Files: research/energy.json, energy.md, energy.png."),
                   tables, images)


def research_sections(scene_name: str, out_dir: Path, presets: list[str], *, report_spp: int,
                      st: ResearchSettings = ResearchSettings(), progress: bool = False,
                      context: renderers.RenderContext = renderers.DIRECT) -> list[Section]:
    """The research sections for ``scene_name`` (files under ``out_dir``; renders in ``context``);
    ``energy`` is scene-independent."""
    return [make() for _, make in research_parts(scene_name, out_dir, presets, report_spp=lambda: report_spp,
                                                 st=st, progress=progress, context=context)]


def research_parts(scene_name: str, out_dir: Path, presets: list[str], *, report_spp: Callable[[], int],
                   st: ResearchSettings = ResearchSettings(), progress: bool = False,
                   context: renderers.RenderContext = renderers.DIRECT) -> list[tuple[str, Callable[[], Section]]]:
    """The research sections as (stage name, a function that builds the section), in order: the
    report runs each as a stage of its own (:mod:`compare.report.stages`). ``report_spp()``: the
    report's reference spp, asked when the LOD fit's section is built. The first creates ``out_dir``."""
    kw = {"st": st, "progress": progress, "context": context}
    def fit_lod() -> Section:
        out_dir.mkdir(parents=True, exist_ok=True)
        return fit_lod_section(scene_name, out_dir, report_spp=report_spp(), **kw)

    return [("research: fit-lod", fit_lod),
            ("research: explain", lambda: explain_section(scene_name, out_dir, **kw)),
            ("research: fit-roughness", lambda: fit_roughness_section(scene_name, out_dir, presets, **kw)),
            ("research: energy", lambda: energy_section(out_dir, **kw))]


__all__ = ["ResearchSettings", "research_parts", "research_sections", "fit_lod_section", "explain_section", "fit_roughness_section",
           "energy_section"]
