"""``pbrcheck probe`` (compare/probe.py: an engine's orientation, exposure and colour space), and the
colour space and error labels of ``compare`` and ``diagnose`` (issue 40): diagnose honours a stored
image's ``display_referred`` flag, compare says in which space it compared, both say why their
relmse differ."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from compare import probe, renderers
from compare.maps import srgb_oetf
from compare.metrics import display_referred
from compare.research import diagnose as dg
import pbrcheck_cli as cli
from pbrcheck.exr import Image, read_exr, write_exr
from pbrcheck.scene import load_scene

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "compare" / "budgets" / "spheres_ci.toml"
REF = ROOT / "compare" / "budgets" / "refs" / "spheres_ci.exr"


@pytest.fixture(scope="module")
def probe_pair(tmp_path_factory):
    d = tmp_path_factory.mktemp("probe")
    scene = probe.probe_scene(d)
    return scene, renderers.render_reference(scene, spp=probe.PROBE_SPP, use_cache=False, progress=False)


def _like(ref: Image, rgb: np.ndarray, **meta) -> Image:
    return Image.from_rgb(np.ascontiguousarray(rgb, np.float32), meta, object=ref.channels["object"])


def test_probe_of_the_reference_itself_is_right_linear_at_unit_exposure(probe_pair):
    scene, ref = probe_pair
    res = probe.analyse_probe(scene, ref, ref)
    assert res.orientation.startswith("right")
    assert res.colour_space == "linear"
    assert res.marker_ratio == pytest.approx(1.0, abs=0.01) and res.background_ratio == pytest.approx(1.0, abs=0.01)
    assert len(res.offsets) >= 5 and all(v == [0.0, 0.0] for v in res.offsets.values())


def test_probe_names_a_planted_turn_encoding_exposure_and_flip(probe_pair):
    scene, ref = probe_pair
    turned = replace(scene, environment=replace(scene.environment, rotation=scene.environment.rotation + 90.0))
    img = renderers.render_reference(turned, spp=probe.PROBE_SPP, use_cache=False, progress=False)
    res = probe.analyse_probe(scene, ref, img)
    assert res.turn_deg == 270.0 and not res.mirrored
    assert "rotation 90 degrees more" in res.orientation and res.colour_space == "linear"
    enc = probe.analyse_probe(scene, ref, _like(ref, srgb_oetf(np.clip(ref.rgb, 0.0, 1.0))))
    assert enc.colour_space.startswith("sRGB-encoded") and enc.orientation.startswith("right")
    half = probe.analyse_probe(scene, ref, _like(ref, 0.5 * ref.rgb))
    assert half.colour_space == "linear with an exposure factor of 0.5"
    assert half.marker_ratio == pytest.approx(0.5, abs=0.01)
    flipped = probe.analyse_probe(scene, ref, _like(ref, ref.rgb[::-1]))
    assert "no turn about +Y explains" in flipped.orientation
    png = probe.analyse_probe(scene, ref, display_referred(ref))
    assert png.colour_space.startswith("display-referred") and png.orientation.startswith("right")


def test_probe_command_on_a_preset(tmp_path, tmp_cache, capsys):
    assert cli.main(["probe", "default", "--out", str(tmp_path / "p")]) == 0
    out = capsys.readouterr().out
    assert "orientation: right" in out and "colour space: linear" in out
    got = json.loads((tmp_path / "p" / "probe.json").read_text())
    assert got["renderer"] == "default" and got["marker_ratio"] == pytest.approx(1.0, abs=0.1)


@pytest.fixture(scope="module")
def spheres_png():
    """The default preset's spheres_ci image as an 8-bit png-srgb engine would hand it over."""
    img = renderers.render_under_test(load_scene(SCENE), renderers.RendererSpec.parse("default"))
    enc = np.round(srgb_oetf(np.clip(img.rgb.astype(np.float64), 0.0, 1.0)) * 255.0) / 255.0
    return Image.from_rgb(enc.astype(np.float32), {"display_referred": "1"}, object=img.channels["object"])


def test_diagnose_honours_display_referred(spheres_png):
    d = dg.diagnose(read_exr(REF), spheres_png)
    assert d.space == "display-referred"
    assert d.likely is None, d.line          # before: "likely cause: srgb_as_linear" on a correct image
    rows = {r.hypothesis: r for r in d.rows}
    assert "display-referred" in rows["srgb_as_linear"].skipped and rows["linear_as_srgb"].skipped


def test_compare_and_diagnose_say_their_space_and_what_their_relmse_is(spheres_png, tmp_path, capsys):
    write_exr(tmp_path / "png.exr", spheres_png)
    assert cli.main(["compare", str(REF), str(tmp_path / "png.exr")]) == 0
    out = capsys.readouterr().out
    assert "colour space: display-referred" in out and "over the valid pixels" in out
    assert cli.main(["diagnose", str(REF), str(tmp_path / "png.exr"), "--quiet"]) == 0
    out = capsys.readouterr().out
    assert f"({dg.ERROR_LABEL};" in out and "colour space: display-referred" in out
    assert "compare's relmse is over the valid pixels only" in out
    assert "likely cause: srgb_as_linear" not in out
