"""glTF scene features that change what the loader's primitives are: skins, morph targets, GPU
instancing, node visibility, material variants, and the choice of a texture's image among its
extensions. Called by :func:`pbrcheck.gltf.load_asset` (kept apart from the reading code).

API
---
- :data:`MODELLED_SCENE_EXTENSIONS` -- the extensions this module models (the loader's
  :data:`pbrcheck.gltf.MODELLED_EXTENSIONS` includes them).
- :func:`node_worlds` -- every node's world matrix (the hierarchy's product of local matrices).
- :func:`node_visible` -- ``KHR_node_visibility``'s flag of one node.
- :func:`morph_weights` -- a mesh instance's default morph weights (node ``weights`` over mesh ``weights``).
- :func:`skin_matrices` -- a skin's joint matrices ``world(joint_j) @ inverseBindMatrix_j``.
- :func:`deform` -- morph targets then skinning applied to a primitive's attributes.
- :func:`instance_matrices` -- ``EXT_mesh_gpu_instancing``'s per-instance world matrices of a node.
- :func:`place` -- positions, normals, tangents and triangles to world space, once per instance, merged.
- :func:`variant_names`, :func:`variant_index`, :func:`variant_material` -- ``KHR_materials_variants``.
- :func:`texture_source` -- the image a texture reads (``EXT_texture_webp``, ``KHR_texture_basisu``, core).
- :func:`decode_ktx2` -- a ``KHR_texture_basisu`` KTX2 image's level 0 as RGBA8 (``opengl_basisu``).
- :func:`meshopt_view` -- an ``EXT_meshopt_compression`` buffer view decoded (the ``meshopt`` package).
- :func:`used_images` -- the images a material's texture reads (the only ones decoded).
- :func:`restore_node_weights` -- the nodes' morph ``weights`` that the JSON reader drops.
- :func:`export_selection` -- the exported JSON drawing the selected variant, hidden nodes removed.

Conventions (Khronos glTF 2.0 specification, 3.7.2.2 morph targets, 3.7.3 skins; the extensions'
READMEs in KhronosGroup/glTF):

- Morph targets: ``attr = base + sum_i w_i * target_i.attr`` for POSITION, NORMAL and TANGENT (the
  tangent's xyz; a target's TANGENT is a VEC3 delta, ``w`` kept). ``w`` are the node's ``weights``
  where present, else the mesh's, else 0 (spec 3.7.2.2 and 5.17 ``node.weights``).
- Skins: ``jointMatrix_j = world(joints[j]) @ inverseBindMatrices[j]`` (identity where the accessor
  is absent); a vertex's skin matrix ``S = sum_k w_k jointMatrix[JOINTS_n[k]]`` over every
  ``JOINTS_n``/``WEIGHTS_n`` set; positions by ``S``, normals by ``S``'s inverse transpose, tangents'
  xyz by ``S``. The skinned mesh node's own transform is ignored (spec 3.7.3.3: only the joints'
  transforms apply); the result is world space. Weights are divided by their sum where it is not 0
  (the specification requires sum 1; engines normalize likewise). The pose is the nodes' own
  transforms (the file's default pose; animations are not played). A primitive of a skinned node
  without ``JOINTS_0`` is not skinned (an ordinary mesh at its node's transform, as engines draw it).
- ``EXT_mesh_gpu_instancing``: instance ``i``'s world matrix is ``world(node) @ T_i R_i S_i``
  (TRANSLATION VEC3, ROTATION VEC4 unit quaternion xyzw, SCALE VEC3; each absent one identity); the
  node's mesh is drawn once per instance, not for the node itself.
- ``KHR_node_visibility``: ``visible`` (default true); a node is visible iff it and every ancestor
  is; a hidden node's meshes and lights are not drawn; cameras are unaffected.
- ``KHR_materials_variants``: the root's ``variants[k].name``; a primitive's ``mappings`` give the
  material of each variant index; a primitive without a mapping for the selected variant, or no
  variant selected, uses its ``material`` (the file's default).
- Images: a texture reads ``EXT_texture_webp``'s ``source`` where present (Pillow decodes WEBP),
  else ``KHR_texture_basisu``'s (a KTX2 image with a Basis Universal payload, ETC1S or UASTC: level 0
  transcoded to RGBA8 by ``opengl_basisu``, Binomial's basis_universal transcoder; its values are the
  stored ones, sRGB-decoded for colour slots like a PNG's), else its core ``source``: what an engine
  with the extensions reads. ``EXT_meshopt_compression``: a buffer view with the extension is decoded from
  the extension's ``buffer``/``byteOffset``/``byteLength`` (``count`` elements of ``byteStride``
  bytes, its ``mode`` and ``filter``) by the ``meshopt`` package (PyPI; meshoptimizer's own decoder
  sources, vendored, behind the JavaScript module's ``decodeGltfBuffer``), whether the extension is
  required or optional (its core fields, the optional fallback, are then not read).
"""

