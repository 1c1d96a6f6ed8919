"""Headless OpenGL: one cached moderngl EGL context, and GLSL source assembly.

Shader sources live in ``realtime/shaders``. :func:`assemble` expands ``#include "file.glsl"``
lines (each file once; the sources of :func:`realtime.generated.glsl_generated` are included by
name like files), prepends ``#version 430``, the named constants of every registry
(:func:`realtime.generated.glsl_defines`: ``#define GEOMETRY_SMITH_GGX 1``) and the ``#define`` lines
of the caller, and keeps a line map so that a compile error reported by the driver is re-reported as
``file.glsl:line`` of the original source (:class:`pbrcheck.errors.ShaderCompileError`). Two driver
formats are parsed: Mesa's ``0:LINE(COL): error: ...`` (source string, line, column) and NVIDIA's
``0(LINE) : error C0000: ...`` (source string and line, no column).

API
---
:func:`get_context`, :func:`renderer_name`, :func:`is_software_renderer`, :func:`timing_clock`,
:func:`timed`, :func:`assemble`, :func:`map_errors`, :func:`dump_sources`,
:func:`compute_program`, :func:`compile_source`, :func:`groups`, :func:`in_bands`, :class:`Source`,
:func:`shader_sources_hash`, :data:`DEFINES_FILE`.

Long GL work and signals: a signal that arrives during a GL call waits until the call returns (the
interpreter runs a handler between two bytecodes; pbrcheck.cli's SIGTERM handler raises
:class:`pbrcheck.errors.Terminated`, exit 143). One dispatch of an 8192^2 ray-cast frame held a
SIGTERM for 44 s on llvmpipe (issue 34). :func:`in_bands` cuts a large frame (the ray-cast dispatch,
the raster colour pass under a scissor) into bands of rows with ``glFinish`` between two, each
sized from the last one's wall time to take about :data:`FRAME_BAND_SECONDS`.

One rule for "what the GL programs read": :func:`shader_sources_hash` hashes every file of
:data:`SHADER_DIR` whatever its suffix (``.glsl`` includes, ``.comp`` compute shaders, the raster
program's ``.vert`` / ``.frag``), the registry's generated sources and its ``#define`` lines. The
real-time cache (:mod:`realtime.cache`) and the gate's baselines (:mod:`compare.baseline`) both key
on it. The compiled-program caches of this process (:func:`compute_program`, :func:`compile_source`,
:func:`realtime.raster.graphics_program`) are keyed by the assembled source text, so a shader file
edited under a running process is compiled again, never served from a program of the old text.
"""

from __future__ import annotations

import hashlib
import re
import time
from dataclasses import dataclass
from pathlib import Path

from pbrcheck.atomic import staged_folder
from pbrcheck.errors import BackendError, ShaderCompileError
from .generated import glsl_defines, glsl_generated

SHADER_DIR = Path(__file__).resolve().parent / "shaders"
GLSL_VERSION = "#version 430"
# GL_TEXTURE_CUBE_MAP_SEAMLESS: filter across cube faces (not on by default in core contexts).
GL_TEXTURE_CUBE_MAP_SEAMLESS = 0x884F
DEBIAN_PACKAGES = "libegl1 libgl1 libgl1-mesa-dri"

_INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"\s*$')
# Mesa: "0:3(14): error: ..." (source string : line (column)).
_ERR_LINE = re.compile(r"(\d+):(\d+)\((\d+)\)")
# NVIDIA: "0(6) : error C0000: ..." (source string (line)), at the start of a message line.
_ERR_LINE_NV = re.compile(r"^(\s*)(\d+)\((\d+)\)(?=\s*:)")

_ctx = None
_programs: dict = {}


def get_context():
    """The process-wide standalone EGL context (GL >= 4.3 core, compute shaders)."""
    global _ctx
    if _ctx is not None:
        return _ctx
    try:
        import moderngl  # local: a missing GL stack becomes a BackendError with the install line
    except ImportError as e:  # pragma: no cover - setup problem
        raise BackendError(f"moderngl is not installed ({e}); run `make setup`") from None
    try:
        ctx = moderngl.create_standalone_context(backend="egl", require=430)
    except Exception as e:
        first = (str(e).strip().splitlines() or [type(e).__name__])[0]
        raise BackendError(
            f"cannot create a headless OpenGL 4.3 context through EGL ({first}); "
            f"install the EGL/OpenGL libraries and Mesa's drivers: apt-get install {DEBIAN_PACKAGES}"
        ) from None
    try:
        ctx.enable_direct(GL_TEXTURE_CUBE_MAP_SEAMLESS)
    except Exception:  # pragma: no cover
        pass
    _ctx = ctx
    return ctx


