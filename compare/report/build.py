"""Static, offline HTML accuracy report: ``pbrcheck report``.

Layout of ``OUT/``: ``index.html`` and one folder per scene with PNGs (tone-mapped reference and
real-time images, FLIP and relative-error maps, plots) plus ``metrics.json``. The page uses no
external URL: styles and the small scripts (reference/real-time slider, an image-decode check that
sets ``data-images-ok`` on ``<body>``) are inline.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import jinja2

from pbrcheck import __version__
from pbrcheck.atomic import write_text_atomic
from pbrcheck.errors import PbrcheckError
from pbrcheck.fmt import TABLE_DIGITS, format_value
from pbrcheck.gltf_scene import RASTER_MISSING, split_presets
from pbrcheck.jsonio import write_json_atomic
from pbrcheck.progress import Progress
from pbrcheck.scene import builtin_scene_names, builtin_scene_path, load_scene

from .. import renderers
from ..corpus import renderlist
from ..corpus.scheduler import open_executor, parse_scheduler
from ..maps import pyplot, save_figure, write_flip_png, write_rel_png, write_tonemapped
from ..metrics import METRICS, compare_images, map_cache
from ..research.diagnose import diagnose
from ..research.fit_roughness import fit_scene
from ..research.hardcases import SPP_CAP as HARDCASE_SPP_CAP
from ..research.hardcases import TABLE_METRICS, run_hardcases, write_hardcases
from ..verdict_spp import VerdictSpp, reference_for_verdict
from .references import references_sections
from .research_sections import ResearchSettings, research_sections
from .section import Section, Table
from .runlog import RUN_FILE, RunLog, recording, run_section, stage
from .summary import furnace_scene, furnace_section, summary_section
from .summary import timed_on as timed_on_text
from .sweep import (combinations, image_timings, parse_vary, plot_speed_error, sweep_rows, timed_on,
                    write_table)

#: Most samples per pixel of diagnose's scene-space re-renders for an external renderer (10 re-renders
#: per renderer and scene; the hypotheses' errors are orders of magnitude above 64-spp noise, and
#: diagnose subtracts the re-renders' own variance).
DIAGNOSE_SPP = 64
#: Reference spp fractions for the convergence study (error of a lower-spp render with another
#: seed against the full reference).
CONVERGENCE_FRACTIONS = (1 / 16, 1 / 8, 1 / 4, 1 / 2)
#: The reference renderer needs two samples per pixel for its variance channels.
MIN_REFERENCE_SPP = 2


def _convergence_spps(spp: int) -> list[int]:
    return sorted({int(spp * f) for f in CONVERGENCE_FRACTIONS if MIN_REFERENCE_SPP <= int(spp * f) < spp})


#: Seed of the convergence renders: different from the reference's so their noise is independent.
CONVERGENCE_SEED = 1
#: Reference metadata not shown under provenance (internal bookkeeping).
PROVENANCE_SKIP = {"cache_key", "cache"}
#: The report's default sweep over the main cost knobs: each entry is varied alone around the
#: first preset (a product of all of them would be hundreds of renders). ``runtime_samples`` only
#: matters with runtime importance sampling, so it is swept together with ``ibl = "runtime"``.
DEFAULT_SWEEP = (
    [{"prefilter_samples": n} for n in (64, 256, 1024)]
    + [{"cube_size": n} for n in (64, 128, 256)]
    + [{"lut_size": n} for n in (16, 32, 64)]
    + [{"lut_format": f} for f in ("f16", "f32")]
    + [{"irradiance": m} for m in ("convolution", "sh9")]
    + [{"ibl": "runtime", "runtime_samples": n} for n in (16, 64)]
)


def default_sweep(preset: str = "default") -> list[dict]:
    """:data:`DEFAULT_SWEEP` less the entries the renderer rejects or that repeat ``preset`` itself."""
    try:
        base = renderers.resolve_options(preset, {})
    except PbrcheckError:  # a renderer without these options: no sweep
        return []
    out = []
    for combo in DEFAULT_SWEEP:
        try:
            opts = renderers.resolve_options(preset, combo)
        except PbrcheckError:  # an option this renderer does not have
            continue
        if opts != base and opts not in [renderers.resolve_options(preset, c) for c in out]:
            out.append(combo)
    return out


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in name)


def plot_materials(path: Path, scene, per_preset: dict[str, dict]) -> str | None:
    """Error against roughness (mean over the grid's metallic rows) and against metallic (mean over
    roughness columns), for relmse and flip_mean, one line per preset."""
    if not scene.grids:
        return None
    plt = pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(10, 7))
    for gi, g in enumerate(scene.grids):
        rows, cols, first = g["rows"], g["columns"], g["first_id"]
        for preset, objs in per_preset.items():
            for mi, metric in enumerate(("relmse", "flip_mean")):
                val = lambda r, c: (objs.get(first + r * cols + c) or {}).get(metric)  # noqa: E731
                rough = [scene.objects[first + c].material.roughness for c in range(cols)]
                met = [scene.objects[first + r * cols].material.metallic for r in range(rows)]
                by_r = [_mean([val(r, c) for r in range(rows)]) for c in range(cols)]
                by_m = [_mean([val(r, c) for c in range(cols)]) for r in range(rows)]
                lab = preset if len(scene.grids) == 1 else f"{preset} (grid {gi})"
                axes[mi][0].plot(rough, by_r, "-o", ms=3, label=lab)
                axes[mi][1].plot(met, by_m, "-o", ms=3, label=lab)
    for mi, metric in enumerate(("relmse", "flip_mean")):
        for j, xl in enumerate(("roughness", "metallic")):
            ax = axes[mi][j]
            ys = [y for line in ax.get_lines() for y in line.get_ydata() if math.isfinite(y)]
            if ys and min(ys) > 0:
                ax.set_yscale("log")
            ax.set_xlabel(xl)
            ax.set_ylabel(f"{metric} (mean over the other axis)")
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7)
    return save_figure(fig, path)


def _mean(xs):
    xs = [x for x in xs if x is not None and math.isfinite(x)]
    return sum(xs) / len(xs) if xs else float("nan")


def plot_ndotv(path: Path, per_preset: dict[str, list]) -> str | None:
    """Error against NdotV (binned), one line per preset; the PNG's name, or None without bins."""
    if not any(per_preset.values()):
        return None
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8))
    for preset, bins in per_preset.items():
        xs = [(b["lo"] + b["hi"]) / 2 for b in bins if b["pixels"]]
        for ax, metric in zip(axes, ("relmse", "flip_mean")):
            ax.plot(xs, [b["metrics"][metric] for b in bins if b["pixels"]], "-o", ms=3, label=preset)
    for ax, metric in zip(axes, ("relmse", "flip_mean")):
        ax.set_xlabel("NdotV")
        ax.set_ylabel(metric)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    return save_figure(fig, path)


