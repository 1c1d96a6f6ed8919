"""Resource budgets of untrusted input, checked before the work, each with a ``--max-*`` override.

An asset or a scene can ask for more memory or time than the machine has (a 657 KB glTF whose
textures decode to 2 GB, a node graph that expands exponentially, ``--spp 1000000000``). Each budget
is one named constant below and one command-line flag (:func:`pbrcheck.args.add_limit_flags`, on
every command that reads a scene); a request above it is refused before any of the work, in one line
naming the limit, the amount asked and the flag that raises it (:class:`LimitError`, exit 2).

The defaults (derivations beside each constant) pass every asset of the shared corpus, the built-in
scenes and the report's references with a wide margin; they refuse what would exhaust a 16 GB machine
or run for minutes without a word.

API
---
- :data:`LIMITS` -- every budget: :class:`Limit` (name, flag, default, unit, what it counts).
- :func:`limit` -- the value in force (default, or the CLI's override).
- :func:`set_limits` / :func:`reset_limits` / :func:`overridden` -- set by the CLI, or a test.
- :func:`check` -- raise :class:`LimitError` when an amount exceeds its budget.
- :class:`LimitError` -- the one-line refusal.
- :class:`OutputSizeError` -- an image larger than a renderer's backend can allocate (the raster
  pipeline asks GL: :func:`realtime.raster.check_target_size`); no flag raises a backend's limit.
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass

from .errors import PbrcheckError

#: Decoded texture bytes of one asset (sum over its images of width x height x channels x bytes per
#: channel, read from the image headers before decoding): 1 GiB = 16 RGBA8 images of 4096^2, four
#: times the largest asset of the shared corpus and of the Khronos sample assets (a few 2048^2 maps);
#: the issue's 657 KB asset asked for 2.16 GB, 12 copies of a 9000^2 image 4.6 GB.
MAX_TEXTURE_BYTES = 1 << 30
#: Triangles of one asset after node expansion (every instance counted), read from the accessors'
#: declared counts before any is decoded: 2^22 (4.2 M; the corpus's largest asset has ~50 k; a
#: 10 M-triangle GLB made realtime crash with SIGSEGV at 7.4 GB and check-scene run 40 s).
MAX_TRIANGLES = 1 << 22
#: Node instances of one asset after the hierarchy is expanded (a node reachable along k paths
#: counts k times): 2^17. The loader spends ~10-20 us per instance before any primitive, so 2^17 is
#: about 2 s at most; a 1.8 KB DAG of 30 levels, each node listing the next twice, expands to 2^31.
MAX_NODE_INSTANCES = 1 << 17
#: Samples of one reference render, spp x width x height (the adaptive ladder's largest level
#: counted): 2^37 = 1.4e11, e.g. 65536 spp at 1440 x 1440 (the report's references use 4096 spp at
#: 360 x 300 = 4.4e8). ``--spp 1000000000`` at 32 x 32 (1e12) asked numpy for 1.4 TiB.
MAX_SAMPLES = 1 << 37
#: Pixels of one reference image: 2^26 = 8192 x 8192. Mitsuba's film and pbrcheck's moments hold
#: ~20 float32 channels per pixel several times over (~25 GB at 16384^2); 8192^2 stays near 6 GB.
MAX_REFERENCE_PIXELS = 1 << 26
#: Pixels of an environment map file, read from its header before decoding: 8192 x 4096 (an "8k"
#: HDRI, 134 MB of float32 RGB; the shared envmaps are 1024 x 512). A 16384 x 8192 HDR made an
#: 8 spp 32 x 32 reference peak at 13.5 GB (the map, its sampling tables and the cube bakes).
MAX_ENV_PIXELS = 8192 * 4096


class LimitError(PbrcheckError):
    """A request above a resource budget: names the file, the amount, the limit and the flag."""

    def __init__(self, where: str, what: str, amount: int, lim: "Limit", value: int):
        self.where, self.what, self.amount, self.limit = where, what, int(amount), lim
        head = f"{where}: " if where else ""
        super().__init__(f"{head}{what}: {int(amount):,} {lim.unit}, above the limit of {int(value):,} "
                         f"({lim.constant}; raise it with {lim.flag} N)")


class OutputSizeError(PbrcheckError):
    """An output image larger than the renderer's backend allows (its limit named, exit 2)."""


@dataclass(frozen=True)
class Limit:
    """One budget: ``name`` (the key of :func:`limit`), the ``--max-*`` flag, the default, the
    unit of its amounts, the help text."""
    name: str
    flag: str
    constant: str
    default: int
    unit: str
    help: str

    @property
    def dest(self) -> str:
        return self.flag[2:].replace("-", "_")


LIMITS: dict[str, Limit] = {lim.name: lim for lim in (
    Limit("texture_bytes", "--max-texture-bytes", "MAX_TEXTURE_BYTES", MAX_TEXTURE_BYTES, "bytes",
          "decoded texture bytes of one glTF asset"),
    Limit("triangles", "--max-triangles", "MAX_TRIANGLES", MAX_TRIANGLES, "triangles",
          "triangles of one glTF asset after node expansion"),
    Limit("node_instances", "--max-node-instances", "MAX_NODE_INSTANCES", MAX_NODE_INSTANCES, "node instances",
          "node instances of one glTF asset after the hierarchy is expanded"),
    Limit("samples", "--max-samples", "MAX_SAMPLES", MAX_SAMPLES, "samples",
          "samples of one reference render (spp x width x height)"),
    Limit("reference_pixels", "--max-reference-pixels", "MAX_REFERENCE_PIXELS", MAX_REFERENCE_PIXELS, "pixels",
          "pixels of one reference image"),
    Limit("env_pixels", "--max-env-pixels", "MAX_ENV_PIXELS", MAX_ENV_PIXELS, "pixels",
          "pixels of an environment map file"),
)}

_current: dict[str, int] = {}


def limit(name: str) -> int:
    """The budget ``name`` in force (the CLI's ``--max-*`` value, else the default)."""
    return int(_current.get(name, LIMITS[name].default))


def set_limits(**values: int | None) -> None:
    """Set budgets by name (``None`` keeps the default); unknown names raise :class:`KeyError`."""
    for k, v in values.items():
        if k not in LIMITS:
            raise KeyError(k)
        if v is None:
            _current.pop(k, None)
        else:
            _current[k] = int(v)


def reset_limits() -> None:
    """Every budget back to its default (and no ``--allow-dir`` folder)."""
    from .untrusted import set_allowed_dirs

    _current.clear()
    set_allowed_dirs(())


def set_limits_from_args(args) -> None:
    """The CLI: the ``--max-*`` values of parsed ``args`` (absent ones: the defaults)."""
    from .untrusted import set_allowed_dirs

    reset_limits()
    set_limits(**{k: getattr(args, lim.dest, None) for k, lim in LIMITS.items()})
    set_allowed_dirs(getattr(args, "allow_dirs", None))


@contextmanager
def overridden(**values: int | None):
    """``with overridden(triangles=10):`` -- budgets for a block (tests), restored after."""
    saved = dict(_current)
    try:
        set_limits(**values)
        yield
    finally:
        _current.clear()
        _current.update(saved)


def check(name: str, amount: int, where: str, what: str) -> None:
    """Raise :class:`LimitError` when ``amount`` exceeds budget ``name`` (equal passes)."""
    value = limit(name)
    if amount > value:
        raise LimitError(where, what, amount, LIMITS[name], value)
