"""The real-time renderer's screen-space transmission (issue 37 item 2; realtime/transmission.py,
realtime/shaders/transmission*.glsl): the GLSL closed forms against their numpy twins on grids with the
extremes; known answers in the raster pipeline (an IOR-1 sheet of transmission 1 shows the patterned
ground behind it, attenuated by exactly the spec's Beer-Lambert over its thickness); a scene without
transmission compiles the same shader source and renders a bit-identical image; the ray-cast pipeline
names what it leaves out."""

from __future__ import annotations

import json

import math
import re
import shutil
import subprocess
from dataclasses import replace

import numpy as np
import pytest

from pbrcheck import transmission_params as tp
from pbrcheck.camera import primary_rays
from pbrcheck.scene import Environment, Material, Plane, load_scene
from realtime import transmission as rt
from realtime.gl import assemble
from realtime.glsl_harness import run_glsl
from realtime.render import render_realtime

SMALL = {"cube_size": 32, "irradiance_source_size": 8, "irradiance_size": 8, "prefilter_levels": 4,
         "prefilter_samples": 64, "lut_size": 16, "lut_samples": 256, "supersample": 1, "pipeline": "raster"}
#: float32 GLSL against float64 numpy (log2, pow: a few ulp).
RTOL_F32 = 2e-5
#: The IOR-1 sheet's own specular: F0 = 0, so the split sum leaves B(n.v, 0) of the DFG LUT (small at
#: the test's view angles) added and the (1 - B) weight on the transmitted light; measured at most
#: 5.6e-4 of the ground's radiance (40 x 40, the test's options), so 2e-3.
SHEET_RTOL = 2e-3


def close(got, want, rtol=RTOL_F32, atol=1e-6):
    np.testing.assert_allclose(np.asarray(got, float), np.asarray(want, float), rtol=rtol, atol=atol)


# ---- GLSL closed forms against the numpy twins ---------------------------------------------------

def test_apply_ior_to_roughness_and_lod_glsl_matches_numpy():
    r, ior, w = np.meshgrid([0.0, 0.01, 0.3, 1.0], [0.0, 1.0, 1.2, 1.5, 2.4, 5.0], [1.0, 320.0, 4096.0], indexing="ij")
    close(run_glsl("apply_ior_to_roughness(x0, x1)", r, ior), rt.apply_ior_to_roughness(r, ior))
    close(run_glsl("transmission_lod(x0, x1, x2)", r, ior, w), rt.transmission_lod(r, ior, w), atol=1e-5)
    # the rule's anchors: IOR 1 never blurs, IOR 1.5 and above take the roughness as it is
    assert np.all(rt.apply_ior_to_roughness(r[:, 1], 1.0) == 0.0)
    close(rt.apply_ior_to_roughness(0.3, 1.5), 0.3)
    close(rt.apply_ior_to_roughness(0.3, 1.25), 0.15)
    close(rt.transmission_lod(1.0, 1.5, 1024), 10.0)


def test_dispersion_iors_glsl_matches_numpy():
    ior, d = np.meshgrid([1.0, 1.5, 2.4], [0.0, 0.5, 1.0, 20.0], indexing="ij")
    close(run_glsl("dispersion_iors(x0, x1)", ior, d, components=3), np.stack(
        [rt.dispersion_iors(a, b) for a, b in zip(ior.ravel(), d.ravel())]).reshape(*ior.shape, 3))
    # three.js: halfSpread = (ior - 1) 0.025 dispersion around the middle IOR
    close(rt.dispersion_iors(1.5, 1.0), [1.4875, 1.5, 1.5125])


