"""Checks of an untrusted glTF document before :mod:`pbrcheck.gltf` does any work on it: the GLB
header, the fields whose malformed values used to crash the loader, and the resource budgets
(:mod:`pbrcheck.limits`) that can be judged from the JSON and the image headers alone.

Each raises :class:`pbrcheck.gltf.AssetError` naming the file and the JSON pointer
(``/accessors/3/byteStride``), or :class:`pbrcheck.limits.LimitError` naming the budget and its
``--max-*`` flag. Kept apart from the loader so that the loader's scene-building code and these
guards change independently.

API
---
- :func:`quiet_library` -- a context: pygltflib's and dataclasses-json's own warnings (and log
  records) captured, never printed; pbrcheck reports the problem in its own line.
- :func:`check_glb_header` -- magic, version 2 (glTF 2.0, 4.4.3: "version ... 2"), declared length.
- :func:`check_document` -- every node's ``matrix`` / TRS shape and finiteness, ``children``,
  every buffer view's ``byteStride``, ``byteOffset``, ``byteLength``, every accessor's
  ``byteOffset`` and ``sparse.count``; every index accessor's component type (unsigned, 3.7.2.1).
- :func:`expansion` -- node instances and triangles after the hierarchy is expanded (memoized, no
  expansion), cycles refused; checked against ``node_instances`` and ``triangles``.
- :func:`image_header_bytes` / :func:`check_texture_bytes` -- decoded bytes from the image headers,
  the sum against ``texture_bytes`` before anything is decoded.
- :func:`pillow_unbounded` -- a context for Pillow with its own decompression-bomb check off (the
  budget above replaces it) and its ``DecompressionBombWarning`` silenced.
- :func:`check_positions` -- positions finite and within :data:`MAX_WORLD_COORDINATE`, in the
  accessor's space and in world space.
- :func:`check_world_matrix` -- a node's world matrix within :data:`MAX_WORLD_COORDINATE`.
- :func:`budgets_key` -- the budgets in force, for the loader's cache key.
- :data:`MAX_WORLD_COORDINATE`, :data:`BYTE_STRIDE_RANGE`, :data:`INDEX_COMPONENT_TYPES`.
"""

from __future__ import annotations

import io
import logging
import math
import threading
import warnings
from contextlib import contextmanager

import numpy as np

from . import limits
from .errors import AssetError

#: Largest |coordinate| of a world-space position: the renderers square differences of positions in
#: float32 (lengths, bounding spheres, depth ranges), so 3 (2 x 1e18)^2 = 1.2e37 must stay below
#: float32's 3.4e38. Positions of 3e38 (finite) or a node scale of 1e300 gave a blank image and exit 0.
MAX_WORLD_COORDINATE = 1e18
#: glTF 2.0 3.6.2.2: ``byteStride`` is an integer in [4, 252], a multiple of 4.
BYTE_STRIDE_RANGE = (4, 252)
#: glTF 2.0 3.7.2.1: index accessors are UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT.
INDEX_COMPONENT_TYPES = (5121, 5123, 5125)
#: Loggers of the reading libraries, silenced while they run.
_LIBRARY_LOGGERS = ("pygltflib", "dataclasses_json")
_PIL_LOCK = threading.Lock()


def _err(file, pointer: str, problem: str) -> AssetError:
    return AssetError(file, pointer, problem)


@contextmanager
def quiet_library():
    """pygltflib's warnings (``warnings.warn``, "Please open an issue at ...") and log records are
    recorded and dropped, never printed: the loader reports what is wrong in its own line."""
    loggers = [logging.getLogger(n) for n in _LIBRARY_LOGGERS]
    saved = [(lg.disabled, lg.propagate) for lg in loggers]
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        for lg in loggers:
            lg.disabled, lg.propagate = True, False
        try:
            yield
        finally:
            for lg, (d, p) in zip(loggers, saved):
                lg.disabled, lg.propagate = d, p


def check_glb_header(file, raw: bytes) -> None:
    """A GLB's 12-byte header: magic ``glTF``, version 2, a declared length not beyond the file."""
    if len(raw) < 12:
        raise _err(file, "", f"a GLB of {len(raw)} bytes, shorter than its 12-byte header")
    version = int.from_bytes(raw[4:8], "little")
    if version != 2:
        raise _err(file, "", f"GLB header version {version} (glTF 2.0 binary files are version 2)")


def _is_int(x) -> bool:
    return isinstance(x, int) and not isinstance(x, bool)


def _finite_numbers(x, n: int) -> bool:
    return (isinstance(x, list) and len(x) == n
            and all(isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c) for c in x))


