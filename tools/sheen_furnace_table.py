"""The sheen lobe's image-based weight of each engine's form in a white furnace (radiance 1), against
the spec's directional albedo E of the sheen lobe (the sheen LUT's R channel, itself checked against a
quadrature in tests/test_realtime_lobes.py), over the sheen LUT's texel centres (n.v, sheen roughness);
prints the Markdown table of docs/realtime.md "Sheen".

``PYTHONPATH=$PWD python tools/sheen_furnace_table.py``

Each form's furnace albedo: the LUT forms their channel (times a prefiltered radiance 1); three.js
pi saturate(DG / pi) (IBLSheenBRDF times the irradiance, pi in a unit furnace); PlayCanvas saturate(DG)
(times the environment along n, 1). Row 0 (alpha at realtime.lobes.SHEEN_MIN_ALPHA) holds the albedo's
grazing spike (~3 at n.v 0.02), which sets every column's maximum.
"""

from __future__ import annotations

import numpy as np

from realtime import lobe_luts, lobes

#: Roughness from which the ratio column averages (the fits' second branch; below it the spec's albedo
#: vanishes away from grazing and ratios are noise).
RATIO_FROM_ROUGHNESS = 0.25


def main() -> None:
    L = lobe_luts.read_sheen_lut(lobe_luts.sheen_lut()).astype(np.float64)
    n = L.shape[0]
    c = (np.arange(n) + 0.5) / n
    NV, R = np.meshgrid(c, c)  # [j, i]: sheen roughness row j, n.v column i
    spec = L[..., 0]
    forms = {"`lut_neubelt` (Filament DFG.z, Sample Viewer)": L[..., 1], "`lut_ibl_sampler_legacy`": L[..., 2],
             "`threejs` (pi saturate(DG / pi) x irradiance)": np.pi * lobes.sheen_dfg_threejs(NV, R, L),
             "`playcanvas` (saturate(DG))": lobes.sheen_dfg_playcanvas(NV, R, L)}
    m = R >= RATIO_FROM_ROUGHNESS
    print(f"| form | mean abs diff | max abs diff at (n.v, r) | mean ratio to E (r >= {RATIO_FROM_ROUGHNESS}) |")
    print("| --- | --- | --- | --- |")
    for name, v in forms.items():
        d = np.abs(v - spec)
        j, i = np.unravel_index(np.argmax(d), d.shape)
        print(f"| {name} | {d.mean():.3f} | {d.max():.3f} at ({c[i]:.2f}, {c[j]:.2f}) | {np.mean(v[m] / spec[m]):.2f} |")
    print(f"\nspec E: mean {spec.mean():.3f}; albedo scaling's E, mean abs diff to the spec's: "
          f"three.js constant {lobes.THREEJS_SHEEN_ALBEDO} {np.abs(lobes.THREEJS_SHEEN_ALBEDO - spec).mean():.3f}, "
          f"Filament (G) {np.abs(L[..., 1] - spec).mean():.3f}")


if __name__ == "__main__":
    main()
