"""The ``pbrcheck`` command line (package ``pbrcheck_cli``, the top of the stack): the one package that
imports every layer; no layer imports it (the core ``pbrcheck`` holds no CLI).

Library code raises :class:`~pbrcheck.errors.PbrcheckError`; this module alone maps errors to exit
codes: 0 success, 1 a check failed (``gate``), 2 bad input (one line on stderr, no traceback,
nothing written), 3 a backend is unavailable, 130 interrupted (Ctrl-C), 143 terminated (SIGTERM).
:func:`main` is the one error boundary (an :class:`OSError` of a write is ``PATH: reason``, exit 2).

Layers import one way (``tests/test_layers.py`` enforces it): core ``pbrcheck`` <- renderers
``reference``, ``realtime`` <- comparator ``compare`` <- ``compare.research``, then
``compare.report`` <- this CLI. Subcommands live with their layer (``reference/commands.py``,
``realtime/commands.py``, ``clients/commands.py``, ``compare/commands.py``, ``compare/research/commands.py``,
``compare/report/commands.py``), each with ``register(subparsers, bench_subparsers)``; as the top of
the stack this module imports them all.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import threading
import time

import clients.commands
import clients.config
import compare.commands
import compare.fidelity_commands
import compare.report.corpus_commands
import compare.report.commands
import compare.research.commands
import realtime.commands
import reference.commands

from pbrcheck import __version__, cache, unmodelled
from pbrcheck.args import add_limit_flags_to_scene_commands
from pbrcheck.environment import load_environment, scene_hash
from pbrcheck.errors import CacheError, PbrcheckError, Terminated, os_reason
from pbrcheck.fmt import terminal_safe
from pbrcheck.gltf_objects import add_asset_arguments, asset_options_of
from pbrcheck.limits import reset_limits, set_limits_from_args
from pbrcheck.scene import DEFAULT_SCENE, builtin_scene_names, dump_toml, load_scene

#: Modules that contribute subcommands, in help order.
COMMAND_MODULES = (reference.commands, realtime.commands, clients.commands, compare.commands, compare.research.commands,
                   compare.report.commands, compare.report.corpus_commands, compare.fidelity_commands)


def _cmd_scenes(args) -> int:
    names = builtin_scene_names()
    width = max(len(n) for n in names)
    for n in names:
        s = load_scene(n)
        mark = " (default)" if n == DEFAULT_SCENE else ""
        print(f"{n:<{width}}  {s.description}{mark}")
    return 0


def _cmd_check_scene(args) -> int:
    scene = load_scene(args.scene, asset_options_of(args))
    env = load_environment(scene)  # validates the environment's pixels too
    if args.json or args.format == "json":  # ensure_ascii: every control character is a \u escape
        print(json.dumps(scene.to_dict(), indent=2))
        return 0
    # TOML: the comment lines escaped for the terminal (one line each, no escape sequence reaches it),
    # the values by dump_toml's own escaping (the output parses whatever the names hold)
    print(terminal_safe(f"# {scene.source}: valid"))
    print(f"# {len(scene.objects)} object(s), {len(scene.lights)} light(s), environment "
          f"{env.width}x{env.height} (max radiance {env.max_radiance:.4g})")
    print(f"# scene hash {scene_hash(scene, env.content_hash)}")
    if getattr(scene, "assets", ()):
        from pbrcheck.gltf_scene import describe
        print("\n".join(terminal_safe(line) for line in describe(scene)))
    from pbrcheck.lobe_params import scene_lobe_lines   # the analytic objects' lobe fields (issue 36)
    print("".join(terminal_safe(line) + "\n" for line in scene_lobe_lines(scene)), end="")
    from pbrcheck.transmission_params import scene_transmission_lines   # transmission fields (issue 37)
    print("".join(terminal_safe(line) + "\n" for line in scene_transmission_lines(scene)), end="")
    print(dump_toml(scene.to_dict()), end="")
    return 0


def _fmt_bytes(n: int) -> str:
    for unit in ("B", "KiB", "MiB", "GiB"):
        if n < 1024 or unit == "GiB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024.0
    return f"{n:.1f} GiB"  # pragma: no cover


def _cmd_cache(args) -> int:
    root = cache.cache_root()
    if args.action in (None, "info"):
        rows = cache.usage(root)
        print(f"cache: {root}")
        for u in rows:
            age = "" if u.oldest_use is None else \
                f", least recently used {(time.time() - u.oldest_use) / 86400.0:.1f} days ago"
            print(f"  {u.namespace:<10} {u.entries:6d} entries {_fmt_bytes(u.bytes):>10}{age}")
        print(f"  {'total':<10} {sum(u.entries for u in rows):6d} entries {_fmt_bytes(sum(u.bytes for u in rows)):>10}")
        return 0
    if args.action == "prune" and args.older_than is None and args.max_size is None:
        raise CacheError("cache prune: give --older-than DAYS and/or --max-size SIZE (pbrcheck cache clear removes all)")
    res = cache.prune(root=root, namespaces=args.namespace, dry_run=args.dry_run,
                      older_than_days=args.older_than if args.action == "prune" else None,
                      max_bytes=cache.parse_size(args.max_size) if args.action == "prune" and args.max_size else None)
    verb = "would remove" if args.dry_run else "removed"
    print(f"cache: {verb} {res.removed} entries ({_fmt_bytes(res.freed_bytes)}); {res.kept} entries "
          f"({_fmt_bytes(res.kept_bytes)}) kept in {root}"
          + (f"; {res.stale_temp_files} stale temporary file(s)" if res.stale_temp_files else ""))
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The ``pbrcheck`` argument parser with every package's subcommands."""
    p = argparse.ArgumentParser(
        prog="pbrcheck",
        description="Reference (Mitsuba 3) vs real-time (GLSL split-sum) validation of physically based shading.",
    )
    p.add_argument("--version", action="version", version=f"pbrcheck {__version__}")
    p.add_argument("--renderers", default=None, metavar="FILE",
                   help="renderers.toml naming the external renderers ext:NAME (default ./renderers.toml when present)")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    s = sub.add_parser("scenes", help="list the built-in scenes")
    s.set_defaults(func=_cmd_scenes)

    s = sub.add_parser("check-scene", help="validate a scene and print it resolved")
    s.add_argument("scene", help="built-in scene name or path to a TOML scene file")
    s.add_argument("--format", choices=("toml", "json"), default="toml",
                   help="toml (default): comment lines describing it, then the resolved scene as TOML; json: the resolved scene")
    s.add_argument("--json", action="store_true", help="the same as --format json")
    s.set_defaults(func=_cmd_check_scene)

    s = sub.add_parser("cache", help="what the render cache holds ($PBRCHECK_CACHE), prune or clear it")
    s.add_argument("action", nargs="?", choices=("info", "prune", "clear"), default="info",
                   help="info (default): entries and size per namespace; prune: the least recently used "
                        "(--older-than, --max-size); clear: every entry")
    s.add_argument("--older-than", type=float, metavar="DAYS", help="prune: entries not used for DAYS days")
    s.add_argument("--max-size", metavar="SIZE", help="prune: then the least recently used until the rest fits "
                   "in SIZE (e.g. 2G, 500M)")
    s.add_argument("--namespace", action="append", metavar="NS",
                   help="only this namespace (reference, realtime, flip, clients; repeatable)")
    s.add_argument("--dry-run", action="store_true", help="say what would be removed, remove nothing")
    s.set_defaults(func=_cmd_cache)

    bench = sub.add_parser("bench", help="benchmarks that print JSON figures")
    bench_sub = bench.add_subparsers(dest="bench_target", metavar="TARGET")
    bench_sub.required = True
    p.set_defaults(_bench_sub=bench_sub)

    for mod in COMMAND_MODULES:
        mod.register(sub, bench_sub)
    for s in sub.choices.values():  # every command that takes a SCENE: --env and --size WxH for an asset
        add_asset_arguments(s)
    add_limit_flags_to_scene_commands(sub)  # --max-* on every command that reads a scene
    return p


