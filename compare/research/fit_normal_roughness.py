"""``pbrcheck fit-normal-roughness``: the GGX roughness to add per normal-map mip level so the filtered
image matches the reference, against Toksvig's closed form.

Two methods (``method``): ``ad`` (default), an inverse fit by Dr.Jit AD inside the reference, and
``scan``, fit-lod's scan of raster renders. The output is the same (the table, its GLSL hook, the
raster evaluation rows).

Method ``ad`` (the fit isolates normal filtering)
-------------------------------------------------
1. The truth: the scene's ``local`` reference with the full-resolution normal map (spp chosen as
   fit-lod chooses it, :func:`compare.verdict_spp.reference_for_verdict`), or a given image (``target``).
2. The model (:mod:`reference.normal_filter`): the same integrator and scene, but each sample's
   normal-map lookup reads the box-filtered mip chain trilinearly at the level the raster pipeline
   reads there (GL's isotropic LOD of the pixel's analytic footprint, less ``log2(supersample)``:
   ``textureQueryLod``'s, the ``normal_lod`` the hook gets), the filtered normal renormalised, and its
   GGX ``alpha^2`` widened by the table: ``alpha'^2 = min(alpha^2 + v(lod), 1)``, ``v`` linear between
   levels (:class:`pbrcheck.normal_roughness.NormalRoughnessTable`'s definition), ``table = u^2``.
3. ``u`` is fitted by Adam on the relative MSE against the truth with the scan's pixel weighting (per
   pixel ``mean over channels (I - T)^2 / (T^2 + REL_EPS)``, averaged over the valid pixels:
   :func:`compare.metrics.pixel_classes` of the truth and the raster image; ``T`` in the weights is the
   reference image, the ``T`` in the difference the truth rendered on the step's own seed, paired
   with the model's render: far less noise, and no bias from a fixed noisy image; a given
   ``target`` is used as is), :data:`ITERATIONS` steps of
   :data:`FIT_SPP` samples, the learning rate decaying from :data:`LR` to :data:`LR_FINAL`, the table the
   mean of the last :data:`AVERAGE_LAST` iterates. Start: Toksvig's per-level table, each entry at
   least :data:`START_INCREMENT` (so an entry that must be 0 has to be fitted down to it).
   Both sides use the same integrator and differ only in the normal map's filtering and the
   widening: the fitted table measures normal filtering alone, not the split-sum, horizon or
   tessellation errors of the real-time image (the scan fit absorbs those: on the panel it fitted
   0.33 - 1.0 where Toksvig gives <= 0.07).
   A level no pixel reads (``|lod - k| >= 1`` everywhere, lod clamped to the table) has no gradient:
   it takes its nearest populated neighbour's entry (``pixels`` 0). ``model_relmse``: the model's
   relmse against the truth with no widening (``filtered``: the filtering error the table corrects),
   the closed forms' tables and the fitted one; unbiased in the renders' noise: two independent
   renders ``a``, ``b`` of :data:`EVAL_SPP`, ``mean (a - t_a)(b - t_b) / (T^2 + REL_EPS)`` with ``t_a``,
   ``t_b`` the truth rendered on the same seeds (paired: ``E[(a - t_a)(b - t_b)] = (E[I] - E[t])^2``),
   ``T`` the reference (the weights); a given target: ``t_a = t_b = T``.

Method ``scan`` (fit-lod's: a dense scan of raster renders, per-group minima refined by a parabola)
----------------------------------------------------------------------------------------------------
1. The target: as ``ad``'s truth.
2. Pixels are grouped by the normal-map level they read: per level k one render with a
   ``hook_specular_aa`` that sets roughness 1 where ``|lod - k| < 0.5``; a pixel belongs to the level
   whose render changes it most (supersampled pixels mix levels: the dominant one counts).
3. The scan: renders with a constant increment ``alpha^2 += u^2`` for ``u`` on ``[0, 1]`` in
   :data:`SCAN_STEP` steps (a hook as well). Per level its pixels' relative MSE is a function of u;
   the minimum on the scan is refined by a parabola through its neighbours (fit-lod's
   ``_parabola_min``) and the table's entry is ``u*^2``. A level without pixels takes its nearest
   fitted neighbour's entry (``pixels`` 0 in the JSON says so).
4. Stage 2 (fit-lod's second stage: the scene error itself): the per-level optima are a start, not
   the answer (a level's pixels read fractional levels, the table interpolates between two entries).
   The table of the lowest rendered scene relmse among the per-level optima, Toksvig's and LEAN's
   per-level tables (so the fit cannot end worse than either closed form's table) is refined one
   populated level at a time, steps of :data:`REFINE_STEPS` in ``sqrt(increment)``, keeping a step
   that lowers the rendered scene relmse. The raster image's other errors (split sum, horizon) enter
   the fit: the table absorbs what roughness can.

Evaluation (both methods) by raster render: ``none``; ``specular_aa = toksvig`` (per pixel, the closed
form); ``toksvig_table`` and ``lean_table`` (the closed forms' per-level means over the normal maps'
texels, :func:`pbrcheck.normal_roughness.level_closed_forms`, as tables through the same hook);
``specular_aa = prefiltered``; ``fitted`` (the written hook file).

Writes ``out`` (JSON: the table, the closed forms per level, every row's relmse) and ``out`` with suffix
``.glsl`` (the ``hook_specular_aa`` file: ``--shader FILE.glsl`` / ``shader=FILE.glsl``).

API: :func:`run_fit_normal_roughness`, :func:`table_markdown`, :data:`METHODS`, :data:`SCAN_STEP`,
:data:`ITERATIONS`, :data:`FIT_SPP` (results:
:class:`compare.research.results.FitNormalRoughnessResult`, :class:`~compare.research.results.LevelFit`).
"""

