"""``renderers.toml``: the external renderers pbrcheck can run (docs/renderers.md).

API
---
- :class:`RendererConfig` -- one ``[renderer.NAME]`` table, validated.
- :func:`load_renderers` -- the built-in clients (``clients/renderers.toml``) plus a user file
  (``path``, else :func:`default_renderers_file`); a user renderer replaces a built-in one of the
  same name.
- :func:`get_renderer` -- one renderer by name (``threejs`` or ``ext:threejs``).
- :func:`set_renderers_file` / :func:`default_renderers_file` -- the user file every ``ext:NAME``
  lookup uses (``pbrcheck --renderers FILE``, else ``$PBRCHECK_RENDERERS``, else
  ``./renderers.toml`` when it exists).
- :func:`expand` -- a command with its placeholders filled in.

Format::

    [renderer.NAME]
    command = ["my-engine", "--scene", "{scenario}", "--out", "{out}"]   # required; {out} required
    output = "exr"            # exr | hdr | pfm | png-srgb (default exr)
    timeout = 600             # seconds (default 600); the process group is killed after it
    version_command = ["my-engine", "--version"]   # optional: its first stdout line is recorded
    lockfile = "package-lock.json"                 # optional: its hash enters the cache key
    inputs = ["adapter.py"]   # optional: further files whose content enters the cache key
    description = "one line"  # optional
    timed_on = "what the time was measured on"     # optional, shown in the report
    variance = true           # optional, Monte Carlo engines: the command also writes {variance},
                              # the variance of each pixel's estimate (R G B, the output's float format)
    renders = 8               # optional, Monte Carlo engines: run the command N times ({seed} = 0..N-1);
                              # the image is their mean, its variance the sample variance / N
    serve_command = ["node", "render.mjs", "--serve"]   # optional: a process that renders many
                              # commands in turn (one browser for a whole run: clients/run.py's
                              # serve_clients); each stdin line a JSON array, the expanded command;
                              # each answer one stdout line {"ok": true, "stdout": LINE} or
                              # {"ok": false, "error": LINE}; it exits when stdin closes

Placeholders: ``{scenario}`` (scenario.json), ``{out}`` (the file to write), ``{dir}`` (the export
folder), ``{width}``, ``{height}``, ``{clients}`` (the built-in clients' folder), ``{config_dir}``
(the folder of the file that defines the renderer), ``{variance}`` (the variance file to write: with
``variance = true`` only, then required), ``{seed}`` (the run's index: with ``renders`` > 1 only,
then required). Relative paths are resolved against
``{config_dir}``, which is also the command's working directory. Every problem is a
:class:`RendererConfigError` naming the file and the field.
"""

from __future__ import annotations

import hashlib
import os
import re
import string
import tomllib
from dataclasses import dataclass
from pathlib import Path

from pbrcheck.errors import PbrcheckError, decode_reason
from pbrcheck.export import OUTPUT_FORMATS

#: The folder of the built-in clients (this package).
CLIENTS_DIR = Path(__file__).resolve().parent
BUILTIN_FILE = CLIENTS_DIR / "renderers.toml"
DEFAULT_FILE_NAME = "renderers.toml"
ENV_VAR = "PBRCHECK_RENDERERS"
#: The prefix that names an external renderer wherever a preset can be named.
PREFIX = "ext:"
DEFAULT_TIMEOUT_S = 600.0
#: The largest ``timeout`` a renderers file may give (seconds: one day; finite, so that every wait
#: and every kill deadline stays representable).
MAX_TIMEOUT_S = 86400.0
PLACEHOLDERS = ("scenario", "out", "dir", "width", "height", "clients", "config_dir", "variance", "seed")
#: Placeholders only a Monte Carlo renderer's command may use: ``{variance}`` with ``variance = true``,
#: ``{seed}`` with ``renders`` > 1 (each then required).
NOISE_PLACEHOLDERS = {"variance": "variance = true", "seed": "renders > 1"}
KEYS = {"command", "output", "timeout", "version_command", "lockfile", "inputs", "description", "timed_on",
        "variance", "renders", "serve_command"}
#: Most independent renders a renderer may ask for (``renders``): each is a full run of the engine.
MAX_RENDERS = 64
NAME_RE = re.compile(r"^[A-Za-z0-9_.-]+$")

