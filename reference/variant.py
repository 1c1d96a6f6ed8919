"""Choosing the Mitsuba variant: ``cuda_ad_rgb`` where a CUDA GPU works, else ``llvm_ad_rgb``, else
``scalar_rgb`` (with a warning: ~50x slower, and without wavefront rendering).

API: :func:`ensure_variant`, :func:`chosen_variant`, :func:`backend_identity` (what of the backend
a reference's pixels depend on: part of every reference cache key)."""

from __future__ import annotations

import warnings

import pbrcheck  # noqa: F401  (DRJIT_LIBLLVM_PATH before drjit loads)

import drjit as dr
import mitsuba as mi

from pbrcheck.errors import BackendError

PREFERENCE = ("cuda_ad_rgb", "llvm_ad_rgb", "scalar_rgb")
_chosen: str | None = None


def _works(variant: str) -> bool:
    if variant not in mi.variants():
        return False
    if variant.startswith("cuda"):
        return bool(dr.has_backend(dr.JitBackend.CUDA))
    if variant.startswith("llvm"):
        return bool(dr.has_backend(dr.JitBackend.LLVM))
    return True


def chosen_variant() -> str | None:
    """The variant :func:`ensure_variant` chose in this process, None before it ran (sets nothing)."""
    return _chosen


def ensure_variant() -> str:
    """Set (once per process) and return the variant the reference renders with; registers the BSDF,
    the integrator, the spot light and the exact envmap."""
    global _chosen
    if _chosen is None:
        for v in PREFERENCE:
            if _works(v):
                _chosen = v
                break
        else:  # pragma: no cover
            raise BackendError("no usable Mitsuba variant (cuda_ad_rgb, llvm_ad_rgb, scalar_rgb)")
        if _chosen == "scalar_rgb":
            warnings.warn("pbrcheck reference: no CUDA or LLVM backend; falling back to Mitsuba's "
                          "scalar_rgb variant (about 50x slower)", RuntimeWarning, stacklevel=2)
    if mi.variant() != _chosen:
        mi.set_variant(_chosen)
    from .bsdf import register  # local: reference.bsdf subclasses mi.BSDF, which needs the variant set
    from .env_radiance import register as register_envmap
    from .integrator import register as register_integrator
    from .lights import register as register_lights

    register()
    register_integrator()
    register_lights()
    register_envmap()
    return _chosen


def backend_identity() -> dict:
    """The variant (:func:`ensure_variant`) and the Mitsuba and Dr.Jit versions: the same scene, spp
    and seed give other samples on another variant (CUDA and LLVM round differently) or release, so
    a reference cache key holds them (a cached ``llvm_ad_rgb`` render is not a ``cuda_ad_rgb`` one)."""
    return {"variant": ensure_variant(), "mitsuba": mi.__version__, "drjit": dr.__version__}