from __future__ import annotations

import json

import numpy as np

#: Extensions modelled here (scene features and image formats).
MODELLED_SCENE_EXTENSIONS = ("EXT_mesh_gpu_instancing", "KHR_node_visibility", "KHR_materials_unlit",
                             "KHR_materials_variants", "EXT_texture_webp", "EXT_meshopt_compression",
                             "KHR_texture_basisu")
#: ``EXT_meshopt_compression``'s modes and filters (the extension's README).
MESHOPT_MODES = ("ATTRIBUTES", "TRIANGLES", "INDICES")
MESHOPT_FILTERS = ("NONE", "OCTAHEDRAL", "QUATERNION", "EXPONENTIAL")
#: Deepest node hierarchy walked for world matrices (a guard against corrupt parent chains; the
#: loader's own traversal reports cycles by name).
MAX_NODE_DEPTH = 4096
#: The sum of a vertex's skin weights below which it is left unnormalized (all weights zero).
MIN_WEIGHT_SUM = 1e-12


# ------------------------------------------------------------------------------------------------
# Nodes
# ------------------------------------------------------------------------------------------------

def node_worlds(r, node_matrix) -> dict[int, np.ndarray]:
    """{node index: world 4x4} for every node of the document (``node_matrix`` the local one)."""
    nodes = r.doc.get("nodes", [])
    parent: dict[int, int] = {}
    for i, n in enumerate(nodes):
        for c in n.get("children", []) if isinstance(n, dict) else []:
            if isinstance(c, int):
                parent.setdefault(c, i)
    out: dict[int, np.ndarray] = {}
    for i in range(len(nodes)):
        chain, j = [], i
        while j is not None and j not in out and len(chain) <= MAX_NODE_DEPTH:
            chain.append(j)
            j = parent.get(j)
            if j in chain:
                raise r.err(f"/nodes/{j}/children", "a cycle in the node hierarchy")
        m = out[j] if j is not None and j in out else np.eye(4)
        for k in reversed(chain):
            m = m @ node_matrix(nodes[k])
            out[k] = m
    return out


def node_visible(r, node: dict, index: int) -> bool:
    """``KHR_node_visibility``'s ``visible`` of ``node`` (true where absent)."""
    ext = node.get("extensions", {}).get("KHR_node_visibility")
    if ext is None:
        return True
    v = ext.get("visible", True) if isinstance(ext, dict) else None
    if not isinstance(v, bool):
        raise r.err(f"/nodes/{index}/extensions/KHR_node_visibility/visible", f"a boolean, found {v!r}")
    return v


def instance_matrices(r, node: dict, index: int, world: np.ndarray, quat_matrix) -> list[np.ndarray]:
    """World matrices of the node's mesh instances: ``[world]`` without ``EXT_mesh_gpu_instancing``,
    else ``world @ T_i R_i S_i`` per instance (module docstring)."""
    ext = node.get("extensions", {}).get("EXT_mesh_gpu_instancing")
    if ext is None:
        return [world]
    p = f"/nodes/{index}/extensions/EXT_mesh_gpu_instancing/attributes"
    attrs = ext.get("attributes", {}) if isinstance(ext, dict) else {}
    cols = {}
    for name, width in (("TRANSLATION", 3), ("ROTATION", 4), ("SCALE", 3)):
        if name in attrs:
            a = r.accessor(attrs[name], f"{p}/{name}").astype(np.float64)
            if a.shape[1] != width:
                raise r.err(f"{p}/{name}", f"expected {width} components, found {a.shape[1]}")
            if not np.isfinite(a).all():
                raise r.err(f"{p}/{name}", "non-finite values")
            cols[name] = a
    if not cols:
        raise r.err(p, "no TRANSLATION, ROTATION or SCALE attribute")
    counts = {k: v.shape[0] for k, v in cols.items()}
    if len(set(counts.values())) != 1:
        raise r.err(p, f"attributes of different counts {counts}")
    n = next(iter(counts.values()))
    out = []
    for i in range(n):
        m = np.eye(4)
        rot = quat_matrix(cols["ROTATION"][i]) if "ROTATION" in cols else np.eye(3)
        m[:3, :3] = rot * (cols["SCALE"][i] if "SCALE" in cols else 1.0)
        if "TRANSLATION" in cols:
            m[:3, 3] = cols["TRANSLATION"][i]
        out.append(world @ m)
    return out