class _ClosedPipeSafe:
    """``sys.stdout`` that outlives its reader (``pbrcheck scenes | head -1``): once the pipe is
    closed, the rest of the output goes to /dev/null and the command finishes with its own exit
    code (no ``BrokenPipeError``)."""

    def __init__(self, stream):
        self._stream = stream
        self._closed = False

    def _drop(self) -> None:
        self._closed = True
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, self._stream.fileno())  # the buffered rest flushes to /dev/null
            os.close(devnull)
        except (OSError, ValueError):
            pass

    def write(self, s):
        if not self._closed:
            try:
                return self._stream.write(s)
            except BrokenPipeError:
                self._drop()
        return len(s)

    def flush(self):
        if not self._closed:
            try:
                self._stream.flush()
            except BrokenPipeError:
                self._drop()

    def __getattr__(self, name):
        return getattr(self._stream, name)


_SIGNALLED: list[int] = []  # the signals received during this call of main(), in order


def _on_sigterm(signum, frame):
    _SIGNALLED.append(signum)
    raise Terminated(signum)


def _on_sigint(signum, frame):
    _SIGNALLED.append(signum)
    raise KeyboardInterrupt


#: Interrupts swallowed where Python could not raise them, not yet delivered again (``pending``), the
#: re-deliveries sent (``sent``), and whether the command has ended (``closed``: no more re-delivery),
#: under one lock shared by the hook, its threads and the command's end (:func:`_finish_swallowed`).
_SWALLOWED: dict = {"pending": [], "sent": 0, "closed": False}
_SWALLOWED_LOCK = threading.Lock()
_RESEND_DELAY_S = 0.02  # long enough for the unraisable hook (and the callback it sits in) to return
#: How long the command's end waits for a re-delivered signal already sent (its handler runs during
#: the wait, inside the command's error boundary, not after the handlers are restored).
_RESEND_SETTLE_S = 0.2


