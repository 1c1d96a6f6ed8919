"""``pbrcheck fit-lod``: the prefiltered-map LOD each roughness wants, and a smooth mapping fitted to it.

Method
------
1. The scene's point lights are removed (they are shaded exactly, not through the prefiltered map),
   and the reference is rendered once (``local`` mode).
2. For each *chain* (the prefiltered levels baked with a built-in mapping: level L holds
   ``roughness_from_lod(L)`` of ``linear``, ``quadratic`` or ``log2``), built once, the frame is
   rendered with the real-time option ``lod_override = L`` (every object read at level L) for a
   dense scan of L over ``[0, prefilter_levels - 1]`` (:data:`LOD_STEP`).
3. Per roughness (objects grouped by their roughness: on a sphere grid, its columns) the relative MSE
   over that group's valid pixels is a function of L; its minimum on the scan is refined by a parabola
   through the three scan points around it (clamped to the bracket).
4. The smooth monotone mapping (:mod:`pbrcheck.lodmap`'s basis, non-negative coefficients) is fitted
   by :func:`compare.research.monotone_fit.fit_lod_to_error`: it minimizes the scene error the scan predicts (each
   roughness's error curve read at the mapping's LOD, weighted by its pixel count), starting from the
   NNLS fit to the optima (:func:`compare.research.monotone_fit.fit_lod_mapping`) and from NNLS fits to each
   built-in mapping's LODs, and from ``linear`` and ``quadratic`` themselves (members of the basis).
   On measured curves (noisy, with bumps at some integer levels) the closest smooth curve to the
   optima can be worse than a built-in mapping; this objective cannot be (up to the scan's
   interpolation) for ``linear`` and ``quadratic``. The chain whose fit predicts the lowest scene
   error is kept (``chain`` in the JSON; every chain's prediction is under ``chains``).
5. Every mapping is evaluated on the scene by a render: ``linear``, ``quadratic``, ``log2`` (each
   with its own chain, as the preset would render it) and ``fitted`` (on the chain it was fitted on,
   through ``lod_mapping=fitted:FILE``).

Without ``--roughness`` a scene holding a sphere grid is used as is; otherwise (or with
``--roughness``) the scene's environment lights a 4-column grid of white metal spheres with the
given roughness values (:func:`probe_scene`).
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from pbrcheck.atomic import write_text_atomic
from pbrcheck.errors import PbrcheckError
from pbrcheck.jsonio import write_json_atomic
from pbrcheck.lodmap import basis_coefficients, builtin_lod
from pbrcheck.progress import Progress
from pbrcheck.lodmap import BUILTIN_LOD_MAPPINGS
from pbrcheck.scene import Scene, scene_from_dict

from .. import renderers
from ..metrics import REL_EPS, pixel_classes
from ..verdict_spp import RESEARCH_PROBE, DEFAULT_SPP_CAP, reference_for_verdict
from .monotone_fit import fit_lod_mapping, fit_lod_to_error, predicted_error
from .results import ChainFit, FitLodResult, LodSample, MappingEval

#: Default roughness samples: 16 values on [0, 1].
DEFAULT_ROUGHNESS = tuple(float(x) for x in np.linspace(0.0, 1.0, 16))
#: LOD scan step. The error curve is smooth in L (trilinear filtering between levels); a quarter
#: level plus the parabola refinement puts the optimum within a few hundredths of a level.
LOD_STEP = 0.25
#: The chains scanned by default: every built-in mapping of the registry.
BUILTIN = BUILTIN_LOD_MAPPINGS


def probe_scene(scene: Scene, roughness, size: int) -> Scene:
    """White metal spheres at ``roughness`` (4 per row) under ``scene``'s environment, framed."""
    env = scene.to_dict()["environment"]
    n = len(roughness)
    cols = min(4, n)
    rows = int(math.ceil(n / cols))
    spacing = 1.1
    objs = []
    for k, r in enumerate(roughness):
        i, j = divmod(k, cols)
        objs.append({"type": "sphere", "name": f"r{r:.3g}",
                     "center": [(j - (cols - 1) / 2) * spacing, ((rows - 1) / 2 - i) * spacing, 0.0],
                     "radius": 0.5, "material": {"base_color": [1.0, 1.0, 1.0], "metallic": 1.0,
                                                 "roughness": float(r)}})
    extent = max(cols, rows) * spacing
    dist = extent / 2 / math.tan(math.radians(18)) + 1.0
    w = max(8, int(round(size * cols / rows)))
    return scene_from_dict({"name": f"{scene.name}_lodprobe", "camera": {
        "origin": [0, 0, dist], "target": [0, 0, 0], "fov": 36.0 * (cols / rows if cols >= rows else 1.0),
        "width": w, "height": int(size)}, "environment": env, "brdf": scene.to_dict()["brdf"], "objects": objs})


