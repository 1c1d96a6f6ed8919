"""glTF 2.0 assets: read a ``.gltf`` / ``.glb`` into flat, world-space triangle primitives, materials,
images, lights and cameras that both the reference and the exporters consume.

API
---
- :func:`load_asset` -- parse and resolve an asset (cached per file content); returns an :class:`Asset`.
- :class:`Asset`, :class:`Primitive`, :class:`GltfMaterial`, :class:`TextureRef`, :class:`GltfImage`,
  :class:`GltfLight`, :class:`GltfCamera` -- the resolved asset (immutable dataclasses, numpy arrays).
- :class:`AssetError` -- every problem, naming the file and the JSON pointer
  (``/meshes/0/primitives/1/attributes/NORMAL``); the CLI maps it to exit 2.
- :data:`MODELLED_EXTENSIONS` (formerly ``SUPPORTED_EXTENSIONS``, kept as an alias) -- the
  extensions modelled (any other one in ``extensionsRequired`` is an error; an optional one is
  listed in :attr:`Asset.extensions_ignored`, and recorded with the
  materials and primitives it touches in :attr:`Asset.unmodelled`: :mod:`pbrcheck.unmodelled`).
- :data:`DECODED_FORMATS` -- the image formats Pillow decodes (PNG, JPEG, WEBP; KTX2 is
  :func:`pbrcheck.gltf_features.decode_ktx2`'s).
- :func:`texture_transform_matrix` -- ``KHR_texture_transform``'s 3x3 UV matrix (T R S).
- :func:`srgb_to_linear` -- the sRGB decoding of colour textures (IEC 61966-2-1).
- :func:`wrap_mirror` -- ``MIRRORED_REPEAT`` of one texture coordinate (numpy twin of
  ``realtime/shaders/texcoord.glsl``'s, compared by the GLSL harness in ``tests/test_gltf_wrap.py``).
- :func:`content_hash` -- sha256 of the asset file and every external resource it names.
- :func:`read_resource`, :func:`resource_cap` -- an external buffer or image through the one resolver
  of untrusted paths (:mod:`pbrcheck.untrusted`: relative, inside the asset's folder after symlinks,
  a regular file, at most its declared size); the loader checks the document
  (:mod:`pbrcheck.asset_guard`) and the budgets (:mod:`pbrcheck.limits`) before the work.

Conventions (glTF 2.0 specification, sections 3.5 accessors, 3.7 geometry, 3.9 materials, 3.8
textures; the extensions' specifications): world = the node hierarchy's product of local matrices
(``matrix`` or ``T * R * S``), +Y up, right-handed, metres; positions and tangents' xyz by the world
matrix, normals by its inverse transpose; a node whose world matrix has a negative determinant has
its triangles' winding reversed (spec 3.7.4) and its tangents' handedness ``w`` flipped. Normalized
integer accessors are decoded as ``max(c / (2^(b-1) - 1), -1)`` (signed) or ``c / (2^b - 1)``;
sparse accessors replace their indices' elements after the base (or zeros). UVs are glTF's (origin
at the image's top-left, v down), images are stored row 0 at the top, so a UV ``(u, v)`` reads
pixel ``(v H, u W)`` without a flip. Where ``NORMAL`` is absent every triangle gets its flat normal
(the vertices are unwelded); where ``TANGENT`` is absent and the material has a normal texture,
tangents are generated (:func:`generate_tangents`: the reference MikkTSpace C implementation,
:mod:`pbrcheck.mikktspace`, per face corner, vertices split where it splits them; ``w`` its sign
negated for glTF's v-down UVs). Skins (the default pose), morph targets (default weights), GPU
instances, node visibility, material variants and the image a texture reads are
:mod:`pbrcheck.gltf_features`'s; only images a material's texture reads are decoded. Primitive names are ``node/mesh/primitive`` (the node's and mesh's names,
or their indices where unnamed, and the primitive's index).

The reader is pygltflib (GLB chunks, JSON, data URIs); accessors are numpy views of its buffers;
``KHR_draco_mesh_compression`` is decoded with DracoPy (Google's Draco); images with Pillow.
References: Khronos glTF 2.0 specification (2021); KHR_texture_transform, KHR_materials_ior,
KHR_materials_emissive_strength, KHR_lights_punctual, KHR_draco_mesh_compression, KHR_mesh_quantization
(integer attributes: any component type, decoded as above); EXT_mesh_gpu_instancing, KHR_node_visibility,
KHR_materials_unlit, KHR_materials_variants, EXT_texture_webp, KHR_texture_basisu, EXT_meshopt_compression
(:mod:`pbrcheck.gltf_features`); KHR_materials_clearcoat, _sheen, _specular, _anisotropy, _iridescence
(parsed into :class:`GltfMaterial`'s lobe fields by :mod:`pbrcheck.lobe_params`, rendered by both renderers:
in :data:`MODELLED_EXTENSIONS`); Mikkelsen 2008,
"Simulation of wrinkled surfaces revisited" (MikkTSpace).
"""

from __future__ import annotations

import base64
import hashlib
import io
import json
import math
import re
import urllib.parse
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import asset_guard, gltf_features, limits, lobe_params, transmission_params, untrusted
from .errors import AssetError, os_reason  # noqa: F401  (AssetError: re-exported, its home is errors)
from .lights import DEFAULT_INNER_CONE, DEFAULT_OUTER_CONE, LIGHT_TYPES
from .mikktspace import corner_tangents
from .unmodelled import announce, asset_unmodelled

#: Extensions pbrcheck models (an ``extensionsRequired`` entry outside this list is an error; an
#: optional one is listed in :attr:`Asset.extensions_ignored`). Scene features: :mod:`pbrcheck.gltf_features`.
MODELLED_EXTENSIONS = ("KHR_lights_punctual", "KHR_materials_emissive_strength", "KHR_materials_ior",
                       "KHR_texture_transform", "KHR_draco_mesh_compression", "KHR_mesh_quantization",
                       *gltf_features.MODELLED_SCENE_EXTENSIONS, *lobe_params.MODELLED_LOBE_EXTENSIONS,
                       *transmission_params.MODELLED_TRANSMISSION_EXTENSIONS)
#: The former name of :data:`MODELLED_EXTENSIONS`.
SUPPORTED_EXTENSIONS = MODELLED_EXTENSIONS
#: Core features of :data:`pbrcheck.unmodelled.CORE_FEATURES` the loader models (the others are
#: named as unmodelled where an asset uses them): skins and morph targets (pbrcheck.gltf_features).
MODELLED_CORE_FEATURES: tuple[str, ...] = ("skins", "morph targets")
COMPONENT_DTYPES = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32,
                    5126: np.float32}
TYPE_SIZES = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
ATTRIBUTES = ("POSITION", "NORMAL", "TANGENT", "TEXCOORD_0", "TEXCOORD_1", "COLOR_0")
WRAP_REPEAT, WRAP_CLAMP, WRAP_MIRROR = 10497, 33071, 33648
ALPHA_MODES = ("OPAQUE", "MASK", "BLEND")
#: Largest asset file read (a .gltf or a .glb): a GLB's length field is a uint32 (glTF 2.0, 4.4.3).
MAX_ASSET_FILE_BYTES = 1 << 32


