"""The reference renderer as it was before REFERENCE_CODE_VERSION 2 (a per-pass Python loop over
pbrcheck's own camera rays, numpy accumulation), kept as a test fixture: the new renderer
(``pbrcheck_reference`` through ``mi.render``) must agree with it within noise (z-tests in
tests/test_reference_integrator.py). Not a public API."""

from __future__ import annotations

import hashlib

import numpy as np

from pbrcheck.camera import camera_frame, tan_half_fov
from pbrcheck.environment import load_environment
from reference.render import _mi, load_mitsuba_scene
from pbrcheck.scene import Scene

MAX_LANES = 1 << 21
DEFAULT_MAX_DEPTH = 8


def camera_rays(scene: Scene, pixel, offset):
    """World rays through pixel indices ``pixel`` (row-major, row 0 at the top) at sub-pixel
    ``offset`` (Point2f in [0, 1)^2): :func:`pbrcheck.camera.primary_rays` in Dr.Jit."""
    mi, dr = _mi()
    cam = scene.camera
    r, u, f = camera_frame(cam)
    tx, ty = tan_half_fov(cam)
    W, H = cam.width, cam.height
    i = mi.Float(pixel // W)
    j = mi.Float(pixel % W)
    x = 2.0 * (j + offset.x) / W - 1.0
    y = 1.0 - 2.0 * (i + offset.y) / H
    d = mi.Vector3f(*[float(v) for v in f]) + (x * tx) * mi.Vector3f(*[float(v) for v in r]) \
        + (y * ty) * mi.Vector3f(*[float(v) for v in u])
    return mi.Ray3f(mi.Point3f(*[float(v) for v in cam.origin]), dr.normalize(d))


# Environment and BSDF samples per camera sample in the local estimator (MIS, power heuristic).
ENV_SAMPLES = 1
BSDF_SAMPLES = 1


def _power(a, b):
    return a * a / (a * a + b * b)


def shade_local(mscene, sampler, ray, lights=()):
    """The ``local`` estimator for a wavefront of rays: (radiance Color3f, hit Bool)."""
    mi, dr = _mi()
    si = mscene.ray_intersect(ray)
    hit = si.is_valid()
    env = mscene.environment()
    L = mi.Color3f(0.0)
    if env is not None:
        L += env.eval(si, ~hit)  # misses: si.wi = -ray.d
    ctx = mi.BSDFContext()
    bsdf = si.bsdf(ray)
    if env is not None:
        for _ in range(ENV_SAMPLES):
            # Environment sample, MIS against the BSDF's density (balance over the sample counts).
            ds, em_w = env.sample_direction(si, sampler.next_2d(hit), hit)
            f, bpdf = bsdf.eval_pdf(ctx, si, si.to_local(ds.d), hit & (ds.pdf > 0))
            w = _power(ENV_SAMPLES * ds.pdf, BSDF_SAMPLES * bpdf) / ENV_SAMPLES
            L += dr.select(hit & (ds.pdf > 0), f * em_w * w, 0.0)
        for _ in range(BSDF_SAMPLES):
            # BSDF sample, MIS against the environment's density (delta lobes: weight 1).
            bs, bw = bsdf.sample(ctx, si, sampler.next_1d(hit), sampler.next_2d(hit), hit)
            wo = si.to_world(bs.wo)
            delta = mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta)
            si_e = dr.zeros(mi.SurfaceInteraction3f)
            si_e.wi = -wo
            Le = env.eval(si_e, hit)
            ds2 = dr.zeros(mi.DirectionSample3f)
            ds2.d = wo
            epdf = env.pdf_direction(si, ds2, hit & ~delta)
            w = dr.select(delta, 1.0, _power(BSDF_SAMPLES * bs.pdf, ENV_SAMPLES * epdf)) / BSDF_SAMPLES
            L += dr.select(hit & (bs.pdf > 0), bw * Le * w, 0.0)
    for pos, inten in lights:
        dv = mi.Point3f(*pos) - si.p
        d2 = dr.squared_norm(dv)
        l = dv * dr.rsqrt(d2)
        f = bsdf.eval(ctx, si, si.to_local(l), hit)
        L += dr.select(hit, f * mi.Color3f(*inten) / d2, 0.0)
    return L, hit


def _seed(seed: int, index: int) -> int:
    h = hashlib.sha256(f"pbrcheck-reference:{seed}:{index}".encode()).digest()
    return int.from_bytes(h[:4], "little")


def legacy_render(scene, *, spp=64, mode="local", seed=0, max_depth=None, env=None, mscene=None):
    """(mean (H, W, 3), variance (H, W, 3), coverage (H, W)) as the version-1 renderer computed them."""
    mi, dr = _mi()
    env = env if env is not None else load_environment(scene)
    if mscene is None:
        mscene = load_mitsuba_scene(scene, env)
    depth = int(max_depth if max_depth is not None else DEFAULT_MAX_DEPTH)
    integrator = mi.load_dict({"type": "path", "max_depth": depth}) if mode == "path" else None
    lights = [(tuple(map(float, l.position)), tuple(map(float, l.intensity))) for l in scene.lights]
    W, H = scene.camera.width, scene.camera.height
    npix = W * H
    per_pass = max(1, min(spp, MAX_LANES // max(npix, 1)))
    s1 = np.zeros((npix, 3))
    s2 = np.zeros((npix, 3))
    hits = np.zeros(npix)
    sampler = mi.load_dict({"type": "independent"})
    done = 0
    k = 0
    shift = None
    if True:
        while done < spp:
            n = min(per_pass, spp - done)
            lanes = npix * n
            sampler.seed(_seed(seed, k), lanes)
            idx = dr.arange(mi.UInt32, lanes)
            pixel = idx // n
            ray = camera_rays(scene, pixel, sampler.next_2d())
            if mode == "local":
                L, hit = shade_local(mscene, sampler, ray, lights)
            else:
                hit = mscene.ray_test(ray)
                L, _, _ = integrator.sample(mscene, sampler, mi.RayDifferential3f(ray), None, True)
            # Per-pixel sums over this pass's n consecutive lanes (float32 within a pass, float64
            # across), shifted by a per-pixel value K (the first pass's first sample) so that the
            # variance s2 - s1^2/spp does not cancel catastrophically in float32.
            Lc = mi.Color3f(L)
            if shift is None:
                shift = dr.gather(mi.Color3f, Lc, dr.arange(mi.UInt32, npix) * n)
                dr.eval(shift)
            Ld = Lc - dr.gather(mi.Color3f, shift, pixel)
            p1 = dr.block_sum(Ld, n)
            p2 = dr.block_sum(Ld * Ld, n)
            ph = dr.block_sum(dr.select(hit, mi.Float(1.0), 0.0), n)
            dr.eval(p1, p2, ph)
            s1 += np.array(p1, dtype=np.float64).T
            s2 += np.array(p2, dtype=np.float64).T
            hits += np.array(ph, dtype=np.float64)
            done += n
            k += 1
    mean = s1 / spp + np.array(shift, dtype=np.float64).T
    var = np.maximum(s2 - s1 * s1 / spp, 0.0) / (spp - 1) / spp
    W, H = scene.camera.width, scene.camera.height
    return mean.reshape(H, W, 3), var.reshape(H, W, 3), (hits / spp).reshape(H, W)
