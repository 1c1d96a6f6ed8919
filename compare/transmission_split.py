"""Each renderer's transmission error against the path truth split into a screen-space part, a LOD-rule
part and a thickness-attenuation part (issue 37 item 3; docs/renderers.md section 12, "The split").

``python -m compare.transmission_split glass --size 96x72 --spp 256 --with default,ext:threejs``
prints one Markdown row per renderer and transmissive object (:func:`report`).

The definition
--------------
The error is the comparator's relmse (:func:`compare.metrics.summarize`: the mean over the pixels and
channels of ``(test - ref)^2 / (ref^2 + REL_EPS)``) over a transmissive object's pixels (the
``transmissive`` region of :func:`compare.transmission_engines.regions`; ``all``: every transmissive
pixel). Its parts, in the same units:

- **screen-space** (a partition of the renderer's own error by pixel): every engine reads the opaque
  pass at the point ``p + thickness t`` (``p`` the front-face hit, ``t = refract(-v, n, 1 / ior)``)
  projected into the screen (realtime/shaders/transmission.glsl, each engine's
  ``getVolumeTransmissionRay``). :func:`lookups` classifies each transmissive pixel, in closed form for
  the scene's analytic spheres and planes, by ray casting a glTF mesh's triangles: ``offscreen`` (behind
  the camera or outside the screen: an engine reads its framebuffer's clamped edge, the real-time
  renderer the prefiltered environment), ``transparent`` (the camera ray through the lookup pixel meets
  another transmissive object behind this one's front hit: on the refracted ray's way, and left out of
  the opaque pass; one in front of it is not on that way), ``opaque`` (the pass holds what the ray sees
  there, up to the other parts). The ``offscreen`` and ``transparent`` parts are the relmse summed over
  those pixels divided by the object's pixel count (so the parts of a partition add up to the total),
  with their share of the total.
- **thickness** (an ablation): the drop of the error when Beer-Lambert over ``thickness`` is replaced by
  Beer-Lambert over the chord the refracted ray really travels (:func:`chord_lengths`: ``2 R
  cos(theta_t)`` through a sphere, ``thickness / cos(theta_t)`` through a slab; a mesh: the refracted
  ray's exit by :func:`ray_triangles`; not where a thickness texture scales the thickness, whose texel
  is not read). Computed from two real renders of the renderer itself (an engine too): ``A`` with the
  scene's attenuation, ``B`` with it removed (``attenuation_distance`` 0: none; a ``.gltf`` asset
  rewritten without its volume's attenuation); every renderer's pixel is ``B + (a_thickness - 1) X``
  with ``X`` the attenuated term, so the chord's image is ``B + (A - B) (a_chord - 1) / (a_thickness -
  1)`` per channel (:func:`chord_swap`; exact where the pixel sees one object, with the chord at its
  centre).
- **LOD** (an ablation, on the real-time renderer's emulation of the engine, :data:`EMULATIONS`): the
  drop of the error when the emulation's ``transmission_lod`` level is moved by the best of
  :data:`LOD_BIASES` for that object (option ``transmission_lod_bias``; per object the roughness and IOR
  are constant, so a bias reaches any rule's level there). An engine's LOD part is its emulation's (the
  engines' own levels cannot be moved from outside); for a preset it is its own.
- **other** = total - screen-space - LOD - thickness: one refraction (no exit refraction, no total
  internal reflection), no inter-reflection, the engines' framebuffers (8 bit in the Sample Viewer),
  their filters.

Caveat: the ablation parts need not add up, nor add to the total with the screen-space part: the error
is not linear in its causes (a pixel off the screen can also be mis-attenuated; fixing one cause can
raise the error another cause was hiding), so ``other`` can be negative. The classification is of the
common form (the thickness-scaled refracted ray from the front face); Babylon.js and Filament are
emulated by the ``default`` preset (their rules are not read, docs/renderers.md section 12).

API
---
:data:`LOD_BIASES`, :data:`EMULATIONS`, :data:`CLASSES`, :class:`Lookups`, :func:`lookups`,
:func:`ray_triangles`, :func:`chord_lengths`, :func:`chord_swap`, :func:`pixel_errors`, :func:`split`,
:func:`markdown`, :func:`report`, :data:`ARGUMENTS`, :func:`main`.

References: KHR_materials_transmission and KHR_materials_volume (Khronos glTF extension READMEs);
KhronosGroup/glTF-Sample-Viewer ``source/Renderer/shaders/ibl.glsl`` ``getVolumeTransmissionRay``.
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import sys
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from pbrcheck.atomic import write_text_atomic
from pbrcheck.camera import camera_frame, primary_rays, tan_half_fov
from pbrcheck.errors import SceneError
from pbrcheck.export import keeping_unmodelled
from pbrcheck.exr import Image
from pbrcheck.fmt import markdown_cell
from pbrcheck.scene import Plane, Sphere, asset_scene, load_scene
from pbrcheck.transmission import refract

from clients.run import object_ids, ray_distances
from realtime.transmission import ior_from_f0

from . import renderers
from .metrics import REL_EPS, compare_images
from .transmission_engines import regions, transmissive_ids

#: The LOD scan: levels added to the emulation's rule (0 included, so a part is never negative). The
#: framebuffer of 96 x 72 has 7 levels (0 .. 6) and the rule reads at most log2(96) x 0.4 = 2.6 on the
#: glass scene, so -2 .. +6 reaches every level from every object's rule level (a first scan to +4 found
#: +4 best on four of the six spheres: at its edge); steps of 1 level (one render each).
LOD_BIASES = (-2.0, -1.0, 0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0)
#: The real-time configuration that emulates each renderer (preset, option overrides): three.js's
#: bicubic read, the Sample Viewer's preset; PlayCanvas takes the Sample Viewer's level (trilinear);
#: Babylon.js's and Filament's rules are not read (docs/renderers.md section 12): ``default``.
EMULATIONS = {"ext:threejs": ("default", {"transmission_lod": "threejs"}),
              "ext:sample-viewer": ("sample_viewer", {}),
              "ext:playcanvas": ("default", {}), "ext:babylon": ("default", {}), "ext:filament": ("default", {})}
#: The lookup classes of :func:`lookups` (codes 0, 1, 2; -1: not a transmissive pixel).
CLASSES = ("opaque", "transparent", "offscreen")
#: Rays per chunk of :func:`ray_triangles` (N x T x 3 float64 temporaries: 2048 x 232 triangles of
#: AttenuationTest x 3 x 8 bytes = 11 MB each).
RAY_CHUNK = 2048
#: Nearest hit :func:`ray_triangles` accepts (world units): a refracted ray starts on its entry face;
#: the glTF assets here are metre-sized, so 1e-6 is far below a chord and above float64 round-off.
MIN_HIT_DISTANCE = 1e-6
#: Extinction of an attenuation colour of 0 in a channel (``-ln 0`` is infinite): a colour floored at
#: this value, exp(-ln(1e-6)) over a chord of one attenuation distance = 1e-6, already black in relmse.
MIN_ATTENUATION_COLOR = 1e-6


@dataclass(frozen=True)
class Lookups:
    """Per pixel (H, W) at the pixel centres: ``ids`` (object id, -1 background), ``cls`` (index into
    :data:`CLASSES`, -1 where the pixel is not a transmissive object), ``uv`` (H, W, 2) the refracted
    lookup point in the screen (GL orientation: v up; nan where not transmissive), ``chord`` (the
    refracted ray's length through the object: nan where not transmissive), ``thickness`` (the
    material's, what the engines attenuate over)."""
    ids: np.ndarray
    cls: np.ndarray
    uv: np.ndarray
    chord: np.ndarray
    thickness: np.ndarray


@dataclass(frozen=True)
class _Optics:
    """What the lookup and the chord swap read of a transmissive object: its IOR, the thickness the
    engines scale the refracted ray by (a glTF mesh's ``thicknessFactor`` x the placement's scale;
    ``textured``: a thickness texture multiplies it, unknown here), the attenuation."""
    ior: float
    thickness: float
    attenuation_distance: float
    attenuation_color: tuple
    textured: bool = False


def _optics(scene, obj) -> _Optics:
    if getattr(obj, "type", "") != "mesh":
        m = obj.material
        return _Optics(ior_from_f0(m.specular), m.thickness, m.attenuation_distance, tuple(m.attenuation_color))
    inst = scene.assets[obj.instance]
    gm = inst.asset.material(obj.gltf_material)
    v = gm.volume
    if v is None:
        return _Optics(gm.ior, 0.0, 0.0, (1.0, 1.0, 1.0))
    scale = float(np.cbrt(abs(np.linalg.det(inst.matrix()[:3, :3]))))
    return _Optics(gm.ior, v.thickness * scale, v.attenuation_distance, tuple(v.attenuation_color),
                   v.thickness_texture is not None)


def _triangles(scene, obj) -> np.ndarray:
    """(T, 3, 3) world-space triangles of a mesh object (as :func:`pbrcheck.gltf_export.mesh_object_ids`)."""
    inst = scene.assets[obj.instance]
    prim = inst.asset.primitives[obj.primitive]
    M = inst.matrix()
    P = prim.positions.astype(np.float64) @ M[:3, :3].T + M[:3, 3]
    return P[prim.indices.astype(np.int64).reshape(-1, 3)]


def ray_triangles(o, d, tris) -> tuple[np.ndarray, np.ndarray]:
    """The nearest hit of each ray (``o`` (N, 3) or (3,), unit ``d`` (N, 3)) among ``tris`` (T, 3, 3),
    Moller-Trumbore in float64: (distance (N,), inf where none; the triangle's index, -1 where none).
    Hits closer than :data:`MIN_HIT_DISTANCE` are ignored (a refracted ray leaving its own entry face)."""
    o = np.broadcast_to(np.asarray(o, float), np.shape(d))
    best, idx = np.full(len(d), np.inf), np.full(len(d), -1)
    v0, e1, e2 = tris[:, 0], tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    for a in range(0, len(d), RAY_CHUNK):
        dd, oo = d[a:a + RAY_CHUNK, None, :], o[a:a + RAY_CHUNK, None, :]
        pv = np.cross(dd, e2[None])
        det = (e1[None] * pv).sum(-1)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            tv = oo - v0[None]
            u = (tv * pv).sum(-1) * inv
            qv = np.cross(tv, e1[None])
            v = (dd * qv).sum(-1) * inv
            s = (e2[None] * qv).sum(-1) * inv
            ok = (np.abs(det) > 1e-12) & (u >= 0) & (v >= 0) & (u + v <= 1) & (s > MIN_HIT_DISTANCE)
        s = np.where(ok, s, np.inf)
        k = s.argmin(-1)
        best[a:a + RAY_CHUNK] = s[np.arange(len(k)), k]
        idx[a:a + RAY_CHUNK] = np.where(np.isfinite(best[a:a + RAY_CHUNK]), k, -1)
    return best, idx


def chord_lengths(obj, p, t) -> np.ndarray:
    """The length the refracted direction ``t`` (unit, (..., 3)) from the surface point ``p`` travels
    inside ``obj``: a sphere of radius R: the second root of ``|p + s t - c|^2 = R^2`` with
    ``|p - c| = R``, ``s = -2 (p - c).t = 2 R cos(theta_t)``; a plane (a slab of the material's
    ``thickness`` below it): ``thickness / cos(theta_t)``, ``cos(theta_t) = |n.t|``."""
    p, t = np.asarray(p, float), np.asarray(t, float)
    if isinstance(obj, Sphere):
        return np.maximum(-2.0 * ((p - np.asarray(obj.center, float)) * t).sum(-1), 0.0)
    n = np.asarray(obj.normal, float) / np.linalg.norm(obj.normal)
    return obj.material.thickness / np.maximum(np.abs(t @ n), 1e-12)


def _depths(scene, obj, o, d, f) -> np.ndarray:
    """The view depth ``(x - o).f`` (``f`` the camera's forward axis) of ``obj``'s first hit along each
    camera ray ``d`` (H, W, 3) (inf where the ray misses it): what hides behind another object at a
    pixel, which :func:`clients.run.object_ids` (the front-most only) cannot say."""
    if getattr(obj, "type", "") == "mesh":
        s = ray_triangles(o, d.reshape(-1, 3), _triangles(scene, obj))[0].reshape(d.shape[:-1])
    else:
        s = ray_distances(obj, o, d)
    return s * (d @ f)


def _front_hits(scene, obj, o, d):
    """(hit points, outward normals facing the eye) of the rays (o, d) on ``obj``'s front face (a
    mesh: its nearest triangle's geometric normal)."""
    if getattr(obj, "type", "") == "mesh":
        tris = _triangles(scene, obj)
        s, k = ray_triangles(o, d, tris)
        s = np.where(np.isfinite(s), s, 0.0)   # a pixel-centre raster hit the ray cast grazes past
        n = np.cross(tris[k, 1] - tris[k, 0], tris[k, 2] - tris[k, 0])
        n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-300)
        return o + d * s[:, None], np.where(((d * n).sum(-1) < 0.0)[:, None], n, -n)
    if isinstance(obj, Sphere):
        oc = o - np.asarray(obj.center, float)
        b = d @ oc
        s = -b - np.sqrt(np.maximum(b * b - (oc @ oc - obj.radius ** 2), 0.0))
        p = o + d * s[..., None]
        return p, (p - np.asarray(obj.center, float)) / obj.radius
    n = np.asarray(obj.normal, float) / np.linalg.norm(obj.normal)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = ((np.asarray(obj.center, float) - o) @ n) / (d @ n)
    p = o + d * s[..., None]
    return p, np.where(((d @ n) < 0.0)[..., None], n, -n) * np.ones_like(p)


