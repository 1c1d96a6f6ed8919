"""The filtered normal-map model of ``pbrcheck fit-normal-roughness`` (``--method ad``): the ``local``
reference with each pixel's normal map read as the raster pipeline reads it, and its GGX ``alpha^2``
widened by a per-level table whose entries are differentiable (Dr.Jit AD).

Model (attached to the :class:`reference.textured.TexturedMaterial` of every normal-mapped object of a
differentiable scene, :func:`attach`; the integrator, the scene and the rest of the material are the
``local`` reference's own)::

    lod    = log2(rho) - log2(s)        rho = max(|d(uv_texels)/dx|, |d(uv_texels)/dy|)   (GL 4.6, 8.14.1)
    t      = trilinear(box mips of the normal map, lod)    (levels floor(lod), floor(lod) + 1, bilinear each)
    n      = normalize(T x' + B y' + N z'),  (x', y', z') = ((2 t.rg - 1) scale, 2 t.b - 1)   (glTF, as textured.py)
    alpha'^2 = min(alpha^2 + v(lod), 1),   v = the table linear between levels, lod clamped to it

* ``rho``: the isotropic scale factor of GL's LOD (its ``max`` of the two axes' lengths; anisotropy 1,
  the raster's default), from the analytic footprint of one pixel at the hit: the camera's projection
  (:mod:`pbrcheck.camera`) differentiated at the hit point ``p``, ``d(pixel)/d(uv) = d(pixel)/dp
  [dp/du dp/dv]`` on the triangle's plane, inverted; ``uv_texels`` is the normal texture's coordinates
  after ``KHR_texture_transform`` times its size. ``s``: the raster's ``supersample`` (it shades an
  ``s W x s H`` image, whose pixels' derivatives are ``1 / s`` of these). This is ``textureQueryLod``'s
  ``y`` (unclamped), the ``normal_lod`` the raster passes ``hook_specular_aa``, computed per sample
  at the sample's hit instead of from a 2 x 2 quad's finite differences.
* Box mips: :func:`pbrcheck.normal_roughness.box_mips` (level ``k``'s texel: the mean of a ``2^k``
  block of level-0 texels, unnormalised, as ``glGenerateMipmap`` filters the uploaded texels); the
  shading normalises the filtered normal, as the raster's does (``normalize`` of ``T x + B y + N z``).
  Each level is a ``gltf_texture`` of its own (the material's wrap modes and transform).
* ``v``: ``table = u^2`` (``u`` the fitted variable: the table stays >= 0), gathered at ``floor(lod)``
  and the next level; ``v = 0`` leaves the roughness unchanged to the bit, as the hook does.

The truth is the same integrator with the full-resolution normal map (what the reference renders): the
two differ only in the normal map's filtering and the widening, so a table fitted between them measures
normal filtering alone, not split-sum or horizon errors of the real-time image.

API: :class:`NormalFilter`, :func:`attach`, :func:`footprint_lod`, :func:`lod_image`,
:func:`render_model`, :func:`render_truth`, :func:`set_table`, :func:`loss_and_gradient`,
:func:`fit_table`, :data:`LOD_DEGENERATE`.

References: OpenGL 4.6 core specification, 8.14.1 (scale factor and level of detail); Toksvig 2005,
"Mipmapping Normal Maps", JGT 10(3); Olano & Baker 2010, "LEAN Mapping".
"""

from __future__ import annotations

from collections.abc import Callable
from types import SimpleNamespace

import numpy as np

from pbrcheck.camera import camera_frame, tan_half_fov
from pbrcheck.errors import PbrcheckError
from pbrcheck.normal_roughness import box_mips

from .render import _mi

#: LOD of a lane whose footprint cannot be inverted (the triangle seen edge-on, no UV derivative):
#: the coarsest level (GL's rho grows without bound there).
LOD_DEGENERATE = 64.0
#: |det d(pixel)/d(uv)| below this: degenerate (pixels per uv unit squared).
DET_EPS = 1e-12


