"""Small glTF 2.0 assets with known answers, built by the tests themselves (no shared files).

:func:`quad_asset` writes a one-quad ``.gltf`` (buffers and images as data URIs) facing +Z, spanning
[-1, 1]^2 at z = 0, UV (0, 0) at the top-left corner (-1, +1) and (1, 1) at the bottom-right, with
one material whose fields are given as glTF JSON; images are numpy arrays encoded as PNG.
"""

from __future__ import annotations

import base64
import io
import json
from pathlib import Path

import numpy as np
from PIL import Image

QUAD_POS = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32)
QUAD_UV = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)
QUAD_NRM = np.array([[0, 0, 1]] * 4, np.float32)
QUAD_TAN = np.array([[1, 0, 0, 1]] * 4, np.float32)
QUAD_IDX = np.array([0, 1, 2, 0, 2, 3], np.uint16)


def png_uri(pixels: np.ndarray) -> str:
    """A data URI of ``pixels`` (H, W, C) uint8 or uint16 as PNG."""
    buf = io.BytesIO()
    p = np.asarray(pixels)
    if p.dtype == np.uint16:
        # Pillow writes 16-bit greyscale only: pack RGB 16-bit through a mode "I;16" per channel is
        # unsupported, so 16-bit images are single-channel here.
        Image.fromarray(p[..., 0] if p.ndim == 3 else p, mode="I;16").save(buf, format="PNG")
    else:
        Image.fromarray(p).save(buf, format="PNG")
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode()


class Doc:
    """A glTF document under construction with one buffer (data URI at :meth:`write`)."""

    def __init__(self):
        self.bin = bytearray()
        self.d: dict = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": []}], "nodes": [],
                        "meshes": [], "accessors": [], "bufferViews": [], "buffers": []}

    def view(self, raw: bytes) -> int:
        while len(self.bin) % 4:
            self.bin.append(0)
        self.d["bufferViews"].append({"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(raw)})
        self.bin += raw
        return len(self.d["bufferViews"]) - 1

    def accessor(self, arr: np.ndarray, type_: str, *, normalized: bool = False, minmax: bool = False, **extra) -> int:
        ct = {np.dtype(np.float32): 5126, np.dtype(np.uint16): 5123, np.dtype(np.uint32): 5125,
              np.dtype(np.uint8): 5121, np.dtype(np.int8): 5120, np.dtype(np.int16): 5122}[arr.dtype]
        a = {"bufferView": self.view(np.ascontiguousarray(arr).tobytes()), "componentType": ct,
             "count": int(arr.shape[0]), "type": type_, **extra}
        if normalized:
            a["normalized"] = True
        if minmax:
            a["min"] = [float(x) for x in arr.min(axis=0)]
            a["max"] = [float(x) for x in arr.max(axis=0)]
        self.d["accessors"].append(a)
        return len(self.d["accessors"]) - 1

    def image(self, pixels: np.ndarray, sampler: dict | None = None) -> int:
        self.d.setdefault("images", []).append({"uri": png_uri(pixels)})
        tex = {"source": len(self.d["images"]) - 1}
        if sampler is not None:
            self.d.setdefault("samplers", []).append(sampler)
            tex["sampler"] = len(self.d["samplers"]) - 1
        self.d.setdefault("textures", []).append(tex)
        return len(self.d["textures"]) - 1

    def mesh(self, attributes: dict[str, int], indices: int | None, material: int | None, **prim) -> int:
        p = {"attributes": attributes, "mode": 4, **prim}
        if indices is not None:
            p["indices"] = indices
        if material is not None:
            p["material"] = material
        self.d["meshes"].append({"name": f"mesh{len(self.d['meshes'])}", "primitives": [p]})
        return len(self.d["meshes"]) - 1

    def node(self, mesh: int, **kw) -> int:
        self.d["nodes"].append({"name": f"node{len(self.d['nodes'])}", "mesh": mesh, **kw})
        self.d["scenes"][0]["nodes"].append(len(self.d["nodes"]) - 1)
        return len(self.d["nodes"]) - 1

    def write(self, path: Path) -> Path:
        self.d["buffers"] = [{"byteLength": len(self.bin),
                              "uri": "data:application/octet-stream;base64," + base64.b64encode(bytes(self.bin)).decode()}]
        path.write_text(json.dumps(self.d))
        return path


def quad_asset(path: Path, material: dict, images: list[tuple[np.ndarray, dict | None]] = (), *,
               tangents: bool = True, scale: float = 1.0, mirrored_u: bool = False) -> Path:
    """A one-quad asset (module docstring); ``images`` become textures 0, 1, ... in order.
    ``mirrored_u``: u runs right to left (u -> 1 - u), as on the mirrored half of a symmetric asset's
    UV layout: the tangent is -x and, the bitangent staying up the image (+y), its sign w is -1."""
    doc = Doc()
    for px, sampler in images:
        doc.image(px, sampler)
    uv = QUAD_UV * (-1, 1) + (1, 0) if mirrored_u else QUAD_UV
    attrs = {"POSITION": doc.accessor(QUAD_POS * scale, "VEC3", minmax=True),
             "NORMAL": doc.accessor(QUAD_NRM, "VEC3"), "TEXCOORD_0": doc.accessor(uv.astype(np.float32), "VEC2")}
    if tangents:
        attrs["TANGENT"] = doc.accessor((QUAD_TAN * (-1, 1, 1, -1)).astype(np.float32) if mirrored_u else QUAD_TAN, "VEC4")
    doc.d["materials"] = [material]
    doc.node(doc.mesh(attrs, doc.accessor(QUAD_IDX, "SCALAR"), 0))
    return doc.write(path)


def quad_scene(tmp_path: Path, asset: Path, *, size=(24, 24), env: str = "[1.0, 1.0, 1.0]",
               fov: float = 30.0, name: str = "scene.toml") -> Path:
    """A scene TOML that looks straight at the quad (filling most of the image) in a constant environment."""
    p = tmp_path / name
    p.write_text(f"""
[camera]
origin = [0.0, 0.0, 4.0]
target = [0.0, 0.0, 0.0]
fov = {fov}
width = {size[0]}
height = {size[1]}

[environment]
type = "constant"
radiance = {env}

[[objects]]
type = "gltf"
path = "{asset.name}"
""")
    return p
