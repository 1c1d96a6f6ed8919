"""glTF 2.0 documents built by code: the writer the tests, the benches and the gate's asset share, and
the gate's asset itself.

Conventions (at both ends: what :func:`panel_asset` writes is what :mod:`pbrcheck.gltf` reads):
glTF 2.0's: +Y up, metres, counter-clockwise front faces, UV (0, 0) at the image's top-left texel
(v grows down the image), tangent ``w`` such that the bitangent ``B = w cross(N, T)`` points to
decreasing v (the normal map's +Y, green, is "up" in the image), colour textures sRGB-encoded,
the others linear. Images are PNG (Pillow), 8 bits per channel.

API
---
- :class:`Doc` -- a document under construction with one buffer: :meth:`Doc.accessor`,
  :meth:`Doc.image`, :meth:`Doc.mesh`, :meth:`Doc.node`; :meth:`Doc.write` (``.gltf``, buffer and
  images as data URIs) and :meth:`Doc.write_glb` (``.glb``: images in buffer views).
- :func:`png_bytes`, :func:`png_uri` -- an array as PNG.
- :func:`panel_asset`, :func:`panel_arrays`, :data:`PANEL_SEGMENTS`, :data:`PANEL_TEXTURE_SIZE`,
  :data:`PANEL_TILES` -- the gate's asset (``compare/budgets/assets/panel.glb``): a curved panel
  with a sRGB base-colour checker, a packed occlusion / roughness / metallic texture and a normal
  map whose ridges tilt strongly along its green channel (so that a base colour read as linear or
  a flipped green channel changes the image far beyond the noise); deterministic (no randomness,
  fixed sizes). ``python -m pbrcheck.gltf_build OUT.glb`` writes it.

References: Khronos glTF 2.0 specification (2021), sections 3.6 (accessors), 3.7.2.1 (TANGENT),
3.8 (textures), 3.9 (materials), 4.4 (GLB file format).
"""

from __future__ import annotations

import base64
import io
import json
import struct
import sys
from pathlib import Path

import numpy as np

from .atomic import write_bytes_atomic, write_text_atomic

#: glTF componentType per numpy dtype.
COMPONENT_TYPES = {np.dtype(np.float32): 5126, np.dtype(np.uint16): 5123, np.dtype(np.uint32): 5125,
                   np.dtype(np.uint8): 5121, np.dtype(np.int8): 5120, np.dtype(np.int16): 5122}


def png_bytes(pixels: np.ndarray) -> bytes:
    """``pixels`` (H, W[, C]) uint8, or single-channel uint16, encoded as PNG (Pillow writes 16-bit
    greyscale only, so a 16-bit image with channels keeps its first)."""
    from PIL import Image

    buf = io.BytesIO()
    p = np.asarray(pixels)
    if p.dtype == np.uint16:
        Image.fromarray(p[..., 0] if p.ndim == 3 else p, mode="I;16").save(buf, format="PNG")
    else:
        Image.fromarray(p).save(buf, format="PNG")
    return buf.getvalue()


def png_uri(pixels: np.ndarray) -> str:
    """A data URI of :func:`png_bytes`."""
    return _data_uri(png_bytes(pixels))


def _data_uri(raw: bytes, mime: str = "image/png") -> str:
    return f"data:{mime};base64," + base64.b64encode(raw).decode()


