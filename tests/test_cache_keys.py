"""The content-addressed keys beside the real-time cache's (tests/test_realtime_cache.py), audited for
inputs that change the pixels but not the key (issue 33): the reference cache (the Mitsuba variant
and releases), the clients' render cache (the engine's version line: the system's Chromium, which no
lockfile pins) and the corpus's rows (the code of each renderer and of the reference: an edit of a
shader made a finished row "done" before)."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import pytest

import compare.corpus.study as study
from compare import renderers
import realtime.gl as gl
from pbrcheck.scene import scene_from_dict

TINY = {"name": "tiny", "camera": {"origin": [0, 0, 4], "fov": 40.0, "width": 16, "height": 8},
        "environment": {"type": "constant", "radiance": [1, 1, 1]},
        "objects": [{"type": "sphere", "radius": 1.0, "material": {"metallic": 1.0, "roughness": 0.5}}]}


@pytest.fixture
def scene():
    return scene_from_dict(TINY)


def test_the_reference_key_holds_the_mitsuba_variant_and_releases(scene, monkeypatch):
    import reference.render as rr
    from reference.variant import backend_identity, ensure_variant

    ident = backend_identity()
    assert ident["variant"] == ensure_variant() and ident["mitsuba"] and ident["drjit"]
    kw = dict(spp=16, mode="local", seed=0, max_depth=None)
    base = rr.reference_cache_key(scene, **kw)
    assert rr.reference_cache_key(scene, **kw) == base
    keys = {base}
    for change in ({"variant": "cuda_ad_rgb" if ident["variant"] != "cuda_ad_rgb" else "llvm_ad_rgb"},
                   {"mitsuba": ident["mitsuba"] + ".1"}, {"drjit": ident["drjit"] + ".1"}):
        monkeypatch.setattr(rr, "backend_identity", lambda c=change: {**ident, **c})
        keys.add(rr.reference_cache_key(scene, **kw))
    assert len(keys) == 4


def test_the_external_key_holds_the_renderers_version_line(scene, tmp_path, monkeypatch, tmp_cache):
    """A Chromium upgraded under an unchanged lockfile (its version is in the built-in clients'
    version line) is another key; the version command runs once per process."""
    from clients import config as C
    from clients import run as R

    (tmp_path / "engine.py").write_text("# the engine\n")
    (tmp_path / "renderers.toml").write_text(
        "[renderer.fake]\n"
        f'command = [{json.dumps(sys.executable)}, "engine.py", "{{scenario}}", "{{out}}"]\n'
        'output = "pfm"\n'
        f'version_command = [{json.dumps(sys.executable)}, "-c", "print(open(\'version.txt\').read())"]\n'
        'lockfile = "engine.py"\n')
    (tmp_path / "version.txt").write_text("engine 1; Chromium 156.0")
    cfg = C.get_renderer("fake", tmp_path / "renderers.toml")
    monkeypatch.setattr(R, "_versions", {})
    a = R.cache_key_for(scene, cfg, "env")
    assert R.renderer_version(cfg) == "engine 1; Chromium 156.0" and R.cache_key_for(scene, cfg, "env") == a
    (tmp_path / "version.txt").write_text("engine 1; Chromium 157.0")
    assert R.cache_key_for(scene, cfg, "env") == a  # memoized for the process
    monkeypatch.setattr(R, "_versions", {})          # a new process
    assert R.cache_key_for(scene, cfg, "env") != a


def _entry(tmp_path):
    return study.Entry("env.exr", str(tmp_path / "env.exr"), "0" * 64)


def test_a_corpus_row_is_keyed_by_the_shaders_of_its_preset(tmp_path, monkeypatch, scene):
    """After an edit of any shader file (raster.frag included) a corpus rerun renders the real-time
    rows again (their render and comparison keys change) and keeps the reference."""
    d = tmp_path / "shaders"
    shutil.copytree(gl.SHADER_DIR, d)
    monkeypatch.setattr(gl, "SHADER_DIR", d)
    st = study.CorpusSettings(scene, (renderers.RendererSpec.parse("default"),))
    study.code_identity.cache_clear()
    before = study._keys(st, _entry(tmp_path), st.renderers[0])
    for name in ("raster.frag", "brdf.glsl"):
        with open(d / name, "a", encoding="utf-8") as f:
            f.write("\n// edited\n")
        assert study._keys(st, _entry(tmp_path), st.renderers[0]) == before  # memoized within a plan
        study.plan([], st)                                                    # the next plan sees it
        after = study._keys(st, _entry(tmp_path), st.renderers[0])
        assert after[:2] == before[:2] and after[2] != before[2] and after[3] != before[3], name
        before = after


def test_a_corpus_row_is_keyed_by_the_reference_code_and_an_external_renderers_config(tmp_path, monkeypatch, scene):
    import reference.render as rr

    st = study.CorpusSettings(scene, (renderers.RendererSpec.parse("ext:threejs"),))
    study.code_identity.cache_clear()
    env_k, ref_k, ren_k, cmp_k = study._keys(st, _entry(tmp_path), st.renderers[0])
    assert json.loads(study.code_identity("ext:threejs"))["external"]["name"] == "threejs"
    monkeypatch.setattr(rr, "REFERENCE_CODE_VERSION", rr.REFERENCE_CODE_VERSION + "-edited")
    from clients import config as C

    real = C.RendererConfig.cache_dict
    monkeypatch.setattr(C.RendererConfig, "cache_dict", lambda self: {**real(self), "lockfile": "another"})
    study.code_identity.cache_clear()
    keys = study._keys(st, _entry(tmp_path), st.renderers[0])
    assert keys[0] == env_k and keys[1] != ref_k and keys[2] != ren_k and keys[3] != cmp_k


def test_a_render_lists_task_keys_hold_the_environments_pixels_and_the_code(tmp_path, monkeypatch):
    """The report's and the sweep's render tasks (keys a long-lived Dask scheduler may still hold):
    another environment file at the same path, or a shader edit, is another key."""
    import numpy as np

    from compare import renderers
    from compare.corpus.renderlist import _render_tasks
    from pbrcheck.exr import Image, write_exr

    env = tmp_path / "env.exr"
    write_exr(env, Image.from_rgb(np.full((8, 16, 3), 0.5, np.float32)))
    s = scene_from_dict({**TINY, "environment": {"type": "file", "path": str(env)}})
    jobs = [renderers.RendererSpec.parse("default"), renderers.RendererSpec.parse("splitsum_basic", {"cube_size": 32})]

    def keys():
        return [t.key for t in _render_tasks(s, jobs, renderers.DIRECT)]

    a = keys()
    assert len(set(a)) == 2 and keys() == a
    write_exr(env, Image.from_rgb(np.full((8, 16, 3), 0.6, np.float32)))
    b = keys()
    assert not set(a) & set(b)
    d = tmp_path / "shaders"
    shutil.copytree(gl.SHADER_DIR, d)
    monkeypatch.setattr(gl, "SHADER_DIR", d)
    with open(d / "raster.vert", "a", encoding="utf-8") as f:
        f.write("\n// edited\n")
    assert not set(keys()) & set(b)
