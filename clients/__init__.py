"""External renderers ("bring your own renderer"): any engine that renders an exported pbrcheck
scene (:mod:`pbrcheck.export`) becomes a renderer under test named ``ext:NAME``.

A renderer layer (rank 1, like ``reference`` and ``realtime``; it imports core only). The
comparator reaches it through :mod:`compare.renderers` only.

Modules
-------
- :mod:`clients.config` -- ``renderers.toml``: the built-in clients plus the user's file.
- :mod:`clients.run` -- export, run the command (process group, timeout), validate and cache the
  output, return a pbrcheck :class:`~pbrcheck.exr.Image`.
- :mod:`clients.commands` -- ``pbrcheck export`` and ``pbrcheck render --renderer``.
- ``clients/threejs/``, ``clients/gltf-sample-viewer/``, ``clients/babylon/``,
  ``clients/playcanvas/``, ``clients/filament/`` -- the browser clients (node + headless Chromium;
  ``clients/browser/``: their shared harness, runner and page helpers), docs/renderers.md.
"""