def test_volume_attenuation_glsl_matches_numpy_and_is_the_specs_beer_lambert():
    t, c, d = np.meshgrid([0.1, 0.9, 4.0], [0.0, 0.15, 0.45, 1.0], [0.0, 0.5, 10.0], indexing="ij")
    got = run_glsl("volume_attenuation(x0, vec3(x1), x2)", t, c, d, components=3)[..., 0]
    want = np.vectorize(lambda a, b, e: rt.volume_attenuation(a, (b, b, b), e)[0])(t, c, d)
    close(got, want, atol=1e-6)
    # the spec's Beer-Lambert: exp(-sigma_t t), sigma_t = -ln(attenuationColor) / attenuationDistance
    vol = tp.Volume(thickness=0.9, attenuation_distance=0.5, attenuation_color=(0.9, 0.45, 0.15))
    close(rt.volume_attenuation(0.9, vol.attenuation_color, 0.5), np.exp(-np.asarray(vol.sigma_t) * 0.9), rtol=1e-12)
    assert np.all(rt.volume_attenuation(3.0, (0.2, 0.5, 0.7), 0.0) == 1.0)       # 0: none (scene files)
    assert np.all(rt.volume_attenuation(3.0, (0.2, 0.5, 0.7), math.inf) == 1.0)  # glTF's default


def test_bicubic_weights_glsl_matches_numpy_and_sum_to_one():
    a = np.linspace(0.0, 1.0, 11)
    got = np.stack([run_glsl(f"bc_w{k}(x0)", a) for k in range(4)], -1)
    want = rt.bspline_weights(a)
    close(got, want, atol=1e-6)
    close(want.sum(-1), 1.0, rtol=1e-12)
    close(rt.bspline_weights(0.0), [1 / 6, 4 / 6, 1 / 6, 0.0], rtol=1e-12)


def test_filament_refraction_roughness_glsl_matches_numpy():
    r, ior = np.meshgrid([0.0, 0.01, 0.3, 1.0], [1.0, 1.2, 1.4, 1.5, 2.4, 5.0], indexing="ij")
    close(run_glsl("filament_refraction_roughness(x0, x1)", r, ior), rt.filament_refraction_roughness(r, ior))
    # Filament's anchors: IOR 1 never blurs (etaIR 3 - 2 = 1), 1.5 and above take the roughness as it is
    assert np.all(rt.filament_refraction_roughness(r[:, 0], 1.0) == 0.0)
    close(rt.filament_refraction_roughness(0.3, 1.5), 0.3)
    close(rt.filament_refraction_roughness(0.6, 1.2), 0.6 * (1.0 - (3.0 / 1.2 - 2.0)))


def test_refraction_direction_glsl_matches_numpy_and_ior_1_goes_straight():
    """Filament's solid and thin refraction directions on a grid of view angles (normal incidence to
    grazing 89 deg, where the solid form meets total internal reflection and falls back), IORs 1 to 3."""
    ang = np.radians([0.0, 20.0, 45.0, 70.0, 85.0, 89.0])
    ior = np.array([1.0, 1.33, 1.5, 2.4, 3.0])
    th = np.array([0.0, 0.5])
    A, I, T = np.meshgrid(ang, ior, th, indexing="ij")
    v = np.stack([np.sin(A), np.cos(A), np.zeros_like(A)], -1)      # n = +y, v towards the eye
    n = np.broadcast_to([0.0, 1.0, 0.0], v.shape)
    got = run_glsl("refraction_direction(vec3(0.0, 1.0, 0.0), vec3(x0, x1, 0.0), x2, x3)",
                   v[..., 0], v[..., 1], I, T, components=3)
    want = rt.refraction_direction(n, v, I, T)
    close(got, want, atol=2e-5)
    close(np.linalg.norm(want, axis=-1), 1.0, rtol=1e-9)
    close(want[..., 0, :], -v[..., 0, :], atol=1e-12)          # thin: the view ray
    close(want[:, 0, 1], -v[:, 0, 1], atol=1e-12)              # IOR 1 solid: straight through
    # normal incidence goes straight through any sphere; oblique glass bends (away from the straight ray)
    close(want[0, :, 1], [[0.0, -1.0, 0.0]] * len(ior), atol=1e-12)
    assert np.dot(want[2, 2, 1], -v[2, 2, 1]) < 0.999


# ---- programs: compiled only where a scene has transmission --------------------------------------

