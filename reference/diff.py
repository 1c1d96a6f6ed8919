"""Differentiable reference rendering with respect to material parameters.

The scene is loaded with a Mitsuba ``perspective`` sensor configured as :mod:`pbrcheck.camera`
(:func:`reference.integrator.sensor_dict`: horizontal fov, ``look_at(origin, target, up)``, box
filter), and rendered with ``mi.render(scene, params, ...)`` and the reference's own ``local``
estimator as a differentiable integrator (``pbrcheck_reference``, an ``RBIntegrator``; detached
sampling, no visibility, so no reparameterization: :mod:`reference.integrator`). It is the estimator
of the ``local`` reference, so a fit and the reference it is checked against have the same
integral, and like the real-time image it has no visibility between objects (Mitsuba's ``prb``, used
before, traced shadow rays). ``integrator="prb"`` keeps Mitsuba's ``prb`` (``max_depth``, default 2)
for comparison. Material parameters of object ``i`` are
``object{i}.bsdf.{base_color,metallic,roughness,specular}`` in :func:`mi.traverse`; the BSDF makes
them opaque, so new values reuse the compiled kernels.

* :func:`render_with_gradient`: an image, a scalar loss and its gradient for chosen parameters.
* :func:`fit_materials`: fit parameters to a target image with ``mi.ad.Adam``.

API: :func:`sensor_dict`, :func:`load_differentiable_scene`, :func:`param_key`,
:func:`render_with_gradient`, :func:`render_image`, :func:`mse_loss`, :func:`fit_materials`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from pbrcheck.environment import load_environment
from pbrcheck.scene import Scene

from .render import _mi, scene_dict

DEFAULT_DIFF_DEPTH = 2
DIFF_INTEGRATORS = ("local", "prb")


def sensor_dict(scene: Scene, spp: int = 16) -> dict:
    """The Mitsuba sensor of ``scene``'s camera (:func:`reference.integrator.sensor_dict`)."""
    _mi()
    from .integrator import sensor_dict as _sensor_dict  # local: needs the variant set

    return _sensor_dict(scene.camera, spp)


def load_differentiable_scene(scene: Scene, *, spp: int = 16, max_depth: int = DEFAULT_DIFF_DEPTH,
                              integrator: str = "local"):
    """(mitsuba scene with sensor and integrator, SceneParameters). ``integrator``: ``local`` (the
    reference's estimator, ``pbrcheck_reference``) or ``prb`` (Mitsuba's, ``max_depth``)."""
    mi, _ = _mi()
    from .integrator import INTEGRATOR_NAME  # local: importing it loads Mitsuba (variant set first)

    if integrator not in DIFF_INTEGRATORS:
        raise ValueError(f"integrator must be one of {DIFF_INTEGRATORS}, not {integrator!r}")
    d = scene_dict(scene, load_environment(scene))
    d["sensor"] = sensor_dict(scene, spp)
    d["integrator"] = ({"type": INTEGRATOR_NAME, "mode": "local"} if integrator == "local"
                       else {"type": "prb", "max_depth": int(max_depth)})
    ms = mi.load_dict(d)
    return ms, mi.traverse(ms)


def param_key(index: int, name: str) -> str:
    return f"object{index}.bsdf.{name}"


def render_with_gradient(mscene, params, keys: Sequence[str], loss_fn: Callable, *, spp: int = 16,
                         seed: int = 0):
    """Render with gradients enabled for ``keys``; returns (image (H, W, 3) numpy, loss float,
    {key: gradient numpy})."""
    mi, dr = _mi()
    for k in keys:
        dr.enable_grad(params[k])
    params.update()
    img = mi.render(mscene, params, spp=spp, seed=seed)
    loss = loss_fn(img)
    dr.backward(loss)
    grads = {k: np.array(dr.grad(params[k])) for k in keys}
    for k in keys:
        dr.disable_grad(params[k])
    params.update()
    return np.array(img), float(np.array(loss).ravel()[0]), grads


def render_image(mscene, params, *, spp: int = 16, seed: int = 0) -> np.ndarray:
    mi, _ = _mi()
    return np.array(mi.render(mscene, params, spp=spp, seed=seed))


def mse_loss(img, target):
    """Mean squared error over pixels and channels (Dr.Jit tensors)."""
    _, dr = _mi()
    return dr.mean(dr.square(img - target), axis=None)


def fit_materials(mscene, params, keys: Sequence[str], target: np.ndarray, *, iterations: int = 20,
                  lr: float = 0.05, spp: int = 8, clamp: tuple[float, float] | dict = (0.0, 1.0),
                  loss_fn: Callable | None = None, lr_final: float | None = None,
                  average_last: int = 0) -> list[float]:
    """Fit ``keys`` so the render matches ``target`` with ``mi.ad.Adam``; returns the losses.

    ``clamp`` is one ``(lo, hi)`` for every key or a ``{key: (lo, hi)}``. ``loss_fn(img, target)``
    (Dr.Jit tensors -> scalar) defaults to :func:`mse_loss`. Each step renders
    with its own seed (Mitsuba decorrelates the primal and the gradient pass within a step, so the
    gradient of a loss of a noisy image is unbiased). Stochastic gradients make the last iterate wander
    around the optimum by about ``lr`` per step; two standard remedies, both optional:

    * ``lr_final``: the learning rate decays geometrically from ``lr`` to ``lr_final`` over the run
      (step ``i`` uses ``lr (lr_final / lr)^(i / (iterations - 1))``);
    * ``average_last``: the result is the mean of the last ``average_last`` iterates (Polyak-Ruppert
      averaging: the iterates' noise averages out, their common drift does not).
    """
    mi, dr = _mi()
    loss_fn = loss_fn or mse_loss
    bounds = clamp if isinstance(clamp, dict) else {k: clamp for k in keys}
    tgt = mi.TensorXf(np.asarray(target, dtype=np.float32))
    opt = mi.ad.Adam(lr=lr)
    for k in keys:
        opt[k] = params[k]
    params.update(opt)
    losses = []
    history: dict[str, list[np.ndarray]] = {k: [] for k in keys}
    n = min(int(average_last), iterations)
    for it in range(iterations):
        if lr_final is not None and iterations > 1:
            opt.set_learning_rate(lr * (lr_final / lr) ** (it / (iterations - 1)))
        img = mi.render(mscene, params, spp=spp, seed=it)
        loss = loss_fn(img, tgt)
        dr.backward(loss)
        opt.step()
        keep = n > 1 and it >= iterations - n  # only the averaged iterates are read back
        # clipped together: the optimizer makes each value it is given opaque, one kernel per key
        # when given unevaluated values (30 a step on spheres)
        clipped = {k: dr.clip(opt[k], *bounds[k]) for k in keys}
        dr.eval(*clipped.values())
        for k in keys:
            opt[k] = clipped[k]
            if keep:
                history[k].append(np.array(opt[k]))
        params.update(opt)
        losses.append(float(np.array(loss).ravel()[0]))
    if n > 1:
        for k in keys:
            params[k] = type(params[k])(np.mean(history[k][-n:], axis=0))
        params.update()
    return losses
