"""The content-addressed cache of real-time renders (realtime/cache.py) and where it is used: a hit is
the stored render; every input that changes the pixels (scene, preset, options, shader hooks, a fitted
mapping's file, the code) changes the key; a corrupt entry is re-rendered; outside
a ``compare.renderers.RenderContext(cache=True)`` every call renders."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

import compare.renderers as renderers
import realtime.cache as rc
import realtime.gl as gl
from pbrcheck.cache import Cache
from pbrcheck.exr import Image
from pbrcheck.scene import load_scene

ROOT_SHADERS = Path(__file__).resolve().parents[1] / "realtime" / "shaders"
SMALL = {"cube_size": 32, "irradiance_source_size": 8, "irradiance_size": 8, "prefilter_levels": 4,
         "prefilter_samples": 64, "supersample": 1}


@pytest.fixture
def scene():
    return load_scene("spheres").with_camera(width=24, height=16)


@pytest.fixture
def counted(monkeypatch):
    """Count the renders that reach the renderer."""
    calls = []
    real = rc.render_realtime

    def render(*a, **k):
        calls.append(a[1] if len(a) > 1 else k.get("preset"))
        return real(*a, **k)

    monkeypatch.setattr(rc, "render_realtime", render)
    return calls


def test_a_hit_is_the_stored_render(scene, counted, tmp_cache):
    a = rc.render_cached(scene, "default", SMALL)
    b = rc.render_cached(scene, "default", SMALL)
    assert (a.meta["cache"], b.meta["cache"]) == ("miss", "hit")
    assert len(counted) == 1
    assert sorted(a.channels) == sorted(b.channels)
    for c in a.channels:
        np.testing.assert_array_equal(a.channels[c], b.channels[c])
    # Same timings, options and renderer: the hit reports the render as it was measured.
    for k in ("timings", "options", "gl_renderer", "timing_clock", "preset"):
        assert a.meta[k] == b.meta[k], k


def test_every_input_of_the_pixels_changes_the_key(scene, tmp_path, monkeypatch, tmp_cache):
    base = rc.realtime_cache_key(scene, "default", SMALL)
    assert rc.realtime_cache_key(scene, "default", dict(SMALL)) == base  # deterministic
    assert rc.realtime_cache_key(scene, "default", {**SMALL, "prefilter_samples": 128}) != base
    assert rc.realtime_cache_key(scene, "filament", SMALL) != base
    assert rc.realtime_cache_key(scene.with_camera(width=25, height=16), "default", SMALL) != base
    # A shader hook file: its content, not its path.
    hook = tmp_path / "h.glsl"
    hook.write_text("vec3 hook_diffuse_ibl(vec3 n) { return vec3(0.0); }\n")
    k1 = rc.realtime_cache_key(scene, "default", {**SMALL, "shader": str(hook)})
    hook.write_text("vec3 hook_diffuse_ibl(vec3 n) { return vec3(1.0); }\n")
    k2 = rc.realtime_cache_key(scene, "default", {**SMALL, "shader": str(hook)})
    assert len({base, k1, k2}) == 3
    # The code: any edit of realtime/ or pbrcheck/ (code_hash) is a miss.
    monkeypatch.setattr(rc, "code_hash", lambda: "0" * 64)
    assert rc.realtime_cache_key(scene, "default", SMALL) != base


def test_files_enter_the_key_by_content_not_path(scene, tmp_path, counted, tmp_cache):
    """The same fitted mapping (another report's --out: the fit's record names other paths) or hook
    file in another folder is a hit, and the hit's metadata names this call's paths."""
    from pbrcheck.lodmap import LodMapping

    fit = LodMapping((0.0, 0.0, 0.0, 0.0, 1.0, 1.5), SMALL["cube_size"], SMALL["prefilter_levels"], "quadratic")
    hook_text = "vec3 hook_diffuse_ibl(vec3 n) { return vec3(0.0); }\n"
    paths = []
    for d in ("a", "b"):
        (tmp_path / d).mkdir()
        # fit-lod's file: the mapping under "mappings.fitted" and the fit's record, which names its --out
        (tmp_path / d / "fit_lod.json").write_text(json.dumps({"glsl": str(tmp_path / d / "fit_lod.glsl"),
                                                               "mappings": {"fitted": fit.to_json()}}))
        (tmp_path / d / "h.glsl").write_text(hook_text)
        paths.append({**SMALL, "lod_mapping": f"fitted:{tmp_path / d / 'fit_lod.json'}",
                      "shader": str(tmp_path / d / "h.glsl")})
    assert rc.realtime_cache_key(scene, "default", paths[0]) == rc.realtime_cache_key(scene, "default", paths[1])
    a = rc.render_cached(scene, "default", paths[0])
    b = rc.render_cached(scene, "default", paths[1])
    assert (a.meta["cache"], b.meta["cache"]) == ("miss", "hit") and len(counted) == 1
    np.testing.assert_array_equal(a.rgb, b.rgb)
    assert str(tmp_path / "b" / "fit_lod.json") in json.loads(b.meta["options"])["lod_mapping"]
    assert json.loads(b.meta["shader"])["path"].endswith(str(Path("b") / "h.glsl"))
    # ... and a changed file is a miss
    fit2 = LodMapping((0.0, 0.0, 0.0, 0.0, 1.2, 1.5), SMALL["cube_size"], SMALL["prefilter_levels"], "quadratic")
    (tmp_path / "b" / "fit_lod.json").write_text(json.dumps(fit2.to_json()))
    assert rc.realtime_cache_key(scene, "default", paths[0]) != rc.realtime_cache_key(scene, "default", paths[1])


def test_code_hash_covers_the_python_and_the_c_sources():
    h = rc.code_hash()
    assert len(h) == 64 and h == rc.code_hash()
    names = {p.name for p in rc.code_files()}
    # every suffix: the Python, and the MikkTSpace C sources that make an asset's tangents
    assert {"render.py", "scene.py", "cache.py", "mikktspace.c", "pbrcheck_mikktspace.c", "furnace.toml"} <= names
    assert not {p for p in rc.code_files() if "__pycache__" in p.parts or p.parent == gl.SHADER_DIR}


@pytest.fixture
def shader_copy(tmp_path, monkeypatch):
    """A temp copy of realtime/shaders that the GL programs read (realtime.gl.SHADER_DIR)."""
    d = tmp_path / "shaders"
    shutil.copytree(gl.SHADER_DIR, d)
    monkeypatch.setattr(gl, "SHADER_DIR", d)
    return d


def test_an_edit_of_any_shader_file_is_a_miss_of_the_reports_cache(scene, shader_copy, monkeypatch, tmp_cache):
    """Every file the GL programs read, whatever its suffix (raster.vert, raster.frag,
    raster_background.frag and fullscreen.vert were missed by a suffix list), keys the cache: after
    an edit of each, the report's cached render (render_cached) is a miss, then a hit."""
    files = sorted(p.name for p in shader_copy.iterdir())
    assert {"raster.vert", "raster.frag", "raster_background.frag", "fullscreen.vert", "render.comp",
            "brdf.glsl"} <= set(files) and len(files) >= 25
    stored = rc.render_realtime(scene, "default", SMALL)  # the pixels do not matter here: the keys do
    renders = []
    monkeypatch.setattr(rc, "render_realtime", lambda *a, **k: renders.append(a) or Image(dict(stored.channels), dict(stored.meta)))
    assert rc.render_cached(scene, "default", SMALL).meta["cache"] == "miss"
    assert rc.render_cached(scene, "default", SMALL).meta["cache"] == "hit"
    keys = {rc.realtime_cache_key(scene, "default", SMALL)}
    for name in files:
        with open(shader_copy / name, "a", encoding="utf-8") as f:
            f.write("\n// edited\n")
        assert rc.render_cached(scene, "default", SMALL).meta["cache"] == "miss", name
        assert rc.render_cached(scene, "default", SMALL).meta["cache"] == "hit", name
        keys.add(rc.realtime_cache_key(scene, "default", SMALL))
    assert len(keys) == len(files) + 1 and len(renders) == len(files) + 1
    # ... and the gate's baselines record the same hash (one rule, not two)
    from compare.baseline import shader_sources_hash

    assert shader_sources_hash() == gl.shader_sources_hash(shader_copy) != gl.shader_sources_hash(ROOT_SHADERS)