def renderer_name() -> str:
    """The GL renderer string of the context (``llvmpipe ...`` on Mesa's software rasterizer)."""
    return str(get_context().info.get("GL_RENDERER", "?"))


def current_renderer_name() -> str | None:
    """:func:`renderer_name` when this process has created its GL context, else None (creates nothing)."""
    return renderer_name() if _ctx is not None else None


#: GL_RENDERER substrings of Mesa's CPU rasterizers, where a GL timer query measures nothing useful
#: (the work runs on the CPU, partly at glFinish) and the wall clock is used instead.
SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swrast", "lavapipe")
CLOCK_GL_TIMER = "gl_timer_query"
CLOCK_WALL = "wall"


def is_software_renderer(name: str | None = None) -> bool:
    """Whether the GL renderer (default: this context's) is a CPU rasterizer."""
    name = (renderer_name() if name is None else name).lower()
    return any(s in name for s in SOFTWARE_RENDERERS)


def timing_clock(name: str | None = None) -> str:
    """The clock :func:`timed` uses on this renderer: GL timer queries (``GL_TIME_ELAPSED``, GPU time
    of the commands issued inside) on a real GPU, the wall clock around ``glFinish`` on llvmpipe."""
    return CLOCK_WALL if is_software_renderer(name) else CLOCK_GL_TIMER


def timed(ctx, fn, clock: str | None = None):
    """``(fn(), seconds)``: GPU time of the GL commands ``fn`` issues (a timer query) or the wall time
    until they finished (``ctx.finish()``), per :func:`timing_clock`."""
    clock = clock or timing_clock()
    if clock == CLOCK_GL_TIMER:
        q = ctx.query(time=True)
        with q:
            out = fn()
        ctx.finish()
        return out, q.elapsed * 1e-9  # nanoseconds
    t0 = time.perf_counter()
    out = fn()
    ctx.finish()
    return out, time.perf_counter() - t0


@dataclass
class Source:
    """Assembled GLSL source and its line map back to the original files."""
    text: str
    line_map: list  # line_map[k] = (file, line) of assembled line k+1


_GENERATED = glsl_generated()


def shader_sources_hash(root: Path | None = None) -> str:
    """SHA-256 over every source the GL programs can read: each file below ``root`` (default:
    :data:`SHADER_DIR` as it is now), whatever its suffix, by relative path and bytes in sorted
    order, then the registry's generated sources (:func:`realtime.generated.glsl_generated`, included
    by name like files) and ``#define`` lines (:func:`realtime.generated.glsl_defines`, prepended to
    every program). Not memoized: ~30 small files, well under a millisecond, and a file edited under
    a running process must change it."""
    root = Path(SHADER_DIR if root is None else root)
    h = hashlib.sha256()
    for p in sorted(root.rglob("*")):
        if p.is_file() and "__pycache__" not in p.parts:
            h.update(p.relative_to(root).as_posix().encode() + b"\0" + p.read_bytes() + b"\0")
    for name, text in sorted(_GENERATED.items()):
        h.update(b"<generated>" + name.encode() + b"\0" + text.encode() + b"\0")
    for k, v in glsl_defines().items():
        h.update(f"<define>{k} {v}\0".encode())
    return h.hexdigest()


def _expand(name: str, seen: set, out_lines: list, out_map: list, stack: tuple = ()) -> None:
    path = SHADER_DIR / name
    if name in stack:
        raise ShaderCompileError(f"{name}: #include cycle through {' -> '.join(stack + (name,))}")
    if name in seen:
        return
    if name in _GENERATED:
        text = _GENERATED[name]
    elif path.is_file():
        text = path.read_text()
    else:
        where = f"{stack[-1]}" if stack else "<entry>"
        raise ShaderCompileError(f"{where}: #include of missing shader file {name!r}")
    seen.add(name)
    for i, line in enumerate(text.splitlines(), start=1):
        m = _INCLUDE.match(line)
        if m:
            _expand(m.group(1), seen, out_lines, out_map, stack + (name,))
            out_lines.append(f"// end of {m.group(1)}")
            out_map.append((name, i))
        else:
            out_lines.append(line)
            out_map.append((name, i))


