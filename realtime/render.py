"""The real-time renderer: precompute passes on the GPU, then one compute pass per frame.

Conventions at both ends of every baked artifact
-----------------------------------------------
* Cube maps: faces in GL order +X, -X, +Y, -Y, +Z, -Z (layer = face); texel (x, y) of a face of size
  ``s`` is the direction ``cube_dir(face, ((x, y) + 0.5) / s)`` of ``shaders/env.glsl`` (GL 4.5 table
  8.19 inverted). World space, no flip: the environment is the scene's radiance function as is.
* Environment cube: level 0 = radiance at texel centres (point evaluation of
  :meth:`pbrcheck.environment.EnvMap.radiance`); levels 1.. = box-filtered mips (glGenerateMipmap).
* Irradiance cube / SH9: E(n) / pi (radiance units: Lambert diffuse = albedo x value). The texel sum
  reads its source texels (direction, solid angle, radiance) from a table baked once a bake
  (``irradiance_texels.comp``), the prefilter its half vectors and source levels from a table baked
  once a level (``prefilter_samples.comp``): the same values the loops computed per texel before
  (bit-identical cubes on llvmpipe), 2.4x and 1.3x less CPU (issue 25).
* Prefiltered cube: ``prefilter_levels`` levels, level L baked at roughness
  ``roughness_from_lod(L)`` of the ``lod_mapping`` (shaders/lod.glsl), read at
  ``lod_from_roughness`` (its inverse); max level = prefilter_levels - 1. Two hooks for
  ``pbrcheck fit-lod``: ``lod_mapping=fitted:FILE`` (or a :class:`~pbrcheck.lodmap.LodMapping` held
  in :class:`~realtime.presets.RealtimeOptions`) bakes the chain of the mapping's ``chain`` and
  reads it at the fitted function (``LOD_FITTED(r)``, a ``#define`` of
  :meth:`pbrcheck.lodmap.LodMapping.glsl_expr`); ``lod_override >= 0`` reads every object at that
  level.
* DFG LUT: N x N, texel (row j, column i) = (n.v = (i + 0.5)/N, roughness = (j + 0.5)/N), row 0 the
  smoothest; R = A, G = B; sampled with GL coordinates (n.v, roughness), linear, clamp to edge.
* Kd LUT: N x 1, texel i = n.v (i + 0.5)/N.
* The lobes' bakes (only for programs whose scene uses the lobe, :mod:`realtime.material_lobes`): the
  sheen LUT (:data:`realtime.lobes.SHEEN_LUT_CONVENTIONS`, :func:`realtime.lobe_luts.sheen_lut`) and the
  Charlie-prefiltered cube (:data:`realtime.lobes.CHARLIE_CUBE_CONVENTIONS`, :func:`charlie_cube`).

Compile-time switches are the named constants of the registries (:mod:`realtime.registry`; ``{"GEOMETRY":
"GEOMETRY_SMITH_GGX"}``); uniforms are set with :func:`_set`, which raises on a uniform the program
lacks unless the caller declares it optional (a variant's compiler may drop a uniform its code
does not read; a misspelt or renamed uniform would otherwise render with 0).

API
---
:func:`render_realtime`, :func:`environment_of`, :func:`env_texture`, :func:`env_cube`,
:func:`irradiance_cube`, :func:`sh9_coefficients`, :func:`prefiltered_cube`, :func:`charlie_cube`, :func:`dfg_lut`,
:func:`read_lut`, :func:`kd_lut`, :func:`sample_cube`, :func:`resolved_terms`,
:func:`chain_mapping`, :func:`effective_cube_format`, :func:`frame_bands` (the frame pass, in bands when large),
:func:`as_options`.
"""

from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import asdict

import numpy as np

from pbrcheck.camera import camera_frame, tan_half_fov
from pbrcheck.environment import EnvMap, load_environment
from pbrcheck.errors import BackendError
from pbrcheck.exr import Image
from pbrcheck.lights import pack_lights
from pbrcheck.energy import SCENE_COMPENSATION
from pbrcheck.lodmap import LOD_MAPPINGS
from pbrcheck.progress import Progress
from pbrcheck.registry import FRESNELS, GEOMETRIES, NDFS
from pbrcheck.sampling import LUT_SAMPLINGS, lut_sampling_for
from pbrcheck.scene import Plane, Scene, plane_frame

from .gl import compute_program, get_context, groups, in_bands, renderer_name, shader_sources_hash, timed, timing_clock
from .hooks import load_hook_file
from .material_lobes import lobe_defines, needs_charlie_cube, needs_split_sum_bakes, object_lobe_rows, scene_lobes
from .transmission import lod_bias_defines
from .presets import (
    RealtimeOptions,
    bake_inputs,
    bake_key,
    check_requirements,
    resolve_options,
    unmet_requirements,
)
from .transmission import raycast_notice as transmission_notice
from .transmission import object_transmission_rows, scene_transmissive, transmission_defines, transmission_meta
from .registry import (DFGS, ENERGY_COMPENSATIONS, HORIZON_OCCLUSIONS, IRRADIANCE_METHODS, IRRADIANCES,
                       RUNTIME_SAMPLINGS, SHADINGS, SPECULAR_AAS, SPECULAR_OCCLUSIONS, role_reads)

HALF_MAX = 65504.0
#: Uniforms of the frame pass (render.comp) that some variants do not read, so the compiler drops
#: them: the split sum's prefiltered cube, max_lod and lod_override (ibl=runtime has none); the
#: log2 mapping's cube_log2; runtime sampling's env_cube, env_face_size and runtime_samples; the
#: LUT-based DFG's dfg_lut (dfg=analytic); the irradiance cube (irradiance=sh9); the material
#: composition's Kd LUT (the article compositions have their own diffuse); the SH9 coefficients
#: ``sh`` (irradiance=convolution, or fresnel=none on the material composition, which has no
#: diffuse term). Every other uniform is
#: required: setting one the program lacks is an error (a renamed uniform would render with 0).
FRAME_VARIANT_UNIFORMS = frozenset({"prefiltered", "max_lod", "lod_override", "cube_log2", "env_cube",
                                    "env_face_size", "runtime_samples", "dfg_lut", "irradiance_cube", "kd_lut",
                                    "sh", "sheen_lut", "charlie_cube", "charlie_max_lod"})


