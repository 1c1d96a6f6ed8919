"""The renderers' transmission against the reference's ``path`` truth (issue 37 item 3; docs/renderers.md,
Transmission): each renderer on a transmissive scene, its error overall and per region, and for an
external engine the same render of the opaque export (the transmission extensions removed, as
:mod:`pbrcheck.unmodelled` does by default) beside the kept one.

``python -m compare.transmission_engines glass --size 96x72 --spp 256 --with default,sample_viewer,ext:threejs``
prints one Markdown row per renderer (the table of docs/renderers.md).

API
---
- :func:`regions` -- the masks of a scene's image: ``transmissive`` (objects whose material
  transmits), ``interior`` (those less their silhouette's edge pixels: the refracted lookup, its LOD
  rule and the thickness attenuation; the comparator's ``valid`` pixels of those), ``opaque`` (every other object: the ground, the screen-space
  content the engines refract), ``background``.
- :func:`measure` -- the rows: per renderer (and ``kept`` / ``opaque`` for an engine) relmse and
  FLIP per region.
- :func:`markdown` -- the rows as a Markdown table (names through :func:`pbrcheck.fmt.markdown_cell`).

The engines' renders with the extensions kept run inside :func:`pbrcheck.export.keeping_unmodelled`
(the explicit choice; their render cache bypassed); the ``opaque`` rows are the default export.
References: KHR_materials_transmission and KHR_materials_volume (Khronos glTF extension READMEs).
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from pbrcheck.export import keeping_unmodelled
from pbrcheck.fmt import markdown_cell
from pbrcheck.scene import asset_scene, load_scene

from clients.run import object_ids

from . import renderers
from .metrics import compare_images, summarize

#: The regions of :func:`regions`, in table order.
REGIONS = ("all", "transmissive", "interior", "opaque", "background")
#: The extensions that make an object transmissive (:func:`transmissive_ids`).
TRANSMISSION_FEATURES = ("KHR_materials_transmission", "KHR_materials_diffuse_transmission")
#: The metrics of each region.
METRICS = ("relmse", "flip_mean")


def transmissive_ids(scene) -> set[int]:
    """The object ids whose material has ``transmission > 0`` or ``diffuse_transmission > 0``
    (analytic objects and glTF primitives: each carries its material), and those a transmission
    extension touches while it is unmodelled for the asset (:attr:`pbrcheck.scene.Scene.unmodelled`:
    the loader left it out of the material, the engines render it when kept)."""
    out = {i for u in getattr(scene, "unmodelled", ()) if u.feature in TRANSMISSION_FEATURES for i in u.objects}
    for o in scene.objects:
        m = o.material
        if getattr(m, "transmission", 0.0) > 0.0 or getattr(m, "diffuse_transmission", 0.0) > 0.0:
            out.add(o.id)
    return out


def regions(scene, ref, cmp) -> dict[str, np.ndarray]:
    """The masks of :data:`REGIONS`. Objects from the numpy ray casting of the scene at pixel centres
    (:func:`clients.run.object_ids`, what the engines' ``object`` AOV is): the path truth's own
    ``object`` AOV numbers the spheres but leaves the glass scene's ground tiles at -1, and the
    comparator's ``valid`` mask (both AOVs agree, full coverage) is then the spheres' interior only."""
    ids = object_ids(scene)
    trans = np.isin(ids, sorted(transmissive_ids(scene)))
    finite = np.isfinite(cmp.maps.diff).all(axis=-1)
    return {"all": finite, "transmissive": finite & trans, "interior": finite & trans & cmp.valid,
            "opaque": finite & (ids >= 0) & ~trans, "background": finite & (ids < 0)}


def _row(scene, ref, img, name: str, form: str) -> dict:
    cmp = compare_images(ref, img, scene=scene, noise=False, itp=False)
    out = {"renderer": name, "export": form, "seconds": img.meta.get("seconds", "")}
    for r, mask in regions(scene, ref, cmp).items():
        s = summarize(cmp.maps, mask)
        out[r] = {k: s[k] for k in METRICS} | {"pixels": int(mask.sum())}
    return out


def measure(scene, names, *, spp: int = 256, opaque: bool = True, progress: bool = False) -> list[dict]:
    """Rows for each renderer of ``names`` (presets, ``ext:NAME``) on ``scene`` against its path truth
    at ``spp``; an engine twice (``kept`` and, with ``opaque``, ``opaque``)."""
    ref = renderers.render_reference(scene, spp=spp, mode="path", progress=progress)
    rows = []
    for n in names:
        spec = renderers.RendererSpec.parse(n)
        if spec.external:
            with keeping_unmodelled():
                rows.append(_row(scene, ref, renderers.render_under_test(scene, spec, progress=progress), n, "kept"))
            if opaque:
                rows.append(_row(scene, ref, renderers.render_under_test(scene, spec, progress=progress), n, "opaque"))
        else:
            rows.append(_row(scene, ref, renderers.render_under_test(scene, spec, progress=progress), n, "-"))
    return rows


def _fmt(x) -> str:
    return "-" if x is None else f"{x:.3g}"


def markdown(rows) -> str:
    """The rows as a Markdown table: relmse / FLIP per region."""
    head = "| renderer | export | " + " | ".join(f"{r} relmse / FLIP" for r in REGIONS) + " |"
    lines = [head, "|" + "---|" * (2 + len(REGIONS))]
    for row in rows:
        cells = [markdown_cell(row["renderer"]), row["export"]]
        cells += [f"{_fmt(row[r]['relmse'])} / {_fmt(row[r]['flip_mean'])}" for r in REGIONS]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m compare.transmission_engines", description=__doc__.splitlines()[0])
    p.add_argument("scene", help="built-in scene name, TOML path, or a .gltf/.glb asset")
    p.add_argument("--size", default="96x72", help="WxH (default 96x72)")
    p.add_argument("--spp", type=int, default=256, help="path truth samples per pixel (default 256)")
    p.add_argument("--with", dest="names", default="default,sample_viewer", help="renderers, comma-separated")
    a = p.parse_args(argv)
    w, h = (int(x) for x in a.size.lower().split("x"))
    if a.scene.endswith((".gltf", ".glb")):
        scene = asset_scene(a.scene, size=(w, h))
    else:
        scene = load_scene(a.scene).with_camera(width=w, height=h)
    print(markdown(measure(scene, [n for n in a.names.split(",") if n], spp=a.spp, progress=True)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