@dataclass(frozen=True)
class TextureRef:
    """A material slot's texture: the image, the UV set, the sampler and ``KHR_texture_transform``."""
    image: int
    texcoord: int = 0
    wrap: tuple[int, int] = (WRAP_REPEAT, WRAP_REPEAT)    # (S, T)
    mag_filter: int | None = None
    min_filter: int | None = None
    transform: tuple[float, ...] | None = None            # row-major 3x3 UV matrix, or None
    scale: float = 1.0                                    # normalTexture.scale / occlusionTexture.strength
    pointer: str = ""


@dataclass(frozen=True)
class GltfMaterial:
    """A glTF material (metal-rough). Factors as in the specification; textures as :class:`TextureRef`."""
    name: str
    base_color: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0)
    metallic: float = 1.0
    roughness: float = 1.0
    base_color_texture: TextureRef | None = None
    metallic_roughness_texture: TextureRef | None = None
    normal_texture: TextureRef | None = None
    occlusion_texture: TextureRef | None = None
    emissive: tuple[float, float, float] = (0.0, 0.0, 0.0)   # emissiveFactor * emissive_strength
    emissive_texture: TextureRef | None = None
    alpha_mode: str = "OPAQUE"
    alpha_cutoff: float = 0.5
    double_sided: bool = False
    ior: float = 1.5
    unlit: bool = False       # KHR_materials_unlit: the base colour (x texture x COLOR_0), no lighting
    # The lobes' extensions (pbrcheck.lobe_params; None: absent). Parsed and validated, not yet
    # rendered: they stay out of MODELLED_EXTENSIONS, so the honesty contract names them.
    clearcoat: lobe_params.Clearcoat | None = None          # KHR_materials_clearcoat
    sheen: lobe_params.Sheen | None = None                  # KHR_materials_sheen
    khr_specular: lobe_params.Specular | None = None        # KHR_materials_specular (``specular`` is the F0)
    anisotropy: lobe_params.Anisotropy | None = None        # KHR_materials_anisotropy
    iridescence: lobe_params.Iridescence | None = None      # KHR_materials_iridescence
    # The transmission extensions (pbrcheck.transmission_params; None: absent; issue 37).
    transmission: transmission_params.Transmission | None = None                  # KHR_materials_transmission
    volume: transmission_params.Volume | None = None                              # KHR_materials_volume
    dispersion: transmission_params.Dispersion | None = None                      # KHR_materials_dispersion
    diffuse_transmission: transmission_params.DiffuseTransmission | None = None   # KHR_materials_diffuse_transmission

    @property
    def specular(self) -> float:
        """Dielectric F0 from the ior: ((ior - 1) / (ior + 1))^2 (0.04 at glTF's default 1.5)."""
        return ((self.ior - 1.0) / (self.ior + 1.0)) ** 2

    def textures(self) -> dict[str, TextureRef]:
        slots = {"baseColor": self.base_color_texture, "metallicRoughness": self.metallic_roughness_texture,
                 "normal": self.normal_texture, "occlusion": self.occlusion_texture,
                 "emissive": self.emissive_texture}
        for attr, _ in (*lobe_params.LOBE_EXTENSIONS.values(),   # the lobes' and transmission's slots
                        *transmission_params.TRANSMISSION_EXTENSIONS.values()):
            lobe = getattr(self, attr)
            if lobe is not None:
                slots.update(lobe.textures())
        return {k: v for k, v in slots.items() if v is not None}


#: The material of primitives without one (glTF spec 3.9.6).
DEFAULT_MATERIAL = GltfMaterial(name="default")
#: Slots whose images hold sRGB-encoded colour (the others are linear data).
SRGB_SLOTS = ("baseColor", "emissive", *lobe_params.SRGB_SLOTS, *transmission_params.SRGB_SLOTS)


@dataclass(frozen=True, eq=False)
class GltfImage:
    """A decoded image: ``pixels`` (H, W, C) uint8 or uint16, row 0 at the top, as stored."""
    name: str
    source: str          # the uri, "data URI" or "bufferView k"
    mime: str
    pixels: np.ndarray
    decoded: bool = True  # False: no used texture reads it; not decoded (``pixels`` empty)

    @property
    def size(self) -> tuple[int, int]:
        return int(self.pixels.shape[1]), int(self.pixels.shape[0])

    def linear(self, srgb: bool) -> np.ndarray:
        """(H, W, 4) float32 in [0, 1]: colour channels sRGB-decoded when ``srgb``, alpha linear,
        grey expanded to RGB, alpha 1 where absent."""
        p = self.pixels
        x = p.astype(np.float32) / float(np.iinfo(p.dtype).max)
        if x.ndim == 2:
            x = x[..., None]
        c = x.shape[2]
        if c in (1, 2):
            rgb, a = np.repeat(x[..., :1], 3, axis=2), (x[..., 1:2] if c == 2 else None)
        else:
            rgb, a = x[..., :3], (x[..., 3:4] if c == 4 else None)
        if srgb:
            rgb = srgb_to_linear(rgb)
        if a is None:
            a = np.ones(rgb.shape[:2] + (1,), np.float32)
        return np.ascontiguousarray(np.concatenate([rgb, a], axis=2), dtype=np.float32)


@dataclass(frozen=True, eq=False)
class Primitive:
    """One (node, primitive): world-space, triangle list. Arrays are float32 except ``indices``."""
    name: str                      # node/mesh/primitive
    node: int
    mesh: int
    primitive: int
    material: int                  # index into Asset.materials (-1: the default material)
    positions: np.ndarray          # (N, 3)
    normals: np.ndarray            # (N, 3) unit
    indices: np.ndarray            # (T, 3) uint32, counter-clockwise front faces
    tangents: np.ndarray | None = None   # (N, 4) xyz unit, w = +-1
    texcoords: tuple[np.ndarray | None, np.ndarray | None] = (None, None)  # TEXCOORD_0/1 (N, 2)
    color: np.ndarray | None = None      # COLOR_0 (N, 4) linear
    flat_normals: bool = False
    generated_tangents: bool = False
    instances: int = 1                   # EXT_mesh_gpu_instancing: copies concatenated in the arrays
    skinned: bool = False                # posed by its node's skin (pbrcheck.gltf_features.deform)
    morph_weights: tuple[float, ...] = ()  # the default morph weights applied

    @property
    def triangles(self) -> int:
        return int(self.indices.shape[0])


@dataclass(frozen=True)
class GltfLight:
    """A ``KHR_lights_punctual`` light in world space. ``intensity``: candela (point, spot) or lux
    (directional), times ``color``; ``direction``: where it shines (the node's -Z)."""
    name: str
    type: str
    color: tuple[float, float, float]
    intensity: float
    position: tuple[float, float, float]
    direction: tuple[float, float, float]
    range: float | None = None
    inner_cone: float = DEFAULT_INNER_CONE
    outer_cone: float = DEFAULT_OUTER_CONE


@dataclass(frozen=True)
class GltfCamera:
    """The first camera of the asset, in world space: origin, forward, up, vertical fov (radians)."""
    name: str
    origin: tuple[float, float, float]
    forward: tuple[float, float, float]
    up: tuple[float, float, float]
    yfov: float
    aspect: float | None
    znear: float


