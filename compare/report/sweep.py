"""Speed against error: render every combination of real-time options, compare each with the
reference, tabulate precompute time, frame time and every metric, and plot the Pareto front.

``precompute_s`` and ``frame_s`` come from the real-time image's ``timings`` metadata (pass name ->
seconds), split by :func:`compare.timings.split_timings`. :data:`DEFAULT_SWEEP` and
:func:`default_sweep`: the report's sweep over the main cost knobs, one at a time.
:func:`approximation_groups`: the asset approximations of :mod:`compare.approximations` (specular_aa,
msaa, supersample, occlusion texture, specular_occlusion, horizon_occlusion), each swept against the
reference mode that is its truth (``pbrcheck sweep SCENE --approximations``).
"""

from __future__ import annotations

import contextlib
import csv
import io
import itertools
import math
from pathlib import Path

from pbrcheck.atomic import write_text_atomic
from pbrcheck.errors import PbrcheckError
from pbrcheck.fmt import csv_cell
from pbrcheck.jsonio import write_json_atomic
from pbrcheck.progress import Progress
from pbrcheck.gltf_objects import AssetOptions
from realtime.registry import IRRADIANCES
from pbrcheck.scene import load_scene

from .. import renderers
from ..approximations import TRUTHS
from ..corpus import renderlist
from ..lobes import LOBE_NAMES, lobe_families, lobe_variants, scene_lobes
from ..corpus.scheduler import open_executor, parse_scheduler
from ..maps import pyplot, save_figure
from ..metrics import METRICS, compare_images
from ..timings import FRAME_KEYS, TOTAL_KEYS, image_timings, split_timings, timed_on, timed_on_label  # noqa: F401  (re-exported)
from ..verdict_spp import MIN_REFERENCE_SPP

class SweepError(PbrcheckError):
    """A malformed ``--vary`` argument."""


def _value(s: str):
    s = s.strip()
    low = s.lower()
    if low in ("true", "false"):
        return low == "true"
    for conv in (int, float):
        try:
            return conv(s)
        except ValueError:
            pass
    return s


def parse_vary(items: list[str]) -> dict[str, list]:
    """``["a=1,2", "b=x,y"]`` -> ``{"a": [1, 2], "b": ["x", "y"]}`` (ints, floats, booleans parsed)."""
    out: dict[str, list] = {}
    for it in items or []:
        key, sep, vals = it.partition("=")
        key = key.strip()
        values = [v for v in vals.split(",") if v.strip()]
        if not sep or not key or not values:
            raise SweepError(f"--vary {it!r}: expected KEY=V1,V2,...")
        if key in out:
            raise SweepError(f"--vary {key}: given twice")
        out[key] = [_value(v) for v in values]
    if not out:
        raise SweepError("--vary: at least one KEY=V1,V2,... is needed")
    return out


def pareto_front(points: list[tuple[float, float]]) -> list[int]:
    """Indices of the points no other point beats in both coordinates (both minimised), by x."""
    idx = [i for i, (x, y) in enumerate(points) if x is not None and y is not None
           and math.isfinite(x) and math.isfinite(y)]
    front = []
    for i in idx:
        xi, yi = points[i]
        dominated = any((points[j][0] <= xi and points[j][1] <= yi) and (points[j][0] < xi or points[j][1] < yi)
                        for j in idx if j != i)
        if not dominated:
            front.append(i)
    return sorted(front, key=lambda i: points[i][0])


def plot_speed_error(path: Path, rows: list[dict], label_key, title: str = "") -> Path:
    """2 x 2 scatter: (precompute, frame time) x (relmse, flip_mean), Pareto fronts marked; the time
    axes name the GL renderer and clock of the rows (:func:`timed_on_label`)."""
    plt = pyplot()
    on = timed_on_label(rows)  # the speed axis names the GL renderer (and clock) it was timed on
    fig, axes = plt.subplots(2, 2, figsize=(10, 7.5))
    for (ci, tkey), (ri, mkey) in itertools.product(enumerate(("precompute_s", "frame_s")),
                                                    enumerate(("relmse", "flip_mean"))):
        ax = axes[ri][ci]
        pts = [(r.get(tkey), r.get(mkey)) for r in rows]
        ok = [i for i, (x, y) in enumerate(pts) if x is not None and y is not None]
        if not ok:
            ax.text(0.5, 0.5, "no timings", ha="center", va="center", transform=ax.transAxes)
            continue
        ax.scatter([pts[i][0] for i in ok], [pts[i][1] for i in ok], s=18, color="tab:blue", zorder=2)
        for i in ok:
            ax.annotate(label_key(rows[i]), pts[i], fontsize=6, xytext=(3, 3), textcoords="offset points")
        front = pareto_front(pts)
        if front:
            ax.plot([pts[i][0] for i in front], [pts[i][1] for i in front], "-o", color="tab:red",
                    ms=6, mfc="none", label="Pareto front", zorder=3)
            ax.legend(fontsize=7)
        ax.set_xlabel(tkey.replace("_s", " time (s)") + (f"\n{on}" if on else ""), fontsize=8 if on else None)
        ax.set_ylabel(mkey)
        if all(pts[i][1] > 0 for i in ok):
            ax.set_yscale("log")
        ax.grid(alpha=0.3)
    if title:
        fig.suptitle(title)
    save_figure(fig, path)  # atomically
    return path


