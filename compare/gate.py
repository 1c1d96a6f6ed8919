"""CI error-budget gate: ``pbrcheck gate BUDGET.toml``.

Budget format (TOML; see docs/compare.md)::

    [[check]]
    name = "spheres-default"         # required, unique
    scene = "spheres"                # built-in name or TOML path (relative to the budget file)
    preset = "default"               # real-time preset or ext:NAME (docs/renderers.md)
    options = { }                    # optional real-time option overrides
    # shader = "hooks/ue4.glsl"      # optional shader hook file (relative to the budget file)
    reference = "refs/spheres.exr"   # stored EXR (relative to the budget file) or "auto"
    # reference_scene = "spheres_ms.toml"  # optional: the reference's scene, the check's scene but
                                     # for [brdf] (the model the engine means to render: multiscatter,
                                     # roughness_floor); the stored EXR must be of it
    spp = 64                         # with reference = "auto": samples per pixel (default 64)
    # test = "engine_out.exr"        # instead of preset: gate an image from any engine (scene
                                     # then only names objects / renders an "auto" reference)
    [check.max]                      # metric = largest allowed value
    relmse = 0.01
    [check.min]                      # optional: metric = smallest allowed value (e.g. psnr)
    psnr = 30

Top level (optional): ``require_baselines = true`` (a check without an accepted baseline is an
error), ``on_change = "fail" | "pass"`` (also per check), ``[[history]]`` (appended by ``--accept``).

Each check is measured twice: (a) accuracy against the reference: ``pass`` or ``fail`` (a metric
outside its budget) as before; (b) change against its accepted baseline (:mod:`compare.baseline`:
``baselines/<check>.exr`` + ``.json`` beside the budget), per object and per screen tile, with the
noise that would explain it: ``pass``, ``regressed`` (a region significantly worse against the
reference), ``improved`` (better, none worse) or ``changed`` (beyond the renderer's run-to-run noise,
neither better nor worse beyond the reference's). ``error``: missing or unreadable image, size
mismatch, NaN, bad scene, a missing required baseline. Trusted verdicts: a budget is trusted when it
sits :data:`BUDGET_NOISE_FACTOR` (10) times above the reference's noise in its own metric (the
metric of a simulated noise-only pair, :func:`compare.metrics.noise_floor`); an ``auto`` reference
is rendered from ``spp`` up (powers of two, at most ``spp_cap``, default 4096) until its noise floor
is also 10x below the check's error (:mod:`compare.verdict_spp`). Where a budget is not trusted the
check's line says ``noise-limited`` with the spp that would be. Each check's line prints its
sensitivity (the smallest brightness change and LOD shift the baseline comparison detects).

Exit status: 2 if any check errored (never pass on missing data), else 1 if any failed, regressed or
changed (unless ``on_change = "pass"``), else 0 (``improved`` prints the command that accepts it).
A malformed budget is an error before any check runs (exit 2, nothing written).
``--accept --reason``: :func:`accept` (refused, nothing written, when a check errors).
``--check NAME`` (repeatable): only the named checks run (and, with ``--accept``, are rewritten).

API
---
- :func:`load_budget`, :func:`budget_settings` -- parse and validate a budget.
- :func:`run_check` -- one check (:class:`Result`); :func:`run_gate` -- a budget, printed, exit code.
- :func:`accept` -- rewrite the baselines and append the history.
- :func:`write_junit`, :func:`write_summary`, :func:`write_html`, :func:`write_thumbnails` -- CI outputs.
- :func:`failure_lines`, :func:`change_lines`, :func:`sensitivity_text`, :func:`noise_note` -- the lines.
- :func:`budget_noise` -- each budget against the reference's noise.

References: JUnit XML as read by CI systems (one testcase per check and per regressed region);
Filament's renderdiff and model-viewer's fidelity test (golden images: a change, not its direction).
"""

from __future__ import annotations

import json
import math
import sys
import time
import tomllib
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pbrcheck.atomic import check_output_path, write_text_atomic
from pbrcheck.environment import scene_hash
from pbrcheck.errors import PbrcheckError, decode_reason
from pbrcheck.exr import RGB, Image, read_exr
from pbrcheck.fmt import format_value
from pbrcheck.registry import SHADINGS
from pbrcheck.scene import builtin_scene_names, load_scene

from . import renderers
from .baseline import Baseline, Change, compare_to_baseline, likely_term, load_baseline, sensitivity
from .maps import safe_name, write_maps
from .metrics import METRICS, compare_images, worse
from .verdict_spp import DEFAULT_SPP_CAP, MIN_REFERENCE_SPP, VerdictSpp, reference_for_verdict, verdict_of

CHECK_KEYS = {"name", "scene", "preset", "options", "shader", "reference", "reference_scene", "spp", "spp_cap", "test", "max", "min",
              "mode", "seed", "on_change"}
#: Top-level keys of a budget file besides [[check]].
BUDGET_KEYS = {"check", "history", "on_change", "require_baselines"}
#: What a ``changed`` verdict (differs from the baseline, neither better nor worse) does.
ON_CHANGE = ("fail", "pass")
DEFAULT_SPP = 64


class BudgetError(PbrcheckError):
    """A malformed budget file (names the file and the field)."""


@dataclass
class Check:
    """One budget check: a scene, the renderer under test (``preset`` or a stored ``test`` EXR), the
    reference (``auto``: rendered at ``spp``, ``mode``, ``seed``; or a stored EXR) and the metric
    bounds ``max`` / ``min``."""
    name: str
    max: dict[str, float]
    min: dict[str, float]
    reference: str
    scene: str | None = None
    preset: str = "default"
    options: dict = field(default_factory=dict)
    test: str | None = None
    spp: int = DEFAULT_SPP
    mode: str = "local"
    seed: int = 0
    spp_cap: int = DEFAULT_SPP_CAP
    on_change: str = "fail"
    # The reference's scene (model-matched reference): the check's scene but for [brdf].
    reference_scene: str | None = None