@dataclass(frozen=True, eq=False)
class Asset:
    """A resolved asset (see the module docstring)."""
    path: str
    primitives: tuple[Primitive, ...]
    materials: tuple[GltfMaterial, ...]
    images: tuple[GltfImage, ...]
    lights: tuple[GltfLight, ...]
    cameras: tuple[GltfCamera, ...]
    extensions_used: tuple[str, ...]
    extensions_ignored: tuple[str, ...]
    content_hash: str
    resources: tuple[str, ...] = ()          # external files (absolute), for the exporter
    scene: int = 0
    unmodelled: tuple = ()                   # pbrcheck.unmodelled.Unmodelled: features not modelled
    variants: tuple[str, ...] = ()           # KHR_materials_variants' names, in index order
    variant: str | None = None               # the selected one (None: the file's default materials)

    def material(self, index: int) -> GltfMaterial:
        return DEFAULT_MATERIAL if index < 0 else self.materials[index]

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(min, max) of every primitive's world positions."""
        lo = np.min([p.positions.min(axis=0) for p in self.primitives], axis=0)
        hi = np.max([p.positions.max(axis=0) for p in self.primitives], axis=0)
        return lo.astype(np.float64), hi.astype(np.float64)

    @property
    def triangles(self) -> int:
        return sum(p.triangles for p in self.primitives)

    def texture_slots(self) -> dict[int, list[str]]:
        """image index -> ["material name:slot", ...]."""
        out: dict[int, list[str]] = {}
        for m in self.materials:
            for slot, t in m.textures().items():
                out.setdefault(t.image, []).append(f"{m.name}:{slot}")
        return out


def srgb_to_linear(x: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 sRGB decoding of values in [0, 1]."""
    x = np.asarray(x, dtype=np.float32)
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4).astype(np.float32)


def wrap_mirror(x):
    """glTF's ``MIRRORED_REPEAT`` (specification 3.8.4.3; OpenGL 4.6 core, 8.14.2, ``mirror(a) = a``
    for ``a >= 0``): ``1 - |mod(x, 2) - 1|``, ``mod(x, 2) = x - 2 floor(x / 2)``: ``x`` on [0, 1], then
    back down to 0 over [1, 2], with period 2."""
    x = np.asarray(x, np.float64)
    return 1.0 - np.abs(np.mod(x, 2.0) - 1.0)


def texture_transform_matrix(offset=(0.0, 0.0), rotation: float = 0.0, scale=(1.0, 1.0)) -> np.ndarray:
    """``KHR_texture_transform``: uv' = T(offset) R(rotation) S(scale) uv, with
    R = [[cos, sin], [-sin, cos]] (the extension's matrix; rotation counter-clockwise in UV space)."""
    c, s = math.cos(rotation), math.sin(rotation)
    T = np.array([[1, 0, offset[0]], [0, 1, offset[1]], [0, 0, 1]], float)
    R = np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]], float)
    S = np.array([[scale[0], 0, 0], [0, scale[1], 0], [0, 0, 1]], float)
    return T @ R @ S


# ------------------------------------------------------------------------------------------------
# Reading
# ------------------------------------------------------------------------------------------------

def _file_bytes(path: Path) -> bytes:
    try:  # a regular file only, read with a bound (pbrcheck.untrusted): never /dev/zero or a FIFO
        return untrusted.read_regular(path, MAX_ASSET_FILE_BYTES)
    except OSError as e:
        raise AssetError(path, "", f"cannot read: {e.strerror}") from None
    except ValueError as e:
        raise AssetError(path, "", f"cannot read: {e}") from None


def _parse(path: Path, raw: bytes) -> tuple[dict, bytes | None]:
    """(glTF JSON, GLB binary chunk or None) via pygltflib."""
    import pygltflib

    if raw[:4] == b"glTF":
        asset_guard.check_glb_header(path, raw)
    try:
        with asset_guard.quiet_library():  # pygltflib's own warnings are never printed
            g, blob = _pygltflib_read(pygltflib, raw)
        doc = json.loads(g.to_json())
        gltf_features.restore_node_weights(doc, raw)
    except AssetError:
        raise
    except Exception as e:  # noqa: BLE001 - pygltflib raises anything on corrupt input
        msg = str(e).splitlines()[0] if str(e) else type(e).__name__
        raise AssetError(path, "", f"not a valid glTF 2.0 file ({msg})") from None
    if not isinstance(doc, dict) or not str(doc.get("asset", {}).get("version", "")).startswith("2"):
        raise AssetError(path, "/asset/version", "expected glTF version 2.0")
    return doc, blob


def _pygltflib_read(pygltflib, raw: bytes):
    """(pygltflib document, GLB binary chunk or None)."""
    if raw[:4] == b"glTF":
        g = pygltflib.GLTF2.load_from_bytes(raw)
        return g, g.binary_blob()
    json.loads(raw.decode("utf-8"))   # pygltflib's own error on bad JSON is not one line
    return pygltflib.GLTF2.from_json(raw.decode("utf-8")), None


def content_hash(path: str | Path) -> str:
    """sha256 of the file and of every external resource (buffers, images) it names."""
    p = Path(path)
    raw = _file_bytes(p)
    h = hashlib.sha256(raw)
    for pointer, uri, cap in _external_uris(p, raw):
        h.update(uri.encode())
        try:  # the one resolver (pbrcheck.untrusted): a refusal is the loader's, raised here first
            h.update(read_resource(p, uri, pointer, cap, pointer.split("/")[1][:-1]))
        except AssetError as e:
            if not isinstance(e.__cause__, FileNotFoundError):
                raise
            h.update(b"<missing>")  # the loader names the missing file
    return h.hexdigest()


def resource_cap(key: str, entry: dict) -> int:
    """Most bytes read of an external resource: a buffer's declared ``byteLength`` plus
    :data:`pbrcheck.untrusted.READ_SLACK`; an image the ``texture_bytes`` budget plus the slack (an
    encoded image larger than its decoded budget is refused by the budget anyway)."""
    if key == "buffers":
        n = entry.get("byteLength", 0)
        n = n if isinstance(n, int) and not isinstance(n, bool) and n >= 0 else 0
        return n + untrusted.READ_SLACK
    return limits.limit("texture_bytes") + untrusted.READ_SLACK


def read_resource(asset: Path, uri: str, pointer: str, cap: int, what: str = "resource") -> bytes:
    """The bytes of an external resource ``uri`` of ``asset`` (``pointer`` its JSON pointer, ``/uri``
    included) through :mod:`pbrcheck.untrusted`: a relative path, percent-decoded, inside the asset's
    folder after symlinks, a regular file, at most ``cap`` bytes; :class:`AssetError` otherwise
    (a missing file's error has the :class:`FileNotFoundError` as its cause)."""
    try:
        rel = untrusted.uri_path(uri)
        f = untrusted.contained_path(asset.parent, rel)
        return untrusted.read_regular(f, cap)
    except ValueError as e:
        raise AssetError(asset, pointer, f"refused {what} {uri!r}: {e}") from None
    except OSError as e:
        f = asset.parent / urllib.parse.unquote(uri)
        raise AssetError(asset, pointer, f"missing or unreadable {what} {str(f)!r} ({os_reason(e)})") from e