def chain_mapping(o: RealtimeOptions) -> str:
    """The built-in mapping whose inverse bakes the prefiltered levels (a fitted mapping's ``chain``):
    :attr:`RealtimeOptions.chain`, a built-in member of :data:`pbrcheck.lodmap.LOD_MAPPINGS`."""
    return o.chain


# Samples of the Kd (diffuse Fresnel) LUT: a smooth 1-D integrand, error < 1e-4 at 4096 points.
KD_LUT_SAMPLES = 4096

_cache: dict = {}
_timings: dict = {}   # artifact key -> seconds it took to bake
_warm: set = set()    # programs already dispatched once (JIT done)


class UniformError(BackendError):
    """A uniform the program lacks was set without being declared optional (renamed or misspelt)."""


def _uniform(prog, name: str, optional: bool):
    """The program's uniform ``name``, or None when it lacks it and ``optional`` (GLSL compilers
    drop uniforms a variant does not read: only those are optional); else :class:`UniformError`."""
    try:
        return prog[name]
    except KeyError:
        if not optional:
            raise UniformError(f"uniform {name!r} is not in the program (renamed or misspelt?); "
                               f"declare it optional where a variant does not read it") from None
        return None


def _set(prog, name, value, optional: bool = False):
    """Set uniform ``name`` (see :func:`_uniform` for ``optional``)."""
    uniform = _uniform(prog, name, optional)
    if uniform is not None:
        uniform.value = value


def _write(prog, name, data: bytes, optional: bool = False):
    """Write an array uniform's bytes (``sh``; see :func:`_uniform` for ``optional``)."""
    uniform = _uniform(prog, name, optional)
    if uniform is not None:
        uniform.write(data)


def _timed(ctx, fn):
    """``(fn(), seconds)`` by :func:`realtime.gl.timed`: GL timer queries on a GPU, wall on llvmpipe."""
    return timed(ctx, fn)


def _visible(result):
    """``result``, after a memory barrier: image stores and SSBO writes of compute shaders are
    incoherent (GL 4.6 core, 7.13.2): a later texture fetch, mip generation or read-back sees them
    only after ``glMemoryBarrier``. llvmpipe runs dispatches in order, so a missing barrier shows on
    a GPU alone (the irradiance bake's table did, on an H100)."""
    get_context().memory_barrier()
    return result


def _baked(key: tuple, timings: dict | None, run):
    """A precompute pass baked once per process: ``run()`` timed with :func:`_timed` on a miss and
    kept in ``_cache`` under ``key`` (:func:`realtime.presets.bake_key`: the bake's name, then its
    context and its options); the bake's wall time goes to ``timings[name]`` on a miss and on a hit
    (a hit reports the original bake, see ``meta["cached_passes"]``). The key ends with the shader
    sources' hash (:func:`realtime.gl.shader_sources_hash`): a shader edited under a running process
    bakes afresh, as its program compiles afresh (a key of the options alone served the old bake)."""
    name = key[0]
    key = (*key, shader_sources_hash())
    if key not in _cache:
        _cache[key], _timings[key] = _timed(get_context(), lambda: _visible(run()))
    if timings is not None:
        timings[name] = _timings[key]
    return _cache[key]


def _env_key(scene_env) -> str:
    return json.dumps(asdict(scene_env), sort_keys=True, default=str)


def environment_of(scene: Scene) -> EnvMap:
    """The scene's :class:`~pbrcheck.environment.EnvMap`, loaded once per process."""
    key = ("envmap", _env_key(scene.environment))
    if key not in _cache:
        _cache[key] = load_environment(scene)
    return _cache[key]


def _bind_env(prog, env_tex, env: EnvMap, unit: int = 0, optional: bool = False):
    """Bind the equirect environment of env.glsl (``optional``: the raster fragment program reads
    it only where a variant looks the environment up directly)."""
    env_tex.use(unit)
    _set(prog, "env_equirect", unit, optional)
    _set(prog, "env_size", (env.width, env.height), optional)
    R = env.to_world()
    _set(prog, "env_rot0", tuple(float(x) for x in R[:, 0]), optional)
    _set(prog, "env_rot1", tuple(float(x) for x in R[:, 1]), optional)
    _set(prog, "env_rot2", tuple(float(x) for x in R[:, 2]), optional)
    _set(prog, "env_scale", float(env.scale), optional)


def env_texture(env: EnvMap):
    """The environment's equirect float32 texture (nearest; the shaders filter it themselves)."""
    key = ("env_tex", env.content_hash)
    if key not in _cache:
        ctx = get_context()
        tex = ctx.texture((env.width, env.height), 3, np.ascontiguousarray(env.data, np.float32).tobytes(), dtype="f4")
        tex.filter = (0x2600, 0x2600)  # GL_NEAREST: read with texelFetch only
        _cache[key] = tex
    return _cache[key]


def effective_cube_format(env: EnvMap, requested: str) -> tuple[str, str | None]:
    """f16 cannot hold radiance above 65504 (it would become Inf): switch to f32 and say so."""
    if requested == "f16" and env.max_radiance * 1.0 > HALF_MAX:
        return "f32", (f"environment radiance {env.max_radiance:.4g} exceeds the half-float maximum {HALF_MAX:g}: "
                       f"cube_format f16 replaced by f32")
    return requested, None


def _cube(size: int, fmt: str, levels: int | None = None):
    ctx = get_context()
    tex = ctx.texture_cube((size, size), 4, dtype="f2" if fmt == "f16" else "f4")
    full = size.bit_length()
    tex.build_mipmaps(0, (levels or full) - 1)
    tex.filter = (0x2703, 0x2601)  # GL_LINEAR_MIPMAP_LINEAR, GL_LINEAR
    return tex


def _image_format(fmt: str) -> str:
    return "rgba16f" if fmt == "f16" else "rgba32f"


def env_cube(env: EnvMap, size: int, fmt: str, timings: dict):
    """Bake the environment into a ``size``^2 cube (level 0 point-evaluated, box-filtered mips)."""
    key = bake_key("env_cube", env.content_hash, cube_size=size, cube_format=fmt)
    prog = compute_program("env_to_cube.comp", {"IMAGE_FORMAT": _image_format(fmt)})

    def run():
        tex = _cube(size, fmt)
        _bind_env(prog, env_texture(env), env)
        tex.bind_to_image(0, read=False, write=True, level=0)
        _set(prog, "face_size", size)
        prog.run(groups(size, 8), groups(size, 8), 6)
        _visible(None)  # the mips are built from the stored level 0
        tex.build_mipmaps()
        return tex

    return _baked(key, timings, run)


