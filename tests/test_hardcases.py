"""Hard cases are finite in both renderers, for every preset (at 16 x 16, small cubes)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from compare.research import hardcases
from compare.research.hardcases import run_hardcases

# Renders, fits or quadratures of seconds each: `make test-fast` skips them, `make test` runs them.
pytestmark = pytest.mark.slow

# Tiny renders keep the whole file well under a minute: 16 px, 4 spp, 32^2 cubes.
SIZE, SPP, CUBE = 16, 4, 32
# The x 1e4 and x 1e-4 scenes are the same picture (lengths scaled, point intensities by s^2):
# a real-time image depends on directions only, so their errors against their references agree
# to float32 precision of the ray-sphere intersection (well under 1 %) unless scale breaks something.
SCALE_RTOL = 0.01


@pytest.fixture(scope="module")
def counted_run():
    """The rows, and how many HDR-FLIP and Delta E ITP maps the run asked for."""
    from compare import metrics

    asked = {"flip": 0, "itp": 0}
    real = metrics.flip_map, metrics.delta_e_itp_map

    def flip(*a, **k):
        asked["flip"] += 1
        return real[0](*a, **k)

    def itp(*a, **k):
        asked["itp"] += 1
        return real[1](*a, **k)

    metrics.flip_map, metrics.delta_e_itp_map = flip, itp
    try:
        return run_hardcases(size=SIZE, spp=SPP, cube_size=CUBE), asked
    finally:
        metrics.flip_map, metrics.delta_e_itp_map = real


@pytest.fixture(scope="module")
def rows(counted_run):
    return counted_run[0]


def test_no_map_the_table_does_not_read(counted_run):
    rows, asked = counted_run
    from compare.research.hardcases import TABLE_METRICS

    assert any(r.metrics for r in rows)
    assert not {"flip_mean", "delta_e_itp_mean"} & set(TABLE_METRICS)
    assert asked == {"flip": 0, "itp": 0}


def test_every_case_and_preset_is_finite(rows):
    from realtime.presets import PRESETS

    cases = {r.case for r in rows}
    assert cases == {"roughness_0", "roughness_1e-4", "roughness_1", "grazing", "f0_0", "f0_1", "sun",
                     "hotspot", "env_2x1", "scale_1e4", "scale_1e-4"}
    assert len(rows) == len(cases) * (1 + len(PRESETS))
    bad = [(r.case, r.preset, r.nonfinite, r.error) for r in rows if not r.finite]
    assert not bad, bad
    # each case's reference spp follows the verdict rule from SPP up to the cap, and says so
    for r in rows:
        if r.renderer == "reference":
            v = r.reference_spp
            assert v["steps"][0][0] == SPP and SPP <= v["spp"] <= v["cap"], (r.case, v)
            assert v["noise_limited"] or v["smallest_error"] is None or v["ratio"] >= v["factor"], (r.case, v)
        else:
            assert r.reference_spp is None
    # every real-time render was compared (finite error figures), none failed to compare
    for r in rows:
        if r.renderer == "realtime":
            assert r.error is None and r.metrics is not None, r
            assert all(np.isfinite(v) for v in r.metrics.values()), r


def test_scale_invariance(rows):
    big = {r.preset: r.metrics["relmse"] for r in rows if r.case == "scale_1e4" and r.metrics}
    small = {r.preset: r.metrics["relmse"] for r in rows if r.case == "scale_1e-4" and r.metrics}
    assert big.keys() == small.keys() and big
    for p in big:
        assert big[p] == pytest.approx(small[p], rel=SCALE_RTOL), (p, big[p], small[p])


def test_cli_exits_1_on_non_finite(tmp_path, monkeypatch, capsys):
    """A renderer that returns NaN is reported and the command exits 1 (the check can fail)."""
    import realtime.render as rr
    from pbrcheck_cli import main

    real = rr.render_realtime

    def poisoned(scene, preset="default", options=None, **kw):
        img = real(scene, preset, options, **kw)
        img.channels["R"][0, 0] = np.nan
        return img

    monkeypatch.setattr(rr, "render_realtime", poisoned)
    code = main(["hardcases", "--out", str(tmp_path), "--size", "8", "--spp", "2", "--cube-size", "16",
                 "--cases", "roughness_1", "--presets", "default", "--quiet"])
    assert code == 1
    d = json.loads((tmp_path / "hardcases.json").read_text())
    assert d["all_finite"] is False
    ref = [r for r in d["rows"] if r["renderer"] == "reference"][0]
    assert ref["reference_spp"]["steps"][0][0] == 2  # the rule's outcome, from --spp up
    rt = [r for r in d["rows"] if r["renderer"] == "realtime"]
    assert rt[0]["nonfinite"] == 1
    assert "NO" in (tmp_path / "hardcases.md").read_text()
    monkeypatch.setattr(rr, "render_realtime", real)
    assert main(["hardcases", "--out", str(tmp_path), "--size", "8", "--spp", "2", "--cube-size", "16",
                 "--cases", "roughness_1", "--presets", "default", "--quiet", "--spp-cap", "2"]) == 0
    ref = [r for r in json.loads((tmp_path / "hardcases.json").read_text())["rows"] if r["renderer"] == "reference"]
    assert ref[0]["reference_spp"]["spp"] == 2 and ref[0]["reference_spp"]["cap"] == 2  # --spp-cap holds it


def test_unknown_case_is_an_error():
    from pbrcheck.errors import PbrcheckError

    with pytest.raises(PbrcheckError, match="unknown case"):
        run_hardcases(size=8, spp=1, cases=["nope"], presets=[])
    assert hardcases.SCALES == (1e4, 1e-4)


def test_renderers_are_validated_through_the_seam_before_any_render():
    """Presets, PRESET+FILE.glsl and ext:NAME are all checked up front (the report once failed late on
    an external renderer after writing its scene sections)."""
    from pbrcheck.errors import PbrcheckError

    with pytest.raises(PbrcheckError, match="hardcases: unknown preset 'nope'"):
        run_hardcases(size=8, spp=1, presets=["nope"])
    with pytest.raises(PbrcheckError, match="hardcases: unknown external renderer 'ext:nope'"):
        run_hardcases(size=8, spp=1, presets=["ext:nope"])
