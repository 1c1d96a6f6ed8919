"""A gate budget file, parsed and validated once: :func:`load_budget` -> :class:`Budget`.

Format (TOML; docs/compare.md)::

    [[check]]
    name = "spheres-default"         # required, unique
    scene = "spheres"                # built-in name or TOML path (relative to the budget file)
    preset = "default"               # real-time preset or ext:NAME (docs/renderers.md)
    options = { }                    # optional real-time option overrides
    # shader = "hooks/ue4.glsl"      # optional shader hook file (relative to the budget file)
    reference = "refs/spheres.exr"   # stored EXR (relative to the budget file) or "auto"
    # reference_scene = "spheres_ms.toml"  # optional: the reference's scene, the check's scene but
                                     # for [brdf] (the model the engine means to render)
    spp = 64                         # with reference = "auto": samples per pixel (default 64)
    # test = "engine_out.exr"        # instead of preset: gate an image from any engine
    [check.max]                      # metric = largest allowed value
    relmse = 0.01
    [check.min]                      # optional: metric = smallest allowed value (e.g. psnr)
    psnr = 30

Top level (optional): ``require_baselines = true`` (a check without an accepted baseline is an
error), ``on_change = "fail" | "pass"`` (also per check), ``[[history]]`` (appended by ``--accept``).
Metric names are those of :data:`compare.metrics.METRICS`. A malformed budget raises
:class:`BudgetError` naming the file and the field, before any check runs.

API
---
- :class:`Budget`, :class:`Check`, :class:`BudgetError`.
- :func:`load_budget` -- parse and validate (a committed ``--accept`` left unfinished is completed
  first: :func:`compare.baseline.finish_accepts`).
- :func:`resolve`, :func:`scene_arg`, :func:`reference_scene` -- a check's paths and scenes.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from pbrcheck.errors import PbrcheckError, decode_reason
from pbrcheck.scene import builtin_scene_names, load_scene

from ..baseline import finish_accepts
from ..maps import safe_name
from ..metrics import METRICS
from ..unmodelled import ALLOW_KEY, allowed_features
from ..verdict_spp import DEFAULT_SPP_CAP, MIN_REFERENCE_SPP

CHECK_KEYS = {"name", "scene", "preset", "options", "shader", "reference", "reference_scene", "spp", "spp_cap", "test", "max", "min",
              "mode", "seed", "on_change", ALLOW_KEY}
#: Top-level keys of a budget file besides [[check]].
BUDGET_KEYS = {"check", "history", "on_change", "require_baselines"}
#: What a ``changed`` verdict (differs from the baseline, neither better nor worse) does.
ON_CHANGE = ("fail", "pass")
DEFAULT_SPP = 64


class BudgetError(PbrcheckError):
    """A malformed budget file (names the file and the field)."""


@dataclass(frozen=True)
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
    # Unmodelled features judged anyway (compare.unmodelled: otherwise the check is NOT_JUDGED).
    allow_unmodelled: tuple[str, ...] = ()


@dataclass(frozen=True)
class Budget:
    """A parsed budget: its ``path``, the folder ``base`` its relative paths are resolved against,
    the ``checks``, the top-level settings and the number of ``[[history]]`` entries."""
    path: Path
    checks: tuple[Check, ...]
    require_baselines: bool = False
    on_change: str = "fail"
    history: int = 0

    @property
    def base(self) -> Path:
        return self.path.parent

    def only(self, names: list[str] | None) -> tuple[Check, ...]:
        """The checks named in ``names`` (``--check``), all of them for None / empty; an unknown
        name is a :class:`BudgetError`."""
        if not names:
            return self.checks
        unknown = sorted(set(names) - {c.name for c in self.checks})
        if unknown:
            raise BudgetError(f"{self.path}: --check {unknown[0]!r}: no such check (checks: "
                              + ", ".join(c.name for c in self.checks) + ")")
        return tuple(c for c in self.checks if c.name in names)


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


def _read(path: Path) -> dict:
    if not path.is_file():
        raise BudgetError(f"{path}: no such budget file")
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as e:
        raise BudgetError(f"{path}: invalid TOML: {e}") from None
    except UnicodeDecodeError as e:
        raise BudgetError(f"{path}: cannot read: {decode_reason(e)}") from None
    except OSError as e:
        raise BudgetError(f"{path}: cannot read: {e.strerror}") from None


def _check(path: Path, i: int, t, names: set, top_change: str) -> Check:
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
        shader = resolve(path.parent, t["shader"])
        if not shader.is_file():
            raise _err(path, f"{w}.shader", "an existing shader hook file", t["shader"])
        options["shader"] = str(shader)
    return Check(name=name, max=mx, min=mn, reference=t["reference"], scene=t.get("scene"),
                 preset=t.get("preset", "default"), options=options,
                 test=t.get("test"), spp=t.get("spp", DEFAULT_SPP), mode=t.get("mode", "local"),
                 seed=t.get("seed", 0), spp_cap=t.get("spp_cap", DEFAULT_SPP_CAP),
                 on_change=t.get("on_change", top_change), reference_scene=t.get("reference_scene"),
                 allow_unmodelled=allowed_features(t, path, w))


def load_budget(path: str | Path) -> Budget:
    """Parse and validate a budget file (once: every setting the gate reads is in the result).

    An ``--accept`` that committed its new baselines and history but was stopped before it put them
    all in place is completed first (:func:`compare.baseline.finish_accepts`), so the budget read
    here and the baselines beside it are one accepted set.

    Raises
    ------
    BudgetError
        The file is missing, unreadable or malformed (names the file and the field).
    """
    path = Path(path)
    if path.is_file():
        finish_accepts(path.parent)
    data = _read(path)
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
    names: set[str] = set()
    out = tuple(_check(path, i, t, names, top_change) for i, t in enumerate(checks))
    return Budget(path=path, checks=out, require_baselines=data.get("require_baselines", False),
                  on_change=top_change, history=len(data.get("history", [])))


def resolve(base: Path, p: str) -> Path:
    """``p`` (a path in a budget) against the budget's folder ``base``; absolute paths as they are."""
    q = Path(p).expanduser()
    return q if q.is_absolute() else base / q


def scene_arg(base: Path, s: str):
    """A check's scene: a built-in scene name, or a scene file relative to ``base``."""
    if not Path(s).suffix and s in builtin_scene_names():
        return load_scene(s)
    return load_scene(resolve(base, s))


def reference_scene(base: Path, check: Check, scene):
    """The check's ``reference_scene``, refused unless it is the check's scene but for ``[brdf]``
    (a model-matched reference: the objects, camera, lights and environment must be the same)."""
    ref_scene = scene_arg(base, check.reference_scene)
    a, b = scene.content_dict(), ref_scene.content_dict()
    a.pop("brdf"), b.pop("brdf")
    if a != b:
        diff = sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))
        raise BudgetError(f"reference_scene {check.reference_scene} differs from scene {check.scene} in "
                          f"{', '.join(diff)}: only [brdf] may differ (the reference's model)")
    return ref_scene
