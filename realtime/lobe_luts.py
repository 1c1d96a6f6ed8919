"""The lobes' LUT bakes on the GL context: the sheen LUT (``realtime/shaders/sheen_lut.comp``), its
conventions :data:`realtime.lobes.SHEEN_LUT_CONVENTIONS` (stated again in the shader's header and at the
reader, ``lobes_sheen.glsl`` sheen_lut_lookup / :func:`realtime.lobes.sheen_lut_lookup`), and its
read-back. Separate from :mod:`realtime.lobes` (numpy only), which the registries import: this module
imports :mod:`realtime.gl`, which imports the registries.

API
---
:func:`sheen_lut`, :func:`read_sheen_lut`.
"""

from __future__ import annotations

import numpy as np

from .gl import compute_program, get_context, groups, shader_sources_hash, timed
from .lobes import SHEEN_LUT_SAMPLES, SHEEN_LUT_SIZE
from .presets import bake_key

_sheen_luts: dict = {}
_sheen_lut_seconds: dict = {}


def sheen_lut(size: int = SHEEN_LUT_SIZE, samples: int = SHEEN_LUT_SAMPLES, fmt: str = "f32",
              timings: dict | None = None):
    """The sheen LUT texture (:data:`realtime.lobes.SHEEN_LUT_CONVENTIONS`), baked once per process and
    shader sources (an edited shader bakes afresh, as realtime.render._baked), keyed by
    :func:`realtime.presets.bake_key` of bake ``sheen_lut`` (options ``sheen_lut_size``, ``sheen_lut_samples``)
    with the format as context. ``timings["sheen_lut"]``: the bake's seconds (:func:`realtime.gl.timed`; a
    cached LUT reports its original bake, as realtime.render's bakes do)."""
    key = (*bake_key("sheen_lut", fmt, sheen_lut_size=size, sheen_lut_samples=samples), shader_sources_hash())
    if key in _sheen_luts:
        if timings is not None:
            timings["sheen_lut"] = _sheen_lut_seconds[key]
        return _sheen_luts[key]
    ctx = get_context()
    prog = compute_program("sheen_lut.comp", {"LUT_FORMAT": "rgba16f" if fmt == "f16" else "rgba32f"})
    tex = ctx.texture((size, size), 4, dtype="f2" if fmt == "f16" else "f4")
    tex.filter = (0x2601, 0x2601)  # GL_LINEAR
    tex.repeat_x = tex.repeat_y = False
    tex.bind_to_image(0, read=False, write=True, level=0)
    prog["lut_size"].value = size
    prog["n_samples"].value = samples
    _, seconds = timed(ctx, lambda: prog.run(groups(size, 8), groups(size, 8), 1))
    ctx.memory_barrier()  # image stores are incoherent (GL 4.6 core, 7.13.2): visible to the read-back after it
    _sheen_luts[key], _sheen_lut_seconds[key] = tex, seconds
    if timings is not None:
        timings["sheen_lut"] = seconds
    return tex


def read_sheen_lut(tex) -> np.ndarray:
    """(N, N, 3) float32: [j, i] = (E_charlie, E_neubelt, E_ibl_sampler_legacy) at n.v (i + 0.5)/N, roughness (j + 0.5)/N."""
    w, h = tex.size
    dt = np.float16 if tex.dtype == "f2" else np.float32
    return np.frombuffer(tex.read(), dt).reshape(h, w, 4)[..., :3].astype(np.float32)
