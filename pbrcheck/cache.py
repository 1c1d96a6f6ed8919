"""Content-addressed cache of expensive renders (references first of all).

Entries live under ``$PBRCHECK_CACHE`` (default ``~/.cache/pbrcheck``) as
``<namespace>/<key[:2]>/<key>.exr``. The key is a SHA-256 over JSON of everything that determines
the pixels (for references: the scene hash with environment pixels, spp, mode, seed and the
reference code version). Writes are atomic (temporary file + ``os.replace``), so concurrent runs
at worst both render and the last rename wins with an equally valid file; a reader never sees a
partial file. A hit sets the entry's modification time, so :func:`prune` (``pbrcheck cache prune``)
removes the least recently used entries first.

Integrity: every entry stores :data:`CHECKSUM_META`, a SHA-256 over its metadata (the header's
``pbrcheck.*`` attributes, its key among them) and every channel's name, shape and pixels. An entry
that fails to read, whose stored key differs, or whose checksum does not match what was read (a
corrupted header that still parses: an attribute renamed or lost) is deleted and is a miss, with one
line on stderr: a corrupt entry is re-rendered, never served, and never served without its
attributes. An entry written before checksums existed has none: it is a miss too (removed silently,
rendered again once).

Ownership (docs/security.md): the root holds a marker, :data:`MARKER` (a ``CACHEDIR.TAG`` of the
Cache Directory Tagging Specification, so backup tools skip the cache, with a line naming pbrcheck),
written when the cache creates the folder or finds it empty. A folder that is not empty and has no
pbrcheck marker is refused as a cache root (:class:`~pbrcheck.errors.CacheError`, exit 2, one line
naming the folder and a file that is not the cache's) -- unless every file in it is in the cache's
own layout (a cache written before markers existed): that folder is adopted and marked. :func:`prune`
and ``pbrcheck cache clear`` remove only files of the cache's layout (a namespace folder of lower-case
letters, digits, ``_`` and ``-``; a two-hex-digit folder; a ``<64 hex digits>.exr`` file whose name
starts with that folder's name, or a writer's temporary file beside it) inside a marked root; they
follow no symbolic link, so a photo, a render or a ``.git`` pack file under the root stays.

API: :func:`cache_root`, :func:`cache_key`, :class:`Cache`, :func:`usage`, :func:`prune`,
:func:`parse_size`, :func:`claim_root`, :func:`is_marked`, :func:`checksum`, :class:`NamespaceUsage`,
:class:`PruneResult`, :data:`MARKER`, :data:`CHECKSUM_META`.

References: B. Ford, "Cache Directory Tagging Specification" (https://bford.info/cachedir/).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import stat
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from .atomic import write_text_atomic
from .errors import CacheError, ImageIOError
from .exr import Image, _meta_value, read_exr, write_exr
from .fmt import terminal_safe

CACHE_ENV = "PBRCHECK_CACHE"
#: The marker file that makes a folder a pbrcheck cache (module docstring).
MARKER = "CACHEDIR.TAG"
#: The first line the Cache Directory Tagging Specification requires of :data:`MARKER`.
CACHEDIR_SIGNATURE = "Signature: 8a477f597d28d172789f06886806bc55"
#: The line of :data:`MARKER` that says pbrcheck wrote it (another tool's tag is not pbrcheck's).
MARKER_OWNER = "# This file is a cache directory tag created by pbrcheck (its render cache, pbrcheck/cache.py)."
MARKER_TEXT = (f"{CACHEDIR_SIGNATURE}\n{MARKER_OWNER}\n"
               "# For information about cache directory tags, see: https://bford.info/cachedir/\n")
#: The metadata attribute holding an entry's checksum (module docstring).
CHECKSUM_META = "cache_checksum"

# The cache's layout: what clear / prune may remove, and what a pre-marker cache may hold.
_NAMESPACE = re.compile(r"^[a-z0-9][a-z0-9_-]*$")
_SHARD = re.compile(r"^[0-9a-f]{2}$")
_ENTRY = re.compile(r"^([0-9a-f]{64})\.exr$")
#: A writer's temporary file beside an entry (pbrcheck.atomic.temp_beside: ``.NAME.XXXXXXXX`` +
#: suffix; write_exr's suffix is ``.tmp.exr``; older writers used ``.tmp``).
_TEMP = re.compile(r"^\.([0-9a-f]{64})\.exr\.[A-Za-z0-9_]+\.tmp(\.exr)?$")

#: Roots checked in this process (the check reads the folder once, not at every entry).
_claimed: set[str] = set()


def cache_root() -> Path:
    """The cache folder: ``$PBRCHECK_CACHE`` or ``~/.cache/pbrcheck``."""
    p = os.environ.get(CACHE_ENV)
    return Path(p).expanduser() if p else Path.home() / ".cache" / "pbrcheck"


def cache_key(**parts) -> str:
    """SHA-256 of the keyword arguments as canonical JSON: a content address."""
    blob = json.dumps(parts, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(blob.encode()).hexdigest()


def is_marked(root: Path) -> bool:
    """Whether ``root`` holds pbrcheck's :data:`MARKER` (a regular file, not a link, with the
    specification's signature first and pbrcheck's line)."""
    m = Path(root) / MARKER
    try:
        if not stat.S_ISREG(m.lstat().st_mode):
            return False
        with open(m, encoding="utf-8", errors="replace") as f:
            head = f.read(4096)
    except OSError:
        return False
    return head.startswith(CACHEDIR_SIGNATURE) and MARKER_OWNER in head


def _is_dir(p: Path) -> bool:
    try:
        return stat.S_ISDIR(p.lstat().st_mode)
    except OSError:
        return False


def _foreign(root: Path) -> Path | None:
    """The first file or folder under ``root`` that is not in the cache's layout (None: every one is,
    or the folder is empty). Symbolic links are never the cache's."""
    for ns in sorted(root.iterdir()):
        if ns.name == MARKER:
            continue
        if not (_NAMESPACE.match(ns.name) and _is_dir(ns)):
            return ns
        for shard in sorted(ns.iterdir()):
            if not (_SHARD.match(shard.name) and _is_dir(shard)):
                return shard
            for f in sorted(shard.iterdir()):
                m = _ENTRY.match(f.name) or _TEMP.match(f.name)
                try:
                    regular = stat.S_ISREG(f.lstat().st_mode)
                except OSError:
                    continue  # removed meanwhile (a concurrent prune)
                if not (m and regular and m.group(1).startswith(shard.name)):
                    return f
    return None


