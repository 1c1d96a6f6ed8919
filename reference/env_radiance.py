"""The reference's environment radiance: an exact float32 bilinear lookup in Dr.Jit, the function of
:meth:`pbrcheck.environment.EnvMap.radiance` on every backend.

Why: Mitsuba's ``envmap`` ``eval`` (and the value its ``sample_direction`` divides by its pdf)
interpolates through ``dr.Texture2f``, which on CUDA uses the GPU's hardware texture units: the
position between texels has 8 fractional bits. Measured on an NVIDIA H100, Mitsuba 3.9.1
``cuda_ad_rgb``, a random 64 x 37 map, 50 000 random directions, against ``EnvMap.radiance``: max
relative error 0.16, 99th percentile 0.0094, max absolute 0.025 (``llvm_ad_rgb``: p99 1.4e-5). The
``envmap`` plugin has no switch to turn the acceleration off (its dict refuses ``accel``). The
project's rule is that every renderer reads the same environment radiance function, so the local
estimator reads it here, on both backends, and keeps Mitsuba's envmap for its importance sampling
and its pdf only (the weight of a Mitsuba sample is this radiance over Mitsuba's pdf: unbiased).

Convention (input end: the emitter's own parameters, as :func:`reference.render.environment_emitter_dict`
builds them from the shared :class:`~pbrcheck.environment.EnvMap`; output end: its ``radiance``):

* pixels: ``mi.traverse(emitter)["data"]``, Mitsuba 3.9.1's padded layout ``(H, W + 2, 3)`` =
  ``[column W-1, columns 0 .. W-1, column 0]``; the ``W`` real columns are kept (the padding is
  checked: ``BackendError`` otherwise, another Mitsuba's layout). ``scale``: ``mi.traverse(emitter)["scale"]``;
  rotation: ``emitter.world_transform()``.
* ``d_local = R^-1 d`` (``d`` the unit world direction the radiance arrives *from*, ``-si.wi`` as
  Mitsuba's ``eval`` reads it); ``u = atan2(x, -z) / 2pi``, ``v = safe_acos(y) / pi``;
  half-texel shift ``u -= 0.5 / W``, then wrap ``u -= floor(u)``, ``v -= floor(v)``;
  ``x = u W`` (column ``c`` at ``u = (c + 0.5) / W``; the first column copied as padding after the
  last: ``c + 1 = W`` reads column 0), ``y = v (H - 1)`` (row ``r`` at ``theta = pi r / (H - 1)``);
  ``ix = min(floor x, W - 1)``, ``iy = min(floor y, H - 2)``, bilinear with float weights
  ``x - ix``, ``y - iy`` of the 4 texels (manual gathers), each step ``a + w (b - a)`` (so a
  constant region is exactly its value, as in Mitsuba); times ``scale``. All in float32: equal
  to ``EnvMap.radiance`` (float64) within float32 rounding of the position
  (``tests/test_env_radiance.py``, on the active variant, so on CUDA too).

API: :class:`ExactEnvironment` (``radiance(d, active)``), :func:`emitter_pixels`, :class:`ExactEnvmap`
(plugin :data:`ENVMAP_PLUGIN`), :func:`bind_environment`, :func:`exact_environment`, :func:`register`,
:data:`RAY_EPSILON`. References: ``pbrcheck/environment.py`` (the convention, Mitsuba 3's
``envmap.cpp``); Dr.Jit ``Texture`` (``use_accel``: hardware interpolation on CUDA).
"""

from __future__ import annotations

import numpy as np

import drjit as dr
import mitsuba as mi

from pbrcheck.errors import BackendError


def emitter_pixels(emitter) -> np.ndarray:
    """The ``(H, W, 3)`` float32 pixels of a Mitsuba ``envmap`` emitter (its padding removed)."""
    t = np.array(mi.traverse(emitter)["data"], dtype=np.float32)
    if t.ndim != 3 or t.shape[2] != 3 or t.shape[1] < 4 or t.shape[0] < 3:
        raise BackendError(f"reference.env_radiance: envmap data: expected an (H >= 3, W + 2 >= 4, 3) tensor, found {t.shape}")
    if not (np.array_equal(t[:, 0], t[:, -2]) and np.array_equal(t[:, -1], t[:, 1])):
        raise BackendError(f"reference.env_radiance: envmap data {t.shape}: not padded as [column W-1, 0 .. W-1, column 0] "
                                     f"(Mitsuba {mi.__version__}; the layout of 3.9.1 is expected)")
    return np.ascontiguousarray(t[:, 1:-1])


#: The envmap plugin with the exact radiance (:class:`ExactEnvmap`), what the reference's scenes use.
ENVMAP_PLUGIN = "pbrcheck_envmap"
#: Mitsuba's ``math::RayEpsilon<float>`` (the envmap's bounding sphere is padded by it).
RAY_EPSILON = float(mi.math.RayEpsilon)