# ------------------------------------------------------------------------------------------------
# Morph targets and skins
# ------------------------------------------------------------------------------------------------

def morph_weights(r, node: dict, node_i: int, mesh: dict, mesh_i: int, targets: int) -> np.ndarray:
    """The default weights of a mesh instance: the node's ``weights``, else the mesh's, else zeros."""
    for owner, ptr in ((node, f"/nodes/{node_i}/weights"), (mesh, f"/meshes/{mesh_i}/weights")):
        if "weights" in owner:
            w = owner["weights"]
            if (not isinstance(w, list) or not all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                   and np.isfinite(x) for x in w)):
                raise r.err(ptr, f"a list of finite numbers, found {w!r}")
            if targets and len(w) != targets:
                raise r.err(ptr, f"{len(w)} weights for {targets} morph targets")
            return np.asarray(w, np.float64)
    return np.zeros(targets)


def skin_matrices(r, skin_index, node_i: int, worlds: dict[int, np.ndarray]) -> np.ndarray:
    """(J, 4, 4) joint matrices of skin ``skin_index`` (module docstring)."""
    skin = r.get("skins", skin_index, f"/nodes/{node_i}/skin")
    sp = f"/skins/{skin_index}"
    joints = skin.get("joints", [])
    if not isinstance(joints, list) or not joints:
        raise r.err(sp + "/joints", "a non-empty list of node indices")
    for k, j in enumerate(joints):
        r.get("nodes", j, f"{sp}/joints/{k}")
    if "inverseBindMatrices" in skin:
        ibm = r.accessor(skin["inverseBindMatrices"], sp + "/inverseBindMatrices").astype(np.float64)
        if ibm.shape != (len(joints), 16):
            raise r.err(sp + "/inverseBindMatrices", f"{len(joints)} MAT4 elements, found {ibm.shape[0]} "
                        f"of {ibm.shape[1]} components")
        if not np.isfinite(ibm).all():
            raise r.err(sp + "/inverseBindMatrices", "non-finite values")
        ibm = ibm.reshape(-1, 4, 4).transpose(0, 2, 1)     # column-major in the file
    else:
        ibm = np.broadcast_to(np.eye(4), (len(joints), 4, 4))
    return np.stack([worlds[j] for j in joints]) @ ibm


def _skin_per_vertex(r, attrs: dict, pp: str, joint_mats: np.ndarray, n: int) -> np.ndarray:
    """(n, 4, 4) skin matrices of a primitive's vertices from every JOINTS_n / WEIGHTS_n set."""
    S = np.zeros((n, 4, 4))
    total = np.zeros(n)
    k = 0
    while f"JOINTS_{k}" in attrs or f"WEIGHTS_{k}" in attrs:
        jp, wp = f"{pp}/attributes/JOINTS_{k}", f"{pp}/attributes/WEIGHTS_{k}"
        if f"JOINTS_{k}" not in attrs or f"WEIGHTS_{k}" not in attrs:
            raise r.err(jp if f"JOINTS_{k}" not in attrs else wp, f"JOINTS_{k} and WEIGHTS_{k} come in pairs")
        J = r.accessor(attrs[f"JOINTS_{k}"], jp)
        W = r.accessor(attrs[f"WEIGHTS_{k}"], wp).astype(np.float64)
        for arr, ptr in ((J, jp), (W, wp)):
            if arr.shape != (n, 4):
                raise r.err(ptr, f"{n} VEC4 elements (POSITION's count), found {arr.shape[0]} of {arr.shape[1]}")
        if np.issubdtype(J.dtype, np.floating):
            raise r.err(jp, "unsigned byte or short joint indices")
        J = J.astype(np.int64)
        if J.size and (J.min() < 0 or J.max() >= joint_mats.shape[0]):
            raise r.err(jp, f"joint {int(J.max())} out of range ({joint_mats.shape[0]} joints)")
        if not np.isfinite(W).all():
            raise r.err(wp, "non-finite values")
        S += np.einsum("nc,ncij->nij", W, joint_mats[J])
        total += W.sum(axis=1)
        k += 1
    if k == 0:
        raise r.err(pp + "/attributes", "a skinned mesh without JOINTS_0 / WEIGHTS_0")
    ok = np.abs(total) > MIN_WEIGHT_SUM
    S[ok] /= total[ok, None, None]
    S[~ok] = np.eye(4)     # no influence: the bind pose (a vertex the specification forbids)
    return S