def _no_lights(scene: Scene) -> Scene:
    return replace(scene, lights=())


def _groups(scene: Scene) -> dict[float, list[int]]:
    g: dict[float, list[int]] = {}
    for k, o in enumerate(scene.objects):
        g.setdefault(round(float(o.material.roughness), 6), []).append(k)
    return dict(sorted(g.items()))


def _relmse_maps(ref, img, valid):
    d = (img.rgb.astype(np.float64) - ref.rgb.astype(np.float64)) ** 2 / (ref.rgb.astype(np.float64) ** 2 + REL_EPS)
    return d.mean(axis=-1), valid


def _group_errors(ref, img, valid, ids, groups) -> dict[float, float]:
    e, _ = _relmse_maps(ref, img, valid)
    out = {}
    for r, members in groups.items():
        m = valid & np.isin(ids, members)
        out[r] = float(e[m].mean()) if m.any() else float("nan")
    return out


def _scene_relmse(ref, img, valid) -> float:
    e, _ = _relmse_maps(ref, img, valid)
    return float(e[valid].mean())


def _parabola_min(x: np.ndarray, y: np.ndarray, k: int) -> tuple[float, float]:
    """Refine the scan minimum at index k with a parabola through its neighbours."""
    if k == 0 or k == len(x) - 1 or not np.all(np.isfinite(y[k - 1:k + 2])):
        return float(x[k]), float(y[k])
    x0, x1, x2 = x[k - 1:k + 2]
    y0, y1, y2 = y[k - 1:k + 2]
    den = (y0 - 2 * y1 + y2)
    if den <= 0:
        return float(x1), float(y1)
    t = 0.5 * (y0 - y2) / den  # offset in steps from x1
    t = float(np.clip(t, -1.0, 1.0))
    h = x1 - x0
    return float(x1 + t * h), float(y1 - 0.25 * (y0 - y2) * t)


def _scan_chain(fit_scene, ref, preset, base, chain, lods, groups, prog, context) -> tuple[list[LodSample], np.ndarray, dict]:
    """Render ``fit_scene`` at every LOD of ``lods`` on the prefiltered chain baked with ``chain``;
    per roughness group the error curve, its refined minimum and the group's pixel count."""
    curves = {r: [] for r in groups}
    valid = ids = None
    counts = {}
    for L in lods:
        img = renderers.render_under_test(fit_scene, preset,
                                          {**base, "lod_mapping": chain, "lod_override": float(L)}, context=context)
        if valid is None:
            valid, _, _ = pixel_classes(ref, img)
            ids = np.rint(ref.channels["object"]).astype(np.int64)
            counts = {r: int((valid & np.isin(ids, m)).sum()) for r, m in groups.items()}
        for r, e in _group_errors(ref, img, valid, ids, groups).items():
            curves[r].append(e)
        prog.update(1, f"{chain} chain, LOD {L:.2f}")
    samples = []
    for r, ys in curves.items():
        y = np.asarray(ys)
        if not np.any(np.isfinite(y)):
            continue
        k = int(np.nanargmin(y))
        lod, err = _parabola_min(lods, y, k)
        spread = float(np.nanmax(y) - np.nanmin(y))
        samples.append(LodSample(r, lod, err, spread, counts[r], [float(v) for v in y]))
    return samples, valid, counts


