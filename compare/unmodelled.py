"""The gate's rule for features pbrcheck does not model (:mod:`pbrcheck.unmodelled`): a check whose
scene uses one is ``not judged`` (exit 2: the gate cannot say whether the engine is right), unless
the check's budget allows that feature by name::

    [[check]]
    name = "clearcoat-threejs"
    scene = "clearcoat.toml"
    allow_unmodelled = ["KHR_materials_clearcoat"]   # judged anyway: the budget knows it is left out

API: :func:`unjudged_reason` (the reason a check is not judged, or None), :func:`allowed_features`
(the ``allow_unmodelled`` value of a check's table, validated), :data:`ALLOW_KEY`,
:class:`AllowError`. The gate raises :class:`compare.gate.NotJudged` with the reason (verdict
``NOT_JUDGED``, exit 2).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from pbrcheck.errors import PbrcheckError
from pbrcheck.fmt import terminal_safe

#: The key of a budget's check that allows unmodelled features by name.
ALLOW_KEY = "allow_unmodelled"


class AllowError(PbrcheckError):
    """A malformed ``allow_unmodelled`` (names the budget file and the check's field)."""


def allowed_features(table: Mapping, file: str | Path = "<budget>", where: str = "check") -> tuple[str, ...]:
    """``table[ALLOW_KEY]`` (absent: ``()``), which must be a list of non-empty strings (the features'
    names, as in ``extensionsUsed``); raises :class:`AllowError` otherwise."""
    v = table.get(ALLOW_KEY, [])
    if not isinstance(v, list) or not all(isinstance(x, str) and x.strip() for x in v):
        raise AllowError(f"{file}: {where}.{ALLOW_KEY}: expected a list of feature names "
                         f"(e.g. [\"KHR_materials_clearcoat\"]), found {v!r}")
    return tuple(v)


def unjudged_reason(scene, check_budget) -> str | None:
    """Why a check of ``scene`` is not judged (its scene uses features pbrcheck does not model that
    ``check_budget`` does not allow by name), or None (judged). ``check_budget``: the check's table
    (a mapping with :data:`ALLOW_KEY`) or a check object with an ``allow_unmodelled`` attribute;
    ``scene`` None (a check of a stored image without a scene): judged."""
    if scene is None:
        return None
    if isinstance(check_budget, Mapping):
        allow = set(allowed_features(check_budget))
    else:
        allow = set(getattr(check_budget, ALLOW_KEY, ()) or ())
    left: dict[str, set[str]] = {}
    for u in scene.unmodelled:
        if u.feature not in allow:
            left.setdefault(u.feature, set()).update(u.materials)
    if not left:
        return None
    named = "; ".join(f"{terminal_safe(f)} (materials: {', '.join(terminal_safe(m) for m in sorted(ms)) or 'none'})"
                      for f, ms in left.items())
    names = ", ".join(f'"{f}"' for f in left)
    return (f"the scene uses what pbrcheck does not model: {named}; the reference leaves it out, so the "
            f"engine cannot be judged; allow it by name with {ALLOW_KEY} = [{names}] "
            f"in the check's table to judge it anyway")
