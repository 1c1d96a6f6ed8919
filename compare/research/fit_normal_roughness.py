"""``pbrcheck fit-normal-roughness``: the GGX roughness to add per normal-map mip level so the raster
image matches the reference, against Toksvig's closed form.

Method (fit-lod's: a dense scan of renders, per-group minima refined by a parabola; no AD)
------------------------------------------------------------------------------------------
1. The target: the scene's ``local`` reference (spp chosen as fit-lod chooses it,
   :func:`compare.verdict_spp.reference_for_verdict`), or a given image (``target``: a test's known answer).
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
   that lowers the rendered scene relmse.
5. Evaluation by render: ``none``; ``specular_aa = toksvig`` (per pixel, the closed form);
   ``toksvig_table`` and ``lean_table`` (the closed forms' per-level means over the normal maps'
   texels, :func:`pbrcheck.normal_roughness.level_closed_forms`, as tables through the same hook);
   ``specular_aa = prefiltered``; ``fitted`` (the written hook file).

Writes ``out`` (JSON: the table, the closed forms per level, every row's relmse) and ``out`` with suffix
``.glsl`` (the ``hook_specular_aa`` file: ``--shader FILE.glsl`` / ``shader=FILE.glsl``).

API: :func:`run_fit_normal_roughness`, :func:`table_markdown`, :data:`SCAN_STEP` (results:
:class:`compare.research.results.FitNormalRoughnessResult`, :class:`~compare.research.results.LevelFit`).
"""

from __future__ import annotations

import hashlib
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


def run_fit_normal_roughness(scene: Scene, *, preset: str = "default", options: dict | None = None, spp: int = 64,
                             size: int | None = None, out: Path, scan_step: float = SCAN_STEP, refine_steps=REFINE_STEPS,
                             target: Image | None = None, spp_cap: int | None = DEFAULT_SPP_CAP,
                             progress: bool = False,
                             context: renderers.RenderContext = renderers.DIRECT) -> FitNormalRoughnessResult:
    """Group, scan, fit and evaluate (module docstring); writes ``out`` (JSON) and its ``.glsl``.

    Parameters
    ----------
    scene : Scene
        A scene with normal-mapped glTF objects (rendered by the raster pipeline).
    preset, options : str, dict
        The renderer under test and its overrides (no ``shader``: the fit writes the hook).
    spp, spp_cap : int
        Least and most reference samples per pixel (fit-lod's rule).
    size : int, optional
        Image height (default: the scene's own).
    out : Path
        The JSON to write (the GLSL goes next to it).
    scan_step : float
        Step of ``sqrt(increment)`` on [0, 1].
    refine_steps : sequence of float
        Stage 2's steps of ``sqrt(increment)`` (empty: the best start as is).
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
        A ``shader`` option, no normal-mapped object, a target of another size, or no level with pixels.
    """
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
    us = np.arange(0.0, 1.0 + 1e-9, scan_step)
    none_img = renderers.render_under_test(scene, preset, {**base, "specular_aa": "none"}, context=context)
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
    with tempfile.TemporaryDirectory(prefix="pbrcheck-nr-") as tmpd, \
            Progress("fit-normal-roughness", total=n_levels + 1 + len(us) + 3 + 2 * len(refine_steps) * n_levels + 5, enabled=progress) as prog:
        tmp = Path(tmpd)
        plain = renderers.render_under_test(scene, preset, {**base, "shader": _constant_hook(tmp, 0.0)},
                                            context=context)
        prog.update(1, "groups")
        change = []
        for k in range(n_levels):
            img = renderers.render_under_test(scene, preset, {**base, "shader": _hook(
                tmp, f"level_{k}", f"return abs(normal_lod - {float(k):.1f}) < 0.5 ? 1.0 : roughness;")},
                context=context)
            change.append(np.abs(img.rgb.astype(np.float64) - plain.rgb).sum(axis=-1))
            prog.update(1, f"group level {k}")
        change = np.stack(change)
        level = np.where(change.max(axis=0) > 0.0, change.argmax(axis=0), -1)
        level = np.where(valid, level, -1)
        curves = []
        for u in us:
            img = renderers.render_under_test(scene, preset, {**base, "shader": _constant_hook(tmp, float(u * u))},
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
            o = {**base, "shader": _write(tmp, NormalRoughnessTable(tuple(float(x) for x in entries)))}
            err = float(_rel_map(ref, renderers.render_under_test(scene, preset, o, context=context))[valid].mean())
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
        table = NormalRoughnessTable(tuple(float(x) for x in cur))
        evals = {"none": {"specular_aa": "none"}, "toksvig": {"specular_aa": "toksvig"},
                 "toksvig_table": {"shader": _write(tmp, NormalRoughnessTable(tuple(tok)))},
                 "lean_table": {"shader": _write(tmp, NormalRoughnessTable(tuple(lean)))},
                 "prefiltered": {"specular_aa": "prefiltered"}, "fitted": {"shader": _write(tmp, table)}}
        rel = {}
        for name, o in evals.items():
            img = none_img if name == "none" else renderers.render_under_test(scene, preset, {**base, **o},
                                                                              context=context)
            rel[name] = float(_rel_map(ref, img)[valid].mean())
            prog.update(1, f"evaluate {name}")
    glsl = out.with_suffix(".glsl")
    write_text_atomic(glsl, table.glsl(FITTED_SOURCE))
    result = FitNormalRoughnessResult(
        scene=scene.name, preset=preset, options=base, size=[scene.camera.width, scene.camera.height],
        target=target_name, metric="relmse over valid pixels", levels=rows, fitted=table.to_json(),
        start=start, start_relmse=start_err, relmse=rel, reference_spp=verdict.to_dict() if verdict is not None else None, glsl=str(glsl))
    write_json_atomic(out, result)
    return result


def _write(tmp: Path, table: NormalRoughnessTable) -> str:
    """``table``'s hook file, named by its text's hash: every table is written as the final one is, so
    a table rendered twice (a start, a refinement kept, the evaluation) is one program and one render
    of the caches."""
    text = table.glsl(FITTED_SOURCE)
    p = tmp / f"table_{hashlib.sha256(text.encode()).hexdigest()[:16]}.glsl"
    p.write_text(text)
    return str(p)


def table_markdown(result: FitNormalRoughnessResult) -> str:
    """Per level the fitted increment and the closed forms; every row's relmse."""
    lines = [f"{result.scene} ({result.size[0]} x {result.size[1]}), target: {result.target}; stage 2 from "
             f"{result.start} (" + ", ".join(f"{k} {v:.5g}" for k, v in result.start_relmse.items()) + ")", "",
             "| level | pixels | fitted alpha^2 increment | per-level optimum | Toksvig (mean) | LEAN (mean) |",
             "| --- | --- | --- | --- | --- | --- |"]
    for r in result.levels:
        opt = "-" if r.optimum is None else f"{r.optimum:.4g}"
        lines.append(f"| {r.level} | {r.pixels} | {r.fitted:.4g} | {opt} | {r.toksvig:.4g} | {r.lean:.4g} |")
    lines += ["", "| normal filtering | relmse |", "| --- | --- |"]
    for k, v in result.relmse.items():
        lines.append(f"| {k} | {v:.5g} |")
    return "\n".join(lines) + "\n"
