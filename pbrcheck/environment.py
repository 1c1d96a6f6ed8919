"""Environments: one radiance function that both renderers see identically.

Every environment type becomes an equirectangular float32 RGB image in **Mitsuba 3's envmap
convention**, and :meth:`EnvMap.radiance` reproduces Mitsuba's own lookup (``envmap.cpp``,
``eval_spectrum``) in numpy; the GLSL cubemap bake evaluates the same function per texel.

Convention (an image of H rows and W columns):

* direction from spherical angles: ``d = (sin(phi) sin(theta), cos(theta), -cos(phi) sin(theta))``,
  +Y up; ``u = phi / 2pi`` in [0, 1), ``v = theta / pi`` in [0, 1].
* rows: row ``r`` sits at ``theta = pi r / (H - 1)`` (the poles are the first and last rows).
* columns: column ``c`` sits at ``phi = 2 pi (c + 0.5) / W`` (Mitsuba's half-texel shift), and the
  map wraps around in phi.
* between texel centres: bilinear interpolation.
* ``scale`` multiplies the radiance; ``rotation`` (degrees) rotates the map about +Y: Mitsuba's
  ``to_world = rotate([0, 1, 0], rotation)``, so ``radiance(d) = scale * image(R^-1 d)``.

Images smaller than Mitsuba's minimum of 2 x 3 (W x H) are expanded without changing the function
they define along the axis that has one: one row becomes three equal rows, two rows ``a, b`` become
``a, (a+b)/2, b`` (the same linear interpolation in theta), one column becomes two equal columns.

Procedural environments are rasterized at these resolutions: ``constant`` and ``none`` at 16 x 8
(exact at any size), ``sky`` at ``resolution`` (default 1024 x 512), each texel the average of 8 x 8
point samples over its footprint for the sun disk (so the sun keeps its energy), and one point sample
of the smooth sky gradient.

Size: a file's pixels (from its header, before decoding: :func:`check_environment_size`) and a sky's
resolution are held to the ``env_pixels`` budget (:data:`pbrcheck.limits.MAX_ENV_PIXELS`,
``--max-env-pixels``).
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from .errors import EnvironmentMapError, PbrcheckError
from .exr import read_exr
from .scene import LDR_ENVIRONMENT_SUFFIXES, Environment, Scene

# Resolution (W, H) at which constant and black environments are rasterized: any size is exact.
CONSTANT_RESOLUTION = (16, 8)
# Point samples per texel side when rasterizing the sun disk (coverage, so the sun keeps its energy).
SUN_SUPERSAMPLING = 8


@dataclass(frozen=True)
class EnvMap:
    """An environment radiance function: ``data`` (H, W, 3) float32 unscaled, plus scale and rotation."""

    data: np.ndarray
    scale: float = 1.0
    rotation: float = 0.0
    source: str = "<environment>"

    # -- derived ---------------------------------------------------------------------------------
    @property
    def height(self) -> int:
        return int(self.data.shape[0])

    @property
    def width(self) -> int:
        return int(self.data.shape[1])

    @cached_property
    def content_hash(self) -> str:
        """SHA-256 over the pixels, shape, scale and rotation: what defines the radiance function."""
        h = hashlib.sha256()
        h.update(np.ascontiguousarray(self.data, dtype=np.float32).tobytes())
        h.update(repr((self.data.shape, float(self.scale), float(self.rotation))).encode())
        return h.hexdigest()

    @cached_property
    def max_radiance(self) -> float:
        return float(self.data.max()) * self.scale

    def to_world(self) -> np.ndarray:
        """3x3 rotation matrix about +Y by ``rotation`` degrees (Mitsuba's ``Transform4f.rotate``)."""
        return rotation_y(self.rotation)

    def radiance(self, directions: np.ndarray) -> np.ndarray:
        """Radiance arriving *from* world directions ``(..., 3)`` (need not be normalized).

        Reproduces Mitsuba's ``envmap`` ``eval``: ``d_local = R^-1 d``; ``u = atan2(x, -z) / 2pi``,
        ``v = safe_acos(y) / pi``; half-texel shift in u, wrap, bilinear on the image padded with a
        copy of its first column. Evaluated in float64, returned as float32 ``(..., 3)``.
        """
        d = np.asarray(directions, dtype=np.float64)
        shape = d.shape[:-1]
        d = d.reshape(-1, 3)
        n = np.linalg.norm(d, axis=1, keepdims=True)
        d = d / np.where(n > 0, n, 1.0)
        d = d @ self.to_world()          # row vectors: d @ R == (R^T d) == R^-1 d
        return (lookup_equirect(self.data, d) * self.scale).astype(np.float32).reshape(*shape, 3)


def rotation_y(degrees: float) -> np.ndarray:
    """Right-handed rotation about +Y (x' = cos x + sin z, z' = -sin x + cos z)."""
    a = math.radians(degrees)
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def direction_to_uv(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mitsuba's ``direction_to_uv``: ``u = atan2(x, -z) / 2pi`` in (-0.5, 0.5], ``v = acos(y) / pi``."""
    u = np.arctan2(d[..., 0], -d[..., 2]) / (2 * np.pi)
    v = np.arccos(np.clip(d[..., 1], -1.0, 1.0)) / np.pi
    return u, v


def uv_to_direction(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Inverse of :func:`direction_to_uv`."""
    theta, phi = v * np.pi, u * 2 * np.pi
    st = np.sin(theta)
    return np.stack([np.sin(phi) * st, np.cos(theta), -np.cos(phi) * st], axis=-1)


def texel_directions(width: int, height: int) -> np.ndarray:
    """(H, W, 3) directions of the texel centres of this convention (row r: theta = pi r/(H-1),
    column c: phi = 2pi (c + 0.5)/W)."""
    v = np.arange(height) / (height - 1)
    u = (np.arange(width) + 0.5) / width
    uu, vv = np.meshgrid(u, v)
    return uv_to_direction(uu, vv)


def lookup_equirect(data: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Bilinear lookup of ``data`` (H, W, C) at unit local directions ``d`` (N, 3), as Mitsuba does."""
    H, W = data.shape[:2]
    u, v = direction_to_uv(d)
    # Half-texel shift: column c is at u = (c + 0.5) / W. Then wrap to [0, 1).
    u = u - 0.5 / W
    u = u - np.floor(u)
    v = v - np.floor(v)  # v is in [0, 1]; floor(1) = 1 maps the south pole to 0 as Mitsuba does
    x = u * W            # padded width W + 1, so (res - 1) = W
    y = v * (H - 1)
    ix = np.minimum(x.astype(np.int64), W - 1)
    iy = np.minimum(y.astype(np.int64), H - 2)
    wx = (x - ix)[:, None]
    wy = (y - iy)[:, None]
    ix1 = (ix + 1) % W   # the padded column W is a copy of column 0
    v00 = data[iy, ix]
    v10 = data[iy, ix1]
    v01 = data[iy + 1, ix]
    v11 = data[iy + 1, ix1]
    v0 = (1 - wx) * v00 + wx * v10
    v1 = (1 - wx) * v01 + wx * v11
    return (1 - wy) * v0 + wy * v1


# ---------------------------------------------------------------------------------------------
# Construction
# ---------------------------------------------------------------------------------------------


def validate_pixels(data: np.ndarray, source: str) -> np.ndarray:
    """Check an environment image and bring it to (H, W, 3) float32 with H >= 3, W >= 2."""
    a = np.asarray(data)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3 or a.shape[0] < 1 or a.shape[1] < 1 or a.shape[2] not in (1, 3, 4):
        raise EnvironmentMapError(source, f"expected an (H, W, 1|3|4) image, found shape {tuple(np.shape(data))}")
    if a.shape[2] == 1:
        a = np.repeat(a, 3, axis=2)
    elif a.shape[2] == 4:
        a = a[:, :, :3]
    a = a.astype(np.float32)
    bad = ~np.isfinite(a)
    if bad.any():
        r, c, _ = np.argwhere(bad)[0]
        kind = "NaN" if np.isnan(a[r, c]).any() else "Inf"
        raise EnvironmentMapError(source, f"{int(bad.any(axis=2).sum())} pixel(s) hold NaN or Inf (first: {kind} at row {r}, column {c})")
    if (a < 0).any():
        r, c, _ = np.argwhere(a < 0)[0]
        raise EnvironmentMapError(source, f"{int((a < 0).any(axis=2).sum())} pixel(s) hold negative radiance (first at row {r}, column {c}: {a[r, c].tolist()})")
    if a.shape[1] == 1:
        a = np.repeat(a, 2, axis=1)
    if a.shape[0] == 1:
        a = np.repeat(a, 3, axis=0)
    elif a.shape[0] == 2:
        a = np.stack([a[0], 0.5 * (a[0] + a[1]), a[1]])
    return np.ascontiguousarray(a)


#: LDR environment files: 8 bits per channel, sRGB-encoded (as the Render Fidelity scenarios' .jpg
#: lighting), decoded to linear radiance in [0, 1] (the scene model's list).
LDR_SUFFIXES = LDR_ENVIRONMENT_SUFFIXES


def read_image_file(path: str | Path) -> np.ndarray:
    """Read an .exr (OpenEXR) or .hdr (Radiance RGBE, via Mitsuba's Bitmap) file as float32 (H, W, C);
    an LDR file (:data:`LDR_SUFFIXES`, via Pillow) as its RGB sRGB-decoded to linear (IEC 61966-2-1),
    alpha dropped."""
    p = Path(path)
    if not p.is_file():
        raise EnvironmentMapError(str(p), "no such file")
    suffix = p.suffix.lower()
    check_environment_size(p)  # the env_pixels budget, from the header, before decoding
    try:
        if suffix == ".exr":
            img = read_exr(p)
            return img.rgb
        if suffix == ".hdr":
            import mitsuba as mi  # heavy optional import: only .hdr files need Mitsuba's reader

            return np.array(mi.Bitmap(str(p)), dtype=np.float32)
        if suffix in LDR_SUFFIXES:
            from PIL import Image as _PIL

            from .gltf import srgb_to_linear
            with _PIL.open(p) as im:
                rgb = np.asarray(im.convert("RGB"), dtype=np.float32) / 255.0
            return srgb_to_linear(rgb).astype(np.float32)
    except EnvironmentMapError:
        raise
    except Exception as e:  # the readers raise assorted types; this is the file boundary
        raise EnvironmentMapError(str(p), f"unreadable image ({type(e).__name__}: {e})".splitlines()[0]) from None
    raise EnvironmentMapError(str(p), f"unsupported image type {suffix!r} (expected .exr, .hdr, "
                              + ", ".join(LDR_SUFFIXES) + ")")


def check_environment_size(p: Path) -> None:
    """The ``env_pixels`` budget (:mod:`pbrcheck.limits`, ``--max-env-pixels``) of an .exr / .hdr
    file, from its header alone; an unreadable header is left to the decoder's error."""
    from .exr import exr_size
    from .hdrimage import hdr_size
    from .limits import check

    size = {".exr": exr_size, ".hdr": hdr_size}.get(p.suffix.lower())
    try:
        W, H = size(p) if size else (0, 0)
    except PbrcheckError:
        return
    check("env_pixels", W * H, str(p), f"environment map of {W}x{H}")


def rasterize_sky(env: Environment) -> np.ndarray:
    """Rasterize the procedural sun-and-sky at ``env.resolution`` (see module docstring).

    Sky: ``mix(horizon, zenith, sqrt(cos theta))`` above the horizon, ``ground_radiance`` below.
    Sun: a disk of ``sun_angular_diameter`` around ``sun_direction`` with ``sun_radiance``; each
    texel holds the disk's coverage of its footprint, so small suns keep their energy.
    """
    W, H = env.resolution
    dirs = texel_directions(W, H)
    y = dirs[..., 1:2]
    zen = np.array(env.sky_radiance)
    hor = np.array(env.horizon_radiance)
    gnd = np.array(env.ground_radiance)
    sky = np.where(y >= 0, hor + (zen - hor) * np.sqrt(np.clip(y, 0, 1)), gnd)

    # Sun coverage over each texel's footprint (only the texels near the sun are supersampled).
    s = np.array(env.sun_direction, dtype=np.float64)
    s /= np.linalg.norm(s)
    cos_r = math.cos(math.radians(env.sun_angular_diameter) / 2)
    texel_rad = max(2 * math.pi / W, math.pi / (H - 1))
    near = (dirs @ s) > math.cos(math.radians(env.sun_angular_diameter) / 2 + 2 * texel_rad)
    rows, cols = np.nonzero(near)
    cover = np.zeros((H, W))
    if rows.size:
        k = SUN_SUPERSAMPLING
        off = (np.arange(k) + 0.5) / k - 0.5
        ou, ov = np.meshgrid(off, off)
        u = (cols[:, None] + 0.5 + ou.ravel()[None, :]) / W
        v = np.clip((rows[:, None] + ov.ravel()[None, :]) / (H - 1), 0.0, 1.0)
        inside = (uv_to_direction(u, v) @ s) >= cos_r
        cover[rows, cols] = inside.mean(axis=1)
    img = sky + cover[..., None] * np.array(env.sun_radiance)[None, None, :]
    return img.astype(np.float32)


def load_environment(scene_or_env: Scene | Environment) -> EnvMap:
    """The :class:`EnvMap` of a scene's environment (validated; raises EnvironmentMapError)."""
    env = scene_or_env.environment if isinstance(scene_or_env, Scene) else scene_or_env
    W, H = CONSTANT_RESOLUTION
    if env.type == "constant":
        data, src = np.broadcast_to(np.array(env.radiance, np.float32), (H, W, 3)), "<constant>"
    elif env.type == "none":
        data, src = np.zeros((H, W, 3), np.float32), "<none>"
    elif env.type == "sky":
        from .limits import check
        check("env_pixels", env.resolution[0] * env.resolution[1], "<sky>",
              f"sky environment resolution {env.resolution[0]}x{env.resolution[1]}")
        data, src = rasterize_sky(env), "<sky>"
    elif env.type == "file":
        src = str(env.path)
        data = read_image_file(src)
    else:  # pragma: no cover - the scene loader rejects other types
        raise EnvironmentMapError(None, f"unknown environment type {env.type!r}")
    return EnvMap(validate_pixels(data, src), scale=float(env.scale), rotation=float(env.rotation), source=src)


def scene_hash(scene: Scene, environment_hash: str | None = None) -> str:
    """SHA-256 of what determines the pixels: the resolved scene (less names) and the environment's
    pixels (``environment_hash``; computed by loading the environment when not given)."""
    if environment_hash is None:
        environment_hash = load_environment(scene).content_hash
    blob = json.dumps({"scene": scene.content_dict(), "environment_pixels": environment_hash},
                      sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(blob.encode()).hexdigest()
