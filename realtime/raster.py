"""The raster pipeline of the real-time renderer: glTF meshes (and tessellated analytic shapes) drawn
with a vertex and a fragment shader that includes the frame pass's shading module unchanged
(``shaders/raster.vert``, ``shaders/raster.frag``), so every preset, option, hook and energy
compensation applies as in the ray-cast compute pass.

Conventions (the same at both ends as :mod:`realtime.render`)
-------------------------------------------------------------
* Camera: :func:`pbrcheck.camera.camera_frame` / :func:`~pbrcheck.camera.tan_half_fov`; NDC (x, y) is
  the direction ``x tx r + y ty u + f`` of the reference's primary rays; the colour pass runs at
  ``(s W, s H)`` so its fragments are the compute pass's sub-pixel samples ``(k + 0.5) / s`` and the
  box filter averages them; the AOV pass runs at ``(W, H)`` (pixel centres). Images are read back
  with row 0 at the top (GL's row 0 is the bottom: flipped).
* Outputs: R, G, B (radiance), coverage (the fraction of samples covered by geometry; with BLEND
  the accumulated alpha ``a + (1 - a) dst``), N / NdotV (the interpolated vertex normal at the pixel
  centre, flipped on a double-sided back face; not the normal-mapped one), object (the id of the
  nearest primitive at the pixel centre, -1 background; BLEND primitives included).
* Geometry: each glTF primitive of :class:`pbrcheck.gltf.Primitive` placed by its instance's
  matrix (normals by the inverse transpose, tangents' w and the winding flipped where the
  determinant is negative); spheres tessellated as UV spheres of :data:`SPHERE_SEGMENTS` with exact
  normals, rectangles as two triangles; analytic shapes are drawn without culling (their back side
  shades black, as the compute pass's).
* Culling: back faces (counter-clockwise fronts) culled unless ``doubleSided``.
* Textures: RGBA16F with full mip chains (glGenerateMipmap, a box filter in linear space), baseColor
  and emissive sRGB-decoded before upload (:meth:`pbrcheck.gltf.GltfImage.linear`), the others
  linear; trilinear filtering, anisotropy the option ``anisotropy`` (1: off); REPEAT and
  CLAMP_TO_EDGE by the texture, MIRRORED_REPEAT folded in the shader; glTF samplers' min/mag
  filters are not followed (always trilinear). The occlusion texture (R, ``strength``) scales the
  image-based diffuse light and feeds the specular occlusion (``occlusion_texture``,
  ``specular_occlusion`` options; ``shaders/occlusion.glsl``).
* Alpha: OPAQUE, MASK (discard below ``alphaCutoff``), BLEND (after the opaque primitives, sorted
  back to front by the distance of each primitive's bounding-box centre, depth test without depth
  writes, ``src alpha, 1 - src alpha``).
* Transmission (``KHR_materials_transmission`` / ``_volume`` / ``_dispersion``; :mod:`realtime.transmission`,
  only where a material transmits): :func:`_opaque_pass` draws the background and the non-transmissive
  non-BLEND primitives into an RGBA32F texture of the colour pass's size with its full mip chain
  (``glGenerateMipmap``; GL orientation, row 0 at the bottom) on :data:`TRANSMISSION_UNIT`; the colour
  pass then draws the opaque primitives, the transmissive ones back to front (bounding-box centres),
  then BLEND; docs/realtime.md "Transmission".
* Point, spot and directional lights: unshadowed (``shadows`` is refused with this pipeline).
* Specular anti-aliasing (``specular_aa``, ``shaders/specular_aa.glsl``): ``prefiltered`` reads a
  companion R32F texture per normal map, :func:`normal_variance_texture`, whose level k holds the
  slope variance of the level-0 normals under each texel of the normal map's level k
  (:func:`pbrcheck.specular_aa.slope_variance_mips`), sampled trilinearly with the normal map's
  coordinates; ``toksvig`` reads the mip-filtered normal's length; ``screen_space`` the geometric
  normal's ``dFdx``/``dFdy`` in the colour pass (at its s W x s H resolution).
* MSAA (``msaa``): the colour pass renders into ``msaa``-sample colour and depth renderbuffers (one
  shading per fragment, coverage and depth per sample) resolved by ``glBlitFramebuffer`` (the
  average of the samples) before the s x s box filter: on top of supersampling, so ``supersample = 1,
  msaa = 4`` is MSAA alone and ``supersample = 2, msaa = 4`` 16 coverage samples per pixel, 4 shaded.
  ``msaa`` above the context's ``GL_MAX_SAMPLES`` raises :class:`pbrcheck.errors.BackendError`
  (llvmpipe: 4; exit 3, a limit of the GL backend) before any work (:func:`check_msaa`, called by
  :func:`realtime.render.render_realtime` before its bakes). The AOV pass stays single-sampled at the
  pixel centres.
* Alpha-to-coverage (``alpha_to_coverage``, needs ``msaa > 1``): MASK primitives are drawn with
  ``GL_SAMPLE_ALPHA_TO_COVERAGE`` and ``GL_SAMPLE_ALPHA_TO_ONE``, writing the sharpened alpha
  (``shaders/coverage.glsl``) instead of discarding below ``alphaCutoff``.

API
---
:func:`draw_items` (the scene's primitives as vertex arrays and materials), :func:`raster_frame`
(one frame: colour, AOV and object images), :func:`graphics_program`, :data:`VERTEX_LAYOUT`,
:data:`SPHERE_SEGMENTS`, :func:`tessellate_sphere`, :func:`normal_variance_texture`, :func:`max_msaa`,
:func:`check_msaa`, :func:`max_target_side`, :func:`check_target_size` (the colour pass's size against
this GL's limits, supersampling counted, before any bake: :class:`pbrcheck.limits.OutputSizeError`),
:func:`check_texture_sizes` (the assets' texture images against ``GL_MAX_TEXTURE_SIZE``).

References: Khronos glTF 2.0 specification (2021) sections 3.7, 3.8, 3.9; OpenGL 4.5 core
specification sections 14.6 (polygon rasterization, culling), 8.14 (mipmapping).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from pbrcheck.camera import camera_frame, tan_half_fov
from pbrcheck.errors import BackendError
from pbrcheck.gltf import WRAP_CLAMP, WRAP_MIRROR
from pbrcheck.scene import Material, Plane, Scene, plane_frame
from pbrcheck.specular_aa import slope_variance_mips

from .gl import ShaderCompileError, assemble, get_context, in_bands, map_errors, timed
from .lobes import sphere_tangent
from .material_lobes import (LOBE_TEXTURE_SLOTS, gltf_lobe_rows, material_active_lobes, scene_lobe_rows,
                             scene_material_active_lobes)
from .presets import bake_key
from .transmission import ior_from_f0

#: Interleaved vertex: position 3, normal 3, tangent 4, uv0 2, uv1 2, colour 4 (float32).
VERTEX_LAYOUT = ("3f 3f 4f 2f 2f 4f", "in_pos", "in_nrm", "in_tan", "in_uv0", "in_uv1", "in_col")
VERTEX_FLOATS = 18
#: (longitude, latitude) segments of a tessellated analytic sphere.
SPHERE_SEGMENTS = (256, 128)
#: Depth range: near = far x this (and at least the nearest vertex depth x 0.5 when positive).
NEAR_FAR_RATIO = 1e-4
#: Texture slots of raster.frag, in order: (glTF slot, sRGB).
TEXTURE_SLOTS = (("baseColor", True), ("metallicRoughness", False), ("normal", False), ("emissive", True))
#: First texture unit of the material textures (units 0-5 are the shading module's).
MATERIAL_UNIT0 = 6
TEXTURE_SLOTS_N = 4
#: Texture unit of the normal map's slope-variance companion (after the occlusion texture's).
NORMAL_VAR_UNIT = MATERIAL_UNIT0 + TEXTURE_SLOTS_N + 1
#: First texture unit of the lobe textures (raster.frag tex_lobe; after realtime.render.LOBE_TEXTURE_UNITS).
LOBE_UNIT0 = 14
#: The lobe factor rows of a material without lobes (realtime.material_lobes.LOBE_ROW_LAYOUT at the neutral values).
NEUTRAL_LOBE_ROWS = scene_lobe_rows(Material())
#: Texture unit of the opaque-pass framebuffer of transmission (after the lobe textures', LOBE_UNIT0 + 10).
TRANSMISSION_UNIT = 24
#: GL enums moderngl has no flag for (OpenGL 4.5 core, 14.9.3 multisample fragment operations).
GL_SAMPLE_ALPHA_TO_COVERAGE = 0x809E
GL_SAMPLE_ALPHA_TO_ONE = 0x809F
ALPHA_CODES = {"OPAQUE": 0, "MASK": 1, "BLEND": 2}

_programs: dict = {}
_textures: dict = {}


@dataclass
class DrawItem:
    """One primitive to draw: vertices (N, 18) float32, triangles (T, 3) uint32, its material."""
    object_id: int
    name: str
    vertices: np.ndarray
    indices: np.ndarray
    base_color: tuple = (1.0, 1.0, 1.0, 1.0)
    metallic: float = 0.0
    roughness: float = 0.5
    specular: float = 0.04
    emissive: tuple = (0.0, 0.0, 0.0)
    alpha_mode: str = "OPAQUE"
    alpha_cutoff: float = 0.5
    cull: bool = True
    flip_backface: bool = False
    normal_scale: float = 1.0
    textures: dict = field(default_factory=dict)   # slot -> (GltfImage, TextureRef, srgb)
    unlit: bool = False                             # KHR_materials_unlit (raster.frag's UNLIT_MATERIALS)
    lobe_rows: np.ndarray | None = None             # (4, 4) lobe factors (material_lobes.LOBE_ROW_LAYOUT); None: no lobe
    lobe_textures: dict = field(default_factory=dict)   # lobe slot -> (GltfImage, TextureRef, srgb)
    coat_normal_scale: float = 1.0
    # KHR_materials_transmission / volume / dispersion (realtime/transmission.py; 0: none)
    transmission: float = 0.0
    thickness: float = 0.0                          # world units
    attenuation_color: tuple = (1.0, 1.0, 1.0)
    attenuation_distance: float = 0.0               # 0: none
    dispersion: float = 0.0
    diffuse_transmission: float = 0.0               # KHR_materials_diffuse_transmission
    diffuse_transmission_color: tuple = (1.0, 1.0, 1.0)
    transmission_textures: dict = field(default_factory=dict)   # "transmission" (R) / "thickness" (G) -> (GltfImage, TextureRef, srgb)

    @property
    def centre(self) -> np.ndarray:
        p = self.vertices[:, :3]
        return 0.5 * (p.min(axis=0) + p.max(axis=0))


def graphics_program(vert: str, frag: str, defines: dict | None = None, user: tuple[str, str] | None = None):
    """Compiled (cached) vertex + fragment program (sources assembled as :func:`realtime.gl.assemble`)."""
    vs, fs = assemble(vert, defines), assemble(frag, defines, user)
    key = (vs.text, fs.text)  # the texts, not the file names: an edited file is compiled again
    if key in _programs:
        return _programs[key]
    try:
        prog = get_context().program(vertex_shader=vs.text, fragment_shader=fs.text)
    except Exception as e:
        msg = str(e)
        raise ShaderCompileError(f"{frag}: GLSL compile failed: {map_errors(msg, fs)}", user=user is not None) from None
    _programs[key] = prog
    return prog


def _vertices(pos, nrm, tan=None, uv0=None, uv1=None, col=None) -> np.ndarray:
    n = len(pos)
    v = np.zeros((n, VERTEX_FLOATS), np.float32)
    v[:, 0:3], v[:, 3:6] = pos, nrm
    v[:, 6:10] = tan if tan is not None else (1.0, 0.0, 0.0, 1.0)
    if uv0 is not None:
        v[:, 10:12] = uv0
    if uv1 is not None:
        v[:, 12:14] = uv1
    v[:, 14:18] = col if col is not None else 1.0
    return v


def tessellate_sphere(center, radius: float, segments=SPHERE_SEGMENTS) -> tuple[np.ndarray, np.ndarray]:
    """(positions, normals, triangles) of a UV sphere, counter-clockwise seen from outside."""
    nu, nv = segments
    th = np.linspace(0.0, math.pi, nv + 1)
    ph = np.linspace(0.0, 2 * math.pi, nu + 1)
    T, P = np.meshgrid(th, ph, indexing="ij")
    n = np.stack([np.sin(T) * np.cos(P), np.cos(T), -np.sin(T) * np.sin(P)], axis=-1).reshape(-1, 3)
    idx = np.arange((nv + 1) * (nu + 1)).reshape(nv + 1, nu + 1)
    a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
    tri = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    # orient every triangle counter-clockwise seen from outside (drop the degenerate pole ones)
    p = n * radius + np.asarray(center, float)
    e = np.cross(p[tri[:, 1]] - p[tri[:, 0]], p[tri[:, 2]] - p[tri[:, 0]])
    area = np.linalg.norm(e, axis=1)
    keep = area > 1e-14 * radius * radius
    tri = tri[keep]
    outward = np.einsum("ij,ij->i", e[keep], n[tri].mean(axis=1)) > 0
    tri[~outward] = tri[~outward][:, ::-1]
    return p.astype(np.float32), n.astype(np.float32), tri.astype(np.uint32)


def draw_items(scene: Scene) -> list[DrawItem]:
    """Every object of ``scene`` as a :class:`DrawItem` (glTF primitives placed; analytic shapes tessellated)."""
    out = []
    for ob in scene.objects:
        if getattr(ob, "type", "") == "mesh":
            inst = scene.assets[ob.instance]
            prim = inst.asset.primitives[ob.primitive]
            m = inst.asset.material(ob.gltf_material) if ob.gltf_material >= 0 else inst.asset.material(-1)
            M = inst.matrix()
            A = M[:3, :3]
            det = float(np.linalg.det(A))
            pos = prim.positions.astype(np.float64) @ A.T + M[:3, 3]
            nrm = prim.normals.astype(np.float64) @ np.linalg.inv(A)
            nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-30)
            tan = None
            if prim.tangents is not None:
                t = prim.tangents[:, :3].astype(np.float64) @ A.T
                t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-30)
                tan = np.concatenate([t, prim.tangents[:, 3:4] * (1.0 if det >= 0 else -1.0)], axis=1)
            tri = prim.indices if det >= 0 else prim.indices[:, ::-1]
            tex = {}
            refs = m.textures()
            for slot, srgb in (*TEXTURE_SLOTS, ("occlusion", False)):
                ref = refs.get(slot)
                if ref is not None:
                    tex[slot] = (inst.asset.images[ref.image], ref, srgb)
            lobes = {}
            if material_active_lobes(m):
                rows, ltex = gltf_lobe_rows(m)
                cn = ltex.get("clearcoatNormal")
                lobes = dict(lobe_rows=rows, coat_normal_scale=cn[0].scale if cn is not None else 1.0,
                             lobe_textures={k: (inst.asset.images[r.image], r, srgb) for k, (r, srgb) in ltex.items()})
            lobes.update(_gltf_transmission(m, A, inst.asset.images))
            out.append(DrawItem(
                ob.id, ob.name, _vertices(pos, nrm, tan, prim.texcoords[0], prim.texcoords[1], prim.color),
                np.ascontiguousarray(tri, np.uint32), tuple(m.base_color), m.metallic, m.roughness, m.specular,
                tuple(m.emissive), m.alpha_mode, m.alpha_cutoff, cull=not m.double_sided,
                flip_backface=m.double_sided,
                normal_scale=m.normal_texture.scale if m.normal_texture is not None else 1.0, textures=tex,
                unlit=m.unlit, **lobes))
            continue
        mat = ob.material
        common = dict(base_color=(*mat.base_color, 1.0), metallic=mat.metallic, roughness=mat.roughness,
                      specular=mat.specular, cull=False, flip_backface=False)
        if mat.transmission > 0.0 or mat.diffuse_transmission > 0.0:
            common.update(transmission=mat.transmission, thickness=mat.thickness,
                          attenuation_color=tuple(mat.attenuation_color),
                          attenuation_distance=mat.attenuation_distance, dispersion=mat.dispersion,
                          diffuse_transmission=mat.diffuse_transmission,
                          diffuse_transmission_color=tuple(mat.diffuse_transmission_color))
        lobed = bool(scene_material_active_lobes(mat))
        if lobed:
            common["lobe_rows"] = scene_lobe_rows(mat)
        if isinstance(ob, Plane):
            t, b, n = (np.asarray(x, float) for x in plane_frame(ob.normal))
            c = np.asarray(ob.center, float)
            hx, hy = 0.5 * ob.size[0] * t, 0.5 * ob.size[1] * b
            pos = np.array([c - hx - hy, c + hx - hy, c + hx + hy, c - hx + hy])
            tri = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
            if np.dot(np.cross(pos[1] - pos[0], pos[2] - pos[0]), n) < 0:
                tri = tri[:, ::-1].copy()
            tan = np.tile([*t, 1.0], (4, 1)) if lobed else None   # plane_frame's tangent, as the ray-cast pass
            out.append(DrawItem(ob.id, getattr(ob, "name", str(ob.id)), _vertices(pos, np.tile(n, (4, 1)), tan), tri,
                                **common))
        else:
            pos, nrm, tri = tessellate_sphere(ob.center, ob.radius)
            # the ray-cast pass's tangent frame (lobes_material.glsl sphere_tangent), w = 1
            tan = np.concatenate([sphere_tangent(nrm), np.ones((len(nrm), 1))], axis=1) if lobed else None
            out.append(DrawItem(ob.id, getattr(ob, "name", str(ob.id)), _vertices(pos, nrm, tan), tri, **common))
    return out


def _gltf_transmission(m, A: np.ndarray, images) -> dict:
    """A glTF material's transmission fields of :class:`DrawItem` (``{}`` without transmission): the
    factor and its texture (R), the volume's thickness in world units (the mesh-space ``thicknessFactor``
    times the mean length of the instance matrix's columns; the Sample Viewer scales the ray per axis)
    and its texture (G), the attenuation (an infinite distance as 0), the dispersion, the diffuse
    transmission's factors (its textures are not read)."""
    t = getattr(m, "transmission", None)
    dt = getattr(m, "diffuse_transmission", None)
    if (t is None or not t.active) and (dt is None or not dt.active):
        return {}
    out = {"transmission": float(t.factor) if t is not None and t.active else 0.0}
    tex = {}
    if t is not None and t.active and t.texture is not None:
        tex["transmission"] = (images[t.texture.image], t.texture, False)
    if dt is not None and dt.active:   # its textures are not read (factors only)
        out.update(diffuse_transmission=float(dt.factor), diffuse_transmission_color=tuple(dt.color))
    vol = getattr(m, "volume", None)
    if vol is not None and vol.active:
        scale = float(np.mean(np.linalg.norm(A, axis=0)))
        d = vol.attenuation_distance
        out.update(thickness=vol.thickness * scale, attenuation_color=tuple(vol.attenuation_color),
                   attenuation_distance=0.0 if math.isinf(d) else float(d))
        if vol.thickness_texture is not None:
            tex["thickness"] = (images[vol.thickness_texture.image], vol.thickness_texture, False)
    if tex:
        out["transmission_textures"] = tex
    disp = getattr(m, "dispersion", None)
    if disp is not None and disp.active:
        out["dispersion"] = float(disp.dispersion)
    return out


