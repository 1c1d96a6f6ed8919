"""glTF assets in resolved scenes: what ``check-scene`` prints about them, the ray-cast pipeline's
refusal of asset scenes.

API
---
- :func:`describe` -- ``check-scene``'s lines: meshes, triangles, materials, textures, lights, camera,
  extensions used and ignored.
- :func:`require_analytic`, :class:`UnsupportedSceneError`, :data:`RASTER_MISSING` -- the ray-cast
  pipeline's one-line refusal of meshes (``pipeline=raycast``; ``auto`` rasterizes them).
- :func:`scene_has_assets`, :func:`framing_camera`; re-exported: :class:`~pbrcheck.gltf_objects.Mesh`,
  :class:`~pbrcheck.gltf_objects.AssetInstance`, :func:`~pbrcheck.scene.asset_scene`,
  :class:`~pbrcheck.gltf_objects.AssetOptions`, :func:`~pbrcheck.gltf_objects.parse_size`,
  :func:`~pbrcheck.gltf_objects.is_asset_path`.
"""

from __future__ import annotations

from .gltf import AssetError
from .gltf_objects import (AssetInstance, AssetOptions, Mesh, framing, is_asset_path,  # noqa: F401
                           parse_size)
from .scene import Camera, Scene, asset_scene  # noqa: F401


def scene_has_assets(scene: Scene) -> bool:
    return bool(getattr(scene, "assets", ()))


def framing_camera(lo, hi, width: int, height: int) -> Camera:
    """model-viewer's default framing of the box [lo, hi] (:func:`pbrcheck.gltf_objects.framing`)."""
    origin, target, fov = framing(lo, hi, width, height)
    return Camera(origin=origin, target=target, up=(0.0, 1.0, 0.0), fov=fov, width=width, height=height)