#: The report's default sweep over the main cost knobs: each entry is varied alone around the
#: first preset (a product of all of them would be hundreds of renders). ``runtime_samples`` only
#: matters with runtime importance sampling, so it is swept together with ``ibl = "runtime"``.
DEFAULT_SWEEP = (
    [{"prefilter_samples": n} for n in (64, 256, 1024)]
    + [{"cube_size": n} for n in (64, 128, 256)]
    + [{"lut_size": n} for n in (16, 32, 64)]
    + [{"lut_format": f} for f in ("f16", "f32")]
    + [{"irradiance": m} for m in IRRADIANCES.names]
    + [{"ibl": "runtime", "runtime_samples": n} for n in (16, 64)]
)


def default_sweep(spec: renderers.RendererSpec) -> list[dict]:
    """:data:`DEFAULT_SWEEP` less the entries the renderer ``spec`` rejects or that repeat ``spec`` itself."""
    if spec.external:  # a renderer without these options: no sweep
        return []
    out, seen = [], [spec.options]
    for combo in DEFAULT_SWEEP:
        try:
            opts = spec.with_options(**combo).options
        except PbrcheckError:  # an option this renderer does not have
            continue
        if opts not in seen:
            out.append(combo)
            seen.append(opts)
    return out


def lobe_combos(spec: renderers.RendererSpec, scene) -> list[dict]:
    """``--lobes``: one option dict per other real-time form of each lobe ``scene``'s objects carry
    (:func:`compare.lobes.lobe_variants`, read from the real-time registry: a family joins once the
    renderer takes it as an option). Raises :class:`SweepError` where the scene has no lobe or the
    renderer takes none of its lobes' forms as an option (an external one takes none)."""
    used = scene_lobes(scene)
    if not used:
        raise SweepError(f"sweep --lobes: scene {scene.name!r} has no object with a glTF PBR extension lobe "
                         f"({', '.join(LOBE_NAMES.values())})")
    out = lobe_variants(spec, scene)
    if not out:
        fams = [f"{f.switch} ({'option ' + f.option if f.option else 'not an option yet'})"
                for f in lobe_families() if f.extension in used]
        raise SweepError(f"sweep --lobes: renderer {spec.text} takes none of the forms of "
                         f"{', '.join(LOBE_NAMES[e] for e in used)} as an option: {', '.join(fams) or 'no family'}")
    return out


def combinations(vary: dict[str, list]) -> list[dict]:
    """Every combination of the varied options (their product), as option dicts."""
    keys = list(vary)
    return [dict(zip(keys, combo)) for combo in itertools.product(*(vary[k] for k in keys))]


def approximation_groups() -> list[tuple[str, list[dict]]]:
    """``[(reference mode, option dicts)]``: the rows of :data:`compare.approximations.TRUTHS`, the
    options under every row of a mode included, raster pipeline."""
    return [(mode, [{**base, **opts, "pipeline": "raster"} for _, opts in rows]) for mode, (rows, base) in TRUTHS.items()]


def sweep_rows(scene, ref, combos: list[dict], *, spec: renderers.RendererSpec, progress=None,
               executor=None, context: renderers.RenderContext = renderers.DIRECT) -> list[dict]:
    """Render and compare each option dict of ``combos`` (variants of renderer ``spec``, rendered in
    ``context``); one row each. With an ``executor`` (``--scheduler``) the renders and comparisons run
    as its tasks (:func:`compare.corpus.renderlist.sweep_metrics`)."""
    preset = spec.text
    variants = [spec.with_options(**o) for o in combos]
    if executor is not None:
        res = renderlist.sweep_metrics(executor, scene, ref, variants, progress, context=context)
        return [{"preset": preset, "options": o, "precompute_s": r["precompute_s"], "frame_s": r["frame_s"],
                 **r["timed_on"], **r["metrics"]} for o, r in zip(combos, res)]
    rows = []
    for options, variant in zip(combos, variants):
        img = renderers.render_under_test(scene, variant, progress=False, context=context)
        cmp = compare_images(ref, img, scene=scene, noise=False, flip_cache=context.flip_cache)
        pre, frame = image_timings(img)
        rows.append({"preset": preset, "options": options, "precompute_s": pre, "frame_s": frame,
                     **timed_on(img), **cmp.metrics})
        if progress is not None:
            progress.update(1)
    return rows