def test_an_edited_shader_is_compiled_again_in_the_same_process(shader_copy):
    """The compiled-program caches are keyed by the assembled text, not the file name: an edit made
    under a running process is compiled, not served from the program of the old text."""
    from realtime.raster import graphics_program

    a = gl.compute_program("sh9.comp")
    assert gl.compute_program("sh9.comp") is a
    g = graphics_program("fullscreen.vert", "raster_background.frag")
    assert graphics_program("fullscreen.vert", "raster_background.frag") is g
    for name in ("sh9.comp", "raster_background.frag"):
        with open(shader_copy / name, "a", encoding="utf-8") as f:
            f.write("\n// edited\n")
    assert gl.compute_program("sh9.comp") is not a
    assert graphics_program("fullscreen.vert", "raster_background.frag") is not g


def test_an_edited_shader_bakes_again_in_the_same_process(shader_copy):
    """The bakes kept for the process (cubes, SH, LUTs) are keyed by the shader sources too: after an
    edit of the bake's shader a render bakes afresh instead of reading the bake of the old text."""
    from realtime.render import dfg_lut

    a = dfg_lut(8, 16, "f32", "smith_ggx_correlated")
    assert dfg_lut(8, 16, "f32", "smith_ggx_correlated") is a
    with open(shader_copy / "dfg_lut.comp", "a", encoding="utf-8") as f:
        f.write("\n// edited\n")
    assert dfg_lut(8, 16, "f32", "smith_ggx_correlated") is not a


