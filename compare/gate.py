"""CI error-budget gate: ``pbrcheck gate BUDGET.toml``.

Budget format (TOML; see docs/compare.md)::

    [[check]]
    name = "spheres-default"         # required, unique
    scene = "spheres"                # built-in name or TOML path (relative to the budget file)
    preset = "default"               # real-time preset or ext:NAME (docs/renderers.md)
    options = { }                    # optional real-time option overrides
    # shader = "hooks/ue4.glsl"      # optional shader hook file (relative to the budget file)
    reference = "refs/spheres.exr"   # stored EXR (relative to the budget file) or "auto"
    spp = 64                         # with reference = "auto": samples per pixel (default 64)
    # test = "engine_out.exr"        # instead of preset: gate an image from any engine (scene
                                     # then only names objects / renders an "auto" reference)
    [check.max]                      # metric = largest allowed value
    relmse = 0.01
    [check.min]                      # optional: metric = smallest allowed value (e.g. psnr)
    psnr = 30

Outcome per check: ``pass``, ``fail`` (a metric outside its budget) or ``error`` (missing or
unreadable image, size mismatch, NaN, bad scene...). Trusted verdicts: a budget is trusted when it
sits :data:`BUDGET_NOISE_FACTOR` (10) times above the reference's noise in its own metric (the
metric of a simulated noise-only pair, :func:`compare.metrics.noise_floor`); an ``auto`` reference
is rendered from ``spp`` up (powers of two, at most ``spp_cap``, default 4096) until its noise floor
is also 10x below the check's error (:mod:`compare.verdict_spp`). Where a budget is not trusted the
check's line says ``noise-limited`` with the spp that would be (it still passes or fails on its
budgets); the reference's spp and these figures are in the JUnit output and the summary. Exit status: 2 if any check errored (never
pass on missing data), else 1 if any failed, else 0. A malformed budget is an error before any
check runs (exit 2, nothing written).
"""

from __future__ import annotations

import math
import sys
import time
import tomllib
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

from pbrcheck.atomic import check_output_path, write_bytes_atomic, write_text_atomic
from pbrcheck.environment import scene_hash
from pbrcheck.errors import PbrcheckError, decode_reason
from pbrcheck.exr import RGB, read_exr
from pbrcheck.fmt import format_value
from pbrcheck.gltf_scene import RASTER_MISSING, split_presets
from pbrcheck.scene import builtin_scene_names, load_scene

from . import renderers
from .maps import safe_name, write_maps
from .metrics import METRICS, compare_images, worse
from .verdict_spp import DEFAULT_SPP_CAP, MIN_REFERENCE_SPP, VerdictSpp, reference_for_verdict, verdict_of

CHECK_KEYS = {"name", "scene", "preset", "options", "shader", "reference", "spp", "spp_cap", "test", "max", "min",
              "mode", "seed"}
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


