"""Why a fitted LOD mapping is ``regressed`` on the gate: each object's own best LOD, against the
default preset's mapping.

``python tools/lod_regions.py [STEP]`` renders compare/budgets/spheres_ci.toml with the default preset
at ``lod_override = L`` (every prefiltered lookup at level L; the default's quadratic chain) for L
over the levels in steps of STEP (default 0.25), and compares each render with the committed
reference and spheres-default's accepted baseline as the gate does (compare/baseline.py), per
object. Per roughness column it prints the default mapping's LOD, each object's best L (the scan
minimum, refined by a parabola) and the interval of L where no object of the column is significantly
worse than the baseline (``d_relmse <= GATE_Z sigma_d``). A column whose objects want LODs on both
sides of the default has no such interval beyond the default itself: any mapping that moves that
column's LOD makes an object worse, so no mapping is ``improved`` there. docs/compare.md has the output.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from compare import renderers  # noqa: E402
from compare.baseline import GATE_Z, compare_to_baseline, load_baseline  # noqa: E402
from pbrcheck.exr import read_exr  # noqa: E402
from pbrcheck.lodmap import builtin_lod  # noqa: E402
from pbrcheck.scene import load_scene  # noqa: E402

BUDGETS = ROOT / "compare" / "budgets"


def main(argv: list[str]) -> int:
    step = float(argv[0]) if argv else 0.25
    scene = load_scene(BUDGETS / "spheres_ci.toml")
    ref = read_exr(BUDGETS / "refs" / "spheres_ci.exr")
    base = load_baseline(BUDGETS, "spheres-default")
    names = {i: o.name for i, o in enumerate(scene.objects) if o.name}
    spec = renderers.RendererSpec.parse("default")
    levels = spec.options.prefilter_levels
    scan = np.arange(0.0, levels - 1 + 1e-9, step)
    rows = {}  # object -> [(L, d_relmse, sigma_d, relmse_before)]
    for L in scan:
        img = renderers.render_under_test(scene, spec.with_options(lod_override=float(L)))
        ch = compare_to_baseline(ref, base, img, names)
        for x in ch.regions:
            if x.name.startswith("object "):
                rows.setdefault(x.name, []).append((L, x.d_relmse, x.sigma_d, x.relmse_before))
        print(f"L = {L:.2f} rendered", file=sys.stderr, flush=True)
    mats = {f"object {o.name}": o.material for o in scene.objects if o.name}
    cols = sorted({m.roughness for m in mats.values()})
    print("| roughness | default LOD | objects' best LOD (metallic: L*) | L with no object worse |")
    print("|---|---|---|---|")
    for r in cols:
        lq = float(builtin_lod("quadratic", r, levels - 1, np.log2(256)))
        objs = [k for k, m in mats.items() if m.roughness == r]
        best, ok = [], np.ones(len(scan), bool)
        for k in sorted(objs, key=lambda k: mats[k].metallic):
            a = np.array(rows[k])
            rel = a[:, 3] + a[:, 1]
            i = int(np.argmin(rel))
            if 0 < i < len(scan) - 1:  # parabola through the minimum and its neighbours
                y0, y1, y2 = rel[i - 1:i + 2]
                den = y0 - 2 * y1 + y2
                li = scan[i] + (0.5 * step * (y0 - y2) / den if den > 0 else 0.0)
            else:
                li = scan[i]
            best.append(f"{mats[k].metallic:g}: {li:.2f}")
            ok &= a[:, 1] <= GATE_Z * a[:, 2]
        good = scan[ok]
        span = f"{good.min():.2f} .. {good.max():.2f}" if good.size else "none on the scan"
        print(f"| {r:g} | {lq:.2f} | {', '.join(best)} | {span} |")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
