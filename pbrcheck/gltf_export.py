"""Export of scenes holding a glTF asset: the user's asset itself, with its resources, for the
external engines (``pbrcheck export``; :func:`pbrcheck.export.export_scene` calls
:func:`asset_document` for such scenes).

The written ``scene.gltf`` is the asset's own JSON with: the chosen glTF scene only, its root nodes
under one node ``pbrcheck_root`` carrying the scene file's placement (``matrix``, column-major;
omitted when the identity), pbrcheck's camera first in ``cameras`` (the asset's cameras follow,
their nodes re-indexed) on a node ``camera``; a GLB's binary chunk becomes ``scene.bin``; external
buffers and images are copied beside it under their own relative URIs, except one that would take
the name of a file the export writes itself (``reserved``: ``scenario.json``, ``scene.gltf``,
``environment.*``, the objects' buffer; compared case-insensitively) or a name already taken: that
copy goes into a sub-folder :data:`RENAMED_FOLDER` (``_asset/scenario.json``), its URI rewritten, so
no file of the asset is overwritten by the export's own; data URIs stay. Analytic
objects of the same scene are added by :func:`pbrcheck.export.gltf_document`, tessellated as in an
analytic scene's export (nodes ``object_<k>_<name>``, a buffer ``pbrcheck_objects.bin`` of their
own). The asset's ``KHR_materials_variants`` variant drawn becomes its default material, and nodes
hidden by ``KHR_node_visibility`` lose their meshes and lights
(:func:`pbrcheck.gltf_features.export_selection`); skins, morph targets and GPU instances are kept
for the engines to apply. The scene file's own lights are added there too (root nodes ``light_<k>`` beside
``pbrcheck_root``, after the asset's ``KHR_lights_punctual`` lights). One asset per exported scene
(:class:`~pbrcheck.gltf.AssetError` otherwise).

API: :func:`asset_document` (the JSON, the files to write beside it), :data:`RENAMED_FOLDER`, :func:`mesh_object_ids`
(the ``object`` AOV of a scene's meshes by rasterizing pixel centres in numpy).
"""

from __future__ import annotations

import copy
import json
import urllib.parse
from pathlib import Path

import numpy as np

from .camera import camera_frame, tan_half_fov
from . import gltf_features
from .gltf import AssetError, read_resource, resource_cap

#: The sub-folder of an asset's resource whose name an export file takes (:func:`asset_document`);
#: ``_asset2``, ``_asset3``, ... when that path is taken too.
RENAMED_FOLDER = "_asset"
#: Most candidate (triangle, pixel) pairs rasterized at once by :func:`mesh_object_ids`.
RASTER_CHUNK = 1 << 22


def _read_doc(path: Path) -> tuple[dict, bytes | None]:
    raw = path.read_bytes()
    if raw[:4] == b"glTF":
        n = int.from_bytes(raw[12:16], "little")
        doc = json.loads(raw[20:20 + n].decode("utf-8"))
        off = 20 + n
        blob = None
        if off + 8 <= len(raw):
            m = int.from_bytes(raw[off:off + 4], "little")
            blob = raw[off + 8:off + 8 + m]
        return doc, blob
    return json.loads(raw.decode("utf-8")), None


def _free_path(rel: str, taken: set[str]) -> str:
    """``rel``, or ``_asset/rel`` (``_asset2/rel``, ...) when ``rel`` is taken (case-insensitively)."""
    out, n = rel, 1
    while out.casefold() in taken:
        out = f"{RENAMED_FOLDER}{n if n > 1 else ''}/{rel}"
        n += 1
    return out


def asset_document(scene, camera_node: dict, camera: dict, bin_name: str = "scene.bin",
                   reserved: tuple[str, ...] = ()) -> tuple[dict, dict[str, bytes]]:
    """(glTF JSON, {relative path: bytes}) of the scene's one asset (its analytic objects, if any, are
    :func:`pbrcheck.export.gltf_document`'s to add); no resource takes a name in ``reserved`` (the
    export's own files) or another resource's (module docstring)."""
    if len(scene.assets) != 1:
        raise AssetError(scene.source, "objects", "an exported scene holds at most one glTF asset "
                         f"(this one has {len(scene.assets)})")
    inst = scene.assets[0]
    src = Path(inst.path)
    doc, blob = _read_doc(src)
    doc = gltf_features.export_selection(copy.deepcopy(doc), inst.variant)   # the variant and visibility drawn
    files: dict[str, bytes] = {}
    taken = {r.casefold() for r in reserved}
    placed: dict[str, str] = {}  # the asset's relative path -> where its copy goes
    for key in ("buffers", "images"):
        for k, b in enumerate(doc.get(key, [])):
            uri = b.get("uri")
            if uri is None:
                if key == "buffers" and k == 0 and blob is not None:
                    b["uri"] = bin_name
                    files[bin_name] = bytes(blob)
                    taken.add(bin_name.casefold())
                continue
            if uri.startswith("data:"):
                continue
            rel = urllib.parse.unquote(uri)
            norm = Path(rel).as_posix()
            if norm not in placed:
                placed[norm] = _free_path(norm, taken)
                taken.add(placed[norm].casefold())
                # the loader's resolver: a symlink out of the asset's folder is refused, never its target copied
                files[placed[norm]] = read_resource(src, uri, f"/{key}/{k}/uri", resource_cap(key, b), key[:-1])
            if placed[norm] != norm:
                b["uri"] = urllib.parse.quote(placed[norm])
    si = inst.asset.scene
    roots = doc["scenes"][si]["nodes"] if doc.get("scenes") else inst.asset and [
        i for i in range(len(doc.get("nodes", [])))
        if i not in {c for n in doc.get("nodes", []) for c in n.get("children", [])}]
    nodes = doc.setdefault("nodes", [])
    for n in nodes:
        if "camera" in n:
            n["camera"] += 1
    root = {"name": "pbrcheck_root", "children": list(roots)}
    if not inst.is_identity():
        root["matrix"] = [float(x) for x in inst.matrix().T.reshape(-1)]
    nodes.append(root)
    nodes.append(camera_node)
    doc["cameras"] = [camera] + doc.get("cameras", [])
    doc["scenes"] = [{"name": scene.name, "nodes": [len(nodes) - 2, len(nodes) - 1]}]
    doc["scene"] = 0
    doc.setdefault("asset", {})["generator"] = doc["asset"].get("generator", "") + " + pbrcheck export"
    return doc, files


