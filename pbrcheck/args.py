"""Argument parsing helpers shared by every package's ``commands`` module.

API
---
:func:`split_list` (comma-separated lists), :func:`positive_int` (an argparse type with a lower bound).
"""

from __future__ import annotations

import argparse


def split_list(s: str | None) -> list[str] | None:
    """``"a, b,c"`` -> ``["a", "b", "c"]`` (empty items dropped); None stays None."""
    if s is None:
        return None
    return [x.strip() for x in s.split(",") if x.strip()]


def positive_int(lo: int):
    """An argparse ``type`` accepting integers >= ``lo`` (a clear message otherwise)."""
    def parse(s):
        try:
            v = int(s)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, found {s!r}") from None
        if v < lo:
            raise argparse.ArgumentTypeError(f"expected an integer >= {lo}, found {v}")
        return v
    return parse