def claim_root(root: Path, *, create: bool) -> bool:
    """Check that ``root`` may be used as the cache; returns whether it exists (and is the cache).

    A marked folder is the cache. A missing folder is created and marked when ``create`` (else:
    False, nothing to read). An empty folder, or one whose every file is in the cache's layout (a
    cache from before markers), is marked when ``create`` and used. Anything else raises
    :class:`~pbrcheck.errors.CacheError` naming the folder and a file that is not the cache's:
    ``pbrcheck cache clear`` must never take a user's folder for the cache."""
    root = Path(root)
    if str(root) in _claimed and (not create or is_marked(root)):
        return True  # checked before in this process (a read of an unmarked old cache: once, not per entry)
    try:
        st = root.stat()  # a root that is a link to a folder: the user's choice of folder
    except FileNotFoundError:
        if not create:
            return False
        try:
            root.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise CacheError(f"{root}: cannot create the cache folder ({e.strerror or e})") from None
        st = root.stat()
    except OSError as e:
        raise CacheError(f"{root}: cannot use as the cache folder ({e.strerror or e})") from None
    if not stat.S_ISDIR(st.st_mode):
        raise CacheError(f"{root}: not a folder (${CACHE_ENV} names the cache folder)")
    if not is_marked(root):
        try:
            other = _foreign(root)
        except OSError as e:
            raise CacheError(f"{root}: cannot read the cache folder ({e.strerror or e})") from None
        if other is not None:
            raise CacheError(f"{root}: not a pbrcheck cache (no {MARKER} written by pbrcheck, and it holds "
                             f"{terminal_safe(other.relative_to(root))}, which is not a cache entry): set ${CACHE_ENV} to a new "
                             "or empty folder")
        if not create:
            _claimed.add(str(root))
            return True
        try:
            write_text_atomic(root / MARKER, MARKER_TEXT)
        except OSError as e:
            raise CacheError(f"{root}: cannot write the cache marker {MARKER} ({e.strerror or e})") from None
    _claimed.add(str(root))
    return True


def checksum(channels: dict, meta: dict) -> str:
    """SHA-256 over ``meta`` as stored (string values; :data:`CHECKSUM_META` left out) and every
    channel's name, shape and float32 pixels, in name order."""
    h = hashlib.sha256()
    stored = {k: _meta_value(v) for k, v in meta.items() if k != CHECKSUM_META}
    h.update(json.dumps(stored, sort_keys=True, separators=(",", ":")).encode())
    for name in sorted(channels):
        a = channels[name]
        h.update(b"\0" + json.dumps([name, list(a.shape), "f4"]).encode() + b"\0")
        h.update(memoryview(a).cast("B") if a.flags.c_contiguous else a.tobytes())
    return h.hexdigest()


