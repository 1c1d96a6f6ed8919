"""Mitsuba's ``multijitter`` sampler with its counts opaque: one kernel for every sample count.

Mitsuba 3.9.1's ``multijitter`` (``src/samplers/multijitter.cpp``, ``src/render/sampler.cpp``,
``permute_kensler`` in ``include/mitsuba/core/random.h``) bakes its sample count ``n``, its grid
``(res_x, res_y)``, their reciprocals, the bit mask of ``n - 1`` and the samples per wavefront into
the kernel as literals. An adaptive reference renders one replicate count per level (2, 8, 16, 64,
256 samples ...; :func:`reference.integrator.replicate_plan`), so each level compiled its own
~3300-operation kernel (27 compiles for one ``spheres`` reference on the CPU, ~25 s of LLVM time per
report). :class:`OpaqueMultijitter` computes the same numbers, bit for bit (tested against
``multijitter`` for each count and mask, ``tests/test_opaque_sampler.py``), from the same
operations with every count an opaque variable (``dr.opaque``: a kernel input, not a constant), so
the kernels of all levels, the pilot's included, are one kernel.

The algorithm (Kensler 2013, "Correlated multi-jittered sampling"): dimension ``d`` of sample ``i``
of a sequence (a (replicate, pixel) pair) is the permuted index ``permute_kensler(i, n, seed_d)``
plus a PCG32 jitter, over ``n``; a 2-D dimension maps the permuted index to a cell of the
``res_x x res_y`` grid (``res_y = floor(sqrt n)``, ``res_x = n / res_y``) and permutes the
sub-stratum in each axis. ``seed_d`` = the sequence's TEA hash of the pass seed plus ``d``.

Only the local estimator uses it (the ``path`` mode hands its sampler to Mitsuba's C++ ``path``
integrator, which needs a ``mi.Sampler``; it keeps ``multijitter``). The sampler is a Dr.Jit
``DRJIT_STRUCT``, so it is loop state in ``dr.while_loop`` as Mitsuba's samplers are.

API: :class:`OpaqueMultijitter`, :class:`Divisor`, :func:`permute_kensler`, :func:`grid`.
References: Kensler 2013 (Pixar technical memo 13-01); Mitsuba 3.9.1's sources above; Granlund &
Montgomery 1994, "Division by invariant integers using multiplication" (PLDI).
"""

from __future__ import annotations

import math

import drjit as dr
import numpy as np
import mitsuba as mi

# The constants of Mitsuba's permute_kensler and multijitter (random.h, multijitter.cpp).
_KENSLER = (0xe170893d, 0x0929eb3f, 0x6935fa69, 0x74dcb303, 0x9e501cc3, 0xc860a3df)
_SEED_1D, _SEED_2D, _SEED_X, _SEED_Y = 0x45fbe943, 0x51633e2d, 0x68bc21eb, 0x02e5be93


def grid(n: int) -> tuple[int, int]:
    """``multijitter``'s grid ``(res_x, res_y)`` of ``n`` samples: ``res_y = floor(sqrt n)``
    (float32 ``sqrt`` as Mitsuba computes it; exact for these sizes), ``res_x = ceil(n / res_y)``;
    ``n`` is taken as it is only where ``res_x res_y = n``."""
    ry = max(1, int(math.sqrt(float(n))))
    return (n + ry - 1) // ry, ry


def _mask(n: int) -> int:
    """``n - 1`` with every bit below its highest set (permute_kensler's ``w``)."""
    w = n - 1
    for s in (1, 2, 4, 8, 16):
        w |= w >> s
    return w


def _rcp32(v: int) -> float:
    """``dr::rcp(ScalarFloat(v))``: the float32 reciprocal, correctly rounded."""
    return float(np.float32(1.0) / np.float32(v))