def test_transmission_defines_only_for_scenes_with_transmission():
    from realtime.presets import resolve_options
    o = resolve_options("default", {})
    glass, plain = load_scene("glass"), load_scene("clearcoat")
    assert rt.transmission_defines(plain, o, "raster") == {} == rt.transmission_defines(plain, o, "raycast")
    d = rt.transmission_defines(glass, o, "raster")
    assert d["TRANSMISSION"] == 1 and d["TRANSMISSION_LOD"] == "TRANSMISSION_LOD_SAMPLE_VIEWER"
    assert d["TRANSMISSION_SOURCE"] == "TRANSMISSION_SOURCE_SCREEN" and "TRANSMISSION_PER_OBJECT" not in d
    o3 = resolve_options("default", {"transmission_lod": "threejs"})
    assert rt.transmission_defines(glass, o3, "raster")["TRANSMISSION_LOD"] == "TRANSMISSION_LOD_THREEJS"
    # the ray-cast pipeline has no opaque-pass framebuffer: Filament's cube, the material per object
    c = rt.transmission_defines(glass, o, "raycast")
    assert c["TRANSMISSION_SOURCE"] == "TRANSMISSION_SOURCE_CUBEMAP" and c["TRANSMISSION_PER_OBJECT"] == 1
    oc = resolve_options("default", {"transmission_source": "cubemap"})
    assert rt.transmission_defines(glass, oc, "raster")["TRANSMISSION_SOURCE"] == "TRANSMISSION_SOURCE_CUBEMAP"
    assert rt.transmission_defines(glass, resolve_options("default", {"shading": "article000"}), "raycast") == {}


def _preprocessed(defines: dict, source: str = "raster.frag") -> str:
    """``source`` assembled and through the C preprocessor (comments and ``#version`` dropped): what the
    GLSL compiler sees."""
    src = "\n".join(line for line in assemble(source, defines).text.splitlines() if not line.startswith("#version"))
    out = subprocess.run(["cpp", "-P", "-undef", "-w"], input=src, capture_output=True, text=True, check=True).stdout
    return re.sub(r"\s+", " ", out)


@pytest.mark.skipif(shutil.which("cpp") is None, reason="needs the C preprocessor (cpp) to see past #ifdef")
@pytest.mark.parametrize("preset", ["default", "sample_viewer"])
def test_a_transmission_free_program_has_no_transmission_code(preset):
    """raster.frag without TRANSMISSION preprocesses to a source naming no transmission symbol; with a
    glass scene's defines it does (so the check can fail). Checked once by hand against the parent
    commit (b628101): the preprocessed raster.frag of both presets' frame defines is identical."""
    from realtime import render as R
    from realtime.presets import resolve_options
    o = resolve_options(preset)
    scene = load_scene("spheres")
    terms = {**R.resolved_terms(scene, o), "energy_compensation": R.resolved_energy_compensation(scene, o)}
    base = {**R.frame_defines(o, terms), "AOV_PASS": 0}
    symbols = re.compile(r"\b(transmission_\w+|apply_ior_to_roughness|volume_attenuation|bc_w\d)\b")
    assert rt.transmission_defines(scene, o, "raster") == {}
    assert not symbols.search(_preprocessed(base))
    found = {m.group(1) for m in symbols.finditer(_preprocessed({**base, **rt.transmission_defines(
        load_scene("glass"), o, "raster")}))}
    assert {"transmission_fb", "apply_ior_to_roughness", "volume_attenuation"} <= found
    # render.comp likewise (the ray-cast pipeline): nothing without transmission, the cube refraction with it
    assert rt.transmission_defines(scene, o, "raycast") == {}
    assert not symbols.search(_preprocessed(frame := R.frame_defines(o, terms), "render.comp"))
    found = {m.group(1) for m in symbols.finditer(_preprocessed({**frame, **rt.transmission_defines(
        load_scene("glass"), o, "raycast")}, "render.comp"))}
    assert {"transmission_change", "volume_attenuation"} <= found and "transmission_fb" not in found


def test_presets_take_the_sample_viewer_rule():
    from realtime.presets import PRESETS
    assert PRESETS["default"]["transmission_lod"] == "sample_viewer"
    assert PRESETS["sample_viewer"]["transmission_lod"] == "sample_viewer"
    assert rt.REALTIME_TRANSMISSION_EXTENSIONS == (tp.TRANSMISSION, tp.VOLUME, tp.DISPERSION, tp.DIFFUSE_TRANSMISSION)


