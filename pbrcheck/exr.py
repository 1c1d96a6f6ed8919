"""EXR images: float32 channels plus string metadata, through the OpenEXR 3.x ``File`` API.

Channel names both renderers write (all float32, (H, W), row 0 at the top):

* ``R``, ``G``, ``B``: linear radiance;
* ``variance.R``, ``variance.G``, ``variance.B``: variance of the reference's pixel estimate;
* ``N.X``, ``N.Y``, ``N.Z``: world shading normal (0 on background);
* ``NdotV``: cosine between the normal and the direction to the camera (0 on background);
* ``object``: object index in scene order, -1 on background (exact small integers in float32);
* ``coverage``: fraction of the pixel covered by geometry.

Metadata is a flat ``dict[str, str]`` stored as EXR string attributes named ``pbrcheck.<key>``;
hashes and large integers are strings because OpenEXR silently loses large ints. Compression is ZIP
(Mitsuba cannot read ZSTD or HTJ2K). Writes are atomic: a temporary file in the target directory,
then ``os.replace``.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import tempfile
import threading
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import OpenEXR

from .atomic import _mkdir_parent, temp_beside
from .errors import ImageIOError

META_PREFIX = "pbrcheck."
RGB = ("R", "G", "B")
VARIANCE = ("variance.R", "variance.G", "variance.B")
#: Metadata key of an image whose ``variance.*`` channels are an external Monte Carlo engine's own
#: noise (the renderer contract, docs/renderers.md; its value says how it was obtained): the
#: comparator subtracts that variance (compare.metrics, "noisy image under test").
ENGINE_VARIANCE_META = "engine_variance"
NORMAL = ("N.X", "N.Y", "N.Z")
AOVS = NORMAL + ("NdotV", "object", "coverage")


@dataclass
class Image:
    """Named float32 channels of one size and string metadata."""

    channels: dict[str, np.ndarray]
    meta: dict[str, str] = field(default_factory=dict)

    def __post_init__(self):
        shapes = {np.shape(v) for v in self.channels.values()}
        if len(shapes) > 1:
            raise ValueError(f"channels differ in shape: {sorted(shapes)}")
        self.channels = {k: np.ascontiguousarray(v, dtype=np.float32) for k, v in self.channels.items()}

    @classmethod
    def from_rgb(cls, rgb: np.ndarray, meta: dict | None = None, **extra: np.ndarray) -> "Image":
        ch = {c: rgb[..., i] for i, c in enumerate(RGB)}
        ch.update(extra)
        return cls(ch, dict(meta or {}))

    @property
    def shape(self) -> tuple[int, int]:
        return next(iter(self.channels.values())).shape

    @property
    def rgb(self) -> np.ndarray:
        return np.stack([self.channels[c] for c in RGB], axis=-1)

    def stack(self, names) -> np.ndarray:
        return np.stack([self.channels[c] for c in names], axis=-1)

    def has(self, *names: str) -> bool:
        return all(n in self.channels for n in names)

    @property
    def variance(self) -> np.ndarray | None:
        return self.stack(VARIANCE) if self.has(*VARIANCE) else None

    def meta_json(self, key: str, default=None):
        v = self.meta.get(key)
        return default if v is None else json.loads(v)


def _meta_value(v) -> str:
    return v if isinstance(v, str) else json.dumps(v, sort_keys=True)


def write_exr(path: str | Path, image: Image) -> Path:
    """Write atomically; metadata values that are not strings are stored as JSON strings."""

    path = Path(path)
    _mkdir_parent(path)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    for k, v in image.meta.items():
        header[META_PREFIX + k] = _meta_value(v)
    channels = {k: np.ascontiguousarray(v, dtype=np.float32) for k, v in image.channels.items()}
    tmp = temp_beside(path, ".tmp.exr")  # default permissions, same folder: os.replace is atomic
    try:
        with _quiet_stderr() as said:
            with OpenEXR.File(header, channels) as f:
                f.write(tmp)
        os.replace(tmp, path)
    except BaseException as e:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if not isinstance(e, Exception):
            raise
        free = _free_bytes(path.parent)
        if free is not None and free < 1 << 16:  # OpenEXR's message on a full disk names no reason
            raise OSError(28, "No space left on device", str(path)) from None
        raise ImageIOError(str(path), f"cannot write EXR ({_first_line(e, said)})") from None
    return path


def _free_bytes(folder: Path) -> int | None:
    try:
        st = os.statvfs(folder)
    except OSError:
        return None
    return st.f_bavail * st.f_frsize


def _first_line(e: BaseException, said: list[str]) -> str:
    """The first line of an OpenEXR exception (else of what the library printed)."""
    text = str(e).strip() or (said[0] if said else "") or type(e).__name__
    return text.splitlines()[0]


def _flush_c_stdio() -> None:
    try:
        import ctypes

        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):
        pass


@contextlib.contextmanager
def _quiet_stderr():
    """OpenEXR's libraries print their own messages (a corrupt chunk on stderr, "Warning: Exception
    raised ..." on stdout) before raising: in the main thread both file descriptors are captured here
    (the list yielded gets their lines after the block) so that pbrcheck's one error line stands
    alone."""
    said: list[str] = []
    if threading.current_thread() is not threading.main_thread():
        yield said
        return
    import sys

    saved: dict[int, int] = {}
    try:
        for stream in (sys.stdout, sys.stderr):
            stream.flush()
        sink = tempfile.TemporaryFile()
        for fd in (1, 2):
            saved[fd] = os.dup(fd)
    except (OSError, ValueError, AttributeError):
        for fd in saved.values():
            os.close(fd)
        yield said
        return
    py_streams = sys.stdout, sys.stderr  # the bindings print their "Warning: ..." through Python
    try:
        for fd in saved:
            os.dup2(sink.fileno(), fd)
        sys.stdout, sys.stderr = io.StringIO(), io.StringIO()
        try:
            yield said
        finally:
            _flush_c_stdio()  # the library's buffered std::cout/stdio lines go to the sink, not later
            for fd, keep in saved.items():
                os.dup2(keep, fd)
            printed = sys.stdout.getvalue() + sys.stderr.getvalue()
            sys.stdout, sys.stderr = py_streams
            sink.seek(0)
            text = sink.read().decode("utf-8", "replace") + printed
            said.extend(l.strip() for l in text.splitlines() if l.strip())
    finally:
        for fd in saved.values():
            os.close(fd)
        sink.close()


def exr_size(path: str | Path) -> tuple[int, int]:
    """(width, height) of an EXR from its header alone (no pixel is read).

    Raises :class:`ImageIOError` for a missing or unreadable file."""
    path = Path(path)
    if not path.is_file():
        raise ImageIOError(str(path), "no such file")
    try:
        with _quiet_stderr() as said:
            with OpenEXR.File(str(path), header_only=True) as f:
                lo, hi = f.header()["dataWindow"]
    except Exception as e:
        raise ImageIOError(str(path), f"not a readable EXR ({_first_line(e, said)})") from None
    return int(hi[0] - lo[0] + 1), int(hi[1] - lo[1] + 1)


def read_exr(path: str | Path, require: tuple[str, ...] = ()) -> Image:
    """Read every channel as float32 (H, W) and the ``pbrcheck.*`` metadata.

    Interleaved ``RGB``/``RGBA`` images from other tools are split into ``R``, ``G``, ``B`` (``A``).
    Raises :class:`ImageIOError` for a missing or unreadable file or a missing required channel.
    """

    path = Path(path)
    if not path.is_file():
        raise ImageIOError(str(path), "no such file")
    try:
        with _quiet_stderr() as said:
            with OpenEXR.File(str(path), separate_channels=True) as f:
                hdr = dict(f.header())  # copy: reading channels clears the live header dict
                chans = {name: np.array(c.pixels, dtype=np.float32) for name, c in f.channels().items()}
    except Exception as e:
        detail = _first_line(e, said)
        if said and "file has 0 parts" in detail:  # the library's own line says what was wrong
            detail = said[0].replace(f"{path}: ", "")
        raise ImageIOError(str(path), f"not a readable EXR ({detail})") from None
    out: dict[str, np.ndarray] = {}
    for name, a in chans.items():
        if a.ndim == 3:  # interleaved (only when a tool wrote e.g. "RGB" as one channel group)
            for i, c in enumerate(name[: a.shape[2]]):
                out[c] = a[..., i]
        else:
            out[name] = a
    missing = [c for c in require if c not in out]
    if missing:
        raise ImageIOError(str(path), f"missing channel(s) {', '.join(missing)} (has {', '.join(sorted(out))})")
    meta = {k[len(META_PREFIX):]: (v if isinstance(v, str) else str(v)) for k, v in hdr.items()
            if isinstance(k, str) and k.startswith(META_PREFIX)}
    return Image(out, meta)
