"""Measure the real-time approximations of assets against the reference in the mode that is their
truth (issue 23, section 2): prints one relmse table per asset, a row per option.

``python tools/approximation_errors.py [--size N] [--spp N] [--env FILE.hdr] [--no-helmet]``

Assets
------
* ``bumpy``: the bench asset of :func:`reference.bench_asset.make_asset` (a UV sphere with a checker
  base colour, a roughness gradient 0.16 .. 0.94 across u, metallic on one half) with a
  high-frequency normal map built here: slopes ``(s_x, s_y) = BUMP_SLOPE (cos a sin b, sin a cos b)``,
  ``a = 2 pi BUMP_CYCLES[0] u``, ``b = 2 pi BUMP_CYCLES[1] v`` (about 2.5 pixels a cycle at 96 x 96,
  tilts up to 35 degrees). It has no occlusion texture: the occlusion rows measure the horizon only.
* ``DamagedHelmet`` (``../shared/assets``, when present): its own textures, occlusion texture included.

Both are framed as ``pbrcheck`` frames an asset (:func:`pbrcheck.scene.asset_scene`), lit by ``--env``
(default ``../shared/envmaps/royal_esplanade_1k.hdr`` when present, else the constant environment).

Rows
----
Shading approximations against the reference's ``local`` mode (no occlusion: the real-time renders
turn ``occlusion_texture`` off): ``none`` (supersample 1), each ``specular_aa``, ``msaa=4`` and
``supersample=4`` (the default preset's), all at one sample a pixel unless named. Occlusion
approximations against ``path`` (one bounce of visibility and interreflection: the reference's truth
for occlusion): the occlusion texture on the diffuse light alone, then ``specular_occlusion`` lagarde
and gtso, and ``horizon_occlusion=marmoset``, at supersample 4.

Columns: ``relmse`` and ``smape`` (bounded: a few outlier pixels, such as a sun glint, cannot
dominate it) over the pixels fully covered in both images (:func:`compare.metrics.compare_images`,
edges excluded), and ``relmse_all`` over every pixel (silhouettes and background included: what MSAA
changes). The reference's own noise: ``ref_noise``, the relmse of a second reference of another seed
against the first (a floor under which no row can be told apart). Timings are not printed (the
machine is shared); figures go to docs/realtime.md by hand.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

SHARED = Path(__file__).resolve().parent.parent.parent / "shared"
#: Cycles of the bump in u and v, and its largest slope.
BUMP_CYCLES = (48, 24)
BUMP_SLOPE = 0.7
BUMP_TEXTURE = 512

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


def bump_normal_map(size: int = BUMP_TEXTURE) -> np.ndarray:
    """The ``bumpy`` asset's tangent-space normal map, uint8 (size, size, 3) (module docstring)."""
    v, u = (np.mgrid[0:size, 0:size] + 0.5) / size
    a, b = 2 * np.pi * BUMP_CYCLES[0] * u, 2 * np.pi * BUMP_CYCLES[1] * v
    n = np.stack([-BUMP_SLOPE * np.cos(a) * np.sin(b), -BUMP_SLOPE * np.sin(a) * np.cos(b), np.ones_like(a)], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return np.round((n * 0.5 + 0.5) * 255).astype(np.uint8)


def relmse_all(ref, test) -> float:
    from compare.metrics import REL_EPS
    r, t = ref.rgb.astype(np.float64), test.rgb.astype(np.float64)
    return float(((t - r) ** 2 / (r * r + REL_EPS)).mean())


def measure(scene, name: str, spp: int, out=sys.stdout) -> None:
    from compare.metrics import compare_images
    from reference.render import render_reference
    from realtime.render import render_realtime

    def rel(ref, img):
        c = compare_images(ref, img, scene=scene, noise=False, flip=False, itp=False)
        m = c.summary["metrics"]
        return f"{m['relmse']:.5f} | {m['smape']:.5f} | {relmse_all(ref, img):.5f}"

    print(f"\n### {name} ({scene.camera.width} x {scene.camera.height}, reference {spp} spp)\n", file=out)
    print("| truth | option | relmse | smape | relmse_all |\n|---|---|---|---|---|", file=out)
    for mode, rows, base in (("local", LOCAL_ROWS, {"occlusion_texture": False}), ("path", PATH_ROWS, {})):
        print(f"{name}: reference {mode} ...", file=sys.stderr, flush=True)
        ref = render_reference(scene, spp=spp, mode=mode, progress=True)
        ref2 = render_reference(scene, spp=spp, mode=mode, seed=1, progress=False)
        print(f"| {mode} | ref_noise (seed 1 vs 0) | {rel(ref, ref2)} |", file=out, flush=True)
        for label, opts in rows:
            print(f"{name}: {mode} {label} ...", file=sys.stderr, flush=True)
            img = render_realtime(scene, "default", {**base, **opts}, progress=False)
            print(f"| {mode} | {label} | {rel(ref, img)} |", file=out, flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=96)
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--env", default=None)
    ap.add_argument("--no-helmet", action="store_true")
    args = ap.parse_args(argv)
    from pbrcheck.scene import asset_scene
    from reference.bench_asset import make_asset

    env = args.env
    default_env = SHARED / "envmaps" / "royal_esplanade_1k.hdr"
    if env is None and default_env.exists():
        env = str(default_env)
    print(f"environment: {env or 'constant 1'}", file=sys.stdout)
    size = (args.size, args.size)
    with tempfile.TemporaryDirectory(prefix="pbrcheck-approx-") as tmp:
        bumpy = make_asset(Path(tmp) / "bumpy.gltf", segments=128, tex=BUMP_TEXTURE, normal_map=bump_normal_map())
        measure(asset_scene(bumpy, env=env, size=size), "bumpy", args.spp)
    helmet = SHARED / "assets" / "DamagedHelmet" / "DamagedHelmet.gltf"
    if helmet.exists() and not args.no_helmet:
        measure(asset_scene(helmet, env=env, size=size), "DamagedHelmet", args.spp)
    return 0


if __name__ == "__main__":
    sys.exit(main())
