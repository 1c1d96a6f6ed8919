"""Float image files other engines read and write: Radiance RGBE (.hdr), PFM (.pfm) and 8-bit sRGB
PNG, beside pbrcheck's own EXR (:mod:`pbrcheck.exr`).

API
---
- :func:`write_hdr` -- Radiance RGBE, new-style run-length scanlines (every reader accepts them).
- :func:`read_hdr` -- Radiance RGBE through Mitsuba's ``Bitmap`` reader (flat and RLE scanlines).
- :func:`hdr_size` -- (width, height) of a Radiance file from its header alone (no pixel read).
- :func:`write_pfm` / :func:`read_pfm` -- Portable Float Map (``PF`` colour, little or big endian).
- :func:`read_png_srgb` -- an 8-bit PNG as display values in [0, 1] (the sRGB code values / 255).
- :func:`read_float_image` -- any of .exr, .hdr, .pfm as float32 (H, W, 3), row 0 at the top.

Every array is (H, W, 3) float32 with row 0 at the **top** (PFM stores rows bottom-up; the reader
and the writer flip). Problems raise :class:`~pbrcheck.errors.ImageIOError` naming the file.
Writes are atomic (:func:`pbrcheck.atomic.write_bytes_atomic`).

References: Greg Ward, "Real Pixels", Graphics Gems II (1991) for RGBE; the Radiance file format
(``radiance-online.org``, "Radiance File Formats", section "Picture File Format"); Paul Debevec's
PFM description (``www.pauldebevec.com/Research/HDR/PFM``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .atomic import write_bytes_atomic
from .errors import ImageIOError
from .exr import read_exr

#: Largest scanline length the new-style RLE encoding can state (15 bits).
RGBE_RLE_MAX_WIDTH = 0x7FFF
#: Longest literal chunk of the RLE encoding (a count byte of 1..128 means "that many literal bytes").
RGBE_LITERAL_CHUNK = 128




def rgbe_encode(rgb: np.ndarray) -> np.ndarray:
    """(H, W, 3) non-negative float -> (H, W, 4) uint8 RGBE (Ward 1991).

    ``m = max(r, g, b) = f 2^e`` with ``f`` in [0.5, 1); the mantissas are ``floor(c 256 / 2^e)``
    and the exponent byte ``e + 128``; ``m < 1e-32`` is stored as four zeros.
    """
    rgb = np.asarray(rgb, dtype=np.float64)
    m = rgb.max(axis=-1)
    frac, exp = np.frexp(m)
    ok = m >= 1e-32
    scale = np.where(ok, frac * 256.0 / np.where(ok, m, 1.0), 0.0)
    out = np.zeros(rgb.shape[:-1] + (4,), np.uint8)
    out[..., :3] = np.clip(np.floor(rgb * scale[..., None]), 0, 255).astype(np.uint8)
    out[..., 3] = np.where(ok, np.clip(exp + 128, 0, 255), 0).astype(np.uint8)
    return out


def write_hdr(path: str | Path, rgb: np.ndarray) -> Path:
    """Write (H, W, 3) linear radiance as a Radiance ``.hdr`` (``-Y H +X W``: row 0 at the top).

    Scanlines use the new-style RLE layout with literal chunks only (no runs): a flat scanline whose
    first pixel happens to be (2, 2, x, <128) would be misread as RLE by some readers; an RLE one
    never is. Widths outside [8, 32767] use flat scanlines, as the format requires.
    """
    path = Path(path)
    rgb = np.asarray(rgb)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ImageIOError(str(path), f"expected an (H, W, 3) image, got shape {rgb.shape}")
    if not np.all(np.isfinite(rgb)) or np.any(rgb < 0):
        raise ImageIOError(str(path), "RGBE stores only finite non-negative radiance")
    H, W = rgb.shape[:2]
    px = rgbe_encode(rgb)
    parts = [f"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\nSOFTWARE=pbrcheck\n\n-Y {H} +X {W}\n".encode("ascii")]
    if 8 <= W <= RGBE_RLE_MAX_WIDTH:
        starts = list(range(0, W, RGBE_LITERAL_CHUNK))
        head = bytes([2, 2, W >> 8, W & 0xFF])
        for row in px:
            line = [head]
            for c in range(4):
                comp = row[:, c].tobytes()
                for s in starts:
                    chunk = comp[s:s + RGBE_LITERAL_CHUNK]
                    line.append(bytes([len(chunk)]))
                    line.append(chunk)
            parts.append(b"".join(line))
    else:
        parts.append(px.tobytes())
    return write_bytes_atomic(path, b"".join(parts))


#: Bytes of a Radiance header read at most by :func:`hdr_size` (the header is a few lines of text).
HDR_HEADER_MAX_BYTES = 1 << 16


def hdr_size(path: str | Path) -> tuple[int, int]:
    """(width, height) of a Radiance ``.hdr`` from its header: the text lines up to the empty line,
    then the resolution string (``-Y H +X W``; the other orientations ``+Y``/``-X``, and X first,
    are read too). Raises :class:`ImageIOError` for a file without one in its first
    :data:`HDR_HEADER_MAX_BYTES` bytes."""
    import re

    from .untrusted import read_regular_prefix

    path = Path(path)
    try:
        head = read_regular_prefix(path, HDR_HEADER_MAX_BYTES)
    except (OSError, ValueError) as e:
        raise ImageIOError(str(path), f"not a readable Radiance HDR ({getattr(e, 'strerror', None) or e})") from None
    _, sep, rest = head.partition(b"\n\n")
    m = re.match(rb"\s*([-+])([XY]) (\d+) ([-+])([XY]) (\d+)\s*\n", rest) if sep else None
    if m is None or m.group(2) == m.group(5):
        raise ImageIOError(str(path), "not a readable Radiance HDR (no resolution line after the header)")
    a, b = int(m.group(3)), int(m.group(6))
    return (b, a) if m.group(2) == b"Y" else (a, b)


def read_hdr(path: str | Path) -> np.ndarray:
    """Read a Radiance ``.hdr`` as float32 (H, W, 3), row 0 at the top (Mitsuba's ``Bitmap``)."""
    path = Path(path)
    if not path.is_file():
        raise ImageIOError(str(path), "no such file")
    try:
        import mitsuba as mi  # heavy import only for .hdr files

        a = np.array(mi.Bitmap(str(path)), dtype=np.float32)
    except Exception as e:  # the reader raises assorted types; this is the file boundary
        raise ImageIOError(str(path), f"not a readable Radiance HDR ({type(e).__name__}: {e})".splitlines()[0]) from None
    if a.ndim == 2:
        a = np.repeat(a[..., None], 3, axis=2)
    return np.ascontiguousarray(a[..., :3])


def write_pfm(path: str | Path, rgb: np.ndarray) -> Path:
    """Write (H, W, 3) float32 as a little-endian colour PFM (rows stored bottom-up, as PFM says)."""
    path = Path(path)
    rgb = np.asarray(rgb, dtype="<f4")
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ImageIOError(str(path), f"expected an (H, W, 3) image, got shape {rgb.shape}")
    H, W = rgb.shape[:2]
    head = f"PF\n{W} {H}\n-1.0\n".encode("ascii")
    return write_bytes_atomic(path, head + np.ascontiguousarray(rgb[::-1]).tobytes())


def read_pfm(path: str | Path) -> np.ndarray:
    """Read a PFM (``PF`` colour or ``Pf`` grey; the sign of the scale gives the byte order) as
    float32 (H, W, 3), row 0 at the top."""
    path = Path(path)
    if not path.is_file():
        raise ImageIOError(str(path), "no such file")
    data = path.read_bytes()
    try:
        tokens, pos = [], 0
        while len(tokens) < 4:  # "PF" W H scale, separated by whitespace, then one whitespace byte
            while data[pos:pos + 1].isspace():
                pos += 1
            start = pos
            while pos < len(data) and not data[pos:pos + 1].isspace():
                pos += 1
            tokens.append(data[start:pos].decode("ascii"))
        pos += 1
        kind, W, H, scale = tokens[0], int(tokens[1]), int(tokens[2]), float(tokens[3])
        if kind not in ("PF", "Pf") or W <= 0 or H <= 0 or scale == 0:
            raise ValueError(f"bad header {tokens}")
    except (ValueError, IndexError, UnicodeDecodeError) as e:
        raise ImageIOError(str(path), f"not a readable PFM ({e})") from None
    ch = 3 if kind == "PF" else 1
    n = W * H * ch
    body = data[pos:pos + 4 * n]
    if len(body) != 4 * n:
        raise ImageIOError(str(path), f"not a readable PFM (truncated: {len(body)} of {4 * n} bytes)")
    a = np.frombuffer(body, dtype="<f4" if scale < 0 else ">f4").reshape(H, W, ch)[::-1]
    if ch == 1:
        a = np.repeat(a, 3, axis=2)
    return np.ascontiguousarray(a, dtype=np.float32)


def read_png_srgb(path: str | Path) -> np.ndarray:
    """An 8-bit PNG as (H, W, 3) float32 display values ``code / 255`` (alpha dropped, grey
    expanded); no transfer function is undone: the caller compares in display space."""
    path = Path(path)
    if not path.is_file():
        raise ImageIOError(str(path), "no such file")
    try:
        from PIL import Image as PILImage  # Pillow comes with matplotlib

        with PILImage.open(path) as im:
            if im.mode not in ("RGB", "RGBA", "L", "LA", "P"):
                raise ValueError(f"mode {im.mode} is not 8-bit")
            a = np.asarray(im.convert("RGB"), dtype=np.float32) / 255.0
    except Exception as e:  # Pillow raises assorted types; this is the file boundary
        raise ImageIOError(str(path), f"not a readable 8-bit PNG ({type(e).__name__}: {e})".splitlines()[0]) from None
    return np.ascontiguousarray(a)


def read_float_image(path: str | Path) -> np.ndarray:
    """Read ``.exr``, ``.hdr`` or ``.pfm`` (by suffix) as float32 (H, W, 3), row 0 at the top."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".exr":
        return read_exr(path, require=("R", "G", "B")).rgb
    if suffix == ".hdr":
        return read_hdr(path)
    if suffix == ".pfm":
        return read_pfm(path)
    raise ImageIOError(str(path), f"unsupported image type {suffix!r} (expected .exr, .hdr or .pfm)")