def _external_uris(p: Path, raw: bytes) -> list[tuple[str, str, int]]:
    """(JSON pointer of the uri, uri, read cap) of every external buffer and image."""
    if raw[:4] == b"glTF":
        try:
            n = int.from_bytes(raw[12:16], "little")
            doc = json.loads(raw[20:20 + n].decode("utf-8"))
        except Exception:  # noqa: BLE001 - corrupt: load_asset reports it
            return []
    else:
        try:
            doc = json.loads(raw.decode("utf-8"))
        except Exception:  # noqa: BLE001
            return []
    uris = []
    for key in ("buffers", "images"):
        for k, b in enumerate(doc.get(key, []) if isinstance(doc, dict) else []):
            u = b.get("uri") if isinstance(b, dict) else None
            if isinstance(u, str) and not u.startswith("data:"):
                uris.append((f"/{key}/{k}/uri", u, resource_cap(key, b)))
    return uris


class _Reader:
    """Buffers, accessors and images of one document, with pointers for every error."""

    def __init__(self, path: Path, doc: dict, blob: bytes | None):
        self.path, self.doc, self.blob = path, doc, blob
        self._buffers: dict[int, bytes] = {}
        self._image_bytes: dict[int, tuple[bytes, str]] = {}
        self.resources: list[str] = []

    def err(self, pointer: str, problem: str) -> AssetError:
        return AssetError(self.path, pointer, problem)

    def get(self, key: str, index, pointer: str) -> dict:
        arr = self.doc.get(key, [])
        if isinstance(index, bool) or not isinstance(index, int) or not (0 <= index < len(arr)):
            raise self.err(pointer, f"index {index!r} out of range (the file has {len(arr)} {key})")
        return arr[index]

    def _uri_bytes(self, uri: str, pointer: str, what: str, cap: int) -> bytes:
        if uri.startswith("data:"):
            head, _, data = uri.partition(",")
            try:
                return base64.b64decode(data) if head.endswith(";base64") else urllib.parse.unquote_to_bytes(data)
            except Exception:  # noqa: BLE001
                raise self.err(pointer + "/uri", f"undecodable data URI of a {what}") from None
        data = read_resource(self.path, uri, pointer + "/uri", cap, what)
        self.resources.append(str(untrusted.contained_path(self.path.parent, untrusted.uri_path(uri))))
        return data

    def buffer(self, index: int, pointer: str) -> bytes:
        if index not in self._buffers:
            p = f"/buffers/{index}"
            b = self.get("buffers", index, pointer)
            if "uri" in b:
                data = self._uri_bytes(b["uri"], p, "buffer", resource_cap("buffers", b))
            elif index == 0 and self.blob is not None:
                data = self.blob
            else:
                raise self.err(p, "a buffer without uri outside a GLB's binary chunk")
            if len(data) < int(b.get("byteLength", 0)):
                raise self.err(p + "/byteLength", f"{b.get('byteLength')} bytes declared, {len(data)} present")
            self._buffers[index] = data
        return self._buffers[index]

    def view(self, index: int, pointer: str) -> tuple[bytes, int, int, int | None]:
        """(buffer bytes, byte offset, byte length, byte stride) of a buffer view."""
        v = self.get("bufferViews", index, pointer)
        decoded = gltf_features.meshopt_view(self, v, index)   # EXT_meshopt_compression
        if decoded is not None:
            return decoded
        p = f"/bufferViews/{index}"
        data = self.buffer(v.get("buffer", -1), p + "/buffer")
        off, length = int(v.get("byteOffset", 0)), int(v.get("byteLength", 0))
        if off < 0 or off + length > len(data):
            raise self.err(p, f"byte range [{off}, {off + length}) outside its buffer of {len(data)} bytes")
        return data, off, length, v.get("byteStride")

    def _elements(self, view: int, byte_offset: int, count: int, dtype, ncomp: int, pointer: str,
                  what: str) -> np.ndarray:
        data, voff, vlen, stride = self.view(view, pointer + "/bufferView")
        item = np.dtype(dtype).itemsize
        elem = item * ncomp
        stride = int(stride) if stride else elem
        need = byte_offset + (count - 1) * stride + elem if count else 0
        if byte_offset < 0 or need > vlen:
            raise self.err(pointer, f"{what} out of range: needs {need} bytes of bufferView {view}, which has {vlen}")
        if count == 0:
            return np.zeros((0, ncomp), dtype)
        return np.ndarray((count, ncomp), dtype=dtype, buffer=data, offset=voff + byte_offset,
                          strides=(stride, item)).copy()

    def accessor(self, index, pointer: str) -> np.ndarray:
        """(count, components) array, normalized integers as floats, sparse applied."""
        a = self.get("accessors", index, pointer)
        p = f"/accessors/{index}"
        ct, typ = a.get("componentType"), a.get("type")
        if ct not in COMPONENT_DTYPES:
            raise self.err(p + "/componentType", f"unknown component type {ct!r}")
        if typ not in TYPE_SIZES:
            raise self.err(p + "/type", f"unknown type {typ!r}")
        dtype, n = COMPONENT_DTYPES[ct], TYPE_SIZES[typ]
        count = a.get("count")
        if not isinstance(count, int) or count < 0:
            raise self.err(p + "/count", f"expected a count >= 0, found {count!r}")
        if "bufferView" in a:
            x = self._elements(a["bufferView"], int(a.get("byteOffset", 0)), count, dtype, n, p, "accessor")
        else:
            x = np.zeros((count, n), dtype)
        sp = a.get("sparse")
        if sp:
            k = int(sp.get("count", 0))
            ii, vv = sp.get("indices", {}), sp.get("values", {})
            ict = ii.get("componentType")
            if ict not in (5121, 5123, 5125):
                raise self.err(p + "/sparse/indices/componentType", f"unknown index type {ict!r}")
            idx = self._elements(ii.get("bufferView", -1), int(ii.get("byteOffset", 0)), k,
                                 COMPONENT_DTYPES[ict], 1, p + "/sparse/indices", "sparse indices")[:, 0]
            val = self._elements(vv.get("bufferView", -1), int(vv.get("byteOffset", 0)), k, dtype, n,
                                 p + "/sparse/values", "sparse values")
            if k and int(idx.max()) >= count:
                raise self.err(p + "/sparse/indices", f"index {int(idx.max())} out of range (count {count})")
            x = x.copy()
            x[idx.astype(np.int64)] = val
        if a.get("normalized") and dtype is not np.float32:
            bits = np.dtype(dtype).itemsize * 8
            if np.issubdtype(dtype, np.signedinteger):
                x = np.maximum(x.astype(np.float32) / float(2 ** (bits - 1) - 1), -1.0)
            else:
                x = x.astype(np.float32) / float(2 ** bits - 1)
        return x

    def image_undecoded(self, index: int) -> GltfImage:
        """An image no used texture reads: named, its format sniffed from the file name or
        ``mimeType`` alone, its data neither read nor decoded (``decoded`` False)."""
        im = self.get("images", index, f"/images/{index}")
        uri = im.get("uri") if isinstance(im.get("uri"), str) else None
        source = (uri if not uri.startswith("data:") else "data URI") if uri else f"bufferView {im.get('bufferView')}"
        mime = im.get("mimeType") or (uri.partition(";")[0][5:] if uri and uri.startswith("data:") else
                                      _MIME_BY_SUFFIX.get(Path(urllib.parse.unquote(uri or "")).suffix.lower(), "unknown"))
        return GltfImage(im.get("name", f"image{index}"), source, str(mime), np.zeros((0, 0, 4), np.uint8),
                         decoded=False)

    def image_bytes(self, index: int) -> tuple[bytes, str]:
        """(encoded bytes, source) of image ``index``, read once (the budget reads the headers first)."""
        if index not in self._image_bytes:
            self._image_bytes[index] = self._read_image(index)
        return self._image_bytes[index]

    def _read_image(self, index: int) -> tuple[bytes, str]:
        p = f"/images/{index}"
        im = self.get("images", index, p)
        if "uri" in im:
            data = self._uri_bytes(im["uri"], p, "texture image", resource_cap("images", im))
            source = im["uri"] if not im["uri"].startswith("data:") else "data URI"
        elif "bufferView" in im:
            buf, off, length, _ = self.view(im["bufferView"], p + "/bufferView")
            data = buf[off:off + length]
            source = f"bufferView {im['bufferView']}"
        else:
            raise self.err(p, "an image without uri or bufferView")
        return data, source

    def image(self, index: int) -> GltfImage:
        p = f"/images/{index}"
        im = self.get("images", index, p)
        data, source = self.image_bytes(index)
        from PIL import Image as PILImage

        sniffed = _sniff_format(bytes(data[:16]))
        if sniffed == "KTX2":   # KHR_texture_basisu (pbrcheck.gltf_features.decode_ktx2)
            return GltfImage(im.get("name", f"image{index}"), source, "image/ktx2",
                             gltf_features.decode_ktx2(self, data, p, source))
        if sniffed not in (None, "PNG", "JPEG", "WEBP"):
            raise self.err(p, f"unsupported image format {sniffed} of {source!r} (PNG, JPEG, WEBP and KTX2 are)")
        try:
            with asset_guard.pillow_unbounded(), PILImage.open(io.BytesIO(data)) as pim:
                fmt = pim.format
                if fmt not in DECODED_FORMATS:
                    raise self.err(p, f"unsupported image format {fmt} (PNG, JPEG and WEBP are)")
                if pim.mode in ("P", "PA"):
                    pim = pim.convert("RGBA")
                elif pim.mode == "CMYK":
                    pim = pim.convert("RGB")
                elif pim.mode in ("I;16", "I;16B", "I;16L", "I"):
                    arr = np.asarray(pim).astype(np.uint16)
                    return GltfImage(im.get("name", f"image{index}"), source, "image/png", arr)
                pixels = np.asarray(pim)
        except AssetError:
            raise
        except Exception as e:  # noqa: BLE001 - Pillow raises many types on corrupt data
            # Pillow's messages embed its stream's repr (<_io.BytesIO object at 0x...>): name the format instead
            what = sniffed or "an unrecognized format"
            msg = _PIL_STREAM.sub("", str(e)).strip().splitlines()
            raise self.err(p, f"unreadable texture image {source!r} ({what}; {type(e).__name__}"
                           + (f": {msg[0]}" if msg else "") + ")") from None
        if pixels.dtype == bool:
            pixels = pixels.astype(np.uint8) * 255
        mime = DECODED_FORMATS[fmt]
        return GltfImage(im.get("name", source if not source.startswith("data") else f"image{index}"), source, mime,
                         np.ascontiguousarray(pixels))


