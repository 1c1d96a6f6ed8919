"""`pbrcheck diagnose`: every planted convention mismatch is named, a correct image is not.

The reference is the committed CI reference of the spheres scene (1024 spp). Image-space mismatches
are planted by transforming the real-time default preset's image; scene-space mismatches by
rendering the reference of the broken scene (another seed, so its noise is independent) or, for the
linear ones (diffuse and light units off by a factor), by the same decomposition on that render.
"""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from compare import renderers
from compare.research import diagnose as dg
import pbrcheck_cli as cli
from pbrcheck.environment import load_environment
from pbrcheck.exr import Image, read_exr, write_exr
from pbrcheck.scene import load_scene

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "compare" / "budgets" / "spheres_ci.toml"
REF = ROOT / "compare" / "budgets" / "refs" / "spheres_ci.exr"
#: Spp of the planted scene-space images and of diagnose's re-renders (fast; the mismatches' errors
#: are orders of magnitude above this noise).
SPP = 32
#: Seed and spp of the planted scene-space images.
PLANT_SEED = 7
PLANT_SPP = 512


@pytest.fixture(scope="module")
def scene():
    return load_scene(SCENE)


@pytest.fixture(scope="module")
def ref():
    return read_exr(REF)


@pytest.fixture(scope="module")
def correct(scene):
    return renderers.render_under_test(scene, renderers.RendererSpec.parse("default"))


def _with_rgb(img: Image, rgb: np.ndarray) -> Image:
    return Image.from_rgb(np.ascontiguousarray(rgb, np.float32))


def test_a_correct_image_has_no_convention_mismatch(ref, correct):
    d = dg.diagnose(ref, correct)
    assert d.likely is None
    assert d.line.startswith("no convention mismatch found")
    # The exposure fit exists but removes little of an approximation's error.
    exposure = next(r for r in d.rows if r.hypothesis == "exposure")
    assert abs(exposure.fitted["factor"] - 1.0) < dg.EXPOSURE_MIN_DEVIATION


def test_an_image_within_noise_says_so(ref):
    d = dg.diagnose(ref, ref)
    assert d.likely is None and "within the reference's noise" in d.line


IMAGE_NAMES = [h.name for h in dg.HYPOTHESES if h.kind == "image"]
SCENE_NAMES = [h.name for h in dg.HYPOTHESES if h.kind == "scene"]


def test_hypotheses_are_one_list_of_unique_names_each_found_by_name():
    names = [h.name for h in dg.HYPOTHESES]
    assert len(names) == len(set(names)) and {h.kind for h in dg.HYPOTHESES} == {"image", "scene", "lobe"}
    assert all(dg.hypothesis(n).name == n for n in names)
    with pytest.raises(dg.DiagnoseError, match="unknown scene hypothesis 'flip_vertical'"):
        dg.hypothesis_scene("flip_vertical", load_scene("furnace"), Path("."))


def test_an_image_only_diagnosis_has_one_row_per_image_hypothesis(ref, correct):
    assert sorted(r.hypothesis for r in dg.diagnose(ref, correct).rows) == sorted(IMAGE_NAMES)


@pytest.mark.parametrize("name", [h for h in IMAGE_NAMES if h not in ("exposure", "hdr_clamp", "premultiplied_alpha")])
def test_planted_image_mismatch_is_named(name, ref, correct):
    t = correct.rgb
    planted = {"flip_vertical": t[::-1], "flip_horizontal": t[:, ::-1], "swap_rb": t[..., ::-1],
               "srgb_as_linear": dg.srgb_oetf(np.clip(t, 0, None)), "linear_as_srgb": dg.srgb_eotf(t)}[name]
    d = dg.diagnose(ref, _with_rgb(correct, planted))
    assert d.likely == name, dg.table_markdown(d)


def test_planted_exposure_is_named_with_its_factor(ref, correct):
    d = dg.diagnose(ref, _with_rgb(correct, correct.rgb * 0.5))
    assert d.likely == "exposure"
    assert d.rows[0].fitted["factor"] == pytest.approx(2.0, rel=0.02)