def _resend(signum: int) -> None:
    time.sleep(_RESEND_DELAY_S)
    with _SWALLOWED_LOCK:
        if _SWALLOWED["closed"] or signum not in _SWALLOWED["pending"]:
            return            # the command ended first: _finish_swallowed reports it
        _SWALLOWED["pending"].remove(signum)
        _SWALLOWED["sent"] += 1
        os.kill(os.getpid(), signum)


def _finish_swallowed() -> None:
    """At a command's normal end: an interrupt swallowed and not yet delivered again (the command
    finished within the re-delivery's delay) is raised here, so the exit code says it; one already
    sent again is waited for, so that its handler runs here."""
    with _SWALLOWED_LOCK:
        _SWALLOWED["closed"] = True
        pending, sent = list(_SWALLOWED["pending"]), _SWALLOWED["sent"]
        _SWALLOWED["pending"].clear()
    if pending:
        raise Terminated(pending[-1]) if pending[-1] != signal.SIGINT else KeyboardInterrupt()
    if sent:
        time.sleep(_RESEND_SETTLE_S)


def _reset_swallowed() -> None:
    with _SWALLOWED_LOCK:
        _SWALLOWED.update(pending=[], sent=0, closed=False)


def _unraisable_hook(previous):
    """``sys.unraisablehook`` for a call of main(): an interrupt raised where Python cannot propagate
    it (a gc callback such as Dask's ``GCDiagnosis``, a ``__del__``, a weakref callback) is only
    *printed* by the default hook and the command goes on to the end, as if Ctrl-C had never come.
    Here it is delivered again, as a fresh signal, so that it lands in the command's own frames at the
    next bytecode: the same clean-up and exit code as any other interrupt."""

    def hook(u):
        if isinstance(u.exc_value, KeyboardInterrupt):
            signum = getattr(u.exc_value, "signum", signal.SIGINT)
            # Not signal.raise_signal nor _thread.interrupt_main: both run the handler at once, inside
            # this hook, whose exception Python drops. A thread sends the signal again once this hook
            # has returned: its handler runs in the main thread at the next bytecode (should that be
            # inside another callback, the interrupt comes back here and goes round once more).
            with _SWALLOWED_LOCK:
                if _SWALLOWED["closed"]:
                    return
                _SWALLOWED["pending"].append(signum)
            threading.Thread(target=_resend, args=(signum,), daemon=True).start()
            return
        previous(u)

    return hook


def _describe_os_error(e: OSError) -> str:
    """``PATH: reason`` of an OSError that escaped a command (a write, or a user's file read)."""
    names = [str(f) for f in (e.filename, e.filename2) if f is not None]
    return f"{' -> '.join(names)}: {os_reason(e)}" if names else os_reason(e)