from __future__ import annotations

import hashlib
import json
import tempfile
from pathlib import Path

import numpy as np

from pbrcheck.atomic import write_text_atomic
from pbrcheck.errors import PbrcheckError
from pbrcheck.exr import Image
from pbrcheck.jsonio import write_json_atomic
from pbrcheck.normal_roughness import NormalRoughnessTable, level_closed_forms
from pbrcheck.progress import Progress
from pbrcheck.scene import Scene

from .. import renderers
from ..metrics import REL_EPS, pixel_classes
from ..verdict_spp import DEFAULT_SPP_CAP, RESEARCH_PROBE, reference_for_verdict
from .fit_lod import _parabola_min
from .results import FitNormalRoughnessResult, LevelFit

#: Scan step of ``u = sqrt(alpha^2 increment)`` on [0, 1]: 33 renders; with the parabola refinement
#: the optimum's u within about a hundredth.
SCAN_STEP = 1.0 / 32.0
#: The written hook's header names its maker.
FITTED_SOURCE = "pbrcheck fit-normal-roughness"
#: Stage 2's steps of ``sqrt(increment)`` per level (each level tries +h then -h, keeps an improvement).
REFINE_STEPS = (1.0 / 16.0, 1.0 / 64.0)
#: The fit's methods (module docstring); the first is the default.
METHODS = ("ad", "scan")
#: ad: Adam steps, samples per pixel of each step's primal and adjoint renders.
ITERATIONS = 80
FIT_SPP = 8
#: ad: learning rate of ``u = sqrt(increment)``, decaying geometrically to LR_FINAL (the last steps
#: move u by about that much: the table's resolution near 0.1 is 2 u LR_FINAL ~ 0.001).
LR = 0.03
LR_FINAL = 0.003
#: ad: the table is the mean of the last iterates (their Monte Carlo jitter averages out).
AVERAGE_LAST = 20
#: ad: least starting increment per level (Toksvig's mean can be 0: u = 0 is a stationary point of
#: u^2, from which no gradient moves; and a level that must end at 0 is then fitted down to it).
START_INCREMENT = 0.01
#: ad: samples per pixel of the model's evaluation renders (model_relmse).
EVAL_SPP = 64


def _hook(tmp: Path, name: str, body: str) -> str:
    p = tmp / f"{name}.glsl"
    p.write_text("float hook_specular_aa(float roughness, float normal_length, float normal_lod) {\n"
                 f"    {body}\n}}\n")
    return str(p)


def _constant_hook(tmp: Path, v: float) -> str:
    """The one-level table of increment ``v`` (every level the same): the written hook's own GLSL,
    harness-compared with its numpy twin (tests/test_fit_normal_roughness.py)."""
    p = tmp / f"const_{v:.9g}.glsl"
    p.write_text(NormalRoughnessTable((float(v),)).glsl(FITTED_SOURCE + ", scan"))
    return str(p)