def footprint_lod(p, dp_du, dp_dv, camera, texels: tuple[int, int], uv_matrix=(1.0, 0.0, 0.0, 1.0),
                  supersample: int = 1):
    """GL's level of detail (unclamped) of a texture of ``texels`` = (W, H) read at ``p`` (Dr.Jit
    Vector3f, world) on a surface with ``dp_du``, ``dp_dv``, seen by ``camera`` (:class:`pbrcheck.scene.Camera`)
    through ``supersample`` x ``supersample`` sub-pixels; ``uv_matrix`` (m00, m01, m10, m11): the
    texture transform's linear part (module docstring)."""
    mi, dr = _mi()
    r, u, f = (mi.Vector3f(*[float(c) for c in v]) for v in camera_frame(camera))
    tx, ty = tan_half_fov(camera)
    o = mi.Vector3f(*[float(c) for c in camera.origin])
    q = p - o
    qf, qr, qu = dr.dot(q, f), dr.dot(q, r), dr.dot(q, u)
    inv = dr.rcp(qf * qf)
    # pixel x = (qr / qf / tx + 1) W / 2, pixel y = (1 - qu / qf / ty) H / 2 (pbrcheck.camera)
    gx = (r * qf - f * qr) * (inv * (camera.width / (2.0 * tx)))
    gy = (u * qf - f * qu) * (inv * (-camera.height / (2.0 * ty)))
    a, b = dr.dot(gx, dp_du), dr.dot(gx, dp_dv)
    c, d = dr.dot(gy, dp_du), dr.dot(gy, dp_dv)
    det = a * d - b * c
    ok = dr.abs(det) > DET_EPS
    idet = dr.select(ok, dr.rcp(det), 0.0)
    du_dx, dv_dx, du_dy, dv_dy = d * idet, -c * idet, -b * idet, a * idet
    m00, m01, m10, m11 = (float(x) for x in uv_matrix)
    W, H = float(texels[0]), float(texels[1])
    sx_x, sy_x = (m00 * du_dx + m01 * dv_dx) * W, (m10 * du_dx + m11 * dv_dx) * H
    sx_y, sy_y = (m00 * du_dy + m01 * dv_dy) * W, (m10 * du_dy + m11 * dv_dy) * H
    rho2 = dr.maximum(sx_x * sx_x + sy_x * sy_x, sx_y * sx_y + sy_y * sy_y)
    lod = 0.5 * dr.log2(dr.maximum(rho2, 1e-30)) - float(np.log2(max(int(supersample), 1)))
    return dr.select(ok, lod, LOD_DEGENERATE)


class NormalFilter:
    """The filtered lookup and the widening of one material (module docstring). ``u``: the table's
    variable (``table = u^2``), replaced by :func:`fit_table` between renders."""

    def __init__(self, material, camera, supersample: int, u):
        mi, dr = _mi()
        from .textured import GltfTexture, texture_dict

        tex = material.tex["normal"]
        if not isinstance(tex, GltfTexture):
            raise PbrcheckError("normal filter: the normal texture is not a gltf_texture")
        if material.uvset["normal"] != material.primary_texcoord:
            raise PbrcheckError(f"normal filter: the normal map reads TEXCOORD_{material.uvset['normal']}, "
                                "not the mesh's own set: its footprint needs that set's dp/duv")
        data = np.asarray(mi.traverse(tex.inner)["data"], np.float32)[1:-1, 1:-1, :3]  # less the wrap padding
        self.levels = max(data.shape[:2]).bit_length()
        ref = SimpleNamespace(wrap=(tex.wrap_s, tex.wrap_t), mag_filter=None,
                              transform=[*tex.m, 0.0, 0.0, 1.0])
        self.mips = [mi.load_dict(texture_dict(lvl, ref)) for lvl in box_mips(data, self.levels)]
        self.material = material
        self.camera = camera
        self.supersample = int(supersample)
        self.texels = (tex.width, tex.height)
        self.uv_matrix = (tex.m[0], tex.m[1], tex.m[3], tex.m[4])
        self.u = u

    def lod(self, si):
        return footprint_lod(si.p, si.dp_du, si.dp_dv, self.camera, self.texels, self.uv_matrix,
                             self.supersample)

    def lookup(self, si, active):
        """(the trilinearly filtered normal-map texel, Color3f; ``v(lod)``) at ``si``."""
        mi, dr = _mi()
        lod = self.lod(si)
        # the mip chain: lod clamped to this map's levels (GL's trilinear lookup)
        n = self.levels
        x = dr.clip(lod, 0.0, float(n - 1))
        k0 = mi.UInt32(dr.floor(x))
        k1 = dr.minimum(k0 + 1, n - 1)
        fr = x - mi.Float(k0)
        t = mi.Color3f(0.0)
        for k, m in enumerate(self.mips):
            w = dr.select(k0 == k, 1.0 - fr, 0.0) + dr.select((k1 == k) & (k0 != k), fr, 0.0)
            use = mi.Bool(active) & (w > 0.0)
            t += dr.select(use, m.eval(si, use) * w, 0.0)
        # the table: lod clamped to its entries (the hook's clamp), whatever this map's own levels
        table = dr.square(self.u)
        nt = dr.width(table)
        xt = dr.clip(lod, 0.0, float(nt - 1))
        j0 = mi.UInt32(dr.floor(xt))
        j1 = dr.minimum(j0 + 1, nt - 1)
        ft = xt - mi.Float(j0)
        v = (1.0 - ft) * dr.gather(mi.Float, table, j0, active) + ft * dr.gather(mi.Float, table, j1, active)
        return t, v

    @staticmethod
    def widen(rough, v):
        """``alpha'^2 = min(alpha^2 + v, 1)`` in perceptual roughness; ``v = 0``: unchanged."""
        _, dr = _mi()
        a2 = dr.square(dr.square(rough))
        return dr.select(v > 0.0, dr.sqrt(dr.sqrt(dr.minimum(a2 + v, 1.0))), rough)


