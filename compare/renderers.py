"""The renderers the comparator measures, behind one seam.

Every compare, report and research module renders through these functions (called as
``renderers.render_reference(...)``, never imported by name), so a test replaces a renderer with
``monkeypatch.setattr(compare.renderers, "render_under_test", fake)`` in one place.

API
---
- :func:`render_reference` -- the Mitsuba reference (:func:`reference.render.render_reference`).
- :class:`RendererSpec` -- a renderer under test, parsed once where its name is read (the command
  line, a budget file, a report's configuration) from the renderer mini-language (``default``, a
  preset name, ``PRESET+FILE.glsl``, ``ext:NAME``) and option overrides (``--set key=value``):
  :meth:`RendererSpec.parse`; a real-time one holds its resolved, validated
  :class:`realtime.presets.RealtimeOptions`. Every layer below takes the spec, none re-parses.
- :func:`render_under_test` -- render a :class:`RendererSpec`: a real-time preset
  (:func:`realtime.render.render_realtime`, with the spec's resolved options: resolved once per
  render) or ``ext:NAME``, an external renderer of ``renderers.toml``
  (:func:`clients.run.render_external`).
- :class:`RenderContext` -- how :func:`render_under_test` renders, passed to it explicitly
  (``context=``): whether real-time renders come from the content-addressed cache
  (:mod:`realtime.cache`; the report) and the external renders started in the background
  (:class:`Prefetch`); and whether their comparisons keep FLIP maps on disk. :data:`DIRECT` (the
  default) renders every call.
- :func:`prefetch_external` -- a context that renders some external renderers' images in a
  background thread while this process renders the rest; yields the :class:`Prefetch` to put in a
  :class:`RenderContext` (the report).
- :func:`is_external` -- whether a renderer name names an external renderer (``ext:NAME``; the
  parser's test, for a name not parsed yet).
- :func:`preset_names` -- every real-time preset, in the registry's order.
- :func:`resolve_options` -- a bare preset's resolved options (what :class:`RendererSpec` resolves
  through, once per spec; the seam a test replaces for fake presets).
- :func:`check_backend_limits` -- raise :class:`pbrcheck.errors.BackendError` where this machine's GL
  cannot render a spec's options (``msaa`` above ``GL_MAX_SAMPLES``: :func:`realtime.raster.check_msaa`),
  for preflights that render other things first (report, sweep).
- :func:`multiscatter_albedo` -- the reference random walk's directional albedo
  (:func:`reference.multiscatter_measure.directional_albedo`).
- :func:`backends` -- the GL renderer and the reference's variant this process renders with.
- :data:`CACHE_COUNTS` -- hits and misses of the real-time and reference caches in this process.
- :func:`trim_caches` -- bound the renderers' per-process caches to a few environments (corpus
  workers, :func:`realtime.render.trim_environment_caches`).
"""

from __future__ import annotations

import contextlib
import json
from collections import Counter
from collections.abc import Mapping
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from types import MappingProxyType

from clients import config as _clients_config
from clients import run as _clients
from pbrcheck.errors import PbrcheckError
from pbrcheck.exr import Image
from pbrcheck.export import keeps_unmodelled
from pbrcheck.scene import Scene
from realtime import cache as _realtime_cache
from realtime import gl as _realtime_gl
from realtime import presets as _presets
from realtime.presets import RealtimeOptions
from realtime import render as _realtime
from reference import render as _reference

from .worktime import work


#: Hits, misses and uncached renders (``off``) of the renderers' caches in this process, by renderer
#: kind (:mod:`compare.report.runlog` reports a run's share).
CACHE_COUNTS: dict[str, Counter] = {"realtime": Counter(), "reference": Counter()}


def render_reference(scene: Scene, **kwargs) -> Image:
    """The reference image of ``scene``; keyword arguments as :func:`reference.render.render_reference`
    (``spp``, ``mode``, ``seed``, ``use_cache``, ``progress``)."""
    with work("reference"):
        img = _reference.render_reference(scene, **kwargs)
    CACHE_COUNTS["reference"][img.meta.get("cache", "off")] += 1
    return img


class Prefetch:
    """External renderers' images being rendered in the background (:func:`prefetch_external`), by
    (scene content, renderer); :meth:`take` hands each one out once."""

    def __init__(self):
        self._futures: dict[str, Future] = {}

    def submit(self, pool: ThreadPoolExecutor, scene: Scene, spec: "RendererSpec") -> None:
        k = _prefetch_key(scene, spec)
        if k not in self._futures:
            self._futures[k] = pool.submit(_clients.render_external, scene, spec.name, progress=False,
                                           use_cache=not keeps_unmodelled())

    def take(self, scene: Scene, spec: "RendererSpec") -> Future | None:
        """The future of ``(scene, spec)``, removed (a second call renders again), or None."""
        return self._futures.pop(_prefetch_key(scene, spec), None)

    def close(self) -> None:
        """Cancel the renders not yet started (running ones finish) and forget them all: a later
        :meth:`take` finds nothing, so its caller renders."""
        for f in self._futures.values():
            f.cancel()
        self._futures.clear()