def _rel_map(ref: Image, img: Image) -> np.ndarray:
    r, t = ref.rgb.astype(np.float64), img.rgb.astype(np.float64)
    return ((t - r) ** 2 / (r * r + REL_EPS)).mean(axis=-1)


def _normal_maps(scene: Scene) -> list[np.ndarray]:
    from realtime.raster import draw_items
    out, seen = [], set()
    for it in draw_items(scene):
        nm = it.textures.get("normal")
        if nm is not None and id(nm[0]) not in seen:
            seen.add(id(nm[0]))
            out.append(nm[0].linear(False))
    return out


def run_fit_normal_roughness(scene: Scene, *, method: str = "ad", preset: str = "default",
                             options: dict | None = None, spp: int = 64, size: int | None = None, out: Path,
                             scan_step: float = SCAN_STEP, refine_steps=REFINE_STEPS, iterations: int = ITERATIONS,
                             fit_spp: int = FIT_SPP, start: list | None = None, target: Image | None = None,
                             spp_cap: int | None = DEFAULT_SPP_CAP, progress: bool = False,
                             context: renderers.RenderContext = renderers.DIRECT) -> FitNormalRoughnessResult:
    """Fit (``method`` ``ad`` or ``scan``) and evaluate (module docstring); writes ``out`` (JSON) and
    its ``.glsl``.

    Parameters
    ----------
    scene : Scene
        A scene with normal-mapped glTF objects (rendered by the raster pipeline).
    method : str
        ``ad`` (the filtered reference fitted by AD) or ``scan`` (raster renders scanned).
    preset, options : str, dict
        The renderer under test and its overrides (no ``shader``: the fit writes the hook).
    spp, spp_cap : int
        Least and most reference samples per pixel (fit-lod's rule).
    size : int, optional
        Image height (default: the scene's own).
    out : Path
        The JSON to write (the GLSL goes next to it).
    scan_step : float
        scan: step of ``sqrt(increment)`` on [0, 1].
    refine_steps : sequence of float
        scan: stage 2's steps of ``sqrt(increment)`` (empty: the best start as is).
    iterations, fit_spp : int
        ad: Adam steps and the samples per pixel of each.
    start : list of float, optional
        ad: the starting table (default: Toksvig's, floored at :data:`START_INCREMENT`).
    target : Image, optional
        The image to match instead of the reference (same camera).
    progress : bool
        Show progress.

    Returns
    -------
    FitNormalRoughnessResult

    Raises
    ------
    PbrcheckError
        An unknown method, a ``shader`` option, no normal-mapped object, a target of another size, no
        level with pixels; ad: ``anisotropy`` > 1 or ``normal_sampling = lod0`` (the model reads the
        normal map as isotropic trilinear filtering does), a start of another length.
    """
    if method not in METHODS:
        raise PbrcheckError(f"fit-normal-roughness: method: expected one of {', '.join(METHODS)}, found {method!r}")
    if method == "ad" and (int(iterations) < 1 or int(fit_spp) < 1):
        raise PbrcheckError(f"fit-normal-roughness: iterations and fit_spp: expected >= 1, found {iterations} "
                            f"and {fit_spp}")
    base = dict(options or {})
    if base.get("shader"):
        raise PbrcheckError("fit-normal-roughness: options: shader: the fit writes the hook; start without one")
    base.pop("specular_aa", None)
    if size is not None:
        scene = scene.with_camera(width=max(8, int(round(size * scene.camera.width / scene.camera.height))),
                                  height=int(size))
    maps = _normal_maps(scene)
    if not maps:
        raise PbrcheckError(f"fit-normal-roughness: {scene.name}: no object has a normal map")
    n_levels = max(max(m.shape[:2]).bit_length() for m in maps)
    closed = [level_closed_forms(m, n_levels) for m in maps]
    tok = [float(np.mean([c["toksvig"][k] for c in closed])) for k in range(n_levels)]
    lean = [float(np.mean([c["lean"][k] for c in closed])) for k in range(n_levels)]
    spec = renderers.RendererSpec.parse(preset, base)  # once; every render below a variant of it
    none_img = renderers.render_under_test(scene, spec.with_options(specular_aa="none"), context=context)
    used = json.loads(none_img.meta.get("options", "{}"))
    if method == "ad":
        if float(used.get("anisotropy", 1.0)) > 1.0 or used.get("normal_sampling", "mip") != "mip":
            raise PbrcheckError("fit-normal-roughness: options: method ad models isotropic trilinear normal "
                                "filtering: anisotropy must be 1 and normal_sampling mip, found "
                                f"{used.get('anisotropy')} and {used.get('normal_sampling')}")
        if start is not None and len(start) != n_levels:
            raise PbrcheckError(f"fit-normal-roughness: start: expected {n_levels} increments (the normal map's "
                                f"levels), found {len(start)}")
    verdict = None
    if target is None:
        ref, verdict = reference_for_verdict(scene, [none_img], spp=spp, cap=spp_cap, mode="local",
                                             metric="relmse", probe=RESEARCH_PROBE, progress=progress)
        target_name = f"reference local, {verdict.spp} spp"
    else:
        ref = target
        target_name = str(target.meta.get("renderer", "given image"))
        if ref.shape != none_img.shape:
            raise PbrcheckError(f"fit-normal-roughness: target: expected {none_img.shape}, found {ref.shape}")
    valid, _, _ = pixel_classes(ref, none_img)
    out = Path(out)
    n_fit = (iterations + 5) if method == "ad" else (n_levels + 1 + len(np.arange(0.0, 1.0 + 1e-9, scan_step))
                                                   + 3 + 2 * len(refine_steps) * n_levels)
    extra = {}
    with tempfile.TemporaryDirectory(prefix="pbrcheck-nr-") as tmpd, \
            Progress("fit-normal-roughness", total=n_fit + 5, enabled=progress) as prog:
        tmp = Path(tmpd)
        if method == "ad":
            rows, cur, start_name, start_err, extra = _fit_ad(
                scene, ref, valid, tok, lean, supersample=int(used.get("supersample", 1)), iterations=iterations,
                fit_spp=fit_spp, start=start, paired=target is None, prog=prog)
        else:
            rows, cur, start_name, start_err = _fit_scan(scene, spec, ref, valid, tok, lean, tmp,
                                                         scan_step, refine_steps, prog, context)
        table = NormalRoughnessTable(tuple(float(x) for x in cur))
        evals = {"none": {"specular_aa": "none"}, "toksvig": {"specular_aa": "toksvig"},
                 "toksvig_table": {"shader": _write(tmp, NormalRoughnessTable(tuple(tok)))},
                 "lean_table": {"shader": _write(tmp, NormalRoughnessTable(tuple(lean)))},
                 "prefiltered": {"specular_aa": "prefiltered"}, "fitted": {"shader": _write(tmp, table)}}
        rel = {}
        for name, o in evals.items():
            img = none_img if name == "none" else renderers.render_under_test(scene, spec.with_options(**o),
                                                                              context=context)
            rel[name] = float(_rel_map(ref, img)[valid].mean())
            prog.update(1, f"evaluate {name}")
    glsl = out.with_suffix(".glsl")
    write_text_atomic(glsl, table.glsl(FITTED_SOURCE))
    result = FitNormalRoughnessResult(
        scene=scene.name, preset=preset, options=base, size=[scene.camera.width, scene.camera.height],
        target=target_name, metric="relmse over valid pixels", levels=rows, fitted=table.to_json(),
        start=start_name, start_relmse=start_err, relmse=rel,
        reference_spp=verdict.to_dict() if verdict is not None else None, glsl=str(glsl), method=method, **extra)
    write_json_atomic(out, result)
    return result