@dataclass
class Result:
    """The outcome of one :class:`Check`: ``pass``, ``fail`` (with each broken bound, its worst
    objects and whether the reference's noise could explain it) or ``error`` (with the message and
    the exit code it maps to)."""
    check: Check
    status: str                      # pass | fail | error
    metrics: dict | None = None
    failures: list[dict] = field(default_factory=list)
    error: str | None = None
    exit_code: int = 0
    seconds: float = 0.0
    maps: dict = field(default_factory=dict)
    verdict: VerdictSpp | None = None  # the reference's spp and noise floor against the error
    budget_noise: list = field(default_factory=list)  # per budget: the reference's noise in its metric
    change: Change | None = None     # against the accepted baseline (None: no baseline)
    baseline: Baseline | None = None
    sensitivity: dict | None = None
    likely: str | None = None        # the term a change most likely comes from
    ref_image: Image | None = None   # kept for --accept, the thumbnails and --html
    test_image: Image | None = None
    names: dict = field(default_factory=dict)      # object id -> name
    materials: dict = field(default_factory=dict)  # region name -> material

    @property
    def outcome(self) -> str:
        """pass | fail (accuracy budget) | regressed | improved | changed | error."""
        if self.status in ("error", "fail"):
            return self.status
        return self.change.verdict if self.change is not None else "pass"


def _err(file, where, expected, found=None) -> BudgetError:
    msg = f"{file}: {where}: expected {expected}"
    if found is not None:
        msg += f", found {found!r}"
    return BudgetError(msg)


def _bounds(file, where, t) -> dict[str, float]:
    if not isinstance(t, dict):
        raise _err(file, where, "a table of metric = number", t)
    out = {}
    for k, v in t.items():
        if k not in METRICS:
            raise _err(file, f"{where}.{k}", "a metric name (" + ", ".join(METRICS) + ")", k)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
            raise _err(file, f"{where}.{k}", "a finite number >= 0", v)
        out[k] = float(v)
    return out


def load_budget(path: str | Path) -> tuple[list[Check], Path]:
    """Parse and validate a budget; returns the checks and the budget's directory."""
    path = Path(path)
    if not path.is_file():
        raise BudgetError(f"{path}: no such budget file")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as e:
        raise BudgetError(f"{path}: invalid TOML: {e}") from None
    except UnicodeDecodeError as e:
        raise BudgetError(f"{path}: cannot read: {decode_reason(e)}") from None
    except OSError as e:
        raise BudgetError(f"{path}: cannot read: {e.strerror}") from None
    extra = set(data) - BUDGET_KEYS
    if extra:
        raise _err(path, sorted(extra)[0], "[[check]] tables, [[history]], on_change or require_baselines",
                   sorted(extra)[0])
    top_change = data.get("on_change", "fail")
    if top_change not in ON_CHANGE:
        raise _err(path, "on_change", " or ".join(f'"{x}"' for x in ON_CHANGE), top_change)
    if not isinstance(data.get("require_baselines", False), bool):
        raise _err(path, "require_baselines", "true or false", data["require_baselines"])
    if not isinstance(data.get("history", []), list):
        raise _err(path, "history", "[[history]] tables", data["history"])
    checks = data.get("check")
    if not isinstance(checks, list) or not checks:
        raise _err(path, "check", "at least one [[check]] table", checks if checks is not None else "nothing")
    out: list[Check] = []
    names = set()
    for i, t in enumerate(checks):
        w = f"check[{i}]"
        if not isinstance(t, dict):
            raise _err(path, w, "a table", t)
        for k in t:
            if k not in CHECK_KEYS:
                raise _err(path, f"{w}.{k}", "one of the keys " + ", ".join(sorted(CHECK_KEYS)), k)
        name = t.get("name")
        if not isinstance(name, str) or not name.strip():
            raise _err(path, f"{w}.name", "a non-empty string", name if name is not None else "nothing")
        if name in names:
            raise _err(path, f"{w}.name", "a unique check name", name)
        same = [n for n in names if safe_name(n) == safe_name(name)]
        if same:  # e.g. "a/b" and "a_b": their error maps would go to one folder
            raise _err(path, f"{w}.name", f"a name whose maps folder is not that of check {same[0]!r} "
                       f"(both are {safe_name(name)!r})", name)
        names.add(name)
        if "on_change" in t and t["on_change"] not in ON_CHANGE:
            raise _err(path, f"{w}.on_change", " or ".join(f'"{x}"' for x in ON_CHANGE), t["on_change"])
        for k in ("scene", "preset", "reference", "reference_scene", "test", "mode", "shader"):
            if k in t and not isinstance(t[k], str):
                raise _err(path, f"{w}.{k}", "a string", t[k])
        if "reference" not in t:
            raise _err(path, f"{w}.reference", 'a stored EXR path or "auto" (required)', "nothing")
        has_test, has_scene = "test" in t, "scene" in t
        if not (has_test or has_scene):
            raise _err(path, w, "scene (rendered with preset) or test (an image path)", "neither")
        if t["reference"] == "auto" and not has_scene:
            raise _err(path, f"{w}.reference", '"auto" only together with scene', "auto")
        if "reference_scene" in t and not has_scene:
            raise _err(path, f"{w}.reference_scene", "reference_scene only together with scene",
                       t["reference_scene"])
        if has_test and ("preset" in t or "options" in t or "shader" in t):
            raise _err(path, w, "preset/options/shader only with scene, not with test", "test")
        if "options" in t and not isinstance(t["options"], dict):
            raise _err(path, f"{w}.options", "a table of real-time options", t["options"])
        for k in ("spp", "seed", "spp_cap"):
            lo = MIN_REFERENCE_SPP if k in ("spp", "spp_cap") else 0
            if k in t and (isinstance(t[k], bool) or not isinstance(t[k], int) or t[k] < lo):
                raise _err(path, f"{w}.{k}", f"an integer >= {lo}", t[k])
        mx = _bounds(path, f"{w}.max", t.get("max", {}))
        mn = _bounds(path, f"{w}.min", t.get("min", {}))
        if not mx and not mn:
            raise _err(path, f"{w}.max", "at least one metric budget in [check.max] or [check.min]", "nothing")
        options = dict(t.get("options", {}))
        if "shader" in t:  # a hook file, relative to this budget file
            shader = _resolve(path.parent, t["shader"])
            if not shader.is_file():
                raise _err(path, f"{w}.shader", "an existing shader hook file", t["shader"])
            options["shader"] = str(shader)
        out.append(Check(name=name, max=mx, min=mn, reference=t["reference"], scene=t.get("scene"),
                         preset=t.get("preset", "default"), options=options,
                         test=t.get("test"), spp=t.get("spp", DEFAULT_SPP), mode=t.get("mode", "local"),
                         seed=t.get("seed", 0), spp_cap=t.get("spp_cap", DEFAULT_SPP_CAP),
                         on_change=t.get("on_change", top_change),
                         reference_scene=t.get("reference_scene")))
    return out, path.parent


