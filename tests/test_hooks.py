"""Shader hooks (`--shader FILE.glsl`): parsing, wiring into the frame pass, the examples as documented,
errors naming the user's file and line, and every place a preset can be named."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

import pbrcheck_cli as cli
from pbrcheck.exr import read_exr
from pbrcheck.scene import load_scene, scene_from_dict
from realtime.gl import ShaderCompileError, is_software_renderer
from realtime.hooks import HOOKS, HookError, load_hook_file
from realtime.presets import OptionError, resolve_options
from realtime.render import render_realtime

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples" / "shaders"
SPHERES_CI = ROOT / "compare" / "budgets" / "spheres_ci.toml"
#: A hook that spells out a preset's terms renders the preset: bit for bit on Mesa; on a GPU within
#: this relative difference, since its compiler may contract (fma) or reorder the two programs'
#: arithmetic differently (NVIDIA, H100: see the test).
HOOK_EQUIVALENT_GPU_RTOL = 1e-5
#: Two spheres, a white metal and a white dielectric, in a white furnace, no lights.
TWO = {"name": "two", "camera": {"origin": [0, 0, 6], "fov": 40, "width": 48, "height": 24},
       "environment": {"type": "constant", "radiance": [1, 1, 1]},
       "objects": [{"type": "sphere", "center": [-1.1, 0, 0], "radius": 1.0,
                    "material": {"base_color": [1, 1, 1], "metallic": 1.0, "roughness": 0.5}},
                   {"type": "sphere", "center": [1.1, 0, 0], "radius": 1.0,
                    "material": {"base_color": [1, 1, 1], "metallic": 0.0, "roughness": 0.5}}]}
#: Relative MSE between the ue4 example and its option equivalent: only Karis's spherical-Gaussian
#: Fresnel differs (its error against Schlick's power is below 0.5 % of F).
UE4_EQUIVALENT_RELMSE = 1e-6


def relmse(a, b):
    return float(((a - b) ** 2 / (b * b + 0.01)).mean())


def write(tmp_path, text, name="hooks.glsl"):
    p = tmp_path / name
    p.write_text(text)
    return p


@pytest.fixture(scope="module")
def spheres():
    return load_scene(SPHERES_CI)


@pytest.fixture(scope="module")
def two():
    return scene_from_dict(TWO)


def test_prototypes_and_docs_match_the_hook_list():
    glsl = (ROOT / "realtime" / "shaders" / "hooks.glsl").read_text()
    docs = (ROOT / "docs" / "hooks.md").read_text()
    protos = re.findall(r"#ifdef (HOOK_\w+)\n(.*);\n#endif", glsl)
    assert [(h.define, h.signature) for h in HOOKS] == protos
    for h in HOOKS:
        assert f"`{h.signature}`" in docs, h.name


def test_a_hook_that_reproduces_the_built_in_gives_the_same_image(spheres, tmp_path):
    f = write(tmp_path, "float hook_lod(float roughness, float max_lod, float cube_log2) {\n"
                        "    return lod_quadratic(roughness, max_lod, cube_log2);\n}\n")
    a = render_realtime(spheres, "default", {"shader": str(f)}, progress=False)
    b = render_realtime(spheres, "default", progress=False)
    assert np.array_equal(a.rgb, b.rgb)
    meta = json.loads(a.meta["shader"])
    assert meta["path"] == str(f) and meta["hooks"] == ["hook_lod"] and len(meta["sha256"]) == 64
    assert json.loads(b.meta["shader"]) is None


def test_filament_example_is_the_filament_preset(spheres):
    a = render_realtime(spheres, "default", {"irradiance": "sh9", "shader": str(EXAMPLES / "filament.glsl")},
                        progress=False)
    b = render_realtime(spheres, "filament", progress=False)
    if is_software_renderer():
        assert np.array_equal(a.rgb, b.rgb)
    else:
        np.testing.assert_allclose(a.rgb, b.rgb, rtol=HOOK_EQUIVALENT_GPU_RTOL, atol=1e-7)


def test_ue4_example_is_karis_2013(spheres):
    u = render_realtime(spheres, "default", {"lod_mapping": "log2", "shader": str(EXAMPLES / "ue4.glsl")},
                        progress=False)
    e = render_realtime(spheres, "default", {"lod_mapping": "log2", "geometry": "schlick_ggx_ibl"}, progress=False)
    d = render_realtime(spheres, "default", progress=False)
    assert np.isfinite(u.rgb).all()
    assert relmse(u.rgb, e.rgb) < UE4_EQUIVALENT_RELMSE
    assert relmse(u.rgb, d.rgb) > 100 * UE4_EQUIVALENT_RELMSE
    assert json.loads(u.meta["shader"])["hooks"] == ["hook_lod", "hook_G", "hook_F"]


def _object_means(img):
    obj = np.rint(img.channels["object"]).astype(int)
    cov = img.channels["coverage"] >= 0.999
    return [img.rgb[(obj == k) & cov].mean() for k in (0, 1)]


def test_ibl_hooks_replace_what_they_document(two, tmp_path):
    base_metal, base_diel = _object_means(render_realtime(two, "default", progress=False))
    no_spec = write(tmp_path, "vec3 hook_specular_ibl(vec3 n, vec3 v, float roughness, vec3 F0) "
                              "{ return vec3(0.0); }\n", "nospec.glsl")
    metal, diel = _object_means(render_realtime(two, "default", {"shader": str(no_spec)}, progress=False))
    assert metal == 0.0 and 0.0 < diel < base_diel  # the metal had only specular; the dielectric keeps its diffuse
    # With a preset that compensates energy, the whole specular IBL is still the hook's.
    assert _object_means(render_realtime(two, "filament", {"shader": str(no_spec)}, progress=False))[0] == 0.0
    no_diff = write(tmp_path, "vec3 hook_diffuse_ibl(vec3 n) { return vec3(0.0); }\n", "nodiff.glsl")
    metal, diel = _object_means(render_realtime(two, "default", {"shader": str(no_diff)}, progress=False))
    assert metal == pytest.approx(base_metal, rel=1e-6) and diel < base_diel
    dfg = write(tmp_path, "vec2 hook_dfg(float NoV, float roughness) { return vec2(0.5, 0.0); }\n", "dfg.glsl")
    metal, _ = _object_means(render_realtime(two, "default", {"shader": str(dfg)}, progress=False))
    assert metal == pytest.approx(0.5, rel=2e-3)  # F0 = 1: specular = prefiltered (1 in a furnace) x A
    ec = write(tmp_path, "vec3 hook_energy_compensation(vec3 F0, float A, float B, float r) { return vec3(2.0); }\n",
               "ec.glsl")
    metal, _ = _object_means(render_realtime(two, "default", {"shader": str(ec)}, progress=False))
    assert metal == pytest.approx(2 * base_metal, rel=1e-5)


def test_compile_errors_name_the_users_file_and_line(spheres, tmp_path):
    f = write(tmp_path, "// line 1\nfloat hook_lod(float roughness, float max_lod, float cube_log2) {\n"
                        "    return undefined_thing;\n}\n")
    with pytest.raises(ShaderCompileError, match=re.escape(f"{f}:3")):
        render_realtime(spheres, "default", {"shader": str(f)}, progress=False)


@pytest.mark.parametrize("text, match", [
    ("// nothing here\n", "defines no hook"),
    ("/* float hook_lod(float r, float m, float c) { return 0.0; } */\n", "defines no hook"),
    ("float hook_lod(float roughness) { return 0.0; }\n", r":1: hook_lod must be declared as `float hook_lod\("),
    ("\nvec3 hook_spec(vec3 n) { return n; }\n", r":2: hook_spec is not a hook"),
])
def test_bad_hook_files_are_rejected_naming_file_and_line(tmp_path, text, match):
    f = write(tmp_path, text)
    with pytest.raises(HookError, match=match):
        load_hook_file(f)


def test_hooks_need_the_material_shading_and_an_existing_file(tmp_path):
    f = write(tmp_path, "vec3 hook_diffuse_ibl(vec3 n) { return vec3(0.0); }\n")
    with pytest.raises(OptionError, match="shading=article000"):
        resolve_options("splitsum_basic", {"shader": str(f)})
    with pytest.raises(OptionError, match="no such file"):
        resolve_options("default", {"shader": "nope.glsl"})
    assert resolve_options("default", {"shader": str(f)}).shader == str(f)
    # the renderer name PRESET+FILE.glsl: split once where it is read (RendererSpec.parse)
    from compare.renderers import RendererSpec
    with pytest.raises(OptionError, match="shading=article000"):
        RendererSpec.parse(f"splitsum_basic+{f}")
    with pytest.raises(OptionError, match="no such file"):
        RendererSpec.parse("default+nope.glsl")
    spec = RendererSpec.parse(f"default+{f}")
    assert (spec.text, spec.name, spec.options.shader, spec.override_dict["shader"]) == (
        f"default+{f}", "default", str(f), str(f))


def test_cli_realtime_shader_and_gate_shader_key(tmp_path, capsys):
    f = EXAMPLES / "ue4.glsl"
    out = tmp_path / "u.exr"
    assert cli.main(["realtime", str(SPHERES_CI), "--shader", str(f), "--set", "lod_mapping=log2",
                     "--out", str(out)]) == 0
    assert json.loads(read_exr(out).meta["shader"])["path"] == str(f)
    budget = tmp_path / "b.toml"
    budget.write_text(f'''[[check]]
name = "ue4"
scene = "{SPHERES_CI}"
shader = "{f}"
options = {{ lod_mapping = "log2" }}
reference = "{ROOT / 'compare' / 'budgets' / 'refs' / 'spheres_ci.exr'}"
[check.max]
relmse = 1.0
''')
    assert cli.main(["gate", str(budget)]) == 0
    assert "pass ue4" in capsys.readouterr().out
    budget.write_text(budget.read_text().replace(str(f), "missing.glsl"))
    assert cli.main(["gate", str(budget)]) == 2
    assert "shader" in capsys.readouterr().err
