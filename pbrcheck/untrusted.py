"""Files named by untrusted input: the one resolver of every path an asset or a scene names.

An asset (a ``.gltf`` / ``.glb``) or a scene file is data someone else may have written: the paths
it names must not make pbrcheck read anything the user did not hand it. The rule (docs/assets.md,
"Paths an asset or a scene may name"):

* a reference is a relative path (a glTF URI is percent-decoded first, RFC 3986 2.1, so ``..%2F`` is
  checked as ``../``); an absolute path, a drive letter, a scheme other than ``data:``, a NUL byte
  are refused;
* it is resolved against the folder of the file that names it, symlinks followed
  (:func:`os.path.realpath`), and the result must lie inside that folder (itself resolved): a
  ``../`` or a symlink out of the folder is refused;
* it must be a regular file: ``/dev/zero``, ``/dev/urandom``, a FIFO or a socket is refused in one
  line. The file is opened ``O_NONBLOCK`` (opening a FIFO for reading would otherwise block until a
  writer comes) and checked with ``fstat`` on the open descriptor, so a file swapped for a FIFO
  between the check and the open is caught too;
* never more than ``limit`` bytes are read (a glTF buffer's declared ``byteLength`` plus
  :data:`READ_SLACK`; an image :data:`pbrcheck.limits.MAX_RESOURCE_BYTES`): a file that grew, or a
  device that slipped through, cannot exhaust memory.

Absolute paths the user passes on the command line (a scene, an asset, ``--env FILE``) are the
user's own choice and are not contained; a path *written in* a scene file is (:func:`contained_path`),
unless it lies in a folder the user names with ``--allow-dir DIR`` (:func:`allowed_dirs`; e.g. the
asset folder of scenes written by ``import-scenario --out``).

Refusals are :class:`ValueError` with the reason in words; the callers raise their own typed error
(:class:`~pbrcheck.gltf.AssetError` with the JSON pointer, :class:`~pbrcheck.errors.SceneError` with
the field), exit 2.

API
---
- :func:`uri_path` -- a glTF URI -> the relative path it names (percent-decoded), or the refusal.
- :func:`check_relative` -- a relative path without ``..`` components, or the refusal.
- :func:`contained_path` -- resolve a relative path inside a folder, symlinks followed.
- :func:`read_contained` -- :func:`contained_path` + a bounded read of a regular file.
- :func:`read_regular` -- a bounded read of a regular file (no containment: the user's own path).
- :func:`read_regular_prefix` -- a header: the first bytes of a regular file.
- :func:`scene_file_path` -- a path written in a scene file, resolved and contained in its folder
  (or in a folder the user allowed).
- :func:`set_allowed_dirs`, :func:`allowed_dirs` -- the folders the user allows scene files to name
  (``--allow-dir``; a context manager for a block).
- :data:`READ_SLACK`.
"""

from __future__ import annotations

from contextlib import contextmanager

import os
import re
import stat
import urllib.parse
from pathlib import Path


#: Bytes read beyond a glTF buffer's declared ``byteLength``: the specification lets a buffer's file
#: be padded to a multiple of 4 (glTF 2.0, 3.6.1.1), so 3 would do; 4 KiB leaves room for a trailing
#: newline or a tool's padding and still stops a device or a growing file at once.
READ_SLACK = 4096
#: Bytes per ``read`` call while reading a resource.
_CHUNK = 1 << 20
_SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.\-]*:")


def _kind(mode: int) -> str:
    for test, name in ((stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISFIFO, "a FIFO"), (stat.S_ISSOCK, "a socket"), (stat.S_ISDIR, "a folder")):
        if test(mode):
            return name
    return "not a regular file"


def uri_path(uri: str) -> str:
    """The relative path a glTF ``uri`` names, percent-decoded; raises :class:`ValueError` (the
    reason in words) for an absolute path, a scheme (``file:``, ``http:``...), a NUL byte or a
    ``..`` component (checked after decoding, so ``..%2F`` too)."""
    if not isinstance(uri, str) or not uri:
        raise ValueError("an empty or non-string uri")
    if _SCHEME.match(uri) and not re.match(r"^[A-Za-z]:[\\/]", uri):
        raise ValueError(f"a uri with a scheme ({uri.split(':', 1)[0]}:); only relative paths and data: URIs are read")
    rel = urllib.parse.unquote(uri)
    return check_relative(rel)


def check_relative(rel: str) -> str:
    """``rel`` if it is a relative path without ``..`` components; :class:`ValueError` otherwise."""
    if "\x00" in rel:
        raise ValueError("a NUL byte in the path")
    if rel.startswith(("/", "\\")) or re.match(r"^[A-Za-z]:", rel) or Path(rel).is_absolute():
        raise ValueError(f"an absolute path ({rel!r}); only paths relative to the file's folder are read")
    if ".." in re.split(r"[\\/]", rel):
        raise ValueError(f"a path leaving the file's folder ({rel!r})")
    return rel