def lookups(scene) -> Lookups:
    """The refracted lookup of every transmissive pixel of ``scene``: analytic spheres and planes in
    closed form; glTF meshes by ray casting their triangles (:func:`ray_triangles`: the front hit, its
    geometric normal, the exit of the refracted ray for the chord).

    Raises
    ------
    SceneError
        A transmissive object of another kind."""
    cam = scene.camera
    o, d = primary_rays(cam)
    ids = object_ids(scene)
    trans = transmissive_ids(scene)
    shape = ids.shape
    cls = np.full(shape, -1, np.int8)
    uv = np.full((*shape, 2), np.nan)
    chord = np.full(shape, np.nan)
    thick = np.full(shape, np.nan)
    r, u, f = camera_frame(cam)
    tx, ty = tan_half_fov(cam)
    for obj in scene.objects:
        if obj.id in trans and not (isinstance(obj, (Sphere, Plane)) or getattr(obj, "type", "") == "mesh"):
            raise SceneError(scene.source, f"objects[{obj.id}]", "a sphere, a plane or a glTF mesh",
                             type(obj).__name__)
    depth = {obj.id: _depths(scene, obj, o, d, f) for obj in scene.objects if obj.id in trans}
    for obj in scene.objects:
        if obj.id not in trans:
            continue
        m = ids == obj.id
        if not m.any():
            continue
        p, n = _front_hits(scene, obj, o, d[m])
        opt = _optics(scene, obj)
        t = refract(-d[m], n, np.full(len(p), opt.ior))
        t /= np.maximum(np.linalg.norm(t, axis=-1, keepdims=True), 1e-300)
        q = p + opt.thickness * t - o
        z = q @ f
        with np.errstate(divide="ignore", invalid="ignore"):
            uvm = np.stack([0.5 * (q @ r) / (tx * z) + 0.5, 0.5 * (q @ u) / (ty * z) + 0.5], -1)
        off = (z <= 0.0) | (uvm < 0.0).any(-1) | (uvm > 1.0).any(-1)
        col = np.clip(np.floor(np.nan_to_num(uvm[:, 0]) * shape[1]), 0, shape[1] - 1).astype(int)
        row = np.clip(np.floor((1.0 - np.nan_to_num(uvm[:, 1])) * shape[0]), 0, shape[0] - 1).astype(int)
        # another transmissive object behind this one's front hit at the lookup pixel: on the refracted
        # ray's way, and left out of the opaque pass (one in front of it is not on that way)
        zp = (p - o) @ f
        other = np.zeros(len(p), bool)
        for k, z in depth.items():
            if k != obj.id:
                other |= np.isfinite(z[row, col]) & (z[row, col] > zp)
        cls[m] = np.where(off, 2, np.where(other, 1, 0))
        uv[m] = uvm
        if getattr(obj, "type", "") == "mesh":   # the exit: the refracted ray's next hit on the mesh
            chord[m] = ray_triangles(p, t, _triangles(scene, obj))[0]
        else:
            chord[m] = chord_lengths(obj, p, t)
        # a thickness texture's texel is unknown here: no thickness to swap (chord_swap keeps the pixel)
        thick[m] = np.nan if opt.textured else opt.thickness
    return Lookups(ids, cls, uv, chord, thick)