def deform(r, prim: dict, pp: str, data: dict, weights: np.ndarray | None,
           joint_mats: np.ndarray | None) -> dict:
    """``data`` (attribute name -> (N, C) array, local space) with the morph targets (``weights``)
    and then the skin (``joint_mats``; the result is world space) applied; a new dict."""
    data = dict(data)
    targets = prim.get("targets", [])
    n = data["POSITION"].shape[0]
    if targets and weights is not None:
        for t, (target, w) in enumerate(zip(targets, weights)):
            if w == 0.0 or not isinstance(target, dict):
                continue
            for k, width in (("POSITION", 3), ("NORMAL", 3), ("TANGENT", 3)):
                if k not in target or k not in data:
                    continue
                tp = f"{pp}/targets/{t}/{k}"
                d = r.accessor(target[k], tp).astype(np.float64)
                if d.shape != (n, width):
                    raise r.err(tp, f"{n} VEC3 deltas (the attribute's count), found {d.shape[0]} of {d.shape[1]}")
                if not np.isfinite(d).all():
                    raise r.err(tp, "non-finite values")
                base = data[k].astype(np.float64)
                base[:, :3] += w * d
                data[k] = base.astype(np.float32)
    if joint_mats is not None:
        S = _skin_per_vertex(r, prim.get("attributes", {}), pp, joint_mats, n)
        A = S[:, :3, :3]
        p = data["POSITION"].astype(np.float64)
        data["POSITION"] = (np.einsum("nij,nj->ni", A, p) + S[:, :3, 3]).astype(np.float32)
        if "NORMAL" in data:
            nrm = np.einsum("nji,nj->ni", np.linalg.inv(A), data["NORMAL"].astype(np.float64))
            data["NORMAL"] = nrm.astype(np.float32)
        if "TANGENT" in data:
            t = data["TANGENT"].astype(np.float64)
            t[:, :3] = np.einsum("nij,nj->ni", A, t[:, :3])
            data["TANGENT"] = t.astype(np.float32)
    return data


# ------------------------------------------------------------------------------------------------
# To world space
# ------------------------------------------------------------------------------------------------

def _place_one(r, node_i: int, pos, nrm, tan, tri, world: np.ndarray):
    M = world[:3, :3]
    det = float(np.linalg.det(M))
    if abs(det) < 1e-30:
        raise r.err(f"/nodes/{node_i}", "a singular world transform (zero scale)")
    wpos = (pos.astype(np.float64) @ M.T + world[:3, 3]).astype(np.float32)
    wn = nrm @ np.linalg.inv(M)
    wn /= np.maximum(np.linalg.norm(wn, axis=1, keepdims=True), 1e-30)
    wt = None
    if tan is not None:
        t3 = tan[:, :3].astype(np.float64) @ M.T
        t3 /= np.maximum(np.linalg.norm(t3, axis=1, keepdims=True), 1e-30)
        w = np.where(tan[:, 3] < 0, -1.0, 1.0) * (1.0 if det > 0 else -1.0)
        wt = np.concatenate([t3, w[:, None]], axis=1).astype(np.float32)
    if det < 0:
        tri = tri[:, [0, 2, 1]]
    return wpos, wn.astype(np.float32), wt, tri


def place(r, node_i: int, pos, nrm, tan, tri, worlds: list[np.ndarray]):
    """(positions, normals, tangents or None, triangles) in world space: positions and tangents' xyz
    by each matrix of ``worlds``, normals by its inverse transpose, the winding reversed and the
    tangents' ``w`` flipped where its determinant is negative (spec 3.7.4); several matrices (GPU
    instances) give one copy each, concatenated (triangles offset)."""
    parts = [_place_one(r, node_i, pos, nrm, tan, tri, w) for w in worlds]
    if len(parts) == 1:
        return parts[0]
    n = pos.shape[0]
    return (np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]),
            None if tan is None else np.concatenate([p[2] for p in parts]),
            np.concatenate([p[3] + k * n for k, p in enumerate(parts)]))


# ------------------------------------------------------------------------------------------------
# Variants and images
# ------------------------------------------------------------------------------------------------

