"""pbrcheck energy (compare/research/energy.py): the albedo grid against the random walk, the
tables, the plot and the CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest

from compare.research import energy
from pbrcheck import cli
from realtime.registry import ENERGY_COMPENSATIONS


def test_albedo_grid_small(tmp_path):
    res = energy.run_energy(roughness=(0.0, 0.5, 1.0), f0=(0.5, 1.0), nov=(0.2, 1.0), samples=4096, images=False)
    walk = np.asarray(res.walk)
    assert walk.shape == (3, 2, 2)
    # F0 = 1: the walk conserves energy; every compensation restores it by construction.
    np.testing.assert_allclose(walk[:, 1, :], 1.0, atol=1e-6)
    for c in ENERGY_COMPENSATIONS.names[1:]:
        np.testing.assert_allclose(np.asarray(res.albedo[c])[:, 1, :], 1.0, atol=1e-6)
    s = {x.compensation: x for x in res.summaries}
    # Single scattering loses the most; every compensation does better on this grid.
    assert all(s[c].mean_abs < s["none"].mean_abs for c in ENERGY_COMPENSATIONS.names[1:])
    assert res.best() != "none"
    paths = energy.write_energy(res, tmp_path)
    assert json.loads(paths["json"].read_text())["summaries"][0]["compensation"] == "none"
    assert "| filament |" in paths["table"].read_text() and paths["plot"].stat().st_size > 1000


def test_walk_albedo_single_scattering_is_the_dfg_albedo():
    """order_max = 1 of the walk = F0 A + B of the quadrature the DFG LUT approximates."""
    from compare import renderers
    from pbrcheck import brdf

    m, se = renderers.multiscatter_albedo(0.4, 0.6, 0.5, samples=1 << 18, order_max=1)
    A, B = brdf.specular_dfg(0.4, 0.6)
    assert abs(float(m) - (0.5 * A + B)) <= 4.0 * float(se) + 1e-5


@pytest.mark.slow
def test_cli_energy_with_images(tmp_path, tmp_cache, capsys):
    rc = cli.main(["energy", "--samples", "1024", "--scenes", "furnace", "--size", "12", "--spp", "8",
                   "--out", str(tmp_path), "--quiet", "--set", "cube_size=32", "--set", "prefilter_samples=64",
                   "--set", "lut_size=16", "--set", "lut_samples=256", "--set", "prefilter_levels=5"])
    assert rc == 0
    out = capsys.readouterr().out
    assert "Furnace: mean radiance" in out
    d = json.loads((tmp_path / "energy.json").read_text())
    rows = {r["compensation"]: r for r in d["images"]}
    assert set(ENERGY_COMPENSATIONS.names) <= set(rows)
    assert (tmp_path / "energy_furnace_filament.png").exists()