def _texture(image, ref, srgb: bool, anisotropy: float, times: dict | None = None):
    """The image as an RGBA16F texture with its full mip chain (cached per image, colour space, wrap).
    ``times``: adds the seconds of the upload (decode to linear half floats, the level-0 upload) to
    ``texture_upload`` and of the mip generation to ``texture_mips`` (each up to ``ctx.finish()``)."""
    key = bake_key("material_texture", id(image), srgb, ref.wrap, anisotropy=anisotropy)
    hit = _textures.get(key)
    if hit is not None and hit[0] is image:
        return hit[1]
    ctx = get_context()
    t0 = time.perf_counter()
    px = image.linear(srgb).astype(np.float16)
    h, w = px.shape[:2]
    tex = ctx.texture((w, h), 4, np.ascontiguousarray(px).tobytes(), dtype="f2")
    ctx.finish()
    t1 = time.perf_counter()
    tex.build_mipmaps()
    ctx.finish()
    if times is not None:
        times["texture_upload"] = times.get("texture_upload", 0.0) + t1 - t0
        times["texture_mips"] = times.get("texture_mips", 0.0) + time.perf_counter() - t1
    return _sampled(key, image, tex, ref, anisotropy)


def _sampled(key, image, tex, ref, anisotropy: float):
    """Set ``tex``'s trilinear filtering, the wrap of ``ref`` and ``anisotropy``; cache it under ``key``."""
    tex.filter = (0x2703, 0x2601)  # GL_LINEAR_MIPMAP_LINEAR, GL_LINEAR (trilinear)
    tex.repeat_x = ref.wrap[0] != WRAP_CLAMP
    tex.repeat_y = ref.wrap[1] != WRAP_CLAMP
    if anisotropy > 1.0:
        tex.anisotropy = float(anisotropy)
    _textures[key] = (image, tex)
    return tex


