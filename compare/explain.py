"""``pbrcheck explain``: attribute a preset's error to its approximations, by measurement.

The preset is rendered and compared with the reference (:func:`compare.metrics.compare_images`, over
valid pixels). Then one approximation at a time is replaced by its exact (or much more accurate)
counterpart through real-time options (:data:`SOURCES`), the scene re-rendered and re-measured.
A source's *contribution* is ``error(preset) - error(preset with that source made exact)``: positive
when the approximation costs accuracy, near zero when it does not matter here, negative when the
approximation happens to cancel another one. Finally every fix except ``v=n=r`` is applied at once
(``all_exact``). Nothing is assumed: every row is a render.

Sources and their exact counterparts:

* ``lut``: DFG term from a 256^2 RG32F LUT at 16384 samples per texel (replaces a small or half-float
  LUT, or Karis's analytic fit).
* ``prefilter_samples``: 8192 samples per prefiltered texel, filtered importance sampling.
* ``v=n=r``: the split sum's prefiltered lobe assumes v = n = r; replaced by runtime importance
  sampling (GGX visible normals, 1024 samples per pixel, mip-filtered lookups). The renderer's
  runtime path composes with article 001's formulas (F0 clamped to [0.02, 0.99], diffuse without
  the Fresnel weight), so this row measures that composition too; it is left out of ``all_exact``.
* ``lod_mapping``: the built-in mapping that measures best on this scene (or ``--fitted FILE``'s
  fitted mapping when given and better).
* ``irradiance``: cube convolution summing every texel of a 64^2 source into a 64^2 cube.
* ``cube``: a 512^2 float32 environment cube (texel resolution and half-float precision).
* ``terms``: the scene's own D, G and F terms, in the frame and in the LUT.
* ``composition``: the README material model's composition (``shading=material``, correct
  reflection vector, no roughness clamp) instead of an article's.
"""

from __future__ import annotations

from pathlib import Path

from pbrcheck.errors import PbrcheckError
from pbrcheck.scene import Scene

#: Reference samples per pixel (command default).
DEFAULT_SPP = 64
#: The metric the contributions are computed on (all metrics are kept in the JSON).
PRIMARY = "relmse"
KEEP = ("relmse", "rmse", "rel_p95", "flip_mean")


def sources(o: dict, *, cube_max: int = 512, samples_scale: float = 1.0) -> dict[str, dict]:
    """Option overrides that make each approximation exact (``samples_scale`` < 1 for tests)."""
    import math

    cube = min(cube_max, 4096)
    levels = max(1, min(cube.bit_length(), o["prefilter_levels"] + int(math.log2(cube / o["cube_size"]))))
    irr_src = min(64, o["cube_size"])
    s = lambda n: max(16, int(n * samples_scale))  # noqa: E731
    return {
        "lut": {"dfg": "lut", "lut_size": 256 if samples_scale >= 1 else 64, "lut_format": "f32",
                "lut_samples": s(16384), "lut_sampling": "vndf"},
        "prefilter_samples": {"prefilter_samples": s(8192), "prefilter_filtered": True,
                              "prefilter_nl_weight": False},
        "v=n=r": {"ibl": "runtime", "runtime_samples": s(1024), "runtime_sampling": "vndf", "runtime_lod": True,
                  "runtime_rotate": True},
        "irradiance": {"irradiance": "convolution", "irradiance_method": "texel_sum", "irradiance_size": 64,
                       "irradiance_source_size": irr_src},
        "cube": {"cube_size": cube, "cube_format": "f32",
                 "prefilter_levels": levels,
                 "irradiance_source_size": min(o["irradiance_source_size"], cube)},
        "terms": {"ndf": "scene", "geometry": "scene", "fresnel": "scene", "lut_geometry": "scene"},
        "composition": {"shading": "material", "reflect_bug": False, "min_roughness": 0.0},
    }


