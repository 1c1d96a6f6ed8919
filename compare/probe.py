"""The engine probe: an engine's environment orientation, exposure and colour space in one render.

A renderer under test (``ext:NAME`` or a preset) renders the **probe scene**: an environment of
0.05 grey with five coloured markers of radiance :data:`MARKER_RADIANCE` (7-degree discs, rotated
:data:`PROBE_ROTATION_DEG` about +Y), seen directly and in a mirror sphere, from the origin looking
down -Z (160 x 100). Three markers lie in front of the camera (background), two behind it (seen only
in the mirror). Against pbrcheck's reference of the same scene:

- **orientation**: each marker's centroid in the background and in the mirror sphere, the engine's
  against the reference's (pixels); and the environment turn about +Y (with or without a mirror in
  u) that best explains the engine's background: for each candidate ``R`` the background the
  reference's environment would show through each background pixel's direction ``d``,
  ``env.radiance(R d)``, the mean absolute difference to the engine's on background pixels, the
  least one kept (docs/renderers.md, "A web engine in an afternoon", point 3);
- **exposure**: the median of the engine's marker cores over the markers' radiance (1: no exposure
  or IBL intensity factor) and its background's median over 0.05;
- **colour space**: ``linear`` when both levels are right; ``sRGB-encoded`` when the background
  reads the sRGB encoding of 0.05 (0.248) and the markers 1 (an output transfer left on);
  ``clamped`` when the markers read 1 or less but the background is right (a clamp or a tone map);
  ``display-referred (png-srgb)`` for an engine that declares its 8-bit output (then compared in
  display space: the levels are the reference's encoded ones).

The probe was ``tests/test_threejs.py``'s (``probe_env``, ``probe_scene``, ``centroids``); the
client tests still run it with their tolerances.

API
---
- :data:`MARKERS`, :data:`MARKER_COS`, :data:`MARKER_RADIANCE`, :data:`BACKGROUND_RADIANCE`.
- :func:`probe_env`, :func:`probe_scene` -- the marker environment file and the probe scene.
- :func:`centroids` -- the markers' centroids (row, column, pixels) in an image.
- :func:`analyse_probe` -- a :class:`ProbeResult` from the probe scene, its reference and the engine's image.
- :func:`run_probe` -- render both (through :mod:`compare.renderers`) and analyse.
- :func:`probe_markdown` -- the result as the command prints it.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from pbrcheck.camera import primary_rays
from pbrcheck.environment import load_environment, texel_directions
from pbrcheck.exr import Image, write_exr
from pbrcheck.scene import Scene, scene_from_dict

from . import renderers
from .maps import srgb_oetf
from .metrics import is_display_referred

#: World direction (before the environment's rotation) -> marker colour. The first three are in
#: front of the camera (background), the last two behind it (seen only in the mirror sphere).
MARKERS = {
    (-0.45, 0.25, -1.0): (8.0, 0.0, 0.0),
    (0.45, 0.25, -1.0): (0.0, 8.0, 0.0),
    (0.0, -0.35, -1.0): (0.0, 0.0, 8.0),
    (0.6, 0.5, 1.0): (8.0, 8.0, 0.0),
    (-0.6, -0.2, 1.0): (0.0, 8.0, 8.0),
}
#: A marker is the disc within 7 degrees of its direction.
MARKER_COS = float(np.cos(np.radians(7.0)))
#: The markers' radiance: above 1, so a clamp or a tone map shows.
MARKER_RADIANCE = 8.0
#: The environment's radiance outside the markers: its sRGB encoding (0.248) is far from it.
BACKGROUND_RADIANCE = 0.05
#: The environment's rotation in the probe scene (about +Y): a turn an engine must honour.
PROBE_ROTATION_DEG = 30.0
#: Size of the marker panorama (width x height) and of the probe image.
PROBE_ENV_SIZE = (256, 129)
PROBE_SIZE = (160, 100)
#: Samples per pixel of the probe's reference (markers and levels are far above 16-spp noise).
PROBE_SPP = 16
#: A level within this fraction of its expected value is right (the client tests: radiance 8 within
#: 3 %, the background within 5 %; an 8-bit store or a prefilter's blur leaves a few percent).
LEVEL_TOLERANCE = 0.1
#: Candidate environment turns of the orientation fit (degrees about +Y).
TURN_STEP_DEG = 2.0
#: The orientation is right when every marker's centroid lies within this many pixels of the
#: reference's (the client tests: background within 1 px, mirror within 2 to 3 px).
OFFSET_TOLERANCE_PX = 3.0
#: A marker's core: pixels above this radiance in its colour's channels (and below it in the others).
MARKER_THRESHOLD = 1.0
#: The markers' level is this percentile of the background pixels' largest channel: the three
#: background markers cover ~4 % of the probe's background (7-degree discs in an 80-degree view).
MARKER_PERCENTILE = 99.0
#: A turn of the environment explains the engine's background when it leaves at most this fraction
#: of the unturned difference (measured: a planted 90-degree turn leaves 0.3 %; a vertical flip's best
#: "turn" leaves 50 %).
TURN_EXPLAINS = 0.25


def probe_env(path: Path) -> None:
    """Write the marker panorama (equirectangular, :data:`PROBE_ENV_SIZE`) to ``path``."""
    d = texel_directions(*PROBE_ENV_SIZE)
    img = np.full(d.shape, BACKGROUND_RADIANCE, np.float32)
    for m, c in MARKERS.items():
        v = np.array(m) / np.linalg.norm(m)
        img[d @ v > MARKER_COS] = c
    write_exr(path, Image.from_rgb(img))


def probe_scene(directory: Path) -> Scene:
    """The probe scene (its panorama written to ``directory/probe.exr``): the marker environment
    rotated :data:`PROBE_ROTATION_DEG` about +Y, seen directly and in a mirror sphere, from the
    origin looking down -Z."""
    directory = Path(directory)
    probe_env(directory / "probe.exr")
    w, h = PROBE_SIZE
    return scene_from_dict({
        "name": "probe", "camera": {"origin": [0, 0, 0.0], "target": [0, 0, -1], "fov": 80.0, "width": w, "height": h},
        "environment": {"type": "file", "path": "probe.exr", "rotation": PROBE_ROTATION_DEG},
        "objects": [{"type": "sphere", "center": [0.0, 0.0, -4.0], "radius": 0.9,
                     "material": {"base_color": [1, 1, 1], "metallic": 1.0, "roughness": 0.0}}],
    }, file=str(directory / "probe.toml"), base_dir=directory)


def centroids(rgb: np.ndarray, threshold: float = MARKER_THRESHOLD) -> dict:
    """Marker colour -> (row, column, pixels) of its core in ``rgb`` (None where absent): the pixels
    above ``threshold`` exactly in the colour's channels."""
    out = {}
    for c in {tuple(v) for v in MARKERS.values()}:
        want = np.array(c) > 0
        mask = np.all((rgb > threshold) == want, axis=-1)
        ys, xs = np.nonzero(mask)
        out[c] = (ys.mean(), xs.mean(), len(ys)) if len(ys) else None
    return out