def budget_settings(path: str | Path) -> dict:
    """The budget's top-level settings (``require_baselines``, ``on_change``), after :func:`load_budget`."""
    data = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    return {"require_baselines": bool(data.get("require_baselines", False)),
            "on_change": data.get("on_change", "fail"), "history": len(data.get("history", []))}


def _reference_scene(base: Path, check: Check, scene):
    """The check's ``reference_scene``, refused unless it is the check's scene but for ``[brdf]``
    (a model-matched reference: the objects, camera, lights and environment must be the same)."""
    ref_scene = _scene_arg(base, check.reference_scene)
    a, b = scene.content_dict(), ref_scene.content_dict()
    a.pop("brdf"), b.pop("brdf")
    if a != b:
        diff = sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))
        raise BudgetError(f"reference_scene {check.reference_scene} differs from scene {check.scene} in "
                          f"{', '.join(diff)}: only [brdf] may differ (the reference's model)")
    return ref_scene


def _resolve(base: Path, p: str) -> Path:
    q = Path(p).expanduser()
    return q if q.is_absolute() else base / q


def _scene_arg(base: Path, s: str):
    if not Path(s).suffix and s in builtin_scene_names():
        return load_scene(s)
    return load_scene(_resolve(base, s))


def run_check(check: Check, base: Path, *, maps_dir: Path | None = None, progress: bool = True) -> Result:
    """Evaluate one check; never raises for data problems (they become ``error`` results).

    Parameters
    ----------
    check : Check
        The check (scene, renderer under test, reference, bounds).
    base : Path
        Folder of the budget file; relative paths in the check are resolved against it.
    maps_dir : Path, optional
        Where the error maps of a failing check go (``maps_dir/<check name>``).
    progress : bool, optional
        Show render progress on stderr.

    Returns
    -------
    Result
        ``pass``, ``fail`` (with the failures and worst objects) or ``error`` (with its message).
    """
    t0 = time.perf_counter()
    res = Result(check, "error")
    try:
        scene = _scene_arg(base, check.scene) if check.scene else None
        if check.test is not None:
            test_path = _resolve(base, check.test)
            test = read_exr(test_path, require=RGB)
            test_name = str(test_path)
        else:
            spec = renderers.RendererSpec.parse(check.preset, check.options)
            test = renderers.render_under_test(scene, spec, progress=progress)
            test_name = spec.text if spec.external else f"real-time {spec.text}"
        ref_scene = _reference_scene(base, check, scene) if check.reference_scene else scene
        if check.reference == "auto":
            ref, res.verdict = reference_for_verdict(ref_scene, [test], spp=check.spp, cap=check.spp_cap,
                                                     mode=check.mode, seed=check.seed, use_cache=True,
                                                     progress=progress)
            ref_name = f"auto reference ({check.scene}, {res.verdict.spp} spp)"
        else:
            ref_path = _resolve(base, check.reference)
            ref = read_exr(ref_path, require=RGB)
            ref_name = str(ref_path)
            if ref_scene is not None and ref.meta.get("scene_hash"):
                # A stored reference of another scene (an edited scene file, a stale EXR) would make
                # the gate measure a scene mismatch, not the shaders: refuse it.
                want = scene_hash(ref_scene)
                if ref.meta["scene_hash"] != want:
                    which = check.reference_scene or check.scene
                    raise BudgetError(f"{ref_path}: reference was rendered for scene hash "
                                      f"{ref.meta['scene_hash'][:16]}, but {which} hashes to {want[:16]}; "
                                      f"re-render it (pbrcheck reference ... --out {check.reference})")
        cmp = compare_images(ref, test, scene=scene, ref_name=ref_name, test_name=test_name)
        if res.verdict is None:
            res.verdict = verdict_of(ref, cmp.summary["noise"])
        res.budget_noise = budget_noise(check, cmp.summary["noise"], res.verdict.spp)
        res.ref_image, res.test_image = ref, test
        if scene is not None:
            res.names = {i: o.name for i, o in enumerate(scene.objects) if o.name}
            res.materials = {f"object {o.name}" if o.name else f"object #{i}":
                             {"metallic": o.material.metallic, "roughness": o.material.roughness}
                             for i, o in enumerate(scene.objects)}
        res.baseline = load_baseline(base, safe_name(check.name))
        if res.baseline is not None:
            res.change = compare_to_baseline(ref, res.baseline, test, res.names)
            res.sensitivity = sensitivity(ref, res.baseline, res.names)
            if res.change.verdict != "pass":
                res.likely = likely_term(res.change, res.materials)
    except PbrcheckError as e:
        res.error, res.exit_code = str(e), max(e.exit_code, 2)
        res.seconds = time.perf_counter() - t0
        return res
    except Exception as e:  # noqa: BLE001 - a renderer bug must not read as "over budget" (exit 1)
        res.error, res.exit_code = f"unexpected {type(e).__name__}: {e}", 2
        res.seconds = time.perf_counter() - t0
        return res
    res.metrics = cmp.metrics
    for bounds, kind in ((check.max, "max"), (check.min, "min")):
        for metric, bound in bounds.items():
            v = cmp.metrics.get(metric)
            if worse(v, bound, upper=(kind == "max")):
                worst = [{"id": o["id"], "name": o["name"], "value": o["metrics"][metric]}
                         for o in cmp.worst_objects(metric)]
                within = (cmp.summary["noise"] or {}).get("within_noise", {}).get(metric)
                res.failures.append({"metric": metric, "value": v, "budget": bound, "kind": kind,
                                     "worst_objects": worst, "within_noise": within})
    res.status = "fail" if res.failures else "pass"
    res.exit_code = 1 if res.failures else 0
    if res.outcome == "regressed" or (res.outcome == "changed" and check.on_change == "fail"):
        res.exit_code = 1
    if res.outcome != "pass" and maps_dir is not None:
        res.maps = {k: str(p) for k, p in write_maps(Path(maps_dir) / safe_name(check.name), cmp).items()}
    res.seconds = time.perf_counter() - t0
    return res


