"""Content-addressed cache of expensive renders (references first of all).

Entries live under ``$PBRCHECK_CACHE`` (default ``~/.cache/pbrcheck``) as
``<namespace>/<key[:2]>/<key>.exr``. The key is a SHA-256 over JSON of everything that determines
the pixels (for references: the scene hash with environment pixels, spp, mode, seed and the
reference code version). Writes are atomic (temporary file + ``os.replace``), so concurrent runs
at worst both render and the last rename wins with an equally valid file; a reader never sees a
partial file. An entry that fails to read, or whose stored key differs, is deleted and reported as
a miss: a corrupt entry is re-rendered, never served.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

from .errors import CacheError, ImageIOError
from .exr import Image, read_exr, write_exr

CACHE_ENV = "PBRCHECK_CACHE"


def cache_root() -> Path:
    """The cache folder: ``$PBRCHECK_CACHE`` or ``~/.cache/pbrcheck``."""
    p = os.environ.get(CACHE_ENV)
    return Path(p).expanduser() if p else Path.home() / ".cache" / "pbrcheck"


def cache_key(**parts) -> str:
    """SHA-256 of the keyword arguments as canonical JSON: a content address."""
    blob = json.dumps(parts, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(blob.encode()).hexdigest()


class Cache:
    """A content-addressed store of EXR images under ``root/namespace`` (atomic writes; a corrupt
    entry is a miss, never an error)."""
    def __init__(self, namespace: str, root: Path | None = None):
        self.root = Path(root) if root is not None else cache_root()
        self.namespace = namespace

    def path(self, key: str) -> Path:
        return self.root / self.namespace / key[:2] / f"{key}.exr"

    def get(self, key: str) -> Image | None:
        p = self.path(key)
        if not p.exists():
            return None
        try:
            img = read_exr(p)
        except ImageIOError:
            img = None
        if img is None or img.meta.get("cache_key") != key:
            try:
                p.unlink()
            except OSError:
                pass
            return None
        return img

    def put(self, key: str, image: Image) -> Path:
        image.meta["cache_key"] = key
        try:
            return write_exr(self.path(key), image)
        except (OSError, ImageIOError) as e:
            raise CacheError(f"{self.path(key)}: cannot write cache entry ({e})") from None