@dataclass
class ProbeResult:
    """What the probe found (module docstring): per marker and region the centroid offset in pixels
    (None: missing in one image), the best environment turn, the levels and the colour space."""

    renderer: str
    offsets: dict = field(default_factory=dict)    # "background: (8, 0, 0)" -> [drow, dcol] or None
    turn_deg: float = 0.0                          # the best turn of the lookup directions about +Y
                                                   # (360 - it: the extra [environment] rotation)
    mirrored: bool = False                         # ... with u mirrored
    turn_error: float = 0.0                        # its mean absolute background difference
    unturned_error: float = 0.0                    # the same with no turn, no mirror
    marker_ratio: float | None = None              # the engine's marker cores over MARKER_RADIANCE
    background_ratio: float | None = None          # its background over BACKGROUND_RADIANCE
    colour_space: str = "linear"
    orientation: str = ""
    lines: list = field(default_factory=list)

    def to_json(self) -> dict:
        return asdict(self)


def _background_under(env, dirs: np.ndarray, turn_deg: float, mirror: bool) -> np.ndarray:
    """The reference environment's radiance through ``dirs`` when the engine reads it turned by
    ``turn_deg`` about +Y (and mirrored in u: ``x -> -x``)."""
    a = np.radians(turn_deg)
    c, s = np.cos(a), np.sin(a)
    rot = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    d = dirs @ rot.T
    if mirror:
        d = d * np.array([-1.0, 1.0, 1.0])
    return env.radiance(d.reshape(-1, 3)).reshape(dirs.shape)