#: A budget is trusted when it is at least this many times the reference's noise in its metric.
BUDGET_NOISE_FACTOR = 10.0
#: Metrics that scale with the variance (1 / spp); the others with its square root (1 / sqrt(spp)).
VARIANCE_LIKE = {"relmse"}


def budget_noise(check: Check, noise: dict | None, spp: int) -> list[dict]:
    """Per ``max`` budget: the reference's noise in that metric, budget / noise and the spp at which
    it would be :data:`BUDGET_NOISE_FACTOR` (``spp_needed``; the noise scales as 1/spp for
    :data:`VARIANCE_LIKE` metrics, else 1/sqrt(spp)).

    The noise is the metric of :func:`compare.metrics.noise_floor`'s simulated pair ``(r, r + sqrt(2
    var) z)`` (two independent renders) scaled to one noisy image against a noise-free one (the
    real-time image): halved for variance-like metrics, divided by sqrt(2) for the others."""
    out = []
    sim = (noise or {}).get("simulated") or {}
    for metric, budget in check.max.items():
        n = sim.get(metric)
        if n is None or not (n > 0) or not math.isfinite(n):
            continue
        power = 1.0 if metric in VARIANCE_LIKE else 2.0
        n = n / 2.0 ** (1.0 / power)
        ratio = budget / n
        need = spp * (BUDGET_NOISE_FACTOR / ratio) ** power if spp and ratio > 0 else math.inf
        out.append({"metric": metric, "budget": budget, "noise": n, "ratio": ratio,
                    "trusted": bool(ratio >= BUDGET_NOISE_FACTOR), "spp_needed": need})
    return out


def noise_note(r: Result) -> str:
    """`` (noise-limited: ...)`` when a budget of ``r`` is not 10x above the reference's noise in its
    metric (or an ``auto`` reference stopped at its cap)."""
    bad = [b for b in r.budget_noise if not b["trusted"]]
    parts = [f"{b['metric']} budget {format_value(b['budget'])} is {b['ratio']:.3g}x the reference's noise "
             f"{format_value(b['noise'])} (>= {BUDGET_NOISE_FACTOR:g}x "
             + (f"at {math.ceil(b['spp_needed'])} spp)" if math.isfinite(b["spp_needed"])
                else "at no spp: a budget of 0 is below any noise)")
             for b in bad]
    if r.check.reference == "auto" and r.verdict is not None and r.verdict.noise_limited:
        parts.append(r.verdict.provenance())
    return f" (noise-limited: {'; '.join(parts)})" if parts else ""


def failure_lines(r: Result) -> list[str]:
    """One line per broken bound of ``r`` (metric, value, budget, worst objects, noise note)."""
    out = []
    for f in r.failures:
        op = ">" if f["kind"] == "max" else "<"
        worst = ", ".join(f"{o['name'] or '#' + str(o['id'])}={format_value(o['value'])}" for o in f["worst_objects"])
        note = " (within the reference's noise)" if f.get("within_noise") else ""
        out.append(f"FAIL {r.check.name}: {f['metric']} = {format_value(f['value'])} {op} budget {format_value(f['budget'])}"
                   f"{note}" + (f"; worst objects: {worst}" if worst else "") + noise_note(r))
    return out


def _pct(x: float) -> str:
    return f"{x:+.3%}" if math.isfinite(x) else str(x)


def sensitivity_text(r: Result) -> str:
    """``brightness +-k %, LOD m mip`` of a check with a baseline (what its change test can see)."""
    s = r.sensitivity
    if not s:
        return ""
    if s.get("lod") is not None:
        lod = f"LOD shift {s['lod']:.2g} mip ({s['lod_region']})"
    elif s.get("lod_probed"):
        lod = "LOD shift: none visible (no region responds to the LOD probe)"
    else:
        lod = "LOD shift: not measured (the renderer takes no shader hooks)"
    return f"sensitivity: brightness +-{s['brightness']:.2%} ({s['brightness_region']}), {lod}"