def describe(scene: Scene) -> list[str]:
    """``check-scene``'s lines for the scene's assets: meshes, triangles, materials, textures (size,
    colour space, slot), lights, camera, extensions used and ignored."""
    from .gltf import SRGB_SLOTS
    from .lobe_params import describe_lobes
    from .transmission_params import describe_transmission

    out: list[str] = []
    for k, inst in enumerate(scene.assets):
        a = inst.asset
        out.append(f"# asset {k}: {inst.path} (glTF scene {a.scene}; translation {list(inst.translation)}, "
                   f"rotation {list(inst.rotation)} deg XYZ, scale {list(inst.scale)})")
        out.append(f"#   {len(a.primitives)} primitive(s), {a.triangles} triangles; objects (node/mesh/primitive):")
        for o in scene.objects:
            if isinstance(o, Mesh) and o.instance == k:
                p = a.primitives[o.primitive]
                extra = [s for s, on in (("flat normals", p.flat_normals), ("generated tangents", p.generated_tangents),
                                         ("TANGENT", p.tangents is not None and not p.generated_tangents),
                                         ("TEXCOORD_1", p.texcoords[1] is not None), ("COLOR_0", p.color is not None),
                                         ("skinned", p.skinned), (f"morph weights {list(p.morph_weights)}", p.morph_weights),
                                         (f"{p.instances} instances", p.instances > 1)) if on]
                out.append(f"#     object {o.id} {o.name}: {p.triangles} triangles, material "
                           f"{a.material(p.material).name!r}" + (f" ({', '.join(extra)})" if extra else ""))
        out.append(f"#   {len(a.materials)} material(s):")
        for i, m in enumerate(a.materials):
            tex = ", ".join(f"{s}=image{t.image}/uv{t.texcoord}" + (" +transform" if t.transform else "")
                            for s, t in m.textures().items())
            out.append(f"#     {i} {m.name!r}: baseColor {list(m.base_color)}, metallic {m.metallic}, roughness "
                       f"{m.roughness}, emissive {list(m.emissive)}, ior {m.ior}, alpha {m.alpha_mode}"
                       + (f" (cutoff {m.alpha_cutoff})" if m.alpha_mode == "MASK" else "")
                       + (", double-sided" if m.double_sided else "") + (", unlit" if m.unlit else "")
                       + (f"; textures {tex}" if tex else ""))
            lobes = describe_lobes(m)   # KHR_materials_clearcoat, sheen, ... (pbrcheck.lobe_params)
            if lobes:
                out.append(f"#       lobes: {lobes}")
            trans = describe_transmission(m)   # KHR_materials_transmission, volume, ... (issue 37)
            if trans:
                out.append(f"#       transmission: {trans}")
        slots = a.texture_slots()
        out.append(f"#   {len(a.images)} texture image(s):")
        for i, im in enumerate(a.images):
            used = slots.get(i, [])
            srgb = any(u.split(":")[-1] in SRGB_SLOTS for u in used)
            lin = any(u.split(":")[-1] not in SRGB_SLOTS for u in used)
            space = "sRGB and linear" if srgb and lin else "sRGB" if srgb else "linear" if lin else "unused"
            if not im.decoded:
                out.append(f"#     image{i} {im.source} ({im.mime}): not decoded (no modelled texture reads it)")
                continue
            out.append(f"#     image{i} {im.source} ({im.mime}): {im.size[0]}x{im.size[1]}, {im.pixels.shape[2] if im.pixels.ndim == 3 else 1} "
                       f"channel(s), {space}; slots {', '.join(used) or 'none'}")
        out.append(f"#   lights: {len(a.lights)}" + "".join(f"; {_light_line(L)}" for L in a.lights))
        out.append(f"#   cameras: {len(a.cameras)}" + (f" (the first, {a.cameras[0].name!r}, is the scene's camera "
                                                       "when the asset is the scene)" if a.cameras else ""))
        if a.variants:
            from .fmt import terminal_safe
            shown = terminal_safe(a.variant) if a.variant is not None else "none: the default materials"
            out.append(f"#   material variants (--variant NAME): {', '.join(terminal_safe(v) for v in a.variants)}; "
                       f"drawn: {shown}")
        out.append(f"#   extensions used: {', '.join(a.extensions_used) or 'none'}; ignored: "
                   f"{', '.join(a.extensions_ignored) or 'none'}")
    c = scene.camera
    out.append(f"# camera: origin {[round(x, 6) for x in c.origin]}, target {[round(x, 6) for x in c.target]}, "
               f"horizontal fov {c.fov:.4g} deg, {c.width}x{c.height}")
    return out


#: The one-line reason the ray-cast pipeline cannot render an asset scene (the raster pipeline can).
RASTER_MISSING = ("the real-time pipeline=raycast ray-casts analytic spheres and planes only; glTF meshes need "
                  "pipeline=raster (or auto)")


class UnsupportedSceneError(AssetError):
    """A renderer that cannot render a scene holding glTF assets."""


def require_analytic(scene: Scene, renderer: str) -> None:
    """Raise :class:`UnsupportedSceneError` when ``scene`` holds glTF assets (``renderer`` names who asks)."""
    if scene_has_assets(scene):
        raise UnsupportedSceneError(scene.source, "", f"{renderer}: {RASTER_MISSING}")


def _light_line(L) -> str:
    """One glTF light of ``check-scene``: type, intensity (cd or lux) x colour, where it is and points
    (the asset's world space, before the scene's placement), the spot's cone."""
    r = lambda v: [round(x, 6) for x in v]  # noqa: E731
    unit = "lux" if L.type == "directional" else "cd"
    where = "" if L.type == "directional" else f" at {r(L.position)}"
    aim = "" if L.type == "point" else f" towards {r(L.direction)}"
    cone = (f", cone {L.inner_cone:.6g}..{L.outer_cone:.6g} rad" if L.type == "spot" else "")
    rng = f", range {L.range} ignored" if L.range is not None and L.type != "directional" else ""
    return f"{L.name} {L.type} {L.intensity:.6g} {unit} x {list(L.color)}{where}{aim}{cone}{rng}"
