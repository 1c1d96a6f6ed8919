"""The report's research sections (LOD fit before / after, error decomposition, apparent roughness)
on a tiny real scene, through both real renderers, and their place in the HTML report."""

from __future__ import annotations

import json

import numpy as np
import pytest

# Renders, fits or quadratures of seconds each: `make test-fast` skips them, `make test` runs them.
pytestmark = pytest.mark.slow

# A 2 x 4 metal/dielectric grid (roughness 0..1 along the columns) under a sky with a sun and one
# point light: every section has something to measure, at 40 x 24 pixels.
SCENE = """
name = "tinygrid"
description = "2 x 4 sphere grid under a sky, one point light"
[camera]
origin = [0.0, 0.0, 7.0]
fov = 36.0
width = 40
height = 24
[environment]
type = "sky"
sun_direction = [0.4, 0.6, 0.7]
sun_angular_diameter = 10.0
sun_radiance = [40.0, 38.0, 35.0]
resolution = [128, 64]
[[lights]]
type = "point"
position = [-3.0, 2.0, 4.0]
intensity = [10.0, 10.0, 10.0]
[[objects]]
type = "sphere_grid"
rows = 2
columns = 4
radius = 0.45
spacing = 1.0
metallic = [0.0, 1.0]
roughness = [0.0, 1.0]
[objects.material]
base_color = [0.9, 0.6, 0.3]
"""

# Small cubes and sample counts so the whole module runs in well under a minute.
OPTS = {"cube_size": 32, "prefilter_levels": 6, "prefilter_samples": 128, "irradiance_source_size": 32,
        "supersample": 2}


@pytest.fixture(scope="module")
def sections(tmp_path_factory):
    from compare.report.research_sections import ResearchSettings, research_sections

    d = tmp_path_factory.mktemp("research")
    scene = d / "tinygrid.toml"
    scene.write_text(SCENE)
    st = ResearchSettings(fitlod_size=24, fitlod_spp=16, explain_size=24, explain_spp=16, fitrough_size=16,
                          fitrough_iterations=5, options=OPTS, samples_scale=1 / 16, cube_max=32,
                          energy_samples=1024, energy_spp=8, energy_size=12, energy_scenes=("furnace",))
    out = d / "research"
    secs = research_sections(str(scene), out, ["default"], report_spp=16, st=st)
    return out, secs


def test_three_sections_with_their_files(sections):
    out, secs = sections
    assert [s.id for s in secs] == ["fit-lod", "explain-default", "fit-roughness", "energy"]
    for s in secs:
        assert s.tables and all(t.rows for t in s.tables)
        for im in s.images:
            assert (out.parent / im["src"]).is_file(), im
    for f in ("fit_lod.json", "fit_lod.glsl", "fit_lod.png", "explain_default.json", "explain_default.md",
              "fit_roughness.json", "fit_roughness.png", "energy.json", "energy.md", "energy.png"):
        assert (out / f).is_file(), f


def test_fit_lod_before_after_is_measured(sections):
    out, secs = sections
    before, after = secs[0].tables[0].rows
    assert "before" in before[1] and "after" in after[1]
    vals = [float(before[2]), float(after[2])]
    assert all(np.isfinite(vals)) and vals[0] != vals[1]  # two different renders, both compared
    d = json.loads((out / "fit_lod.json").read_text())
    assert set(d["chains"]) == {"linear", "quadratic", "log2"} and d["chain"] in d["chains"]
    best = min(d["mappings"][k]["relmse"] for k in ("linear", "quadratic", "log2"))
    assert d["mappings"]["fitted"]["relmse"] <= best * (1 + 1e-6), d["mappings"]


def test_explain_section_has_every_source_and_the_combinations(sections):
    _, secs = sections
    names = [r[0] for r in secs[1].tables[0].rows]
    for src in ("lut", "prefilter_samples", "v=n=r", "irradiance", "cube", "geometry", "ndf_fresnel",
                "composition", "lod_mapping", "all but v=n=r (the best split sum)", "all exact"):
        assert src in names, names


def test_fit_roughness_section_rows_per_roughness(sections):
    out, secs = sections
    rows = secs[2].tables[0].rows
    assert [r[1] for r in rows] == ["0", "0.333", "0.667", "1"]
    d = json.loads((out / "fit_roughness.json").read_text())
    for o in d["default"]["objects"]:
        assert 0.0 <= o["apparent_roughness"] <= 1.0 and np.isfinite(o["loss"])
        lo, hi = o["range"]  # Adam stays inside the scan's range
        assert lo <= o["apparent_roughness"] <= hi


def test_report_template_renders_research_sections(sections, tmp_path):
    """The extras template shows each section's tables and images (offline, relative paths)."""
    from compare.report.build import render_page

    _, secs = sections
    html = render_page([], [], secs)
    for s in secs:
        assert f'id="{s.id}"' in html
        for im in s.images:
            assert f'src="{im["src"]}"' in html
    assert html.count("<table>") == sum(len(s.tables) for s in secs)