def region_text(x) -> str:
    """One region's figures: bias, relmse before -> after, the change in noise units."""
    z = x.d_relmse / x.sigma_d if x.sigma_d > 0 else (math.inf if x.d_relmse else 0.0)
    return (f"{x.name}: relmse {format_value(x.relmse_before)} -> {format_value(x.relmse_after)} "
            f"({_pct(x.relative_d)}, {z:+.3g} sigma of the reference's noise), bias {_pct(x.bias)} "
            f"(threshold {x.bias_threshold:.2g})")


#: Regions named per verdict line.
NAMED_REGIONS = 3


def change_lines(r: Result, budget_path: str = "BUDGET.toml") -> list[str]:
    """The lines of a check's change against its baseline (nothing for ``pass``)."""
    c = r.change
    if c is None or c.verdict == "pass":
        return []
    name = r.check.name
    worse, better, changed = c.by_state("worse"), c.by_state("better"), c.by_state("changed")
    n = len(c.regions)
    if c.verdict == "regressed":
        head = f"REGRESSED {name}: {len(worse)} of {n} regions significantly worse against the reference"
        if better:
            head += f" ({len(better)} better)"
        rows = worse
    elif c.verdict == "improved":
        head = (f"IMPROVED {name}: {len(better)} of {n} regions significantly better against the reference, "
                f"none worse; accept it: pbrcheck gate {budget_path} --accept --reason \"...\"")
        rows = better
    else:
        how = "allowed by on_change = \"pass\"" if r.check.on_change == "pass" else "accept it if intended"
        head = (f"CHANGED {name}: {len(changed)} of {n} regions differ from the baseline beyond the renderer's "
                f"run-to-run noise, neither better nor worse beyond the reference's noise ({how}: "
                f"pbrcheck gate {budget_path} --accept --reason \"...\")")
        rows = changed
    out = [head]
    out += [f"     {region_text(x)}" for x in rows[:NAMED_REGIONS]]
    if len(rows) > NAMED_REGIONS:
        out.append(f"     ... and {len(rows) - NAMED_REGIONS} more region(s)")
    if r.likely:
        out.append(f"     likely term: {r.likely}")
    out += [f"     note: {n}" for n in provenance_changes(r)]
    return out


def provenance_changes(r: Result) -> list[str]:
    """What made the baseline and differs now (GL renderer, client version, shader sources, hook
    file): a change may come from the machine, not the shaders."""
    if r.baseline is None or r.test_image is None:
        return []
    rec, meta, out = r.baseline.record, r.test_image.meta, []
    for key, what in (("gl_renderer", "GL renderer"), ("version", "renderer version")):
        if rec.get(key) and meta.get(key) and rec[key] != meta[key]:
            out.append(f"the baseline was made with {what} {rec[key]!r}, this run used {meta[key]!r}")
    if rec.get("shader_sources_sha256") and meta.get("renderer") == "realtime":
        from .baseline import shader_sources_hash

        if shader_sources_hash() != rec["shader_sources_sha256"]:
            out.append("the real-time shader sources changed since the baseline was accepted")
    hook = json.loads(meta["shader"]) if meta.get("shader") else None
    old = rec.get("hook") or None
    if (hook or {}).get("sha256") != (old or {}).get("sha256"):
        out.append("the shader hook file differs from the baseline's" if hook or old else "")
    return [x for x in out if x]


def _check_line(r: Result) -> str:
    m = r.metrics or {}
    acc = ", ".join(f"{k} {format_value(m.get(k))} {'<=' if kind == 'max' else '>='} {format_value(b)}"
                    for kind, d in (("max", r.check.max), ("min", r.check.min)) for k, b in d.items())
    if r.change is None:
        base = "no accepted baseline (accuracy only)"
    else:
        base = f"baseline: {r.change.verdict} over {len(r.change.regions)} regions"
    sens = sensitivity_text(r)
    return f"{r.outcome} {r.check.name} ({acc}; {base}" + (f"; {sens}" if sens else "") + ")" + noise_note(r)


def write_junit(path: Path, results: list[Result]) -> Path:
    """Write the results as JUnit XML: one testcase per check, and one per region of a regressed
    check that got worse (``<check>/<region>``); failures and errors as such. Atomic."""
    cases = []
    for r in results:
        tc = ET.Element("testcase", classname="pbrcheck.gate", name=r.check.name, time=f"{r.seconds:.3f}")
        lines = failure_lines(r) + change_lines(r)
        if r.status == "error":
            ET.SubElement(tc, "error", message=r.error or "error").text = r.error
        elif r.exit_code:
            ET.SubElement(tc, "failure", message=lines[0] if lines else r.outcome).text = "\n".join(lines)
        if r.metrics:
            out = [_check_line(r)] + [f"{k} = {format_value(v)}" for k, v in r.metrics.items()]
            if r.verdict is not None:
                out.append(f"reference: {r.verdict.provenance()}")
            out += [f"budget {b['metric']}: {b['ratio']:.3g}x the reference's noise" for b in r.budget_noise]
            ET.SubElement(tc, "system-out").text = "\n".join(out)
        cases.append(tc)
        if r.change is not None and r.change.verdict == "regressed":
            for x in r.change.by_state("worse"):
                sub = ET.Element("testcase", classname=f"pbrcheck.gate.{r.check.name}", name=f"{r.check.name}/{x.name}",
                                 time="0")
                ET.SubElement(sub, "failure", message=f"regressed: {region_text(x)}").text = region_text(x)
                cases.append(sub)
    fails = sum(1 for c in cases if c.find("failure") is not None)
    suite = ET.Element("testsuite", name="pbrcheck-gate", tests=str(len(cases)), failures=str(fails),
                       errors=str(sum(r.status == "error" for r in results)),
                       time=f"{sum(r.seconds for r in results):.3f}")
    suite.extend(cases)
    root = ET.Element("testsuites")
    root.append(suite)
    ET.indent(root)
    text = ET.tostring(root, encoding="unicode", xml_declaration=False)
    return write_text_atomic(Path(path), '<?xml version="1.0" encoding="utf-8"?>\n' + text + "\n")


