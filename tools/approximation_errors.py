"""Measure the real-time approximations of assets against the reference in the mode that is their
truth (issue 23, section 2): prints one relmse table per asset, a row per option.

``python tools/approximation_errors.py [--size N] [--spp N] [--env FILE.hdr] [--no-helmet]``;
``python tools/approximation_errors.py --write-bumpy FILE.gltf`` writes the ``bumpy`` asset and exits
(for ``pbrcheck fit-normal-roughness FILE.gltf``, docs/research.md).

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

Rows and columns: :mod:`compare.approximations` (the report's asset section reads the same rows):
shading approximations against ``local``, occlusion approximations against ``path``; ``relmse``,
``smape`` and ``relmse_all``. The reference's own noise: ``ref_noise``, the relmse of a second reference of another seed
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

def bump_normal_map(size: int = BUMP_TEXTURE) -> np.ndarray:
    """The ``bumpy`` asset's tangent-space normal map, uint8 (size, size, 3) (module docstring)."""
    v, u = (np.mgrid[0:size, 0:size] + 0.5) / size
    a, b = 2 * np.pi * BUMP_CYCLES[0] * u, 2 * np.pi * BUMP_CYCLES[1] * v
    n = np.stack([-BUMP_SLOPE * np.cos(a) * np.sin(b), -BUMP_SLOPE * np.sin(a) * np.cos(b), np.ones_like(a)], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return np.round((n * 0.5 + 0.5) * 255).astype(np.uint8)


def measure(scene, name: str, spp: int, out=sys.stdout) -> None:
    """Print ``scene``'s table (:func:`compare.approximations.approximation_rows`, with each truth's
    reference noise first)."""
    from compare.approximations import TRUTHS, approximation_rows, reference_noise_row
    from reference.render import render_reference

    def fmt(r):
        return f"| {r['truth']} | {r['option']} | {r['relmse']:.5f} | {r['smape']:.5f} | {r['relmse_all']:.5f} |"

    print(f"\n### {name} ({scene.camera.width} x {scene.camera.height}, reference {spp} spp)\n", file=out)
    print("| truth | option | relmse | smape | relmse_all |\n|---|---|---|---|---|", file=out)
    refs = {}
    for mode in TRUTHS:
        print(f"{name}: reference {mode} ...", file=sys.stderr, flush=True)
        refs[mode] = render_reference(scene, spp=spp, mode=mode, progress=True)
        print(fmt(reference_noise_row(scene, mode, refs[mode], spp)), file=out, flush=True)
    for r in approximation_rows(scene, spp, references=refs,
                                progress=lambda label: print(f"{name}: {label} ...", file=sys.stderr, flush=True)):
        print(fmt(r), file=out, flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=96)
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--env", default=None)
    ap.add_argument("--no-helmet", action="store_true")
    ap.add_argument("--write-bumpy", metavar="FILE.gltf", help="write the bumpy asset and exit")
    args = ap.parse_args(argv)
    from pbrcheck.scene import asset_scene
    from reference.bench_asset import make_asset

    if args.write_bumpy:
        print(make_asset(Path(args.write_bumpy), segments=128, tex=BUMP_TEXTURE, normal_map=bump_normal_map()))
        return 0

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