def irradiance_cube(env: EnvMap, cube, o: RealtimeOptions, fmt: str, timings: dict):
    """Bake the irradiance cube (E(n) / pi) from the environment cube (``irradiance_method``); reads
    only the options that declare the bake (:func:`realtime.presets.bake_inputs`)."""
    o = bake_inputs("irradiance", o, cube_format=fmt)
    key = o.key(env.content_hash)
    src_lod = math.log2(o.cube_size / o.irradiance_source_size)
    ctx = get_context()
    prog = compute_program("irradiance.comp", {"IMAGE_FORMAT": _image_format(fmt),
                                               **IRRADIANCE_METHODS.select(o.irradiance_method)})
    size = o.irradiance_size
    texel_sum = o.irradiance_method == "texel_sum"
    gather = compute_program("irradiance_texels.comp") if texel_sum else None

    def run():
        tex = ctx.texture_cube((size, size), 4, dtype="f2" if fmt == "f16" else "f4")
        tex.filter = (0x2601, 0x2601)
        cube.use(1)
        texels = None
        if texel_sum:  # the source texels once (irradiance_texels.comp), then the sum over them
            n_src = o.irradiance_source_size
            texels = ctx.buffer(reserve=6 * n_src * n_src * 32)   # SourceTexel: two vec4
            texels.bind_to_storage_buffer(0)
            _set(gather, "src_cube", 1)
            _set(gather, "src_size", n_src)
            _set(gather, "src_lod", float(src_lod))
            gather.run(groups(n_src, 8), groups(n_src, 8), 6)
            # the sum below reads the table through an SSBO: a GPU needs the barrier for the writes to
            # be visible (GL 4.6 core, 7.13.2); llvmpipe's serial dispatches hid its absence, and on
            # an H100 the gate's twenty reruns of the unchanged tree regressed at the 8th bake
            ctx.memory_barrier()
        else:
            _set(prog, "src_cube", 1)
            _set(prog, "src_lod", float(src_lod))
            _set(prog, "step_size", float(o.irradiance_step))
        _set(prog, "face_size", size)
        _set(prog, "src_size", o.irradiance_source_size, optional=not texel_sum)
        tex.bind_to_image(0, read=False, write=True, level=0)
        prog.run(groups(size, 8), groups(size, 8), 6)
        if texels is not None:
            ctx.finish()
            texels.release()
        return tex

    return _baked(key, timings, run)


# Cosine-lobe convolution factors A_l / pi (irradiance over pi), [Ramamoorthi01] eq. 8.
_SH_A = np.array([1.0, 2 / 3, 2 / 3, 2 / 3, 0.25, 0.25, 0.25, 0.25, 0.25])
# Real SH normalization constants of the basis 1, y, z, x, yx, yz, 3z^2-1, zx, x^2-y^2.
_SH_K = np.array([0.282095, 0.488603, 0.488603, 0.488603, 1.092548, 1.092548, 0.315392, 1.092548, 0.546274])


def sh9_coefficients(env: EnvMap, cube, o: RealtimeOptions, fmt: str, timings: dict) -> np.ndarray:
    """(9, 3) coefficients c_i so that sum_i c_i b_i(n) = E(n) / pi (article 002's basis order)."""
    o = bake_inputs("sh9", o, cube_format=fmt)
    key = o.key(env.content_hash)
    size = o.irradiance_source_size
    ctx = get_context()
    prog = compute_program("sh9.comp")

    def run():
        n = 6 * size * size * 9
        buf = ctx.buffer(reserve=n * 16)
        buf.bind_to_storage_buffer(0)
        cube.use(1)
        _set(prog, "src_cube", 1)
        _set(prog, "src_size", size)
        _set(prog, "src_lod", float(math.log2(o.cube_size / size)))
        prog.run(groups(size, 8), groups(size, 8), 6)
        _visible(None)
        proj = np.frombuffer(buf.read(), np.float32).reshape(-1, 9, 4)[..., :3].astype(np.float64).sum(axis=0)
        buf.release()
        # proj_i = int L b_i dw; L_lm = K_i proj_i; E/pi = sum A_l/pi L_lm K_i b_i
        return proj * (_SH_K ** 2 * _SH_A)[:, None]

    return _baked(key, timings, run)


def prefiltered_cube(env: EnvMap, cube, o: RealtimeOptions, fmt: str, timings: dict):
    """Bake the prefiltered chain: level L holds GGX-filtered radiance at the roughness of the chain
    mapping's inverse (``roughness_from_lod``)."""
    chain = chain_mapping(o)  # what the bake reads of lod_mapping (a fitted file's other fields: not)
    o = bake_inputs("prefilter", o, cube_format=fmt, lod_mapping=chain)
    key = o.key(env.content_hash)
    levels = o.prefilter_levels
    size = o.cube_size
    prog = compute_program("prefilter.comp", {
        "IMAGE_FORMAT": _image_format(fmt), "FILTERED": int(o.prefilter_filtered),
        "NL_WEIGHT": int(o.prefilter_nl_weight), **LOD_MAPPINGS.select(chain)})
    table = compute_program("prefilter_samples.comp", {"FILTERED": int(o.prefilter_filtered),
                                                       **LOD_MAPPINGS.select(chain)})
    ctx = get_context()

    def run():
        tex = _cube(size, fmt, levels)
        cube.use(1)
        _set(prog, "src_cube", 1)
        # Filtered importance sampling reads the source size (in the sample table); only the log2
        # chain reads cube_log2.
        _set(prog, "max_lod", float(levels - 1))
        _set(prog, "cube_log2", float(math.log2(size)), optional=chain != "log2")
        _set(prog, "n_samples", int(o.prefilter_samples))
        ns = int(o.prefilter_samples)
        # The level's sample table (prefilter_samples.comp, the same uniforms), then the level.
        _set(table, "src_face_size", float(size), optional=not o.prefilter_filtered)
        _set(table, "max_lod", float(levels - 1))
        _set(table, "cube_log2", float(math.log2(size)), optional=chain != "log2")
        _set(table, "n_samples", ns)
        tables = []
        for L in range(levels):
            s = max(size >> L, 1)
            samples = ctx.buffer(reserve=ns * 16)   # vec4 a sample: half vector, source lod
            tables.append(samples)
            samples.bind_to_storage_buffer(0)
            _set(table, "level", float(L))
            table.run(groups(ns, 64))
            ctx.memory_barrier()
            tex.bind_to_image(0, read=False, write=True, level=L)
            _set(prog, "face_size", s)
            _set(prog, "level", float(L))
            prog.run(groups(s, 8), groups(s, 8), 6)
        ctx.finish()
        for t in tables:
            t.release()
        return tex

    return _baked(key, timings, run)