#: Width in pixels of the summary's thumbnails (larger images are shown with an integer stride).
THUMB_WIDTH = 160
#: Relative difference |t1 - t0| / (t0 + REL_EPS) shown at full colour in the difference thumbnail.
DIFF_THUMB_MAX = 0.05


def write_thumbnails(folder: Path, r: Result) -> dict[str, Path]:
    """Before (baseline) / after (current) / difference PNGs of a check with a baseline."""
    from .maps import _save_rgb, display_rgb, false_colour  # matplotlib: only when thumbnails are written
    from .metrics import REL_EPS

    if r.baseline is None or r.test_image is None:
        return {}
    t0 = r.baseline.image.rgb.astype(np.float64)
    t1 = r.test_image.rgb.astype(np.float64)
    step = max(1, int(math.ceil(t0.shape[1] / THUMB_WIDTH)))
    opts = None
    if r.test_image.meta.get("options"):
        try:
            opts = json.loads(r.test_image.meta["options"])
        except ValueError:
            opts = None
    disp = (lambda x: np.clip(x, 0, 1)) if r.test_image.meta.get("display_referred") == "1" else (lambda x: display_rgb(x, opts))
    rel = (np.abs(t1 - t0) / (np.abs(t0) + REL_EPS)).max(axis=-1)
    stem = safe_name(r.check.name)
    out = {}
    for kind, img in (("before", disp(t0)), ("after", disp(t1)), ("diff", false_colour(rel, DIFF_THUMB_MAX, "inferno"))):
        out[kind] = _save_rgb(Path(folder) / f"{stem}-{kind}.png", img[::step, ::step])
    return out


def write_summary(path: Path, results: list[Result], budget_path: str = "BUDGET.toml") -> Path:
    """Write the Markdown summary (for a CI job summary): every check's outcome, metrics against
    budgets and change against its baseline, a per-object table and before / after / difference
    thumbnails for every check that is not ``pass`` (PNGs in ``<summary stem>-img/`` beside it)."""
    path = Path(path)
    img_dir = path.parent / f"{path.stem}-img"
    lines = ["# pbrcheck gate", "", "| check | outcome | metric | value | budget |", "|---|---|---|---|---|"]
    for r in results:
        budgets = [(m, b, ">") for m, b in r.check.max.items()] + [(m, b, "<") for m, b in r.check.min.items()]
        if r.status == "error":
            lines.append(f"| {r.check.name} | {r.status.upper()} | | | {r.error} |")
            continue
        failed = {f["metric"] for f in r.failures}
        for m, b, op in budgets:
            st = "FAIL" if m in failed else r.outcome
            lines.append(f"| {r.check.name} | {st} | {m} | {format_value(r.metrics.get(m))} | "
                         f"{'<=' if op == '>' else '>='} {format_value(b)} |")
    sens = [f"- {r.check.name}: {sensitivity_text(r)}" for r in results if r.sensitivity]
    if sens:
        lines += ["", "## Sensitivity (smallest change the baseline comparison detects)", ""] + sens
    for r in results:
        if r.change is None or r.change.verdict == "pass":
            continue
        lines += ["", f"## {r.check.name}: {r.change.verdict}", ""] + [l.strip() for l in change_lines(r, budget_path)[:1]]
        if r.likely:
            lines.append(f"\nLikely term: {r.likely}.")
        thumbs = write_thumbnails(img_dir, r)
        if thumbs:
            rel = {k: f"{img_dir.name}/{p.name}" for k, p in thumbs.items()}
            lines += ["", "| before (baseline) | after | difference (0..5 %) |", "|---|---|---|",
                      f"| ![before]({rel['before']}) | ![after]({rel['after']}) | ![difference]({rel['diff']}) |"]
        rows = [x for x in r.change.regions if x.name.startswith("object ") and x.state != "same"]
        lines += ["", "| object | state | bias | relmse before | relmse after | change | sigma (ref. noise) |",
                  "|---|---|---|---|---|---|---|"]
        for x in rows:
            lines.append(f"| {x.name[7:]} | {x.state} | {_pct(x.bias)} | {format_value(x.relmse_before)} | "
                         f"{format_value(x.relmse_after)} | {_pct(x.relative_d)} | {format_value(x.sigma_d)} |")
        if not rows:
            lines.append("| (no object changed; screen tiles did) | | | | | | |")
    refs = [f"- {r.check.name}: {r.verdict.provenance()}; budgets / noise: "
            + ", ".join(f"{b['metric']} {b['ratio']:.3g}x" for b in r.budget_noise) + noise_note(r)
            for r in results if r.verdict is not None]
    if refs:
        lines += ["", "## References (noise floor against the error and the budgets; goal >= 10x)", ""] + refs
    fails = [l for r in results for l in failure_lines(r)]
    if fails:
        lines += ["", "## Failures", ""] + [f"- {l}" for l in fails]
    return write_text_atomic(path, "\n".join(lines) + "\n")