class Doc:
    """A glTF document under construction with one buffer (module docstring)."""

    def __init__(self):
        self.bin = bytearray()
        self.d: dict = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": []}], "nodes": [],
                        "meshes": [], "accessors": [], "bufferViews": [], "buffers": []}
        self._pngs: list[bytes] = []

    def view(self, raw: bytes) -> int:
        """A buffer view of ``raw`` (4-byte aligned); its index."""
        while len(self.bin) % 4:
            self.bin.append(0)
        self.d["bufferViews"].append({"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(raw)})
        self.bin += raw
        return len(self.d["bufferViews"]) - 1

    def accessor(self, arr: np.ndarray, type_: str, *, normalized: bool = False, minmax: bool = False, **extra) -> int:
        """An accessor of ``arr`` (its rows are the elements); its index."""
        a = {"bufferView": self.view(np.ascontiguousarray(arr).tobytes()), "componentType": COMPONENT_TYPES[arr.dtype],
             "count": int(arr.shape[0]), "type": type_, **extra}
        if normalized:
            a["normalized"] = True
        if minmax:
            a["min"] = [float(x) for x in arr.min(axis=0)]
            a["max"] = [float(x) for x in arr.max(axis=0)]
        self.d["accessors"].append(a)
        return len(self.d["accessors"]) - 1

    def image(self, pixels: np.ndarray, sampler: dict | None = None) -> int:
        """A texture of ``pixels`` (PNG) with an optional sampler; the texture's index."""
        raw = png_bytes(pixels)
        self._pngs.append(raw)
        self.d.setdefault("images", []).append({"uri": _data_uri(raw)})
        tex = {"source": len(self.d["images"]) - 1}
        if sampler is not None:
            self.d.setdefault("samplers", []).append(sampler)
            tex["sampler"] = len(self.d["samplers"]) - 1
        self.d.setdefault("textures", []).append(tex)
        return len(self.d["textures"]) - 1

    def mesh(self, attributes: dict[str, int], indices: int | None, material: int | None, **prim) -> int:
        """A mesh of one triangle primitive; its index."""
        p = {"attributes": attributes, "mode": 4, **prim}
        if indices is not None:
            p["indices"] = indices
        if material is not None:
            p["material"] = material
        self.d["meshes"].append({"name": f"mesh{len(self.d['meshes'])}", "primitives": [p]})
        return len(self.d["meshes"]) - 1

    def node(self, mesh: int, **kw) -> int:
        """A root node drawing ``mesh``; its index."""
        self.d["nodes"].append({"name": f"node{len(self.d['nodes'])}", "mesh": mesh, **kw})
        self.d["scenes"][0]["nodes"].append(len(self.d["nodes"]) - 1)
        return len(self.d["nodes"]) - 1

    def write(self, path: Path) -> Path:
        """Write ``path`` (.gltf: the buffer and the images as data URIs), atomically."""
        self.d["buffers"] = [{"byteLength": len(self.bin),
                              "uri": _data_uri(bytes(self.bin), "application/octet-stream")}]
        write_text_atomic(Path(path), json.dumps(self.d))
        return Path(path)

    def write_glb(self, path: Path) -> Path:
        """Write ``path`` (.glb: JSON chunk, then the binary chunk holding the buffer and the images
        as buffer views with their ``mimeType``), atomically."""
        d = json.loads(json.dumps(self.d))
        binary = Doc()
        binary.bin, binary.d["bufferViews"] = bytearray(self.bin), d["bufferViews"]
        for im, raw in zip(d.get("images", []), self._pngs):
            im.pop("uri")
            im.update(bufferView=binary.view(raw), mimeType="image/png")
        blob = bytes(binary.bin) + b"\0" * (-len(binary.bin) % 4)
        d["buffers"] = [{"byteLength": len(blob)}]
        js = json.dumps(d, separators=(",", ":")).encode()
        js += b" " * (-len(js) % 4)
        out = b"".join([struct.pack("<III", 0x46546C67, 2, 12 + 8 + len(js) + 8 + len(blob)),
                        struct.pack("<II", len(js), 0x4E4F534A), js, struct.pack("<II", len(blob), 0x004E4942), blob])
        write_bytes_atomic(Path(path), out)
        return Path(path)


#: Segments of the panel's arc (vertices: two rows of PANEL_SEGMENTS + 1).
PANEL_SEGMENTS = 48
#: Texels on a side of each of the panel's textures.
PANEL_TEXTURE_SIZE = 64
#: Repeats of the textures across the panel (u, v): REPEAT wrapping, so the texel density on screen
#: is high enough for the mip chain to be used (trilinear filtering above LOD 0).
PANEL_TILES = (6, 4)
#: The panel's arc (degrees either side of +Z), radius and half height (metres).
PANEL_ARC_DEG = 55.0
PANEL_RADIUS = 1.0
PANEL_HALF_HEIGHT = 0.75
#: Slopes of the normal map's height field: the ridge's rising and falling faces along +Y (green;
#: the rising face spans PANEL_RISE of the tile) and the fine bumps' amplitude along u (red).
PANEL_RIDGE_SLOPES = (0.6, -0.9)
PANEL_RISE = 0.6
PANEL_BUMP_SLOPE = 0.35
PANEL_BUMPS = 8


def panel_arrays(tex: int = PANEL_TEXTURE_SIZE) -> dict[str, np.ndarray]:
    """The panel's texture images (uint8): ``base_color`` (RGB, sRGB-encoded), ``orm`` (R occlusion,
    G roughness, B metallic; linear) and ``normal`` (RGB tangent-space normal, linear).

    One texture tile: a 2 x 2 checker of two mid-tone colours (sRGB 180, 90, 60 and 70, 130, 170,
    where decoding matters most); a ridge whose face rises along +Y over 80 % of the tile's height
    (tangent slope 0.6 on the green channel) then falls steeply (slope -2.4), with fine bumps along
    u (8 per tile, slope 0.5 on the red channel) that the mip chain averages away; occlusion 0.55 in
    the ridge's foot, 1 elsewhere; roughness rising from 0.2 to 0.7 along u; metallic in one quarter.
    """
    y, x = (np.mgrid[0:tex, 0:tex] + 0.5) / tex   # x along u, y along v (down the image)
    checker = ((np.floor(x * 2) + np.floor(y * 2)) % 2)[..., None]
    base = np.where(checker > 0, [180, 90, 60], [70, 130, 170]).astype(np.uint8)
    up = 1.0 - y                                  # "up" in the image: +Y of the normal map
    sy = np.where(up < PANEL_RISE, *PANEL_RIDGE_SLOPES)          # dh/d(up): green-channel slope
    sx = PANEL_BUMP_SLOPE * np.cos(2 * np.pi * PANEL_BUMPS * x)  # dh/du: the fine bumps
    n = np.stack([-sx, -sy, np.ones_like(x)], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    normal = np.round((n * 0.5 + 0.5) * 255).astype(np.uint8)
    ao = np.where(up < 0.15, 0.55, 1.0)
    rough = 0.2 + 0.5 * x
    metal = ((x >= 0.5) & (y >= 0.5)).astype(float)
    orm = np.round(np.stack([ao, rough, metal], -1) * 255).astype(np.uint8)
    return {"base_color": base, "orm": orm, "normal": normal}


def panel_asset(path: Path, *, segments: int = PANEL_SEGMENTS, tex: int = PANEL_TEXTURE_SIZE) -> Path:
    """Write the gate's panel asset (module docstring) to ``path`` (``.glb``, else ``.gltf``).

    Geometry: a cylindrical arc of :data:`PANEL_ARC_DEG` degrees either side of +Z about the +Y
    axis, radius :data:`PANEL_RADIUS`, from -:data:`PANEL_HALF_HEIGHT` to +:data:`PANEL_HALF_HEIGHT`
    in y, facing +Z; exact normals (radial) and tangents (along the arc, ``w = 1``); UV (0, 0) at
    the top-left, :data:`PANEL_TILES` repeats. One material: factors 1, the three textures of
    :func:`panel_arrays` (the ORM texture is both ``occlusionTexture`` and ``metallicRoughnessTexture``,
    as engines pack them), single-sided, OPAQUE.
    """
    a = np.radians(PANEL_ARC_DEG)
    phi = np.linspace(-a, a, segments + 1)
    rows = []
    for y, v in ((PANEL_HALF_HEIGHT, 0.0), (-PANEL_HALF_HEIGHT, 1.0)):
        s, c = np.sin(phi), np.cos(phi)
        rows.append({"pos": np.stack([PANEL_RADIUS * s, np.full_like(s, y), PANEL_RADIUS * c], -1),
                     "nrm": np.stack([s, np.zeros_like(s), c], -1),
                     "tan": np.stack([c, np.zeros_like(s), -s, np.ones_like(s)], -1),
                     "uv": np.stack([(phi + a) / (2 * a) * PANEL_TILES[0], np.full_like(s, v * PANEL_TILES[1])], -1)})
    cat = {k: np.concatenate([r[k] for r in rows]).astype(np.float32) for k in rows[0]}
    top, bottom = np.arange(segments), np.arange(segments) + segments + 1
    # counter-clockwise seen from +Z (outside): top-left, bottom-left, bottom-right; top-left, bottom-right, top-right
    tris = np.concatenate([np.stack([top, bottom, bottom + 1], -1), np.stack([top, bottom + 1, top + 1], -1)])
    imgs = panel_arrays(tex)
    doc = Doc()
    repeat = {"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497}
    t_base, t_orm, t_nrm = (doc.image(imgs[k], repeat) for k in ("base_color", "orm", "normal"))
    attrs = {"POSITION": doc.accessor(cat["pos"], "VEC3", minmax=True), "NORMAL": doc.accessor(cat["nrm"], "VEC3"),
             "TANGENT": doc.accessor(cat["tan"], "VEC4"), "TEXCOORD_0": doc.accessor(cat["uv"], "VEC2")}
    doc.d["materials"] = [{"name": "panel", "pbrMetallicRoughness": {
        "baseColorTexture": {"index": t_base}, "metallicRoughnessTexture": {"index": t_orm}},
        "normalTexture": {"index": t_nrm}, "occlusionTexture": {"index": t_orm}}]
    m = doc.mesh(attrs, doc.accessor(tris.reshape(-1).astype(np.uint16), "SCALAR"), 0)
    doc.d["meshes"][m]["name"] = "panel"
    doc.node(m, name="panel")
    path = Path(path)
    return doc.write_glb(path) if path.suffix.lower() == ".glb" else doc.write(path)


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: python -m pbrcheck.gltf_build OUT.glb|OUT.gltf  (writes the gate's panel asset)")
    print(panel_asset(Path(sys.argv[1])))
