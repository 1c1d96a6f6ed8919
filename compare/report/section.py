"""The report's typed sections: what every section builder returns and the page template reads.

API
---
:class:`Table` (caption, headers, rows of display strings), :class:`Section` (id, title, note,
tables, images: ``{title, src}`` with ``src`` relative to the report folder).
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class Table:
    """One table: ``rows`` are lists of display strings, as long as ``headers``."""

    caption: str
    headers: list[str]
    rows: list[list[str]]


@dataclass
class Section:
    """One extra section of the report (research, hard cases): prose, tables and images."""

    id: str
    title: str
    note: str
    tables: list[Table] = field(default_factory=list)
    images: list[dict] = field(default_factory=list)