@dataclass
class Result:
    """The outcome of one :class:`Check`: ``pass``, ``fail`` (with each broken bound, its worst
    objects and whether the reference's noise could explain it) or ``error`` (with the message and
    the exit code it maps to)."""
    check: Check
    status: str                      # pass | fail | error | skip (a real-time preset on an asset scene)
    metrics: dict | None = None
    failures: list[dict] = field(default_factory=list)
    error: str | None = None
    exit_code: int = 0
    seconds: float = 0.0
    maps: dict = field(default_factory=dict)
    verdict: VerdictSpp | None = None  # the reference's spp and noise floor against the error
    budget_noise: list = field(default_factory=list)  # per budget: the reference's noise in its metric


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
    extra = set(data) - {"check"}
    if extra:
        raise _err(path, sorted(extra)[0], "only [[check]] tables", sorted(extra)[0])
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
        for k in ("scene", "preset", "reference", "test", "mode", "shader"):
            if k in t and not isinstance(t[k], str):
                raise _err(path, f"{w}.{k}", "a string", t[k])
        if "reference" not in t:
            raise _err(path, f"{w}.reference", 'a stored EXR path or "auto" (required)', "nothing")
        has_test, has_scene = "test" in t, "scene" in t
        if not (has_test or has_scene):
            raise _err(path, w, "scene (rendered with preset) or test (an image path)", "neither")
        if t["reference"] == "auto" and not has_scene:
            raise _err(path, f"{w}.reference", '"auto" only together with scene', "auto")
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
                         seed=t.get("seed", 0), spp_cap=t.get("spp_cap", DEFAULT_SPP_CAP)))
    return out, path.parent


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
        if check.test is None and scene is not None and split_presets(scene, [check.preset])[1]:
            res.status, res.error, res.exit_code = "skip", f"{check.preset} on a glTF asset scene: {RASTER_MISSING}", 0
            res.seconds = time.perf_counter() - t0
            return res
        if check.test is not None:
            test_path = _resolve(base, check.test)
            test = read_exr(test_path, require=RGB)
            test_name = str(test_path)
        else:
            test = renderers.render_under_test(scene, check.preset, check.options or None, progress=progress)
            test_name = check.preset if renderers.is_external(check.preset) else f"real-time {check.preset}"
        if check.reference == "auto":
            ref, res.verdict = reference_for_verdict(scene, [test], spp=check.spp, cap=check.spp_cap,
                                                     mode=check.mode, seed=check.seed, use_cache=True,
                                                     progress=progress)
            ref_name = f"auto reference ({check.scene}, {res.verdict.spp} spp)"
        else:
            ref_path = _resolve(base, check.reference)
            ref = read_exr(ref_path, require=RGB)
            ref_name = str(ref_path)
            if scene is not None and ref.meta.get("scene_hash"):
                # A stored reference of another scene (an edited scene file, a stale EXR) would make
                # the gate measure a scene mismatch, not the shaders: refuse it.
                want = scene_hash(scene)
                if ref.meta["scene_hash"] != want:
                    raise BudgetError(f"{ref_path}: reference was rendered for scene hash "
                                      f"{ref.meta['scene_hash'][:16]}, but {check.scene} hashes to {want[:16]}; "
                                      f"re-render it (pbrcheck reference ... --out {check.reference})")
        cmp = compare_images(ref, test, scene=scene, ref_name=ref_name, test_name=test_name)
        if res.verdict is None:
            res.verdict = verdict_of(ref, cmp.summary["noise"])
        res.budget_noise = budget_noise(check, cmp.summary["noise"], res.verdict.spp)
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
    if res.failures and maps_dir is not None:
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


def write_junit(path: Path, results: list[Result]) -> Path:
    """Write the results as JUnit XML (one testcase per check; failures and errors as such)."""
    suite = ET.Element("testsuite", name="pbrcheck-gate", tests=str(len(results)),
                       failures=str(sum(r.status == "fail" for r in results)),
                       errors=str(sum(r.status == "error" for r in results)),
                       time=f"{sum(r.seconds for r in results):.3f}")
    for r in results:
        tc = ET.SubElement(suite, "testcase", classname="pbrcheck.gate", name=r.check.name, time=f"{r.seconds:.3f}")
        if r.status == "fail":
            lines = failure_lines(r)
            ET.SubElement(tc, "failure", message=lines[0]).text = "\n".join(lines)
        elif r.status == "error":
            ET.SubElement(tc, "error", message=r.error or "error").text = r.error
        elif r.status == "skip":
            ET.SubElement(tc, "skipped", message=r.error or "skipped")
        if r.metrics:
            lines = [f"{k} = {format_value(v)}" for k, v in r.metrics.items()]
            if r.verdict is not None:
                lines.append(f"reference: {r.verdict.provenance()}")
            lines += [f"budget {b['metric']}: {b['ratio']:.3g}x the reference's noise" for b in r.budget_noise]
            ET.SubElement(tc, "system-out").text = "\n".join(lines)
    root = ET.Element("testsuites")
    root.append(suite)
    return write_bytes_atomic(path, ET.tostring(root, encoding="utf-8", xml_declaration=True))