def _fit_turn(scene: Scene, img: np.ndarray, background: np.ndarray) -> tuple[float, bool, float, float]:
    """(turn, mirrored, its mean absolute difference, the unturned one) over the background pixels."""
    dirs = primary_rays(scene.camera)[1][background]
    t = img[background].astype(np.float64)
    env = load_environment(scene)
    best = (0.0, False, np.inf)
    unturned = np.inf
    for mirror in (False, True):
        for turn in np.arange(0.0, 360.0, TURN_STEP_DEG):
            err = float(np.abs(_background_under(env, dirs, float(turn), mirror) - t).mean())
            if turn == 0.0 and not mirror:
                unturned = err
            if err < best[2]:
                best = (float(turn), mirror, err)
    return best[0], best[1], best[2], unturned


def analyse_probe(scene: Scene, ref: Image, img: Image, renderer: str = "test") -> ProbeResult:
    """The probe's findings for ``img`` (the engine's render of :func:`probe_scene`) against ``ref``
    (the reference's): marker offsets, the environment turn, the levels, the colour space."""
    res = ProbeResult(renderer)
    display = is_display_referred(img)
    r_rgb = ref.rgb.astype(np.float64)
    t_rgb = img.rgb.astype(np.float64)
    if display:  # compare display values with display values (compare.metrics does the same)
        r_rgb = srgb_oetf(np.clip(r_rgb, 0.0, 1.0))
    ids = img.channels.get("object", ref.channels.get("object"))
    obj = (np.rint(ids) >= 0) if ids is not None else np.zeros(img.shape, bool)
    # The marker cores: above a threshold between the background and the markers, in each image's
    # own levels (an engine that clamps or encodes keeps its markers, at 1).
    thr_r = _threshold(r_rgb, ~obj, 0.5 if display else MARKER_THRESHOLD)
    thr_t = _threshold(t_rgb, ~obj, thr_r)
    for region, mask in (("background", ~obj), ("mirror", obj)):
        a = centroids(np.where(mask[..., None], t_rgb, 0.0), thr_t)
        b = centroids(np.where(mask[..., None], r_rgb, 0.0), thr_r)
        for c, rb in b.items():
            if rb is None or rb[2] < 4:   # not seen there in the reference (behind, or too few pixels)
                continue
            ra = a.get(c)
            res.offsets[f"{region}: {c}"] = (None if ra is None else
                                               [round(float(ra[0] - rb[0]), 2), round(float(ra[1] - rb[1]), 2)])
    # levels, from the engine's own background pixels (wherever its markers landed): the markers'
    # level is the brightest pixels' (MARKER_PERCENTILE), the background's the median (the markers
    # cover a few percent of it)
    bg = ~obj
    want_marker = 1.0 if display else MARKER_RADIANCE
    want_bg = float(srgb_oetf(np.array(BACKGROUND_RADIANCE))) if display else BACKGROUND_RADIANCE
    if bg.any():
        peak = t_rgb[bg].max(axis=-1)
        res.marker_ratio = float(np.percentile(peak, MARKER_PERCENTILE)) / want_marker
        res.background_ratio = float(np.median(t_rgb[bg])) / want_bg
    res.colour_space = _colour_space(res, display)
    if not display and bg.any() and _moved(res):  # the fit (180 turns x 2) only where it has to explain
        res.turn_deg, res.mirrored, res.turn_error, res.unturned_error = _fit_turn(scene, t_rgb, bg)
    res.orientation = _orientation(res)
    return res


def _threshold(rgb: np.ndarray, background: np.ndarray, default: float) -> float:
    """Halfway between an image's background level (the median of its background pixels' largest
    channel) and its markers' (:data:`MARKER_PERCENTILE`); ``default`` where no marker stands out."""
    v = rgb[background].max(axis=-1) if background.any() else rgb.max(axis=-1).ravel()
    lo, hi = float(np.median(v)), float(np.percentile(v, MARKER_PERCENTILE))
    return 0.5 * (lo + hi) if hi > 2.0 * lo else default