def contained_path(folder: str | Path, rel: str) -> Path:
    """``folder / rel`` resolved (symlinks followed), required to lie inside ``folder`` (resolved too);
    raises :class:`ValueError` with the reason otherwise (``rel`` must pass :func:`check_relative`)."""
    check_relative(rel)
    root = os.path.realpath(folder)
    real = os.path.realpath(os.path.join(root, rel))
    if real != root and not real.startswith(root.rstrip(os.sep) + os.sep):
        raise ValueError(f"{rel!r} resolves outside the file's folder (to {real!r}; a symlink out of it?)")
    return Path(real)


def _open_regular(path: str | Path) -> int:
    """A read-only descriptor of the regular file ``path``: ``stat`` first (a FIFO is never opened),
    then ``O_NONBLOCK`` open and ``fstat`` on the descriptor (a file swapped in between is caught)."""
    st = os.stat(path)
    if not stat.S_ISREG(st.st_mode):
        raise ValueError(f"{_kind(st.st_mode)}, not a regular file")
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    st = os.fstat(fd)
    if not stat.S_ISREG(st.st_mode):
        os.close(fd)
        raise ValueError(f"{_kind(st.st_mode)}, not a regular file")
    return fd


def read_regular(path: str | Path, limit: int) -> bytes:
    """At most ``limit`` bytes of the regular file ``path`` (:func:`_open_regular`); raises
    :class:`ValueError` (the reason) for a device, FIFO, socket or folder, a file longer than
    ``limit``, and :class:`OSError` when it cannot be opened."""
    fd = _open_regular(path)
    try:
        size = os.fstat(fd).st_size
        if size > limit:
            raise ValueError(f"{size} bytes, more than the {limit} read at most")
        parts, n = [], 0
        while n <= limit:
            b = os.read(fd, min(_CHUNK, limit + 1 - n))
            if not b:
                break
            parts.append(b)
            n += len(b)
        if n > limit:
            raise ValueError(f"more than the {limit} bytes read at most (the file grows)")
        return b"".join(parts)
    finally:
        os.close(fd)


def read_regular_prefix(path: str | Path, n: int) -> bytes:
    """The first ``n`` bytes (or fewer) of the regular file ``path`` (a header); the same refusals
    as :func:`read_regular` but for the length."""
    fd = _open_regular(path)
    try:
        return os.read(fd, n)
    finally:
        os.close(fd)


def read_contained(folder: str | Path, rel: str, limit: int) -> tuple[Path, bytes]:
    """(resolved path, bytes) of ``rel`` inside ``folder`` (:func:`contained_path`, :func:`read_regular`)."""
    p = contained_path(folder, rel)
    return p, read_regular(p, limit)


def scene_file_path(scene_dir: str | Path | None, p: str, contained: bool) -> Path:
    """A path written in a scene file, resolved: relative to the scene's folder (``scene_dir``; the
    working directory when None). Where ``contained`` (a scene read from a file: untrusted), the
    resolved path, symlinks followed, must lie in the scene's folder or below, whether written
    relative or absolute; :class:`ValueError` otherwise. Scenes built by pbrcheck itself from the
    user's command line (an asset path, ``--env FILE``) are not ``contained``."""
    base = Path(scene_dir) if scene_dir is not None else Path.cwd()
    path = Path(p)
    if not path.is_absolute():
        path = base / path
    if contained:
        root = os.path.realpath(base)
        real = os.path.realpath(path)
        roots = [root, *(os.path.realpath(d) for d in _ALLOWED)]
        if not any(real.startswith(r.rstrip(os.sep) + os.sep) for r in roots):
            raise ValueError(f"{p!r} resolves to {real!r}, outside the scene's folder {root!r} (a scene file may "
                             "name files in its own folder or below; pass others on the command line, or allow their "
                             "folder with --allow-dir DIR)")
    return path


#: Folders the user allows scene files to name beyond their own (``--allow-dir``), for this call.
_ALLOWED: tuple[Path, ...] = ()


def set_allowed_dirs(dirs) -> None:
    """The folders (the user's ``--allow-dir`` values) a scene file may name files in, besides its
    own; ``()`` or None: none (the CLI resets it after each call, as the ``--max-*`` budgets)."""
    global _ALLOWED
    _ALLOWED = tuple(Path(d) for d in (dirs or ()))


@contextmanager
def allowed_dirs(*dirs):
    """``with allowed_dirs(assets):`` -- :func:`set_allowed_dirs` for a block, restored after."""
    saved = _ALLOWED
    set_allowed_dirs(dirs)
    try:
        yield
    finally:
        set_allowed_dirs(saved)