#: Image formats Pillow decodes (its format name -> MIME type): glTF's core PNG and JPEG, EXT_texture_webp's
#: WEBP (KHR_texture_basisu's KTX2: :func:`pbrcheck.gltf_features.decode_ktx2`).
DECODED_FORMATS = {"PNG": "image/png", "JPEG": "image/jpeg", "WEBP": "image/webp"}
_MIME_BY_SUFFIX = {".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg", ".webp": "image/webp",
                   ".ktx2": "image/ktx2"}
#: Leading bytes of image formats (their specifications' signatures), to name a format in errors.
_SIGNATURES = ((b"\x89PNG\r\n\x1a\n", "PNG"), (b"\xff\xd8\xff", "JPEG"), (b"\xabKTX 20\xbb\r\n\x1a\n", "KTX2"),
               (b"\xabKTX 11\xbb\r\n\x1a\n", "KTX1"), (b"DDS ", "DDS"), (b"GIF8", "GIF"), (b"BM", "BMP"))


#: Pillow's repr of the stream it was given, in its error messages (dropped: it names no file).
_PIL_STREAM = re.compile(r"\s*<_io\.BytesIO object at 0x[0-9a-fA-F]+>")


def _sniff_format(head: bytes) -> str | None:
    """The format an image's first bytes announce (WEBP: RIFF....WEBP), or None."""
    if head[:4] == b"RIFF" and head[8:12] == b"WEBP":
        return "WEBP"
    return next((name for sig, name in _SIGNATURES if head.startswith(sig)), None)


# ------------------------------------------------------------------------------------------------
# Geometry helpers
# ------------------------------------------------------------------------------------------------

def _quat_matrix(q) -> np.ndarray:
    x, y, z, w = (float(c) for c in q)
    n = math.sqrt(x * x + y * y + z * z + w * w) or 1.0
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def node_matrix(node: dict) -> np.ndarray:
    """A node's local 4x4: ``matrix`` (column-major in the file) or T * R * S."""
    if "matrix" in node:
        return np.asarray(node["matrix"], float).reshape(4, 4).T
    m = np.eye(4)
    m[:3, :3] = _quat_matrix(node.get("rotation", (0, 0, 0, 1))) * np.asarray(node.get("scale", (1, 1, 1)), float)
    m[:3, 3] = node.get("translation", (0, 0, 0))
    return m