def normal_variance_texture(image, ref, anisotropy: float):
    """The ``prefiltered`` companion of normal map ``image``: an R32F texture with the normal map's
    mip sizes, level k = :func:`pbrcheck.specular_aa.slope_variance_mips`'s level k, the same wrap
    and filtering (cached per image, wrap and anisotropy)."""
    key = bake_key("normal_variance", id(image), ref.wrap, anisotropy=anisotropy)
    hit = _textures.get(key)
    if hit is not None and hit[0] is image:
        return hit[1]
    h, w = image.pixels.shape[:2]
    mips = slope_variance_mips(image.linear(False), max(w, h).bit_length())
    tex = get_context().texture((w, h), 1, np.ascontiguousarray(mips[0]).tobytes(), dtype="f4")
    tex.build_mipmaps()   # allocates every level; each is overwritten with its own variance below
    for k, m in enumerate(mips[1:], start=1):
        tex.write(np.ascontiguousarray(m).tobytes(), level=k)
    return _sampled(key, image, tex, ref, anisotropy)


def _white():
    key = ("white",)
    if key not in _textures:
        _textures[key] = (None, get_context().texture((1, 1), 4, np.ones(4, np.float32).tobytes(), dtype="f4"))
    return _textures[key][1]


def _set(prog, name, value):
    """Set a uniform where the program has it (the AOV variant drops the shading inputs)."""
    try:
        u = prog[name]
    except KeyError:
        return
    if isinstance(value, bytes):  # an array: the compiler may have shortened it to the elements read
        n = getattr(u, "array_length", 1) or 1
        u.write(value[:n * (len(value) // TEXTURE_SLOTS_N)] if name == "tex_xf" else value)
    else:
        u.value = value


def _depth_range(items: list[DrawItem], origin, f) -> tuple[float, float]:
    zs = [(it.vertices[:, :3].astype(np.float64) - origin) @ f for it in items]
    z = np.concatenate(zs) if zs else np.array([1.0])
    far = max(float(z.max()) * 1.01, 1e-3)
    near = far * NEAR_FAR_RATIO
    zmin = float(z.min())
    if zmin > 0:
        near = max(near, 0.5 * zmin)
    return near, far


def _set_camera(prog, scene: Scene, near: float, far: float):
    r, u, f = camera_frame(scene.camera)
    tx, ty = tan_half_fov(scene.camera)
    _set(prog, "cam_origin", tuple(float(x) for x in scene.camera.origin))
    _set(prog, "cam_r", tuple(float(x) for x in r))
    _set(prog, "cam_u", tuple(float(x) for x in u))
    _set(prog, "cam_f", tuple(float(x) for x in f))
    _set(prog, "cam_tan", (float(tx), float(ty)))
    _set(prog, "depth_ab", ((far + near) / (far - near), -2.0 * far * near / (far - near)))


def _slot_state(ref) -> tuple[int, int, np.ndarray]:
    """(TEXCOORD set, mirror bits, 3x3 UV transform) of a texture reference."""
    mirror = int(ref.wrap[0] == WRAP_MIRROR) | 2 * int(ref.wrap[1] == WRAP_MIRROR)
    xf = np.asarray(ref.transform, float).reshape(3, 3) if ref.transform else np.eye(3)
    return int(ref.texcoord), mirror, xf


def _set_material(prog, it: DrawItem, anisotropy: float, occlusion: bool = True, normal_variance: bool = False):
    _set(prog, "base_factor", tuple(float(x) for x in it.base_color))
    _set(prog, "metallic_factor", float(it.metallic))
    _set(prog, "roughness_factor", float(it.roughness))
    _set(prog, "specular_f0", float(it.specular))
    _set(prog, "emissive_factor", tuple(float(x) for x in it.emissive))
    _set(prog, "alpha_mode", ALPHA_CODES[it.alpha_mode])
    _set(prog, "alpha_cutoff", float(it.alpha_cutoff))
    _set(prog, "normal_scale", float(it.normal_scale))
    _set(prog, "flip_backface", int(it.flip_backface))
    _set(prog, "object_id", float(it.object_id))
    _set(prog, "unlit", int(it.unlit))   # only in programs compiled with UNLIT_MATERIALS
    has, sets, mirror, xf = [], [], [], []
    for k, ((slot, _), name) in enumerate(zip(TEXTURE_SLOTS, ("tex_base", "tex_mr", "tex_normal", "tex_emissive"))):
        entry = it.textures.get(slot)
        unit = MATERIAL_UNIT0 + k
        if entry is None:
            _white().use(unit)
            has.append(0), sets.append(0), mirror.append(0), xf.append(np.eye(3))
        else:
            image, ref, srgb = entry
            _texture(image, ref, srgb, anisotropy).use(unit)
            st, mi, x = _slot_state(ref)
            has.append(1), sets.append(st), mirror.append(mi), xf.append(x)
        _set(prog, name, unit)
    ao = it.textures.get("occlusion") if occlusion else None
    unit = MATERIAL_UNIT0 + TEXTURE_SLOTS_N
    if ao is None:
        _white().use(unit)
        _set(prog, "ao_has", 0)
    else:
        image, ref, srgb = ao
        _texture(image, ref, srgb, anisotropy).use(unit)
        st, mi, x = _slot_state(ref)
        _set(prog, "ao_has", 1)
        _set(prog, "ao_set", st)
        _set(prog, "ao_mirror", mi)
        _set(prog, "ao_xf", tuple(float(v) for v in x.T.reshape(-1)))
        _set(prog, "ao_strength", float(ref.scale))
    _set(prog, "tex_occlusion", unit)
    nm = it.textures.get("normal") if normal_variance else None
    (normal_variance_texture(nm[0], nm[1], anisotropy) if nm is not None else _white()).use(NORMAL_VAR_UNIT)
    _set(prog, "tex_normal_var", NORMAL_VAR_UNIT)
    _set(prog, "tex_has", tuple(has))
    _set(prog, "tex_set", tuple(sets))
    _set(prog, "tex_mirror", tuple(mirror))
    # GLSL mat3 is column-major: write the transposes of the row-major matrices
    _set(prog, "tex_xf", np.ascontiguousarray(np.stack([m.T for m in xf]), np.float32).tobytes())
    if "transmission_factor" in prog:   # a transmission program (transmission.glsl)
        _set(prog, "transmission_factor", float(it.transmission))
        _set(prog, "transmission_thickness", float(it.thickness))
        _set(prog, "transmission_attenuation_color", tuple(float(x) for x in it.attenuation_color))
        _set(prog, "transmission_attenuation_distance", float(it.attenuation_distance))
        _set(prog, "transmission_dispersion", float(it.dispersion))
        _set(prog, "transmission_ior", ior_from_f0(float(it.specular)))
        _set(prog, "diffuse_transmission_factor", float(it.diffuse_transmission))
        _set(prog, "diffuse_transmission_color", tuple(float(x) for x in it.diffuse_transmission_color))
        _set_transmission_textures(prog, it, anisotropy)
    if any(f"lobe_p{k}" in prog for k in range(4)):   # a lobe program (material_lobes.glsl; a variant
        # keeps only the rows its lobes read): this draw's lobe factors and textures
        _set_lobes(prog, it, anisotropy)


#: raster.frag's transmission texture slots (tmap_*[k]): the transmission factor's (R) and the
#: thickness's (G), on units TRANSMISSION_UNIT + 1 + k.
TRANSMISSION_TEXTURE_SLOTS = ("transmission", "thickness")


def _set_transmission_textures(prog, it: DrawItem, anisotropy: float) -> None:
    """Bind draw ``it``'s transmission and thickness textures (white where absent: the factor as it is)
    and their texCoord, KHR_texture_transform and mirror state (``tmap_*`` of transmission.glsl)."""
    _bind_slot_textures(prog, TRANSMISSION_TEXTURE_SLOTS, it.transmission_textures, TRANSMISSION_UNIT + 1, anisotropy,
                        ("tmap", "tmap_has", "tmap_set", "tmap_mirror", "tmap_xf"))


def _bind_slot_textures(prog, slots, textures: dict, unit0: int, anisotropy: float, names: tuple) -> None:
    """Bind ``textures`` (slot -> (GltfImage, TextureRef, srgb)) of ``slots`` in order on units from
    ``unit0`` (white where absent) and write the array uniforms ``names`` = (samplers, has, texCoord set,
    mirror bits, transforms)."""
    n = len(slots)
    has, sets, mirror, xf, units = (np.zeros(n, np.int32), np.zeros(n, np.int32), np.zeros(n, np.int32),
                                    np.tile(np.eye(3, dtype=np.float32), (n, 1, 1)), np.zeros(n, np.int32))
    for k, slot in enumerate(slots):
        units[k] = unit0 + k
        entry = textures.get(slot)
        if entry is None:
            _white().use(unit0 + k)
            continue
        image, ref, srgb = entry
        _texture(image, ref, srgb, anisotropy).use(unit0 + k)
        sets[k], mirror[k], x = _slot_state(ref)
        has[k], xf[k] = 1, x.T   # GLSL mat3 is column-major
    for name, values in zip(names, (units, has, sets, mirror, xf.astype(np.float32))):
        _set_array(prog, name, values)


def _set_array(prog, name: str, values: np.ndarray) -> None:
    """Write the first elements of array uniform ``name`` that the compiler kept (it drops the tail a
    variant does not read), where the program has it."""
    try:
        u = prog[name]
    except KeyError:
        return
    n = getattr(u, "array_length", 1) or 1
    u.write(np.ascontiguousarray(values[:n]).tobytes())


def _set_lobes(prog, it: DrawItem, anisotropy: float) -> None:
    """raster.frag's lobe uniforms of draw ``it``: its factor rows (the neutral ones for a material
    without lobes, which then renders as in a lobe-free program) and lobe textures (units from :data:`LOBE_UNIT0`)."""
    rows = it.lobe_rows if it.lobe_rows is not None else NEUTRAL_LOBE_ROWS
    for k in range(4):
        _set(prog, f"lobe_p{k}", tuple(float(x) for x in rows[k]))
    _set(prog, "lobe_coat_normal_scale", float(it.coat_normal_scale))
    _bind_slot_textures(prog, [slot for slot, *_rest in LOBE_TEXTURE_SLOTS], it.lobe_textures, LOBE_UNIT0, anisotropy,
                        ("tex_lobe", "lobe_has", "lobe_set", "lobe_mirror", "lobe_xf"))


def _vaos(prog, items: list[DrawItem]):
    ctx = get_context()
    out = []
    for it in items:
        vbo = ctx.buffer(np.ascontiguousarray(it.vertices, np.float32).tobytes())
        ibo = ctx.buffer(np.ascontiguousarray(it.indices, np.uint32).tobytes())
        names = [n for n in VERTEX_LAYOUT[1:] if n in prog]
        fmt = " ".join(f if n in names else f[0] + "x4" for f, n in zip(VERTEX_LAYOUT[0].split(), VERTEX_LAYOUT[1:]))
        out.append((ctx.vertex_array(prog, [(vbo, fmt, *names)], ibo, index_element_size=4), vbo, ibo))
    return out


def max_msaa() -> int:
    """The most samples per pixel this GL context's multisampled colour pass can have: ``GL_MAX_SAMPLES``
    (llvmpipe: 4; a GPU: 8 or more)."""
    return int(get_context().max_samples)


def check_msaa(msaa: int) -> None:
    """Raise :class:`pbrcheck.errors.BackendError` (exit 3: a limit of this GL, not bad input: the same
    value renders where the GL offers more samples) naming the option, the value asked and the most
    this GL offers, when ``msaa > 1`` exceeds :func:`max_msaa`. :func:`realtime.render.render_realtime`
    calls it before any bake, :func:`raster_frame` again before drawing."""
    if msaa > 1:
        most = max_msaa()
        if msaa > most:
            raise BackendError(f"option msaa: {msaa} samples asked, this GL ({get_context().info['GL_RENDERER']}) "
                               f"offers at most {most} (GL_MAX_SAMPLES)")


#: The GL limits a colour pass's render targets must fit (OpenGL 4.6 core, table 23.53): its
#: textures, renderbuffers, framebuffer and viewport.
TARGET_SIZE_LIMITS = ("GL_MAX_TEXTURE_SIZE", "GL_MAX_RENDERBUFFER_SIZE", "GL_MAX_FRAMEBUFFER_WIDTH",
                      "GL_MAX_FRAMEBUFFER_HEIGHT", "GL_MAX_VIEWPORT_DIMS")


def max_target_side() -> tuple[int, str]:
    """(largest side of a colour-pass target, the GL limit that sets it) of this GL context
    (llvmpipe: 16384, GL_MAX_TEXTURE_SIZE)."""
    info = get_context().info
    best = None
    for name in TARGET_SIZE_LIMITS:
        v = info.get(name)
        if v is None:
            continue
        v = min(v) if isinstance(v, (tuple, list)) else int(v)
        if best is None or v < best[0]:
            best = (int(v), name)
    return best or (16384, "GL_MAX_TEXTURE_SIZE")


def check_target_size(width: int, height: int, ss: int) -> None:
    """Raise :class:`pbrcheck.limits.OutputSizeError` (exit 2) when the colour pass, ``ss`` x the
    image's sides, exceeds :func:`max_target_side`: GL would answer ``framebuffer is not complete``
    after the bakes (an asset above 4096 wide at the default supersample 4 on a 16384 GL)."""
    from pbrcheck.limits import OutputSizeError

    most, name = max_target_side()
    sw, sh = width * ss, height * ss
    if max(sw, sh) > most:
        raise OutputSizeError(f"realtime raster: a colour pass of {sw}x{sh} ({width}x{height} x supersample {ss}) "
                              f"exceeds this GL's {most} ({name}); lower the size or the supersample option "
                              f"(at most {most // ss} per side at supersample {ss})")


def check_texture_sizes(scene: Scene) -> None:
    """Raise :class:`pbrcheck.limits.OutputSizeError` (exit 2) when an asset's texture image has a
    side above this GL's ``GL_MAX_TEXTURE_SIZE`` (it is uploaded as one texture; the decoded-bytes
    budget allows a 20000 x 1 image), naming the image and its JSON pointer, before any bake."""
    from pbrcheck.limits import OutputSizeError

    most = int(get_context().info["GL_MAX_TEXTURE_SIZE"])
    for inst in getattr(scene, "assets", ()):
        for k in sorted(inst.asset.texture_slots()):   # the images a material samples (the others: never uploaded)
            im = inst.asset.images[k]
            if max(im.size) > most:
                raise OutputSizeError(f"{inst.path}: /images/{k}: a {im.size[0]}x{im.size[1]} texture, above this GL's "
                                      f"GL_MAX_TEXTURE_SIZE of {most}")


def _draw_colour(ctx, fbo, resolved, empty, color_prog, items: list[DrawItem], vaos, anisotropy: float,
                 occlusion: bool, normal_variance: bool, alpha_to_coverage: bool, msaa: int = 1) -> None:
    """The colour pass's GL commands (:func:`raster_frame`): clear, the background triangle, each
    primitive in order (opaque, then BLEND back to front) with its culling, blending and
    alpha-to-coverage state, and the MSAA resolve into ``resolved``. A large target is drawn in bands
    of rows under a scissor (:func:`realtime.gl.in_bands`: a SIGTERM is honoured between two): the
    scissor test only discards fragments outside the band, and each pixel sees the same draws in the
    same order, so the image is bit-identical to one pass. Not with ``msaa`` > 1: llvmpipe (Mesa 22.3)
    then loses samples of a band's top row under the scissor (the image differed there), so a
    multisampled colour pass stays one pass (a SIGTERM waits for it)."""
    import moderngl
    fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
    sw, sh = fbo.size

    def band(y: int, rows: int) -> None:
        if rows < sh:
            fbo.scissor = (0, y, sw, rows)
        ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND | moderngl.CULL_FACE)
        empty.render(moderngl.TRIANGLES, vertices=3)
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.front_face = "ccw"
        ctx.cull_face = "back"
        for it, (vao, _, _) in zip(items, vaos):
            if it.alpha_mode == "BLEND":
                ctx.enable(moderngl.BLEND)
                ctx.blend_func = (moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA, moderngl.ONE,
                                  moderngl.ONE_MINUS_SRC_ALPHA)
                fbo.depth_mask = False
            if it.cull:
                ctx.enable(moderngl.CULL_FACE)
            else:
                ctx.disable(moderngl.CULL_FACE)
            _set_material(color_prog, it, anisotropy, occlusion, normal_variance)
            a2c = alpha_to_coverage and it.alpha_mode == "MASK"
            if a2c:
                ctx.enable_direct(GL_SAMPLE_ALPHA_TO_COVERAGE)
                ctx.enable_direct(GL_SAMPLE_ALPHA_TO_ONE)
            vao.render(moderngl.TRIANGLES)
            if a2c:
                ctx.disable_direct(GL_SAMPLE_ALPHA_TO_COVERAGE)
                ctx.disable_direct(GL_SAMPLE_ALPHA_TO_ONE)
        fbo.depth_mask = True
        ctx.disable(moderngl.BLEND)

    try:
        if msaa > 1:
            band(0, sh)
        else:
            in_bands(ctx, sh, sw, band)
    finally:
        fbo.scissor = None  # the resolve (a blit) and later clears see the whole target
    if resolved is not None:
        ctx.copy_framebuffer(resolved, fbo)


def _opaque_pass(ctx, fbo, empty, color_prog, items: list[DrawItem], vaos, anisotropy: float, occlusion: bool,
                 normal_variance: bool, timings: dict | None) -> list:
    """Transmission's opaque pass (realtime/transmission.py): the background and the non-transmissive,
    non-BLEND primitives drawn as in the colour pass (single-sampled) into an RGBA32F texture of the
    colour pass's size, its full mip chain generated (moderngl attaches level 0 only; glGenerateMipmap
    box-filters each level from the one above), bound to :data:`TRANSMISSION_UNIT` as ``transmission_fb``.
    Returns the GL objects to release. ``timings["transmission_pass"]``: its seconds."""
    t0 = time.perf_counter()
    sw, sh = fbo.size
    tex = ctx.texture((sw, sh), 4, dtype="f4")
    depth = ctx.depth_renderbuffer((sw, sh))
    ofbo = ctx.framebuffer(color_attachments=[tex], depth_attachment=depth)
    _white().use(TRANSMISSION_UNIT)   # never the texture being drawn into (a feedback loop)
    _set(color_prog, "transmission_fb", TRANSMISSION_UNIT)
    ofbo.use()
    ofbo.viewport = (0, 0, sw, sh)
    _draw_colour(ctx, ofbo, None, empty, color_prog, items, vaos, anisotropy, occlusion, normal_variance, False, 1)
    tex.build_mipmaps()
    tex.filter = (0x2703, 0x2601)  # GL_LINEAR_MIPMAP_LINEAR, GL_LINEAR (trilinear)
    tex.repeat_x = tex.repeat_y = False
    tex.use(TRANSMISSION_UNIT)
    _set(color_prog, "transmission_fb_size", (float(sw), float(sh)))
    ctx.finish()
    if timings is not None:
        timings["transmission_pass"] = time.perf_counter() - t0
    return [ofbo, tex, depth]


def raster_frame(scene: Scene, items: list[DrawItem], color_prog, aov_prog, bg_prog, ss: int,
                 anisotropy: float = 1.0, occlusion: bool = True, *, msaa: int = 1,
                 alpha_to_coverage: bool = False, normal_variance: bool = False, timings: dict | None = None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Draw one frame: ``(color (H, W, 4) = radiance, coverage; aov (H, W, 4) = N, NdotV; object (H, W))``.

    ``color_prog`` has the shading inputs bound by the caller; the background program its
    environment. The colour pass runs at (ss W, ss H), with ``msaa`` samples per fragment (resolved),
    and is box-filtered to (W, H); ``alpha_to_coverage`` draws MASK primitives with
    GL_SAMPLE_ALPHA_TO_COVERAGE; ``normal_variance`` binds each normal map's slope-variance companion.
    ``timings["frame"]``: the colour pass's draws alone (clear, background, primitives, MSAA resolve)
    by :func:`realtime.gl.timed` -- a GL timer query on a GPU, as the ray-cast frame times its
    dispatch -- without the target allocation, the read-back and its box filter, or the AOV pass
    (on an H100 the read-back of a 4096 x 4096 float target alone took ~0.9 s of a timed call)."""
    import moderngl
    ctx = get_context()
    check_msaa(msaa)
    W, H = scene.camera.width, scene.camera.height
    r, u, f = camera_frame(scene.camera)
    origin = np.asarray(scene.camera.origin, float)
    near, far = _depth_range(items, origin, np.asarray(f, float))
    opaque = [it for it in items if it.alpha_mode != "BLEND" and it.transmission <= 0.0]
    # transmissive (non-BLEND) primitives after the opaque ones, back to front (the engines' order)
    transmissive = sorted((it for it in items if it.alpha_mode != "BLEND" and it.transmission > 0.0),
                          key=lambda it: -float(np.linalg.norm(it.centre - origin)))
    opaque_only = opaque
    opaque = opaque + transmissive
    blend = sorted((it for it in items if it.alpha_mode == "BLEND"),
                   key=lambda it: -float(np.linalg.norm(it.centre - origin)))
    released = []
    try:
        # colour pass
        sw, sh = W * ss, H * ss
        col = ctx.texture((sw, sh), 4, dtype="f4")
        resolved = None
        if msaa > 1:  # multisampled colour and depth, resolved into col after the draws
            made = [col]
            try:  # a format-specific limit below GL_MAX_SAMPLES: the same typed error, not a GL one
                col_ms = ctx.renderbuffer((sw, sh), 4, samples=msaa, dtype="f4")
                made.insert(0, col_ms)
                depth = ctx.depth_renderbuffer((sw, sh), samples=msaa)
                made.insert(0, depth)
                fbo = ctx.framebuffer(color_attachments=[col_ms], depth_attachment=depth)
            except moderngl.Error as e:
                released += made
                raise BackendError(f"option msaa: {msaa} samples asked, this GL ({ctx.info['GL_RENDERER']}) "
                                   f"cannot multisample the colour pass's RGBA32F and depth buffers with them, although "
                                   f"GL_MAX_SAMPLES is {ctx.max_samples} ({' '.join(str(e).split())})") from None
            resolved = ctx.framebuffer(color_attachments=[col])
            released += [fbo, resolved, col, col_ms, depth]
        else:
            depth = ctx.depth_renderbuffer((sw, sh))
            fbo = ctx.framebuffer(color_attachments=[col], depth_attachment=depth)
            released += [fbo, col, depth]
        fbo.use()
        fbo.viewport = (0, 0, sw, sh)
        for p in (color_prog, aov_prog, bg_prog):
            _set_camera(p, scene, near, far)
        _set(bg_prog, "target_size", (float(sw), float(sh)))
        empty = ctx.vertex_array(bg_prog, [])
        released.append(empty)
        vaos = _vaos(color_prog, opaque + blend)
        for v in vaos:
            released.extend(v)
        if "transmission_fb" in color_prog:   # a 2D texture on its unit even where no draw reads it
            _white().use(TRANSMISSION_UNIT)
            _set(color_prog, "transmission_fb", TRANSMISSION_UNIT)
            _set(color_prog, "transmission_fb_size", (1.0, 1.0))
        if transmissive and "transmission_fb" in color_prog:
            released += _opaque_pass(ctx, fbo, empty, color_prog, opaque_only, vaos[:len(opaque_only)], anisotropy,
                                     occlusion, normal_variance, timings)
            fbo.use()
            fbo.viewport = (0, 0, sw, sh)
        ctx.finish()  # uploads and allocations above stay out of the timed draws
        _, t_draw = timed(ctx, lambda: _draw_colour(ctx, fbo, resolved, empty, color_prog, opaque + blend, vaos,
                                                    anisotropy, occlusion, normal_variance, alpha_to_coverage, msaa))
        if timings is not None:
            timings["frame"] = t_draw
        color = np.frombuffer((resolved or fbo).read(components=4, dtype="f4"), np.float32).reshape(sh, sw, 4)[::-1]
        color = color.reshape(H, ss, W, ss, 4).mean(axis=(1, 3))
        # AOV pass at the pixel centres
        aov_t = ctx.texture((W, H), 4, dtype="f4")
        obj_t = ctx.texture((W, H), 4, dtype="f4")
        depth2 = ctx.depth_renderbuffer((W, H))
        fbo2 = ctx.framebuffer(color_attachments=[aov_t, obj_t], depth_attachment=depth2)
        released += [fbo2, aov_t, obj_t, depth2]
        fbo2.use()
        fbo2.viewport = (0, 0, W, H)
        fbo2.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        vaos2 = _vaos(aov_prog, items)
        for v in vaos2:
            released.extend(v)
        for it, (vao, _, _) in zip(items, vaos2):
            if it.cull:
                ctx.enable(moderngl.CULL_FACE)
            else:
                ctx.disable(moderngl.CULL_FACE)
            _set_material(aov_prog, it, anisotropy)
            vao.render(moderngl.TRIANGLES)
        ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        aov = np.frombuffer(fbo2.read(components=4, dtype="f4", attachment=0), np.float32).reshape(H, W, 4)[::-1].copy()
        obj4 = np.frombuffer(fbo2.read(components=4, dtype="f4", attachment=1), np.float32).reshape(H, W, 4)[::-1]
        covered = obj4[..., 3] > 0.5
        obj = np.where(covered, obj4[..., 0], -1.0).astype(np.float32)
        return np.ascontiguousarray(color, np.float32), aov, obj
    finally:
        for g in released:
            try:
                g.release()
            except Exception:
                pass