def run_explain(scene: Scene, *, preset: str = "default", options: dict | None = None, spp: int = DEFAULT_SPP,
                size: int | None = None, fitted: str | None = None, cube_max: int = 512,
                samples_scale: float = 1.0, progress: bool = False) -> dict:
    from realtime.presets import resolve_options
    from realtime.render import render_realtime
    from reference.render import render_reference

    from .metrics import compare_images

    base = dict(options or {})
    o = resolve_options(preset, base)
    if size is not None:
        scene = scene.with_camera(width=max(8, int(round(size * scene.camera.width / scene.camera.height))),
                                  height=int(size))
    ref = render_reference(scene, spp=spp, mode="local", progress=progress)

    def measure(over: dict) -> dict:
        img = render_realtime(scene, preset, {**base, **over}, progress=False)
        c = compare_images(ref, img, scene=scene, noise=False)
        return {k: c.metrics[k] for k in KEEP}

    baseline = measure({})
    rows = []
    srcs = sources(o, cube_max=cube_max, samples_scale=samples_scale)
    if o["ibl"] == "runtime":
        # Already runtime sampling: the exact counterpart of its sample count and distribution.
        srcs["v=n=r"] = {"runtime_samples": srcs["v=n=r"]["runtime_samples"], "runtime_sampling": "vndf"}
        srcs.pop("composition")  # runtime sampling only exists with article 001's composition
    for name, over in srcs.items():
        try:
            m = measure(over)
        except PbrcheckError as e:
            rows.append({"source": name, "options": over, "metrics": None, "contribution": None,
                         "error": f"{type(e).__name__}: {e}"})
            continue
        rows.append({"source": name, "options": over, "metrics": m,
                     "contribution": baseline[PRIMARY] - m[PRIMARY], "error": None})
    # LOD mapping: the best measured built-in (or the fitted file).
    if o["ibl"] == "splitsum":
        cands = {n: {"lod_mapping": n} for n in ("linear", "quadratic", "log2")}
        if fitted:
            cands["fitted"] = {"lod_mapping": f"fitted:{fitted}"}
        best = None
        for n, over in cands.items():
            m = measure(over)
            if best is None or m[PRIMARY] < best[1][PRIMARY]:
                best = (over, m)
        rows.append({"source": "lod_mapping", "options": best[0], "metrics": best[1],
                     "contribution": baseline[PRIMARY] - best[1][PRIMARY], "error": None})
    # Everything but v=n=r at once.
    allo = {}
    fitted_lod = any(r["source"] == "lod_mapping" and str(r["options"]["lod_mapping"]).startswith("fitted:")
                     for r in rows)
    for r in rows:
        if r["source"] == "v=n=r" or r["metrics"] is None or (fitted_lod and r["source"] == "cube"):
            continue  # a fitted mapping holds for its own cube size and mip count only
        allo.update(r["options"])
    if o["ibl"] == "runtime":
        allo.update(srcs["v=n=r"])
    m_all = measure(allo)
    return {"scene": scene.name, "preset": preset, "options": base, "spp": spp,
            "size": [scene.camera.width, scene.camera.height], "metric": PRIMARY,
            "baseline": baseline, "sources": rows,
            "all_exact": {"options": allo, "metrics": m_all, "contribution": baseline[PRIMARY] - m_all[PRIMARY]}}


def table_markdown(res: dict) -> str:
    def f(v):
        return "n/a" if v is None else f"{v:.4g}"

    b = res["baseline"][PRIMARY]
    lines = [f"scene {res['scene']}, preset {res['preset']}: {PRIMARY} {f(b)} against the {res['spp']}-spp reference",
             "", f"| source made exact | {PRIMARY} after | contribution | share of {PRIMARY} | flip_mean after |",
             "| --- | --- | --- | --- | --- |"]
    for r in res["sources"] + [{"source": "all_exact (all but v=n=r)", **res["all_exact"], "error": None}]:
        m = r["metrics"] or {}
        share = None if r["contribution"] is None or b <= 0 else 100 * r["contribution"] / b
        lines.append(f"| {r['source']} | {f(m.get(PRIMARY))} | {f(r['contribution'])} | "
                     f"{'n/a' if share is None else f'{share:.1f} %'} | {f(m.get('flip_mean'))} |"
                     + (f" {r['error']}" if r.get("error") else ""))
    return "\n".join(lines) + "\n"


def write_explain(res: dict, out: Path) -> Path:
    from .commands import dump_json

    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(dump_json(res) + "\n", encoding="utf-8")
    out.with_suffix(".md").write_text(table_markdown(res), encoding="utf-8")
    return out