def assemble(entry: str, defines: dict | None = None, user: tuple[str, str] | None = None) -> Source:
    """The full source of ``entry`` with includes expanded and ``defines`` prepended; ``user`` =
    ``(file name, text)`` of a shader hook file is appended after the entry (its lines map back to
    that file, so compile errors name ``FILE.glsl:line``; it may not ``#include``)."""
    lines = [GLSL_VERSION]
    lmap = [("<generated>", 1)]
    for k, v in glsl_defines().items():
        lines.append(f"#define {k} {v}")
        lmap.append(("<registry>", len(lmap)))
    for k, v in sorted((defines or {}).items()):
        if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*(\([A-Za-z_][A-Za-z0-9_]*\))?", k):
            raise ShaderCompileError(f"<defines>: bad macro name {k!r}")
        lines.append(f"#define {k} {v}")
        lmap.append(("<defines>", len(lmap)))
    _expand(entry, set(), lines, lmap)
    if user is not None:
        uname, utext = user
        for i, line in enumerate(utext.splitlines(), start=1):
            if _INCLUDE.match(line):
                raise ShaderCompileError(f"{uname}:{i}: #include is not available in a hook file", user=True)
            lines.append(line)
            lmap.append((uname, i))
    return Source("\n".join(lines) + "\n", lmap)


#: The file of :func:`dump_sources` holding the ``#define`` lines :func:`assemble` prepends.
DEFINES_FILE = "registry_defines.glsl"


def dump_sources(folder: str | Path) -> list[str]:
    """Write every GLSL source the programs read into ``folder``, atomically (a staged folder, then
    one rename or a merge into an existing ``folder``): each file of ``realtime/shaders`` as it is,
    each generated include of :func:`realtime.generated.glsl_generated` (its first line names its registry),
    :data:`DEFINES_FILE` (``#version`` and the registries' named constants, which :func:`assemble`
    prepends to every program) and a ``README.txt`` of the conventions. Returns the files' names."""
    files = {p.name: p.read_text() for p in sorted(SHADER_DIR.iterdir()) if p.is_file()}
    clash = set(files) & set(_GENERATED)
    if clash:  # assemble would read the generated source and ignore the file: never ship both
        raise ShaderCompileError(f"generated includes shadow shader files: {', '.join(sorted(clash))}")
    files.update(_GENERATED)  # each begins "// Generated from <its registry>: do not edit."
    files[DEFINES_FILE] = "\n".join([GLSL_VERSION, *(f"#define {k} {v}" for k, v in glsl_defines().items())]) + "\n"
    files["README.txt"] = (
        "The real-time renderer's GLSL as realtime.gl.assemble compiles it: each program is an entry file "
        f"(*.comp, *.vert, *.frag) preceded by {DEFINES_FILE} and its caller's #define lines (the registries' "
        "switches, e.g. #define NDF NDF_GGX), with every #include \"NAME\" expanded once from this folder; "
        "files whose first line says \"Generated from\" are made by realtime/generated.py from the registry "
        "it names (edit that), the others are copies of realtime/shaders.\n")
    with staged_folder(folder) as stage:
        for name, text in files.items():
            (stage / name).write_text(text)
    return sorted(files)


def map_errors(message: str, src: Source) -> str:
    """Rewrite every driver location of ``message`` as ``file:line(col)`` (Mesa's ``0:LINE(COL)``) or
    ``file:line`` (NVIDIA's ``0(LINE)``); keep only the lines that carry a location (all of the
    message when none does)."""

    def where(k: int):
        return src.line_map[k - 1] if 1 <= k <= len(src.line_map) else None

    def sub(m):
        loc = where(int(m.group(2)))
        return f"{loc[0]}:{loc[1]}({m.group(3)})" if loc else m.group(0)

    def sub_nv(m):
        loc = where(int(m.group(3)))
        return f"{m.group(1)}{loc[0]}:{loc[1]}" if loc else m.group(0)

    out = []
    for line in message.splitlines():
        if _ERR_LINE.search(line):
            out.append(_ERR_LINE.sub(sub, line).strip())
        elif _ERR_LINE_NV.search(line):
            out.append(_ERR_LINE_NV.sub(sub_nv, line).strip())
    return "; ".join(out) or message.strip()


def _user_first(message: str, user: tuple[str, str] | None) -> str:
    """A compile error of a hook file ``user`` led by its first ``FILE.glsl:LINE`` location."""
    if user is None:
        return message
    m = re.search(re.escape(user[0]) + r":\d+", message)
    return f"{m.group(0)}: {message}" if m else f"{user[0]}: {message}"