def _glint_pair(factor: float = 1.0, glints: bool = True):
    """A smooth reference (variance channels of 1e-6) and a test 3 % off it in a pattern, times
    ``factor``, with six glints (radiance 300) where the reference has 5: the sun glints an
    unconverged reference misses (DamagedHelmet under royal_esplanade_1k at 16 spp)."""
    yy, xx = np.mgrid[0:48, 0:64]
    base = 0.2 + 0.8 * (xx / 63.0)[..., None] * np.array([1.0, 0.8, 0.6])
    var = {f"variance.{c}": np.full((48, 64), 1e-6, np.float32) for c in "RGB"}
    ref = Image.from_rgb(base.astype(np.float32), **var)
    t = base * (1.0 + 0.03 * np.sin(xx / 5.0 + yy / 7.0))[..., None]
    if glints:
        px = (np.array([5, 12, 20, 30, 38, 44]), np.array([7, 50, 22, 33, 14, 60]))
        ref.channels["R"][px] = ref.channels["G"][px] = ref.channels["B"][px] = 5.0
        t[px] = 300.0
    return ref, Image.from_rgb((t * factor).astype(np.float32))


def test_glints_alone_name_no_cause_a_planted_factor_with_them_is_named():
    """A few outlier pixels carry most of the relative MSE: a fitted exposure and the sRGB transfer
    remove most of it (there) while making the other pixels worse, so neither is named. A true
    factor moves every pixel: the bulk's error goes with it, and it is named."""
    ref, test = _glint_pair()
    d = dg.diagnose(ref, test)
    rows = {r.hypothesis: r for r in d.rows}
    for name in ("exposure", "linear_as_srgb"):                  # what misled it before
        assert rows[name].reduction > dg.LIKELY_REMAINING and rows[name].bulk_reduction < 0, name
    assert rows["exposure"].fitted["factor"] < 0.5
    assert d.likely is None and d.line.startswith("no convention mismatch found"), dg.table_markdown(d)
    ref, test = _glint_pair(factor=0.1, glints=False)
    d = dg.diagnose(ref, test)
    assert d.likely == "exposure", dg.table_markdown(d)
    assert d.rows[0].bulk_reduction > 0.99


def test_a_brighter_region_is_not_named_an_exposure():
    """A tenth of the image 4x brighter in the test (as the Sample Viewer's background under its
    skybox projection) pulls the exposure fit and even helps the bulk, but the per-pixel ratios'
    median stays at 1: not a global factor."""
    ref, test = _glint_pair(glints=False)
    rgb = test.rgb.copy()
    rgb[:5] *= 4.0
    d = dg.diagnose(ref, Image.from_rgb(rgb))
    row = next(r for r in d.rows if r.hypothesis == "exposure")
    assert row.reduction > dg.LIKELY_REMAINING and row.bulk_reduction > 0.5 and row.fitted["factor"] < 0.6
    assert row.fitted["median_ratio"] == pytest.approx(1.0, abs=0.01)
    assert d.likely != "exposure", dg.table_markdown(d)


def test_planted_clamp_is_named_with_its_level(ref, correct):
    d = dg.diagnose(ref, _with_rgb(correct, np.minimum(correct.rgb, 0.2)))
    assert d.likely == "hdr_clamp", dg.table_markdown(d)
    assert d.rows[0].fitted["level"] == pytest.approx(0.2)


def test_planted_premultiplied_alpha_is_named(ref, correct):
    cov = correct.channels["coverage"]
    d = dg.diagnose(ref, _with_rgb(correct, correct.rgb * cov[..., None]))
    assert d.likely == "premultiplied_alpha", dg.table_markdown(d)


def test_premultiplied_alpha_is_skipped_without_coverage(ref, correct):
    plain = Image.from_rgb(ref.rgb)  # no coverage AOV
    d = dg.diagnose(plain, correct)
    row = next(r for r in d.rows if r.hypothesis == "premultiplied_alpha")
    assert row.skipped and row.error_after is None


