"""The one pinhole camera both renderers use: same field-of-view axis, aspect and pixel centres.

Camera frame: ``forward = normalize(target - origin)``, ``right = normalize(forward x up)``,
``true_up = right x forward`` (right-handed; the image's +x is ``right``, its +y is ``true_up``).
``fov`` is the horizontal field of view: ``tan_x = tan(fov / 2)``, ``tan_y = tan_x * height / width``.

Pixel (row i, column j), row 0 at the **top**, sample offset (sx, sy) in [0, 1)^2 (0.5, 0.5 = the
pixel centre)::

    x_ndc = 2 (j + sx) / width - 1          (-1 at the left edge)
    y_ndc = 1 - 2 (i + sy) / height         (+1 at the top edge)
    direction = normalize(forward + x_ndc tan_x right + y_ndc tan_y true_up)

The box pixel filter of the reference integrates over (sx, sy) uniformly; the real-time renderer's
supersampling places ``s x s`` samples at ``(k + 0.5) / s``.
"""

from __future__ import annotations

import math

import numpy as np

from .scene import Camera


def camera_frame(cam: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(right, true_up, forward) unit vectors."""
    o = np.asarray(cam.origin, dtype=np.float64)
    f = np.asarray(cam.target, dtype=np.float64) - o
    f /= np.linalg.norm(f)
    r = np.cross(f, np.asarray(cam.up, dtype=np.float64))
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    return r, u, f


def tan_half_fov(cam: Camera) -> tuple[float, float]:
    """(tan_x, tan_y): horizontal fov, vertical extent from the aspect ratio."""
    tx = math.tan(math.radians(cam.fov) / 2)
    return tx, tx * cam.height / cam.width


def pixel_ndc(cam: Camera, offsets=(0.5, 0.5)) -> tuple[np.ndarray, np.ndarray]:
    """(H, W) arrays of (x_ndc, y_ndc) at the given sub-pixel offset."""
    j = np.arange(cam.width) + offsets[0]
    i = np.arange(cam.height) + offsets[1]
    x = 2.0 * j / cam.width - 1.0
    y = 1.0 - 2.0 * i / cam.height
    return np.meshgrid(x, y)


def primary_rays(cam: Camera, offsets=(0.5, 0.5)) -> tuple[np.ndarray, np.ndarray]:
    """(origin (3,), directions (H, W, 3)) through the pixels at a sub-pixel offset."""
    r, u, f = camera_frame(cam)
    tx, ty = tan_half_fov(cam)
    x, y = pixel_ndc(cam, offsets)
    d = f[None, None, :] + (x * tx)[..., None] * r + (y * ty)[..., None] * u
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    return np.asarray(cam.origin, dtype=np.float64), d


def view_matrix(cam: Camera) -> np.ndarray:
    """4x4 world -> camera (OpenGL: camera looks down -Z, +Y up, +X right)."""
    r, u, f = camera_frame(cam)
    o = np.asarray(cam.origin, dtype=np.float64)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = r, u, -f
    m[:3, 3] = -m[:3, :3] @ o
    return m


def projection_matrix(cam: Camera, near: float, far: float) -> np.ndarray:
    """4x4 OpenGL perspective projection with the same tan_x, tan_y as :func:`primary_rays`."""
    tx, ty = tan_half_fov(cam)
    m = np.zeros((4, 4))
    m[0, 0] = 1.0 / tx
    m[1, 1] = 1.0 / ty
    m[2, 2] = -(far + near) / (far - near)
    m[2, 3] = -2.0 * far * near / (far - near)
    m[3, 2] = -1.0
    return m