def charlie_cube(env: EnvMap, cube, o: RealtimeOptions, fmt: str, timings: dict):
    """Bake the Charlie-prefiltered cube of the sheen lobe (``charlie_prefilter.comp``; its conventions
    :data:`realtime.lobes.CHARLIE_CUBE_CONVENTIONS`): ``charlie_levels`` levels of a ``charlie_size``^2 cube,
    level L at sheen roughness L / (levels - 1), each texel ``charlie_samples`` Charlie samples of the
    environment cube read at their pdf's level."""
    o = bake_inputs("charlie_prefilter", o, cube_format=fmt)
    key = o.key(env.content_hash)
    size, levels = o.charlie_size, o.charlie_levels
    prog = compute_program("charlie_prefilter.comp", {"IMAGE_FORMAT": _image_format(fmt)})

    def run():
        tex = _cube(size, fmt, min(levels, size.bit_length()))
        cube.use(1)
        _set(prog, "src_cube", 1)
        _set(prog, "src_face_size", float(o.cube_size))
        _set(prog, "n_samples", int(o.charlie_samples))
        for L in range(min(levels, size.bit_length())):
            s = max(size >> L, 1)
            tex.bind_to_image(0, read=False, write=True, level=L)
            _set(prog, "face_size", s)
            _set(prog, "sheen_roughness", L / (levels - 1))
            prog.run(groups(s, 8), groups(s, 8), 6)
        return tex

    return _baked(key, timings, run)


def dfg_lut(size: int, samples: int, fmt: str, geometry: str, ndf: str = "ggx", sampling: str = "vndf",
            timings: dict | None = None):
    """The DFG LUT texture (RG16F or RG32F), see the module docstring for its axes."""
    sampling = lut_sampling_for(sampling, ndf)  # e.g. visible-normal sampling exists for GGX only
    key = bake_key("dfg_lut", lut_size=size, lut_samples=samples, lut_format=fmt, lut_geometry=geometry, ndf=ndf,
                   lut_sampling=sampling)
    ctx = get_context()
    prog = compute_program("dfg_lut.comp", {
        "LUT_FORMAT": "rg16f" if fmt == "f16" else "rg32f", **LUT_SAMPLINGS.select(sampling),
        **NDFS.select(ndf), **GEOMETRIES.select(geometry)})

    def run():
        tex = ctx.texture((size, size), 2, dtype="f2" if fmt == "f16" else "f4")
        tex.filter = (0x2601, 0x2601)
        tex.repeat_x = tex.repeat_y = False
        tex.bind_to_image(0, read=False, write=True, level=0)
        _set(prog, "lut_size", size)
        _set(prog, "n_samples", samples)
        prog.run(groups(size, 8), groups(size, 8), 1)
        return tex

    return _baked(key, timings, run)


def read_lut(tex) -> np.ndarray:
    """(N, N, 2) float32: [j, i] = (A, B) at n.v (i+0.5)/N, roughness (j+0.5)/N."""
    w, h = tex.size
    dt = np.float16 if tex.dtype == "f2" else np.float32
    return np.frombuffer(tex.read(), dt).reshape(h, w, 2).astype(np.float32)


def kd_lut(size: int, timings: dict):
    """Bake the N x 1 Kd (diffuse Fresnel weight) LUT over n.v."""
    key = bake_key("kd_lut", lut_size=size)
    ctx = get_context()
    prog = compute_program("kd_lut.comp")

    def run():
        tex = ctx.texture((size, 1), 1, dtype="f4")
        tex.filter = (0x2601, 0x2601)
        tex.repeat_x = tex.repeat_y = False
        tex.bind_to_image(0, read=False, write=True, level=0)
        _set(prog, "lut_size", size)
        _set(prog, "n_samples", KD_LUT_SAMPLES)
        prog.run(groups(size, 64))
        return tex

    return _baked(key, timings, run)


def sample_cube(tex, directions: np.ndarray, lod: float = 0.0) -> np.ndarray:
    """Read a cube texture at world directions (..., 3) through textureLod; returns (..., 3)."""
    ctx = get_context()
    d = np.asarray(directions, np.float32).reshape(-1, 3)
    n = len(d)
    inp = np.zeros((n, 4), np.float32)
    inp[:, :3] = d
    inp[:, 3] = lod
    a = ctx.buffer(inp.tobytes())
    out = ctx.buffer(reserve=max(n, 1) * 16)
    a.bind_to_storage_buffer(0)
    out.bind_to_storage_buffer(1)
    prog = compute_program("sample_cube.comp")
    tex.use(0)
    _set(prog, "cube", 0)
    _set(prog, "count", n)
    prog.run(groups(n, 64))
    _visible(None)
    res = np.frombuffer(out.read(), np.float32).reshape(n, 4)[:, :3].copy()
    a.release()
    out.release()
    return res.reshape(*np.shape(directions)[:-1], 3)


def _dummy(kind: str):
    key = ("dummy", kind)
    if key not in _cache:
        ctx = get_context()
        if kind == "cube":
            t = ctx.texture_cube((1, 1), 4, np.zeros(6 * 16, np.uint8).tobytes(), dtype="f4")
        else:
            t = ctx.texture((1, 1), 4, np.zeros(16, np.uint8).tobytes(), dtype="f4")
        _cache[key] = t
    return _cache[key]


def _object_buffer(scene: Scene) -> np.ndarray:
    rows = []
    for ob in scene.objects:
        m = ob.material
        if isinstance(ob, Plane):
            t, b, n = plane_frame(ob.normal)
            rows.append([*ob.center, 1.0, *n, 0.0, *t, ob.size[0], *b, ob.size[1],
                         *m.base_color, m.metallic, m.roughness, m.specular, ob.id, 0.0])
        else:
            rows.append([*ob.center, 0.0, 0.0, 0.0, 1.0, ob.radius, 0, 0, 0, 0, 0, 0, 0, 0,
                         *m.base_color, m.metallic, m.roughness, m.specular, ob.id, 0.0])
    if not rows:
        rows.append([0.0] * 24)
    return np.asarray(rows, np.float32)