def face_normals(pos: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Unit normals (T, 3) of counter-clockwise triangles."""
    n = np.cross(pos[tri[:, 1]] - pos[tri[:, 0]], pos[tri[:, 2]] - pos[tri[:, 0]])
    ln = np.linalg.norm(n, axis=1, keepdims=True)
    return np.where(ln > 0, n / np.maximum(ln, 1e-30), np.array([0.0, 0.0, 1.0]))


def generate_tangents(pos: np.ndarray, nrm: np.ndarray, uv: np.ndarray, tri: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """MikkTSpace tangents (the reference C implementation, :mod:`pbrcheck.mikktspace`) as glTF
    3.7.2.1 asks: computed per face corner, then the corners rewelded where vertex and tangent agree.
    Returns ``(tangents (M, 4), source (M,), tri (T, 3))``: ``source`` the input vertex of each output
    vertex (a vertex MikkTSpace splits, e.g. on a mirrored-UV seam, appears once per tangent), ``tri``
    the triangles over the output vertices. ``w = -fSign``: MikkTSpace's bitangent follows +v as
    stored, glTF's v points down the image and its bitangent ``w (N x T)`` up the image (as three.js's
    computeMikkTSpaceTangents with negateSign)."""
    tri = np.asarray(tri, dtype=np.int64)
    ct = corner_tangents(pos, nrm, uv, tri)
    ct[:, 3] = np.where(ct[:, 3] < 0, 1.0, -1.0)
    vid = tri.reshape(-1)
    key = np.concatenate([vid.astype(np.int64)[:, None],
                          np.ascontiguousarray(ct).view(np.int32).astype(np.int64)], axis=1)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)                  # output vertices in first-use order
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    return ct[first[order]], vid[first[order]], rank[inverse.reshape(-1)].reshape(-1, 3)


# ------------------------------------------------------------------------------------------------
# Materials
# ------------------------------------------------------------------------------------------------

def _texture_ref(r: _Reader, t: dict, pointer: str, *, scale_key: str | None = None) -> TextureRef:
    if not isinstance(t, dict) or "index" not in t:
        raise r.err(pointer, "a textureInfo with an index")
    tex = r.get("textures", t["index"], pointer + "/index")
    tp = f"/textures/{t['index']}"
    image = gltf_features.texture_source(r, tex, tp)
    wrap = (WRAP_REPEAT, WRAP_REPEAT)
    mag = mn = None
    if "sampler" in tex:
        s = r.get("samplers", tex["sampler"], tp + "/sampler")
        wrap = (int(s.get("wrapS", WRAP_REPEAT)), int(s.get("wrapT", WRAP_REPEAT)))
        for k, w in zip(("wrapS", "wrapT"), wrap):
            if w not in (WRAP_REPEAT, WRAP_CLAMP, WRAP_MIRROR):
                raise r.err(f"/samplers/{tex['sampler']}/{k}", f"unknown wrap mode {w}")
        mag, mn = s.get("magFilter"), s.get("minFilter")
    texcoord = int(t.get("texCoord", 0))
    transform = None
    ext = t.get("extensions", {}).get("KHR_texture_transform")
    if ext is not None:
        m = texture_transform_matrix(ext.get("offset", (0.0, 0.0)), float(ext.get("rotation", 0.0)),
                                     ext.get("scale", (1.0, 1.0)))
        transform = tuple(float(v) for v in m.reshape(-1))
        texcoord = int(ext.get("texCoord", texcoord))
    if texcoord not in (0, 1):
        raise r.err(pointer + "/texCoord", f"TEXCOORD_{texcoord} (TEXCOORD_0 and TEXCOORD_1 are supported)")
    scale = float(t.get(scale_key, 1.0)) if scale_key else 1.0
    return TextureRef(image=int(image), texcoord=texcoord, wrap=wrap, mag_filter=mag, min_filter=mn,
                      transform=transform, scale=scale, pointer=pointer)


def _material(r: _Reader, index: int) -> GltfMaterial:
    p = f"/materials/{index}"
    m = r.doc["materials"][index]
    pbr = m.get("pbrMetallicRoughness", {})
    ext = m.get("extensions", {})
    bc = tuple(float(x) for x in pbr.get("baseColorFactor", (1, 1, 1, 1)))
    if len(bc) != 4:
        raise r.err(p + "/pbrMetallicRoughness/baseColorFactor", "4 numbers")
    strength = float(ext.get("KHR_materials_emissive_strength", {}).get("emissiveStrength", 1.0))
    em = tuple(float(x) * strength for x in m.get("emissiveFactor", (0, 0, 0)))
    mode = m.get("alphaMode", "OPAQUE")
    if mode not in ALPHA_MODES:
        raise r.err(p + "/alphaMode", f"one of {', '.join(ALPHA_MODES)}, found {mode!r}")

    def tex(d, key, ptr, scale_key=None):
        return _texture_ref(r, d[key], f"{ptr}/{key}", scale_key=scale_key) if key in d else None

    return GltfMaterial(
        name=str(m.get("name", f"material{index}")),
        base_color=bc, metallic=float(pbr.get("metallicFactor", 1.0)), roughness=float(pbr.get("roughnessFactor", 1.0)),
        base_color_texture=tex(pbr, "baseColorTexture", p + "/pbrMetallicRoughness"),
        metallic_roughness_texture=tex(pbr, "metallicRoughnessTexture", p + "/pbrMetallicRoughness"),
        normal_texture=tex(m, "normalTexture", p, "scale"),
        occlusion_texture=tex(m, "occlusionTexture", p, "strength"),
        emissive=em, emissive_texture=tex(m, "emissiveTexture", p),
        alpha_mode=mode, alpha_cutoff=float(m.get("alphaCutoff", 0.5)), double_sided=bool(m.get("doubleSided", False)),
        ior=transmission_params.parse_ior(ext, p, r.err),
        unlit="KHR_materials_unlit" in ext,
        **lobe_params.parse_material_lobes(ext, p, r.err, tex),
        **transmission_params.parse_material_transmission(ext, p, r.err, tex),
    )


# ------------------------------------------------------------------------------------------------
# Primitives
# ------------------------------------------------------------------------------------------------

def _draco(r: _Reader, prim: dict, pp: str) -> dict[str, np.ndarray]:
    """Decoded attributes (and "indices") of a Draco-compressed primitive."""
    import DracoPy

    ext = prim["extensions"]["KHR_draco_mesh_compression"]
    ep = pp + "/extensions/KHR_draco_mesh_compression"
    data, off, length, _ = r.view(ext.get("bufferView", -1), ep + "/bufferView")
    try:
        mesh = DracoPy.decode(bytes(data[off:off + length]))
    except Exception as e:  # noqa: BLE001
        raise r.err(ep, f"undecodable Draco data ({e})") from None
    out: dict[str, np.ndarray] = {"indices": np.asarray(mesh.faces, np.uint32).reshape(-1)}
    for name, uid in ext.get("attributes", {}).items():
        att = mesh.get_attribute_by_unique_id(uid)
        if att is None:
            raise r.err(f"{ep}/attributes/{name}", f"no Draco attribute with id {uid}")
        arr = np.asarray(att["data"])
        out[name] = arr.reshape(arr.shape[0], -1).astype(np.float32)
    return out


def _primitive(r: _Reader, node_i: int, node: dict, mesh_i: int, mesh: dict, prim_i: int, prim: dict,
               world: np.ndarray, materials: tuple[GltfMaterial, ...], *, weights: np.ndarray | None = None,
               joint_mats: np.ndarray | None = None, worlds: list[np.ndarray] | None = None,
               variant: int | None = None) -> Primitive:
    """One (node, primitive) in world space: morph ``weights`` and the skin's ``joint_mats`` applied
    (:func:`pbrcheck.gltf_features.deform`; skinned: world space, ``world`` ignored), placed by
    ``worlds`` (GPU instances; default ``[world]``), drawn with ``variant``'s material."""
    pp = f"/meshes/{mesh_i}/primitives/{prim_i}"
    mode = prim.get("mode", 4)
    if mode != 4:
        names = {0: "POINTS", 1: "LINES", 2: "LINE_LOOP", 3: "LINE_STRIP", 5: "TRIANGLE_STRIP", 6: "TRIANGLE_FAN"}
        raise r.err(pp + "/mode", f"a non-triangle primitive ({names.get(mode, mode)}; only TRIANGLES (4) is supported)")
    attrs = prim.get("attributes", {})
    if "POSITION" not in attrs and "KHR_draco_mesh_compression" not in prim.get("extensions", {}):
        raise r.err(pp + "/attributes", "no POSITION attribute")
    if "KHR_draco_mesh_compression" in prim.get("extensions", {}):
        dec = _draco(r, prim, pp)
        data = {k: v for k, v in dec.items() if k in ATTRIBUTES}
        idx = dec["indices"]
    else:
        data = {k: r.accessor(attrs[k], f"{pp}/attributes/{k}") for k in ATTRIBUTES if k in attrs}
        idx = None
        if "indices" in prim:
            idx = r.accessor(prim["indices"], pp + "/indices")[:, 0]
    pos = data["POSITION"].astype(np.float32)
    n = pos.shape[0]
    if pos.shape[1] != 3:
        raise r.err(pp + "/attributes/POSITION", "VEC3 positions")
    bad = ~np.isfinite(pos).all(axis=1)
    if bad.any():
        raise r.err(pp + "/attributes/POSITION", f"{int(bad.sum())} non-finite (NaN or infinite) position(s), "
                    f"first at vertex {int(np.argmax(bad))}")
    asset_guard.check_positions(r.path, pp + "/attributes/POSITION", pos, "")  # before normals square them
    for k, v in data.items():
        if v.shape[0] != n:
            raise r.err(f"{pp}/attributes/{k}", f"count {v.shape[0]} differs from POSITION's {n}")
    if weights is not None or joint_mats is not None:
        data = gltf_features.deform(r, prim, pp, data, weights, joint_mats)
        pos = data["POSITION"]
        if joint_mats is not None:   # skinned: world space already (spec 3.7.3.3)
            worlds = [np.eye(4)]
    if idx is None:
        idx = np.arange(n, dtype=np.uint32)
    idx = idx.astype(np.int64)
    if idx.size % 3:
        raise r.err(pp + "/indices", f"{idx.size} indices, not a multiple of 3")
    if idx.size and idx.min() < 0:
        raise r.err(pp + "/indices", f"negative index {int(idx.min())} (indices are unsigned)")
    if idx.size and idx.max() >= n:
        raise r.err(pp + "/indices", f"index {int(idx.max())} out of range ({n} vertices)")
    tri = idx.reshape(-1, 3)
    # declared counts were checked before decoding (asset_guard.expansion); a Draco stream may decode more
    limits.check("triangles", tri.shape[0], f"{r.path}: {pp}", "triangles of one decoded primitive")
    mat_i = gltf_features.variant_material(r, prim, pp, variant)
    if mat_i >= 0:
        r.get("materials", mat_i, pp + "/material")
    mat = DEFAULT_MATERIAL if mat_i < 0 else materials[mat_i]
    for k, width in (("NORMAL", 3), ("TANGENT", 4), ("TEXCOORD_0", 2), ("TEXCOORD_1", 2)):
        if k in data and data[k].shape[1] != width:
            raise r.err(f"{pp}/attributes/{k}", f"expected {width} components, found {data[k].shape[1]}")
        if k in data and not np.isfinite(data[k]).all():
            raise r.err(f"{pp}/attributes/{k}", "non-finite values")
    for t in mat.textures().values():
        if f"TEXCOORD_{t.texcoord}" not in data:
            raise r.err(pp + "/attributes", f"no TEXCOORD_{t.texcoord}, which the material's {t.pointer} reads")

    flat = "NORMAL" not in data
    if flat:  # spec 3.7.2.1: flat normals; unweld so that every corner has its face's normal
        fn = face_normals(pos, tri)
        data = {k: v[tri.reshape(-1)] for k, v in data.items()}
        pos = data["POSITION"]
        data["NORMAL"] = np.repeat(fn, 3, axis=0).astype(np.float32)
        tri = np.arange(pos.shape[0], dtype=np.int64).reshape(-1, 3)
    nrm = data["NORMAL"].astype(np.float64)
    ln = np.linalg.norm(nrm, axis=1, keepdims=True)
    nrm = np.where(ln > 0, nrm / np.maximum(ln, 1e-30), np.array([0.0, 0.0, 1.0]))
    tan = data.get("TANGENT")
    generated = False
    if tan is None and mat.normal_texture is not None:
        tan, src, tri = generate_tangents(pos, nrm, data[f"TEXCOORD_{mat.normal_texture.texcoord}"], tri)
        data = {k: v[src] for k, v in data.items()}
        pos, nrm = data["POSITION"], nrm[src]
        generated = True

    # to world, once per GPU instance
    worlds = [world] if worlds is None else worlds
    limits.check("triangles", tri.shape[0] * len(worlds), f"{r.path}: /nodes/{node_i}",
                 "triangles of one primitive's GPU instances")
    for w in worlds:  # before the float32 cast of the placed positions overflows
        asset_guard.check_positions(r.path, f"/nodes/{node_i}", pos.astype(np.float64) @ w[:3, :3].T + w[:3, 3],
                                    "world-space ")
    wpos, wn, wt, tri = gltf_features.place(r, node_i, pos, nrm, tan, tri, worlds)
    if len(worlds) > 1:
        data = {k: np.tile(v, (len(worlds), 1)) for k, v in data.items()}
    color = data.get("COLOR_0")
    if color is not None:
        color = color.astype(np.float32)
        if color.shape[1] == 3:
            color = np.concatenate([color, np.ones((color.shape[0], 1), np.float32)], axis=1)
    nname = node.get("name") or str(node_i)
    mname = mesh.get("name") or str(mesh_i)
    return Primitive(
        name=f"{nname}/{mname}/{prim_i}", node=node_i, mesh=mesh_i, primitive=prim_i, material=mat_i,
        positions=wpos, normals=wn.astype(np.float32), indices=np.ascontiguousarray(tri, dtype=np.uint32),
        tangents=wt, texcoords=(data.get("TEXCOORD_0"), data.get("TEXCOORD_1")), color=color,
        flat_normals=flat, generated_tangents=generated, instances=len(worlds), skinned=joint_mats is not None,
        morph_weights=tuple(float(w) for w in weights) if weights is not None else ())


