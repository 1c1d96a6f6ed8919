"""Argument parsing helpers shared by every package's ``commands`` module.

API
---
:func:`split_list` (comma-separated lists), :func:`positive_int` (an argparse type with a lower bound),
:func:`add_limit_flags` (the ``--max-*`` resource budgets, :mod:`pbrcheck.limits`) and
:func:`add_limit_flags_to_scene_commands` (them on every subcommand that takes a scene).
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


def add_limit_flags(parser: argparse.ArgumentParser) -> None:
    """The ``--max-*`` overrides of :data:`pbrcheck.limits.LIMITS` (one flag per resource budget), in
    an argument group of their own; :func:`pbrcheck.limits.set_limits_from_args` applies them."""
    from .limits import LIMITS

    g = parser.add_argument_group("resource limits (untrusted assets and scenes; docs/assets.md)")
    for lim in LIMITS.values():
        g.add_argument(lim.flag, dest=lim.dest, type=positive_int(1), default=None, metavar="N",
                       help=f"{lim.help} (default {lim.default:,} {lim.unit})")
    g.add_argument("--allow-dir", dest="allow_dirs", action="append", default=None, metavar="DIR",
                   help="a folder whose files a scene file may name besides its own folder (repeatable; "
                        "e.g. the assets of scenes written by import-scenario --out)")


#: Arguments (positional or ``--scene``) that name scenes: a subcommand with one reads scenes and assets.
SCENE_ARGUMENTS = ("scene", "scenes")


def add_limit_flags_to_scene_commands(subparsers) -> None:
    """:func:`add_limit_flags` on every subcommand (nested ones too) of the ``subparsers`` action
    that takes a scene (an argument of :data:`SCENE_ARGUMENTS`), once, after every package registered
    its commands: one place for the flags of every command that reads a scene."""
    seen: set[int] = set()

    def walk(action) -> None:
        for p in action.choices.values():
            if id(p) in seen:
                continue
            seen.add(id(p))
            acts = p._actions  # noqa: SLF001 - argparse has no public list of a parser's arguments
            if any(a.dest in SCENE_ARGUMENTS for a in acts) and \
                    not any(a.dest == "max_triangles" for a in acts):
                add_limit_flags(p)
            for a in acts:
                if isinstance(a, argparse._SubParsersAction):  # noqa: SLF001
                    walk(a)

    walk(subparsers)