def main(argv: list[str] | None = None) -> int:
    """Run the command line ``argv`` (default ``sys.argv[1:]``); returns the exit code.

    The one error boundary: a :class:`~pbrcheck.errors.PbrcheckError` prints its line and exits with
    its code; any other :class:`OSError` (a write that failed: read-only folder, a file in the way,
    a full disk; or a user's file that cannot be read) prints ``pbrcheck: error: PATH: reason``, exit
    2; Ctrl-C exits 130 and SIGTERM 143, after the commands' own clean-up (children killed,
    temporary folders removed); a closed stdout is not an error.
    """
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(argv)
    set_limits_from_args(args)
    asset_options_of(args)  # a WxH given to a command's own integer --size is the asset's, from here on
    # --renderers names the file of this call only: an in-process caller (tests, scripts calling
    # main() again) must not inherit it, so the previous choice is restored on the way out.
    prev_renderers = clients.config.user_renderers_file()
    if getattr(args, "renderers", None):
        clients.config.set_renderers_file(args.renderers)
    stdout = sys.stdout
    if not isinstance(stdout, _ClosedPipeSafe):
        sys.stdout = _ClosedPipeSafe(stdout)
    old_term = old_int = None
    old_unraisable = sys.unraisablehook
    if threading.current_thread() is threading.main_thread():
        _SIGNALLED.clear()
        _reset_swallowed()
        old_term = signal.signal(signal.SIGTERM, _on_sigterm)
        old_int = signal.signal(signal.SIGINT, _on_sigint)
        our_unraisable = sys.unraisablehook = _unraisable_hook(old_unraisable)
    unmodelled.start_notices()  # each asset's unmodelled features named once on stderr
    try:
        return _run(args)
    finally:
        unmodelled.stop_notices()
        sys.stdout.flush()  # a reader that left early: the rest goes to /dev/null here, not at exit
        sys.stdout = stdout
        clients.config.set_renderers_file(prev_renderers)
        reset_limits()  # the --max-* values of this call only, as --renderers
        if old_term is not None:
            signal.signal(signal.SIGTERM, old_term)
            signal.signal(signal.SIGINT, old_int)
            if sys.unraisablehook is our_unraisable:  # one a command set on its way out stays (the
                sys.unraisablehook = old_unraisable   # corpus silences Dask's clean-up at exit)


def _run(args) -> int:
    from clients.run import serve_clients

    try:
        with serve_clients():  # one browser per web client for the whole command (killed at its end)
            rc = int(args.func(args) or 0)
        _finish_swallowed()  # an interrupt swallowed near the end still sets the exit code
        return rc
    except PbrcheckError as e:
        print(f"pbrcheck: error: {terminal_safe(str(e))}", file=sys.stderr)
        return e.exit_code
    except OSError as e:
        print(f"pbrcheck: error: {terminal_safe(_describe_os_error(e))}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as e:
        return _interrupted(e)
    except Exception as e:
        # A signal inside a C extension's import (Mitsuba's set_variant) surfaces as a SystemError whose
        # context is the KeyboardInterrupt: still an interrupt, not a crash. One inside a Python
        # callback that C++ called (Mitsuba's plugin constructors: ``mi.load_dict`` building the
        # exact envmap) comes back as a RuntimeError whose *text* holds the interrupt's traceback,
        # with no chain to follow: the handlers' record of the signal tells it apart from a crash.
        cause = _interrupt_in_chain(e)
        if cause is None and _SIGNALLED:
            signum = _SIGNALLED[-1]
            cause = Terminated(signum) if signum != signal.SIGINT else KeyboardInterrupt()
        if cause is None:
            raise
        return _interrupted(cause)


def _interrupt_in_chain(e: BaseException) -> KeyboardInterrupt | None:
    """The KeyboardInterrupt (or Terminated) among ``e``'s causes and contexts, if any."""
    seen = set()
    while e is not None and id(e) not in seen:
        if isinstance(e, KeyboardInterrupt):
            return e
        seen.add(id(e))
        e = e.__cause__ or e.__context__
    return None


def _interrupted(e: KeyboardInterrupt) -> int:
    if isinstance(e, Terminated):
        print("pbrcheck: terminated", file=sys.stderr)
        return 128 + e.signum
    print("pbrcheck: interrupted", file=sys.stderr)
    return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
