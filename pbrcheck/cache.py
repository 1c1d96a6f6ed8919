"""Content-addressed cache of expensive renders (references first of all).

Entries live under ``$PBRCHECK_CACHE`` (default ``~/.cache/pbrcheck``) as
``<namespace>/<key[:2]>/<key>.exr``. The key is a SHA-256 over JSON of everything that determines
the pixels (for references: the scene hash with environment pixels, spp, mode, seed and the
reference code version). Writes are atomic (temporary file + ``os.replace``), so concurrent runs
at worst both render and the last rename wins with an equally valid file; a reader never sees a
partial file. An entry that fails to read, or whose stored key differs, is deleted and reported as
a miss: a corrupt entry is re-rendered, never served. A hit sets the entry's modification time, so
:func:`prune` (``pbrcheck cache prune``) removes the least recently used entries first.

API: :func:`cache_root`, :func:`cache_key`, :class:`Cache`, :func:`usage`, :func:`prune`,
:func:`parse_size`, :class:`NamespaceUsage`, :class:`PruneResult`.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import time
from dataclasses import dataclass
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
        try:
            os.utime(p)  # last use: prune() removes the least recently used first
        except OSError:
            pass
        return img

    def put(self, key: str, image: Image) -> Path:
        image.meta["cache_key"] = key
        try:
            return write_exr(self.path(key), image)
        except (OSError, ImageIOError) as e:
            raise CacheError(f"{self.path(key)}: cannot write cache entry ({e})") from None


# --- usage and pruning ----------------------------------------------------------------------------

#: A crashed writer's temporary file (``.NAME.XXXX.tmp`` beside an entry, pbrcheck.atomic) older
#: than this is removed by :func:`prune` whatever the policy: no live write takes an hour.
STALE_TEMP_S = 3600.0
_SIZE = re.compile(r"^\s*(\d+(?:\.\d+)?)\s*([kmgt]?)i?b?\s*$", re.I)


@dataclass
class NamespaceUsage:
    """Entries and bytes of one namespace; ``oldest_use`` / ``newest_use`` as UNIX times (None when empty)."""
    namespace: str
    entries: int
    bytes: int
    oldest_use: float | None
    newest_use: float | None


@dataclass
class PruneResult:
    """What :func:`prune` removed (or would remove with ``dry_run``) and what is left."""
    removed: int
    freed_bytes: int
    kept: int
    kept_bytes: int
    stale_temp_files: int


def parse_size(text: str) -> int:
    """``"500M"``, ``"2G"``, ``"1.5GiB"``, ``"123"`` (bytes) -> bytes; raises :class:`CacheError`."""
    m = _SIZE.match(str(text))
    if not m:
        raise CacheError(f"size {text!r}: expected a number with an optional unit K, M, G or T (e.g. 2G)")
    power = " kmgt".index(m.group(2).lower() or " ")  # K = 1024 bytes
    return int(float(m.group(1)) * 1024 ** power)


def _entries(root: Path, namespaces: list[str] | None):
    """(namespace, path, stat) of every entry, and the stale temporary files, under ``root``."""
    entries, temps = [], []
    if not root.is_dir():
        return entries, temps
    now = time.time()
    for ns_dir in sorted(d for d in root.iterdir() if d.is_dir()):
        if namespaces and ns_dir.name not in namespaces:
            continue
        for p in ns_dir.glob("*/*"):
            try:
                st = p.stat()
            except OSError:
                continue
            if p.name.startswith(".") and p.name.endswith(".tmp"):
                if now - st.st_mtime > STALE_TEMP_S:
                    temps.append(p)
            elif p.suffix == ".exr":
                entries.append((ns_dir.name, p, st))
    return entries, temps


def usage(root: Path | None = None) -> list[NamespaceUsage]:
    """Entries and bytes per namespace of the cache under ``root`` (default :func:`cache_root`)."""
    root = Path(root) if root is not None else cache_root()
    entries, _ = _entries(root, None)
    out: dict[str, NamespaceUsage] = {}
    for ns, _, st in entries:
        u = out.setdefault(ns, NamespaceUsage(ns, 0, 0, None, None))
        u.entries += 1
        u.bytes += st.st_size
        u.oldest_use = st.st_mtime if u.oldest_use is None else min(u.oldest_use, st.st_mtime)
        u.newest_use = st.st_mtime if u.newest_use is None else max(u.newest_use, st.st_mtime)
    return [out[k] for k in sorted(out)]


def prune(*, root: Path | None = None, namespaces: list[str] | None = None, older_than_days: float | None = None,
          max_bytes: int | None = None, dry_run: bool = False) -> PruneResult:
    """Remove cache entries: those not used for ``older_than_days``, then the least recently used
    until the rest (of the chosen ``namespaces``, default all) fits in ``max_bytes``; with neither
    limit, every entry (``pbrcheck cache clear``). Stale temporary files of crashed writes go too.
    An entry is one file, removed with one ``unlink``: a concurrent reader sees it or a miss, never
    part of it. ``dry_run`` removes nothing and says what would go."""
    if older_than_days is not None and not older_than_days >= 0:
        raise CacheError(f"older-than must be >= 0 days, got {older_than_days}")
    if max_bytes is not None and max_bytes < 0:
        raise CacheError(f"max size must be >= 0 bytes, got {max_bytes}")
    root = Path(root) if root is not None else cache_root()
    present = sorted(d.name for d in root.iterdir() if d.is_dir()) if root.is_dir() else []
    for ns in namespaces or ():
        if ns not in present:
            raise CacheError(f"{root}: no cache namespace {ns!r} (there: {', '.join(present) or 'none'})")
    entries, temps = _entries(root, namespaces)
    entries.sort(key=lambda e: e[2].st_mtime)  # least recently used first
    drop = set()
    if older_than_days is None and max_bytes is None:
        drop = {e[1] for e in entries}
    if older_than_days is not None:
        cutoff = time.time() - older_than_days * 86400.0
        drop |= {p for _, p, st in entries if st.st_mtime < cutoff}
    if max_bytes is not None:
        total = sum(st.st_size for _, p, st in entries if p not in drop)
        for _, p, st in entries:
            if total <= max_bytes:
                break
            if p not in drop:
                drop.add(p)
                total -= st.st_size
    removed = freed = 0
    for _, p, st in entries:
        if p in drop:
            if not dry_run:
                try:
                    p.unlink()
                except FileNotFoundError:
                    continue
                except OSError as e:
                    raise CacheError(f"{p}: cannot remove cache entry ({e})") from None
            removed += 1
            freed += st.st_size
    if not dry_run:
        for t in temps:
            try:
                t.unlink()
            except OSError:
                pass
    kept = [(p, st) for _, p, st in entries if p not in drop]
    return PruneResult(removed, freed, len(kept), sum(st.st_size for _, st in kept), len(temps))