def test_raycast_renders_transmission_and_auto_takes_the_raster_pipeline():
    """pipeline=raycast (and auto with shadows, which only the ray-cast pipeline has) renders glass by
    Filament's cube refraction, with no notice; auto otherwise takes the raster pipeline for a transmissive
    analytic scene; a composition other than material draws it opaque and says so in one line."""
    scene = load_scene("glass").with_camera(width=8, height=6)
    img = render_realtime(scene, "default", {**SMALL, "pipeline": "raycast"}, progress=False)
    assert "transmission" not in img.meta["warnings"]
    shadowed = render_realtime(scene, "default", {**SMALL, "pipeline": "auto", "shadows": True}, progress=False)
    assert shadowed.meta["pipeline"] == "raycast" and "transmission" not in shadowed.meta["warnings"]
    auto = render_realtime(scene, "default", {**SMALL, "pipeline": "auto"}, progress=False)
    assert auto.meta["pipeline"] == "raster" and "transmission_unmodelled" not in auto.meta["warnings"]
    plain = render_realtime(load_scene("spheres").with_camera(width=8, height=6), "default",
                            {**SMALL, "pipeline": "auto"}, progress=False)
    assert plain.meta["pipeline"] == "raycast"
    karis = render_realtime(scene, "default", {**SMALL, "pipeline": "raycast", "shading": "article000"},
                            progress=False)
    assert "transmission_unmodelled: shading=article000 renders transmissive materials opaque" in karis.meta["warnings"]
    # the metadata says which source each render read, not only the option requested (screen, the default)
    assert json.loads(img.meta["transmission"]) == {"source": "cubemap", "source_requested": "screen",
                                                    "lod": img_lod(img), "per_object": True}
    assert json.loads(auto.meta["transmission"])["source"] == "screen"
    assert json.loads(auto.meta["transmission"])["per_object"] is False
    assert "transmission" not in plain.meta and "transmission" not in karis.meta


def img_lod(img) -> str:
    return json.loads(img.meta["options"])["transmission_lod"]


# ---- known answers in the raster pipeline ---------------------------------------------------------

def _ground_scene(sheet: Material | None, width: int = 40):
    """The glass scene's checkered ground seen from above, and optionally a 1.6 x 1.6 sheet at y = 0
    facing the camera, covering the image's centre."""
    g = load_scene("glass").with_camera(origin=(0.0, 3.0, 0.5), target=(0.0, -0.5, 0.0), width=width, height=width)
    ground = [ob for ob in g.objects if ob.name.startswith("ground")]
    objs = list(ground)
    if sheet is not None:
        objs.append(Plane(id=len(objs), center=(0.0, 0.0, 0.0), normal=(0.0, 1.0, 0.0), size=(1.6, 1.6),
                          material=sheet, name="sheet"))
    objs = [replace(ob, id=k) for k, ob in enumerate(objs)]
    return replace(g, objects=tuple(objs))


def _rgb(img):
    return np.stack([img.channels[c] for c in "RGB"], -1)


def _sheet_pixels(img):
    return img.channels["object"] == float(len(_ground_scene(None).objects))


@pytest.mark.parametrize("lod", ["sample_viewer", "threejs"])
def test_ior1_sheet_of_transmission_1_shows_the_ground_attenuated_by_beer_lambert(lod):
    """A sheet of transmission 1, IOR 1 (F0 0), roughness 0 and white base colour over the checkered
    ground: the refracted ray is the view ray, the framebuffer is read at level 0 at the pixel's own
    texel, so the sheet shows the ground (the image without the sheet) times the Beer-Lambert
    attenuation attenuationColor^(thickness / attenuationDistance) of the spec, exp(-sigma_t t)."""
    c, d, t = (0.9, 0.45, 0.15), 0.5, 0.3
    sheet = Material(base_color=(1.0, 1.0, 1.0), metallic=0.0, roughness=0.0, specular=0.0, transmission=1.0,
                     thickness=t, attenuation_distance=d, attenuation_color=c)
    opts = {**SMALL, "transmission_lod": lod}
    bare = render_realtime(_ground_scene(None), "default", opts, progress=False)
    img = render_realtime(_ground_scene(sheet), "default", opts, progress=False)
    m = _sheet_pixels(img)
    assert m.sum() > 100  # the sheet covers the image's centre
    att = np.exp(-np.asarray(tp.Volume(thickness=t, attenuation_distance=d, attenuation_color=c).sigma_t) * t)
    want = _rgb(bare)[m] * att
    got = _rgb(img)[m]
    if lod == "sample_viewer":   # trilinear at level 0 on the texel centre: the texel itself
        np.testing.assert_allclose(got, want, rtol=SHEET_RTOL, atol=1e-4)
    else:   # three.js's B-spline spreads each texel over its neighbours (1/6, 4/6, 1/6): the checker's edges blur
        interior = np.abs(got - want) <= SHEET_RTOL * want + 1e-4
        assert interior.mean() > 0.8
        close(got.mean(axis=0), want.mean(axis=0), rtol=0.03)
    # and the checker shows through: light and dark tiles both under the sheet
    lum = got.mean(-1)
    assert lum.max() > 5 * lum.min()