def _broken_scene(name: str, scene, tmp: Path):
    """The scene a renderer with mismatch ``name`` effectively renders, built here independently of
    diagnose's own hypothesis scenes (so a wrong hypothesis edit cannot pass by agreeing with itself)."""
    env = scene.environment
    mats = lambda fn: replace(scene, objects=tuple(replace(o, material=fn(o.material))  # noqa: E731
                                                  for o in scene.objects))
    if name.startswith("env_rotate_"):
        return replace(scene, environment=replace(env, rotation=env.rotation + int(name[11:])))
    if name == "env_mirror_u":
        # Texel column c sits at phi = 2 pi (c + 0.5) / W; x -> -x is phi -> 2 pi - phi: column W-1-c.
        em = load_environment(scene)
        path = tmp / "mirror.exr"
        write_exr(path, Image.from_rgb(np.ascontiguousarray(em.data[:, ::-1])))
        return replace(scene, environment=replace(env, type="file", path=str(path)))
    if name == "roughness_as_alpha":   # alpha = r, i.e. perceptual roughness sqrt(r)
        return mats(lambda m: replace(m, roughness=m.roughness ** 0.5))
    if name == "roughness_squared_twice":
        return mats(lambda m: replace(m, roughness=m.roughness ** 2))
    if name in ("diffuse_times_pi", "diffuse_over_pi"):
        k = math.pi if name == "diffuse_times_pi" else 1 / math.pi
        return replace(scene, objects=tuple(
            replace(o, material=replace(o.material, base_color=tuple(k * c for c in o.material.base_color)))
            if o.material.metallic == 0 else o for o in scene.objects))
    if name in ("light_units_4pi", "light_units_over_4pi"):
        k = 4 * math.pi if name == "light_units_4pi" else 1 / (4 * math.pi)
        return replace(scene, lights=tuple(replace(li, intensity=tuple(k * c for c in li.intensity))
                                           for li in scene.lights))
    if name == "multiple_scattering":  # an engine that keeps multiply scattered energy
        return replace(scene, brdf=replace(scene.brdf, multiscatter="random_walk"))
    if name == "metallic_blend":  # a glTF engine: Appendix B's mix of two BRDFs
        return replace(scene, brdf=replace(scene.brdf, metallic_blend="gltf"))
    raise KeyError(name)


def _planted_scene_image(name: str, scene, tmp: Path) -> np.ndarray:
    """Another seed than diagnose's re-renders (seed 0), so the right hypothesis's noise is independent
    of the planted image's and diagnose's noise correction has to absorb it; many samples, so the
    planted image is nearly noise-free like an engine's."""
    return renderers.render_reference(_broken_scene(name, scene, tmp), spp=PLANT_SPP, seed=PLANT_SEED).rgb


@pytest.mark.slow
@pytest.mark.parametrize("name", SCENE_NAMES)
def test_planted_scene_mismatch_is_named(name, scene, ref, tmp_path):
    test = _with_rgb(ref, _planted_scene_image(name, scene, tmp_path))
    d = dg.diagnose(ref, test, scene, spp=SPP)
    assert d.likely == name, dg.table_markdown(d)
    assert ("a model difference" in d.line) == dg.hypothesis(name).model


def test_mirrored_environment_is_the_mirror(scene, tmp_path):
    s2 = dg.hypothesis_scene("env_mirror_u", scene, tmp_path)
    a, b = load_environment(scene), load_environment(s2)
    d = np.random.default_rng(3).standard_normal((256, 3))
    m = d * np.array([-1.0, 1.0, 1.0])
    # Bilinear lookups at mirrored positions agree up to the texel grid's own asymmetry.
    assert np.allclose(b.radiance(d), a.radiance(m), rtol=0.05, atol=0.02)


def test_diagnose_rejects_a_scene_of_another_size(ref, correct):
    other = load_scene("furnace")
    with pytest.raises(dg.DiagnoseError, match="the images are 120x100"):
        dg.diagnose(ref, correct, other)


