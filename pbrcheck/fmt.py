"""The one value formatter of pbrcheck's tables, messages and report.

API
---
- :func:`format_value` -- a number with ``digits`` significant digits; ``n/a`` for ``None`` and
  NaN (an undefined metric), ``inf`` / ``-inf`` for infinities; anything else as ``str``.
- :data:`TABLE_DIGITS`, :data:`MESSAGE_DIGITS` -- the two precisions in use: 4 significant digits
  in tables a person reads across (report, research tables), 6 in CLI metric lines and the gate,
  where a value is compared with its budget.
"""

from __future__ import annotations

import math

#: Significant digits in tables (report, research tables).
TABLE_DIGITS = 4
#: Significant digits in CLI metric lines and gate results.
MESSAGE_DIGITS = 6


def format_value(v, digits: int = MESSAGE_DIGITS) -> str:
    """A value for a table or a message.

    Parameters
    ----------
    v : float, int, None or object
        The value.
    digits : int, optional
        Significant digits of a number (default :data:`MESSAGE_DIGITS`).

    Returns
    -------
    str
        ``n/a`` for None or NaN, ``inf`` or ``-inf``, ``f"{v:.{digits}g}"`` for a float; anything
        else (an int, a string) as ``str(v)``.
    """
    if v is None:
        return "n/a"
    if not isinstance(v, float):
        return str(v)  # ints (pixel counts, spp) exactly; bool and str as they are
    if math.isnan(v):
        return "n/a"
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    return f"{v:.{digits}g}"
