"""The real-time approximations of assets measured against the reference in the mode that is their
truth (issue 23, section 2): one row per option, per material. ``tools/approximation_errors.py``
prints these rows; the report's asset section (:mod:`compare.report.scene`) shows them.

Rows
----
Shading approximations against the reference's ``local`` mode (no visibility: the real-time renders
turn ``occlusion_texture`` off, :data:`LOCAL_BASE`): no anti-aliasing at supersample 1, each
``specular_aa``, ``msaa=4``, ``supersample=4`` and supersample 4 with ``prefiltered`` (:data:`LOCAL_ROWS`).
Occlusion approximations against ``path`` (visibility and interreflection: the truth the occlusion
texture approximates): no occlusion, the occlusion texture on the diffuse light, then
``specular_occlusion`` lagarde and gtso, ``horizon_occlusion=marmoset`` and both (:data:`PATH_ROWS`),
at the preset's supersampling.

Each row: ``relmse`` and ``smape`` (bounded: a few outlier pixels, such as a mirror's sub-pixel
glint of the sun, cannot dominate it) over the pixels fully covered in both images
(:func:`compare.metrics.compare_images`, edges excluded), ``relmse_all`` over every pixel
(silhouettes and background included: what MSAA changes), and the same two metrics per glTF
material. :func:`reference_noise_row` is the floor: a second reference of another seed against the
first.

API: :func:`approximation_rows`, :func:`reference_noise_row`, :func:`relmse_all`, :data:`LOCAL_ROWS`,
:data:`PATH_ROWS`, :data:`LOCAL_BASE`, :data:`TRUTHS`.
"""

from __future__ import annotations

import numpy as np

from .metrics import REL_EPS, compare_images

LOCAL_ROWS = [
    ("none (ss 1)", {"supersample": 1}),
    ("specular_aa=toksvig", {"supersample": 1, "specular_aa": "toksvig"}),
    ("specular_aa=screen_space", {"supersample": 1, "specular_aa": "screen_space"}),
    ("specular_aa=prefiltered", {"supersample": 1, "specular_aa": "prefiltered"}),
    ("msaa=4", {"supersample": 1, "msaa": 4}),
    ("supersample=4", {"supersample": 4}),
    ("supersample=4, specular_aa=prefiltered", {"supersample": 4, "specular_aa": "prefiltered"}),
]
PATH_ROWS = [
    ("no occlusion", {"occlusion_texture": False}),
    ("occlusion_texture (diffuse)", {}),
    ("+ specular_occlusion=lagarde", {"specular_occlusion": "lagarde"}),
    ("+ specular_occlusion=gtso", {"specular_occlusion": "gtso"}),
    ("+ horizon_occlusion=marmoset", {"horizon_occlusion": "marmoset"}),
    ("+ gtso + marmoset", {"specular_occlusion": "gtso", "horizon_occlusion": "marmoset"}),
]
#: Options under every ``local`` row: the occlusion texture approximates visibility, which ``local`` lacks.
LOCAL_BASE = {"occlusion_texture": False}
#: Reference mode -> (rows, options under every row).
TRUTHS = {"local": (LOCAL_ROWS, LOCAL_BASE), "path": (PATH_ROWS, {})}
#: The per-material metrics of a row.
MATERIAL_ROW_METRICS = ("relmse", "smape")


def relmse_all(ref, test) -> float:
    """Relative MSE over every pixel (coverage, silhouettes and background included)."""
    r, t = ref.rgb.astype(np.float64), test.rgb.astype(np.float64)
    return float(((t - r) ** 2 / (r * r + REL_EPS)).mean())


def _row(scene, mode: str, label: str, ref, img) -> dict:
    c = compare_images(ref, img, scene=scene, noise=False, flip=False, itp=False)
    m = c.summary["metrics"]
    return {"truth": mode, "option": label, "relmse": m["relmse"], "smape": m["smape"],
            "relmse_all": relmse_all(ref, img),
            "materials": [{"material": x["material"], "pixels": x["pixels"],
                           **{k: x["metrics"].get(k) for k in MATERIAL_ROW_METRICS}}
                          for x in c.summary.get("materials", [])]}


def reference_noise_row(scene, mode: str, ref, spp: int) -> dict:
    """The floor of ``mode``'s rows: a reference of seed 1 against ``ref`` (seed 0)."""
    from reference.render import render_reference
    return _row(scene, mode, "ref_noise (seed 1 vs 0)", ref,
                render_reference(scene, spp=spp, mode=mode, seed=1, progress=False))


def approximation_rows(scene, spp: int, *, preset: str = "default", references: dict | None = None,
                       progress=None) -> list[dict]:
    """Every row of :data:`TRUTHS` for ``scene`` (an asset scene; the real-time renders use the raster
    pipeline), each against a reference of ``spp`` in its truth mode (``references``: mode -> image
    already rendered, else rendered here, cached). ``progress(label)`` is called before each render.
    Returns ``[{"truth", "option", "relmse", "smape", "relmse_all", "materials": [{"material",
    "pixels", "relmse", "smape"}]}]``."""
    from realtime.render import render_realtime
    from reference.render import render_reference

    out = []
    for mode, (rows, base) in TRUTHS.items():
        ref = (references or {}).get(mode)
        if ref is None:
            if progress:
                progress(f"reference {mode} ({spp} spp)")
            ref = render_reference(scene, spp=spp, mode=mode, progress=False)
        for label, opts in rows:
            if progress:
                progress(f"{mode}: {label}")
            img = render_realtime(scene, preset, {**base, **opts, "pipeline": "raster"}, progress=False)
            out.append(_row(scene, mode, label, ref, img))
    return out


__all__ = ["LOCAL_BASE", "LOCAL_ROWS", "MATERIAL_ROW_METRICS", "PATH_ROWS", "TRUTHS", "approximation_rows",
           "reference_noise_row", "relmse_all"]
