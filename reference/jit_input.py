"""numpy arrays handed to Dr.Jit at a 64-byte boundary, so that kernels reading them are reused.

Dr.Jit 1.5 maps a contiguous numpy array into a variable without copying it; a kernel reading mapped
memory that is not 64-byte aligned is generated with ``align 1`` loads instead of ``align 64``, so the
same computation compiles twice depending on where numpy's allocator put the array (measured with
``dr.kernel_history``: ``pbrcheck report``'s fit-roughness stage compiled its loss and material-table
kernels twice, the fit's target and its averaged parameters being numpy arrays; issue 39, compiled
kernels per report). :func:`aligned` returns the array itself where it is aligned, else a copy at a
64-byte boundary (the same values).

API: :data:`ALIGNMENT`, :func:`aligned`.
"""

from __future__ import annotations

import numpy as np

#: The boundary Dr.Jit's own allocations have (its LLVM kernels' ``align 64`` loads).
ALIGNMENT = 64


def aligned(a, dtype=None) -> np.ndarray:
    """``a`` as a C-contiguous numpy array (of ``dtype``, if given) whose data starts at a multiple of
    :data:`ALIGNMENT` bytes: ``a`` itself where it already does, else an aligned copy."""
    a = np.ascontiguousarray(a, dtype=dtype)
    if a.ctypes.data % ALIGNMENT == 0:
        return a
    buf = np.empty(a.nbytes + ALIGNMENT, dtype=np.uint8)
    off = -buf.ctypes.data % ALIGNMENT
    out = buf[off:off + a.nbytes].view(a.dtype).reshape(a.shape)
    out[...] = a
    return out


__all__ = ["ALIGNMENT", "aligned"]