def variant_names(doc: dict) -> tuple[str, ...]:
    """``KHR_materials_variants``' variant names in index order (empty without the extension)."""
    vs = doc.get("extensions", {}).get("KHR_materials_variants", {}).get("variants", [])
    return tuple(str(v.get("name", f"variant{k}")) if isinstance(v, dict) else f"variant{k}"
                 for k, v in enumerate(vs if isinstance(vs, list) else []))


def variant_index(r, name: str | None) -> int | None:
    """The index of variant ``name`` (None: the default materials); raises naming the variants."""
    if name is None:
        return None
    names = variant_names(r.doc)
    if name not in names:
        from .fmt import terminal_safe
        listed = ", ".join(terminal_safe(n) for n in names) or "none"
        raise r.err("/extensions/KHR_materials_variants/variants",
                    f"no material variant {terminal_safe(name)!s} (the file's variants: {listed})")
    return names.index(name)


def variant_material(r, prim: dict, pp: str, variant: int | None) -> int:
    """The material index a primitive draws with under variant index ``variant`` (-1: the default)."""
    default = prim.get("material", -1)
    if variant is None:
        return int(default)
    maps = prim.get("extensions", {}).get("KHR_materials_variants", {}).get("mappings", [])
    for k, m in enumerate(maps if isinstance(maps, list) else []):
        if isinstance(m, dict) and variant in m.get("variants", []):
            mat = m.get("material")
            r.get("materials", mat, f"{pp}/extensions/KHR_materials_variants/mappings/{k}/material")
            return int(mat)
    return int(default)


def texture_source(r, tex: dict, tp: str) -> int:
    """The image index texture ``tex`` reads: ``EXT_texture_webp``'s source, else
    ``KHR_texture_basisu``'s, else the core ``source`` (module docstring)."""
    ext = tex.get("extensions", {}) if isinstance(tex.get("extensions"), dict) else {}
    for name in ("EXT_texture_webp", "KHR_texture_basisu"):
        e = ext.get(name)
        if isinstance(e, dict) and "source" in e:
            r.get("images", e["source"], f"{tp}/extensions/{name}/source")
            return e["source"]
    if "source" not in tex:
        raise r.err(tp, "a texture without source")
    r.get("images", tex["source"], tp + "/source")
    return tex["source"]


def decode_ktx2(r, data: bytes, pointer: str, source: str) -> np.ndarray:
    """Level 0 of a KTX2 image with a Basis Universal payload (``KHR_texture_basisu``) as (H, W, 4)
    uint8, row 0 at the top as KTX2 stores it (its default orientation, ``rd``, is glTF's)."""
    try:
        import opengl_basisu
    except ImportError:  # a declared dependency; a broken install is named, not a traceback
        raise r.err(pointer, "KTX2 images need the opengl_basisu package (pip install --pre opengl_basisu)") from None
    try:
        tex = opengl_basisu.open(bytes(data))
        px = tex.transcode(opengl_basisu.Target.RGBA8).data
    except Exception as e:  # noqa: BLE001 - BasisuError (a ValueError) and others on corrupt data
        msg = str(e).splitlines()[0] if str(e) else ""
        raise r.err(pointer, f"undecodable KTX2 texture image {source!r} ({type(e).__name__}: {msg})") from None
    return np.ascontiguousarray(np.asarray(px, np.uint8).reshape(tex.height, tex.width, 4))


def used_images(materials) -> set[int]:
    """Images read by any material's textures (the only ones the loader decodes)."""
    return {t.image for m in materials for t in m.textures().values()}


# ------------------------------------------------------------------------------------------------
# Export
# ------------------------------------------------------------------------------------------------

