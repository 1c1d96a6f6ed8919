"""Content-addressed cache of real-time renders: a re-run of unchanged shaders costs a file read.

A real-time render is deterministic: the same scene, options, shader sources and GL implementation
give the same pixels. :func:`render_cached` keys a render by all of them and keeps it in the
``realtime`` namespace of :class:`pbrcheck.cache.Cache` (atomic writes; a corrupt or mismatched
entry is a miss):

* the scene's content hash with the environment's pixels (:func:`pbrcheck.environment.scene_hash`);
* the preset name and its resolved options (:func:`realtime.presets.resolve_options`), the SHA-256
  of a shader hook file (``shader`` option) and of the mapping a fitted LOD file holds
  (``fitted:PATH``: its coefficients, cube size, mip count and chain; the file's other fields are the
  fit's record), by content only (the same file in another folder is a hit; the hit's ``options`` and
  ``shader`` metadata name this call's paths);
* :func:`realtime.gl.shader_sources_hash`: every file the GL programs read (``realtime/shaders/``
  whatever its suffix: ``.glsl``, ``.comp``, ``.vert``, ``.frag``; the registry's generated sources
  and defines), computed per call (the same rule as the gate's baselines, :mod:`compare.baseline`);
* :func:`code_hash`: the SHA-256 of every other file the pixels can depend on, whatever its suffix
  (``realtime/``'s and the core package ``pbrcheck/``'s Python, and the MikkTSpace C sources and
  library that make an asset's tangents): any edit of a shader or of the code that drives it is a
  miss, with no version number to forget. A suffix list is how the raster shaders (``raster.vert``,
  ``raster.frag``, ``raster_background.frag``, ``fullscreen.vert``) were once missed;
* the GL renderer and version strings (llvmpipe and a GPU round differently; Mesa's version is in
  ``GL_VERSION``) and moderngl's version.

A hit is the stored image with its stored timings (the frame and bakes as measured when it was
rendered, on the ``gl_renderer`` of its metadata) and ``meta["cache"] = "hit"``; the warnings the
render printed are printed again. Callers choose: :func:`compare.renderers.render_under_test` uses
it only with a caching :class:`compare.renderers.RenderContext` (the report), so a test or a
benchmark of the renderer always renders.

API: :data:`NAMESPACE`, :func:`code_files`, :func:`code_hash`, :func:`realtime_cache_key`, :func:`render_cached`
(:func:`realtime.gl.shader_sources_hash` re-exported).
"""

from __future__ import annotations

import hashlib
import json
import sys
from functools import lru_cache
from pathlib import Path

import moderngl

from pbrcheck.cache import Cache, cache_key
from pbrcheck.environment import scene_hash
from pbrcheck.scene import Scene

from .gl import get_context, renderer_name, shader_sources_hash
from .hooks import load_hook_file
from .presets import RealtimeOptions, resolve_options
from .render import environment_of, render_realtime

#: Cache namespace of real-time renders (``$PBRCHECK_CACHE/realtime``).
NAMESPACE = "realtime"
#: Folders whose every file keys every entry: this package and the core it reads (relative to the
#: repository root; every suffix, less ``__pycache__`` and the shader folder, which
#: :func:`realtime.gl.shader_sources_hash` hashes).
_CODE_DIRS = ("realtime", "pbrcheck")


def code_files() -> list[Path]:
    """The files :func:`code_hash` reads, sorted: every file under :data:`_CODE_DIRS` but
    ``__pycache__`` and :data:`realtime.gl.SHADER_DIR`."""
    root = Path(__file__).resolve().parent.parent
    shaders = Path(__file__).resolve().parent / "shaders"
    return [p for d in _CODE_DIRS for p in sorted((root / d).rglob("*"))
            if p.is_file() and "__pycache__" not in p.parts and shaders not in p.parents]


@lru_cache(maxsize=1)
def code_hash() -> str:
    """SHA-256 over the relative path and bytes of every file of :func:`code_files` (once per
    process: the Python of a running process does not change under it; the shaders, read at every
    compile, are :func:`realtime.gl.shader_sources_hash`, computed per key)."""
    root = Path(__file__).resolve().parent.parent
    h = hashlib.sha256()
    for p in code_files():
        h.update(p.relative_to(root).as_posix().encode() + b"\0" + p.read_bytes() + b"\0")
    return h.hexdigest()


def realtime_cache_key(scene: Scene, preset: str, options: dict | None = None) -> str:
    """The content address of ``scene`` rendered by ``preset`` with ``options`` (module docstring).

    Raises the errors of :func:`realtime.presets.resolve_options` for a bad preset or option."""
    return _key(scene, preset, resolve_options(preset, options))


def _key(scene: Scene, preset: str, o: RealtimeOptions) -> str:
    """:func:`realtime_cache_key` of the resolved options ``o``."""
    env = environment_of(scene)
    fm = o.fitted  # what the render reads of the mapping (a file's other fields are the fit's record)
    fitted = hashlib.sha256(json.dumps(fm.to_json(), sort_keys=True).encode()).hexdigest() if fm else None
    hooks = load_hook_file(o.shader).sha256 if o.shader else None
    # A file enters the key by its content, not its path: the same fitted mapping or hook file
    # written to another folder (another report's --out) renders the same pixels.
    keyed = {**o.as_dict(), **({"lod_mapping": "fitted:"} if fitted else {}), **({"shader": "hooks"} if hooks else {})}
    return cache_key(kind="realtime", scene_hash=scene_hash(scene, env.content_hash), preset=preset,
                     options=json.dumps(keyed, sort_keys=True, default=str), shader_hooks=hooks, fitted_lod=fitted,
                     code=code_hash(), shaders=shader_sources_hash(), gl_renderer=renderer_name(),
                     gl_version=str(get_context().info.get("GL_VERSION", "?")), moderngl=moderngl.__version__)


def render_cached(scene: Scene, preset: str = "default", options: dict | None = None, *,
                  progress: bool = False, cache: Cache | None = None):
    """:func:`realtime.render.render_realtime` through the content-addressed cache (module docstring);
    ``meta["cache"]`` is ``hit`` or ``miss``."""
    cache = cache if cache is not None else Cache(NAMESPACE)
    o = resolve_options(preset, options)
    key = _key(scene, preset, o)
    img = cache.get(key)
    if img is not None:
        img.meta["cache"] = "hit"
        img.meta["scene"] = scene.name  # the key ignores names: two scenes may share an entry
        # ... and files' paths (keyed by content): the metadata names this call's files
        img.meta["options"] = json.dumps(o.as_dict(), sort_keys=True)
        if img.meta.get("shader") and img.meta["shader"] != "null" and o.shader:
            img.meta["shader"] = json.dumps({**json.loads(img.meta["shader"]), "path": load_hook_file(o.shader).path})
        if progress:
            for w in json.loads(img.meta.get("warnings", "[]")):
                print(f"pbrcheck realtime: {w}", file=sys.stderr)
        return img
    img = render_realtime(scene, preset, options, progress=progress)
    cache.put(key, img)
    img.meta["cache"] = "miss"
    return img


__all__ = ["NAMESPACE", "code_files", "code_hash", "realtime_cache_key", "render_cached", "shader_sources_hash"]