def test_rough_sheet_blurs_by_the_lod_rule_and_ior_1_does_not():
    """At IOR 1 applyIorToRoughness is 0: a rough sheet is as sharp as a smooth one; at IOR 1.5 it reads
    level log2(width) r and the checker's contrast under it falls."""
    def sheet(rough, f0):
        return Material(base_color=(1.0, 1.0, 1.0), metallic=0.0, roughness=rough, specular=f0, transmission=1.0)
    f0_15 = ((1.5 - 1.0) / 2.5) ** 2
    imgs = {k: render_realtime(_ground_scene(sheet(*k)), "default", SMALL, progress=False)
            for k in ((0.0, 0.0), (0.6, 0.0), (0.6, f0_15))}
    m = _sheet_pixels(imgs[(0.0, 0.0)])

    def contrast(img):
        lum = _rgb(img)[m].mean(-1)
        return float(lum.std() / lum.mean())

    c0, c_ior1, c_ior15 = (contrast(imgs[k]) for k in ((0.0, 0.0), (0.6, 0.0), (0.6, f0_15)))
    assert c_ior1 == pytest.approx(c0, rel=0.02)
    assert c_ior15 < 0.5 * c0


def test_scene_without_transmission_is_bit_identical_and_takes_no_opaque_pass():
    """Without a transmissive material there is no opaque pass and the option changes nothing, bit for
    bit (the parent commit's image, checked by hand: identical); with a sheet, the ground outside it
    keeps its bits (the TRANSMISSION program shades a non-transmissive draw as before)."""
    from realtime import raster
    scene = _ground_scene(Material(base_color=(0.5, 0.5, 0.5), roughness=0.3))
    calls = []
    orig = raster._opaque_pass
    raster._opaque_pass = lambda *args, **kw: calls.append(1) or orig(*args, **kw)
    try:
        a = render_realtime(scene, "default", SMALL, progress=False)
        b = render_realtime(scene, "default", {**SMALL, "transmission_lod": "threejs"}, progress=False)
        assert calls == []   # no opaque pass
        glass = render_realtime(_ground_scene(Material(roughness=0.0, specular=0.0, transmission=1.0)), "default",
                                SMALL, progress=False)
        assert calls == [1]
    finally:
        raster._opaque_pass = orig
    assert np.array_equal(_rgb(a), _rgb(b))
    outside = ~_sheet_pixels(glass) & ~_sheet_pixels(a)
    assert outside.sum() > 100
    assert np.array_equal(_rgb(glass)[outside], _rgb(a)[outside])
    assert not np.array_equal(_rgb(glass)[~outside], _rgb(a)[~outside])