def write_table(out_dir: Path, rows: list[dict], keys: list[str], stem: str = "sweep") -> dict[str, Path]:
    """Write the sweep rows as ``stem.csv`` and ``stem.json`` in ``out_dir`` (atomically)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    csv_path, json_path = out_dir / f"{stem}.csv", out_dir / f"{stem}.json"
    truth = any("truth" in r for r in rows)   # --approximations: each row's reference mode
    cols = ["preset", *(["truth"] if truth else []), *keys, "precompute_s", "frame_s", *METRICS]
    first = 1 + truth + len(keys)
    buf = io.StringIO(newline="")
    w = csv.writer(buf)
    w.writerow(cols)
    for r in rows:
        w.writerow([csv_cell(c) for c in (r["preset"], *([r.get("truth", "")] if truth else []),
                                          *(r["options"].get(k, "") for k in keys),
                                          *("" if r.get(c) is None else r[c] for c in cols[first:]))])
    write_text_atomic(csv_path, buf.getvalue())
    write_json_atomic(json_path, rows)
    return {"csv": csv_path, "json": json_path}


def run_sweep(scene_arg: str, vary: dict[str, list] | None, *, preset: str = "default", out_dir: Path,
              spp: int = 64, progress: bool = True, also: list[str] | None = None,
              scheduler: str | None = None, mode: str = "local", approximations: bool = False,
              assets: AssetOptions | None = None, lobes: bool = False) -> dict[str, Path]:
    """Render the reference (``mode``) and every combination of ``vary`` over ``preset``; write the
    table and the speed-against-error plot (``pareto.png``) to ``out_dir``; returns their paths.
    ``approximations``: the asset approximations instead (:func:`approximation_groups`), each group
    against a reference in its own mode, a ``truth`` column, one plot per mode (``pareto_MODE.png``).
    ``also``: further renderers (presets or ``ext:NAME``) measured as they are, one row each, on the
    same plot (against the first reference). ``scheduler`` (``local:N``, ``tcp://HOST:PORT``): the
    combinations run there (:mod:`compare.corpus.scheduler`). ``lobes``: also the preset's other
    forms of the lobes the scene's objects carry (:func:`lobe_combos`), one at a time, with the
    preset itself (``vary`` may then be None).

    Raises
    ------
    SweepError
        ``spp`` below 2; ``vary`` None without ``approximations`` or ``lobes``; ``lobes`` on a scene
        without lobes or a renderer that takes none of their forms as an option; ``OptionError`` for
        an unknown option or value (before any render).
    """
    if spp < MIN_REFERENCE_SPP:
        raise SweepError(f"--spp must be >= {MIN_REFERENCE_SPP} (the reference's variance needs two samples), "
                         f"got {spp}")
    if vary is None and not approximations and not lobes:
        raise SweepError("sweep: --vary KEY=V1,V2,..., --approximations or --lobes is needed")
    scene = load_scene(scene_arg, assets)
    base = renderers.RendererSpec.parse(preset)  # the renderer names, parsed once
    # vary {}: the preset as it is (one row); None: no --vary rows (only the approximations)
    groups = ([] if vary is None else [(mode, combinations(vary))]) + (approximation_groups() if approximations else [])
    if lobes:   # the lobe forms join the --vary rows (or make them, with the preset itself first)
        more = lobe_combos(base, scene)
        groups = [(mode, groups[0][1] + more)] + groups[1:] if vary is not None else [(mode, [{}] + more)] + groups
    for _, combos in groups:  # every option and value is checked before rendering
        for combo in combos:
            # this GL's limits too (msaa), before any render
            renderers.check_backend_limits(base.with_options(**combo))
    also = [renderers.RendererSpec.parse(other) for other in also or []]
    for other in also:
        renderers.check_backend_limits(other)
    n = sum(len(c) + 1 for _, c in groups) + len(also)
    spec = parse_scheduler(scheduler) if scheduler else None
    rows = []
    with Progress(f"sweep {scene.name}", total=n, enabled=progress) as p, \
            (open_executor(spec) if spec else contextlib.nullcontext()) as ex:
        for i, (m, combos) in enumerate(groups):
            ref = renderers.render_reference(scene, spp=spp, mode=m, use_cache=True, progress=False)
            p.update(1, f"reference ({m})")
            new = sweep_rows(scene, ref, combos, spec=base, progress=p, executor=ex)
            if i == 0:
                for other in also:
                    new += sweep_rows(scene, ref, [{}], spec=other, progress=p, executor=ex)
            if approximations:
                for r in new:
                    r["truth"] = m
            rows += new
    keys = (list(vary) if vary and not approximations and not lobes
            else sorted({k for _, c in groups for o in c for k in o}))
    paths = write_table(Path(out_dir), rows, keys)

    def label(r):
        return (",".join(f"{k}={r['options'][k]}" for k in keys if k in r["options"] and k != "pipeline")
                or "preset") if r["preset"] == preset else r["preset"]

    for m in dict.fromkeys(r.get("truth", mode) for r in rows):
        name = f"pareto_{m}" if approximations else "pareto"
        paths["plot" if name == "pareto" else f"plot_{m}"] = plot_speed_error(
            Path(out_dir) / f"{name}.png", [r for r in rows if r.get("truth", mode) == m], label,
            f"{scene.name}: speed against error ({preset} + variations, against {m})")
    return paths
