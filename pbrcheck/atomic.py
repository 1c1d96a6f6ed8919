"""Atomic file writes: a reader (or a crash) sees the old file or the new one, never half of one.

The text goes to a temporary file in the destination folder (same file system, so ``os.replace``
is an atomic rename), which gets the permissions a plain ``open()`` would have given (``mkstemp``
makes 0600 files), and then replaces the destination.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path


def umask() -> int:
    """The process umask (read by setting and restoring it)."""
    m = os.umask(0)
    os.umask(m)
    return m


def temp_beside(path: Path, suffix: str = ".tmp") -> str:
    """A closed temporary file next to ``path`` with the default permissions; the caller replaces
    ``path`` with it or removes it."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix, dir=path.parent)
    os.close(fd)
    os.chmod(tmp, 0o666 & ~umask())
    return tmp


def write_bytes_atomic(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (a temporary file beside it, then a rename), creating its
    folder; on any failure the temporary file is removed and ``path`` is untouched."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = temp_beside(path)
    try:
        with open(tmp, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def write_text_atomic(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically, creating its folder."""
    return write_bytes_atomic(path, text.encode("utf-8"))