def test_gltf_transmission_volume_quad_in_a_white_environment(tmp_path):
    """A glTF quad with KHR_materials_transmission 1, KHR_materials_ior 1 and KHR_materials_volume
    (thicknessFactor 0.5, attenuationDistance 1, attenuationColor (0.5, 0.25, 1)) in a constant white
    environment: behind it the opaque pass holds the environment's 1, so the quad is the Beer-Lambert
    transmittance c^(t / d) = (0.5^0.5, 0.25^0.5, 1) (F0 0: only the DFG's B at n.v ~ 1 besides)."""
    import sys
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).parent))
    from gltf_build import quad_asset, quad_scene
    c = [0.5, 0.25, 1.0]
    asset = quad_asset(tmp_path / "sheet.gltf", {
        "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.0},
        "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0}, "KHR_materials_ior": {"ior": 1.0},
                       "KHR_materials_volume": {"thicknessFactor": 0.5, "attenuationDistance": 1.0,
                                                "attenuationColor": c}}}, tangents=False)
    scene = load_scene(quad_scene(tmp_path, asset))
    img = render_realtime(scene, "default", {**SMALL, "pipeline": "auto"}, progress=False)
    m = img.channels["object"] >= 0
    assert m.sum() > 100
    np.testing.assert_allclose(_rgb(img)[m], np.broadcast_to(np.sqrt(c), (int(m.sum()), 3)), rtol=SHEET_RTOL, atol=1e-4)


def test_diffuse_transmission_sheet_in_a_white_environment_is_its_colour():
    """A sheet of diffuse_transmission 1 (colour c), IOR 1 (F0 0), roughness 0, white base in a constant
    white environment: the diffuse is replaced by the back's irradiance E(-n) / pi = 1 times c (the
    Sample Viewer's form); the specular adds the DFG's B at roughness 0 only. No opaque pass is taken."""
    from realtime import raster
    c = (0.8, 0.4, 0.1)
    sheet = Material(base_color=(1.0, 1.0, 1.0), metallic=0.0, roughness=0.0, specular=0.0,
                     diffuse_transmission=1.0, diffuse_transmission_color=c)
    scene = replace(_ground_scene(sheet), environment=Environment(type="constant", radiance=(1.0, 1.0, 1.0)))
    calls = []
    orig = raster._opaque_pass
    raster._opaque_pass = lambda *args, **kw: calls.append(1) or orig(*args, **kw)
    try:
        img = render_realtime(scene, "default", SMALL, progress=False)
    finally:
        raster._opaque_pass = orig
    assert calls == []
    m = _sheet_pixels(img)
    assert m.sum() > 100
    np.testing.assert_allclose(_rgb(img)[m], np.broadcast_to(c, (int(m.sum()), 3)), rtol=SHEET_RTOL, atol=2e-3)


def test_gltf_transmission_and_thickness_textures(tmp_path):
    """One image as both the transmissionTexture (R) and the thicknessTexture (G): the left half R 0
    (opaque: the white diffuse quad in a white environment, ~1 in every channel), the right half R 1 and
    G 0.5 (thickness 0.5 x 0.5: the transmittance c^(0.25 / 1)). Columns near the seam (bilinear and mip
    blur) are left out."""
    import sys
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).parent))
    from gltf_build import quad_asset, quad_scene
    c = np.array([0.5, 0.25, 1.0])
    px = np.zeros((64, 64, 3), np.uint8)
    px[:, :32] = (0, 255, 0)
    px[:, 32:] = (255, 128, 0)
    asset = quad_asset(tmp_path / "tex.gltf", {
        "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.0},
        "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0, "transmissionTexture": {"index": 0}},
                       "KHR_materials_ior": {"ior": 1.0},
                       "KHR_materials_volume": {"thicknessFactor": 0.5, "thicknessTexture": {"index": 0},
                                                "attenuationDistance": 1.0, "attenuationColor": c.tolist()}}},
        [(px, None)], tangents=False)
    scene = load_scene(quad_scene(tmp_path, asset, size=(48, 48)))
    img = render_realtime(scene, "default", {**SMALL, "pipeline": "auto"}, progress=False)
    m = img.channels["object"] >= 0
    cols = np.nonzero(m.any(axis=0))[0]
    lo, hi = cols.min(), cols.max()
    x = np.arange(img.channels["R"].shape[1])[None, :].repeat(m.shape[0], 0)
    left = m & (x < lo + 0.35 * (hi - lo))
    right = m & (x > lo + 0.65 * (hi - lo))
    assert left.sum() > 50 and right.sum() > 50
    rgb = _rgb(img)
    # right: G 128/255 of the thickness 0.5 (the PNG's 8 bits), transmission 1
    t = 0.5 * 128 / 255
    np.testing.assert_allclose(rgb[right], np.broadcast_to(c ** t, (int(right.sum()), 3)), rtol=5e-3, atol=1e-3)
    # left: transmission 0, an opaque white dielectric in a white environment: grey-white, not tinted
    assert np.all(np.abs(rgb[left] - rgb[left].mean(-1, keepdims=True)) < 1e-3)
    assert rgb[left].min() > 0.8


