"""The glTF assets the built-in scenes ship, built by code (issue 37 item 3): the ``slabs`` scene's grid of
glass slabs (``KHR_materials_volume`` attenuation through a known thickness) and the ``prism`` scene's
triangular prism (``KHR_materials_dispersion``).

Why shipped files: a built-in scene is a TOML file in ``pbrcheck/scenes/`` and an analytic object is a
sphere or a plane, so a box or a prism comes in as a glTF asset, through the scene file's existing
``[[objects]] type = "gltf"`` entry with a path relative to the scene's folder (``assets/slabs.gltf``:
:func:`pbrcheck.untrusted.scene_file_path` keeps it inside the folder). The files are written by this
module and committed (``pbrcheck/scenes/assets/``, package data), as the gate's ``panel.glb`` is by
:mod:`pbrcheck.gltf_build`: no new scene-file key, no write at load time (loading a scene never writes;
the cache is not needed), and a test checks the committed bytes equal what this module builds now
(``tests/test_transmission_scenes.py``). ``python -m pbrcheck.scene_assets [FOLDER]`` rewrites them
(default: the package's ``scenes/assets``), atomically (:meth:`pbrcheck.gltf_build.Doc.write`).

Geometry (glTF's conventions: +Y up, metres, counter-clockwise front faces, outward flat normals, so
each body is a closed volume boundary for the reference's interior medium):

- :func:`slabs_asset`: :data:`SLAB_THICKNESSES` (columns, left to right, +X) x :data:`SLAB_ATTENUATIONS`
  (rows, far to near, -Z to +Z) boxes of :data:`SLAB_SIDE` square footprint, bottoms at y = 0,
  centres :data:`SLAB_SPACING` apart around the origin; IOR :data:`SLAB_IOR`, roughness 0,
  transmission 1, ``thicknessFactor`` = the box's true height (so the real-time renderers' thickness
  attenuation is exact at normal incidence and the path truth's is ``exp(-sigma_t d / cos theta_t)``),
  ``attenuationColor`` / ``attenuationDistance`` per row. Node ``i`` is ``slab[NAME,dTHICKNESS]``.
- :func:`prism_asset`: a right prism of :data:`PRISM_LENGTH` along X over an equilateral triangle of side
  :data:`PRISM_SIDE` in the YZ plane, apex down, base (top face) horizontal, the triangle's centroid at
  the origin; IOR :data:`PRISM_IOR`, ``dispersion`` :data:`PRISM_DISPERSION` (the Abbe number
  V_d = 20 / dispersion), roughness 0, ``thicknessFactor`` :func:`prism_thickness` (the horizontal chord
  through the centroid: the internal path of the minimum-deviation ray through the centre).
  :func:`prism_faces` gives the outward normals of the two refracting faces;
  :func:`min_deviation_elevation` the elevation (below the horizontal, towards -Z) of the ray through
  the prism at minimum deviation, which the ``prism`` scene's camera looks along and at whose mirror
  elevation behind the prism its sun stands.

API: :func:`slabs_asset`, :func:`prism_asset`, :func:`write_scene_assets`, :data:`SCENE_ASSETS`,
:data:`ASSETS_DIR`, the constants above, :func:`slab_layout` (per slab: name, centre x, z, thickness,
colour, distance).

References: KHR_materials_volume README ("thicknessFactor ... in the coordinate space of the mesh",
``sigma_t = -ln(attenuationColor) / attenuationDistance``); KHR_materials_dispersion README (``dispersion
= 20 / V_d``); the prism's minimum deviation ``D = 2 asin(n sin(A / 2)) - A`` (Born and Wolf, Principles
of Optics, 4.7.2).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from .gltf_build import Doc

#: Where the built-in scenes' assets live (package data beside the scene files).
ASSETS_DIR = Path(__file__).parent / "scenes" / "assets"

#: The slabs' heights (world units = mesh units: the assets are placed unscaled), left to right.
SLAB_THICKNESSES = (0.1, 0.25, 0.5)
#: Rows, far (-Z) to near (+Z): (name, attenuationColor, attenuationDistance). Amber is the glass scene's
#: tint; the three span transmittances from 0.09 (blue row's red at thickness 0.5) to 0.93.
SLAB_ATTENUATIONS = (("amber", (0.9, 0.45, 0.15), 0.5), ("blue", (0.3, 0.55, 0.95), 0.25),
                     ("grey", (0.5, 0.5, 0.5), 1.0))
#: The slabs' square footprint side and centre spacing (a 0.2 gap between neighbours).
SLAB_SIDE = 0.8
SLAB_SPACING = 1.0
#: The slabs' IOR (KHR_materials_ior; F0 0.04).
SLAB_IOR = 1.5

#: The prism: side of its equilateral cross-section, length along X, IOR at the d line, dispersion (V_d 20,
#: a dense flint; crown glass is ~60, so 0.33, too narrow a spread to see at the scene's size).
PRISM_SIDE = 1.0
PRISM_LENGTH = 2.0
PRISM_IOR = 1.5
PRISM_DISPERSION = 1.0
#: The apex angle of an equilateral cross-section (degrees).
PRISM_APEX_DEG = 60.0

#: The files :func:`write_scene_assets` writes, by file name.
SCENE_ASSETS = ("slabs.gltf", "prism.gltf")


def slab_layout() -> list[tuple[str, float, float, float, tuple[float, float, float], float]]:
    """Per slab, rows far to near, columns left to right: (node name, centre x, centre z, thickness,
    attenuationColor, attenuationDistance)."""
    out = []
    n_r, n_c = len(SLAB_ATTENUATIONS), len(SLAB_THICKNESSES)
    for r, (name, color, dist) in enumerate(SLAB_ATTENUATIONS):
        for c, d in enumerate(SLAB_THICKNESSES):
            x = (c - (n_c - 1) / 2) * SLAB_SPACING
            z = (r - (n_r - 1) / 2) * SLAB_SPACING
            out.append((f"slab[{name},d{d:g}]", x, z, d, color, dist))
    return out


def _box(lo, hi) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(positions, normals, uint16 indices) of an axis-aligned box, 4 vertices per face, outward
    normals, counter-clockwise seen from outside."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    pos, nrm, idx = [], [], []
    for axis in range(3):
        u, v = (axis + 1) % 3, (axis + 2) % 3          # (u, v, axis) right-handed
        for sign in (-1.0, 1.0):
            n = np.zeros(3)
            n[axis] = sign
            corners = []
            for a, b in ((0, 0), (1, 0), (1, 1), (0, 1)):
                p = np.empty(3)
                p[axis] = hi[axis] if sign > 0 else lo[axis]
                p[u] = (lo[u], hi[u])[a]
                p[v] = (lo[v], hi[v])[b]
                corners.append(p)
            if sign < 0:                                 # u x v = +axis: reverse for the -axis face
                corners = corners[::-1]
            k = len(pos)
            pos += corners
            nrm += [n] * 4
            idx += [k, k + 1, k + 2, k, k + 2, k + 3]
    return np.array(pos, np.float32), np.array(nrm, np.float32), np.array(idx, np.uint16)


def _flat_faces(polys: list[list[np.ndarray]]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(positions, normals, uint16 indices) of convex planar polygons, each counter-clockwise seen from
    outside, fanned into triangles with its own flat normal."""
    pos, nrm, idx = [], [], []
    for poly in polys:
        p = [np.asarray(q, float) for q in poly]
        n = np.cross(p[1] - p[0], p[2] - p[0])
        n /= np.linalg.norm(n)
        k = len(pos)
        pos += p
        nrm += [n] * len(p)
        for j in range(1, len(p) - 1):
            idx += [k, k + j, k + j + 1]
    return np.array(pos, np.float32), np.array(nrm, np.float32), np.array(idx, np.uint16)


