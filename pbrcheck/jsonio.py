"""The one JSON writer of pbrcheck: strict JSON (no NaN or Infinity), written atomically.

API
---
- :func:`jsonable` -- a value with non-finite floats replaced by ``None`` and dataclasses / objects
  with a ``to_json()`` method converted, recursively.
- :func:`dump_json` -- the text (2-space indent) of :func:`jsonable`.
- :func:`write_json_atomic` -- :func:`dump_json` plus a newline, written with
  :func:`pbrcheck.atomic.write_text_atomic` (a reader sees the old file or the new one).
- :func:`read_json` -- a JSON file's value, or the caller's typed error naming the file and what
  was expected (unreadable, not UTF-8, not JSON).

Python's ``json`` writes ``NaN`` and ``Infinity`` by default, which no strict JSON reader accepts;
a metric that is undefined (no valid pixel) is ``null`` instead.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

from .atomic import write_text_atomic


def jsonable(x):
    """``x`` as plain JSON values: non-finite floats become ``None``; objects with ``to_json()``
    and dataclasses become dicts; tuples become lists.

    Parameters
    ----------
    x : object
        Nested dicts, lists, tuples, numbers, strings, dataclasses or objects with ``to_json()``.

    Returns
    -------
    object
        A value :func:`json.dumps` accepts with ``allow_nan=False``.
    """
    if hasattr(x, "to_json") and not isinstance(x, type):
        return jsonable(x.to_json())
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        return jsonable(dataclasses.asdict(x))
    if isinstance(x, dict):
        return {k: jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def dump_json(obj, indent: int = 2) -> str:
    """Strict JSON text of ``obj`` (see :func:`jsonable`).

    Parameters
    ----------
    obj : object
        What to serialize.
    indent : int, optional
        Indentation in spaces (default 2).

    Returns
    -------
    str
        The JSON text, without a trailing newline.
    """
    return json.dumps(jsonable(obj), indent=indent, allow_nan=False)


def write_json_atomic(path: str | Path, obj, indent: int = 2) -> Path:
    """Write :func:`dump_json` ``(obj, indent)`` and a newline to ``path`` atomically, creating its
    folder; returns ``path`` (a :class:`~pathlib.Path`)."""
    return write_text_atomic(path, dump_json(obj, indent) + "\n")


def read_json(path: str | Path, error: type[Exception], what: str):
    """The value of the JSON file ``path``; an unreadable file or invalid JSON raises ``error`` with
    one line ``PATH: cannot read WHAT (reason)`` (``what``: e.g. "a fitted LOD mapping")."""
    p = Path(path)
    try:
        return json.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise error(f"{p}: cannot read {what} ({e})") from None