#: The shadings (realtime.registry.SHADINGS) that render the scene's ``[brdf] metallic_blend``: the
#: material composition; the article compositions are their articles' code, F0 mix included.
BLEND_FOLLOWING_SHADINGS = ("material",)


def resolved_terms(scene: Scene, o: RealtimeOptions) -> dict:
    """The D, G, F and LUT-G terms this render uses: an option's value, or the scene's ``[brdf]`` for ``scene``."""
    ndf = scene.brdf.ndf if o.ndf == "scene" else o.ndf
    geometry = scene.brdf.geometry if o.geometry == "scene" else o.geometry
    fresnel = scene.brdf.fresnel if o.fresnel == "scene" else o.fresnel
    lut_geometry = scene.brdf.geometry if o.lut_geometry == "scene" else o.lut_geometry
    # The metallic blend is the scene's ([brdf] metallic_blend): the material composition renders it
    # (brdf.glsl, shading.glsl: METALLIC_BLEND_GLTF); the article compositions keep their articles' F0
    # mix whatever the scene says (BLEND_FOLLOWING_SHADINGS), and the render's "terms" metadata says
    # which one it used.
    blend = scene.brdf.metallic_blend if o.shading in BLEND_FOLLOWING_SHADINGS else "f0"
    return {"ndf": ndf, "geometry": geometry, "fresnel": fresnel, "lut_geometry": lut_geometry,
            "metallic_blend": blend}


def resolved_energy_compensation(scene: Scene, o: RealtimeOptions) -> str:
    """The energy compensation this render uses: the option's value, or for ``scene`` the one that
    matches the scene's reference physics (:data:`pbrcheck.energy.SCENE_COMPENSATION`: none for
    single scattering, the best measured one for ``multiscatter = "random_walk"``)."""
    v = o.energy_compensation
    if v != "scene":
        return v
    v = SCENE_COMPENSATION[scene.brdf.multiscatter]
    # none where the options do not meet its requirements (the material composition's split sum)
    return "none" if unmet_requirements(ENERGY_COMPENSATIONS[v], o) else v


def frame_defines(o: RealtimeOptions, terms: dict) -> dict:
    """The frame pass's ``#define``s for resolved options ``o`` and terms ``terms`` (the render's
    :func:`resolved_terms` plus its ``energy_compensation``, see :func:`resolved_energy_compensation`).

    Every switch comes from its registry (:mod:`realtime.registry`), so the GLSL tests named constants;
    a fitted LOD mapping adds its polynomial as the ``LOD_FITTED(r)`` macro.
    """
    shading = o.shading  # its combination with ibl is checked by resolve_options
    fm = o.fitted
    defines = {
        **SHADINGS.select(shading), **NDFS.select(terms["ndf"]), **GEOMETRIES.select(terms["geometry"]),
        **FRESNELS.select(terms["fresnel"]), **IRRADIANCES.select(o.irradiance), **DFGS.select(o.dfg),
        **LOD_MAPPINGS.select("fitted" if fm is not None else o.lod_mapping), "SHADOWS": int(o.shadows),
        **RUNTIME_SAMPLINGS.select(o.runtime_sampling),
        **ENERGY_COMPENSATIONS.select(terms["energy_compensation"]),
        **SPECULAR_OCCLUSIONS.select(o.specular_occlusion), **HORIZON_OCCLUSIONS.select(o.horizon_occlusion),
        **SPECULAR_AAS.select(o.specular_aa),
        "RUNTIME_LOD": int(o.runtime_lod), "RUNTIME_ROTATE": int(o.runtime_rotate),
        "REFLECT_BUG": int(o.reflect_bug), "IBL_RUNTIME": int(o.ibl == "runtime"),
        "TEXTURE_LOD0": int(o.texture_sampling == "lod0"), "NORMAL_LOD0": int(o.normal_sampling == "lod0"),
    }
    if fm is not None:
        defines["LOD_FITTED(r)"] = fm.glsl_expr("(r)")
    if terms.get("metallic_blend", "f0") == "gltf":  # glTF 2.0 Appendix B (brdf.glsl, shading.glsl)
        defines["METALLIC_BLEND_GLTF"] = 1
    if o.shader:
        defines.update(load_hook_file(o.shader).defines)
    return defines


#: Texture unit of each sampler of the frame pass (unit 0 is the equirect environment).
FRAME_TEXTURE_UNITS = (("prefiltered", 1, "cube"), ("irradiance_cube", 2, "cube"), ("env_cube", 3, "cube"),
                       ("dfg_lut", 4, "2d"), ("kd_lut", 5, "2d"))
#: Texture units of the lobes' baked inputs (material_lobes.glsl; bound only in lobe programs; after the
#: raster pass's material units 6-11).
LOBE_TEXTURE_UNITS = (("sheen_lut", 12, "2d"), ("charlie_cube", 13, "cube"))


def _bind_frame(prog, scene: Scene, o: RealtimeOptions, env, textures: dict, sh) -> tuple:
    """Bind the frame pass's inputs and outputs and set its uniforms.

    Returns the GL objects to release after the frame: the object and light buffers, then the colour,
    AOV and object-index output images.
    """
    ctx = get_context()
    W, H = scene.camera.width, scene.camera.height
    objs = ctx.buffer(_object_buffer(scene).tobytes())
    objs.bind_to_storage_buffer(0)
    if textures.get("lobes"):  # the ObjectLobes buffer (render.comp, binding 3), lobe programs only
        lobes = ctx.buffer(object_lobe_rows(scene).tobytes())
        lobes.bind_to_storage_buffer(3)
        objs = _Released(objs, lobes)
    if textures.get("transmission"):  # the ObjectTransmission buffer (render.comp, binding 4), transmission programs only
        trans = ctx.buffer(object_transmission_rows(scene).tobytes())
        trans.bind_to_storage_buffer(4)
        objs = _Released(objs, trans)
    lbuf = _bind_shading(prog, scene, o, env, textures, sh)
    out_color = ctx.texture((W, H), 4, dtype="f4")
    out_aov = ctx.texture((W, H), 4, dtype="f4")
    out_obj = ctx.texture((W, H), 1, dtype="f4")
    out_color.bind_to_image(0, read=False, write=True, level=0)
    out_aov.bind_to_image(1, read=False, write=True, level=0)
    out_obj.bind_to_image(2, read=False, write=True, level=0)
    r, u, f = camera_frame(scene.camera)
    tx, ty = tan_half_fov(scene.camera)
    _set(prog, "n_objects", len(scene.objects))
    _set(prog, "cam_origin", tuple(float(x) for x in scene.camera.origin))
    _set(prog, "cam_right", tuple(float(x) for x in r * tx))
    _set(prog, "cam_up", tuple(float(x) for x in u * ty))
    _set(prog, "cam_forward", tuple(float(x) for x in f))
    _set(prog, "image_size", (W, H))
    _set(prog, "ss", int(o.supersample))
    return objs, lbuf, out_color, out_aov, out_obj