def _add_body(doc: Doc, name: str, geometry, material: dict) -> None:
    pos, nrm, idx = geometry
    doc.d.setdefault("materials", []).append(material)
    m = doc.mesh({"POSITION": doc.accessor(pos, "VEC3", minmax=True), "NORMAL": doc.accessor(nrm, "VEC3")},
                 doc.accessor(idx, "SCALAR"), len(doc.d["materials"]) - 1)
    doc.node(m, name=name)


def _glass(name: str, ior: float, volume: dict, **extensions) -> dict:
    return {"name": name,
            "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0,
                                     "roughnessFactor": 0.0},
            "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0},
                           "KHR_materials_ior": {"ior": ior}, "KHR_materials_volume": volume, **extensions}}


def _used(doc: Doc) -> None:
    doc.d["extensionsUsed"] = sorted({e for m in doc.d["materials"] for e in m["extensions"]})


def slabs_asset(path: Path, *, ior: float = SLAB_IOR) -> Path:
    """Write the slab grid (module docstring) to ``path`` (.gltf); ``ior`` (tests: 1, index-matched)."""
    doc = Doc()
    for name, x, z, d, color, dist in slab_layout():
        h = SLAB_SIDE / 2
        vol = {"thicknessFactor": d, "attenuationColor": list(color), "attenuationDistance": dist}
        _add_body(doc, name, _box((x - h, 0.0, z - h), (x + h, d, z + h)), _glass(name, ior, vol))
    _used(doc)
    return doc.write(path)


