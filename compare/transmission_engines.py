"""The renderers' transmission against the reference's ``path`` truth (issue 37 item 3; docs/renderers.md,
Transmission): each renderer on a transmissive scene, its error overall and per region, and for an
external engine the same render of the opaque export (the transmission extensions removed, as
:mod:`pbrcheck.unmodelled` does by default) beside the kept one.

``python -m compare.transmission_engines glass --size 96x72 --spp 256 --with default,sample_viewer,ext:threejs``
prints one Markdown row per renderer (the table of docs/renderers.md); a glTF asset instead of a scene
takes ``--env FILE.hdr`` (default the neutral constant environment).

API
---
- :func:`regions` -- the masks of a scene's image: ``transmissive`` (objects whose material
  transmits), ``interior`` (those less their silhouette's edge pixels: the refracted lookup, its LOD
  rule and the thickness attenuation; the comparator's ``valid`` pixels of those), ``opaque`` (every other object: the ground, the screen-space
  content the engines refract), ``background``.
- :func:`transmissive_ids` -- the objects whose material transmits; :func:`transmission_stripped` --
  whether the default export still strips transmission (unmodelled).
- :func:`asset_without` -- a ``.gltf`` copy without some extensions on its transmissive materials
  (a proxy truth, ``--truth-without``, where the reference leaves such a material opaque).
- :func:`measure` -- the rows: per renderer (and ``kept`` / ``opaque`` for an engine; one ``default``
  row once transmission is modelled) relmse and FLIP per region.
- :func:`markdown` -- the rows as a Markdown table (names through :func:`pbrcheck.fmt.markdown_cell`).

The engines' renders with the extensions kept run inside :func:`pbrcheck.export.keeping_unmodelled`
(the explicit choice; their render cache bypassed); the ``opaque`` rows are the default export.
References: KHR_materials_transmission and KHR_materials_volume (Khronos glTF extension READMEs).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

from pbrcheck import export, untrusted
from pbrcheck.atomic import write_bytes_atomic, write_text_atomic
from pbrcheck.errors import AssetError, SceneError
from pbrcheck.gltf import read_resource, resource_cap
from pbrcheck.export import keeping_unmodelled
from pbrcheck.fmt import markdown_cell
from pbrcheck.scene import asset_scene, load_scene
from pbrcheck.transmission_params import is_transmissive
from pbrcheck.unmodelled import strip_unmodelled

from clients.run import object_ids

from . import renderers
from .metrics import compare_images, summarize

#: The regions of :func:`regions`, in table order.
REGIONS = ("all", "transmissive", "interior", "opaque", "background")
#: The extensions that make an object transmissive (:func:`transmissive_ids`).
TRANSMISSION_FEATURES = ("KHR_materials_transmission", "KHR_materials_diffuse_transmission")
#: The metrics of each region.
METRICS = ("relmse", "flip_mean")
#: The factor of each of :data:`TRANSMISSION_FEATURES` that makes a material transmissive (its README).
_FACTORS = ("transmissionFactor", "diffuseTransmissionFactor")


def transmissive_ids(scene) -> set[int]:
    """The object ids whose material has ``transmission > 0`` or ``diffuse_transmission > 0``
    (analytic objects and glTF primitives: each carries its material), and the glTF primitives whose
    glTF material transmits (:func:`pbrcheck.transmission_params.is_transmissive`: its parsed
    extensions, whether or not the honesty contract names them unmodelled and the loader left them
    out of the scene material; an extension present with factor 0, as IridescenceSuzanne's two
    opaque heads, does not count)."""
    out = set()
    for o in scene.objects:
        m = o.material
        if getattr(m, "transmission", 0.0) > 0.0 or getattr(m, "diffuse_transmission", 0.0) > 0.0:
            out.add(o.id)
        elif getattr(o, "gltf_material", None) is not None and \
                is_transmissive(scene.assets[o.instance].asset.material(o.gltf_material)):
            out.add(o.id)
    return out


def transmission_stripped() -> bool:
    """Whether the engines' default export removes ``KHR_materials_transmission`` (unmodelled in the
    honesty contract: :func:`pbrcheck.unmodelled.strip_unmodelled` over the export's modelled set).
    Once transmission is modelled the default export keeps it: the ``opaque`` rows would repeat the
    ``kept`` ones, and :func:`measure` labels its one row per engine ``default``."""
    doc = {"materials": [{"name": "probe", "extensions": {TRANSMISSION_FEATURES[0]: {"transmissionFactor": 1.0}}}]}
    return bool(strip_unmodelled(doc, export.SUPPORTED_EXTENSIONS))


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


def asset_without(path, extensions, folder) -> Path:
    """A copy of the ``.gltf`` at ``path`` in ``folder`` (its external files copied beside it: the
    loader reads resources inside the asset's own folder only) whose transmissive materials
    (``transmissionFactor`` or ``diffuseTransmissionFactor`` above 0) lack ``extensions``: a proxy
    truth where the reference does not render such a material with them (IridescenceSuzanne's glass,
    whose iridescence thickness texture leaves it opaque in the reference). :class:`AssetError` where
    no such material carries them (the proxy would be the asset itself)."""
    src, out = Path(path), Path(folder)
    doc = json.loads(src.read_text())
    removed = 0
    for m in doc.get("materials", []):
        ext = m.get("extensions", {})
        if any(ext.get(e, {}).get(k, 0.0) > 0.0 for e, k in zip(TRANSMISSION_FEATURES, _FACTORS)):
            removed += sum(ext.pop(e, None) is not None for e in extensions)
    if not removed:
        raise AssetError(src, "/materials", f"no transmissive material carries {', '.join(extensions)}")
    for key in ("buffers", "images"):
        for i, r in enumerate(doc.get(key, [])):
            if "uri" in r and not r["uri"].startswith("data:"):
                data = read_resource(src, r["uri"], f"/{key}/{i}/uri", resource_cap(key, r))   # checked relative
                write_bytes_atomic(out / untrusted.uri_path(r["uri"]), data)
    return write_text_atomic(out / src.name, json.dumps(doc))


def measure(scene, names, *, spp: int = 256, opaque: bool = True, progress: bool = False, truth=None) -> list[dict]:
    """Rows for each renderer of ``names`` (presets, ``ext:NAME``) on ``scene`` against its path truth
    at ``spp`` (``truth``: that scene's instead, the same camera; :func:`asset_without`'s proxy); an
    engine twice (``kept`` and, with ``opaque``, ``opaque``) while the default export strips
    transmission (:func:`transmission_stripped`), once (``default``: the extensions are then modelled
    and exported as they are) after."""
    if truth is not None and truth.camera != scene.camera:
        raise SceneError(getattr(truth, "source", None), "camera", f"the measured scene's camera {scene.camera}",
                         truth.camera)
    ref = renderers.render_reference(scene if truth is None else truth, spp=spp, mode="path", progress=progress)
    stripped = transmission_stripped()
    rows = []
    for n in names:
        spec = renderers.RendererSpec.parse(n)
        if spec.external:
            with keeping_unmodelled():   # a no-op once nothing transmissive is unmodelled
                rows.append(_row(scene, ref, renderers.render_under_test(scene, spec, progress=progress), n,
                                 "kept" if stripped else "default"))
            if opaque and stripped:
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
    p.add_argument("--env", default=None, help="an asset's environment (.hdr / .exr; default the neutral constant 1)")
    p.add_argument("--truth-without", default="", metavar="EXT,...",
                   help="a .gltf's proxy truth: rendered from a copy whose transmissive materials lack these "
                        "extensions (asset_without); the renderers still render the asset itself")
    a = p.parse_args(argv)
    w, h = (int(x) for x in a.size.lower().split("x"))
    names = [n for n in a.names.split(",") if n]
    if a.truth_without and not a.scene.endswith(".gltf"):
        p.error("--truth-without needs a .gltf asset")
    if a.scene.endswith((".gltf", ".glb")):
        scene = asset_scene(a.scene, size=(w, h), env=a.env)
    else:
        scene = load_scene(a.scene).with_camera(width=w, height=h)
    if not a.truth_without:
        print(markdown(measure(scene, names, spp=a.spp, progress=True)))
        return 0
    with tempfile.TemporaryDirectory() as d:
        proxy = asset_without(a.scene, [e for e in a.truth_without.split(",") if e], d)
        truth = asset_scene(proxy, size=(w, h), env=a.env)
        print(markdown(measure(scene, names, spp=a.spp, progress=True, truth=truth)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