def run_fit_lod(scene: Scene, *, roughness=None, preset: str = "default", options: dict | None = None,
                spp: int = 64, size: int | None = None, out: Path, lod_step: float = LOD_STEP,
                chains=BUILTIN, spp_cap: int | None = DEFAULT_SPP_CAP, progress: bool = False,
                context: renderers.RenderContext = renderers.DIRECT) -> FitLodResult:
    """Scan, fit and evaluate; writes ``out`` (JSON) and ``out`` with suffix ``.glsl``.

    ``chains``: the built-in mappings whose prefiltered chains are scanned and fitted on (default all
    three). The mapping is fitted on each; the chain whose fit predicts the lowest scene error wins.
    Scanning every chain is what lets the fit compete with each built-in mapping *on its own chain*
    (reading the quadratic chain at the linear mapping's LOD is not the linear mapping).

    Parameters
    ----------
    scene : Scene
        A scene with a sphere grid (used as is) or any scene whose environment lights the probe.
    roughness : sequence of float, optional
        Roughness values of a probe grid (:func:`probe_scene`) in [0, 1].
    preset, options : str, dict
        The renderer under test and its overrides (must use the prefiltered map, built-in mapping).
    spp : int
        Least reference samples per pixel: more (powers of two, at most ``spp_cap``) until the
        reference's noise floor is 10x below the preset's error on the fit scene
        (:mod:`compare.verdict_spp`; the outcome is the result's ``reference_spp``).
    size : int, optional
        Image height.
    out : Path
        The JSON to write (the GLSL goes next to it).
    lod_step : float
        Scan step in levels.
    chains : sequence of str
        Built-in mappings whose chains are scanned.
    progress : bool
        Show progress.

    Returns
    -------
    FitLodResult
        Samples, per-chain fits and every mapping's measured error.

    Raises
    ------
    PbrcheckError
        A preset without the prefiltered map, a fitted starting mapping, unknown chains, roughness
        outside [0, 1], or fewer than two roughness groups with valid pixels.
    """
    base = dict(options or {})
    base.pop("lod_override", None)
    o = renderers.resolve_options(preset, base)
    if o["ibl"] != "splitsum":
        raise PbrcheckError(f"fit-lod: preset {preset!r} does not use the prefiltered map (ibl={o['ibl']})")
    if o.fitted is not None:
        raise PbrcheckError("fit-lod: start from a built-in lod_mapping, not a fitted one")
    chains = tuple(chains)
    if not chains or any(c not in BUILTIN for c in chains):
        raise PbrcheckError(f"fit-lod: chains: expected some of {', '.join(BUILTIN)}, found {list(chains)}")
    has_grid = bool(scene.grids)
    if roughness is not None or not has_grid:
        rs = list(DEFAULT_ROUGHNESS if roughness is None else roughness)
        if not rs or any(not (0.0 <= r <= 1.0) for r in rs):
            raise PbrcheckError(f"fit-lod: roughness values must lie in [0, 1], found {rs}")
        fit_scene = probe_scene(scene, rs, size or 96)
    else:
        fit_scene = scene if size is None else scene.with_camera(
            width=max(8, int(round(size * scene.camera.width / scene.camera.height))), height=int(size))
    fit_scene = _no_lights(fit_scene)
    groups = _groups(fit_scene)
    # The reference's spp: its noise floor 10x below the preset's own error on the fit scene (the
    # error every scanned level is measured against; compare.verdict_spp), at most spp_cap.
    own_img = renderers.render_under_test(fit_scene, preset, base, progress=False, context=context)
    ref, verdict = reference_for_verdict(fit_scene, [own_img], spp=spp, cap=spp_cap, mode="local",
                                         metric="relmse", probe=RESEARCH_PROBE, tails=False, progress=progress)
    spp = verdict.spp
    M = o["prefilter_levels"] - 1
    cube_log2 = math.log2(o["cube_size"])
    lods = np.arange(0.0, M + 1e-9, lod_step)
    per_chain = {}
    valid = None
    with Progress("fit-lod scan", total=len(chains) * len(lods) + len(BUILTIN) + 1, enabled=progress) as prog:
        for chain in chains:
            samples, valid, _ = _scan_chain(fit_scene, ref, preset, base, chain, lods, groups, prog, context)
            if len(samples) < 2:
                raise PbrcheckError(f"fit-lod: need >= 2 roughness values with valid pixels, found {len(samples)}")
            rr = np.array([s.roughness for s in samples])
            table = np.array([s.scan for s in samples])
            table = np.where(np.isfinite(table), table, np.nanmax(table))
            weights = [s.pixels for s in samples]
            starts = [fit_lod_mapping(rr, builtin_lod(n, rr, M, cube_log2), cube_size=o["cube_size"],
                                      mip_count=o["prefilter_levels"]).coefficients for n in BUILTIN]
            starts += [c for c in (basis_coefficients(n, M) for n in BUILTIN) if c is not None]
            fitted = replace(fit_lod_to_error(rr, lods, table, cube_size=o["cube_size"],
                                              mip_count=o["prefilter_levels"], weights=weights, starts=starts),
                             chain=chain)
            per_chain[chain] = {
                "samples": samples, "mapping": fitted,
                "predicted_relmse": predicted_error(fitted(rr), lods, table, weights),
                # the chain's own built-in mapping read off the scan: the interpolation check
                "builtin_predicted_relmse": predicted_error(builtin_lod(chain, rr, M, cube_log2), lods, table,
                                                            weights)}
        best_chain = min(per_chain, key=lambda c: per_chain[c]["predicted_relmse"])
        samples = per_chain[best_chain]["samples"]
        fitted = per_chain[best_chain]["mapping"]
        rr = np.array([s.roughness for s in samples])
        out = Path(out)
        result = FitLodResult(
            scene=scene.name, fit_scene=fit_scene.name, preset=preset, options=base, spp=spp,
            size=[fit_scene.camera.width, fit_scene.camera.height], lod_step=lod_step,
            metric="relmse over valid pixels (point lights removed)", chain=best_chain, samples=samples,
            chains={c: ChainFit(v["predicted_relmse"], v["builtin_predicted_relmse"],
                                list(v["mapping"].coefficients), [s.lod for s in v["samples"]])
                    for c, v in per_chain.items()},
            mappings={"fitted": MappingEval(None, mapping=fitted.to_json())}, reference_spp=verdict.to_dict())
        for name in BUILTIN:
            # the preset's own mapping is the image the spp rule already rendered
            img = own_img if name == o["lod_mapping"] else renderers.render_under_test(
                fit_scene, preset, {**base, "lod_mapping": name}, context=context)
            result.mappings[name] = MappingEval(_scene_relmse(ref, img, valid),
                                                [float(v) for v in builtin_lod(name, rr, M, cube_log2)])
            prog.update(1, f"evaluate {name}")
        img = renderers.render_under_test(fit_scene, preset, {**base, "lod_mapping": fitted}, context=context)
        prog.update(1, "evaluate fitted")
    result.mappings["fitted"].relmse = _scene_relmse(ref, img, valid)
    result.mappings["fitted"].lod = [float(v) for v in fitted(rr)]
    result.per_roughness_optimum_mean_relmse = float(np.mean([s.relmse for s in samples]))
    glsl = out.with_suffix(".glsl")
    write_text_atomic(glsl, fitted.glsl())
    result.glsl = str(glsl)
    write_json_atomic(out, result)
    return result


def table_markdown(result: FitLodResult) -> str:
    """The chains' predictions, the optima and every mapping's measured error as Markdown tables."""
    lines = [f"fitted on the {result.chain} chain (the chain whose fit predicts the lowest scene error)", "",
             "| chain | fit's predicted relmse | chain's own mapping, predicted |", "| --- | --- | --- |"]
    for c, v in result.chains.items():
        lines.append(f"| {c} | {v.predicted_relmse:.5g} | {v.builtin_predicted_relmse:.5g} |")
    lines += ["", "| roughness | optimal LOD | relmse at optimum | fitted LOD |", "| --- | --- | --- | --- |"]
    fl = result.mappings["fitted"].lod
    for s, f in zip(result.samples, fl):
        lines.append(f"| {s.roughness:.4g} | {s.lod:.3f} | {s.relmse:.4g} | {f:.3f} |")
    lines += ["", "| mapping | relmse over the scene |", "| --- | --- |"]
    for k, v in result.mappings.items():
        lines.append(f"| {k} | {v.relmse:.5g} |")
    return "\n".join(lines) + "\n"
