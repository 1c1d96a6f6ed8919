"""One gate check evaluated: :func:`run_check` -> :class:`~compare.gate.verdict.CheckResult`.

Each check is measured twice: (a) accuracy against the reference (a metric outside its budget:
``OVER_BUDGET``); (b) change against its accepted baseline (:mod:`compare.baseline`), per object and
per screen tile, with the noise that would explain it (``REGRESSED``, ``IMPROVED``, ``CHANGED``).
Trusted verdicts: a budget is trusted when it sits :data:`BUDGET_NOISE_FACTOR` (10) times above
the reference's noise in its own metric (the metric of a simulated noise-only pair,
:func:`compare.metrics.noise_floor`, scaled by the metric's ``noise_power``,
:data:`compare.metrics.METRICS`); an ``auto`` reference is rendered from ``spp`` up until its noise
floor is also 10x below the check's error (:mod:`compare.verdict_spp`).

The renderer under test is called in one place, :func:`render_test` (the check's own render, the
runs that measure its spread at ``--accept``, and the LOD probe).

API
---
- :func:`run_check` -- evaluate one check (never raises for data problems: they are verdicts).
- :func:`render_test` -- render a check's scene with its renderer under test.
- :func:`takes_hooks` -- whether the check's renderer takes shader hooks (the LOD probe).
- :func:`budget_noise`, :data:`BUDGET_NOISE_FACTOR` -- each budget against the reference's noise.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

from pbrcheck.environment import scene_hash
from pbrcheck.errors import PbrcheckError
from pbrcheck.exr import RGB, Image, read_exr
from realtime.registry import SHADINGS

from .. import renderers
from ..baseline import compare_to_baseline, likely_term, load_baseline, sensitivity
from ..maps import safe_name, write_maps
from ..metrics import METRICS, compare_images, worse
from ..unmodelled import unjudged_reason
from ..verdict_spp import reference_for_verdict, verdict_of
from .budget import BudgetError, Check, reference_scene, resolve, scene_arg
from .verdict import CheckResult, NotJudged, Verdict, error_verdict, judged_verdict

#: A budget is trusted when it is at least this many times the reference's noise in its metric.
BUDGET_NOISE_FACTOR = 10.0


def render_test(check: Check, scene, *, options: dict | None = None, progress: bool = True,
                use_cache: bool = True) -> Image:
    """Render ``scene`` with ``check``'s renderer under test (its preset and options, or ``options``
    instead): the one call of :func:`compare.renderers.render_under_test` in the gate."""
    opts = check.options if options is None else options
    return renderers.render_under_test(scene, check.preset, opts or None, progress=progress, use_cache=use_cache)


def takes_hooks(check: Check) -> bool:
    """Whether the check's renderer takes shader hooks (a real-time preset with ``shading =
    material``) and its own hook file, if any, defines no ``hook_lod`` (the LOD probe replaces that
    hook). The hook file is parsed with :func:`realtime.hooks.load_hook_file`, the parser the
    renderer compiles it with (a ``hook_lod`` in a comment or a string is no definition)."""
    if check.test is not None or renderers.is_external(check.preset):
        return False
    try:
        o = renderers.resolve_options(check.preset, {k: v for k, v in check.options.items() if k != "shader"})
    except PbrcheckError:
        return False
    if not SHADINGS[o["shading"]].extra.get("hooks"):
        return False
    shader = check.options.get("shader")
    if not shader:
        return True
    from realtime.hooks import load_hook_file

    return "hook_lod" not in load_hook_file(shader).hooks


def budget_noise(check: Check, noise: dict | None, spp: int) -> tuple[dict, ...]:
    """Per ``max`` budget: the reference's noise in that metric, budget / noise and the spp at which
    it would be :data:`BUDGET_NOISE_FACTOR` (``spp_needed``; the noise scales as
    ``spp ** (-1 / noise_power)``, :class:`compare.metrics.Metric`).

    The noise is the metric of :func:`compare.metrics.noise_floor`'s simulated pair ``(r, r + sqrt(2
    var) z)`` (two independent renders) scaled to one noisy image against a noise-free one (the
    real-time image): variance halved, i.e. the metric divided by ``2 ** (1 / noise_power)``."""
    out = []
    sim = (noise or {}).get("simulated") or {}
    for metric, budget in check.max.items():
        n = sim.get(metric)
        if n is None or not (n > 0) or not math.isfinite(n):
            continue
        power = METRICS[metric].noise_power
        n = n / 2.0 ** (1.0 / power)
        ratio = budget / n
        need = spp * (BUDGET_NOISE_FACTOR / ratio) ** power if spp and ratio > 0 else math.inf
        out.append({"metric": metric, "budget": budget, "noise": n, "ratio": ratio,
                    "trusted": bool(ratio >= BUDGET_NOISE_FACTOR), "spp_needed": need})
    return tuple(out)


def _stored_reference(base: Path, check: Check, ref_scene) -> tuple[Image, str]:
    ref_path = resolve(base, check.reference)
    ref = read_exr(ref_path, require=RGB)
    if ref_scene is not None and ref.meta.get("scene_hash"):
        # A stored reference of another scene (an edited scene file, a stale EXR) would make the
        # gate measure a scene mismatch, not the shaders: refuse it.
        want = scene_hash(ref_scene)
        if ref.meta["scene_hash"] != want:
            which = check.reference_scene or check.scene
            raise BudgetError(f"{ref_path}: reference was rendered for scene hash "
                              f"{ref.meta['scene_hash'][:16]}, but {which} hashes to {want[:16]}; "
                              f"re-render it (pbrcheck reference ... --out {check.reference})")
    return ref, str(ref_path)


def _failures(check: Check, cmp) -> tuple[dict, ...]:
    out = []
    for bounds, kind in ((check.max, "max"), (check.min, "min")):
        for metric, bound in bounds.items():
            v = cmp.metrics.get(metric)
            if worse(v, bound, upper=(kind == "max")):
                worst = [{"id": o["id"], "name": o["name"], "value": o["metrics"][metric]}
                         for o in cmp.worst_objects(metric)]
                within = (cmp.summary["noise"] or {}).get("within_noise", {}).get(metric)
                out.append({"metric": metric, "value": v, "budget": bound, "kind": kind,
                            "worst_objects": worst, "within_noise": within})
    return tuple(out)


def _measure(check: Check, base: Path, progress: bool) -> dict:
    """The check's figures (the fields of its :class:`CheckResult` but ``verdict``); raises for data
    problems."""
    scene = scene_arg(base, check.scene) if check.scene else None
    why = unjudged_reason(scene, check)
    if why is not None:  # a feature the reference leaves out: no verdict, nothing rendered
        raise NotJudged(why)
    if check.test is not None:
        test_path = resolve(base, check.test)
        test = read_exr(test_path, require=RGB)
        test_name = str(test_path)
    else:
        test = render_test(check, scene, progress=progress)
        test_name = check.preset if renderers.is_external(check.preset) else f"real-time {check.preset}"
    ref_scene = reference_scene(base, check, scene) if check.reference_scene else scene
    spp_verdict = None
    if check.reference == "auto":
        ref, spp_verdict = reference_for_verdict(ref_scene, [test], spp=check.spp, cap=check.spp_cap,
                                                 mode=check.mode, seed=check.seed, use_cache=True,
                                                 progress=progress)
        ref_name = f"auto reference ({check.scene}, {spp_verdict.spp} spp)"
    else:
        ref, ref_name = _stored_reference(base, check, ref_scene)
    cmp = compare_images(ref, test, scene=scene, ref_name=ref_name, test_name=test_name)
    if spp_verdict is None:
        spp_verdict = verdict_of(ref, cmp.summary["noise"])
    out = {"cmp": cmp, "reference_spp": spp_verdict, "ref_image": ref, "test_image": test,
           "budget_noise": budget_noise(check, cmp.summary["noise"], spp_verdict.spp),
           "names": {}, "materials": {}}
    if scene is not None:
        out["names"] = {i: o.name for i, o in enumerate(scene.objects) if o.name}
        out["materials"] = {f"object {o.name}" if o.name else f"object #{i}":
                            {"metallic": o.material.metallic, "roughness": o.material.roughness}
                            for i, o in enumerate(scene.objects)}
    baseline = out["baseline"] = load_baseline(base, safe_name(check.name))
    if baseline is not None:
        out["change"] = compare_to_baseline(ref, baseline, test, out["names"])
        out["sensitivity"] = sensitivity(ref, baseline, out["names"])
        if out["change"].verdict != "pass":
            out["likely"] = likely_term(out["change"], out["materials"])
    return out


def run_check(check: Check, base: Path, *, maps_dir: Path | None = None, progress: bool = True) -> CheckResult:
    """Evaluate one check; never raises for data problems (they become ERROR / BACKEND_ERROR /
    NOT_JUDGED verdicts with the message).

    Parameters
    ----------
    check : Check
        The check (scene, renderer under test, reference, bounds).
    base : Path
        Folder of the budget file; relative paths in the check are resolved against it.
    maps_dir : Path, optional
        Where the error maps of a check that is not ``pass`` go (``maps_dir/<check name>``).
    progress : bool, optional
        Show render progress on stderr.
    """
    t0 = time.perf_counter()
    try:
        m = _measure(check, Path(base), progress)
    except Exception as e:  # noqa: BLE001 - a renderer bug must not read as "over budget" (exit 1)
        msg = str(e) if isinstance(e, PbrcheckError) else f"unexpected {type(e).__name__}: {e}"
        return CheckResult(check, error_verdict(e), error=msg, seconds=time.perf_counter() - t0)
    cmp = m.pop("cmp")
    failures = _failures(check, cmp)
    verdict = judged_verdict(bool(failures), m.get("change"), check.on_change)
    maps = {}
    if verdict is not Verdict.PASS and maps_dir is not None:
        maps = {k: str(p) for k, p in write_maps(Path(maps_dir) / safe_name(check.name), cmp).items()}
    return CheckResult(check, verdict, metrics=cmp.metrics, failures=failures, maps=maps,
                       seconds=time.perf_counter() - t0, **m)
