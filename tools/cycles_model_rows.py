"""Per-metallic-row differences of a test image against a reference on a sphere-grid scene (the
``spheres`` scene's 5 metallic rows x 6 roughness columns): the measurement of docs/renderers.md
section 10 (Cycles' Principled BSDF against glTF's BRDF).

Usage::

    python tools/cycles_model_rows.py TEST.exr REFERENCE.exr [SCENE]

TEST and REFERENCE are EXRs at the scene's size (``pbrcheck render`` / ``pbrcheck reference``
output); SCENE (default ``spheres``) gives each object's material; the object ids are the
reference's ``object`` AOV. Pixels: the object's in both images (the test's own AOV where it has
one) and fully covered in the reference. Printed per row: relmse over the row's pixels (compare/
metrics.py's formula and ``REL_EPS``), the test/reference mean ratio per roughness, and each
sphere's relmse.
"""

from __future__ import annotations

import sys

import numpy as np

from compare.metrics import REL_EPS
from pbrcheck.exr import read_exr
from pbrcheck.scene import load_scene

#: The reference's coverage a pixel needs to count (silhouette pixels mix sphere and background).
FULL_COVERAGE = 0.999


def _relmse(t: np.ndarray, r: np.ndarray) -> float:
    return float(((t - r) ** 2 / (r * r + REL_EPS)).mean())


def rows(test_path: str, ref_path: str, scene_name: str = "spheres") -> dict[float, list[tuple[float, np.ndarray, np.ndarray]]]:
    """metallic -> [(roughness, test pixels, reference pixels)] per sphere."""
    test, ref = read_exr(test_path), read_exr(ref_path)
    ids = ref.channels["object"]
    test_ids = test.channels.get("object", ids)
    cov = ref.channels.get("coverage")
    out: dict[float, list] = {}
    for o in load_scene(scene_name).objects:
        m = (ids == o.id) & (test_ids == o.id)
        if cov is not None:
            m &= cov >= FULL_COVERAGE
        out.setdefault(round(o.material.metallic, 3), []).append((round(o.material.roughness, 2), test.rgb[m], ref.rgb[m]))
    return out


def main(argv: list[str]) -> int:
    if len(argv) not in (2, 3):
        print(__doc__.strip().splitlines()[3].strip(), file=sys.stderr)
        return 1
    table = rows(*argv)
    print("| metallic | relmse (row) | test / reference mean, roughness 0 .. 1 | relmse per sphere, roughness 0 .. 1 |")
    print("|---|---|---|---|")
    for met in sorted(table):
        spheres = sorted(table[met], key=lambda x: x[0])
        t = np.concatenate([s[1] for s in spheres])
        r = np.concatenate([s[2] for s in spheres])
        ratios = " / ".join(f"{s[1].mean() / s[2].mean():.3f}" for s in spheres)
        per = " / ".join(f"{_relmse(s[1], s[2]):.3f}" for s in spheres)
        print(f"| {met:.2f} | {_relmse(t, r):.4f} | {ratios} | {per} |")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
