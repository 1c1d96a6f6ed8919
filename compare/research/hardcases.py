"""Hard cases: scenes at the edges of the model, through the reference and every real-time preset.

Each case is a scene built in code (:func:`case_scenes`): roughness 0, 1e-4 and 1; grazing views;
F0 = 0 and F0 = 1; the built-in ``sun`` (radiance above the half-float maximum) and ``hotspot``; a
2 x 1 environment image (written as an EXR file in a temporary directory); very large (x 1e4) and
very small (x 1e-4) scene scales. Every case is rendered by the reference (``local`` mode, small
spp) and by every real-time preset at a small resolution; each output is checked for NaN / Inf
(colour, and the reference's variance), and the real-time error against the reference is measured
with :func:`compare.metrics.compare_images` over the valid pixels.

``run_hardcases`` returns rows ``{case, renderer, preset, finite, nonfinite, metrics | error}``;
``pbrcheck hardcases`` writes them as ``hardcases.json`` and ``hardcases.md`` (a table) and exits 1
when any output is non-finite.
"""

from __future__ import annotations

import copy
import tempfile
from pathlib import Path

import numpy as np

from pbrcheck.atomic import write_text_atomic
from pbrcheck.errors import PbrcheckError
from pbrcheck.exr import Image, write_exr
from pbrcheck.fmt import TABLE_DIGITS, format_value
from pbrcheck.jsonio import write_json_atomic
from pbrcheck.scene import Scene, load_scene, scene_from_dict

from .. import renderers
from ..metrics import compare_images
from ..verdict_spp import RESEARCH_PROBE, reference_for_verdict
from .results import HardcaseRow

#: Resolution of the hard-case renders (the command's default; the tests use 16).
DEFAULT_SIZE = 48
#: Reference samples per pixel: enough to see a gross error, not a converged image.
DEFAULT_SPP = 16
#: Most reference spp of a case (at the default 48 px, 2.4 M samples: about a second on 2 CPU cores).
SPP_CAP = 1024
#: Scales of the "very large" and "very small" scene cases.
SCALES = (1e4, 1e-4)
#: The metrics the table shows.
TABLE_METRICS = ("relmse", "rmse", "rel_p95")

_SKY = {"type": "sky", "sun_direction": [0.4, 0.6, 0.7], "sun_angular_diameter": 8.0,
        "sun_radiance": [60.0, 55.0, 48.0], "resolution": [256, 128]}


def _spheres(roughness: float, *, metallic=(0.0, 1.0), base=(0.9, 0.6, 0.3), specular=0.04, env=None,
             lights=True) -> dict:
    objs = []
    for i, m in enumerate(metallic):
        objs.append({"type": "sphere", "name": f"m{m:g}", "center": [(i - (len(metallic) - 1) / 2) * 1.1, 0, 0],
                     "radius": 0.5, "material": {"base_color": list(base), "metallic": m,
                                                 "roughness": roughness, "specular": specular}})
    d = {"camera": {"origin": [0, 0, 4], "target": [0, 0, 0], "fov": 40},
         "environment": copy.deepcopy(env or _SKY), "objects": objs}
    if lights:
        d["lights"] = [{"type": "point", "position": [-3.0, 2.0, 4.0], "intensity": [10.0, 10.0, 10.0]}]
    return d


def _grazing() -> dict:
    return {"camera": {"origin": [0, 0.04, 6], "target": [0, 0, -2], "fov": 50},
            "environment": copy.deepcopy(_SKY),
            "lights": [{"type": "point", "position": [0.0, 0.3, -6.0], "intensity": [20.0, 20.0, 20.0]}],
            "objects": [{"type": "plane", "name": "floor", "center": [0, 0, 0], "normal": [0, 1, 0],
                         "size": [40.0, 40.0],
                         "material": {"base_color": [0.8, 0.8, 0.8], "metallic": 1.0, "roughness": 0.2}},
                        {"type": "sphere", "name": "ball", "center": [0, 0.3, 0], "radius": 0.3,
                         "material": {"base_color": [0.5, 0.5, 0.5], "metallic": 0.0, "roughness": 0.05}}]}