class _Released:
    """GL objects released together (the object buffer and, in lobe programs, the ObjectLobes buffer)."""

    def __init__(self, *objs):
        self.objs = objs

    def release(self):
        for g in self.objs:
            g.release()


def _bind_shading(prog, scene: Scene, o: RealtimeOptions, env, textures: dict, sh, raster: bool = False):
    """Bind the shading module's inputs (shading.glsl: environment, baked textures, SH, lights
    buffer, LOD and roughness uniforms) for ``prog`` (the compute frame pass or the raster
    fragment program); returns the lights buffer to release after the frame."""
    ctx = get_context()
    lbuf = ctx.buffer(pack_lights(scene.lights).tobytes())  # 3 vec4 per light (shaders/lights.glsl)
    lbuf.bind_to_storage_buffer(1)
    _bind_env(prog, env_texture(env), env, 0, optional=raster)
    for name, unit, kind in FRAME_TEXTURE_UNITS:
        tex = textures[name]
        (tex if tex is not None else _dummy(kind)).use(unit)
        _set(prog, name, unit, optional=name in FRAME_VARIANT_UNIFORMS)
    if o.irradiance == "sh9":
        _write(prog, "sh", np.asarray(sh, np.float32).tobytes(), optional="sh" in FRAME_VARIANT_UNIFORMS)
    _set(prog, "n_lights", len(scene.lights))
    for name, value in (("max_lod", float(o.prefilter_levels - 1)),
                        ("cube_log2", float(math.log2(o.cube_size))),
                        ("env_face_size", float(o.cube_size)),
                        ("runtime_samples", int(o.runtime_samples)),
                        ("lod_override", float(o.lod_override))):
        _set(prog, name, value, optional=name in FRAME_VARIANT_UNIFORMS)
    _set(prog, "min_roughness", float(o.min_roughness))
    if textures.get("lobes"):  # material_lobes.glsl's baked inputs (each read by some lobe programs only)
        for name, unit, kind in LOBE_TEXTURE_UNITS:
            tex = textures.get(name)
            (tex if tex is not None else _dummy(kind)).use(unit)
            _set(prog, name, unit, optional=True)
        _set(prog, "charlie_max_lod", float(o.charlie_levels - 1), optional=True)
    return lbuf


def _frame_meta(scene: Scene, preset: str, o: RealtimeOptions, terms: dict, timings: dict, cached_before: set,
                fmt: str, warnings: list, hooks=None) -> dict:
    """The EXR metadata of a real-time render: preset, options, terms, timings and conventions; with a
    shader hook file, its path, SHA-256 and the hooks it defines (``shader``)."""
    cached = sorted(p for p in ("env_cube", "irradiance", "sh9", "prefilter", "dfg_lut", "kd_lut", "charlie_prefilter")
                    if p in timings and any(isinstance(c, tuple) and c[0] == p for c in cached_before))
    return {
        "renderer": "realtime",
        "gl_renderer": renderer_name(),
        "timing_clock": timing_clock(),
        "preset": preset,
        "options": json.dumps(o.as_dict(), sort_keys=True),
        "terms": json.dumps(terms, sort_keys=True),
        "timings": json.dumps(timings, sort_keys=True),
        "cached_passes": json.dumps(cached),
        "cube_format_used": fmt,
        "warnings": json.dumps(warnings),
        "scene": scene.name,
        "shader": json.dumps({"path": hooks.path, "sha256": hooks.sha256, "hooks": list(hooks.hooks)}
                             if hooks else None),
        "conventions": json.dumps({
            "cube_faces": "+X,-X,+Y,-Y,+Z,-Z (GL order)",
            "lut": "pixel (row j, col i): n.v=(i+0.5)/N, roughness=(j+0.5)/N, row 0 smoothest; R=A, G=B",
            "prefilter_levels": o.prefilter_levels,
            "irradiance": "E(n)/pi",
            "aovs": "N, NdotV, object at the pixel centre ray; coverage over the s x s samples",
        }),
    }