def _light(r: _Reader, index: int, world: np.ndarray, node_i: int) -> GltfLight:
    lights = r.doc.get("extensions", {}).get("KHR_lights_punctual", {}).get("lights", [])
    p = f"/nodes/{node_i}/extensions/KHR_lights_punctual/light"
    if not isinstance(index, int) or not 0 <= index < len(lights):
        raise r.err(p, f"light {index!r} out of range ({len(lights)} lights)")
    L = lights[index]
    lp = f"/extensions/KHR_lights_punctual/lights/{index}"
    if not isinstance(L, dict):
        raise r.err(lp, "a light object")
    typ = L.get("type")
    if typ not in LIGHT_TYPES:
        raise r.err(f"{lp}/type", f"unknown light type {typ!r} (one of {', '.join(LIGHT_TYPES)})")
    color = L.get("color", [1.0, 1.0, 1.0])
    if (not isinstance(color, list) or len(color) != 3 or not all(_finite_number(c) and c >= 0 for c in color)):
        raise r.err(f"{lp}/color", f"3 finite numbers >= 0, found {color!r}")
    intensity = L.get("intensity", 1.0)
    if not (_finite_number(intensity) and intensity >= 0):
        raise r.err(f"{lp}/intensity", f"a finite number >= 0, found {intensity!r}")
    spot = L.get("spot", {}) if typ == "spot" else {}
    inner = spot.get("innerConeAngle", DEFAULT_INNER_CONE)
    outer = spot.get("outerConeAngle", DEFAULT_OUTER_CONE)
    if not (_finite_number(outer) and 0 < outer <= math.pi / 2):
        raise r.err(f"{lp}/spot/outerConeAngle", f"an angle in (0, pi/2] radians, found {outer!r}")
    if not (_finite_number(inner) and 0 <= inner < outer):
        raise r.err(f"{lp}/spot/innerConeAngle", f"an angle in [0, outerConeAngle) radians, found {inner!r}")
    d = -world[:3, 2]  # the node's -Z in world space
    n = float(np.linalg.norm(d))
    if typ != "point" and not n > 1e-12:
        raise r.err(f"/nodes/{node_i}", f"a transform that keeps the {typ} light's -Z axis (a zero scale)")
    d = d / (n or 1.0)
    return GltfLight(name=str(L.get("name", f"light{index}")), type=typ, color=tuple(float(c) for c in color),
                     intensity=float(intensity), position=tuple(float(c) for c in world[:3, 3]),
                     direction=tuple(float(c) for c in d), range=L.get("range"), inner_cone=float(inner),
                     outer_cone=float(outer))