def _fit_ad(scene, ref: Image, valid, tok, lean, *, supersample: int, iterations: int, fit_spp: int, start, paired: bool,
            prog):
    """Method ``ad`` (module docstring): (rows, table, start name, {}, extra result fields)."""
    from reference.diff import load_differentiable_scene
    from reference.render import _mi
    from reference import normal_filter as nf

    mi, _ = _mi()
    n = len(tok)
    ms, _ = load_differentiable_scene(scene, spp=fit_spp)
    filters = nf.attach(ms, scene.camera, supersample, mi.Float(np.zeros(n, np.float32)))
    if not filters:
        raise PbrcheckError(f"fit-normal-roughness: {scene.name}: no reference material has a normal map")
    if max(f.levels for f in filters) != n:
        raise PbrcheckError(f"fit-normal-roughness: {scene.name}: the reference's normal maps have "
                            f"{max(f.levels for f in filters)} levels, the raster's {n}")
    lod = nf.lod_image(ms, filters)
    mapped = valid & np.isfinite(lod)
    if not mapped.any():
        raise PbrcheckError(f"fit-normal-roughness: {scene.name}: no valid pixel reads a normal map")
    x = np.clip(lod[mapped], 0.0, n - 1)
    dominant = np.rint(x).astype(int)
    populated = [bool((np.abs(x - k) < 1.0).any()) for k in range(n)]
    T = ref.rgb.astype(np.float64)
    weight = (valid[..., None] / (T * T + REL_EPS)) / (3.0 * int(valid.sum()))
    u0 = np.sqrt(np.maximum(tok, START_INCREMENT)) if start is None else np.sqrt(np.asarray(start, np.float64))
    # the reference as the truth: paired renders on each step's seed (reference.normal_filter.loss_and_gradient)
    table, losses = nf.fit_table(ms, filters, None if paired else T, weight, u0, iterations=iterations, spp=fit_spp, lr=LR,
                                 lr_final=LR_FINAL, average_last=min(AVERAGE_LAST, iterations),
                                 progress=lambda it, loss: prog.update(1, f"adam {it} loss {loss:.4g}"))
    have = [k for k in range(n) if populated[k]]
    cur = [float(table[k]) if populated[k] else float(table[min(have, key=lambda j: (abs(j - k), j))])
           for k in range(n)]
    rows = [LevelFit(k, int((dominant == k).sum()) if populated[k] else 0, cur[k], tok[k], lean[k])
            for k in range(n)]

    def model_error(entries, name):
        # unbiased in the model's noise: E[(a - T)(b - T)] = (E[I] - T)^2 for independent renders a, b
        nf.set_table(filters, mi.Float(np.sqrt(np.asarray(entries, np.float64)).astype(np.float32)))
        seeds = ((1 << 20), (1 << 20) + 1)
        a, b = (nf.render_model(ms, spp=EVAL_SPP, seed=k) for k in seeds)
        ta, tb = (nf.render_truth(ms, filters, spp=EVAL_SPP, seed=k) for k in seeds) if paired else (T, T)
        prog.update(1, f"model {name}")
        e = ((a - ta) * (b - tb) / (T * T + REL_EPS)).mean(axis=-1)
        return float(e[valid].mean())

    model = {name: model_error(t, name) for name, t in
             (("filtered", [0.0] * n), ("toksvig_table", tok), ("lean_table", lean), ("fitted", cur))}
    extra = {"model_relmse": model, "losses": [float(v) for v in losses],
             "lod": {"convention": "GL isotropic LOD of the pixel's analytic footprint at each sample's hit, "
                                   f"less log2(supersample = {supersample}); pixels: valid pixels whose centre's "
                                   "LOD (clamped to the table) rounds to the level",
                     "supersample": supersample,
                     "min": float(np.min(lod[mapped])), "max": float(np.max(lod[mapped])),
                     "median": float(np.median(lod[mapped]))}}
    name = "toksvig_table floored at %g" % START_INCREMENT if start is None else "given"
    return rows, cur, name, {}, extra


