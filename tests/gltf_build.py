"""Small glTF 2.0 assets with known answers, built by the tests themselves (no shared files).

:func:`quad_asset` writes a one-quad ``.gltf`` (buffers and images as data URIs) facing +Z, spanning
[-1, 1]^2 at z = 0, UV (0, 0) at the top-left corner (-1, +1) and (1, 1) at the bottom-right, with
one material whose fields are given as glTF JSON; images are numpy arrays encoded as PNG. The
document writer (:class:`Doc`, :func:`png_uri`) is :mod:`pbrcheck.gltf_build`'s.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pbrcheck.gltf_build import Doc, png_uri  # noqa: F401  (the writer lives in the package)

QUAD_POS = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32)
QUAD_UV = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)
QUAD_NRM = np.array([[0, 0, 1]] * 4, np.float32)
QUAD_TAN = np.array([[1, 0, 0, 1]] * 4, np.float32)
QUAD_IDX = np.array([0, 1, 2, 0, 2, 3], np.uint16)
#: u running right to left, as on the mirrored half of a symmetric asset's UV layout: the tangent is
#: -x and, the bitangent staying up the image (+y), its sign w is -1.
MIRRORED_UV = QUAD_UV * np.array([-1, 1], np.float32) + np.array([1, 0], np.float32)
MIRRORED_TAN = np.array([[-1, 0, 0, -1]] * 4, np.float32)


def quad_asset(path: Path, material: dict, images: list[tuple[np.ndarray, dict | None]] = (), *,
               tangents: bool = True, scale: float = 1.0, uv0: np.ndarray = QUAD_UV,
               uv1: np.ndarray | None = None, tangent: np.ndarray = QUAD_TAN) -> Path:
    """A one-quad asset (module docstring); ``images`` become textures 0, 1, ... in order; ``uv0``,
    ``uv1``: the corners' TEXCOORD_0 (default :data:`QUAD_UV`) and TEXCOORD_1 (default none);
    ``tangent``: the corners' TANGENT (default :data:`QUAD_TAN`; with ``uv0`` :data:`MIRRORED_UV`,
    :data:`MIRRORED_TAN`)."""
    doc = Doc()
    for px, sampler in images:
        doc.image(px, sampler)
    attrs = {"POSITION": doc.accessor(QUAD_POS * scale, "VEC3", minmax=True),
             "NORMAL": doc.accessor(QUAD_NRM, "VEC3"), "TEXCOORD_0": doc.accessor(np.asarray(uv0, np.float32), "VEC2")}
    if uv1 is not None:
        attrs["TEXCOORD_1"] = doc.accessor(np.asarray(uv1, np.float32), "VEC2")
    if tangents:
        attrs["TANGENT"] = doc.accessor(np.asarray(tangent, np.float32), "VEC4")
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
