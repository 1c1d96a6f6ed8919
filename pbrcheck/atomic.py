"""Atomic file writes: a reader (or a crash) sees the old file or the new one, never half of one.

The text goes to a temporary file in the destination folder (same file system, so ``os.replace``
is an atomic rename), which gets the permissions a plain ``open()`` would have given (``mkstemp``
makes 0600 files), and then replaces the destination. A folder of outputs is staged the same way
(:func:`staged_folder`): written whole into a sibling temporary folder, then renamed into place.

Every :class:`OSError` raised here names the destination (``err.filename``), never a temporary
file, so the CLI's one error boundary (:mod:`pbrcheck_cli`) prints ``PATH: reason``.

API
---
:func:`write_bytes_atomic`, :func:`write_text_atomic`, :func:`temp_beside`, :func:`staged_folder`,
:func:`check_output_path`, :func:`path_error`, :func:`umask`.
"""

from __future__ import annotations

import errno
import os
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path


def umask() -> int:
    """The process umask (read by setting and restoring it)."""
    m = os.umask(0)
    os.umask(m)
    return m


def path_error(e: OSError, path: str | Path) -> OSError:
    """``e`` re-addressed to ``path`` (same errno and reason): a failed write of a temporary file
    (or a full disk, whose error names no file) is reported as a failure to write ``path``."""
    out = OSError(e.errno, e.strerror or str(e), str(path))
    return out


def temp_beside(path: Path, suffix: str = ".tmp") -> str:
    """A closed temporary file next to ``path`` with the default permissions; the caller replaces
    ``path`` with it or removes it."""
    path = Path(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix, dir=path.parent)
    except OSError as e:
        raise path_error(e, path) from None
    os.close(fd)
    os.chmod(tmp, 0o666 & ~umask())
    return tmp


def _mkdir_parent(path: Path) -> None:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except FileExistsError as e:  # a file where a folder is needed
        raise OSError(errno.ENOTDIR, "a file is in the way of its folder", str(path)) from e
    except OSError as e:
        raise path_error(e, path) from None


def write_bytes_atomic(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (a temporary file beside it, then a rename), creating its
    folder; on any failure the temporary file is removed and ``path`` is untouched."""
    path = Path(path)
    _mkdir_parent(path)
    if path.is_dir():
        raise OSError(errno.EISDIR, "is a folder, expected a file", str(path))
    tmp = temp_beside(path)
    try:
        with open(tmp, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except OSError as e:
        Path(tmp).unlink(missing_ok=True)
        raise path_error(e, path) from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def write_text_atomic(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically, creating its folder."""
    return write_bytes_atomic(path, text.encode("utf-8"))


def _merge(src: Path, dst: Path) -> None:
    """Move every entry of ``src`` into the existing folder ``dst`` (renames on one file system)."""
    for child in sorted(src.iterdir()):
        target = dst / child.name
        if child.is_dir() and target.is_dir():
            _merge(child, target)
            child.rmdir()
        else:
            if target.is_dir():
                shutil.rmtree(target)
            os.replace(child, target)


@contextmanager
def staged_folder(path: str | Path):
    """``with staged_folder(out) as stage:`` write a whole output folder into ``stage`` (a sibling
    temporary folder of ``out``); on success it becomes ``out`` by one rename (or, where ``out``
    already exists, its entries are renamed into it, every file already complete); on any failure
    or interrupt the stage is removed and ``out`` is untouched. Yields the stage's ``Path``."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise OSError(errno.ENOTDIR, "exists and is not a folder", str(path))
    _mkdir_parent(path)
    try:
        stage = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent))
    except OSError as e:
        raise path_error(e, path) from None
    try:
        os.chmod(stage, 0o777 & ~umask())
        try:
            yield stage
        except OSError as e:
            # a write into the stage names the stage: name the destination instead
            if e.filename and str(e.filename).startswith(str(stage)):
                rel = os.path.relpath(e.filename, stage)
                raise path_error(e, path / rel) from None
            raise
        except Exception as e:  # a typed error (e.g. an EXR that cannot be written) naming the stage
            if len(e.args) == 1 and isinstance(e.args[0], str) and str(stage) in e.args[0]:
                e.args = (e.args[0].replace(str(stage), str(path)),)
            raise
        try:
            if path.is_dir():
                _merge(stage, path)
            else:
                os.rename(stage, path)
        except OSError as e:
            raise path_error(e, path) from None
    finally:
        if stage.exists():
            shutil.rmtree(stage, ignore_errors=True)


def check_output_path(path: str | Path, *, folder: bool = False) -> Path:
    """Check before any work that ``path`` can be written (a file, or with ``folder`` a folder):
    no file in the way of its folders, not a folder where a file is expected (or the reverse), the
    nearest existing folder writable, its file system not full. Raises an :class:`OSError` naming
    ``path`` (the CLI prints ``PATH: reason``, exit 2). Creates nothing."""
    path = Path(path)
    if path.exists():
        if folder and not path.is_dir():
            raise OSError(errno.ENOTDIR, "exists and is not a folder", str(path))
        if not folder and path.is_dir():
            raise OSError(errno.EISDIR, "is a folder, expected a file", str(path))
    anc = path if (folder and path.is_dir()) else path.parent
    anc = Path(os.path.abspath(anc))
    while not anc.exists():
        if anc.parent == anc:
            break
        anc = anc.parent
    if not anc.is_dir():
        raise OSError(errno.ENOTDIR, f"{anc} is a file, not a folder", str(path))
    if not os.access(anc, os.W_OK | os.X_OK):
        raise OSError(errno.EACCES, f"folder {anc} is not writable", str(path))
    try:
        st = os.statvfs(anc)
    except OSError:
        return path
    if st.f_bavail == 0 and os.geteuid() != 0 or st.f_bfree == 0:
        raise OSError(errno.ENOSPC, "no space left on device", str(path))
    return path