def compute_program(entry: str, defines: dict | None = None, user: tuple[str, str] | None = None):
    """Compiled (cached) compute shader of ``entry`` with ``defines`` (and a hook file ``user`` =
    ``(file name, text)``, see :func:`assemble`)."""
    src = assemble(entry, defines, user)
    key = ("__compute__", src.text)  # the text, not the file name: an edited file is compiled again
    prog = _programs.get(key)
    if prog is not None:
        return prog
    ctx = get_context()
    try:
        prog = ctx.compute_shader(src.text)
    except Exception as e:
        # with a user's hook file taking part the error is bad input (exit 2, FILE.glsl:LINE first)
        raise ShaderCompileError(_user_first(f"{entry}: GLSL compile failed: {map_errors(str(e), src)}", user),
                                 user=user is not None) from None
    _programs[key] = prog
    return prog


def compile_source(text_entry: str, extra: str, defines: dict | None = None, name: str = "<harness>",
                   user: tuple[str, str] | None = None):
    """Compile an entry file with an extra generated block (the harness's expression) and, as
    :func:`assemble`, a hook file ``user`` = ``(file name, text)`` appended."""
    d = dict(defines or {})
    src = assemble(text_entry, d, user)
    key = ("__extra__", src.text, extra)  # the assembled text: an edited file is compiled again
    prog = _programs.get(key)
    if prog is not None:
        return prog
    marker = "//@HARNESS@"
    lines = src.text.split("\n")
    lmap = list(src.line_map)
    for k, l in enumerate(lines):
        if l.strip() == marker:
            extra_lines = extra.split("\n")
            lines[k:k + 1] = extra_lines
            lmap[k:k + 1] = [(name, j + 1) for j in range(len(extra_lines))]
            break
    s = Source("\n".join(lines), lmap)
    try:
        prog = get_context().compute_shader(s.text)
    except Exception as e:
        raise ShaderCompileError(_user_first(f"{name}: GLSL compile failed: {map_errors(str(e), s)}", user),
                                 user=user is not None) from None
    _programs[key] = prog
    return prog


#: A frame of at most this many samples (pixels x samples per pixel) is one GL call, as it always was
#: (a 360 x 300 report frame at supersample 4 has 1.7 M); a larger one goes in bands (:func:`in_bands`).
SINGLE_DISPATCH_SAMPLES = 1 << 21
#: The wall time a band of a large frame aims at (the next band's rows are scaled from the last
#: band's measured time): about the longest a SIGTERM waits for the GL work in flight.
FRAME_BAND_SECONDS = 0.5
#: The first band of a large frame: this many samples at most (then :data:`FRAME_BAND_SECONDS`
#: decides): 1 M samples are ~0.1-0.5 s of llvmpipe at the default preset, ~1 ms on a GPU.
FIRST_BAND_SAMPLES = 1 << 20
#: The most a band's rows grow from one band to the next (a band that finished fast on a cheap
#: region of the image must not make the next, on an expensive region, far longer than the aim).
BAND_GROWTH = 4
#: Rows of a band are a multiple of this: the compute pass's work-group height (render.comp: 8 x 8),
#: and whole 2 x 2 fragment quads of the raster pass.
BAND_ROWS_STEP = 8


def in_bands(ctx, rows: int, samples_per_row: int, band) -> int:
    """Issue the GL work of a frame of ``rows`` rows of ``samples_per_row`` samples: ``band(0, rows)``
    once when the frame has at most :data:`SINGLE_DISPATCH_SAMPLES` samples; else ``band(y, n)`` for
    consecutive bands of rows (``n`` a multiple of :data:`BAND_ROWS_STEP` but the last), each
    followed by ``ctx.finish()`` -- the process is back in Python then, where a pending signal's
    handler runs -- and sized from the previous band's wall time to take about
    :data:`FRAME_BAND_SECONDS` (growing at most :data:`BAND_GROWTH` times). ``band`` must draw the
    same pixels however the rows are cut. Returns the number of bands."""
    if rows * samples_per_row <= SINGLE_DISPATCH_SAMPLES:
        band(0, rows)
        return 1
    step = BAND_ROWS_STEP
    n = max(step, FIRST_BAND_SAMPLES // max(samples_per_row, 1) // step * step)
    y = count = 0
    while y < rows:
        n = min(n, rows - y)
        t0 = time.perf_counter()
        band(y, n)
        ctx.finish()  # back in Python after every band: a pending signal's handler runs here
        dt = time.perf_counter() - t0
        y, count = y + n, count + 1
        n = max(step, int(min(n * FRAME_BAND_SECONDS / max(dt, 1e-6), n * BAND_GROWTH)) // step * step)
    return count


def groups(n: int, local: int) -> int:
    """Work groups of ``local`` invocations covering ``n`` items (at least one)."""
    return max(1, (int(n) + local - 1) // local)