def export_selection(doc: dict, variant: str | None) -> dict:
    """``doc`` (a copy of the asset's JSON, edited in place and returned) made to draw what the
    loader draws, whatever an engine supports: under ``variant`` every primitive's ``material`` is
    the variant's (the extension kept: the selected variant becomes the file's default); a node
    hidden by ``KHR_node_visibility`` and its descendants lose their ``mesh`` and
    ``KHR_lights_punctual`` light (an engine without the extension would draw them). Skins, morph
    targets and GPU instances stay as they are: engines apply them as the loader does."""
    names = variant_names(doc)
    if variant is not None and variant in names:
        k = names.index(variant)
        for mesh in doc.get("meshes", []):
            for prim in mesh.get("primitives", []):
                maps = prim.get("extensions", {}).get("KHR_materials_variants", {}).get("mappings", [])
                for m in maps:
                    if k in m.get("variants", []) and "material" in m:
                        prim["material"] = m["material"]
                        break
    nodes = doc.get("nodes", [])
    hidden = [i for i, n in enumerate(nodes)
              if n.get("extensions", {}).get("KHR_node_visibility", {}).get("visible", True) is False]
    stack, seen = list(hidden), set()
    while stack:
        i = stack.pop()
        if i in seen or not 0 <= i < len(nodes):
            continue
        seen.add(i)
        nodes[i].pop("mesh", None)
        nodes[i].pop("skin", None)
        nodes[i].pop("weights", None)
        ext = nodes[i].get("extensions", {})
        ext.pop("KHR_lights_punctual", None)
        ext.pop("EXT_mesh_gpu_instancing", None)
        stack.extend(nodes[i].get("children", []))
    return doc


def restore_node_weights(doc: dict, raw: bytes) -> None:
    """Put back the nodes' ``weights`` (morph weights overriding the mesh's, spec 5.25) that the
    reader's round trip through pygltflib drops (its ``Node`` has no such field), from the file's
    own JSON (``raw``: the .gltf text or the .glb bytes, whose JSON chunk starts at byte 20)."""
    try:
        text = raw[20:20 + int.from_bytes(raw[12:16], "little")] if raw[:4] == b"glTF" else raw
        nodes = json.loads(text.decode("utf-8")).get("nodes", [])
    except Exception:  # noqa: BLE001 - the reader has parsed it already; nothing to restore
        return
    for node, src in zip(doc.get("nodes", []), nodes if isinstance(nodes, list) else []):
        if isinstance(node, dict) and isinstance(src, dict) and "weights" in src:
            node["weights"] = src["weights"]


def meshopt_view(r, v: dict, index: int) -> tuple[bytes, int, int, int | None] | None:
    """``(data, 0, byte length, byte stride)`` of buffer view ``v`` (index ``index``) decoded from
    its ``EXT_meshopt_compression`` (module docstring), or None without the extension. Decoded once
    per reader."""
    ext = v.get("extensions", {}).get("EXT_meshopt_compression") if isinstance(v.get("extensions"), dict) else None
    if ext is None:
        return None
    cache = r.__dict__.setdefault("_meshopt_views", {})
    if index in cache:
        return cache[index]
    p = f"/bufferViews/{index}/extensions/EXT_meshopt_compression"
    if not isinstance(ext, dict):
        raise r.err(p, "an object")
    mode, filt = ext.get("mode"), ext.get("filter", "NONE")
    if mode not in MESHOPT_MODES:
        raise r.err(p + "/mode", f"one of {', '.join(MESHOPT_MODES)}, found {mode!r}")
    if filt not in MESHOPT_FILTERS:
        raise r.err(p + "/filter", f"one of {', '.join(MESHOPT_FILTERS)}, found {filt!r}")
    fields = {}
    for k in ("count", "byteStride", "byteLength"):
        x = ext.get(k)
        if isinstance(x, bool) or not isinstance(x, int) or x < (0 if k == "count" else 1):
            raise r.err(f"{p}/{k}", f"an integer >= {0 if k == 'count' else 1}, found {x!r}")
        fields[k] = x
    off = ext.get("byteOffset", 0)
    if isinstance(off, bool) or not isinstance(off, int) or off < 0:
        raise r.err(p + "/byteOffset", f"an integer >= 0, found {off!r}")
    data = r.buffer(ext.get("buffer", -1), p + "/buffer")
    if off + fields["byteLength"] > len(data):
        raise r.err(p, f"byte range [{off}, {off + fields['byteLength']}) outside its buffer of {len(data)} bytes")
    try:
        import meshopt
    except ImportError:  # a declared dependency; a broken install is named, not a traceback
        raise r.err(p, "EXT_meshopt_compression needs the meshopt package (pip install meshopt)") from None
    count, stride = fields["count"], fields["byteStride"]
    try:
        out = meshopt.decode_gltf_buffer(bytes(data[off:off + fields["byteLength"]]), count, stride, mode,
                                         None if filt == "NONE" else filt)
    except Exception as e:  # noqa: BLE001 - the decoder raises ValueError / RuntimeError on corrupt data
        raise r.err(p, f"undecodable meshopt data ({type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''})") from None
    raw = np.ascontiguousarray(out).tobytes()
    cache[index] = (raw, 0, len(raw), v.get("byteStride"))
    return cache[index]