# ---- known answers in the ray-cast pipeline (Filament's cube-map refraction) ------------------------

#: The IOR-1 sheet against the environment it hides, ray-cast: the background pixels read the
#: equirectangular map, the sheet the prefiltered cube's level 0 (64^2 faces, bilinear) along the same
#: direction; on the smooth sunless sky the two differ by the cube's resampling and the sheet's own
#: B(n.v, 0) specular, measured at most 0.6 % (48 x 48, these options), so 2 %.
RAYCAST_ENV_RTOL = 0.02
#: The sky's step to the ground at the horizon is resampled by the cube over about two of its texels
#: (64^2 faces: 90 / 64 = 1.4 deg each): pixels within this elevation of the horizon are left out.
HORIZON_MARGIN_DEG = 4.0


def _raycast_sheet_scene(sheet: Material | None, env: Environment, width: int = 48):
    """A vertical 1.6 x 1.6 sheet at z = 0 facing the camera, which looks at the horizon through it
    (the sky's gradient above, the ground's below), nothing behind it: the environment shows through."""
    g = load_scene("glass").with_camera(origin=(0.0, 0.2, 2.5), target=(0.0, 0.2, 0.0), width=width, height=width)
    objs = () if sheet is None else (Plane(id=0, center=(0.0, 0.2, 0.0), normal=(0.0, 0.0, 1.0), size=(1.6, 1.6),
                                           material=sheet, name="sheet"),)
    return replace(g, objects=objs, environment=env)


@pytest.mark.parametrize("thickness", [0.0, 0.3])   # thin, and Filament's solid sphere
def test_raycast_ior1_sheet_shows_the_environment_behind_it(thickness):
    """Transmission 1, IOR 1 (F0 0), roughness 0, white: the cube refraction's direction is the view ray
    (thin: -v; solid at IOR 1: straight through), so the sheet shows the sky it hides: the same pixels
    without the sheet."""
    sky = Environment(type="sky", sun_radiance=(0.0, 0.0, 0.0))
    sheet = Material(base_color=(1.0, 1.0, 1.0), metallic=0.0, roughness=0.0, specular=0.0, transmission=1.0,
                     thickness=thickness)
    opts = {**SMALL, "pipeline": "raycast", "cube_size": 64}
    bare = render_realtime(_raycast_sheet_scene(None, sky), "default", opts, progress=False)
    img = render_realtime(_raycast_sheet_scene(sheet, sky), "default", opts, progress=False)
    _, d = primary_rays(_raycast_sheet_scene(None, sky).camera)
    m = (img.channels["object"] == 0.0) & (np.abs(np.degrees(np.arcsin(d[..., 1]))) > HORIZON_MARGIN_DEG)
    assert m.sum() > 400 and img.meta["pipeline"] == "raycast"
    np.testing.assert_allclose(_rgb(img)[m], _rgb(bare)[m], rtol=RAYCAST_ENV_RTOL)
    # and the sky's gradient shows through (not one flat colour)
    assert np.ptp(_rgb(img)[m][:, 2]) > 0.05 * _rgb(img)[m][:, 2].mean()