_HTML = """<!doctype html><html><head><meta charset="utf-8"><title>pbrcheck gate</title><style>
body{{font-family:sans-serif;margin:1em 2em}} table{{border-collapse:collapse}} td,th{{border:1px solid #ccc;padding:2px 6px;text-align:right}}
.l{{text-align:left}} figure{{display:inline-block;margin:4px;vertical-align:top}}
.cmp{{position:relative;width:300px;display:inline-block}}
.cmp img{{display:block;width:300px;image-rendering:pixelated}}
.cmp img.top{{position:absolute;left:0;top:0;clip-path:inset(0 calc(100% - var(--pos,50%)) 0 0)}}
.cmp input{{width:300px}} img.img{{width:300px;image-rendering:pixelated}}
</style></head><body><h1>pbrcheck gate: {budget}</h1>
<p>Every check that is not <code>pass</code>: the slider shows the accepted baseline (left) against the
current render (right); the difference is |after - before| / (before + 0.01), 0 to 5 %.</p>
{body}</body></html>
"""


def write_html(folder: Path, results: list[Result], budget_path: str = "BUDGET.toml") -> Path | None:
    """``--html DIR``: ``DIR/index.html`` with the report's slider (baseline / current), the
    difference and the region table for every check that is not ``pass``. Written atomically."""
    import html as _h

    folder = Path(folder)
    parts = []
    for r in results:
        if r.outcome == "pass":
            continue
        parts.append(f"<h2>{_h.escape(r.check.name)}: {_h.escape(r.outcome)}</h2>")
        lines = failure_lines(r) + change_lines(r, budget_path) + ([f"error: {r.error}"] if r.error else [])
        parts.append("<pre>" + _h.escape("\n".join(lines)) + "</pre>")
        thumbs = write_thumbnails(folder, r)
        if thumbs:
            b, a, d = (thumbs[k].name for k in ("before", "after", "diff"))
            parts.append(f'<figure><div class="cmp" style="--pos:50%"><img src="{a}" alt="after"><img class="top" '
                         f'src="{b}" alt="before"><input type="range" min="0" max="100" value="50" aria-label="baseline / '
                         f'current split" oninput="this.parentNode.style.setProperty(\'--pos\',this.value+\'%\')"></div>'
                         f'<figcaption>slider: baseline (left) / current (right)</figcaption></figure>'
                         f'<figure><img class="img" src="{d}" alt="difference"><figcaption>difference</figcaption></figure>')
        if r.change is not None:
            parts.append("<table><tr><th class='l'>region</th><th>state</th><th>bias</th><th>relmse before</th>"
                         "<th>relmse after</th><th>change</th></tr>")
            for x in r.change.regions:
                if x.state != "same":
                    parts.append(f"<tr><td class='l'>{_h.escape(x.name)}</td><td>{x.state}</td><td>{_pct(x.bias)}</td>"
                                 f"<td>{format_value(x.relmse_before)}</td><td>{format_value(x.relmse_after)}</td>"
                                 f"<td>{_pct(x.relative_d)}</td></tr>")
            parts.append("</table>")
    if not parts:
        parts.append("<p>Every check passes.</p>")
    return write_text_atomic(folder / "index.html", _HTML.format(budget=_h.escape(str(budget_path)), body="\n".join(parts)))


def _takes_hooks(check: Check) -> bool:
    """Whether the check's renderer takes shader hooks (a real-time preset with ``shading = material``)
    and has no ``hook_lod`` of its own (the LOD probe replaces it)."""
    if check.test is not None or renderers.is_external(check.preset):
        return False
    try:
        no_hook = {k: v for k, v in check.options.items() if k != "shader"}
        o = renderers.RendererSpec.parse(check.preset, no_hook).options
    except PbrcheckError:
        return False
    if not SHADINGS[o.shading].extra.get("hooks"):
        return False
    shader = check.options.get("shader")
    return not (shader and "hook_lod" in Path(shader).read_text(encoding="utf-8", errors="replace"))


def _accept_one(r: Result, base: Path, staging: Path, reason: str, date: str, progress: bool) -> str:
    """Measure the run-to-run spread and the LOD probe of one check, stage its baseline; returns the
    history line (the figures)."""
    from .baseline import LOD_PROBE_HOOK, SPREAD_RUNS, probe_response, shader_sources_hash, spread_of, stage_baseline

    c = r.check
    scene = _scene_arg(base, c.scene) if c.scene else None
    spec = renderers.RendererSpec.parse(c.preset, c.options) if c.test is None else None
    images = [r.test_image.rgb]
    probe = None
    if c.test is None:
        for _ in range(SPREAD_RUNS - 1):
            renderers.trim_caches(0)  # every run bakes its environment afresh
            images.append(renderers.render_under_test(scene, spec, progress=progress, use_cache=False).rgb)
        if _takes_hooks(c):
            import tempfile

            with tempfile.TemporaryDirectory(prefix="pbrcheck-lod-probe-") as d:
                hook = Path(d) / "lod_probe.glsl"
                hook.write_text(LOD_PROBE_HOOK, encoding="utf-8")
                img = renderers.render_under_test(scene, spec.with_options(shader=str(hook)), progress=progress)
            probe = probe_response(r.ref_image, r.test_image.rgb, img.rgb, r.test_image, r.names)
    spread = spread_of(images)
    meta = r.test_image.meta
    record = {
        "check": c.name, "accepted": date, "reason": reason, "preset": c.preset if c.test is None else None,
        "test": c.test, "scene": c.scene, "options": json.loads(meta["options"]) if meta.get("options") else c.options,
        "shader_sources_sha256": shader_sources_hash() if c.test is None and not renderers.is_external(c.preset) else None,
        "hook": json.loads(meta["shader"]) if meta.get("shader") else None,
        "renderer": meta.get("renderer"), "version": meta.get("version"), "gl_renderer": meta.get("gl_renderer"),
        "runs": len(images), "bit_exact": bool(np.all(spread == 0)), "spread_max": float(spread.max()),
        "metrics": r.metrics, "lod_probe": probe,
        "conventions": "regions: 'object NAME' and 'tile xA-B,yC-D' (compare/baseline.py); lod_probe: per region "
                       "bias and change of a render LOD_PROBE mip deeper",
    }
    stage_baseline(staging, safe_name(c.name), r.test_image, spread, record)
    before = r.change.verdict if r.change is not None else "new"
    fig = ", ".join(f"{k} {format_value(r.metrics.get(k))}" for k in r.check.max)
    return (f"{c.name}: {before}; {fig}; {'bit-exact' if record['bit_exact'] else 'spread max ' + format_value(record['spread_max'])}"
            f" over {len(images)} runs")


