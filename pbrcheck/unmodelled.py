"""The honesty contract for what pbrcheck does not model: every glTF feature (extension) an asset uses
that neither renderer models is recorded as data, named once per asset on stderr, kept out of the
gate's verdict, and removed from what the engines get.

A feature is *unmodelled* when it is in the asset's ``extensionsUsed`` (or appears in an
``extensions`` object of the document without being declared there) and not in
:data:`pbrcheck.gltf.SUPPORTED_EXTENSIONS` (the one list of what the loader models; it grows as
features are modelled), or when it is a core feature of :data:`CORE_FEATURES` (skins, morph
targets) that a primitive uses and :data:`pbrcheck.gltf.MODELLED_CORE_FEATURES` does not list. An unmodelled ``extensionsRequired`` entry never gets this far: the loader
refuses the asset. For each feature the record names the materials it touches (a material whose
own ``extensions`` or texture slots use it, a material of a primitive or node that carries it, a
material reading a texture that carries it) and the objects: in :attr:`pbrcheck.gltf.Asset.unmodelled`
the indices into the asset's primitives, in :attr:`pbrcheck.scene.Scene.unmodelled` the scene's
object ids (the ``object`` AOV). A feature found nowhere more specific (a root-level extension, one
on buffers or images only) touches the whole asset: every primitive, every material.

The transmission extensions (:data:`pbrcheck.transmission_params.MODELLED_TRANSMISSION_EXTENSIONS`) are
modelled, except on a glTF material the reference's path mode renders opaque
(:func:`pbrcheck.transmission_params.reference_renders` false: its alpha mode, unlit, a texture it does
not read per hit): there the extension the material uses is recorded for that material alone, its
notice saying why (:func:`pbrcheck.transmission_params.reference_refusal`). Conversely, on a material
the reference renders transmissive, the lobe extensions its transmissive BSDF does not take
(:func:`pbrcheck.transmission_params.lobes_left_out`: clearcoat, sheen, KHR_materials_specular,
anisotropy; modelled on opaque materials) are recorded for that material alone
(:func:`transmissive_lobes_left_out`, notice :data:`TRANSMISSIVE_LOBE`).

API
---
- :data:`CORE_FEATURES` -- the core (non-extension) features checked; :data:`METADATA_EXTENSIONS` --
  extensions that never change the image (never unmodelled).
- :func:`materials_text` -- a record's material names for one line.
- :class:`Unmodelled` -- one feature: ``feature``, ``materials`` (names), ``objects``, ``asset`` (path).
- :func:`asset_unmodelled` -- the records of one parsed glTF document (the loader calls it).
- :func:`scene_unmodelled` -- the records of a scene (object ids, the asset's path).
- :func:`notice_lines` -- the stderr lines naming an asset's unmodelled features.
- :func:`start_notices`, :func:`stop_notices`, :func:`announce` -- the one place those lines are
  printed: the CLI starts the notices for one command; the loader announces every asset it returns;
  each asset (path, content hash) is named once per command; :func:`announce_scene` likewise for a
  scene file's analytic objects whose lobe fields use an unmodelled extension.
- :func:`strip_unmodelled` -- remove the unmodelled material extensions from a glTF document
  (``pbrcheck export`` and the external engines' export, unless ``--keep-unmodelled``).

References: Khronos glTF 2.0 specification (2021), section 3.12 (extensions: ``extensionsUsed``,
``extensionsRequired``, ``extensions`` objects on any property); issue 35 (features dropped silently).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

from .fmt import terminal_safe
from .lobe_params import MODELLED_LOBE_EXTENSIONS, scene_features
from .transmission_params import (MODELLED_TRANSMISSION_EXTENSIONS, REFERENCE_RENDERED, TRANSMISSION_EXTENSIONS,
                                  lobes_left_out, reference_refusal, reference_renders,
                                  scene_features as transmission_scene_features)


@dataclass(frozen=True)
class Unmodelled:
    """One feature an asset uses that pbrcheck does not model (module docstring)."""
    feature: str
    materials: tuple[str, ...] = ()
    objects: tuple[int, ...] = ()
    asset: str = ""


def _extension_names(x, out: set[str]) -> None:
    """Every key of every ``extensions`` object under ``x`` (``extras`` is the user's, skipped)."""
    if isinstance(x, dict):
        for k, v in x.items():
            if k == "extras":
                continue
            if k == "extensions" and isinstance(v, dict):
                out.update(str(e) for e in v)
            _extension_names(v, out)
    elif isinstance(x, list):
        for v in x:
            _extension_names(v, out)


def _texture_indices(x, out: set[int]) -> None:
    """The ``index`` of every textureInfo under a material (any key ending in ``Texture``)."""
    if isinstance(x, dict):
        for k, v in x.items():
            if k == "extras":
                continue
            if isinstance(k, str) and k.endswith("Texture") and isinstance(v, dict) \
                    and isinstance(v.get("index"), int) and not isinstance(v.get("index"), bool):
                out.add(v["index"])
            _texture_indices(v, out)
    elif isinstance(x, list):
        for v in x:
            _texture_indices(v, out)


def _names(x) -> set[str]:
    out: set[str] = set()
    _extension_names(x, out)
    return out


def _list(doc: dict, key: str) -> list:
    v = doc.get(key, [])
    return v if isinstance(v, list) else []


#: Core glTF features (no extension) that change the image, by name: whether one primitive uses it,
#: given (node, mesh primitive). A feature here that the loader does not list in its modelled core
#: features (:data:`pbrcheck.gltf.MODELLED_CORE_FEATURES`) is unmodelled like an extension.
CORE_FEATURES = {
    "skins": lambda node, prim: "skin" in node,                           # spec 3.7.3: the pose
    "morph targets": lambda node, prim: bool(prim.get("targets")),        # spec 3.7.2.2: default weights
}


#: Extensions whose specifications give them no effect on the image (metadata: XMP packets): never
#: unmodelled.
METADATA_EXTENSIONS = ("KHR_xmp", "KHR_xmp_json_ld")


def _node_prim(doc: dict, p) -> tuple[dict, dict, dict]:
    """(node, mesh, mesh primitive) of a loaded primitive ``p`` (empty where malformed)."""
    nodes, meshes = _list(doc, "nodes"), _list(doc, "meshes")
    node = nodes[p.node] if 0 <= p.node < len(nodes) and isinstance(nodes[p.node], dict) else {}
    mesh = meshes[p.mesh] if 0 <= p.mesh < len(meshes) and isinstance(meshes[p.mesh], dict) else {}
    prims = mesh.get("primitives", []) if isinstance(mesh.get("primitives"), list) else []
    prim = prims[p.primitive] if 0 <= p.primitive < len(prims) and isinstance(prims[p.primitive], dict) else {}
    return node, mesh, prim


def _record(feature, objs: set, mats: set, primitives, material_names) -> Unmodelled:
    mats = mats | {p.material for k, p in enumerate(primitives) if k in objs and p.material >= 0}
    names = tuple(dict.fromkeys(str(material_names[i]) for i in sorted(mats) if 0 <= i < len(material_names)))
    return Unmodelled(feature, names, tuple(sorted(objs)))


def asset_unmodelled(doc: dict, primitives, material_names, modelled, modelled_core=(),
                     materials=()) -> tuple[Unmodelled, ...]:
    """The unmodelled features of glTF document ``doc``: ``primitives`` are the loaded primitives
    (``node``, ``mesh``, ``primitive``, ``material`` attributes; their index is the record's
    object), ``material_names`` the loaded materials' names, ``modelled`` the extensions modelled,
    ``modelled_core`` the :data:`CORE_FEATURES` modelled, ``materials`` the loaded materials (for the
    modelled transmission extensions on materials the reference renders opaque:
    :func:`transmission_refused`). Extensions in ``extensionsUsed``'s order, then the undeclared ones
    sorted, then the refused transmission extensions, then the core features."""
    used = [str(e) for e in _list(doc, "extensionsUsed")]
    found = _names(doc)
    features = [e for e in dict.fromkeys(used + sorted(found - set(used)))
                if e not in modelled and e not in METADATA_EXTENSIONS]
    core = []
    for name, uses in CORE_FEATURES.items():
        if name not in modelled_core:
            objs = {k for k, (node, _, prim) in enumerate(_node_prim(doc, p) for p in primitives) if uses(node, prim)}
            if objs:
                core.append(_record(name, objs, set(), primitives, material_names))
    refused = transmission_refused(primitives, materials, modelled, material_names)
    refused += transmissive_lobes_left_out(primitives, materials, modelled, material_names)
    if not features:
        return tuple(refused + core)
    materials = _list(doc, "materials")
    textures = _list(doc, "textures")
    mat_ext = [_names(m) for m in materials]
    mat_tex = []
    for m in materials:
        s: set[int] = set()
        _texture_indices(m, s)
        mat_tex.append(s)
    tex_ext = [_names(t) for t in textures]
    out = []
    for f in features:
        mats = {i for i, e in enumerate(mat_ext) if f in e}
        mats |= {i for i, ts in enumerate(mat_tex) if any(0 <= t < len(tex_ext) and f in tex_ext[t] for t in ts)}
        objs = {k for k, p in enumerate(primitives) if p.material in mats}
        for k, p in enumerate(primitives):
            node, mesh, prim = _node_prim(doc, p)
            if f in _names({"extensions": node.get("extensions", {})}) or f in _names(prim) \
                    or f in _names({"extensions": mesh.get("extensions", {})}):
                objs.add(k)
        if not mats and not objs:  # a root-level (or buffer / image-only) feature: the whole asset
            objs = set(range(len(primitives)))
        out.append(_record(f, objs, mats, primitives, material_names))
    return tuple(out + refused + core)


def transmission_refused(primitives, materials, modelled, material_names) -> list[Unmodelled]:
    """The modelled transmission extensions (in ``modelled``) on loaded glTF ``materials`` the
    reference's path mode renders opaque (:func:`pbrcheck.transmission_params.reference_refusal`): one
    record per extension, naming those materials and their primitives."""
    out = []
    for ext, (field, _) in TRANSMISSION_EXTENSIONS.items():
        if ext not in modelled or ext not in MODELLED_TRANSMISSION_EXTENSIONS:
            continue
        mats = {i for i, m in enumerate(materials) if getattr(m, field, None) is not None and reference_refusal(m)}
        if mats:
            objs = {k for k, p in enumerate(primitives) if p.material in mats}
            out.append(_record(ext, objs, mats, primitives, material_names))
    return out


def transmissive_lobes_left_out(primitives, materials, modelled, material_names) -> list[Unmodelled]:
    """The modelled lobe extensions (in ``modelled``) on loaded glTF ``materials`` the reference renders
    with its transmissive BSDF, which leaves them out (:func:`pbrcheck.transmission_params.lobes_left_out`):
    one record per extension, naming those materials and their primitives."""
    left = {i: lobes_left_out(m) for i, m in enumerate(materials)}
    out = []
    for ext in dict.fromkeys(e for es in left.values() for e in es):
        if ext not in modelled:   # unmodelled everywhere: asset_unmodelled names it already
            continue
        mats = {i for i, es in left.items() if ext in es}
        objs = {k for k, p in enumerate(primitives) if p.material in mats}
        out.append(_record(ext, objs, mats, primitives, material_names))
    return out


def scene_unmodelled(scene) -> tuple[Unmodelled, ...]:
    """The unmodelled features of every glTF asset of ``scene``, ``objects`` as scene object ids
    (an instance's primitive ``k`` is object ``first_id + k``), ``asset`` the file's path; then
    those of the scene file's analytic objects: a material whose lobe fields (``clearcoat``,
    ``sheen_color``, ...: :mod:`pbrcheck.lobe_params`) differ from their neutral values uses that
    extension, unmodelled while :data:`pbrcheck.lobe_params.MODELLED_LOBE_EXTENSIONS` and
    :data:`pbrcheck.transmission_params.MODELLED_TRANSMISSION_EXTENSIONS` (parts of
    :data:`pbrcheck.gltf.MODELLED_EXTENSIONS`) lack it (transmission fields included) (``materials`` the objects' names, ``asset``
    the scene file)."""

    out = []
    for inst in getattr(scene, "assets", ()):
        for u in getattr(inst.asset, "unmodelled", ()) if inst.asset is not None else ():
            out.append(Unmodelled(u.feature, u.materials, tuple(inst.first_id + k for k in u.objects), inst.path))
    analytic: dict[str, list] = {}
    for o in getattr(scene, "objects", ()):
        if getattr(o, "type", "") in ("sphere", "plane"):
            for f in (*scene_features(o.material), *transmission_scene_features(o.material)):
                if f not in MODELLED_LOBE_EXTENSIONS and f not in MODELLED_TRANSMISSION_EXTENSIONS:
                    analytic.setdefault(f, []).append(o)
            for f in lobes_left_out(o.material):   # modelled, but not by the transmissive BSDF
                if f in MODELLED_LOBE_EXTENSIONS:
                    analytic.setdefault(f, []).append(o)
    for f, objs in analytic.items():
        out.append(Unmodelled(f, tuple(o.name for o in objs), tuple(o.id for o in objs), getattr(scene, "source", "")))
    return tuple(out)


#: Most material names one notice line lists before "and N more".
NOTICE_MAX_MATERIALS = 8


def materials_text(materials) -> str:
    """The material names of a record for one line: at most :data:`NOTICE_MAX_MATERIALS`, then
    "and N more"; control characters escaped."""
    names = [terminal_safe(m) for m in materials]
    if not names:
        return "the default material"
    more = len(names) - NOTICE_MAX_MATERIALS
    return ", ".join(names[:NOTICE_MAX_MATERIALS]) + (f" and {more} more" if more > 0 else "")


def notice_lines(asset) -> list[str]:
    """One stderr line per unmodelled feature of ``asset`` (a loaded :class:`pbrcheck.gltf.Asset`)."""
    name = terminal_safe(Path(asset.path).name)
    return [f"pbrcheck: {name}: not modelled: {terminal_safe(u.feature)} (materials: "
            f"{materials_text(u.materials)}): {_what_is_left_out(asset, u)}; "
            f"a gate check of it is not judged" for u in asset.unmodelled]


#: What a notice says of a transmission extension the reference renders (its path mode) while
#: :data:`pbrcheck.transmission_params.MODELLED_TRANSMISSION_EXTENSIONS` lacks it (the real-time
#: renderer no longer renders it): a state the honesty contract keeps a wording for.
PARTLY_RENDERED = "rendered in part: by the reference in path mode only, not by the real-time image"
#: What a notice says of a modelled transmission extension on a material the reference renders opaque.
REFERENCE_REFUSED = "the reference renders these materials opaque ({why})"
#: What a notice says of a modelled lobe extension on a material the reference renders transmissive.
TRANSMISSIVE_LOBE = "the reference's transmissive BSDF leaves it out on these transmissive materials"


def _what_is_left_out(asset, u) -> str:
    """Which images leave feature ``u`` out: both, except a transmission extension: modelled, the
    reference's refusal of its materials (:func:`pbrcheck.transmission_params.reference_refusal`); else
    :data:`PARTLY_RENDERED` where the reference's path mode renders every material (issue 37: constant
    factors or the textures it reads per hit, :func:`pbrcheck.transmission_params.reference_renders`)."""
    mats = [m for m in getattr(asset, "materials", ()) if m.name in u.materials]
    if u.feature in MODELLED_TRANSMISSION_EXTENSIONS:
        why = "; ".join(dict.fromkeys(terminal_safe(reference_refusal(m)) for m in mats if reference_refusal(m)))
        return REFERENCE_REFUSED.format(why=why or "its path mode does not take these materials")
    if u.feature in REFERENCE_RENDERED and mats and all(reference_renders(m) for m in mats):
        return PARTLY_RENDERED
    if u.feature in MODELLED_LOBE_EXTENSIONS and mats and all(u.feature in lobes_left_out(m) for m in mats):
        return TRANSMISSIVE_LOBE
    return "the reference and the real-time image leave it out"


_NOTICES: dict = {"on": False, "stream": None, "seen": set()}


def start_notices(stream=None) -> None:
    """Name each asset's unmodelled features on ``stream`` (default: ``sys.stderr`` at the time of
    printing) from now on, each asset once; the CLI calls it at the start of every command."""
    _NOTICES.update(on=True, stream=stream, seen=set())


def stop_notices() -> None:
    """No more notices (library use stays silent; the records are on the asset and the scene)."""
    _NOTICES.update(on=False, stream=None, seen=set())


def announce(asset):
    """Print ``asset``'s notice lines if notices are on and this asset (path, content hash) was not
    named yet in this command; returns ``asset``."""
    key = (asset.path, asset.content_hash)
    if _NOTICES["on"] and asset.unmodelled and key not in _NOTICES["seen"]:
        _NOTICES["seen"].add(key)
        stream = _NOTICES["stream"] or sys.stderr
        for line in notice_lines(asset):
            print(line, file=stream)
    return asset


def announce_scene(scene):
    """Print, like :func:`announce`, one line per unmodelled feature of ``scene``'s analytic objects
    (the lobe fields of :func:`scene_unmodelled`; the assets announce themselves), once per scene
    file and feature in a command; returns ``scene``."""
    if not _NOTICES["on"]:
        return scene
    stream = _NOTICES["stream"] or sys.stderr
    name = terminal_safe(Path(getattr(scene, "source", "")).name)
    for u in scene_unmodelled(scene):
        key = ("scene", getattr(scene, "source", ""), u.feature)
        if u.asset != getattr(scene, "source", None) or key in _NOTICES["seen"]:
            continue
        _NOTICES["seen"].add(key)
        # the transmission extensions of analytic objects: the reference's path mode renders them (issue 37);
        # named here only while MODELLED_TRANSMISSION_EXTENSIONS lacks them
        what = (PARTLY_RENDERED if u.feature in REFERENCE_RENDERED
                else TRANSMISSIVE_LOBE if u.feature in MODELLED_LOBE_EXTENSIONS   # recorded only there
                else "the reference and the real-time image leave it out")
        print(f"pbrcheck: {name}: not modelled: {terminal_safe(u.feature)} (objects: {materials_text(u.materials)}): "
              f"{what}; a gate check of it is not judged", file=stream)
    return scene


def strip_unmodelled(doc: dict, modelled) -> list[tuple[str, tuple[str, ...]]]:
    """Remove from glTF document ``doc`` (in place) every material extension not in ``modelled``,
    and from ``extensionsUsed`` / ``extensionsRequired`` every extension no longer present anywhere
    in the document. Returns [(feature, material names)] of what was removed, in first-seen order."""
    removed: dict[str, list[str]] = {}
    for i, m in enumerate(_list(doc, "materials")):
        ext = m.get("extensions") if isinstance(m, dict) else None
        if not isinstance(ext, dict):
            continue
        for e in [e for e in ext if e not in modelled]:
            del ext[e]
            removed.setdefault(e, []).append(str(m.get("name", f"material{i}")))
        if not ext:
            del m["extensions"]
    if removed:
        left = _names(doc)
        for key in ("extensionsUsed", "extensionsRequired"):
            if isinstance(doc.get(key), list):
                doc[key] = [e for e in doc[key] if e not in removed or e in left]
                if not doc[key]:
                    del doc[key]
    return [(e, tuple(ms)) for e, ms in removed.items()]
