"""Build step beyond pyproject.toml: the reference MikkTSpace (pbrcheck/mikktspace_c, C only, loaded by
pbrcheck.mikktspace through ctypes). Needs a C compiler (Debian: build-essential)."""
from setuptools import Extension, setup

setup(ext_modules=[Extension(
    "pbrcheck._mikktspace",
    sources=["pbrcheck/mikktspace_c/pbrcheck_mikktspace.c", "pbrcheck/mikktspace_c/mikktspace.c"],
    include_dirs=["pbrcheck/mikktspace_c"],
    extra_compile_args=["-O2"],
)])
