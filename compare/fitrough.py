"""``pbrcheck fit-roughness``: apparent roughness of a real-time preset, through the differentiable
reference.

The real-time image of the scene is the target. Every object's roughness in the reference
(:mod:`reference.diff`: Mitsuba ``prb``, ``max_depth`` 2) is optimized jointly with Dr.Jit AD and
``mi.ad.Adam`` (L2 over the image; objects do not interact at this depth except by occluding the
environment, so the joint fit is a per-object fit). Each object starts at its own roughness; the
result ``r*`` is the roughness the reference needs to look like the preset. ``r* > r``: the preset
looks blurrier than the material it was given; ``r* < r``: sharper. The per-object loss is the final
render's MSE over the object's pixels (object AOV of the real-time image).
"""

from __future__ import annotations

import math

import numpy as np

from pbrcheck.brdf import DELTA_LOBE_ALPHA
from pbrcheck.scene import Scene

#: Lowest roughness the fit may reach. Below sqrt(DELTA_LOBE_ALPHA) = 0.01 the reference BSDF is a
#: Dirac mirror lobe (reference/bsdf.py) whose value does not depend on roughness: no derivative, and
#: Mitsuba's prb raises when no fitted parameter is attached. A mirror material's r* reads "as sharp
#: as roughness 0.01". 5 % above the threshold: 0.01 squared in float32 is 9.99e-5, still a mirror.
ROUGH_MIN = 1.05 * math.sqrt(DELTA_LOBE_ALPHA)
ITERATIONS = 40
LR = 0.03
SPP = 16


def fit_roughness(scene: Scene, target_rgb: np.ndarray, object_ids: np.ndarray, *, iterations: int = ITERATIONS,
                  lr: float = LR, spp: int = SPP, start=None) -> list[dict]:
    """Fit every object's reference roughness to ``target_rgb`` (H, W, 3); one row per object."""
    from reference.diff import (
        fit_materials,
        load_differentiable_scene,
        param_key,
        render_image,
    )
    from reference.render import _mi

    mi, _ = _mi()
    ms, params = load_differentiable_scene(scene, spp=spp)
    keys = [param_key(i, "roughness") for i in range(len(scene.objects))]
    for i, k in enumerate(keys):
        r0 = scene.objects[i].material.roughness if start is None else start[i]
        params[k] = mi.Float(float(np.clip(r0, ROUGH_MIN, 1.0)))
    params.update()
    losses = fit_materials(ms, params, keys, np.asarray(target_rgb, np.float32), iterations=iterations, lr=lr,
                           spp=spp, clamp=(ROUGH_MIN, 1.0))
    final = render_image(ms, params, spp=4 * spp, seed=10_000)
    rows = []
    for i, (ob, k) in enumerate(zip(scene.objects, keys)):
        m = np.rint(object_ids) == i
        loss = float(np.mean((final[m] - target_rgb[m]) ** 2)) if m.any() else None
        rows.append({"object": i, "name": ob.name, "roughness": float(ob.material.roughness),
                     "apparent_roughness": float(np.array(params[k]).ravel()[0]), "loss": loss,
                     "pixels": int(m.sum())})
    if rows:
        rows[0]["image_losses"] = losses  # the optimizer's trace (whole image), first row only
    return rows


def run_fit_roughness(scene: Scene, *, preset: str = "default", options: dict | None = None,
                      size: int | None = None, iterations: int = ITERATIONS, lr: float = LR, spp: int = SPP) -> dict:
    from realtime.render import render_realtime

    if size is not None:
        scene = scene.with_camera(width=max(8, int(round(size * scene.camera.width / scene.camera.height))),
                                  height=int(size))
    img = render_realtime(scene, preset, options, progress=False)
    rows = fit_roughness(scene, img.rgb, img.channels["object"], iterations=iterations, lr=lr, spp=spp)
    trace = rows[0].pop("image_losses", []) if rows else []
    return {"scene": scene.name, "preset": preset, "options": dict(options or {}), "iterations": iterations,
            "lr": lr, "spp": spp, "size": [scene.camera.width, scene.camera.height], "objects": rows,
            "image_loss_trace": trace}


def table_markdown(res: dict) -> str:
    lines = [f"scene {res['scene']}, preset {res['preset']}", "",
             "| object | roughness r | apparent r* | r* - r | loss (MSE) |", "| --- | --- | --- | --- | --- |"]
    for r in res["objects"]:
        loss = "n/a" if r["loss"] is None else f"{r['loss']:.4g}"
        lines.append(f"| {r['name'] or r['object']} | {r['roughness']:.3f} | {r['apparent_roughness']:.3f} | "
                     f"{r['apparent_roughness'] - r['roughness']:+.3f} | {loss} |")
    return "\n".join(lines) + "\n"