def plot_convergence(path: Path, conv: list[dict], top_spp: int, floor: float | None,
                     preset_mse: dict[str, float]) -> str | None:
    """MSE of lower-spp references against the report's reference (log-log) with the variance
    prediction, the noise floor and each preset's MSE; the PNG's name, or None without data."""
    if not conv:
        return None
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    spps = [c["spp"] for c in conv]
    ax.loglog(spps, [max(c["mse"], 1e-30) for c in conv], "-o", label=f"MSE of n spp vs {top_spp} spp")
    if all(c["expected"] is not None for c in conv):
        ax.loglog(spps, [c["expected"] for c in conv], "--", color="gray",
                  label="expected from variances (unbiased)")
    if floor is not None:
        ax.axhline(floor, color="tab:green", lw=1, label=f"noise floor of the {top_spp}-spp reference")
    for i, (p, mse) in enumerate(preset_mse.items()):
        if mse is not None and mse > 0:
            ax.axhline(mse, color=f"C{(i + 3) % 10}", ls=":", lw=1, label=p)
    ax.set_xlabel("reference samples per pixel")
    ax.set_ylabel("MSE over valid pixels")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    return save_figure(fig, path)


TEMPLATE = r"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<title>pbrcheck accuracy report</title>
<style>
body{font-family:system-ui,sans-serif;margin:1.5em;color:#222;max-width:1500px}
table{border-collapse:collapse;font-size:13px;margin:0.5em 0}
td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}
th{background:#f0f0f0} td.l,th.l{text-align:left}
.noise{color:#777}
.row{display:flex;flex-wrap:wrap;gap:12px;align-items:flex-start}
figure{margin:0} figcaption{font-size:12px;color:#555}
.img{width:300px;image-rendering:pixelated}
.cmp{position:relative;width:300px;display:inline-block}
.cmp img{display:block;width:300px;image-rendering:pixelated}
.cmp img.top{position:absolute;left:0;top:0;clip-path:inset(0 calc(100% - var(--pos,50%)) 0 0)}
.cmp input{width:300px}
.plot{max-width:100%}
code{font-size:12px}
</style></head>
<body data-images-ok="pending" data-js-errors="0">
<script>
(function(){var n=0;window.addEventListener('error',function(){n++;document.body.setAttribute('data-js-errors',String(n));},true);
window.addEventListener('load',function(){var imgs=document.images,bad=0;for(var i=0;i<imgs.length;i++){if(!(imgs[i].complete&&imgs[i].naturalWidth>0))bad++;}
document.body.setAttribute('data-images-ok',bad===0?'yes':'no:'+bad);document.body.setAttribute('data-image-count',String(imgs.length));});})();
</script>
<h1>pbrcheck accuracy report</h1>
<p>Generated {{ generated }} by pbrcheck {{ version }}. Metrics are over valid pixels (fully covered
object pixels in both images) and RGB; definitions in <code>docs/compare.md</code>. A grey value
(&asymp;) is within what the reference's own Monte Carlo noise could explain. Images are shown through
each renderer's own display transform where its preset has one (tone map, exposure: analytic_mobile
uses article 002's ACES fit), otherwise (and for the reference) through a filmic curve; every metric
is computed on linear radiance, before any display transform.</p>
{% macro section(x) %}
<h2 id="{{ x.id }}">{{ x.title }}</h2>
<p>{{ x.note }}</p>
{% for t in x.tables %}{% if t.caption %}<h3>{{ t.caption }}</h3>{% endif %}
<table><tr>{% for h in t.headers %}<th class="l">{{ h }}</th>{% endfor %}</tr>
{% for row in t.rows %}<tr>{% for c in row %}<td class="l">{{ c }}</td>{% endfor %}</tr>{% endfor %}</table>
{% endfor %}
{% for im in x.images %}<h3>{{ im.title }}</h3><img class="plot" src="{{ im.src }}" alt="{{ im.title }}">
{% endfor %}
{% endmacro %}
{% for x in top|default([]) %}{{ section(x) }}{% endfor %}
{% for s in scenes %}
<h2 id="{{ s.id }}">Scene {{ s.name }}</h2>
<p>{{ s.description }}</p>
{% for r in s.presets %}
<h3>{{ s.name }} / preset {{ r.preset }}</h3>
<div class="row">
<figure><div class="cmp" style="--pos:50%"><img src="{{ r.rt_png }}" alt="{{ r.preset }}"><img class="top" src="{{ s.ref_png }}" alt="reference">
<input type="range" min="0" max="100" value="50" aria-label="reference / renderer under test split"
 oninput="this.parentNode.style.setProperty('--pos',this.value+'%')"></div>
<figcaption>slider: reference (left) / renderer under test (right)</figcaption></figure>
<figure><img class="img" src="{{ s.ref_png }}" alt="reference"><figcaption>reference ({{ s.spp }} spp)</figcaption></figure>
<figure><img class="img" src="{{ r.rt_png }}" alt="{{ r.preset }}"><figcaption>under test: {{ r.preset }}</figcaption></figure>
<figure><img class="img" src="{{ r.flip_png }}" alt="FLIP map"><figcaption>HDR-FLIP (0..1, magma)</figcaption></figure>
<figure><img class="img" src="{{ r.rel_png }}" alt="relative error"><figcaption>|t-r|/(r+0.01), max RGB (0..1, inferno)</figcaption></figure>
</div>
{% if r.diagnosis %}<p>Convention check (<code>pbrcheck diagnose</code>): {{ r.diagnosis }}{% if r.diagnosis_json %} (<a href="{{ r.diagnosis_json }}">every hypothesis</a>){% endif %}.</p>{% endif %}
{% endfor %}
<h3>Metrics per preset</h3>
<table><tr><th class="l">preset</th>{% for m in metric_names %}<th>{{ m }}</th>{% endfor %}<th>precompute (s)</th><th>frame (s)</th><th>valid / edge / bg px</th></tr>
{% for r in s.presets %}<tr><td class="l">{{ r.preset }}</td>{% for m in metric_names %}<td{% if r.within[m] %} class="noise" title="within reference noise"{% endif %}>{% if r.within[m] %}&asymp;{% endif %}{{ fmt(r.metrics[m]) }}</td>{% endfor %}
<td>{{ fmt(r.precompute) }}</td><td>{{ fmt(r.frame) }}</td><td>{{ r.pixels.valid }} / {{ r.pixels.edge }} / {{ r.pixels.background }}</td></tr>{% endfor %}
</table>
{% if s.material_rows %}<h3>Metrics per glTF material</h3>
<table><tr><th class="l">renderer</th><th class="l">material</th>{% for m in material_metrics %}<th>{{ m }}</th>{% endfor %}<th>pixels</th></tr>
{% for r in s.material_rows %}<tr><td class="l">{{ r.preset }}</td><td class="l">{{ r.material }}</td>{% for m in material_metrics %}<td>{{ fmt(r.metrics[m]) }}</td>{% endfor %}<td>{{ r.pixels }}</td></tr>{% endfor %}
</table><p>bias: sum(test - reference) / sum(reference) over the material's pixels (signed).</p>{% endif %}
{% if s.noise_floor is not none %}<p>Reference noise floor (mean variance over valid pixels): {{ fmt(s.noise_floor) }}.</p>{% endif %}
{% if s.verdict %}<p>Reference spp for a trusted verdict (noise floor &ge; {{ s.verdict.factor }}x below the smallest error): {{ s.verdict.provenance() }}{% if s.verdict.noise_limited %} <strong>noise-limited</strong>{% endif %}.</p>{% endif %}
{% for p in s.plots %}<h3>{{ p.title }}</h3><img class="plot" src="{{ p.src }}" alt="{{ p.title }}">{% if p.get("note") %}<p>{{ p.note }}</p>{% endif %}
{% endfor %}
{% if s.sweep_rows %}<h3>Sweep table</h3><table><tr><th class="l">options</th><th>precompute (s)</th><th>frame (s)</th><th>relmse</th><th>flip_mean</th></tr>
{% for r in s.sweep_rows %}<tr><td class="l"><code>{{ r.label }}</code></td><td>{{ fmt(r.precompute_s) }}</td><td>{{ fmt(r.frame_s) }}</td><td>{{ fmt(r.relmse) }}</td><td>{{ fmt(r.flip_mean) }}</td></tr>{% endfor %}
</table><p>Also as <a href="{{ s.id }}/sweep.csv">CSV</a> and <a href="{{ s.id }}/sweep.json">JSON</a>.</p>{% endif %}
<h3>Provenance</h3>
<table>{% for k, v in s.provenance %}<tr><th class="l">{{ k }}</th><td class="l"><code>{{ v }}</code></td></tr>{% endfor %}</table>
{% endfor %}
{% for x in extras %}{{ section(x) }}{% endfor %}
</body></html>
"""


def _fmt(v) -> str:
    return format_value(v, TABLE_DIGITS)


#: The metrics the report's per-material table lists (the summary's ``materials``; ``bias`` is
#: compare.metrics.material_bias, the relative signed bias).
MATERIAL_METRICS = ("relmse", "flip_mean", "bias")


def material_rows(preset: str, summary: dict) -> list[dict]:
    """The per-material table's rows of one renderer (glTF asset scenes; empty otherwise):
    ``{"preset", "material", "pixels", "metrics": {MATERIAL_METRICS}}``."""
    return [{"preset": preset, "material": m["material"], "pixels": m["pixels"],
             "metrics": {k: m["metrics"].get(k) for k in MATERIAL_METRICS}}
            for m in summary.get("materials", [])]


@dataclass(frozen=True)
class ReportSettings:
    """What every scene section renders: the renderers under test, the reference spp, the sweep
    (``vary``: option -> values, every combination; else the default sweep when ``sweep``) and the
    reference convergence study."""

    presets: list[str]
    spp: int
    vary: dict | None = None
    convergence: bool = True
    sweep: bool = True
    executor: object = None  # --scheduler: renders of presets and sweep run as its tasks
    #: Largest reference spp the trusted-verdict rule may choose (compare.verdict_spp); ``spp`` is the
    #: least; None: as many as fit in ``DEFAULT_TIME_BUDGET_S`` of rendering per scene.
    spp_cap: int | None = None


@dataclass
class PresetResult:
    """One renderer under test on one scene: its metrics, noise flags, timings and image files."""

    preset: str
    metrics: dict
    pixels: dict
    within: dict
    precompute: float | None
    frame: float | None
    rt_png: str
    flip_png: str
    rel_png: str
    mse: float
    timed_on: str = ""
    space: str = "linear"
    diagnosis: str = ""       # external renderers: pbrcheck diagnose's verdict line
    diagnosis_json: str = ""  # ... and its table (JSON, relative to the report)


@dataclass
class SceneSection:
    """One scene of the report (:data:`TEMPLATE`'s ``scenes``)."""

    id: str
    name: str
    description: str
    spp: object
    ref_png: str
    presets: list[PresetResult]
    plots: list[dict]
    provenance: list[tuple[str, str]]
    noise_floor: float | None
    sweep_rows: list[dict]
    verdict: VerdictSpp | None = None
    material_rows: list[dict] = field(default_factory=list)   # glTF assets: renderer x material


def _provenance(scene, ref) -> list[tuple[str, str]]:
    src = scene.source
    if scene.name in builtin_scene_names() and src == str(builtin_scene_path(scene.name)):
        src = f"built-in scene {scene.name} (pbrcheck/scenes/{scene.name}.toml)"  # no machine paths
    out = [("scene source", src)]
    for k in sorted(ref.meta):  # scene hash, spp, mode, seed, variant, versions, seconds...
        if k not in PROVENANCE_SKIP:
            out.append((f"reference {k}", ref.meta[k]))
    return out


def _measure_preset(scene, ref, preset: str, sd: Path, sid: str, img=None) -> tuple[PresetResult, object, object]:
    """Render ``preset`` (unless its image ``img`` is given), compare it, write its images; returns its
    result, the comparison and image."""
    img = img if img is not None else renderers.render_under_test(scene, preset, None, progress=False)
    cmp = compare_images(ref, img, scene=scene, ref_name="reference", test_name=preset if renderers.is_external(preset) else f"real-time {preset}")
    p = _safe(preset)
    write_tonemapped(sd / f"rt_{p}.png", img.rgb, img.meta_json("options", None) if "options" in img.meta else None)
    write_flip_png(sd / f"flip_{p}.png", cmp)
    write_rel_png(sd / f"rel_{p}.png", cmp)
    pre, frame = image_timings(img)
    noise = cmp.summary["noise"]
    res = PresetResult(preset, cmp.metrics, cmp.summary["pixels"],
                       {m: bool(noise and noise["within_noise"].get(m)) for m in METRICS}, pre, frame,
                       f"{sid}/rt_{p}.png", f"{sid}/flip_{p}.png", f"{sid}/rel_{p}.png",
                       (cmp.metrics["rmse"] or 0.0) ** 2, timed_on_text(img.meta), cmp.summary["space"])
    if renderers.is_external(preset):
        res.diagnosis, res.diagnosis_json = _diagnose(scene, ref, img, sd, sid, p, res.space)
    return res, cmp, img


def _diagnose(scene, ref, img, sd: Path, sid: str, p: str, space: str) -> tuple[str, str]:
    """Run :func:`compare.research.diagnose.diagnose` on an external renderer's image (scene-space
    hypotheses re-rendered at :data:`DIAGNOSE_SPP` at most); returns its line and its JSON's path."""
    if space != "linear":
        return "not run: the renderer's output is display-referred (png-srgb)", ""
    d = diagnose(ref, img, scene, spp=min(int(ref.meta.get("spp", DIAGNOSE_SPP)), DIAGNOSE_SPP))
    write_json_atomic(sd / f"diagnose_{p}.json", d)
    return d.line, f"{sid}/diagnose_{p}.json"


def _convergence(scene, ref, spp: int, prog) -> list[dict]:
    """MSE of lower-spp renders (another seed) against the reference, with the variance prediction."""
    conv = []
    for s in _convergence_spps(spp):
        low = renderers.render_reference(scene, spp=s, seed=CONVERGENCE_SEED, use_cache=True, progress=False)
        c = compare_images(ref, low, noise=False, flip=False, itp=False)  # reads mse and relmse only
        lv = low.variance
        exp = None
        if lv is not None and ref.variance is not None:
            exp = float(lv[c.valid].mean() + ref.variance[c.valid].mean())
        conv.append({"spp": s, "mse": (c.metrics["rmse"] or 0.0) ** 2, "relmse": c.metrics["relmse"],
                     "expected": exp})
        prog.update(1, f"{scene.name}: convergence {s} spp")
    return conv


def _scene_section(scene_arg, out_dir: Path, st: ReportSettings, prog) -> SceneSection:
    """Render the reference and every renderer of ``st`` on one scene, compare, plot, write files."""
    scene = load_scene(scene_arg)
    presets, skipped = split_presets(scene, st.presets)  # asset scenes: external renderers only
    if skipped:
        if not presets:
            raise PbrcheckError(f"report: {scene.source}: every preset skipped ({', '.join(skipped)}): {RASTER_MISSING}")
        st = replace(st, presets=presets, vary=None, sweep=False)
    sid = _safe(scene.name)
    sd = out_dir / sid
    sd.mkdir(parents=True, exist_ok=True)
    # The renderers under test first: the reference's spp is chosen so that its noise floor sits
    # NOISE_FLOOR_FACTOR below the smallest of their errors (compare.verdict_spp), at most spp_cap.
    with stage(f"{scene.name}: renderers under test"):
        if st.executor is not None:  # --scheduler: the renders run as the executor's tasks
            images = dict(zip(st.presets, renderlist.render_images(st.executor, scene,
                                                                   [(p, None) for p in st.presets])))
        else:
            images = {p: renderers.render_under_test(scene, p, None, progress=False) for p in st.presets}
    with stage(f"{scene.name}: reference"):
        ref, verdict = reference_for_verdict(scene, list(images.values()), spp=st.spp, cap=st.spp_cap)
    prog.update(1, f"{scene.name}: reference ({verdict.spp} spp)")
    write_tonemapped(sd / "reference.png", ref.rgb)
    results, objs, bins, speed_rows, dump, mat_rows = [], {}, {}, [], {}, []
    provenance = _provenance(scene, ref)
    provenance.append(("reference spp rule", verdict.provenance()))
    if skipped:
        provenance.append(("presets skipped", f"{', '.join(skipped)}: {RASTER_MISSING}"))
    for a in getattr(scene, "assets", ()):
        provenance.append((f"glTF asset {Path(a.path).name}", f"sha256 {a.content_hash}; extensions used: "
                           f"{', '.join(a.asset.extensions_used) or 'none'}; ignored: "
                           f"{', '.join(a.asset.extensions_ignored) or 'none'}"))
    noise_floor = None
    for preset in st.presets:
        with stage(f"{scene.name}: comparisons and diagnose"):
            res, cmp, img = _measure_preset(scene, ref, preset, sd, sid, images[preset])
        if cmp.summary["noise"] is not None:
            noise_floor = cmp.summary["noise"]["mean_variance"]
        results.append(res)
        objs[preset] = {o["id"]: o["metrics"] for o in cmp.summary["objects"]}
        bins[preset] = cmp.summary["ndotv"]
        speed_rows.append({"preset": preset, "options": {}, "precompute_s": res.precompute, "frame_s": res.frame,
                           **timed_on(img), **cmp.metrics})
        dump[preset] = {**cmp.summary, "options": img.meta_json("options", None) if "options" in img.meta else None,
                        "timings": img.meta_json("timings", None) if "timings" in img.meta else None}
        provenance.append((f"{preset} options", img.meta.get("options", "")))
        mat_rows += material_rows(preset, cmp.summary)   # glTF assets: per material
        if img.meta_json("shader", None):  # a shader hook file: its path, hash and hooks
            provenance.append((f"{preset} shader hooks", img.meta["shader"]))
        prog.update(1, f"{scene.name}: {preset}")
    plots = []
    m = plot_materials(sd / "materials.png", scene, objs)
    if m:
        plots.append({"title": "Error against roughness and metallic (sphere grid)", "src": f"{sid}/{m}"})
    n = plot_ndotv(sd / "ndotv.png", bins)
    if n:
        plots.append({"title": "Error against NdotV", "src": f"{sid}/{n}"})
    # Sweep over the cost knobs (from the first preset).
    combos = combinations(st.vary) if st.vary else (default_sweep(st.presets[0]) if st.sweep else [])
    sweep_table = []
    if combos:
        with stage(f"{scene.name}: sweep"):
            srows = sweep_rows(scene, ref, combos, preset=st.presets[0], progress=prog, executor=st.executor)
        write_table(sd, srows, sorted({k for c in combos for k in c}))
        for r in srows:
            label = ",".join(f"{k}={v}" for k, v in r["options"].items())
            sweep_table.append({**r, "label": label})
            speed_rows.append({**r, "preset": label})
    sp = plot_speed_error(sd / "speed.png", speed_rows, lambda r: r["preset"],
                          f"{scene.name}: speed against error")
    plots.append({"title": "Speed against error (presets" + (" and sweep" if sweep_table else "") + ")",
                  "src": f"{sid}/{sp.name}", "note": "Red: Pareto front (no other point is both faster and more accurate)."})
    conv = []
    if st.convergence:
        with stage(f"{scene.name}: convergence"):
            conv = _convergence(scene, ref, verdict.spp, prog)
    if conv:
        cp = plot_convergence(sd / "convergence.png", conv, verdict.spp, noise_floor, {r.preset: r.mse for r in results})
        if cp:
            plots.append({"title": "Reference convergence", "src": f"{sid}/{cp}",
                          "note": "If the reference is converged, the renderers' MSE lines lie far above its noise floor."})
    write_json_atomic(sd / "metrics.json", {"scene": scene.name, "presets": dump, "convergence": conv,
                                            "sweep": sweep_table, "reference_spp": verdict.to_dict()}, indent=1)
    return SceneSection(sid, scene.name, scene.description, ref.meta.get("spp", st.spp), f"{sid}/reference.png",
                        results, plots, provenance, noise_floor, sweep_table, verdict, mat_rows)


def hardcases_section(out_dir: Path, presets: list[str] | None = None, progress: bool = False) -> Section:
    """The hard-case report section (rendered small: 32 px, 16 spp, 64^2 cubes)."""
    settings = {"size": 32, "spp": 16, "cube_size": 64, "presets": presets}
    rows = run_hardcases(size=32, spp=16, cube_size=64, presets=presets, progress=progress)
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
            out.append(f"{r.case} {v.spp}" + (" noise-limited" if v.noise_limited else ""))
    return ", ".join(out) or "n/a"


def build_report(scenes: list[str], *, presets: list[str] | None = None, out_dir: Path,
                 spp: int = 64, vary: list[str] | None = None, convergence: bool = True,
                 spp_cap: int | None = None,
                 sweep: bool = True, progress: bool = True, hardcases: bool = False,
                 research: bool = False, extras: list[Section] | None = None, furnace: bool = True,
                 scheduler: str | None = None, cache: bool = True) -> Path:
    """Render, compare and write ``out_dir/index.html``; returns its path.

    ``spp`` is the least reference spp of a scene; more are rendered (powers of two, at most
    ``spp_cap``; default: as many as render in :data:`compare.verdict_spp.DEFAULT_TIME_BUDGET_S`
    seconds per scene at the measured speed) until the reference's noise
    floor is :data:`compare.verdict_spp.NOISE_FLOOR_FACTOR` times below the smallest error of the
    presets against it, else the section says "noise-limited"; the rule's outcome is in the
    provenance table and ``metrics.json`` (``reference_spp``).
    ``hardcases``: add the hard-case section (:mod:`compare.hardcases`, 32 px, 16 spp, 64^2 cubes;
    its JSON and table go to ``out_dir/hardcases``). ``research``: add the LOD fit (before / after),
    the error decomposition and the apparent-roughness sections for the first scene
    (:mod:`compare.report.research_sections`; files under ``out_dir/research``). ``extras``: further
    :class:`~compare.report.section.Section` s. The page opens with the summary (one row per
    renderer and scene) and, with ``furnace``, the white furnace per renderer
    (:mod:`compare.report.summary`), then every external renderer against both the single-scattering
    and the random-walk reference (:mod:`compare.report.references`). ``scheduler`` (``local:N``, ``tcp://HOST:PORT``): the presets'
    and the sweep's renders run there (:mod:`compare.corpus.renderlist`). ``cache``: real-time renders
    come from the content-addressed cache where their scene, options, shader and code are unchanged
    (:func:`compare.renderers.realtime_cache`; their timings are those measured when rendered), and
    HDR-FLIP maps from the disk where both images are unchanged (:func:`compare.metrics.map_cache`).

    Raises
    ------
    PbrcheckError
        No preset, ``spp`` below 2, an unknown scene, preset or swept option: raised before anything
        is rendered or written."""
    if presets is None:
        presets = renderers.preset_names()
    if not presets:
        raise PbrcheckError("report: no preset to compare")
    if spp < MIN_REFERENCE_SPP:
        raise PbrcheckError(f"report: --spp must be >= {MIN_REFERENCE_SPP}, got {spp}")
    vary_d = parse_vary(vary) if vary else None
    # Validate everything before rendering or writing: scenes, presets, swept options.
    for s in scenes:
        load_scene(s)
    for p in presets:
        renderers.resolve_options(p, {})
    for combo in combinations(vary_d) if vary_d else []:
        renderers.resolve_options(presets[0], combo)
    spec = parse_scheduler(scheduler) if scheduler else None
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    n_conv = len(_convergence_spps(spp)) if convergence else 0  # at the least spp (progress only)
    n_sweep = len(combinations(vary_d)) if vary_d else (len(default_sweep(presets[0])) if sweep else 0)
    total = len(scenes) * (1 + len(presets) + n_conv + n_sweep) + (len(presets) if furnace else 0)
    total += len(scenes) * sum(renderers.is_external(p) for p in presets)  # both references per ext:NAME
    sections = []
    # The external renderers' images, in the order the sections use them, rendered in a background
    # thread while this process renders the presets, references and maps.
    ext = [p for p in presets if renderers.is_external(p)]
    prefetch = [(load_scene(s), p) for s in scenes for p in ext] + ([(furnace_scene(), p) for p in ext] if furnace else [])
    if research:  # fit-roughness's targets (the first scene at its fit size)
        prefetch += [(fit_scene(load_scene(scenes[0]), ResearchSettings().fitrough_size), p) for p in ext]
    extras = list(extras or [])
    with recording(RunLog()) as log, renderers.realtime_cache(cache), map_cache(cache), \
            renderers.prefetch_external(prefetch if spec is None else []):
        with Progress("report", total=total, enabled=progress) as prog, \
                (open_executor(spec) if spec else contextlib.nullcontext()) as ex:
            st = ReportSettings(list(presets), spp, vary_d, convergence, sweep, executor=ex,
                                spp_cap=None if spp_cap is None else int(spp_cap))
            for s in scenes:
                sections.append(_scene_section(s, out_dir, st, prog))
            with stage("summary and furnace"):
                top = [summary_section(sections)] + ([furnace_section(list(presets), spp, prog)] if furnace else [])
            with stage("both references"):
                top += references_sections(scenes, sections, list(presets), out_dir, prog)  # ext:NAME vs both
        extras += _research_and_hardcases(scenes, out_dir, presets, sections, research, hardcases, progress)
    run = log.to_dict()
    write_json_atomic(out_dir / RUN_FILE, run, indent=1)
    extras.append(run_section(run))
    env = jinja2.Environment(autoescape=True, undefined=jinja2.StrictUndefined)
    page = env.from_string(TEMPLATE).render(
        scenes=sections, top=top, extras=extras, metric_names=METRICS, material_metrics=MATERIAL_METRICS,
        fmt=_fmt, version=__version__,
        generated=_dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"))
    index = out_dir / "index.html"
    write_text_atomic(index, page)
    return index


def _research_and_hardcases(scenes, out_dir: Path, presets, sections, research: bool, hardcases: bool,
                            progress: bool) -> list[Section]:
    extras = []
    if research:
        # at the first scene's trusted-verdict spp (the reference its sections compare against)
        extras += research_sections(scenes[0], out_dir / "research", presets, report_spp=sections[0].verdict.spp,
                                    progress=progress)
    if hardcases:
        # The shipped shaders' robustness: real-time presets only (an external engine's hard cases
        # cost a browser start each; `pbrcheck hardcases --presets ext:NAME` runs them on their own).
        with stage("hard cases"):
            extras.append(hardcases_section(out_dir / "hardcases",
                                            [p for p in presets if not renderers.is_external(p)], progress))
    return extras


__all__ = ["build_report", "default_sweep"]