_user_file: Path | None = None


class RendererConfigError(PbrcheckError):
    """A malformed ``renderers.toml`` or an unknown renderer name (names the file and the field)."""


@dataclass(frozen=True)
class RendererConfig:
    """One external renderer, validated (see the module docstring for the fields)."""
    name: str
    command: tuple[str, ...]
    source: str
    config_dir: Path
    output: str = "exr"
    timeout: float = DEFAULT_TIMEOUT_S
    version_command: tuple[str, ...] | None = None
    lockfile: str | None = None
    inputs: tuple[str, ...] = ()
    description: str = ""
    timed_on: str = ""
    builtin: bool = False
    #: The command also writes ``{variance}``: the variance of each pixel's estimate (docs/renderers.md).
    variance: bool = False
    #: Independent runs (``{seed}`` = 0..renders-1) whose mean is the image and whose sample variance
    #: over ``renders`` its variance; 1: one run.
    renders: int = 1
    #: A process that renders many ``command`` lines in turn (module docstring); not part of the
    #: cache key: a render served or run alone gives the same pixels.
    serve_command: tuple[str, ...] | None = None

    @property
    def noisy(self) -> bool:
        """Whether the renderer hands pbrcheck its image's variance (a Monte Carlo engine)."""
        return self.variance or self.renders > 1

    @property
    def label(self) -> str:
        return PREFIX + self.name

    def lockfile_path(self) -> Path | None:
        if not self.lockfile:
            return None
        p = Path(expand_one(self.lockfile, self._base_values(), self.source, "lockfile"))
        return p if p.is_absolute() else self.config_dir / p

    def lockfile_hash(self) -> str | None:
        """SHA-256 of the lockfile (``missing`` when it does not exist), or None without one."""
        p = self.lockfile_path()
        if p is None:
            return None
        try:
            return hashlib.sha256(p.read_bytes()).hexdigest()
        except OSError:
            return "missing"

    def inputs_hash(self) -> str | None:
        """SHA-256 over the ``inputs`` files (name and content; ``missing`` for an absent one), or
        None without any."""
        if not self.inputs:
            return None
        h = hashlib.sha256()
        for arg in self.inputs:
            p = Path(expand_one(arg, self._base_values(), self.source, f"renderer.{self.name}.inputs"))
            p = p if p.is_absolute() else self.config_dir / p
            try:
                data = p.read_bytes()
            except OSError:
                data = b"missing"
            h.update(arg.encode() + b"\0" + hashlib.sha256(data).digest())
        return h.hexdigest()

    def cache_dict(self) -> dict:
        """What about the renderer determines its pixels (part of the cache key)."""
        d = {"name": self.name, "command": list(self.command), "output": self.output,
             "lockfile": self.lockfile_hash(), "inputs": self.inputs_hash()}
        if self.noisy:  # only then: every other renderer keeps its key (and its cached renders)
            d.update(variance=self.variance, renders=self.renders)
        return d

    def _base_values(self) -> dict[str, str]:
        return {"clients": str(CLIENTS_DIR), "config_dir": str(self.config_dir)}


def expand_one(arg: str, values: dict[str, str], source: str, where: str) -> str:
    """``arg`` with its ``{placeholders}`` filled from ``values`` (``{{``/``}}`` are literal braces)."""
    try:
        return arg.format_map(values)
    except (KeyError, IndexError, ValueError) as e:
        raise RendererConfigError(f"{source}: {where}: bad placeholder in {arg!r} ({e}); "
                                  f"known: {', '.join('{' + p + '}' for p in PLACEHOLDERS)}") from None


def expand(cfg: RendererConfig, argv: tuple[str, ...], key: str | None = None, **values) -> list[str]:
    """The command ``argv`` of ``cfg`` with placeholders filled (``values``: scenario, out, dir,
    width, height as strings); ``key`` names it in errors (default ``command``, or
    ``version_command`` when ``argv`` is that)."""
    if key is None:
        key = "version_command" if argv == cfg.version_command and argv != cfg.command else "command"
    vals = {**cfg._base_values(), **{k: str(v) for k, v in values.items()}}
    return [expand_one(a, vals, cfg.source, f"renderer.{cfg.name}.{key}") for a in argv]