def _near(x: float | None, want: float) -> bool:
    return x is not None and abs(x - want) <= LEVEL_TOLERANCE * want


def _colour_space(res: ProbeResult, display: bool) -> str:
    if display:
        return "display-referred (png-srgb: compared in display space)"
    srgb_bg = float(srgb_oetf(np.array(BACKGROUND_RADIANCE))) / BACKGROUND_RADIANCE
    m = res.marker_ratio
    if _near(res.background_ratio, 1.0) and _near(m, 1.0):
        return "linear"
    if _near(res.background_ratio, srgb_bg) and m is not None and m * MARKER_RADIANCE <= 1.0 + LEVEL_TOLERANCE:
        return "sRGB-encoded (an output transfer is on: clamped to 1 and encoded)"
    if _near(res.background_ratio, 1.0) and m is not None and m * MARKER_RADIANCE <= 1.0 + LEVEL_TOLERANCE:
        return "clamped or tone mapped (the background is right, the markers stop at 1)"
    if m is not None and res.background_ratio is not None and _near(m / res.background_ratio, 1.0):
        return f"linear with an exposure factor of {m:.3g}"
    return "unknown (neither linear, nor sRGB-encoded, nor clamped: look at the image)"


def _moved(res: ProbeResult) -> list[str]:
    """The markers missing or further than OFFSET_TOLERANCE_PX from the reference's."""
    return [k for k, v in res.offsets.items() if v is None or max(abs(v[0]), abs(v[1])) > OFFSET_TOLERANCE_PX]


def _orientation(res: ProbeResult) -> str:
    moved = _moved(res)
    if not moved:
        return f"right: every marker within {OFFSET_TOLERANCE_PX:g} px of the reference's"
    if res.turn_error <= TURN_EXPLAINS * res.unturned_error:
        extra = (360.0 - res.turn_deg) % 360.0
        how = (f"as pbrcheck's with [environment] rotation {extra:g} degrees more"
               + (", mirrored in u" if res.mirrored else ""))
        return (f"off: {len(moved)} marker(s) moved; the engine shows the environment {how} "
                f"(mean abs. background difference {res.turn_error:.3g} against {res.unturned_error:.3g} as it is): "
                f"turn it by {-extra:g} degrees about +Y in the engine")
    return f"off: {len(moved)} marker(s) moved; no turn about +Y explains the background (a flip of the image?)"


def run_probe(spec: renderers.RendererSpec, directory: Path, *, spp: int = PROBE_SPP, use_cache: bool = True,
              context: renderers.RenderContext = renderers.DIRECT) -> tuple[ProbeResult, Image, Image]:
    """Render the probe scene in ``directory`` with the renderer ``spec`` (``ext:NAME`` or a preset,
    parsed by the caller) and the reference (``spp``); returns (result, the engine's image, the reference)."""
    scene = probe_scene(Path(directory))
    img = renderers.render_under_test(scene, spec, progress=False, context=context)
    ref = renderers.render_reference(scene, spp=spp, use_cache=use_cache, progress=False)
    return analyse_probe(scene, ref, img, spec.text), img, ref


def probe_markdown(res: ProbeResult) -> str:
    """The probe's findings, as ``pbrcheck probe`` prints them."""
    def fmt(x):
        return "-" if x is None else f"{x:.3f}"
    out = [f"# probe: {res.renderer}", "",
           f"orientation: {res.orientation}",
           f"exposure: markers {fmt(res.marker_ratio)} x, background {fmt(res.background_ratio)} x their radiance "
           f"(1: no exposure, IBL intensity or light-unit factor)",
           f"colour space: {res.colour_space}", "",
           "| marker (region: colour) | offset (rows, columns) px |", "|---|---|"]
    for k, v in res.offsets.items():
        out.append(f"| {k} | {'missing' if v is None else f'{v[0]:+.2f}, {v[1]:+.2f}'} |")
    return "\n".join(out) + "\n"


__all__ = ["BACKGROUND_RADIANCE", "MARKERS", "MARKER_COS", "MARKER_RADIANCE", "ProbeResult", "analyse_probe",
           "centroids", "probe_env", "probe_markdown", "probe_scene", "run_probe"]