def _scaled(d: dict, s: float) -> dict:
    """Every length times ``s``; point intensities times s^2 (same irradiance, same image)."""
    d = copy.deepcopy(d)
    cam = d["camera"]
    cam["origin"] = [x * s for x in cam["origin"]]
    cam["target"] = [x * s for x in cam.get("target", [0, 0, 0])]
    for o in d["objects"]:
        o["center"] = [x * s for x in o.get("center", [0, 0, 0])]
        if "radius" in o:
            o["radius"] *= s
        if "size" in o:
            o["size"] = [x * s for x in o["size"]]
    for l in d.get("lights", []):
        l["position"] = [x * s for x in l["position"]]
        l["intensity"] = [x * s * s for x in l["intensity"]]
    return d


def _builtin(name: str) -> dict:
    sc = load_scene(name)
    d = sc.to_dict()
    d.pop("name", None)
    d.pop("description", None)
    return d


def case_dicts(tmp_dir: Path) -> dict[str, dict]:
    """Scene tables of every hard case (the 2 x 1 environment is written into ``tmp_dir``)."""
    env2x1 = Path(tmp_dir) / "env_2x1.exr"
    write_exr(env2x1, Image.from_rgb(np.array([[[2.0, 1.0, 0.5], [0.1, 0.3, 1.5]]], np.float32)))
    return {
        "roughness_0": _spheres(0.0),
        "roughness_1e-4": _spheres(1e-4),
        "roughness_1": _spheres(1.0),
        "grazing": _grazing(),
        "f0_0": _spheres(0.3, metallic=(0.0, 1.0), base=(0.0, 0.0, 0.0), specular=0.0),
        "f0_1": _spheres(0.3, metallic=(1.0,), base=(1.0, 1.0, 1.0)),
        "sun": _builtin("sun"),
        "hotspot": _builtin("hotspot"),
        "env_2x1": _spheres(0.4, env={"type": "file", "path": str(env2x1)}),
        "scale_1e4": _scaled(_spheres(0.3), SCALES[0]),
        "scale_1e-4": _scaled(_spheres(0.3), SCALES[1]),
    }


def case_scenes(tmp_dir: Path, size: int = DEFAULT_SIZE, only: list[str] | None = None) -> dict[str, Scene]:
    """Every hard case (or those in ``only``) as a :class:`~pbrcheck.scene.Scene` of height ``size``."""
    out = {}
    for name, d in case_dicts(tmp_dir).items():
        if only and name not in only:
            continue
        d = copy.deepcopy(d)
        d["name"] = f"hardcase_{name}"
        cam = d.setdefault("camera", {})
        aspect = cam.get("width", 1) / cam.get("height", 1)
        cam["width"] = int(size) if aspect <= 1 else int(round(size * min(aspect, 2)))
        cam["height"] = int(size)
        out[name] = scene_from_dict(d)
    return out


def _nonfinite(img) -> int:
    n = int(np.count_nonzero(~np.isfinite(img.rgb)))
    v = img.variance
    if v is not None:
        n += int(np.count_nonzero(~np.isfinite(v)))
    return n


def small_cube_options(spec: renderers.RendererSpec, cube_size: int) -> dict:
    """Overrides that bake a ``cube_size`` cube for renderer ``spec`` (mip count capped to fit); none
    for an external renderer (``ext:NAME`` takes no options)."""
    if spec.external:
        return {}
    o = spec.options
    levels = min(o.prefilter_levels, int(cube_size).bit_length())
    return {"cube_size": int(cube_size), "prefilter_levels": levels,
            "irradiance_source_size": min(o.irradiance_source_size, int(cube_size))}


