"""The content-addressed cache of real-time renders (realtime/cache.py) and where it is used: a hit is
the stored render; every input that changes the pixels (scene, preset, options, shader hooks, a fitted
mapping's file, the code) changes the key; a corrupt entry is re-rendered; outside
a ``compare.renderers.RenderContext(cache=True)`` every call renders."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import compare.renderers as renderers
import realtime.cache as rc
from pbrcheck.cache import Cache
from pbrcheck.scene import load_scene

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


def test_code_hash_covers_the_shaders_and_the_python():
    h = rc.code_hash()
    assert len(h) == 64 and h == rc.code_hash()
    root = rc.Path(rc.__file__).resolve().parent.parent
    files = [p for d in rc._CODE_DIRS for p in (root / d).rglob("*") if p.suffix in rc._CODE_SUFFIXES]
    names = {p.name for p in files}
    assert {"render.comp", "brdf.glsl", "render.py", "scene.py"} <= names


def test_a_corrupt_entry_is_rendered_again(scene, counted, tmp_cache):
    rc.render_cached(scene, "default", SMALL)
    path = Cache(rc.NAMESPACE).path(rc.realtime_cache_key(scene, "default", SMALL))
    path.write_bytes(b"not an exr")
    img = rc.render_cached(scene, "default", SMALL)
    assert img.meta["cache"] == "miss" and len(counted) == 2
    assert rc.render_cached(scene, "default", SMALL).meta["cache"] == "hit"


def test_the_seam_caches_only_with_a_caching_context(scene, counted, tmp_cache):
    renderers.render_under_test(scene, renderers.RendererSpec.parse("default", SMALL))
    renderers.render_under_test(scene, renderers.RendererSpec.parse("default", SMALL), context=renderers.DIRECT)
    assert len(counted) == 0  # the default context: render_realtime itself, never the cache
    cached = renderers.RenderContext(cache=True)
    a = renderers.render_under_test(scene, renderers.RendererSpec.parse("default", SMALL), context=cached)
    b = renderers.render_under_test(scene, renderers.RendererSpec.parse("default", SMALL), context=cached)
    c = renderers.render_under_test(scene, renderers.RendererSpec.parse("default", SMALL), context=renderers.RenderContext(cache=False))
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
