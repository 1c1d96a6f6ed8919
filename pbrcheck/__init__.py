"""pbrcheck: a differentiable reference renderer and validator for real-time physically based shading.

Importing the package points Dr.Jit at LLVM 19 (``DRJIT_LIBLLVM_PATH``) when the variable is unset and
the library is found: Dr.Jit 1.5's LLVM backend aborts with Mesa's LLVM 15 ("Cannot select ...
fminimum"), and both LLVMs coexist in one process (Mesa keeps its own). This must happen before
``drjit`` is first imported, so it lives here, at the root of every import path.
"""

from __future__ import annotations

import glob
import os

__version__ = "0.1.0"

# Where Debian (and Ubuntu) put LLVM 19's shared library; first match wins.
_LLVM19_CANDIDATES = (
    "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1",
    "/usr/lib/x86_64-linux-gnu/libLLVM-19.so",
    "/usr/lib/aarch64-linux-gnu/libLLVM.so.19.1",
    "/usr/lib/aarch64-linux-gnu/libLLVM-19.so",
    "/usr/lib/llvm-19/lib/libLLVM.so.19.1",
    "/usr/lib/llvm-19/lib/libLLVM-19.so",
)


def find_llvm19() -> str | None:
    """Path of an LLVM 19 shared library, or None."""
    for path in _LLVM19_CANDIDATES:
        if os.path.exists(path):
            return path
    hits = sorted(glob.glob("/usr/lib/*/libLLVM*.so.19*")) + sorted(glob.glob("/usr/lib/llvm-19/lib/libLLVM*.so*"))
    return hits[0] if hits else None


if not os.environ.get("DRJIT_LIBLLVM_PATH"):
    _llvm = find_llvm19()
    if _llvm:
        os.environ["DRJIT_LIBLLVM_PATH"] = _llvm