def _check_nodes(file, doc: dict) -> None:
    nodes = doc.get("nodes", [])
    if not isinstance(nodes, list):
        raise _err(file, "/nodes", "an array of nodes")
    for i, n in enumerate(nodes):
        p = f"/nodes/{i}"
        if not isinstance(n, dict):
            raise _err(file, p, "a node object")
        for key, size in (("matrix", 16), ("translation", 3), ("rotation", 4), ("scale", 3)):
            if key in n and not _finite_numbers(n[key], size):
                v = n[key]
                found = f"{len(v)} values" if isinstance(v, list) else repr(v)
                raise _err(file, f"{p}/{key}", f"{size} finite numbers, found {found}")
        ch = n.get("children", [])
        if not isinstance(ch, list):
            raise _err(file, f"{p}/children", "an array of node indices")
        for k, c in enumerate(ch):
            if not _is_int(c) or not 0 <= c < len(nodes):
                raise _err(file, f"{p}/children/{k}", f"a node index in [0, {len(nodes)}), found {c!r}")


def _check_int(file, d: dict, key: str, pointer: str, lo: int, default=None) -> None:
    v = d.get(key, default)
    if v is None:
        return
    if not _is_int(v) or v < lo:
        raise _err(file, f"{pointer}/{key}", f"an integer >= {lo}, found {v!r}")


def _check_views(file, doc: dict) -> None:
    for i, v in enumerate(doc.get("bufferViews", []) or []):
        p = f"/bufferViews/{i}"
        if not isinstance(v, dict):
            raise _err(file, p, "a bufferView object")
        _check_int(file, v, "byteOffset", p, 0)
        _check_int(file, v, "byteLength", p, 1)
        s = v.get("byteStride")
        lo, hi = BYTE_STRIDE_RANGE
        if s is not None and (not _is_int(s) or not lo <= s <= hi or s % 4):
            raise _err(file, f"{p}/byteStride", f"a multiple of 4 in [{lo}, {hi}], found {s!r}")


def _check_accessors(file, doc: dict) -> None:
    for i, a in enumerate(doc.get("accessors", []) or []):
        p = f"/accessors/{i}"
        if not isinstance(a, dict):
            raise _err(file, p, "an accessor object")
        _check_int(file, a, "byteOffset", p, 0)
        sp = a.get("sparse")
        if sp is not None:
            if not isinstance(sp, dict):
                raise _err(file, f"{p}/sparse", "a sparse object")
            _check_int(file, sp, "count", f"{p}/sparse", 1, default="missing")
            for part in ("indices", "values"):
                q = sp.get(part)
                if not isinstance(q, dict):
                    raise _err(file, f"{p}/sparse/{part}", f"a sparse {part} object")
                _check_int(file, q, "byteOffset", f"{p}/sparse/{part}", 0)


def _check_index_accessors(file, doc: dict) -> None:
    accessors = doc.get("accessors", []) or []
    for mi, m in enumerate(doc.get("meshes", []) or []):
        for pi, prim in enumerate((m or {}).get("primitives", []) if isinstance(m, dict) else []):
            k = prim.get("indices") if isinstance(prim, dict) else None
            if _is_int(k) and 0 <= k < len(accessors) and isinstance(accessors[k], dict):
                ct = accessors[k].get("componentType")
                if ct not in INDEX_COMPONENT_TYPES:
                    raise _err(file, f"/accessors/{k}/componentType",
                               f"component type {ct!r} for the indices of /meshes/{mi}/primitives/{pi}; indices "
                               f"are unsigned ({', '.join(map(str, INDEX_COMPONENT_TYPES))})")


def check_document(file, doc: dict) -> None:
    """The fields checked here are the ones the loader would otherwise crash on (module docstring)."""
    _check_nodes(file, doc)
    _check_views(file, doc)
    _check_accessors(file, doc)
    _check_index_accessors(file, doc)


def _mesh_triangles(doc: dict, mesh_index) -> int:
    """Triangles a mesh declares: its primitives' index counts / 3 (or POSITION counts / 3)."""
    meshes, accessors = doc.get("meshes", []) or [], doc.get("accessors", []) or []
    if not _is_int(mesh_index) or not 0 <= mesh_index < len(meshes) or not isinstance(meshes[mesh_index], dict):
        return 0
    total = 0
    for prim in meshes[mesh_index].get("primitives", []) or []:
        if not isinstance(prim, dict):
            continue
        k = prim.get("indices", (prim.get("attributes") or {}).get("POSITION"))
        if _is_int(k) and 0 <= k < len(accessors) and isinstance(accessors[k], dict):
            c = accessors[k].get("count", 0)
            total += c // 3 if _is_int(c) and c > 0 else 0
    return total