def run_hardcases(*, size: int = DEFAULT_SIZE, spp: int = DEFAULT_SPP, presets: list[str] | None = None,
                  cases: list[str] | None = None, cube_size: int | None = None, options: dict | None = None,
                  spp_cap: int | None = SPP_CAP, progress: bool = False,
                  context: renderers.RenderContext = renderers.DIRECT) -> list[HardcaseRow]:
    """Render every case with the reference and each preset; one row per render.

    Parameters
    ----------
    size : int, optional
        Image height in pixels.
    spp : int, optional
        Least reference samples per pixel: more (powers of two, at most ``spp_cap``) until the
        reference's noise floor is 10x below the smallest error of the presets on the case
        (:mod:`compare.verdict_spp`; the outcome is the reference row's ``reference_spp``).
    presets : list of str, optional
        Renderers under test (default: every real-time preset).
    cases : list of str, optional
        Only these cases (default: all of :func:`case_dicts`).
    cube_size : int, optional
        Bake ``cube_size``^2 cubes instead of each preset's own (:func:`small_cube_options`).
    options : dict, optional
        Further real-time option overrides for every preset.
    spp_cap : int, optional
        Most reference samples per pixel of a case (None: the verdict rule's time budget).
    progress : bool, optional
        Show render progress.

    Returns
    -------
    list of HardcaseRow
        The reference row of each case, then one row per preset.

    Raises
    ------
    PbrcheckError
        An unknown preset or case (before any render).
    """
    presets = renderers.preset_names() if presets is None else presets
    specs = {}
    for p in presets:  # presets, PRESET+FILE.glsl and ext:NAME, parsed once (raises for unknown ones)
        try:
            specs[p] = renderers.RendererSpec.parse(p)
        except PbrcheckError as e:
            raise PbrcheckError(f"hardcases: {e}") from None
    rows = []
    with tempfile.TemporaryDirectory(prefix="pbrcheck_hardcases_") as tmp:
        scenes = case_scenes(Path(tmp), size, cases)
        if cases:
            missing = sorted(set(cases) - set(scenes))
            if missing:
                raise PbrcheckError(f"hardcases: unknown case(s) {', '.join(missing)}; cases are: "
                                    f"{', '.join(case_dicts(Path(tmp)))}")
        for name, sc in scenes.items():
            # The presets first: the reference's spp is then chosen so that its noise floor sits 10x
            # below the smallest of their errors (compare.verdict_spp), at most spp_cap.
            imgs, prow = {}, []
            for p in presets:
                o = dict(small_cube_options(specs[p], cube_size) if cube_size else {})
                o.update(options or {})
                try:
                    img = renderers.render_under_test(sc, specs[p].with_options(**o), progress=progress,
                                                      context=context)
                except PbrcheckError as e:
                    prow.append(HardcaseRow(name, "realtime", p, finite=False, nonfinite=None,
                                            error=f"{type(e).__name__}: {e}"))
                    continue
                nf = _nonfinite(img)
                prow.append(HardcaseRow(name, "realtime", p, finite=nf == 0, nonfinite=nf))
                if nf == 0:
                    imgs[p] = img
            ref, verdict = reference_for_verdict(sc, list(imgs.values()), spp=spp, cap=spp_cap, mode="local",
                                                 metric="relmse", probe=RESEARCH_PROBE, tails=False, seed=0, use_cache=False,
                                                 progress=progress)
            nf = _nonfinite(ref)
            ref_ok = nf == 0
            rows.append(HardcaseRow(name, "reference", None, finite=nf == 0, nonfinite=nf,
                                    reference_spp=verdict.to_dict()))
            for row in prow:
                img = imgs.get(row.preset)
                if img is not None and ref_ok:
                    try:
                        # The table reads neither FLIP nor Delta E ITP: their maps are not computed.
                        c = compare_images(ref, img, scene=sc, noise=False, flip=False, itp=False)
                        row.metrics = {k: c.metrics[k] for k in TABLE_METRICS}
                    except PbrcheckError as e:
                        row.error = f"{type(e).__name__}: {e}"
                rows.append(row)
    return rows


def table_markdown(rows: list[HardcaseRow]) -> str:
    """The rows as a Markdown table (:data:`TABLE_METRICS`, a note for failures)."""
    head = "| case | renderer | preset | finite | " + " | ".join(TABLE_METRICS) + " | note |"
    lines = [head, "|" + " --- |" * (5 + len(TABLE_METRICS))]
    for r in rows:
        m = r.metrics or {}
        note = r.error or ("" if r.finite else f"{r.nonfinite} non-finite value(s)")
        lines.append(f"| {r.case} | {r.renderer} | {r.preset or '-'} | {'yes' if r.finite else 'NO'} | "
                     + " | ".join(format_value(m.get(k), TABLE_DIGITS) for k in TABLE_METRICS) + f" | {note} |")
    return "\n".join(lines) + "\n"


def write_hardcases(rows: list[HardcaseRow], out_dir: Path, settings: dict) -> dict[str, Path]:
    """Write ``hardcases.json`` (settings, all_finite, rows) and ``hardcases.md`` into ``out_dir``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    js = out_dir / "hardcases.json"
    write_json_atomic(js, {"settings": settings, "all_finite": all(r.finite for r in rows), "rows": rows})
    md = out_dir / "hardcases.md"
    write_text_atomic(md, table_markdown(rows))
    return {"json": js, "table": md}