@contextmanager
def _without_attenuation(scene):
    """``scene`` with no attenuation (render ``B`` of :func:`chord_swap`): every analytic object's
    ``attenuation_distance`` 0 (none); a glTF asset's document rewritten without ``KHR_materials_volume``'s
    ``attenuationDistance`` / ``attenuationColor`` into a temporary folder beside copies of its files
    (the engines export the asset's own document), loaded with the same camera, environment and lights.

    Raises
    ------
    SceneError
        A binary ``.glb`` asset or several assets (only one ``.gltf`` is rewritten)."""
    analytic = tuple(replace(ob, material=replace(ob.material, attenuation_distance=0.0))
                     if getattr(ob, "type", "") != "mesh" and ob.material.attenuation_distance > 0.0 else ob
                     for ob in scene.objects)
    if not getattr(scene, "assets", ()):
        yield replace(scene, objects=analytic)
        return
    src = Path(scene.assets[0].asset.path)
    if len(scene.assets) != 1 or src.suffix.lower() != ".gltf" or any(ob.type != "mesh" for ob in scene.objects):
        raise SceneError(scene.source, "objects", "one .gltf asset and no analytic object (its attenuation "
                         "is removed by rewriting the document)", src.name)
    doc = json.loads(src.read_text())
    for m in doc.get("materials", []):
        vol = m.get("extensions", {}).get("KHR_materials_volume")
        if vol is not None:
            vol.pop("attenuationDistance", None)
            vol.pop("attenuationColor", None)
    with tempfile.TemporaryDirectory(prefix="pbrcheck-split-") as tmp:
        for f in src.parent.iterdir():   # copies: the loader refuses a link out of the asset's folder
            if f.name != src.name and f.is_file():
                shutil.copyfile(f, Path(tmp) / f.name)
        out = Path(tmp) / src.name
        write_text_atomic(out, json.dumps(doc))
        free = asset_scene(out, size=(scene.camera.width, scene.camera.height))
        yield replace(free, camera=scene.camera, environment=scene.environment, lights=scene.lights)