def expansion(file, doc: dict, roots: list, root_pointer: str) -> tuple[int, int]:
    """(node instances, triangles) of the hierarchy under ``roots`` once expanded, computed without
    expanding (each node's subtree summed once, memoized, iteratively: no recursion limit); a cycle
    is refused. Checked against the ``node_instances`` and ``triangles`` budgets."""
    nodes = doc.get("nodes", []) or []
    inst: dict[int, int] = {}
    tris: dict[int, int] = {}
    for r in roots:
        if not _is_int(r) or not 0 <= r < len(nodes):
            raise _err(file, root_pointer, f"node index {r!r} out of range (the file has {len(nodes)} nodes)")
    on_path: set[int] = set()
    for r in roots:
        stack = [(r, False)]
        while stack:
            n, done = stack.pop()
            if done:
                on_path.discard(n)
                ch = nodes[n].get("children", [])
                inst[n] = 1 + sum(inst[c] for c in ch)
                tris[n] = _mesh_triangles(doc, nodes[n].get("mesh")) + sum(tris[c] for c in ch)
                continue
            if n in inst:
                continue
            on_path.add(n)
            stack.append((n, True))
            for c in nodes[n].get("children", []):
                if c in on_path:
                    raise _err(file, f"/nodes/{n}/children", "a cycle in the node hierarchy")
                if c not in inst:
                    stack.append((c, False))
    n_inst = sum(inst[r] for r in roots)
    n_tri = sum(tris[r] for r in roots)
    limits.check("node_instances", n_inst, str(file), "node instances after the hierarchy is expanded")
    limits.check("triangles", n_tri, str(file), "triangles after the hierarchy is expanded")
    return n_inst, n_tri


@contextmanager
def pillow_unbounded():
    """Pillow with its decompression-bomb check off and ``DecompressionBombWarning`` silenced: the
    ``texture_bytes`` budget, judged from the headers before decoding, replaces it (Pillow's warning
    leaked to stderr; its error at 2x ``MAX_IMAGE_PIXELS`` hid the image's size)."""
    from PIL import Image

    with _PIL_LOCK, warnings.catch_warnings():
        warnings.simplefilter("ignore", Image.DecompressionBombWarning)
        saved = Image.MAX_IMAGE_PIXELS
        Image.MAX_IMAGE_PIXELS = None
        try:
            yield
        finally:
            Image.MAX_IMAGE_PIXELS = saved


#: Bytes per pixel of the decoded array by Pillow mode (palette images are expanded to RGBA, CMYK
#: converted to RGB, 16-bit grey kept as uint16: :meth:`pbrcheck.gltf._Reader.image`).
_MODE_BYTES = {"1": 1, "L": 1, "LA": 2, "P": 4, "PA": 4, "RGB": 3, "RGBA": 4, "CMYK": 3, "YCbCr": 3,
               "I;16": 2, "I;16B": 2, "I;16L": 2, "I": 2, "F": 4, "LAB": 3, "HSV": 3, "RGBX": 4, "RGBa": 4, "La": 2}


def image_header_bytes(data: bytes) -> tuple[int, int, int] | None:
    """(width, height, decoded bytes) from an image's header alone (Pillow's ``open`` reads no
    pixels), or None when Pillow cannot identify it (the decoder reports that later)."""
    from PIL import Image

    try:
        with pillow_unbounded(), Image.open(io.BytesIO(data)) as im:
            w, h = im.size
            return w, h, w * h * _MODE_BYTES.get(im.mode, 4)
    except Exception:  # noqa: BLE001 - unidentifiable: the decode reports it with its pointer
        return None


def check_texture_bytes(file, headers: list[tuple[int, int, int] | None]) -> int:
    """The sum of the images' decoded bytes against the ``texture_bytes`` budget; returns it."""
    total = sum(h[2] for h in headers if h is not None)
    biggest = max((h for h in headers if h is not None), key=lambda h: h[2], default=None)
    what = "decoded texture bytes" + (f" of {len(headers)} image(s), the largest {biggest[0]}x{biggest[1]}"
                                      if biggest else "")
    limits.check("texture_bytes", total, str(file), what)
    return total


def budgets_key() -> tuple[int, ...]:
    """The budgets a loaded asset was checked against (part of the loader's cache key: an asset
    loaded under a larger budget is checked again under a smaller one)."""
    return tuple(limits.limit(n) for n in ("node_instances", "triangles", "texture_bytes"))


def check_world_matrix(file, pointer: str, world: np.ndarray) -> None:
    """A node's world matrix with every entry within :data:`MAX_WORLD_COORDINATE` (a scale of 1e300
    is finite, but its determinant and every position it moves overflow)."""
    m = float(np.abs(world).max())
    if not m <= MAX_WORLD_COORDINATE:
        raise _err(file, pointer, f"a world transform with an entry of magnitude {m:g}, beyond "
                   f"{MAX_WORLD_COORDINATE:g} (the node hierarchy's scales and translations)")


def check_positions(file, pointer: str, wpos: np.ndarray, space: str) -> None:
    """Positions (``space``: "" for the accessor's, "world-space " after the node transforms) finite
    and within :data:`MAX_WORLD_COORDINATE` (a huge scale or position gave a blank image and exit 0)."""
    with np.errstate(invalid="ignore", over="ignore"):
        a = np.abs(wpos)
        bad = ~(a <= MAX_WORLD_COORDINATE).all(axis=1)
    if bad.any():
        i = int(np.argmax(bad))
        raise _err(file, pointer, f"{int(bad.sum())} {space}position(s) non-finite or beyond "
                   f"{MAX_WORLD_COORDINATE:g} (first at vertex {i}: {[float(x) for x in wpos[i]]})")