class Divisor:
    """Division by an opaque ``d`` without a division instruction (none is vectorized on a CPU: a
    divide by a kernel input runs lane by lane, which made these kernels a third slower than
    ``multijitter``'s, whose literal divisors LLVM turns into multiplications): the round-up method
    of Granlund & Montgomery 1994 (Hacker's Delight, 10-8): with ``l = ceil(log2 d)``,
    ``m = floor(2^32 (2^l - d) / d) + 1``, ``t = mul_hi(m, x)``, the quotient is
    ``(t + ((x - t) >> min(l, 1))) >> max(l - 1, 0)``, exact for every 32-bit ``x`` and ``d >= 1``
    (tested against ``//``). ``d``, ``m`` and the shifts are opaque: one kernel for every ``d``."""

    DRJIT_STRUCT = {"d": mi.UInt32, "m": mi.UInt32, "s1": mi.UInt32, "s2": mi.UInt32}

    def __init__(self, d: int = 1):
        d = int(d)
        if not 1 <= d < 1 << 32:
            raise ValueError(f"Divisor: {d} is not a 32-bit divisor")
        ln = (d - 1).bit_length()  # ceil(log2 d)
        self.d = dr.opaque(mi.UInt32, d)
        self.m = dr.opaque(mi.UInt32, ((1 << 32) * ((1 << ln) - d)) // d + 1)
        self.s1 = dr.opaque(mi.UInt32, min(ln, 1))
        self.s2 = dr.opaque(mi.UInt32, max(ln - 1, 0))

    def div(self, x):
        t = dr.mul_hi(self.m, x)
        return (t + ((x - t) >> self.s1)) >> self.s2

    def mod(self, x):
        return x - self.div(x) * self.d


def permute_kensler(index, n, w, seed, active):
    """Mitsuba's ``permute_kensler(index, n, seed, active)`` with ``n`` and its mask ``w``
    (:func:`_mask`) as Dr.Jit variables (opaque: the kernel does not depend on them): a cycle walk
    of Kensler's hash until the index lies below ``n`` (a :class:`Divisor`); lanes not ``active``
    keep their index."""
    def body(active, index):
        tmp = index ^ seed
        tmp *= _KENSLER[0]
        tmp ^= seed >> 16
        tmp ^= (tmp & w) >> 4
        tmp ^= seed >> 8
        tmp *= _KENSLER[1]
        tmp ^= seed >> 23
        tmp ^= (tmp & w) >> 1
        tmp *= 1 | (seed >> 27)
        tmp *= _KENSLER[2]
        tmp ^= (tmp & w) >> 11
        tmp *= _KENSLER[3]
        tmp ^= (tmp & w) >> 2
        tmp *= _KENSLER[4]
        tmp ^= (tmp & w) >> 2
        tmp *= _KENSLER[5]
        tmp &= w
        tmp ^= tmp >> 5
        index = dr.select(active, tmp, index)
        return active & (index >= n.d), index

    _, index = dr.while_loop((mi.Bool(active), mi.UInt32(index)), lambda a, i: dr.detach(a), body,
                             label="perm")
    return n.mod(index + seed)


class OpaqueMultijitter:
    """``multijitter`` (jittered, base seed 0) of ``n`` samples per sequence, ``per`` of them per
    wavefront lane block, every count opaque (module docstring). Mitsuba's sampler interface as
    the local estimator uses it: :meth:`seed`, :meth:`advance`, :meth:`next_1d`, :meth:`next_2d`,
    :meth:`sample_count`, :meth:`clone`."""

    DRJIT_STRUCT = {"rng": mi.PCG32, "dim": mi.UInt32, "sample_index": mi.UInt32, "perm_seed": mi.UInt32,
                    "n": Divisor, "w": mi.UInt32, "res_x": Divisor, "w_x": mi.UInt32, "res_y": Divisor,
                    "w_y": mi.UInt32, "per": Divisor, "offsets": mi.UInt32, "inv_n": mi.Float, "inv_res_x": mi.Float,
                    "inv_res_y": mi.Float}

    def __init__(self, n: int = 4, per: int | None = None):
        # (A DRJIT_STRUCT is built with no arguments by Dr.Jit's traversal, then its fields are set.)
        self.rng = mi.PCG32()
        self.dim = dr.opaque(mi.UInt32, 0)
        self.sample_index = dr.opaque(mi.UInt32, 0)
        self.perm_seed = mi.UInt32(0)
        self.offsets = mi.UInt32(0)
        self._count = 0
        self.set_sample_count(n)
        self.set_samples_per_wavefront(per or self._count)

    def set_sample_count(self, n: int) -> None:
        """``n`` samples per sequence (``multijitter``'s grid; a count it would round up raises:
        the caller picks counts it takes, :func:`reference.integrator.multijitter_count_ok`)."""
        rx, ry = grid(int(n))
        if rx * ry != int(n):
            raise ValueError(f"OpaqueMultijitter: multijitter rounds {n} samples up to {rx * ry}")
        self._count = int(n)
        self.n, self.w = Divisor(n), dr.opaque(mi.UInt32, _mask(n))
        self.res_x, self.w_x = Divisor(rx), dr.opaque(mi.UInt32, _mask(rx))
        self.res_y, self.w_y = Divisor(ry), dr.opaque(mi.UInt32, _mask(ry))
        self.inv_n = dr.opaque(mi.Float, _rcp32(n))
        self.inv_res_x, self.inv_res_y = dr.opaque(mi.Float, _rcp32(rx)), dr.opaque(mi.Float, _rcp32(ry))

    def set_samples_per_wavefront(self, per: int) -> None:
        if self._count % int(per):
            raise ValueError(f"OpaqueMultijitter: {self._count} samples are not a multiple of {per} per wavefront")
        self._per = int(per)
        self.per = Divisor(per)

    def sample_count(self) -> int:
        return self._count

    def clone(self) -> "OpaqueMultijitter":
        c = OpaqueMultijitter.__new__(OpaqueMultijitter)
        c.__dict__.update(self.__dict__)
        return c

    def seed(self, seed: int, wavefront_size: int) -> None:
        """Mitsuba's ``PCG32Sampler::seed`` and ``multijitter``'s permutation seed per sequence
        (``compute_per_sequence_seed``), base seed 0; ``seed`` opaque too."""
        s = dr.opaque(mi.UInt32, int(seed) & 0xFFFFFFFF)
        idx = dr.arange(mi.UInt32, int(wavefront_size))
        v0, v1 = mi.sample_tea_32(s, idx)
        self.rng = mi.PCG32()
        self.rng.seed(mi.UInt64(v0), mi.UInt64(v1))
        self.perm_seed = mi.sample_tea_32(dr.opaque(mi.UInt32, 0), self.per.d * self.per.div(idx) + s)[0]
        self.dim = dr.opaque(mi.UInt32, 0)
        self.sample_index = dr.opaque(mi.UInt32, 0)
        # each lane's sample within its sequence in this pass (current_sample_index's offsets)
        self.offsets = self.per.mod(idx)

    def advance(self) -> None:
        self.dim = dr.opaque(mi.UInt32, 0)
        self.sample_index = self.sample_index + 1

    def _index(self):
        """``current_sample_index``: the pass's sample index times ``per`` plus the lane's offset."""
        return dr.fma(self.sample_index, self.per.d, self.offsets)

    def _next_seed(self):
        ps = self.perm_seed + self.dim
        self.dim = self.dim + 1
        return ps

    def next_1d(self, active=True):
        active = mi.Bool(active)
        idx = self._index()
        ps = self._next_seed()
        p = mi.Float(permute_kensler(idx, self.n, self.w, ps * _SEED_1D, active))
        j = self.rng.next_float32(active)
        return (p + j) * self.inv_n

    def next_2d(self, active=True):
        active = mi.Bool(active)
        idx = self._index()
        ps = self._next_seed()
        s = permute_kensler(idx, self.n, self.w, ps * _SEED_2D, active)
        y = self.res_x.div(s)
        x = s - y * self.res_x.d
        sx = permute_kensler(x, self.res_x, self.w_x, ps * _SEED_X, active)
        sy = permute_kensler(y, self.res_y, self.w_y, ps * _SEED_Y, active)
        jx = self.rng.next_float32(active)
        jy = self.rng.next_float32(active)
        return mi.Point2f((mi.Float(x) + (mi.Float(sy) + jx) * self.inv_res_y) * self.inv_res_x,
                          (mi.Float(y) + (mi.Float(sx) + jy) * self.inv_res_x) * self.inv_res_y)


__all__ = ["Divisor", "OpaqueMultijitter", "grid", "permute_kensler"]