class ExactEnvironment:
    """The radiance of one ``envmap`` emitter by the exact lookup of the module docstring."""

    def __init__(self, emitter):
        self.emitter = emitter
        data = emitter_pixels(emitter)
        self.H, self.W = int(data.shape[0]), int(data.shape[1])
        self.pixels = mi.Float(data.ravel())  # (row-major, RGB interleaved)
        self.scale = mi.Float(dr.detach(mi.traverse(emitter)["scale"]))
        self.to_local = emitter.world_transform().inverse()

    def radiance(self, d, active=True) -> mi.Color3f:
        """Radiance arriving from unit world directions ``d`` (``mi.Vector3f``); 0 where not ``active``."""
        active = mi.Bool(active)
        H, W = self.H, self.W
        v = self.to_local @ mi.Vector3f(d)
        u = dr.atan2(v.x, -v.z) * dr.inv_two_pi - 0.5 / W
        u -= dr.floor(u)
        t = dr.safe_acos(v.y) * dr.inv_pi
        t -= dr.floor(t)  # v in [0, 1]: the south pole (v = 1) maps to row 0, as Mitsuba does
        x = u * W
        y = t * (H - 1)
        ix = dr.minimum(mi.UInt32(x), W - 1)
        iy = dr.minimum(mi.UInt32(y), H - 2)
        wx = x - mi.Float(ix)
        wy = y - mi.Float(iy)
        ix1 = dr.select(ix + 1 == W, 0, ix + 1)
        r0, r1 = iy * W, (iy + 1) * W

        def texel(i):
            return dr.gather(mi.Color3f, self.pixels, i, active)

        # a + w (b - a): exactly a where b = a (a constant region, a furnace, stays exact)
        v00, v01 = texel(r0 + ix), texel(r1 + ix)
        v0 = dr.fma(wx, texel(r0 + ix1) - v00, v00)
        v1 = dr.fma(wx, texel(r1 + ix1) - v01, v01)
        return dr.select(active, dr.fma(wy, v1 - v0, v0) * self.scale, 0.0)


class ExactEnvmap(mi.Emitter):
    """Plugin :data:`ENVMAP_PLUGIN`: Mitsuba's ``envmap`` (same ``bitmap``, ``scale``, ``to_world``)
    whose radiance is :class:`ExactEnvironment`'s, so that Mitsuba's own integrators (``path``,
    ``volpath``) read the exact lookup too. ``eval``, ``eval_direction`` and the weight of
    ``sample_direction`` (radiance / pdf) use the exact lookup; the direction, its pdf and
    ``pdf_direction`` are the inner ``envmap``'s. Python emitters get no ``set_scene``: the scene's
    bounding sphere (the length of the shadow rays, ``2 r`` as Mitsuba's envmap) comes from
    :func:`bind_environment`, called by ``reference.render.load_mitsuba_scene`` and by the
    integrator before every wavefront (a scene loaded otherwise and rendered by another integrator
    would cast shadow rays of length 2 only)."""

    def __init__(self, props):
        mi.Emitter.__init__(self, props)
        self.inner = mi.load_dict({"type": "envmap", "bitmap": props.get("bitmap"),
                                   "scale": float(props.get("scale", 1.0)),
                                   "to_world": props.get("to_world", mi.ScalarTransform4f())})
        self.m_flags = self.inner.flags()
        self.exact = ExactEnvironment(self.inner)
        self.radius: float | None = None  # the scene's bounding-sphere radius (bind_environment)

    def eval(self, si, active=True):
        return self.exact.radiance(-si.wi, active)

    def eval_direction(self, it, ds, active=True):
        return self.exact.radiance(ds.d, active)

    def pdf_direction(self, it, ds, active=True):
        return self.inner.pdf_direction(it, ds, active)

    def sample_direction(self, it, sample, active=True):
        ds, _ = self.inner.sample_direction(it, sample, active)
        ds.emitter = mi.EmitterPtr(self)
        if self.radius is not None:  # unbound: the inner envmap's unit sphere (Mitsuba's pointer
            # calls trace every live instance, those of other scenes too, so this must not raise)
            ds.dist = mi.Float(2.0 * self.radius)
            ds.p = dr.fma(ds.d, ds.dist, it.p)
        w = dr.select(active & (ds.pdf > 0), self.exact.radiance(ds.d, active) / ds.pdf, 0.0)
        return ds, w

    def world_transform(self):
        return self.inner.world_transform()

    def bbox(self):
        return self.inner.bbox()

    def traverse(self, callback):
        pass  # the environment is no differentiable parameter of the reference

    def to_string(self):
        return f"ExactEnvmap[{self.exact.W} x {self.exact.H}]"


def bind_environment(scene) -> None:
    """Give a scene's :class:`ExactEnvmap` the scene's bounding-sphere radius (as Mitsuba's
    ``envmap.set_scene``: ``max(RayEpsilon, r (1 + RayEpsilon))``); nothing for other environments."""
    env = scene.environment()
    if isinstance(env, ExactEnvmap):
        r = float(scene.bbox().bounding_sphere().radius)
        env.radius = max(RAY_EPSILON, r * (1.0 + RAY_EPSILON))


def exact_environment(env) -> ExactEnvironment:
    """The exact lookup of an environment emitter: an :class:`ExactEnvmap`'s own, else a new one."""
    return env.exact if isinstance(env, ExactEnvmap) else ExactEnvironment(env)


_REGISTERED: set[str] = set()


def register() -> None:
    """Register :data:`ENVMAP_PLUGIN` with the current variant (once per variant)."""
    v = mi.variant()
    if v in _REGISTERED:
        return
    mi.register_emitter(ENVMAP_PLUGIN, lambda props: ExactEnvmap(props))
    _REGISTERED.add(v)


__all__ = ["ENVMAP_PLUGIN", "RAY_EPSILON", "ExactEnvmap", "bind_environment", "exact_environment", "register", "ExactEnvironment", "emitter_pixels"]
