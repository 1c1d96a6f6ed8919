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


class AssetError(PbrcheckError):
    """A glTF asset that cannot be used: names the file and the JSON pointer (``/accessors/3/byteStride``);
    raised by :mod:`pbrcheck.gltf` and :mod:`pbrcheck.asset_guard`, importable from both."""

    def __init__(self, file, pointer: str, problem: str):
        self.file = str(file)
        self.pointer = pointer
        self.problem = problem
        where = f"{self.file}: {pointer}" if pointer else self.file
        super().__init__(f"{where}: {problem}")


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
    """A GLSL compile/link error, mapped back to the original shader file and line.

    Exit 3 (the shipped shaders do not compile: a broken GL backend) unless ``user`` (a user's
    shader hook file took part: bad input, exit 2, the message names ``FILE.glsl:LINE``)."""

    exit_code = 3

    def __init__(self, message: str, *, user: bool = False):
        super().__init__(message)
        if user:
            self.exit_code = 2


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread by the CLI's handler: a ``KeyboardInterrupt`` so that every
    clean-up written for Ctrl-C (children's process groups killed, temporary folders removed) runs
    for it too; the CLI exits 128 + ``signum`` (143)."""

    def __init__(self, signum: int = 15):
        super().__init__(signum)
        self.signum = signum


def os_reason(e: OSError) -> str:
    """The reason of an :class:`OSError` in words (``strerror``, else its text)."""
    return e.strerror or str(e) or type(e).__name__


def decode_reason(e: UnicodeDecodeError) -> str:
    """A text file's bad encoding in words: where the first byte that is not UTF-8 is."""
    return f"not UTF-8 text (byte 0x{e.object[e.start]:02x} at offset {e.start})"


def read_user_text(path, error: type, what: str = "file") -> str:
    """The UTF-8 text of a user's file ``path``; an unreadable file or one that is not UTF-8 raises
    ``error(f"{path}: cannot read the {what}: reason")`` (one line, exit 2)."""
    from pathlib import Path

    try:
        return Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise error(f"{path}: no such {what}") from None
    except OSError as e:
        raise error(f"{path}: cannot read the {what}: {os_reason(e)}") from None
    except UnicodeDecodeError as e:
        raise error(f"{path}: cannot read the {what}: {decode_reason(e)}") from None
