"""The one value formatter of pbrcheck's tables, messages and report.

API
---
- :func:`format_value` -- a number with ``digits`` significant digits; ``n/a`` for ``None`` and
  NaN (an undefined metric), ``inf`` / ``-inf`` for infinities; anything else as ``str``.
- :data:`TABLE_DIGITS`, :data:`MESSAGE_DIGITS` -- the two precisions in use: 4 significant digits
  in tables a person reads across (report, research tables), 6 in CLI metric lines and the gate,
  where a value is compared with its budget.
- :func:`terminal_safe`, :func:`xml_text`, :func:`markdown_cell`, :func:`csv_cell` -- a name from
  an untrusted scene or asset made safe for one output format (a terminal line, XML 1.0 character
  data, a Markdown table cell, a spreadsheet cell). Every writer of a name into such an output goes
  through one of these (docs/security.md).
- :func:`file_name_part` -- a name made one part of a file name (a command's default output path).

References
----------
- W3C, Extensible Markup Language (XML) 1.0, section 2.2 "Characters" (the legal ``Char`` ranges).
- OWASP, "CSV Injection" (cells beginning with ``= + - @``, tab or carriage return).
"""

from __future__ import annotations

import math
import re

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


#: C0 and C1 control characters and DEL: a terminal interprets them (ESC starts an ANSI sequence,
#: CR rewinds the line, BS erases), so a name that holds one can forge or hide output.
_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f]")


def terminal_safe(s: str) -> str:
    """``s`` with every control character shown as its Python escape (``\\x1b``, ``\\n``).

    For names printed on a terminal (gate lines, ``check-scene``, stderr messages): the text stays
    one line and no escape sequence reaches the terminal. Printable text, non-ASCII included, is kept.
    """
    return _CONTROL.sub(lambda m: repr(m.group())[1:-1], str(s))


#: Characters XML 1.0 forbids anywhere in a document (section 2.2): C0 controls but tab, LF and CR;
#: the surrogates; U+FFFE and U+FFFF.
_XML_ILLEGAL = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\ud800-\udfff\ufffe\uffff]")


def xml_text(s: str) -> str:
    """``s`` as XML 1.0-legal text: characters XML forbids replaced by their escape in visible form
    (``\\x1b``); the markup characters are left to the XML writer's own escaping."""
    return _XML_ILLEGAL.sub(lambda m: repr(m.group())[1:-1], str(s))


def markdown_cell(s: str) -> str:
    """``s`` for one cell of a Markdown (GitHub) table: one line, no raw HTML, no column break.

    Control characters escaped (:func:`terminal_safe`; newlines become ``\\n``), ``&``, ``<``, ``>``
    as HTML entities (GitHub renders inline HTML in a table), ``|`` and the backslash escaped, and
    the inline-markup characters (`` ` * _ [ ] ``) escaped so a name cannot become a link or code span.
    """
    s = terminal_safe(s)
    s = s.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
    return re.sub(r"([\\|`*_\[\]])", r"\\\1", s)


#: First characters that make a spreadsheet read a cell as a formula (OWASP "CSV Injection").
_FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def csv_cell(v):
    """A value for a CSV cell: a string that begins with ``= + - @``, tab or CR is prefixed with a
    single quote so a spreadsheet shows it as text (OWASP's rule); numbers and None are returned
    unchanged (a negative number is data, not a formula)."""
    if isinstance(v, str) and v.startswith(_FORMULA_START):
        return "'" + v
    return v


#: What a file name made from a name keeps: letters and digits (any script), ``_ . + -``.
_FILE_NAME_DROP = re.compile(r"[^\w.+-]")


def file_name_part(s: str, default: str = "scene") -> str:
    """``s`` as one part of a file name (a default output path such as ``out/realtime/NAME_PRESET.exr``):
    every other character (a path separator, a control character) becomes ``_``, leading dots are
    removed (no ``..``, no hidden file); ``default`` when nothing is left. A scene named
    ``../../x`` cannot write outside the output folder."""
    out = _FILE_NAME_DROP.sub("_", str(s)).lstrip(".")
    return out or default