def _toml_str(s: str) -> str:
    return json.dumps(s, ensure_ascii=False)


def accept(budget: Path, results: list[Result], reason: str, *, progress: bool = True, stream=None) -> None:
    """Rewrite every check's baseline from ``results`` and append ``reason``, the date and the figures to
    the budget's ``[[history]]``. The baselines are written into a staging folder first and renamed
    into place only when every one is written; the budget file is rewritten atomically."""
    import datetime
    import os
    import shutil
    import tempfile

    from .baseline import BASELINE_DIR

    stream = stream or sys.stdout
    base = Path(budget).parent
    date = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    target = base / BASELINE_DIR
    target.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=".staging-", dir=target))
    try:
        lines = [_accept_one(r, base, staging, reason, date, progress) for r in results]
        for p in sorted(staging.iterdir()):
            os.replace(p, target / p.name)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    text = Path(budget).read_text(encoding="utf-8")
    block = (f"\n[[history]]\ndate = {_toml_str(date)}\nreason = {_toml_str(reason)}\nfigures = [\n"
             + "".join(f"  {_toml_str(l)},\n" for l in lines) + "]\n")
    write_text_atomic(Path(budget), text.rstrip("\n") + "\n" + block)
    for l in lines:
        print(f"accepted {l}", file=stream)
    print(f"gate: {len(lines)} baseline(s) written to {target}; history appended to {budget}", file=stream)


def run_gate(budget: str | Path, *, junit: str | None = None, summary: str | None = None,
             maps_dir: str | None = None, html: str | None = None, accept_reason: str | None = None,
             progress: bool = True, stream=None, only: list[str] | None = None) -> int:
    """Run every check of ``budget``; print one line per check and the totals.

    Parameters
    ----------
    budget : str or Path
        The budget TOML file (:func:`load_budget`).
    junit, summary : str, optional
        Write JUnit XML / a Markdown summary (with thumbnails in ``<stem>-img/``) there.
    maps_dir : str, optional
        Error maps of checks that are not ``pass`` go to ``maps_dir/<check>``.
    html : str, optional
        Write ``html/index.html``: the slider of every check that is not ``pass``.
    accept_reason : str, optional
        Accept the current renders as the baselines (:func:`accept`) with this reason; refused
        (nothing written) when a check errors.
    progress : bool, optional
        Show render progress on stderr.
    stream : file, optional
        Where the lines go (default stdout).
    only : list of str, optional
        Run only the checks of these names (``--check``); with ``accept_reason`` only their
        baselines are rewritten (the others' stay as accepted).

    Returns
    -------
    int
        0: every check passes (or improved, or changed with ``on_change = "pass"``; or accepted);
        1: a budget is broken, a check regressed, or changed; >= 2 a check could not be evaluated
        (the largest exit code).

    Raises
    ------
    BudgetError
        The budget file is missing or malformed (nothing is rendered).
    """
    stream = stream or sys.stdout
    checks, base = load_budget(budget)
    if only:
        unknown = sorted(set(only) - {c.name for c in checks})
        if unknown:
            raise BudgetError(f"{budget}: --check {unknown[0]!r}: no such check (checks: "
                              + ", ".join(c.name for c in checks) + ")")
        checks = [c for c in checks if c.name in only]
    settings = budget_settings(budget)
    # the outputs' paths are checked before any render (a crash after the work helps nobody)
    for out, folder in ((junit, False), (summary, False), (maps_dir, True), (html, True)):
        if out:
            check_output_path(out, folder=folder)
    results = []
    for c in checks:
        r = run_check(c, base, maps_dir=Path(maps_dir) if maps_dir else None, progress=progress)
        if r.status != "error" and r.baseline is None and settings["require_baselines"] \
                and accept_reason is None:
            r.status, r.exit_code = "error", 2
            r.error = (f"no accepted baseline ({Path(base) / 'baselines' / safe_name(c.name)}.exr) and the budget sets "
                       f"require_baselines = true; accept one: pbrcheck gate {budget} --accept --reason \"...\"")
        results.append(r)
        if r.status == "error":
            print(f"ERROR {c.name}: {r.error}", file=stream)
            continue
        for line in failure_lines(r):
            print(line, file=stream)
        for line in change_lines(r, str(budget)):
            print(line, file=stream)
        print(_check_line(r), file=stream)
        if r.maps:
            print(f"     error maps: {Path(r.maps['rel_error']).parent}", file=stream)
    if junit:
        write_junit(Path(junit), results)
    if summary:
        write_summary(Path(summary), results, str(budget))
    if html:
        print(f"gate: page {write_html(Path(html), results, str(budget))}", file=stream)
    n = {s: sum(r.outcome == s for r in results)
         for s in ("pass", "fail", "regressed", "improved", "changed", "error")}
    print("gate: " + ", ".join(f"{v} {k}" for k, v in n.items() if v or k == "pass"), file=stream)
    errors = [r.exit_code for r in results if r.status == "error"]
    if errors:
        if accept_reason is not None:
            print("gate: nothing accepted (a check errored)", file=stream)
        return max(errors)
    if accept_reason is not None:
        accept(Path(budget), results, accept_reason, progress=progress, stream=stream)
        return 0
    return max((r.exit_code for r in results), default=0)