def mesh_object_ids(scene, ids: np.ndarray, best_t: np.ndarray) -> None:
    """Write into ``ids`` (H, W) the mesh object seen through each pixel centre where it is nearer
    than ``best_t`` (the ray distance already found; updated): pixel-centre rasterization of the
    scene's triangles (perspective-correct depth), the ``object`` AOV of external images."""
    cam = scene.camera
    W, H = cam.width, cam.height
    r, u, f = camera_frame(cam)
    tx, ty = tan_half_fov(cam)
    o = np.asarray(cam.origin, float)
    # ray length per unit forward depth at each pixel centre
    jj = 2.0 * (np.arange(W) + 0.5) / W - 1.0
    ii = 1.0 - 2.0 * (np.arange(H) + 0.5) / H
    X, Y = np.meshgrid(jj * tx, ii * ty)
    stretch = np.sqrt(1.0 + X * X + Y * Y)
    for obj in scene.objects:
        if obj.type != "mesh":
            continue
        inst = scene.assets[obj.instance]
        prim = inst.asset.primitives[obj.primitive]
        M = inst.matrix()
        p = prim.positions.astype(np.float64) @ M[:3, :3].T + M[:3, 3] - o
        z = p @ f
        c = ((p @ r) / np.maximum(z, 1e-12) / tx + 1.0) * 0.5 * W - 0.5       # column of pixel centres
        rw = (1.0 - (p @ u) / np.maximum(z, 1e-12) / ty) * 0.5 * H - 0.5      # row
        tri = prim.indices.astype(np.int64)
        front = (z[tri] > 1e-6).all(axis=1)
        tri = tri[front]
        cx, cy, cz = c[tri], rw[tri], z[tri]
        j0 = np.clip(np.ceil(cx.min(1)), 0, W).astype(np.int64)
        j1 = np.clip(np.floor(cx.max(1)), -1, W - 1).astype(np.int64)
        i0 = np.clip(np.ceil(cy.min(1)), 0, H).astype(np.int64)
        i1 = np.clip(np.floor(cy.max(1)), -1, H - 1).astype(np.int64)
        nw, nh = np.maximum(j1 - j0 + 1, 0), np.maximum(i1 - i0 + 1, 0)
        cnt = nw * nh
        keep = cnt > 0
        tri_idx = np.nonzero(keep)[0]
        starts = np.concatenate([[0], np.cumsum(cnt[keep])])
        k0 = 0
        while k0 < len(tri_idx):
            k1 = int(np.searchsorted(starts, starts[k0] + RASTER_CHUNK, side="right")) - 1
            k1 = max(k1, k0 + 1)
            sel = tri_idx[k0:k1]
            n = cnt[sel]
            t = np.repeat(np.arange(len(sel)), n)
            local = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
            w_ = nw[sel][t]
            jp = j0[sel][t] + local % w_
            ip = i0[sel][t] + local // w_
            x0, x1, x2 = cx[sel][t].T
            y0, y1, y2 = cy[sel][t].T
            area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
            e0 = (x1 - jp) * (y2 - ip) - (x2 - jp) * (y1 - ip)
            e1 = (x2 - jp) * (y0 - ip) - (x0 - jp) * (y2 - ip)
            e2 = (x0 - jp) * (y1 - ip) - (x1 - jp) * (y0 - ip)
            with np.errstate(divide="ignore", invalid="ignore"):
                b0, b1, b2 = e0 / area, e1 / area, e2 / area
            inside = (np.abs(area) > 1e-18) & (b0 >= 0) & (b1 >= 0) & (b2 >= 0)
            zz = cz[sel][t]
            with np.errstate(divide="ignore"):
                depth = 1.0 / (b0 / zz[:, 0] + b1 / zz[:, 1] + b2 / zz[:, 2])
            ip, jp, depth = ip[inside], jp[inside], depth[inside]
            dist = depth * stretch[ip, jp]
            flat = ip * W + jp
            bt = best_t.reshape(-1)        # views: best_t and ids are contiguous (H, W) arrays
            np.minimum.at(bt, flat, dist)
            win = dist == bt[flat]
            ids.reshape(-1)[flat[win]] = obj.id
            k0 = k1