def test_raycast_tinted_sphere_is_the_environment_times_beer_lambert():
    """A sphere of transmission 1, IOR 1, roughness 0, white, thickness t in a constant environment L:
    the split sum's specular gives L B(n.v, 0) (F0 0), the transmitted light L (1 - B) times the
    Beer-Lambert attenuation a = exp(-sigma_t t). So a clear sphere (attenuation colour 1) is L at every
    pixel, an opaque-black one (colour 0: a = 0) is the specular L B alone, and a tinted one is exactly
    L B + (L - L B) a: the environment times exp(-sigma_t t) where B is 0 (its centre)."""
    c, d, t, L = (0.9, 0.45, 0.15), 0.5, 0.3, 0.7
    g = load_scene("glass")
    ball = next(ob for ob in g.objects if getattr(ob, "radius", 0.0) > 0.0)
    g = g.with_camera(origin=tuple(np.add(ball.center, (0.0, 0.0, 4.0 * ball.radius))), target=ball.center,
                      width=24, height=24)

    def render(color):
        glass = Material(base_color=(1.0, 1.0, 1.0), metallic=0.0, roughness=0.0, specular=0.0, transmission=1.0,
                         thickness=t, attenuation_distance=d, attenuation_color=color)
        scene = replace(g, objects=(replace(ball, id=0, material=glass),),
                        environment=Environment(type="constant", radiance=(L, L, L)))
        return render_realtime(scene, "default", {**SMALL, "pipeline": "raycast"}, progress=False)

    tinted, clear, black = render(c), render((1.0, 1.0, 1.0)), render((0.0, 0.0, 0.0))
    m = tinted.channels["object"] == 0.0
    assert m.sum() > 200
    att = np.exp(-np.asarray(tp.Volume(thickness=t, attenuation_distance=d, attenuation_color=c).sigma_t) * t)
    spec = _rgb(black)[m]
    np.testing.assert_allclose(_rgb(clear)[m], L, rtol=1e-5)
    np.testing.assert_allclose(_rgb(tinted)[m], spec + (L - spec) * att, rtol=1e-5, atol=1e-6)
    # the centre pixel (n.v = 1, B(1, 0) small): the environment times exp(-sigma_t t)
    centre = _rgb(tinted)[12, 12]
    np.testing.assert_allclose(centre, L * att, rtol=SHEET_RTOL, atol=1e-4)


def test_raycast_diffuse_transmission_sheet_in_a_white_environment_is_its_colour():
    """The raster pipeline's diffuse-transmission known answer in the ray-cast pipeline (the same GLSL):
    E(-n) / pi = 1 times the colour c, plus the DFG's B at roughness 0 only."""
    c = (0.8, 0.4, 0.1)
    sheet = Material(base_color=(1.0, 1.0, 1.0), metallic=0.0, roughness=0.0, specular=0.0,
                     diffuse_transmission=1.0, diffuse_transmission_color=c)
    img = render_realtime(_raycast_sheet_scene(sheet, Environment(type="constant", radiance=(1.0, 1.0, 1.0)), 24),
                          "default", {**SMALL, "pipeline": "raycast"}, progress=False)
    m = img.channels["object"] == 0.0
    assert m.sum() > 100 and img.meta["pipeline"] == "raycast"
    np.testing.assert_allclose(_rgb(img)[m], np.broadcast_to(c, (int(m.sum()), 3)), rtol=SHEET_RTOL, atol=2e-3)


def test_raster_with_the_cubemap_source_takes_no_opaque_pass_and_matches_the_ray_cast_pipeline():
    """transmission_source = cubemap in the raster pipeline: Filament's cube refraction, no opaque pass;
    an IOR-1 sheet over the checkered ground then shows the environment (below the horizon: one colour),
    not the ground, as the ray-cast pipeline does (the same GLSL: equal within float noise)."""
    from realtime import raster
    sheet = Material(base_color=(1.0, 1.0, 1.0), metallic=0.0, roughness=0.0, specular=0.0, transmission=1.0)
    scene = _ground_scene(sheet, 24)
    calls = []
    orig = raster._opaque_pass
    raster._opaque_pass = lambda *args, **kw: calls.append(1) or orig(*args, **kw)
    try:
        img = render_realtime(scene, "default", {**SMALL, "transmission_source": "cubemap"}, progress=False)
    finally:
        raster._opaque_pass = orig
    assert calls == [] and img.meta["pipeline"] == "raster"
    ray = render_realtime(scene, "default", {**SMALL, "pipeline": "raycast"}, progress=False)
    m = _sheet_pixels(img) & _sheet_pixels(ray)
    assert m.sum() > 100
    np.testing.assert_allclose(_rgb(img)[m], _rgb(ray)[m], rtol=1e-4, atol=1e-6)
    lum = _rgb(img)[m].mean(-1)
    assert lum.max() < 1.01 * lum.min()   # the environment, not the checker
