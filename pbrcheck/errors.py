"""Typed errors of pbrcheck.

Library code raises these; only the CLI (:mod:`pbrcheck.cli`) turns them into one line on stderr
and an exit code (2 for bad input). Every error names the file and, where there is one, the field.
"""

from __future__ import annotations


class PbrcheckError(Exception):
    """Base class. ``str(err)`` is the one-line message the CLI prints."""

    exit_code = 2


class SceneError(PbrcheckError):
    """A malformed scene file: names the file, the field, what was expected and what was found."""

    def __init__(self, file: str | None, field: str | None, expected: str, found: object = None,
                 *, message: str | None = None):
        self.file = file or "<scene>"
        self.field = field
        self.expected = expected
        self.found = found
        if message is None:
            where = f"{self.file}: {field}" if field else self.file
            message = f"{where}: expected {expected}"
            if found is not None:
                message += f", found {found!r}"
        super().__init__(message)


class EnvironmentMapError(PbrcheckError):
    """An unusable environment: unreadable file, wrong shape, NaN, Inf or negative radiance."""

    def __init__(self, file: str | None, problem: str):
        self.file = file or "<environment>"
        self.problem = problem
        super().__init__(f"{self.file}: {problem}")


class ImageIOError(PbrcheckError):
    """An EXR that cannot be read or written, or lacks a required channel."""

    def __init__(self, file: str | None, problem: str):
        self.file = file or "<image>"
        self.problem = problem
        super().__init__(f"{self.file}: {problem}")


class CacheError(PbrcheckError):
    """The render cache cannot be used (e.g. its directory is not writable)."""


class BackendError(PbrcheckError):
    """A rendering backend (GL context, Dr.Jit/LLVM) is unavailable; the message says how to fix it."""

    exit_code = 3


class ShaderCompileError(PbrcheckError):
    """A GLSL compile/link error, mapped back to the original shader file and line."""

    exit_code = 3