@dataclass(frozen=True)
class RenderContext:
    """How :func:`render_under_test` renders; passed to it (``context=``), never held in a module.

    ``cache``: real-time presets render through :func:`realtime.cache.render_cached` (keyed by
    scene, options, shader and code content and the GL renderer; ``meta["cache"]`` says ``hit`` or
    ``miss``); otherwise every call renders, so the renderer's own tests and benchmarks always measure
    a render. External renderers have their own cache (:mod:`clients.run`). ``prefetch``: external
    renders started in the background (:func:`prefetch_external`); one of them is taken from there
    (waiting if needed; a failed render raises its own error there, as it would have).
    ``flip_cache``: the comparisons of these renders keep their HDR-FLIP maps on disk by content
    (callers pass it on as ``compare.metrics.compare_images(..., flip_cache=...)``)."""

    cache: bool = False
    prefetch: Prefetch | None = field(default=None, compare=False)
    flip_cache: bool = False

    def local(self) -> "RenderContext":
        """This context without its prefetch (what a render in another process can use)."""
        return replace(self, prefetch=None)


#: Render every call: no cache, nothing prefetched (the default of :func:`render_under_test`).
DIRECT = RenderContext()


@dataclass(frozen=True)
class RendererSpec:
    """A renderer under test, parsed once (:meth:`parse`) and passed down as is.

    ``text``: the name as it was given (``default``, ``filament``, ``default+hooks/ue4.glsl``,
    ``ext:threejs``): what outputs call it (report columns, check names, metadata). ``name``: the
    preset (the ``+FILE.glsl`` split off, :func:`realtime.presets.split_preset`) or ``ext:NAME``.
    ``overrides``: the option overrides as given, the name's hook file included (sorted pairs;
    :meth:`with_options` derives a variant from them). ``options``: the resolved, validated
    :class:`realtime.presets.RealtimeOptions` of a real-time renderer (what the render reads;
    ``None`` for an external one, which takes none)."""

    text: str
    name: str
    overrides: tuple[tuple[str, object], ...] = ()
    options: RealtimeOptions | None = None

    @classmethod
    def parse(cls, text: str, overrides: Mapping | None = None) -> "RendererSpec":
        """The spec of renderer name ``text`` with option ``overrides`` (``--set``, a budget's
        ``options``; values as :func:`realtime.presets.parse_value` takes them).

        Raises
        ------
        OptionError
            An unknown preset or option, a bad value, ``PRESET+`` with no file, or a combination the
            options refuse (:func:`realtime.presets.resolve_options`).
        RendererConfigError
            ``ext:NAME`` that no ``renderers.toml`` defines.
        PbrcheckError
            Options given to an external renderer (it takes none: its command sets them).
        """
        if not isinstance(text, str) or not text:
            raise _presets.OptionError(f"renderer {text!r}: expected a preset name, PRESET+FILE.glsl or ext:NAME")
        if is_external(text):
            _no_options(text, overrides)
            _clients_config.get_renderer(text)
            return cls(text, text)
        preset, named = _presets.split_preset(text)
        merged = {**named, **(overrides or {})}
        return cls(text, preset, tuple(sorted(merged.items())), resolve_options(preset, merged))

    @property
    def external(self) -> bool:
        """Whether this is an external renderer (``ext:NAME``)."""
        return self.options is None

    @property
    def override_dict(self) -> Mapping:
        """The option overrides (read-only)."""
        return MappingProxyType(dict(self.overrides))

    def with_options(self, **changes) -> "RendererSpec":
        """This real-time spec with further option overrides (validated again: a variant of the
        renderer, as a study's ``{**base, "energy_compensation": c}``); the same ``text``."""
        if self.external:
            _no_options(self.text, changes)
            return self
        merged = {**dict(self.overrides), **changes}
        return replace(self, overrides=tuple(sorted(merged.items(), key=lambda kv: kv[0])),
                       options=resolve_options(self.name, merged))

    def __str__(self) -> str:
        return self.text