def _placeholders(arg: str) -> set[str]:
    try:
        return {f for _, f, _, _ in string.Formatter().parse(arg) if f is not None}
    except ValueError:
        return {"<unbalanced brace>"}


def _command(file: str, where: str, v, *, need_out: bool) -> tuple[str, ...]:
    if not isinstance(v, list) or not v or not all(isinstance(a, str) and a for a in v):
        raise RendererConfigError(f"{file}: {where}: expected a non-empty array of non-empty strings, found {v!r}")
    used = set().union(*(_placeholders(a) for a in v))
    unknown = sorted(used - set(PLACEHOLDERS))
    if unknown:
        raise RendererConfigError(f"{file}: {where}: unknown placeholder(s) {', '.join(unknown)}; "
                                  f"known: {', '.join('{' + p + '}' for p in PLACEHOLDERS)}")
    if need_out and "out" not in used:
        raise RendererConfigError(f"{file}: {where}: the command must name the output file with {{out}}")
    return tuple(v)


def parse_renderers(data: dict, *, file: str, config_dir: Path, builtin: bool = False) -> dict[str, RendererConfig]:
    """Validate a parsed ``renderers.toml``; returns name -> :class:`RendererConfig`."""
    extra = sorted(set(data) - {"renderer"})
    if extra:
        raise RendererConfigError(f"{file}: unknown top-level key(s) {', '.join(extra)}; expected [renderer.NAME] tables")
    tables = data.get("renderer", {})
    if not isinstance(tables, dict):
        raise RendererConfigError(f"{file}: renderer: expected [renderer.NAME] tables, found {tables!r}")
    out = {}
    for name, t in tables.items():
        w = f"renderer.{name}"
        if not NAME_RE.match(name):
            raise RendererConfigError(f"{file}: {w}: a name of letters, digits, '_', '-' or '.'")
        if not isinstance(t, dict):
            raise RendererConfigError(f"{file}: {w}: expected a table, found {t!r}")
        bad = sorted(set(t) - KEYS)
        if bad:
            raise RendererConfigError(f"{file}: {w}: unknown key(s) {', '.join(bad)}; allowed: {', '.join(sorted(KEYS))}")
        if "command" not in t:
            raise RendererConfigError(f"{file}: {w}.command: required (an array: the program and its arguments)")
        command = _command(file, f"{w}.command", t["command"], need_out=True)
        output = t.get("output", "exr")
        if output not in OUTPUT_FORMATS:
            raise RendererConfigError(f"{file}: {w}.output: expected one of {', '.join(OUTPUT_FORMATS)}, found {output!r}")
        timeout = t.get("timeout", DEFAULT_TIMEOUT_S)
        if isinstance(timeout, bool) or not isinstance(timeout, (int, float)) or not 0 < timeout <= MAX_TIMEOUT_S:
            raise RendererConfigError(f"{file}: {w}.timeout: expected a number of seconds > 0 and <= "
                                      f"{MAX_TIMEOUT_S:g} (one day), found {timeout!r}")
        variance, renders = _noise_keys(file, w, t, output, command)
        vc = t.get("version_command")
        if vc is not None:
            vc = _command(file, f"{w}.version_command", vc, need_out=False)
        sc = t.get("serve_command")
        if sc is not None:
            sc = _command(file, f"{w}.serve_command", sc, need_out=False)
        for k in ("lockfile", "description", "timed_on"):
            if k in t and not isinstance(t[k], str):
                raise RendererConfigError(f"{file}: {w}.{k}: expected a string, found {t[k]!r}")
        inputs = t.get("inputs", [])
        if not isinstance(inputs, list) or not all(isinstance(a, str) and a for a in inputs):
            raise RendererConfigError(f"{file}: {w}.inputs: expected an array of file paths, found {inputs!r}")
        out[name] = RendererConfig(name=name, command=command, source=file, config_dir=config_dir,
                                   output=output, timeout=float(timeout), version_command=vc,
                                   lockfile=t.get("lockfile"), inputs=tuple(inputs), description=t.get("description", ""),
                                   timed_on=t.get("timed_on", ""), builtin=builtin, variance=variance,
                                   renders=renders, serve_command=sc)
    return out