def write_summary(path: Path, results: list[Result]) -> Path:
    """Write a Markdown table of every check's metrics against its budgets (for CI summaries)."""
    icon = {"pass": "PASS", "fail": "FAIL", "error": "ERROR", "skip": "SKIP"}
    lines = ["# pbrcheck gate", "", "| check | status | metric | value | budget |", "|---|---|---|---|---|"]
    for r in results:
        budgets = [(m, b, ">") for m, b in r.check.max.items()] + [(m, b, "<") for m, b in r.check.min.items()]
        if r.status in ("error", "skip"):
            lines.append(f"| {r.check.name} | {icon[r.status]} | | | {r.error} |")
            continue
        failed = {f["metric"] for f in r.failures}
        for m, b, op in budgets:
            st = "FAIL" if m in failed else "pass"
            lines.append(f"| {r.check.name} | {st} | {m} | {format_value(r.metrics.get(m))} | "
                         f"{'<=' if op == '>' else '>='} {format_value(b)} |")
    refs = [f"- {r.check.name}: {r.verdict.provenance()}; budgets / noise: "
            + ", ".join(f"{b['metric']} {b['ratio']:.3g}x" for b in r.budget_noise) + noise_note(r)
            for r in results if r.verdict is not None]
    if refs:
        lines += ["", "## References (noise floor against the error and the budgets; goal >= 10x)", ""] + refs
    fails = [l for r in results for l in failure_lines(r)]
    if fails:
        lines += ["", "## Failures", ""] + [f"- {l}" for l in fails]
    return write_text_atomic(path, "\n".join(lines) + "\n")


def run_gate(budget: str | Path, *, junit: str | None = None, summary: str | None = None,
             maps_dir: str | None = None, progress: bool = True, stream=None) -> int:
    """Run every check of ``budget``; print one line per check and the totals.

    Parameters
    ----------
    budget : str or Path
        The budget TOML file (:func:`load_budget`).
    junit, summary : str, optional
        Write JUnit XML / a Markdown summary there.
    maps_dir : str, optional
        Error maps of failing checks go to ``maps_dir/<check>``.
    progress : bool, optional
        Show render progress on stderr.
    stream : file, optional
        Where the lines go (default stdout).

    Returns
    -------
    int
        0 all pass, 1 a check failed, >= 2 a check could not be evaluated (the largest exit code).

    Raises
    ------
    BudgetError
        The budget file is missing or malformed (nothing is rendered).
    """
    stream = stream or sys.stdout
    checks, base = load_budget(budget)
    # the outputs' paths are checked before any render (a crash after the work helps nobody)
    for out, folder in ((junit, False), (summary, False), (maps_dir, True)):
        if out:
            check_output_path(out, folder=folder)
    results = []
    for c in checks:
        r = run_check(c, base, maps_dir=Path(maps_dir) if maps_dir else None, progress=progress)
        results.append(r)
        if r.status == "pass":
            print(f"pass {c.name}{noise_note(r)}", file=stream)
        elif r.status == "fail":
            for line in failure_lines(r):
                print(line, file=stream)
            if r.maps:
                print(f"     error maps: {Path(r.maps['rel_error']).parent}", file=stream)
        elif r.status == "skip":
            print(f"skip {c.name}: {r.error}", file=stream)
        else:
            print(f"ERROR {c.name}: {r.error}", file=stream)
    if junit:
        write_junit(Path(junit), results)
    if summary:
        write_summary(Path(summary), results)
    n = {s: sum(r.status == s for r in results) for s in ("pass", "fail", "error", "skip")}
    print(f"gate: {n['pass']} passed, {n['fail']} failed, {n['error']} error(s)"
          + (f", {n['skip']} skipped (real-time presets on glTF asset scenes)" if n["skip"] else ""), file=stream)
    errors = [r.exit_code for r in results if r.status == "error"]
    if errors:
        return max(errors)
    return 1 if n["fail"] else 0