def test_a_corrupt_entry_is_rendered_again(scene, counted, tmp_cache):
    rc.render_cached(scene, "default", SMALL)
    path = Cache(rc.NAMESPACE).path(rc.realtime_cache_key(scene, "default", SMALL))
    path.write_bytes(b"not an exr")
    img = rc.render_cached(scene, "default", SMALL)
    assert img.meta["cache"] == "miss" and len(counted) == 2
    assert rc.render_cached(scene, "default", SMALL).meta["cache"] == "hit"


def test_the_seam_caches_only_with_a_caching_context(scene, counted, tmp_cache):
    renderers.render_under_test(scene, "default", SMALL)
    renderers.render_under_test(scene, "default", SMALL, context=renderers.DIRECT)
    assert len(counted) == 0  # the default context: render_realtime itself, never the cache
    cached = renderers.RenderContext(cache=True)
    a = renderers.render_under_test(scene, "default", SMALL, context=cached)
    b = renderers.render_under_test(scene, "default", SMALL, context=cached)
    c = renderers.render_under_test(scene, "default", SMALL, context=renderers.RenderContext(cache=False))
    assert (a.meta["cache"], b.meta["cache"]) == ("miss", "hit") and "cache" not in c.meta
    assert len(counted) == 1


def test_a_hit_prints_the_renders_warnings_again(scene, tmp_cache, capsys, monkeypatch):
    a = rc.render_cached(scene, "default", SMALL)
    # Pretend the stored render had warned (an f16 cube replaced by f32, say).
    key = rc.realtime_cache_key(scene, "default", SMALL)
    a.meta["warnings"] = json.dumps(["cube_format f16 replaced by f32"])
    Cache(rc.NAMESPACE).put(key, a)
    capsys.readouterr()
    rc.render_cached(scene, "default", SMALL, progress=True)
    assert "cube_format f16 replaced by f32" in capsys.readouterr().err