def prism_faces() -> dict[str, np.ndarray]:
    """The prism's vertices in its (y, z) cross-section (``top_front``, ``top_back``, ``apex``) and the
    outward unit normals (y, z) of its two refracting faces (``front``: facing +Z and down; ``back``)."""
    s = PRISM_SIDE
    h = s * math.sqrt(3.0) / 2.0
    top_front, top_back, apex = np.array([h / 3, s / 2]), np.array([h / 3, -s / 2]), np.array([-2 * h / 3, 0.0])
    half = math.radians(PRISM_APEX_DEG) / 2
    return {"top_front": top_front, "top_back": top_back, "apex": apex,
            "front": np.array([-math.sin(half), math.cos(half)]), "back": np.array([-math.sin(half), -math.cos(half)])}


def prism_thickness() -> float:
    """The horizontal chord through the centroid: 2/3 of the side (the width falls linearly from the
    side at the top face to 0 at the apex; the centroid is a third of the height below the top)."""
    return 2.0 * PRISM_SIDE / 3.0


def min_deviation_elevation(ior: float = PRISM_IOR) -> float:
    """Degrees: the minimum deviation ``D = 2 asin(n sin(A / 2)) - A``; the ray through the prism at
    minimum deviation runs parallel to the top face inside, so by symmetry it enters descending at
    ``D / 2`` below the horizontal and leaves ascending at ``D / 2`` above it."""
    a = math.radians(PRISM_APEX_DEG)
    return math.degrees(2.0 * math.asin(ior * math.sin(a / 2)) - a) / 2.0


def prism_asset(path: Path, *, dispersion: float = PRISM_DISPERSION) -> Path:
    """Write the prism (module docstring) to ``path`` (.gltf); ``dispersion`` (tests: 0, none)."""
    f = prism_faces()
    x0, x1 = -PRISM_LENGTH / 2, PRISM_LENGTH / 2

    def p(x, yz):
        return np.array([x, yz[0], yz[1]])

    tf, tb, ap = f["top_front"], f["top_back"], f["apex"]
    polys = [[p(x0, tf), p(x1, tf), p(x1, tb), p(x0, tb)],     # top (+Y)
             [p(x0, ap), p(x1, ap), p(x1, tf), p(x0, tf)],     # front (+Z, down)
             [p(x0, tb), p(x1, tb), p(x1, ap), p(x0, ap)],     # back (-Z, down)
             [p(x0, ap), p(x0, tf), p(x0, tb)],                # cap -X
             [p(x1, ap), p(x1, tb), p(x1, tf)]]                # cap +X
    doc = Doc()
    ext = {"KHR_materials_dispersion": {"dispersion": dispersion}} if dispersion > 0 else {}
    _add_body(doc, "prism", _flat_faces(polys), _glass("prism", PRISM_IOR, {"thicknessFactor": prism_thickness()},
                                                         **ext))
    _used(doc)
    return doc.write(path)


def write_scene_assets(folder: Path = ASSETS_DIR) -> list[Path]:
    """Write :data:`SCENE_ASSETS` into ``folder`` (created if missing); their paths."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    return [slabs_asset(folder / SCENE_ASSETS[0]), prism_asset(folder / SCENE_ASSETS[1])]


if __name__ == "__main__":  # pragma: no cover - the regeneration command (module docstring)
    for out in write_scene_assets(Path(sys.argv[1]) if len(sys.argv) > 1 else ASSETS_DIR):
        print(out)
