"""The gathered materials' per-material tables (``reference.bsdf.MaterialView``, the lobes'
``reference.lobe_bsdf.view_tables``): entry j of a table is material j's value, differentiable in each.

And the lookups from a shape's registry id (``si.shape`` reinterpreted as ``UInt32``) to a value
per shape, :func:`shape_lookup` (the gathered materials' index, the dispatch tables, the culling
flags, the AOV pass's object ids): a kernel input, so the kernels reading it do not depend on the
scene's ids.

API: :func:`table_indices`, :func:`material_table`, :func:`shape_lookup`.
"""

from __future__ import annotations

import pbrcheck  # noqa: F401  (sets DRJIT_LIBLLVM_PATH before drjit loads)

import drjit as dr
import mitsuba as mi


def table_indices(n: int) -> tuple:
    """``(arange(n), [opaque j for j < n])``: the indices of :func:`material_table` (made per call:
    a variable kept between calls would not be an input of a frozen pass, ``reference.frozen``)."""
    return dr.arange(mi.UInt32, n), [dr.opaque(mi.UInt32, j) for j in range(n)]


def material_table(tp, values, indices):
    """``(len(values),)`` array of type ``tp`` whose entry j is ``values[j]`` (one Dr.Jit value per
    material; ``indices``: :func:`table_indices`), differentiable in each value: the sum over j of
    ``select(k == j, values[j], 0)``, j opaque. Exactly the values (one term of each lane is not zero).
    Why not a chain ``t = select(k == j, v_j, t)``: its adjoint routes value j's gradient through the
    n - j selects after it, so each material's backward kernel had its own length (``pbrcheck
    report``'s fit-roughness compiled 30 of them for spheres' 30 materials); the sum's adjoint is the
    same kernel for every j."""
    k, idx = indices
    t = dr.zeros(tp, len(values))
    for j, v in enumerate(values):
        t = t + dr.select(k == idx[j], tp(v), 0.0)
    return t


def shape_lookup(scene, values, tp=None, fill=0):
    """Array of type ``tp`` (default ``mi.UInt32``) indexed by shape registry id: ``values[i]`` at
    the id of ``scene.shapes()[i]``, ``fill`` elsewhere; evaluated."""
    tp = tp or mi.UInt32
    ids = dr.reinterpret_array(mi.UInt32, scene.shapes_dr())
    lut = dr.full(tp, fill, int(dr.max(ids)[0]) + 1)
    dr.scatter(lut, tp(values), ids)
    dr.eval(lut)
    return lut


__all__ = ["material_table", "shape_lookup", "table_indices"]