def attach(mscene, camera, supersample: int, u) -> list[NormalFilter]:
    """A :class:`NormalFilter` on every normal-mapped glTF material of the Mitsuba scene ``mscene``
    (the table variable ``u`` shared: one table for every map, indexed by the LOD as the hook indexes
    it); returns them (empty: no normal map)."""
    from .textured import TexturedMaterial

    out, seen = [], set()
    for s in mscene.shapes():
        b = s.bsdf()
        if isinstance(b, TexturedMaterial) and "normal" in b.tex and id(b) not in seen:
            seen.add(id(b))
            b.normal_filter = NormalFilter(b, camera, supersample, u)
            out.append(b.normal_filter)
    return out


def set_table(filters: list[NormalFilter], u) -> None:
    """Point every filter at ``u`` (``table = u^2``)."""
    for f in filters:
        f.u = u


def lod_image(mscene, filters: list[NormalFilter]) -> np.ndarray:
    """(H, W) the LOD at each pixel centre's first hit on a normal-mapped object (NaN elsewhere),
    by :func:`footprint_lod` (the pixels a level's table entry serves, for the report)."""
    mi, dr = _mi()
    from pbrcheck.camera import primary_rays

    cam = filters[0].camera
    o, d = primary_rays(cam)
    H, W = d.shape[:2]
    dd = d.reshape(-1, 3)
    ray = mi.Ray3f(mi.Point3f(*[float(c) for c in o]), mi.Vector3f(dd[:, 0], dd[:, 1], dd[:, 2]))
    si = mscene.ray_intersect(ray)
    out = np.full(H * W, np.nan)
    for s in mscene.shapes():
        f = getattr(s.bsdf(), "normal_filter", None)
        if f is None:
            continue
        mine = si.is_valid() & (dr.reinterpret_array(mi.UInt32, si.shape)
                                == dr.reinterpret_array(mi.UInt32, mi.ShapePtr(s)))
        lod = np.array(f.lod(si))
        m = np.array(mine)
        out[m] = lod[m]
    return out.reshape(H, W)


def render_model(mscene, *, spp: int, seed: int = 0) -> np.ndarray:
    """A primal render of the model (H, W, 3) at the filters' current table."""
    mi, _ = _mi()
    return np.array(mi.render(mscene, spp=spp, seed=seed))[..., :3]


def render_truth(mscene, filters: list[NormalFilter], *, spp: int, seed: int = 0) -> np.ndarray:
    """A primal render of the truth (H, W, 3): the same scene with the filters detached (the
    full-resolution normal map, no widening: the ``local`` reference). On the model's ``seed`` it
    uses the model's random numbers (the same pixel positions, environment and lobe samples)."""
    for f in filters:
        f.material.normal_filter = None
    try:
        return render_model(mscene, spp=spp, seed=seed)
    finally:
        for f in filters:
            f.material.normal_filter = f