def chord_swap(scene, look: Lookups, attenuated: np.ndarray, free: np.ndarray) -> np.ndarray:
    """The (H, W, 3) image with the attenuation over the chord instead of the thickness, from a render
    ``attenuated`` (the scene's Beer-Lambert over ``thickness``) and ``free`` (no attenuation):
    ``free + (attenuated - free) (a_chord - 1) / (a_thickness - 1)``, ``a_L = exp(-sigma_t L)``,
    ``sigma_t = -ln(attenuation_color) / attenuation_distance``; the ratio by ``expm1`` (its limit
    ``chord / thickness`` where sigma_t is 0, where ``attenuated - free`` is 0 anyway). Pixels of no
    attenuating transmissive object keep ``attenuated``."""
    out = np.array(attenuated, float, copy=True)
    for obj in scene.objects:
        m = (look.ids == obj.id) & np.isfinite(look.chord) & np.isfinite(look.thickness)
        if not m.any():
            continue
        opt = _optics(scene, obj)
        dist = opt.attenuation_distance
        if dist <= 0.0 or math.isinf(dist):
            continue
        sigma = -np.log(np.maximum(np.asarray(opt.attenuation_color, float), MIN_ATTENUATION_COLOR)) / dist
        lc, lt = look.chord[m][:, None], look.thickness[m][:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(sigma > 0.0, np.expm1(-sigma * lc) / np.expm1(-sigma * lt), lc / lt)
        ratio = np.where(np.isfinite(ratio), ratio, 1.0)   # thickness 0 (thin-walled): nothing to swap
        out[m] = free[m] + (attenuated[m] - free[m]) * ratio
    return out


def pixel_errors(scene, ref, img) -> tuple[np.ndarray, np.ndarray]:
    """(the per-pixel relmse term summed over channels (H, W), the ``transmissive`` mask of
    :func:`compare.transmission_engines.regions`): a mask's relmse is ``e[mask].sum() / (3 mask.sum())``."""
    cmp = compare_images(ref, img, scene=scene, noise=False, itp=False)
    e = (cmp.maps.diff.astype(float) ** 2 / (cmp.maps.ref.astype(float) ** 2 + REL_EPS)).sum(-1)
    return e, regions(scene, ref, cmp)["transmissive"]


def _relmse(e, mask) -> float:
    n = int(mask.sum())
    return float(e[mask].sum() / (3 * n)) if n else float("nan")


def _render(scene, name: str, overrides: dict | None = None, progress: bool = False):
    spec = renderers.RendererSpec.parse(name, None if renderers.is_external(name) else overrides)
    if spec.external:
        with keeping_unmodelled():
            return renderers.render_under_test(scene, spec, progress=progress)
    return renderers.render_under_test(scene, spec, progress=progress)


def split(scene, ref, name: str, *, overrides: dict | None = None, biases=LOD_BIASES,
          look: Lookups | None = None, memo: dict | None = None, progress: bool = False) -> list[dict]:
    """The rows of renderer ``name`` (a preset, ``ext:NAME``) on ``scene`` against the truth ``ref``:
    one per transmissive object and ``all``, each ``{renderer, object, pixels, total, offscreen,
    transparent, lod, lod_bias, thickness, other, emulation}`` (relmse units; ``offscreen`` /
    ``transparent`` also as ``*_share`` of the total). ``overrides``: options of a preset and of the
    emulation (the tests' small bakes); ``memo``: a dict shared by the calls of one scene and truth, so
    renderers of one emulation render its LOD scan once. See the module docstring for the definitions."""
    look = look if look is not None else lookups(scene)
    base = _render(scene, name, overrides, progress)
    e, trans = pixel_errors(scene, ref, base)
    with _without_attenuation(scene) as free_scene:
        free = _render(free_scene, name, overrides, progress)
    swapped = Image.from_rgb(chord_swap(scene, look, base.rgb, free.rgb).astype(np.float32), dict(base.meta),
                             **{k: v for k, v in base.channels.items() if k not in ("R", "G", "B")})
    e_chord, _ = pixel_errors(scene, ref, swapped)
    memo = {} if memo is None else memo

    def scan(preset, over, b):
        key = (preset, tuple(sorted(over.items())), b)
        if key not in memo:
            memo[key] = pixel_errors(scene, ref, _render(scene, preset, {**over, "transmission_lod_bias": b}
                                                         if b else over, progress))[0]
        return memo[key]

    if renderers.is_external(name):
        preset, extra = EMULATIONS.get(name, ("default", {}))
        emulation = f"{preset}" + "".join(f" {k}={v}" for k, v in extra.items())
        emu_over = {**(overrides or {}), **extra}
    else:
        preset, emu_over, emulation = name, dict(overrides or {}), "-"
        memo.setdefault((preset, tuple(sorted(emu_over.items())), 0.0), e)
    scans = {b: scan(preset, emu_over, b) for b in sorted({0.0, *biases})}
    e_emu = scans[0.0]
    objects = [(ob.name, trans & (look.ids == ob.id)) for ob in scene.objects if ob.id in transmissive_ids(scene)]
    rows = []
    for label, mask in [("all", trans), *objects]:
        if not mask.any():
            continue
        total = _relmse(e, mask)
        part = {c: _relmse(e, mask & (look.cls == k)) * (mask & (look.cls == k)).sum() / mask.sum()
                if (mask & (look.cls == k)).any() else 0.0 for k, c in enumerate(CLASSES)}
        if label == "all":   # the best bias per object, summed: each object's pixels are read at its own
            emu = _relmse(e_emu, mask)
            best = sum(min(_relmse(s, m) for s in scans.values()) * m.sum() for _, m in objects if m.any()) / mask.sum()
            bias = None
        else:
            emu = _relmse(e_emu, mask)
            bias, best = min(((b, _relmse(s, mask)) for b, s in scans.items()), key=lambda x: (x[1], abs(x[0])))
        lod = emu - best
        thickness = total - _relmse(e_chord, mask)
        screen = part["offscreen"] + part["transparent"]
        rows.append({"renderer": name, "object": label, "pixels": int(mask.sum()), "total": total,
                     "offscreen": part["offscreen"], "transparent": part["transparent"],
                     "offscreen_share": part["offscreen"] / total if total else 0.0,
                     "transparent_share": part["transparent"] / total if total else 0.0,
                     "emulation": emulation, "emulation_total": emu, "lod": lod, "lod_bias": bias,
                     "thickness": thickness, "other": total - screen - lod - thickness,
                     "classes": {c: int((mask & (look.cls == k)).sum()) for k, c in enumerate(CLASSES)}})
    return rows


def _fmt(x) -> str:
    return "-" if x is None else f"{x:.3g}"


def markdown(rows) -> str:
    """The rows as a Markdown table (names through :func:`pbrcheck.fmt.markdown_cell`)."""
    head = ("| renderer | object | pixels (opaque / transparent / offscreen) | total relmse | off-screen (share) "
            "| behind transparent (share) | LOD (emulation; best bias) | thickness | other |")
    lines = [head, "|" + "---|" * 9]
    for r in rows:
        c = r["classes"]
        emu = "" if r["emulation"] == "-" else f"{markdown_cell(r['emulation'])}: "
        bias = "" if r["lod_bias"] is None else f"; {r['lod_bias']:+g}"
        lines.append(" | ".join([
            f"| {markdown_cell(r['renderer'])}", markdown_cell(r["object"]),
            f"{r['pixels']} ({c['opaque']} / {c['transparent']} / {c['offscreen']})", _fmt(r["total"]),
            f"{_fmt(r['offscreen'])} ({r['offscreen_share']:.0%})", f"{_fmt(r['transparent'])} ({r['transparent_share']:.0%})",
            f"{emu}{_fmt(r['lod'])}{bias}", _fmt(r["thickness"]), _fmt(r["other"])]) + " |")
    return "\n".join(lines)


def report(scene, names, *, spp: int = 256, progress: bool = False) -> str:
    """The Markdown table of :func:`split` for every renderer of ``names`` on ``scene`` against its path
    truth at ``spp`` (one lookup classification and one LOD-scan memo for all)."""
    ref = renderers.render_reference(scene, spp=spp, mode="path", progress=progress)
    look, memo = lookups(scene), {}
    return markdown([r for n in names for r in split(scene, ref, n, look=look, memo=memo, progress=progress)])


#: The command line of :func:`main`: (name or flag, add_argument's keywords).
ARGUMENTS = (
    ("scene", {"help": "built-in scene name, TOML path, or a .gltf asset"}),
    ("--size", {"default": "96x72", "help": "WxH (default 96x72)"}),
    ("--spp", {"type": int, "default": 256, "help": "path truth samples per pixel (default 256)"}),
    ("--with", {"dest": "names", "default": "default,sample_viewer", "help": "renderers, comma-separated"}),
)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m compare.transmission_split", description=__doc__.splitlines()[0])
    for flag, kw in ARGUMENTS:
        p.add_argument(flag, **kw)
    a = p.parse_args(argv)
    size = tuple(int(x) for x in a.size.lower().split("x"))
    scene = (asset_scene(a.scene, size=size) if a.scene.endswith((".gltf", ".glb"))
             else load_scene(a.scene).with_camera(width=size[0], height=size[1]))
    print(report(scene, [n for n in a.names.split(",") if n], spp=a.spp, progress=True))
    return 0


if __name__ == "__main__":
    sys.exit(main())