class Cache:
    """A content-addressed store of EXR images under ``root/namespace`` (atomic writes; a corrupt
    entry is a miss, never an error; the root must be pbrcheck's: :func:`claim_root`)."""
    def __init__(self, namespace: str, root: Path | None = None):
        if not _NAMESPACE.match(namespace):
            raise ValueError(f"cache namespace {namespace!r}: lower-case letters, digits, '_' and '-' only")
        self.root = Path(root) if root is not None else cache_root()
        self.namespace = namespace

    def path(self, key: str) -> Path:
        return self.root / self.namespace / key[:2] / f"{key}.exr"

    def get(self, key: str) -> Image | None:
        p = self.path(key)
        if not claim_root(self.root, create=False) or not p.exists():
            return None
        try:
            img = read_exr(p)
        except ImageIOError:
            img = None
        problem = None
        if img is None:
            problem = "not a readable EXR"
        elif img.meta.get("cache_key") != key:
            problem = "stored under another key"
        elif CHECKSUM_META in img.meta and img.meta[CHECKSUM_META] != checksum(img.channels, img.meta):
            problem = "its checksum does not match its header and pixels"
        if problem is not None or CHECKSUM_META not in img.meta:
            try:
                p.unlink()
            except OSError:
                pass
            if problem is not None:  # an entry from before checksums: silently rendered again
                print(f"pbrcheck: cache: {p}: corrupt entry removed ({problem}); computing it again", file=sys.stderr)
            return None
        try:
            os.utime(p)  # last use: prune() removes the least recently used first
        except OSError:
            pass
        img.meta.pop(CHECKSUM_META)
        return img

    def put(self, key: str, image: Image) -> Path:
        image.meta["cache_key"] = key
        stored = Image(image.channels, dict(image.meta))
        stored.meta[CHECKSUM_META] = checksum(stored.channels, stored.meta)
        claim_root(self.root, create=True)
        try:
            return write_exr(self.path(key), stored)
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
    """(namespace, path, stat) of every entry, and the stale temporary files, under ``root``: files of
    the cache's layout only (module docstring), found without following a symbolic link."""
    entries, temps = [], []
    if not _is_dir(root):
        return entries, temps
    now = time.time()
    for ns_dir in sorted(d for d in root.iterdir() if _NAMESPACE.match(d.name) and _is_dir(d)):
        if namespaces and ns_dir.name not in namespaces:
            continue
        for shard in sorted(d for d in ns_dir.iterdir() if _SHARD.match(d.name) and _is_dir(d)):
            for p in shard.iterdir():
                m = _ENTRY.match(p.name) or _TEMP.match(p.name)
                if not (m and m.group(1).startswith(shard.name)):
                    continue
                try:
                    st = p.lstat()
                except OSError:
                    continue
                if not stat.S_ISREG(st.st_mode):
                    continue
                if p.name.startswith("."):
                    if now - st.st_mtime > STALE_TEMP_S:
                        temps.append(p)
                else:
                    entries.append((ns_dir.name, p, st))
    return entries, temps


def usage(root: Path | None = None) -> list[NamespaceUsage]:
    """Entries and bytes per namespace of the cache under ``root`` (default :func:`cache_root`)."""
    root = Path(root) if root is not None else cache_root()
    if not claim_root(root, create=False):
        return []
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
    Only files of the cache's layout in a root :func:`claim_root` accepts are touched; another
    folder raises :class:`~pbrcheck.errors.CacheError` and nothing is removed.
    An entry is one file, removed with one ``unlink``: a concurrent reader sees it or a miss, never
    part of it. ``dry_run`` removes nothing and says what would go."""
    if older_than_days is not None and not older_than_days >= 0:
        raise CacheError(f"older-than must be >= 0 days, got {older_than_days}")
    if max_bytes is not None and max_bytes < 0:
        raise CacheError(f"max size must be >= 0 bytes, got {max_bytes}")
    root = Path(root) if root is not None else cache_root()
    # a folder that is not pbrcheck's is refused before anything is removed; a pre-marker cache is
    # adopted (marked) here, as by a write
    exists = claim_root(root, create=False) and (dry_run or claim_root(root, create=True))
    present = sorted(d.name for d in root.iterdir() if _NAMESPACE.match(d.name) and _is_dir(d)) if exists else []
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
