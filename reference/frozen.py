"""``dr.freeze`` of the reference's render pass: the Dr.Jit state a pass reads, as the frozen function's inputs.

A frozen function (Dr.Jit 1.5, ``dr.freeze``) records its kernels once and replays them for inputs
of the same layout, without Python tracing. Every Dr.Jit variable it reads must be one of its
inputs; the local estimator reads, besides the scene (a Mitsuba object, traversable), the
integrator's cached tables (gathered materials, the environment's exact lookup and its proposal,
the scene's dispatch tables: plain Python objects) and the Python BSDFs' and emitters' own arrays.
:func:`jit_state` collects them: Dr.Jit arrays and structs, Mitsuba objects and
``mi.DiscreteDistribution`` (traversable), and the attributes of the project's own Python objects,
recursively. A changed scene (other shapes, materials or environment) has other arrays, so the
frozen function sees other inputs: it replays with their values, or records anew where their
layout differs (never a stale image: ``tests/test_reference_speed.py``).

Measured on the CPU (2 threads, spheres, ``render_groups`` of 16 replicates x 4 samples, median
process CPU seconds of warm runs): 90 x 75: traced 0.063, frozen 0.063; 180 x 150: traced 0.228,
frozen 0.209. On the CPU the pass is bound by its kernel and the replay's traversal of the inputs
costs about what the trace saved; hence opt-in (``ReferenceIntegrator.freeze``) until a GPU, where
tracing is the larger share, measures it (issue 39).

**The BSDF evaluation path** (:class:`FrozenSampleEval`): one BSDF's ``sample`` then
``eval_pdf`` of the sampled direction (what the estimator asks of a BSDF per sample, and what
``pbrcheck bench reference`` times as ``bsdf_speed_ratio``) through ``dr.freeze``, the BSDF's arrays
as inputs and its Python structure (mirror limit, model, lobes) as a hashed key: a BSDF whose
structure changes records anew. Bit for bit the traced values (``tests/test_reference_speed.py``).
The differentiable fits' steps: :class:`reference.diff.GradientStep`.

API: :func:`jit_state`, :func:`pass_state`, :data:`NOT_PASS_STATE`, :func:`structure_key`,
:class:`FrozenSampleEval`.
"""

from __future__ import annotations

import drjit as dr
import mitsuba as mi

#: Modules whose objects' attributes :func:`jit_state` walks (the project's own classes).
OWN_MODULES = ("reference", "pbrcheck")


def jit_state(obj, out: list | None = None, seen: set | None = None) -> list:
    """The Dr.Jit arrays, structs and traversable Mitsuba objects reachable from ``obj`` (dicts,
    lists, tuples and the attributes of the project's own objects), each once."""
    out = [] if out is None else out
    seen = set() if seen is None else seen
    if obj is None or isinstance(obj, (bool, int, float, str, bytes)) or id(obj) in seen:
        return out
    seen.add(id(obj))
    if isinstance(obj, mi.DiscreteDistribution) or dr.is_array_v(obj) or hasattr(type(obj), "DRJIT_STRUCT"):
        out.append(obj)
        return out
    if isinstance(obj, dict):
        for v in obj.values():
            jit_state(v, out, seen)
        return out
    if isinstance(obj, (list, tuple)):
        for v in obj:
            jit_state(v, out, seen)
        return out
    if isinstance(obj, mi.Object):
        out.append(obj)
    if hasattr(obj, "__dict__") and type(obj).__module__.startswith(OWN_MODULES):
        jit_state(vars(obj), out, seen)
    return out


#: Integrator attributes that are not state a pass reads (its progress callback, its own frozen
#: function and the shapes it was warmed for).
NOT_PASS_STATE = ("progress", "_frozen", "_warm")


def pass_state(integrator, scene, sensor) -> list:
    """:func:`jit_state` of what a reference pass reads: the integrator's cached tables, the scene's
    emitters, its shapes' BSDFs and the sensor (``ReferenceIntegrator._pass``,
    ``reference.diff.GradientStep``)."""
    return jit_state([{k: v for k, v in vars(integrator).items() if k not in NOT_PASS_STATE},
                      list(scene.emitters()), [s.bsdf() for s in scene.shapes()], sensor])


def structure_key(bsdf) -> tuple:
    """The Python-level structure of a BSDF that selects other code (a frozen function's hashed key):
    its class, mirror-limit flag, scene-wide model and glTF lobes (``reference.bsdf.PBRMaterial``)."""
    return (type(bsdf).__name__, getattr(bsdf, "delta", None), bsdf.model() if hasattr(bsdf, "model") else None,
            getattr(getattr(bsdf, "lobes", None), "used", None))


class FrozenSampleEval:
    """``(bs, weight, f, pdf) = fse(si, u1, u2)``: ``bsdf.sample(ctx, si, u1, u2)`` and
    ``bsdf.eval_pdf(ctx, si, bs.wo)`` of one BSDF (module docstring), frozen (``freeze``, default)
    or traced; ``n_recordings``: how often the frozen function recorded."""

    def __init__(self, bsdf, freeze: bool = True):
        self.bsdf = bsdf
        self.freeze = bool(freeze)
        self._frozen = dr.freeze(self._run) if self.freeze else None

    @staticmethod
    def _run(bsdf, si, u1, u2, state, key):
        ctx = mi.BSDFContext()
        bs, w = bsdf.sample(ctx, si, u1, u2)
        f, pdf = bsdf.eval_pdf(ctx, si, bs.wo)
        return bs, w, f, pdf

    @property
    def n_recordings(self) -> int:
        return int(self._frozen.n_recordings) if self._frozen is not None else 0

    def __call__(self, si, u1, u2):
        fn = self._frozen if self.freeze else self._run
        return fn(self.bsdf, si, u1, u2, jit_state([self.bsdf]), structure_key(self.bsdf))


__all__ = ["FrozenSampleEval", "NOT_PASS_STATE", "OWN_MODULES", "jit_state", "pass_state", "structure_key"]