def render_under_test(scene: Scene, spec: RendererSpec, *, progress: bool = False,
                      context: RenderContext = DIRECT, use_cache: bool = True) -> Image:
    """Render ``scene`` with the renderer under test ``spec``.

    Parameters
    ----------
    scene : Scene
        The scene.
    spec : RendererSpec
        The renderer, parsed once (:meth:`RendererSpec.parse`): a real-time preset with its resolved
        options (rendered as they are: no second resolve) or ``ext:NAME``.
    progress : bool, optional
        Show progress on stderr.
    context : RenderContext, optional
        The cache and the background renders to use (default :data:`DIRECT`: render).
    use_cache : bool, optional
        False: render afresh even where a cache would serve the image (an external renderer's
        render cache, the context's real-time cache): the gate's run-to-run spread.

    Returns
    -------
    Image
        Linear radiance ``R G B`` and the AOVs, with the renderer's metadata.

    Raises
    ------
    PbrcheckError
        The renderer failed (``RendererError``); ``TypeError`` for a renderer that is not a
        :class:`RendererSpec` (a name must be parsed where it is read).
    """
    if not isinstance(spec, RendererSpec):
        raise TypeError(f"render_under_test takes a RendererSpec (RendererSpec.parse), got {spec!r}")
    if spec.external:
        fut = context.prefetch.take(scene, spec) if context.prefetch is not None else None
        with work("clients"):  # the wait for a background render, or the render itself
            if fut is not None:  # rendered (or being rendered) in the background: its result or error
                return fut.result()
            # kept unmodelled extensions (pbrcheck.export.keeping_unmodelled): the render cache's key
            # names the stripped export, so such a render neither reads nor writes it
            return _clients.render_external(scene, spec.name, progress=progress,
                                            use_cache=use_cache and not keeps_unmodelled())
    with work("realtime"):
        if context.cache and use_cache:
            img = _realtime_cache.render_cached(scene, spec.name, spec.options, progress=progress)
            CACHE_COUNTS["realtime"][img.meta.get("cache", "off")] += 1
            return img
        CACHE_COUNTS["realtime"]["off"] += 1
        return _realtime.render_realtime(scene, spec.name, spec.options, progress=progress)


def backends() -> dict:
    """What this process renders with: the GL renderer and clock of the real-time renders and the
    reference's Mitsuba variant (``None`` for a renderer this process has not started)."""
    from reference import variant as _variant  # local: only reads the chosen variant, sets nothing

    gl = _realtime_gl.current_renderer_name()
    return {"gl_renderer": gl, "timing_clock": _realtime_gl.timing_clock(gl) if gl else None,
            "reference_variant": _variant.chosen_variant()}


def _prefetch_key(scene: Scene, spec: RendererSpec) -> str:
    return json.dumps([scene.content_dict(), spec.name], sort_keys=True, default=str)


@contextlib.contextmanager
def prefetch_external(jobs, workers: int = 1):
    """Render the external renderers' images of ``jobs`` (``(scene, RendererSpec)`` pairs) in
    ``workers`` background threads while this process renders the rest: an external renderer is a
    process of its own (a browser on SwiftShader) that this one would otherwise only wait for.
    Yields the :class:`Prefetch`: :func:`render_under_test` with a :class:`RenderContext` holding it
    takes its result. On exit, renders not yet started are cancelled and running ones finish (their
    results stay in the external renderers' cache)."""
    pre = Prefetch()
    pool = ThreadPoolExecutor(max_workers=max(1, int(workers)), thread_name_prefix="pbrcheck-prefetch")
    try:
        for scene, spec in jobs:
            if spec.external:
                pre.submit(pool, scene, spec)
        yield pre
    finally:
        pre.close()
        pool.shutdown(wait=True)


def is_external(name: str) -> bool:
    """Whether renderer name ``name`` names an external renderer (``ext:NAME``); a parsed spec says
    so itself (:attr:`RendererSpec.external`)."""
    return name.startswith(_clients_config.PREFIX)


def _no_options(name: str, options: dict | None) -> None:
    if options:
        raise PbrcheckError(f"{name}: an external renderer takes no options (got {', '.join(sorted(options))}); "
                            "set them in its renderers.toml command")


def preset_names() -> list[str]:
    """Every real-time preset name."""
    return list(_presets.PRESETS)


def resolve_options(preset: str, overrides: Mapping | None = None) -> RealtimeOptions:
    """The resolved options of real-time preset ``preset`` (a bare preset name) with ``overrides``
    (:func:`realtime.presets.resolve_options`): what :class:`RendererSpec` resolves through, the one
    place a test replaces to stand in fake presets."""
    return _presets.resolve_options(preset, dict(overrides or {}))


def check_backend_limits(spec: RendererSpec) -> None:
    """Raise :class:`pbrcheck.errors.BackendError` (exit 3) where this GL cannot render ``spec``'s
    options (:func:`realtime.raster.check_msaa`); nothing for an external renderer. Opens the GL
    context only where the options multisample."""
    msaa = 1 if spec.external else int(getattr(spec.options, "msaa", 1))
    if msaa <= 1:
        return
    from realtime import raster as _raster
    _raster.check_msaa(msaa)


def multiscatter_albedo(mu, roughness, F0, **kwargs):
    """(mean, standard error) of the random walk's directional albedo; arguments as
    :func:`reference.multiscatter_measure.directional_albedo` (``samples``, ``seed``, ``order_max``)."""
    from reference import multiscatter_measure as _ms  # local: sets Mitsuba's variant on first use

    return _ms.directional_albedo(mu, roughness, F0, **kwargs)


def trim_caches(keep_environments: int) -> None:
    """Free the renderers' per-process bakes of all but the ``keep_environments`` most recent
    environments (a process that renders many environments calls it between renders)."""
    _realtime.trim_environment_caches(keep_environments)