def _finite_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _camera(r: _Reader, index: int, world: np.ndarray, node_i: int) -> GltfCamera | None:
    cam = r.get("cameras", index, f"/nodes/{node_i}/camera")
    if cam.get("type") != "perspective":
        return None
    per = cam.get("perspective", {})
    R = world[:3, :3]
    f = -R[:, 2] / (np.linalg.norm(R[:, 2]) or 1.0)
    u = R[:, 1] / (np.linalg.norm(R[:, 1]) or 1.0)
    return GltfCamera(name=str(cam.get("name", f"camera{index}")), origin=tuple(float(c) for c in world[:3, 3]),
                      forward=tuple(float(c) for c in f), up=tuple(float(c) for c in u),
                      yfov=float(per.get("yfov", math.radians(45))), aspect=per.get("aspectRatio"),
                      znear=float(per.get("znear", 0.01)))


_CACHE: dict[tuple, Asset] = {}


def load_asset(path: str | Path, *, scene: int | None = None, variant: str | None = None) -> Asset:
    """Read ``path`` (.gltf or .glb) and resolve glTF scene ``scene`` (default: the file's ``scene``,
    else 0) into an :class:`Asset`, its primitives drawn with ``KHR_materials_variants``' ``variant``
    (None: the file's default materials). Raises :class:`AssetError`. Cached by content in this process."""
    p = Path(path)
    raw = _file_bytes(p)
    h = content_hash(p)
    key = (str(p.resolve()), h, -1 if scene is None else int(scene), variant, asset_guard.budgets_key())
    if key in _CACHE:
        return announce(_CACHE[key])
    doc, blob = _parse(p, raw)
    asset_guard.check_document(p, doc)  # malformed fields, before any is used
    r = _Reader(p, doc, blob)
    used = tuple(doc.get("extensionsUsed", []))
    required = doc.get("extensionsRequired", [])
    for k, e in enumerate(required):
        if e not in MODELLED_EXTENSIONS:
            raise r.err(f"/extensionsRequired/{k}", f"required extension {e} is not supported by pbrcheck "
                        f"(supported: {', '.join(MODELLED_EXTENSIONS)})")
    ignored = tuple(e for e in used if e not in MODELLED_EXTENSIONS)
    variant_i = gltf_features.variant_index(r, variant)
    materials = tuple(_material(r, i) for i in range(len(doc.get("materials", []))))
    wanted = gltf_features.used_images(materials)
    scenes = doc.get("scenes", [])
    si = int(scene if scene is not None else doc.get("scene", 0))
    if scenes:
        sc = r.get("scenes", si, "/scene")
        roots = sc.get("nodes", [])
    elif scene is not None:
        raise r.err("/scenes", f"scene {scene} asked for, the file has none")
    else:  # no scenes: every root node
        children = {c for n in doc.get("nodes", []) for c in n.get("children", [])}
        roots = [i for i in range(len(doc.get("nodes", []))) if i not in children]
    # the budgets judged from the JSON and the image headers, before any decoding (pbrcheck.limits)
    asset_guard.expansion(p, doc, roots, f"/scenes/{si}/nodes" if scenes else "/nodes")
    # every node's world matrix, for the joints of skins (only where a node has a skin)
    skinned = any(isinstance(n, dict) and "skin" in n for n in doc.get("nodes", []))
    worlds = gltf_features.node_worlds(r, node_matrix) if skinned else {}
    # only the images a used texture reads are read and decoded (the others named, not decoded)
    n_images = len(doc.get("images", []))
    asset_guard.check_texture_bytes(p, [asset_guard.image_header_bytes(r.image_bytes(i)[0])
                                        for i in range(n_images) if i in wanted])
    images = tuple(r.image(i) if i in wanted else r.image_undecoded(i) for i in range(n_images))
    prims: list[Primitive] = []
    lights: list[GltfLight] = []
    cameras: list[GltfCamera] = []
    hidden = 0   # meshes of nodes KHR_node_visibility hides
    stack = [(int(n), np.eye(4), (), f"/scenes/{si}/nodes", True) for n in roots]
    while stack:
        ni, parent, seen, ptr, visible = stack.pop(0)
        node = r.get("nodes", ni, ptr)
        if ni in seen:
            raise r.err(f"/nodes/{ni}/children", "a cycle in the node hierarchy")
        world = parent @ node_matrix(node)
        if not np.isfinite(world).all():
            raise r.err(f"/nodes/{ni}", "a non-finite transform")
        asset_guard.check_world_matrix(p, f"/nodes/{ni}", world)
        visible = visible and gltf_features.node_visible(r, node, ni)   # KHR_node_visibility
        hidden += int("mesh" in node and not visible)
        if "mesh" in node and visible:
            mesh = r.get("meshes", node["mesh"], f"/nodes/{ni}/mesh")
            joints = None
            inst = gltf_features.instance_matrices(r, node, ni, world, _quat_matrix)
            for pi, prim in enumerate(mesh.get("primitives", [])):
                targets = prim.get("targets", []) if isinstance(prim, dict) else []
                weights = (gltf_features.morph_weights(r, node, ni, mesh, node["mesh"], len(targets))
                           if targets else None)
                # a skin poses the primitives that have joints (as engines do: without JOINTS_0 a
                # primitive is an ordinary mesh at its node's transform)
                skinned = "skin" in node and "JOINTS_0" in (prim.get("attributes", {}) if isinstance(prim, dict) else {})
                if skinned and joints is None:
                    joints = gltf_features.skin_matrices(r, node["skin"], ni, worlds)
                prims.append(_primitive(r, ni, node, node["mesh"], mesh, pi, prim, world, materials,
                                        weights=weights, joint_mats=joints if skinned else None, worlds=inst,
                                        variant=variant_i))
        if "camera" in node:
            c = _camera(r, node["camera"], world, ni)
            if c is not None:
                cameras.append(c)
        le = node.get("extensions", {}).get("KHR_lights_punctual")
        if le is not None and visible:
            lights.append(_light(r, le.get("light"), world, ni))
        for c in node.get("children", []):
            stack.append((int(c), world, seen + (ni,), f"/nodes/{ni}/children", visible))
    if not prims:
        raise r.err(f"/scenes/{si}" if scenes else "/nodes", "no mesh primitive to render"
                    + (f" ({hidden} mesh node(s) hidden by KHR_node_visibility)" if hidden else ""))
    asset = Asset(path=str(p.resolve()), primitives=tuple(prims), materials=materials, images=images,
                  lights=tuple(lights), cameras=tuple(cameras), extensions_used=used, extensions_ignored=ignored,
                  content_hash=h, resources=tuple(dict.fromkeys(r.resources)), scene=si,
                  unmodelled=asset_unmodelled(doc, prims, [m.name for m in materials], MODELLED_EXTENSIONS,
                                               MODELLED_CORE_FEATURES, materials),
                  variants=gltf_features.variant_names(doc), variant=variant)
    _CACHE[key] = asset
    return announce(asset)
