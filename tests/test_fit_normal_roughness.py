"""fit-normal-roughness (issue 23, section 3): the per-level roughness table, its closed forms, its
GLSL hook, and the fit against a known answer built here: a normal map of 1-texel stripes of slopes
+S and -S along x, whose every mip level >= 1 averages both (filtered normal length
L = 1 / sqrt(1 + S^2) exactly, slope variance S^2)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from compare import renderers
from compare.metrics import REL_EPS
from compare.research.fit_normal_roughness import run_fit_normal_roughness
from pbrcheck.normal_roughness import NormalRoughnessError, NormalRoughnessTable, level_closed_forms
from pbrcheck.scene import asset_scene
from realtime.glsl_harness import run_glsl
from realtime.hooks import load_hook_file
from reference.bench_asset import make_asset

#: Slope of the stripes.
S = 0.5
#: Texels of the stripe map (8 levels; read at levels 1 to 4 on the 32-pixel sphere).
STRIPE_TEXELS = 128
#: The 8-bit normal map moves L and the slope variance by about 1 % (the quantized +-S): closed forms
#: against the analytic values.
CLOSED_FORM_TOL = 0.01
#: The fit's table against S^2 where a level has enough pixels: the scan's step (1/8 in sqrt) refined by
#: a parabola, on 8-bit slopes.
RECOVERY_TOL = 0.02
#: Least pixels of a level whose fitted entry is compared (levels with a couple of pixels are noisy).
MIN_LEVEL_PIXELS = 20
#: The small real-time setup of tests/test_raster.py (fast bakes), one sample a pixel.
#: The generated hook (float32 GLSL, the table printed with 9 significant digits) against
#: NormalRoughnessTable.__call__ (float64): tests/test_specular_aa.py's GLSL_ATOL.
GLSL_ATOL = 2e-6
#: Roughness 0 and 1 and between; lod below 0, at and between every level of the tables below, above the last.
TWIN_ROUGHNESS = np.array([0.0, 1e-4, 0.05, 0.3, 0.5, 0.9, 1.0])
TWIN_LODS = np.array([-3.0, -1e-6, 0.0, 1e-6, 0.25, 0.5, 1.0, 1.5, 2.0, 2.75, 3.0, 3.0 + 1e-6, 4.0, 1e6])
#: Tables: zero and large increments, a zero level between non-zero ones, one level, all zero.
TWIN_TABLES = ((0.0, 0.2, 0.4, 0.8), (0.0, 1e-6, 0.0, 25.0), (3.0, 0.0, 1e-3, 1e3), (0.3,), (0.0,),
               (0.0, 0.0, 0.0, 0.0))
SMALL = {"cube_size": 32, "irradiance_source_size": 8, "irradiance_size": 8, "prefilter_levels": 4,
         "prefilter_samples": 64, "lut_size": 16, "lut_samples": 256, "supersample": 1}


def stripe_map(n: int = STRIPE_TEXELS, s: float = S) -> np.ndarray:
    nrm = np.zeros((n, n, 3))
    nrm[..., 0] = np.where(np.arange(n) % 2 == 0, s, -s)[None, :]
    nrm[..., 2] = 1.0
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    return np.round((nrm * 0.5 + 0.5) * 255).astype(np.uint8)


def test_closed_forms_of_stripes_are_analytic():
    c = level_closed_forms(stripe_map().astype(np.float64) / 255.0)
    assert len(c["toksvig"]) == len(c["lean"]) == STRIPE_TEXELS.bit_length()
    L = 1.0 / np.sqrt(1.0 + S * S)
    assert c["lean"][0] == 0.0 and c["toksvig"][0] < CLOSED_FORM_TOL
    assert np.allclose(c["toksvig"][1:], 2.0 * (1.0 - L) / L, atol=CLOSED_FORM_TOL)
    assert np.allclose(c["lean"][1:], S * S, atol=CLOSED_FORM_TOL)


def test_table_interpolates_and_round_trips(tmp_path):
    t = NormalRoughnessTable((0.0, 0.2, 0.4))
    assert np.allclose(t.variance([-1.0, 0.0, 0.5, 1.5, 2.0, 9.0]), [0.0, 0.0, 0.1, 0.3, 0.4, 0.4])
    assert np.allclose(t(0.5, 1.0), (0.5 ** 4 + 0.2) ** 0.25)
    assert t(0.3, 0.0) == 0.3                     # no increment: roughness to the bit
    p = tmp_path / "t.json"
    p.write_text(json.dumps({"fitted": t.to_json()}))
    assert NormalRoughnessTable.load(p) == t
    with pytest.raises(NormalRoughnessError, match="increments"):
        NormalRoughnessTable.from_json({"increments": [0.1, -0.2]}, "x.json")
    with pytest.raises(NormalRoughnessError, match="bad.json"):
        NormalRoughnessTable.load(tmp_path / "bad.json")
    g = tmp_path / "t.glsl"
    g.write_text(t.glsl())
    assert load_hook_file(g).hooks == ("hook_specular_aa",)


@pytest.mark.parametrize("increments", TWIN_TABLES, ids=lambda t: f"{len(t)}levels-" + "-".join(f"{x:g}" for x in t))
def test_generated_hook_glsl_matches_its_numpy_twin(tmp_path, increments):
    """The hook_specular_aa that NormalRoughnessTable.glsl writes, run by the GLSL harness, against
    NormalRoughnessTable.__call__ on a grid including the extremes (roughness 0 and 1, lod below 0, at
    each level, between levels, above the last; normal_length is not read: 0 and 1 give the same)."""
    t = NormalRoughnessTable(increments)
    g = tmp_path / "t.glsl"
    g.write_text(t.glsl())
    hook = load_hook_file(g)
    r, lod, L = np.meshgrid(TWIN_ROUGHNESS, TWIN_LODS, np.array([0.0, 1.0]), indexing="ij")
    got = run_glsl("hook_specular_aa(x0, x1, x2)", r, L, lod, hook=hook)
    np.testing.assert_allclose(got, t(r, lod), rtol=0, atol=GLSL_ATOL)
    # Where the interpolated increment is 0 the roughness comes back to the bit, in both.
    flat = t.variance(lod) == 0.0
    assert np.array_equal(got[flat], r[flat].astype(np.float32)) and np.array_equal(t(r, lod)[flat], r[flat])


@pytest.fixture(scope="module")
def stripe_fit(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("nr")
    scene = asset_scene(make_asset(tmp / "stripes.gltf", segments=32, tex=64, normal_map=stripe_map()),
                        env=None, size=(32, 32))
    # The known answer as an image: specular_aa = prefiltered reads S^2 at every level >= 1.
    target = renderers.render_under_test(scene, renderers.RendererSpec.parse("default", {**SMALL, "specular_aa": "prefiltered"}))
    res = run_fit_normal_roughness(scene, method="scan", options=SMALL, out=tmp / "fit.json", target=target,
                                   scan_step=0.125,
                                   refine_steps=())
    return scene, target, res


def test_fit_recovers_the_known_table(stripe_fit):
    _, _, res = stripe_fit
    checked = [r for r in res.levels if r.pixels >= MIN_LEVEL_PIXELS]
    assert checked, "no level with enough pixels"
    for r in checked:
        # stage 1 alone (LEAN's exact table is one of stage 2's starts) and the written table
        assert abs(r.optimum - S * S) <= RECOVERY_TOL, (r.level, r.optimum)
        assert abs(r.fitted - S * S) <= RECOVERY_TOL, (r.level, r.fitted)
    assert res.relmse["fitted"] < 0.01 * res.relmse["none"]


def test_written_hook_renders_and_reduces_the_error(stripe_fit):
    scene, target, res = stripe_fit
    assert load_hook_file(res.glsl).hooks == ("hook_specular_aa",)
    table = NormalRoughnessTable.load(res.glsl.replace(".glsl", ".json"))
    assert np.allclose(table.increments, [r.fitted for r in res.levels])

    def rel(img):
        r, t = target.rgb.astype(np.float64), img.rgb.astype(np.float64)
        return float(((t - r) ** 2 / (r * r + REL_EPS)).mean())

    hooked = renderers.render_under_test(scene, renderers.RendererSpec.parse("default", {**SMALL, "shader": res.glsl}))
    none = renderers.render_under_test(scene, renderers.RendererSpec.parse("default", {**SMALL, "specular_aa": "none"}))
    assert rel(hooked) < 0.01 * rel(none)
    # The hook replaces specular_aa: the option under it changes nothing.
    again = renderers.render_under_test(scene, renderers.RendererSpec.parse("default", {**SMALL, "shader": res.glsl, "specular_aa": "toksvig"}))
    assert np.array_equal(again.rgb, hooked.rgb)


def test_cli_refuses_a_scene_without_normal_map_and_a_hook(tmp_path, capsys):
    import pbrcheck_cli as cli
    out = tmp_path / "fit.json"
    assert cli.main(["fit-normal-roughness", "spheres", "--size", "8", "--out", str(out), "--quiet"]) == 2
    assert "no object has a normal map" in capsys.readouterr().err
    g = tmp_path / "h.glsl"
    g.write_text(NormalRoughnessTable((0.1,)).glsl())
    assert cli.main(["fit-normal-roughness", "spheres", "--shader", str(g), "--out", str(out), "--quiet"]) == 2
    assert "shader" in capsys.readouterr().err
    assert not out.exists() and not out.with_suffix(".glsl").exists()