def _noise_keys(file: str, w: str, t: dict, output: str, command: tuple[str, ...]) -> tuple[bool, int]:
    """(``variance``, ``renders``) of one table, validated against its output and command: a
    variance needs a float output (an 8-bit ``png-srgb`` image is compared without noise floors),
    each key its placeholder, and the placeholders their key."""
    variance = t.get("variance", False)
    if not isinstance(variance, bool):
        raise RendererConfigError(f"{file}: {w}.variance: expected true or false, found {variance!r}")
    renders = t.get("renders", 1)
    if isinstance(renders, bool) or not isinstance(renders, int) or not 1 <= renders <= MAX_RENDERS:
        raise RendererConfigError(f"{file}: {w}.renders: expected an integer from 1 to {MAX_RENDERS}, "
                                  f"found {renders!r}")
    if variance and renders > 1:
        raise RendererConfigError(f"{file}: {w}: variance = true and renders = {renders}: give one or the "
                                  "other (the variance image of one run, or N independent runs)")
    if (variance or renders > 1) and output == "png-srgb":
        raise RendererConfigError(f"{file}: {w}.output: png-srgb has no variance (display-referred images "
                                  "are compared without noise floors); use exr, hdr or pfm")
    used = set().union(*(_placeholders(a) for a in command))
    active = {"variance": variance, "seed": renders > 1}
    for ph, key in NOISE_PLACEHOLDERS.items():
        if active[ph] and ph not in used:
            raise RendererConfigError(f"{file}: {w}.command: {key} needs {{{ph}}} in the command")
        if ph in used and not active[ph]:
            raise RendererConfigError(f"{file}: {w}.command: {{{ph}}} only with {key}")
    return variance, renders


def _read(path: Path, *, builtin: bool = False) -> dict[str, RendererConfig]:
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise RendererConfigError(f"{path}: no such renderers file") from None
    except OSError as e:
        raise RendererConfigError(f"{path}: cannot read: {e.strerror}") from None
    except tomllib.TOMLDecodeError as e:
        raise RendererConfigError(f"{path}: not valid TOML: {e}") from None
    except UnicodeDecodeError as e:
        raise RendererConfigError(f"{path}: cannot read: {decode_reason(e)}") from None
    return parse_renderers(data, file=str(path), config_dir=path.resolve().parent, builtin=builtin)


def set_renderers_file(path: str | Path | None) -> None:
    """Make ``path`` the user renderers file of every later lookup (``pbrcheck --renderers``)."""
    global _user_file
    _user_file = Path(path) if path is not None else None


def user_renderers_file() -> Path | None:
    """The file :func:`set_renderers_file` named (``None``: none), so a caller can restore it."""
    return _user_file


def default_renderers_file() -> tuple[Path | None, bool]:
    """(the user renderers file, whether it was named explicitly): :func:`set_renderers_file`, else
    ``$PBRCHECK_RENDERERS``, else ``./renderers.toml`` (only when it exists)."""
    if _user_file is not None:
        return _user_file, True
    env = os.environ.get(ENV_VAR)
    if env:
        return Path(env), True
    p = Path(DEFAULT_FILE_NAME)
    return (p, False) if p.is_file() else (None, False)


def load_renderers(path: str | Path | None = None) -> dict[str, RendererConfig]:
    """The built-in renderers plus those of ``path`` (else :func:`default_renderers_file`); a
    named file that does not exist is an error."""
    out = _read(BUILTIN_FILE, builtin=True)
    if path is None:
        path, _ = default_renderers_file()
    if path is not None:
        out.update(_read(Path(path)))
    return out


def strip_prefix(name: str) -> str:
    return name[len(PREFIX):] if name.startswith(PREFIX) else name


def get_renderer(name: str, path: str | Path | None = None) -> RendererConfig:
    """The renderer ``name`` (with or without ``ext:``); unknown names list the known ones."""
    known = load_renderers(path)
    key = strip_prefix(name)
    if key not in known:
        where = f" (renderers files: {BUILTIN_FILE.name} built in" + (
            f", {path or default_renderers_file()[0]}" if (path or default_renderers_file()[0]) else "") + ")"
        raise RendererConfigError(f"unknown external renderer {name!r}; known: "
                                  f"{', '.join(PREFIX + k for k in sorted(known))}{where}")
    return known[key]