def render_realtime(scene: Scene, preset: str = "default", options: RealtimeOptions | dict | None = None, *,
                    progress: bool = True) -> Image:
    """Render ``scene`` with ``preset`` and its options; returns R, G, B and the AOVs.

    ``options``: the resolved :class:`~realtime.presets.RealtimeOptions` of ``preset`` (what a caller
    that parsed them once passes: :class:`compare.renderers.RendererSpec`, :mod:`realtime.cache`;
    rendered as they are), or option overrides resolved here (:func:`as_options`).

    Meta: ``preset``, ``options`` (JSON of every option value), ``timings`` (JSON seconds per pass;
    a pass whose artifact came from this process's cache reports its original bake time and is listed
    in ``cached_passes``; GL timer queries on a GPU, the wall clock on llvmpipe: ``timing_clock``),
    ``gl_renderer``, ``warnings``, ``renderer``, ``terms``.

    Before any bake: :class:`~realtime.presets.OptionError` for options the resolved pipeline does not
    take, :class:`pbrcheck.errors.BackendError` (exit 3) for ``msaa`` above this GL's
    ``GL_MAX_SAMPLES`` (:func:`realtime.raster.check_msaa`).
    """
    o = as_options(preset, options)
    pipeline = resolved_pipeline(scene, o)
    check_pipeline_options(pipeline, o)
    ctx = get_context()
    if pipeline == "raster":  # this GL's limits, before any bake
        from .raster import check_msaa, check_target_size, check_texture_sizes
        check_msaa(int(o.msaa))
        check_target_size(scene.camera.width, scene.camera.height, int(o.supersample))
        check_texture_sizes(scene)
    terms = {**resolved_terms(scene, o), "energy_compensation": resolved_energy_compensation(scene, o)}
    timings: dict = {}
    cached_before = {k for k in _cache}
    warnings = []
    env = environment_of(scene)
    fmt, warn = effective_cube_format(env, o.cube_format)
    if warn:
        warnings.append(warn)
        if progress:
            print(f"pbrcheck realtime: {warn}", file=sys.stderr)
    W, H = scene.camera.width, scene.camera.height
    n_passes = 6
    with Progress(f"realtime {scene.name} [{preset}]", total=n_passes, enabled=progress) as bar:
        cube = env_cube(env, o.cube_size, fmt, timings)
        bar.update(1, "env_cube")
        irr = None
        sh = np.zeros((9, 3))
        if o.irradiance == "sh9":
            sh = sh9_coefficients(env, cube, o, fmt, timings)
        else:
            irr = irradiance_cube(env, cube, o, fmt, timings)
        bar.update(1, "irradiance")
        # the lobes the scene's materials use, compiled into this render's programs (material_lobes.glsl);
        # none: the programs and bakes are exactly the lobe-free ones
        lobes = scene_lobes(scene)
        ldefs = lobe_defines(lobes, o)
        if lobes and not ldefs:
            warnings.append(f"lobes_ignored: shading={o.shading} renders no lobe ({', '.join(lobes)}); "
                            f"shading=material does")
        # transmission (realtime/transmission.py): compiled only into the programs of scenes with a
        # transmissive material; reads the prefiltered cube (Filament's cube-map refraction in the ray-cast
        # pipeline, the off-screen fallback in the raster one) and the DFG LUT
        tdefs = transmission_defines(scene, o, pipeline)
        tdefs.update(lod_bias_defines(tdefs, o))   # option transmission_lod_bias (compare.transmission_split)
        tnote = transmission_notice(scene, o, pipeline)
        if tnote:
            warnings.append(tnote)
            if progress:
                print(f"pbrcheck realtime: {tnote}", file=sys.stderr)
        split = o.ibl == "splitsum" or needs_split_sum_bakes(ldefs) or bool(tdefs)
        pre = None
        if split:
            pre = prefiltered_cube(env, cube, o, fmt, timings)
        bar.update(1, "prefilter")
        lut = None
        if o.dfg == "lut" and split:  # runtime sampling integrates the BRDF itself
            lut = dfg_lut(o.lut_size, o.lut_samples, o.lut_format, terms["lut_geometry"], terms["ndf"],
                          o.lut_sampling, timings)
        bar.update(1, "dfg_lut")
        kd = kd_lut(o.lut_size, timings)
        bar.update(1, "kd_lut")

        defines = {**frame_defines(o, terms), **ldefs, **tdefs}
        hooks = load_hook_file(o.shader) if o.shader else None
        baked = {"prefiltered": pre, "irradiance_cube": irr, "env_cube": cube, "dfg_lut": lut, "kd_lut": kd,
                 "transmission": bool(tdefs)}
        if ldefs:
            from .lobe_luts import sheen_lut
            b = bake_inputs("sheen_lut", o)
            baked.update(lobes=lobes, sheen_lut=sheen_lut(b.sheen_lut_size, b.sheen_lut_samples, timings=timings)
                         if "LOBE_SHEEN" in ldefs else None,
                         charlie_cube=charlie_cube(env, cube, o, fmt, timings) if needs_charlie_cube(ldefs) else None)
        if pipeline == "raster":
            color, aov, obj = _raster(scene, o, env, baked, sh, defines, hooks, timings)
            bar.update(1, "frame")
            meta = _frame_meta(scene, preset, o, terms, timings, cached_before, fmt, warnings, hooks)
            meta["pipeline"] = pipeline
            _lobe_meta(meta, ldefs)
            meta.update(transmission_meta(tdefs, o, pipeline))
            return _image(color, aov, obj, meta)
        t0 = time.perf_counter()
        prog = compute_program("render.comp", defines, (hooks.path, hooks.text) if hooks else None)
        timings["compile_frame"] = time.perf_counter() - t0

        buffers = _bind_frame(prog, scene, o, env, baked, sh)
        out_color, out_aov, out_obj = buffers[2:]

        def frame():
            frame_bands(ctx, prog, W, H, int(o.supersample))

        if id(prog) not in _warm:
            # Warm-up: llvmpipe compiles the shader to machine code at its first dispatch; one 8x8
            # tile takes that cost out of the timed frame (the tile is rewritten by the frame).
            _, timings["frame_warmup"] = _timed(ctx, lambda: prog.run(1, 1, 1))
            _warm.add(id(prog))

        _, timings["frame"] = _timed(ctx, frame)
        bar.update(1, "frame")
        _visible(None)  # the frame's image stores, before the read-back
        color = np.frombuffer(out_color.read(), np.float32).reshape(H, W, 4).copy()
        aov = np.frombuffer(out_aov.read(), np.float32).reshape(H, W, 4).copy()
        obj = np.frombuffer(out_obj.read(), np.float32).reshape(H, W).copy()
        for t in buffers:
            t.release()

    meta = _frame_meta(scene, preset, o, terms, timings, cached_before, fmt, warnings, hooks)
    meta["pipeline"] = pipeline
    _lobe_meta(meta, ldefs)
    meta.update(transmission_meta(tdefs, o, pipeline))
    return _image(color, aov, obj, meta)


def _lobe_meta(meta: dict, ldefs: dict) -> None:
    """``meta["lobes"]``: the lobe switches compiled into the render's programs (JSON), only where there
    are some (a lobe-free render's metadata is what it was)."""
    if ldefs:
        meta["lobes"] = json.dumps(ldefs, sort_keys=True)


def frame_bands(ctx, prog, W: int, H: int, ss: int) -> int:
    """Dispatch the frame pass ``prog`` (render.comp) over the W x H image through
    :func:`realtime.gl.in_bands`: one dispatch for a frame of at most
    :data:`~realtime.gl.SINGLE_DISPATCH_SAMPLES` samples, else bands of rows with ``glFinish``
    between (a SIGTERM is honoured between two). A pixel is computed once, from its own coordinates
    (``tile_origin`` + the invocation's): the image is bit-identical either way. Returns the number
    of dispatches."""
    def band(y: int, rows: int) -> None:
        _set(prog, "tile_origin", (0, y))
        prog.run(groups(W, 8), groups(rows, 8), 1)

    return in_bands(ctx, H, W * ss * ss, band)


