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
* :class:`GradientStep`: one step's render, loss and gradients, replayed by ``dr.freeze`` (issue 39).

**Frozen steps.** A fit's step traces the whole estimator and its adjoint in Python every
iteration (Dr.Jit then finds the compiled kernels in its cache, but the trace remains). With
``freeze`` (the default) :class:`GradientStep` wraps the render, the loss and ``dr.backward`` in
``dr.freeze``: recorded on the first calls, replayed afterwards without tracing. What it reads is
passed as its inputs (:func:`reference.frozen.jit_state`: the integrator's tables, the emitters'
and the Python BSDFs' arrays, the sensor), the seed as an opaque ``UInt32``, and the BSDFs' Python
structure (their ``model()`` and mirror-limit flags, which select other code) as a hashed key, so a
structural change records anew instead of replaying stale kernels. A recording Dr.Jit refuses makes the
fit run traced (one ``RuntimeWarning``; ``GradientStep.fallback``). Adam's update stays outside the
frozen function: ``dr.opt.Adam``'s learning rate is a Python float that the schedule changes every
step (a changed Python value retraces), and an array learning rate is multiplied in place by
``_LRCache.product`` (Dr.Jit 1.5), which changes the caller's array. Tested
(``tests/test_reference_diff.py``): a frozen fit equals the traced fit iterate by iterate (bit for
bit measured; tested within float32 rounding, a gradient's sum may be reduced in another order); a BSDF whose structure changes records again and gives the traced
loss and gradient. Measured on the CPU (``tools/frozen_timings.py``: spheres 90 x 75, 8 spp, its 3
roughness keys, median of 10 warm steps): traced 19.1 ms, frozen 9.3 ms a step (wall).

API: :func:`sensor_dict`, :func:`load_differentiable_scene`, :func:`param_key`,
:func:`render_with_gradient`, :func:`render_image`, :func:`mse_loss`, :class:`GradientStep`,
:func:`fit_materials`.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence

import numpy as np

from pbrcheck.environment import load_environment
from pbrcheck.scene import Scene

from .jit_input import aligned
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


class GradientStep:
    """``step(target, seed) -> (loss, [gradient of each key])``: ``mi.render(mscene, params, spp,
    seed)``, ``loss_fn(image, target)`` and ``dr.backward``, traced every call or, with ``freeze``,
    recorded and replayed by ``dr.freeze`` (module docstring). ``n_recordings``: how often the frozen
    function recorded (0 when traced). The keys' values must have gradients enabled."""

    def __init__(self, mscene, params, keys: Sequence[str], loss_fn: Callable, *, spp: int, freeze: bool = True):
        _, dr = _mi()
        self.mscene, self.params, self.keys, self.loss_fn, self.spp = mscene, params, list(keys), loss_fn, int(spp)
        self.freeze = bool(freeze)
        self._frozen = dr.freeze(self._step) if self.freeze else None
        self._warm = None   # the shapes whose first step ran traced
        self.fallback = None  # why a recording failed, where one did (the fit then runs traced)

    def _step(self, mscene, target, seed, state, key):
        mi, dr = _mi()
        img = mi.render(mscene, self.params, spp=self.spp, seed=seed)
        loss = self.loss_fn(img, target)
        dr.backward(loss)
        return loss, [dr.grad(self.params[k]) for k in self.keys]

    @property
    def n_recordings(self) -> int:
        return int(self._frozen.n_recordings) if self._frozen is not None else 0

    def __call__(self, target, seed: int):
        mi, dr = _mi()
        from .frozen import pass_state, structure_key

        shapes = list(self.mscene.shapes())
        # what the pass reads (the frozen function's inputs) and the Python structure it depends on
        state = pass_state(self.mscene.integrator(), self.mscene, self.mscene.sensors()[0])
        key = tuple(structure_key(s.bsdf()) for s in shapes)
        # The first step of a scene runs traced: it fills the integrator's caches (the gathered
        # materials' table, the environment's lookups), whose construction reads arrays back, which
        # a recording cannot do; later steps replay.
        warm = self._warm is not None and len(self._warm) == len(shapes) and all(
            a is b for a, b in zip(self._warm, shapes))
        frozen = self.freeze and warm
        self._warm = tuple(shapes)
        args = (self.mscene, target, dr.opaque(mi.UInt32, int(seed) & 0xFFFFFFFF), state, key)
        if not frozen:
            return self._step(*args)
        try:
            return self._frozen(*args)
        except RuntimeError as e:
            # A recording Dr.Jit refuses (a read-back or an input it cannot see, e.g. on another
            # backend): this step and the rest of the fit run traced, the same numbers, and it says so
            # once; a frozen step is an optimisation, never a reason for a fit to fail.
            if "record" not in str(e):
                raise
            self.freeze, self.fallback = False, str(e).splitlines()[0]
            warnings.warn(f"GradientStep: dr.freeze could not record the step ({self.fallback}); "
                          "the fit runs traced", RuntimeWarning, stacklevel=2)
            for k in self.keys:
                dr.clear_grad(self.params[k])
            return self._step(*args)


def fit_materials(mscene, params, keys: Sequence[str], target: np.ndarray, *, iterations: int = 20,
                  lr: float = 0.05, spp: int = 8, clamp: tuple[float, float] | dict = (0.0, 1.0),
                  loss_fn: Callable | None = None, lr_final: float | None = None,
                  average_last: int = 0, freeze: bool = True, history: list | None = None) -> list[float]:
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

    ``freeze``: each step's render and gradient through :class:`GradientStep` frozen (the same numbers
    as traced, bit for bit; module docstring). ``history``: a list that receives each iterate's
    ``{key: numpy value}`` (for tests and plots).
    """
    mi, dr = _mi()
    loss_fn = loss_fn or mse_loss
    bounds = clamp if isinstance(clamp, dict) else {k: clamp for k in keys}
    tgt = mi.TensorXf(aligned(target, np.float32))   # (reference.jit_input: one kernel whatever numpy's alignment)
    opt = mi.ad.Adam(lr=lr)
    for k in keys:
        opt[k] = params[k]
    params.update(opt)
    losses = []
    kept: dict[str, list[np.ndarray]] = {k: [] for k in keys}
    n = min(int(average_last), iterations)
    step = GradientStep(mscene, params, keys, loss_fn, spp=spp, freeze=freeze)
    # the bounds opaque: one clip kernel whatever each object's bracket (issue 39: compiled kernels)
    lims = {k: tuple(dr.opaque(type(params[k]), float(b)) for b in bounds[k]) for k in keys}
    for it in range(iterations):
        if lr_final is not None and iterations > 1:
            opt.set_learning_rate(lr * (lr_final / lr) ** (it / (iterations - 1)))
        loss, grads = step(tgt, it)
        for k, g in zip(keys, grads):   # Adam outside the frozen function (module docstring)
            dr.set_grad(opt[k], g)
        opt.step()
        keep = n > 1 and it >= iterations - n  # only the averaged iterates are read back
        # clipped together: the optimizer makes each value it is given opaque, one kernel per key
        # when given unevaluated values (30 a step on spheres)
        clipped = {k: dr.clip(opt[k], *lims[k]) for k in keys}
        dr.eval(*clipped.values())
        for k in keys:
            opt[k] = clipped[k]
            if keep:
                kept[k].append(np.array(opt[k]))
        params.update(opt)
        losses.append(float(np.array(loss).ravel()[0]))
        if history is not None:
            history.append({k: np.array(params[k]) for k in keys})
    if n > 1:
        for k in keys:
            params[k] = type(params[k])(aligned(np.mean(kept[k][-n:], axis=0), np.float32))
        params.update()
    return losses