def _fit_scan(scene, spec, ref, valid, tok, lean, tmp, scan_step, refine_steps, prog, context):
    """Method ``scan`` (module docstring): (rows, table, start name, start relmse per start)."""
    n_levels = len(tok)
    us = np.arange(0.0, 1.0 + 1e-9, scan_step)
    plain = renderers.render_under_test(scene, spec.with_options(shader=_constant_hook(tmp, 0.0)), context=context)
    prog.update(1, "groups")
    change = []
    for k in range(n_levels):
        img = renderers.render_under_test(scene, spec.with_options(shader=_hook(
            tmp, f"level_{k}", f"return abs(normal_lod - {float(k):.1f}) < 0.5 ? 1.0 : roughness;")),
            context=context)
        change.append(np.abs(img.rgb.astype(np.float64) - plain.rgb).sum(axis=-1))
        prog.update(1, f"group level {k}")
    change = np.stack(change)
    level = np.where(change.max(axis=0) > 0.0, change.argmax(axis=0), -1)
    level = np.where(valid, level, -1)
    curves = []
    for u in us:
        img = renderers.render_under_test(scene, spec.with_options(shader=_constant_hook(tmp, float(u * u))),
                                          context=context)
        e = _rel_map(ref, img)
        curves.append([float(e[level == k].mean()) if (level == k).any() else float("nan")
                       for k in range(n_levels)])
        prog.update(1, f"scan u {u:.3f}")
    curves = np.asarray(curves)        # (scan, level)
    rows, fitted = [], [None] * n_levels
    for k in range(n_levels):
        npx = int((level == k).sum())
        row = LevelFit(k, npx, float("nan"), tok[k], lean[k])
        if npx:
            y = curves[:, k]
            u_opt, err = _parabola_min(us, y, int(np.nanargmin(y)))
            fitted[k] = u_opt * u_opt
            row.relmse_at_optimum, row.scan = max(err, 0.0), [float(v) for v in y]
        rows.append(row)
    have = [k for k in range(n_levels) if fitted[k] is not None]
    if not have:
        raise PbrcheckError(f"fit-normal-roughness: {scene.name}: no valid pixel reads a normal map")
    for k in range(n_levels):
        rows[k].optimum = fitted[k]
        if fitted[k] is None:
            fitted[k] = fitted[min(have, key=lambda j: (abs(j - k), j))]

    def scene_error(entries, name):
        o = spec.with_options(shader=_write(tmp, NormalRoughnessTable(tuple(float(x) for x in entries))))
        err = float(_rel_map(ref, renderers.render_under_test(scene, o, context=context))[valid].mean())
        prog.update(1, name)
        return err

    # Stage 2 (fit-lod's error objective): from the best of the per-level optima and the closed
    # forms' tables, by the scene error of renders, one level at a time (steps in sqrt(increment)).
    starts = {"per_level_optima": list(fitted), "toksvig_table": list(tok), "lean_table": list(lean)}
    start_err = {n: scene_error(t, f"start {n}") for n, t in starts.items()}
    start = min(start_err, key=start_err.get)
    cur, cur_err = list(starts[start]), start_err[start]
    for h in refine_steps:
        for k in have:
            for d in (h, -h):
                trial = list(cur)
                trial[k] = float(np.clip(np.sqrt(cur[k]) + d, 0.0, 1.0)) ** 2
                if trial[k] == cur[k]:
                    continue
                e = scene_error(trial, f"refine level {k}")
                if e < cur_err:
                    cur, cur_err = trial, e
                    break
    for k in range(n_levels):
        rows[k].fitted = float(cur[k])
    return rows, cur, start, start_err