def _image(color, aov, obj, meta) -> Image:
    return Image({
        "R": color[..., 0], "G": color[..., 1], "B": color[..., 2],
        "N.X": aov[..., 0], "N.Y": aov[..., 1], "N.Z": aov[..., 2], "NdotV": aov[..., 3],
        "object": obj, "coverage": color[..., 3],
    }, meta)


def as_options(preset: str, options: RealtimeOptions | dict | None) -> RealtimeOptions:
    """``options`` when they are resolved already (a :class:`~realtime.presets.RealtimeOptions`:
    resolved once by the caller), else ``preset``'s with these overrides
    (:func:`~realtime.presets.resolve_options`)."""
    return options if isinstance(options, RealtimeOptions) else resolve_options(preset, options)


def resolved_pipeline(scene: Scene, o: RealtimeOptions) -> str:
    """``raycast`` or ``raster``: the option's value, or for ``auto`` raster exactly when the scene
    holds glTF meshes, or a transmissive material without ``shadows`` (only the raster pipeline has the
    opaque pass transmission reads, realtime/transmission.py); other analytic scenes keep the exact
    ray-cast geometry. ``raycast`` on a scene with meshes raises
    :class:`pbrcheck.gltf_scene.UnsupportedSceneError`."""
    from pbrcheck.gltf_scene import require_analytic, scene_has_assets
    if o.pipeline == "auto":
        return "raster" if scene_has_assets(scene) or (scene_transmissive(scene) and not o.shadows) else "raycast"
    if o.pipeline == "raycast":
        require_analytic(scene, "real-time pipeline=raycast")
    return o.pipeline


def check_pipeline_options(pipeline: str, o: RealtimeOptions) -> None:
    """Raise :class:`~realtime.presets.OptionError` for the options whose requirements the resolved
    ``pipeline`` does not meet (the raster-only ones on a render that ``auto`` resolved to the ray-cast
    pipeline): :func:`~realtime.presets.resolve_options` leaves these to the render
    (:data:`~realtime.presets.DEFERRED`) and refuses them with an explicit ``pipeline``."""
    check_requirements(o, {"pipeline": pipeline})


def _raster(scene: Scene, o: RealtimeOptions, env, baked: dict, sh, defines: dict, hooks, timings: dict):
    """One frame of the raster pipeline (:mod:`realtime.raster`): (color, aov, object) arrays."""
    from . import raster
    ctx = get_context()
    user = (hooks.path, hooks.text) if hooks else None
    t0 = time.perf_counter()
    items = raster.draw_items(scene)
    timings["geometry"] = time.perf_counter() - t0
    # KHR_materials_unlit: its path is compiled only into the programs of scenes that draw an unlit material
    unlit = {"UNLIT_MATERIALS": 1} if any(it.unlit for it in items) else {}
    t0 = time.perf_counter()
    prog = raster.graphics_program("raster.vert", "raster.frag",
                                   {**defines, **unlit, "AOV_PASS": 0, "ALPHA_TO_COVERAGE": int(o.alpha_to_coverage)},
                                   user)
    aov_prog = raster.graphics_program("raster.vert", "raster.frag", {**defines, "AOV_PASS": 1}, user)
    bg_prog = raster.graphics_program("fullscreen.vert", "raster_background.frag")
    timings["compile_frame"] = time.perf_counter() - t0
    lbuf = _bind_shading(prog, scene, o, env, baked, sh, raster=True)
    # the specular_aa member reads a baked variance (prefiltered): bind each normal map's slope-variance mips
    variance = role_reads(SPECULAR_AAS, o.specular_aa, "specular_aa", "variance")
    _bind_env(bg_prog, env_texture(env), env, 0)
    try:
        # upload the material textures and generate their mips before the timed frame, each timed
        timings.update(texture_upload=0.0, texture_mips=0.0)
        for it in items:
            for image, ref, srgb in (*it.textures.values(), *it.lobe_textures.values(),
                                     *it.transmission_textures.values()):
                raster._texture(image, ref, srgb, o.anisotropy, timings)
            if variance and "normal" in it.textures:  # and its slope-variance mips
                t0 = time.perf_counter()
                raster.normal_variance_texture(*it.textures["normal"][:2], o.anisotropy)
                ctx.finish()
                timings["texture_mips"] += time.perf_counter() - t0
        # timings["frame"]: the draws alone (raster_frame); frame_total: the whole call, with the
        # render targets' allocation, the read-back and box filter, and the AOV pass
        t0 = time.perf_counter()
        color, aov, obj = raster.raster_frame(scene, items, prog, aov_prog, bg_prog, int(o.supersample), o.anisotropy,
                                              o.occlusion_texture, msaa=o.msaa, alpha_to_coverage=o.alpha_to_coverage,
                                              normal_variance=variance, timings=timings)
        timings["frame_total"] = time.perf_counter() - t0
    finally:
        lbuf.release()
    return color, aov, obj


#: Cache kinds whose key's second element is an environment's content hash.
ENVIRONMENT_CACHE_KINDS = ("env_tex", "env_cube", "irradiance", "sh9", "prefilter", "charlie_prefilter")


def trim_environment_caches(keep: int) -> int:
    """Free what this process baked for all but the ``keep`` most recently first-seen environments
    (their textures, cubes, SH coefficients and loaded maps); returns how many were freed.

    Every environment's bakes stay in this process's cache for the next render (about 30 MiB per
    1k x 512 map with the default preset), so a process that renders a long corpus calls this
    between renders (:func:`compare.renderers.trim_caches`) to keep its memory bounded. GL objects
    are released explicitly (moderngl does not free them when they are dropped)."""
    order: list[str] = []
    for k in _cache:
        if isinstance(k, tuple) and k[0] in ENVIRONMENT_CACHE_KINDS and k[1] not in order:
            order.append(k[1])
    drop = set(order[:max(len(order) - keep, 0)])
    if not drop:
        return 0
    for k in list(_cache):
        if not isinstance(k, tuple):
            continue
        env_bake = k[0] in ENVIRONMENT_CACHE_KINDS and k[1] in drop
        env_map = k[0] == "envmap" and getattr(_cache[k], "content_hash", None) in drop
        if env_bake or env_map:
            v = _cache.pop(k)
            _timings.pop(k, None)
            for obj in (v if isinstance(v, tuple) else (v,)):
                release = getattr(obj, "release", None)
                if callable(release):
                    release()
    return len(drop)
