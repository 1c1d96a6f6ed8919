"""Error decomposition: every source is a measured render, and making everything exact helps."""

from __future__ import annotations

import numpy as np

from compare.explain import run_explain
from pbrcheck.scene import load_scene

# Tiny: spheres at 24 px high, 16 spp, 32^2 cubes, exact counterparts at 1/8 of their sample counts
# (still 8 x the preset's prefilter and LUT counts where those matter).
OPTS = {"cube_size": 32, "prefilter_levels": 5, "irradiance_source_size": 32, "supersample": 2}
SIZE, SPP = 24, 16


def test_explain_measures_every_source():
    # splitsum_basic (article 000) carries several approximations at once: half-float LUT with the
    # direct-lighting k, N.L-weighted prefilter, linear LOD, its composition.
    res = run_explain(load_scene("spheres"), preset="splitsum_basic", options=OPTS, spp=SPP, size=SIZE,
                      cube_max=32, samples_scale=0.125)
    names = [r["source"] for r in res["sources"]]
    assert names == ["lut", "prefilter_samples", "v=n=r", "irradiance", "cube", "terms", "composition",
                     "lod_mapping"]
    b = res["baseline"]["relmse"]
    assert np.isfinite(b) and b > 0
    for r in res["sources"]:
        assert r["error"] is None, r
        assert all(np.isfinite(v) for v in r["metrics"].values()), r
        assert r["contribution"] == b - r["metrics"]["relmse"]
    # measured, not assumed: the sources that change this preset's pixels change the error
    changed = [r["source"] for r in res["sources"] if abs(r["contribution"]) > 1e-9]
    assert {"terms", "composition", "prefilter_samples"} <= set(changed), changed
    assert res["all_exact"]["metrics"]["relmse"] <= b, res["all_exact"]