def loss_and_gradient(mscene, filters: list[NormalFilter], target: np.ndarray | None, weight: np.ndarray, u, *,
                      spp: int, seed: int = 0, seed_grad: int | None = None) -> tuple[float, np.ndarray]:
    """(loss, d loss / d u) at ``u`` for the loss ``L = sum weight (I - T)^2`` (``weight`` (H, W, 3),
    fixed), ``I`` a render of the model: the primal pass on ``seed``, then the integrator's adjoint
    pass (``render_backward``) of ``dL/dI = 2 weight (I - T)`` on ``seed_grad`` (default: another
    seed, so the stochastic gradient is unbiased; ``seed_grad = seed``: the gradient of that one
    render's loss, which finite differences of renders at that seed check where the estimator is
    deterministic in ``u``, as under punctual lights). ``target`` None: ``T`` is
    :func:`render_truth` on ``seed`` (paired with ``I``: ``I - T`` has the expected difference and
    far less noise than against a fixed image, whose own noise would also bias the fit)."""
    mi, dr = _mi()
    integ = mscene.integrator()
    uu = mi.Float(np.asarray(u, np.float32))
    set_table(filters, uu)
    with dr.suspend_grad():
        img = integ.render(mscene, seed=int(seed), spp=int(spp))
        img_np = np.array(img, np.float64)
        if target is None:
            target = render_truth(mscene, filters, spp=spp, seed=seed)
    diff = img_np[..., :3] - target[..., :3]
    loss = float(np.sum(weight * diff * diff))
    dimg = np.zeros(img_np.shape, np.float32)
    dimg[..., :3] = 2.0 * weight * diff
    dr.enable_grad(uu)
    set_table(filters, uu)
    sg = int(seed) + 1 if seed_grad is None else int(seed_grad)
    integ.render_backward(mscene, None, mi.TensorXf(dimg), seed=sg, spp=int(spp))
    g = np.array(dr.grad(uu), np.float64)
    dr.disable_grad(uu)
    return loss, g


#: Adam's moment decays (Kingma & Ba 2015, their defaults) and its epsilon.
ADAM_BETAS = (0.9, 0.999)
ADAM_EPS = 1e-8


def fit_table(mscene, filters: list[NormalFilter], target: np.ndarray | None, weight: np.ndarray, u0, *,
              iterations: int, spp: int, lr: float, lr_final: float, average_last: int,
              seed: int = 0, progress: Callable[[int, float], None] | None = None) -> tuple[np.ndarray, list[float]]:
    """Fit ``u`` (``table = u^2``) with Adam (Kingma & Ba 2015) so the model matches ``target``
    (H, W, 3; None: the truth rendered on each step's seed, :func:`loss_and_gradient`) under
    :func:`loss_and_gradient`'s loss; the learning rate decays geometrically from
    ``lr`` to ``lr_final``; ``u`` stays in [-1, 1] (increments <= 1); the result is the mean of the
    last ``average_last`` tables (Polyak-Ruppert: the iterates' Monte Carlo jitter averages out).
    Each step renders on seeds of its own. Returns (table, losses); the filters keep the result."""
    mi, _ = _mi()
    u = np.asarray(u0, np.float64).copy()
    m1, m2 = np.zeros_like(u), np.zeros_like(u)
    b1, b2 = ADAM_BETAS
    losses, kept = [], []
    for it in range(iterations):
        step = lr * (lr_final / lr) ** (it / (iterations - 1)) if iterations > 1 else lr
        loss, g = loss_and_gradient(mscene, filters, target, weight, u, spp=spp, seed=seed + 2 * it,
                                    seed_grad=seed + 2 * it + 1)
        m1 = b1 * m1 + (1 - b1) * g
        m2 = b2 * m2 + (1 - b2) * g * g
        mh, vh = m1 / (1 - b1 ** (it + 1)), m2 / (1 - b2 ** (it + 1))
        u = np.clip(u - step * mh / (np.sqrt(vh) + ADAM_EPS), -1.0, 1.0)
        losses.append(loss)
        if it >= iterations - max(int(average_last), 1):
            kept.append(u * u)
        if progress is not None:
            progress(it, loss)
    table = np.mean(kept, axis=0)
    set_table(filters, mi.Float(np.sqrt(table).astype(np.float32)))
    return table, losses