def _write(tmp: Path, table: NormalRoughnessTable) -> str:
    """``table``'s hook file, named by its text's hash: every table is written as the final one is, so
    a table rendered twice (a start, a refinement kept, the evaluation) is one program and one render
    of the caches."""
    text = table.glsl(FITTED_SOURCE)
    p = tmp / f"table_{hashlib.sha256(text.encode()).hexdigest()[:16]}.glsl"
    p.write_text(text)
    return str(p)


def table_markdown(result: FitNormalRoughnessResult) -> str:
    """Per level the fitted increment and the closed forms; every row's relmse (ad: the model's too)."""
    if result.method == "ad":
        head = (f"{result.scene} ({result.size[0]} x {result.size[1]}), truth: {result.target}; method ad "
                f"from {result.start}, {len(result.losses or [])} Adam steps (loss {result.losses[0]:.4g} -> "
                f"{result.losses[-1]:.4g}); LOD {result.lod['min']:.2f} .. {result.lod['max']:.2f}"
                if result.losses else f"{result.scene}: method ad")
    else:
        head = (f"{result.scene} ({result.size[0]} x {result.size[1]}), target: {result.target}; method scan, "
                f"stage 2 from {result.start} (" + ", ".join(f"{k} {v:.5g}" for k, v in result.start_relmse.items())
                + ")")
    lines = [head, "",
             "| level | pixels | fitted alpha^2 increment | per-level optimum | Toksvig (mean) | LEAN (mean) |",
             "| --- | --- | --- | --- | --- | --- |"]
    for r in result.levels:
        opt = "-" if r.optimum is None else f"{r.optimum:.4g}"
        lines.append(f"| {r.level} | {r.pixels} | {r.fitted:.4g} | {opt} | {r.toksvig:.4g} | {r.lean:.4g} |")
    if result.model_relmse:
        lines += ["", "| model (filtered reference) table | relmse against the truth |", "| --- | --- |"]
        for k, v in result.model_relmse.items():
            lines.append(f"| {k} | {v:.5g} |")
    lines += ["", "| normal filtering (raster) | relmse |", "| --- | --- |"]
    for k, v in result.relmse.items():
        lines.append(f"| {k} | {v:.5g} |")
    return "\n".join(lines) + "\n"
