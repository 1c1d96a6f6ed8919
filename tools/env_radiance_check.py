"""The environment radiance the reference reads, against ``pbrcheck.environment.EnvMap.radiance``, on the
active reference variant (``cuda_ad_rgb`` on a GPU): Mitsuba's own ``envmap`` ``eval`` (CUDA: hardware
texture interpolation) and ``reference.env_radiance``'s exact lookup; then the ``local`` and ``path``
renders of a small ``spheres`` with the exact lookup against Mitsuba's envmap, same samples.

``python tools/env_radiance_check.py`` prints one line per comparison: the relative error's maximum
and 99th percentile and the largest absolute error over 50 000 random directions on a random 64 x 37
map (the figures docs/reference.md quotes), then per render mode the largest relative pixel
difference and the image means. Needs no GPU (on the CPU every figure is float32 rounding).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from pbrcheck.environment import EnvMap, load_environment, validate_pixels  # noqa: E402
from pbrcheck.scene import load_scene  # noqa: E402
from reference.variant import ensure_variant  # noqa: E402


def _mitsuba_radiance(self, d, active=True):
    """Mitsuba's envmap ``eval`` of the emitter an ``ExactEnvironment`` reads (the lookup it replaced)."""
    import drjit as dr
    import mitsuba as mi

    si = dr.zeros(mi.SurfaceInteraction3f)
    si.wi = -mi.Vector3f(d)
    return self.emitter.eval(si, mi.Bool(active))


def main() -> None:
    variant = ensure_variant()
    import drjit as dr
    import mitsuba as mi

    from reference import env_radiance as er
    from reference import render as rr

    print(f"variant {variant}, Mitsuba {mi.__version__}, Dr.Jit {dr.__version__}")
    data = validate_pixels(np.random.default_rng(3).random((37, 64, 3)).astype(np.float32) * 5, "random")
    d = np.random.default_rng(0).normal(size=(50_000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d = d.astype(np.float32).astype(np.float64)
    dv = mi.Vector3f(d[:, 0], d[:, 1], d[:, 2])
    for rotation, scale in ((0.0, 1.0), (-120.0, 2.0)):
        env = EnvMap(data, scale=scale, rotation=rotation)
        ref = env.radiance(d)
        plain = mi.load_dict(rr.environment_emitter_dict(env, "envmap"))
        si = dr.zeros(mi.SurfaceInteraction3f)
        si.wi = -dv
        exact = er.exact_environment(mi.load_dict(rr.environment_emitter_dict(env)))
        for name, got in (("mitsuba envmap eval", np.array(plain.eval(si)).T),
                          ("exact lookup", np.array(exact.radiance(dv)).T)):
            err = np.abs(got - ref)
            rel = err / np.abs(ref)
            print(f"rotation {rotation:6.1f} scale {scale}: {name:20s} max rel {rel.max():.3g}  "
                  f"p99 rel {np.quantile(rel, 0.99):.3g}  max abs {err.max():.3g}")
    scene = load_scene("spheres").with_camera(width=48, height=40)
    env = load_environment(scene)
    ours = rr.load_mitsuba_scene(scene, env)
    theirs = mi.load_dict({**rr.scene_dict(scene, env), "environment": rr.environment_emitter_dict(env, "envmap")})
    for mode in ("local", "path"):
        kw = dict(spp=64, seed=3, mode=mode, max_depth=3, progress=False, sampler="independent",
                  adaptive=False, env=env, env_sampling="envmap")
        a = rr.render_uncached(scene, mscene=ours, **kw)
        exact_radiance = er.ExactEnvironment.radiance
        er.ExactEnvironment.radiance = _mitsuba_radiance  # local mode: the lookup before the exact one
        try:
            b = rr.render_uncached(scene, mscene=theirs, **kw)
        finally:
            er.ExactEnvironment.radiance = exact_radiance
        rel = np.abs(a.rgb - b.rgb) / np.maximum(np.abs(b.rgb), 1e-6)
        z = np.abs(a.rgb - b.rgb) / np.maximum(np.sqrt(a.variance + b.variance), 1e-30)
        print(f"{mode} spheres 48 x 40, 64 spp, exact vs Mitsuba's envmap radiance: max rel pixel "
              f"{rel.max():.3g}, p99 {np.quantile(rel, 0.99):.3g}, max z {z.max():.3g}, "
              f"means {a.rgb.mean():.6f} / {b.rgb.mean():.6f}")


if __name__ == "__main__":
    main()