def test_cli_names_the_cause_writes_json_and_rejects_bad_input(tmp_path, ref, correct, capsys):
    test = tmp_path / "test.exr"
    write_exr(test, _with_rgb(correct, correct.rgb[::-1]))
    out = tmp_path / "d.json"
    assert cli.main(["diagnose", str(REF), str(test), "--json", str(out), "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "likely cause: flip_vertical" in text
    assert json.loads(out.read_text())["likely"] == "flip_vertical"
    small = tmp_path / "small.exr"
    write_exr(small, Image.from_rgb(np.ones((4, 4, 3), np.float32)))
    bad = tmp_path / "bad.json"
    assert cli.main(["diagnose", str(REF), str(small), "--json", str(bad), "--quiet"]) == 2
    assert "size mismatch" in capsys.readouterr().err
    assert not bad.exists()


def _lit_quad_scene(tmp_path: Path, lights: list[dict], env: str = 'type = "constant"') -> Path:
    """A one-quad glTF asset carrying ``lights`` (KHR_lights_punctual, each on its own node 2 above
    the quad), alone in a scene file with environment ``env``."""
    from gltf_build import quad_asset
    doc = json.loads(quad_asset(tmp_path / "q.gltf", {"pbrMetallicRoughness": {"metallicFactor": 0.0}}).read_text())
    if lights:
        doc["extensionsUsed"] = ["KHR_lights_punctual"]
        doc["extensions"] = {"KHR_lights_punctual": {"lights": lights}}
        for k in range(len(lights)):
            doc["nodes"].append({"translation": [0, 2, 0], "extensions": {"KHR_lights_punctual": {"light": k}}})
            doc["scenes"][0]["nodes"].append(len(doc["nodes"]) - 1)
    (tmp_path / "q.gltf").write_text(json.dumps(doc))
    s = tmp_path / "s.toml"
    s.write_text(f'[camera]\norigin = [0.0, 0.0, 4.0]\nwidth = 8\nheight = 8\n[environment]\n{env}\n'
                 '[[objects]]\ntype = "gltf"\npath = "q.gltf"\n')
    return s


def test_light_units_on_asset_scenes_name_the_lights_and_scale_the_assets_own(tmp_path):
    """On a glTF asset scene: the light-units hypotheses say which lights the scene lacks (no point
    lights was printed for a scene lit by its environment alone, and for directional-only ones),
    scale the point and spot lights the asset brings (KHR_lights_punctual) and not its directional
    ones, and the edit changes the scene's content hash (it was the unedited scene's cache entry);
    environment rotations are skipped under a constant environment (the same image: no re-render)."""
    from pbrcheck.environment import scene_hash
    from pbrcheck.lights import DirectionalLight
    ref = Image.from_rgb(np.ones((8, 8, 3), np.float32))
    units = dg.hypothesis("light_units_4pi")
    (tmp_path / "a").mkdir()
    bare = load_scene(_lit_quad_scene(tmp_path / "a", [], env='type = "sky"'))
    why = units.applies_to(ref, bare)
    assert why == "neither the scene file nor its glTF assets (KHR_lights_punctual) have a punctual light: " \
                  "only the environment lights it", why
    assert units.applies_to(ref, load_scene("furnace")) == "the scene has no punctual light: only the " \
                                                           "environment lights it"
    assert all(dg.hypothesis(f"env_rotate_{d}").applies_to(ref, bare) is None for d in (90, 180, 270))
    (tmp_path / "b").mkdir()
    sun = load_scene(_lit_quad_scene(tmp_path / "b", [{"type": "directional", "intensity": 2.0}]))
    assert "directional only" in units.applies_to(ref, sun) and "no 4 pi" in units.applies_to(ref, sun)
    for name in ("env_rotate_90", "env_rotate_180", "env_rotate_270", "env_mirror_u"):
        assert "constant" in dg.hypothesis(name).applies_to(ref, sun), name
    (tmp_path / "c").mkdir()
    both = load_scene(_lit_quad_scene(tmp_path / "c", [{"type": "point", "intensity": 3.0},
                                                         {"type": "directional", "intensity": 2.0}]))
    assert units.applies_to(ref, both) is None and "spot" in units.description
    edited = dg.hypothesis_scene("light_units_4pi", both, tmp_path)
    point, sun_light = edited.lights
    assert point.intensity == pytest.approx((12 * math.pi,) * 3) and isinstance(sun_light, DirectionalLight)
    assert sun_light == both.lights[1]
    assert scene_hash(edited, "e") != scene_hash(both, "e")
    assert scene_hash(load_scene(tmp_path / "c" / "s.toml"), "e") == scene_hash(both, "e")
