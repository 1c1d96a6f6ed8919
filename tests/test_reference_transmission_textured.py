"""reference/transmission.py's textured transmissive glTF material (issue 37): ``pbr_transmissive_textured``
reads the transmission, base colour and metallic-roughness textures per hit in the reference's ``path``
mode. Known answers: a thin sheet of IOR 1 and roughness 0 passes the environment behind it unchanged
where it transmits (Fresnel 0 at IOR 1, within the camera's 15 degrees of normal incidence: (1 - cos)^5
< 1e-7), tinted by the base colour; a roughness texel renders as the constant-factor material of that
roughness (the same sampler, the same seed); the shared TransmissionTest and TransmissionRoughnessTest
render with transmission (slow, skipped where ../shared is absent)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pbrcheck.scene import scene_from_dict
from tests.gltf_build import quad_asset

SUN_BEHIND = {"type": "sky", "sun_direction": [0.1, 0.15, 0.98], "sun_angular_diameter": 20.0}
PATH = dict(mode="path", max_depth=8, progress=False, seed=1)
#: A transmitted pixel of a clear IOR-1 sheet equals the environment behind: float32 noise only.
PASS_ATOL = 1e-5
NEAREST = {"magFilter": 9728}
SHARED = Path(__file__).resolve().parents[2] / "shared" / "assets" / "khronos"
#: The smallest 99th percentile over pixels of max_rgb |transmission - opaque| a shared asset's 48 x 48,
#: 4 spp path render must show (as tests/test_lobes_reference.py's ASSET_MIN_CHANGE).
ASSET_MIN_CHANGE = 1e-2


@pytest.fixture(scope="module")
def render():
    from reference.variant import ensure_variant

    ensure_variant()
    from reference.render import render_uncached

    return lambda scene, spp=8: render_uncached(scene, spp=spp, **PATH)


def _sheet(tmp_path, name, images, *, pbr=None, ext=None, ior=1.0):
    mat = {"name": name, "pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 0.0, **(pbr or {})},
           "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0, **(ext or {})},
                          "KHR_materials_ior": {"ior": ior}}}
    return quad_asset(tmp_path / f"{name}.gltf", mat, images, scale=3.0)


def _scene(asset, translation=(0.0, 0.0, 0.0)):
    return scene_from_dict({"camera": {"origin": [0, 0, 4], "target": [0, 0, 0], "fov": 30, "width": 12, "height": 12},
                            "environment": SUN_BEHIND,
                            "objects": [{"type": "gltf", "path": str(asset), "translation": list(translation)}]})


def _rgb(img):
    return np.stack([img.channels[c] for c in ("R", "G", "B")], -1)


def test_a_transmission_texture_of_zero_and_one_halves(render, tmp_path):
    """transmissionTexture R 0 on the left half, 1 on the right (NEAREST): the right half of the image
    is the environment behind (the sheet moved out of view), the left half the opaque white diffuse."""
    px = np.zeros((4, 4, 4), np.uint8)
    px[..., 3] = 255
    px[:, 2:, 0] = 255
    sheet = _sheet(tmp_path, "half", [(px, NEAREST)], ext={"transmissionTexture": {"index": 0}})
    seen, away = _rgb(render(_scene(sheet))), _rgb(render(_scene(sheet, (50.0, 0.0, 0.0))))
    np.testing.assert_allclose(seen[:, 6:], away[:, 6:], atol=PASS_ATOL)
    assert np.abs(seen[:, :6] - away[:, :6]).max(axis=-1).min() > 0.05


def test_a_base_color_texture_tints_the_transmission(render, tmp_path):
    """baseColorTexture (sRGB (255, 188, 64)) on a clear IOR-1 sheet: the image is the environment
    behind times the decoded colour ([Trans]: specular_btdf * baseColor)."""
    from pbrcheck.gltf import load_asset

    px = np.zeros((2, 2, 4), np.uint8)
    px[...] = (255, 188, 64, 255)
    sheet = _sheet(tmp_path, "tint", [(px, None)], pbr={"baseColorTexture": {"index": 0}})
    tint = load_asset(sheet).images[0].linear(True)[0, 0, :3]
    seen, away = _rgb(render(_scene(sheet))), _rgb(render(_scene(sheet, (50.0, 0.0, 0.0))))
    np.testing.assert_allclose(seen, away * tint, atol=PASS_ATOL, rtol=1e-5)
    assert tint[2] < 0.1 < away.min()


def test_a_roughness_texel_renders_as_the_factor_of_that_roughness(render, tmp_path):
    """metallicRoughnessTexture G = 128 under roughnessFactor 1 renders as a constant sheet of roughness
    128/255 (the same sampler and seed); G = 255 as roughness 1, and the two differ (the blur)."""
    def rough_sheet(g):
        px = np.zeros((2, 2, 4), np.uint8)
        px[...] = (0, g, 0, 255)
        return _sheet(tmp_path, f"tex{g}", [(px, None)], ior=1.5,
                      pbr={"roughnessFactor": 1.0, "metallicRoughnessTexture": {"index": 0}})

    def const_sheet(r):
        return _sheet(tmp_path, f"const{r:.3f}", [], ior=1.5, pbr={"roughnessFactor": r})

    half, full = _rgb(render(_scene(rough_sheet(128)))), _rgb(render(_scene(rough_sheet(255))))
    np.testing.assert_allclose(half, _rgb(render(_scene(const_sheet(128 / 255)))), atol=1e-4, rtol=1e-4)
    np.testing.assert_allclose(full, _rgb(render(_scene(const_sheet(1.0)))), atol=1e-4, rtol=1e-4)
    assert np.abs(half - full).max() > 0.05


def test_diffuse_transmission_textures_render_as_their_constant_twin(render, tmp_path):
    """diffuseTransmissionTexture A (153 = 0.6) times factor 1 and diffuseTransmissionColorTexture
    (sRGB (255, 128, 64)) render as the sheet of constant factor 0.6 and colour the decoded texel (the
    same sampler and seed); both differ from the sheet without diffuse transmission's colour."""
    from pbrcheck.gltf import load_asset

    def sheet(name, dt, images):
        mat = {"name": name, "pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 0.5},
               "extensions": {"KHR_materials_diffuse_transmission": dt}}
        return quad_asset(tmp_path / f"{name}.gltf", mat, images, scale=3.0)

    a = np.zeros((2, 2, 4), np.uint8)
    a[..., 3] = 153
    c = np.zeros((2, 2, 4), np.uint8)
    c[...] = (255, 128, 64, 255)
    tex = sheet("dttex", {"diffuseTransmissionFactor": 1.0, "diffuseTransmissionTexture": {"index": 0},
                          "diffuseTransmissionColorTexture": {"index": 1}}, [(a, None), (c, None)])
    color = load_asset(tex).images[1].linear(True)[0, 0, :3]
    const = sheet("dtconst", {"diffuseTransmissionFactor": 153 / 255,
                              "diffuseTransmissionColorFactor": [float(x) for x in color]}, [])
    white = sheet("dtwhite", {"diffuseTransmissionFactor": 153 / 255}, [])
    seen = _rgb(render(_scene(tex)))
    np.testing.assert_allclose(seen, _rgb(render(_scene(const))), atol=1e-4, rtol=1e-4)
    assert np.abs(seen - _rgb(render(_scene(white)))).max() > 0.01


def test_a_transmission_texture_is_rendered_and_a_lobe_texture_keeps_it_opaque(tmp_path):
    """A transmission-textured material is rendered by the reference (reference_renders) through
    ``pbr_transmissive_textured`` (modelled: no notice); a lobe texture (clearcoat) still leaves it opaque,
    its transmission named with the reason."""
    from pbrcheck.gltf import load_asset
    from pbrcheck.transmission_params import reference_renders
    from pbrcheck.unmodelled import notice_lines

    px = np.full((2, 2, 4), 255, np.uint8)
    tex = _sheet(tmp_path, "tex", [(px, None)], ext={"transmissionTexture": {"index": 0}})
    coat = quad_asset(tmp_path / "coat.gltf", {"name": "coat", "extensions": {
        "KHR_materials_transmission": {"transmissionFactor": 1.0},
        "KHR_materials_clearcoat": {"clearcoatFactor": 1.0, "clearcoatTexture": {"index": 0}}}}, [(px, None)])
    assert reference_renders(load_asset(tex).materials[0]) and not reference_renders(load_asset(coat).materials[0])
    assert notice_lines(load_asset(tex)) == []
    assert "the reference renders these materials opaque (textures it does not read per hit: clearcoat)" in \
        notice_lines(load_asset(coat))[0]


@pytest.mark.slow
@pytest.mark.parametrize("name", ["TransmissionTest", "TransmissionRoughnessTest"])
def test_shared_transmission_assets_render_with_transmission(render, name, monkeypatch):
    """Every transmissive material of the shared asset is rendered by the reference (its MASK ones
    too: tests/test_reference_transmission_alpha.py), and a low-spp path render under a real environment differs from the same render with
    the transmissive BSDFs left out (the opaque fallback) by more than :data:`ASSET_MIN_CHANGE`."""
    from pbrcheck.gltf import load_asset
    from pbrcheck.scene import asset_scene
    from pbrcheck.transmission_params import is_transmissive, reference_renders
    from reference import transmission

    path = SHARED / name / f"{name}.gltf"
    envs = sorted((SHARED.parents[1] / "envmaps").glob("*.hdr")) if (SHARED.parents[1] / "envmaps").is_dir() else []
    if not path.exists() or not envs:
        pytest.skip(f"{path} or ../shared/envmaps is absent (the real assets live in ../shared)")
    mats = [m for m in load_asset(path).materials if is_transmissive(m)]
    assert mats and all(reference_renders(m) for m in mats)
    sc = asset_scene(path, env=str(envs[0]), size=(48, 48))
    a = _rgb(render(sc, 4))
    monkeypatch.setattr(transmission, "gltf_shape_props", lambda *args, **kw: {})
    b = _rgb(render(sc, 4))
    assert np.isfinite(a).all()
    change = float(np.percentile(np.abs(a - b).max(axis=-1), 99))
    assert change > ASSET_MIN_CHANGE, change


def test_a_textured_transmissive_asset_has_its_own_cache_key_part(render, tmp_path, monkeypatch):
    """Scenes holding a textured transmissive material key their cached renders with
    TEXTURED_CODE_VERSION (they rendered opaque before); others keep their keys."""
    from reference import render as reference_render
    from reference.render import reference_cache_key
    from reference.render import TEXTURED_TRANSMISSION_CODE_VERSION as TEXTURED_CODE_VERSION
    from reference.render import transmission_cache_parts as cache_parts

    px = np.full((2, 2, 4), 255, np.uint8)
    tex = _scene(_sheet(tmp_path, "tex", [(px, None)], ext={"transmissionTexture": {"index": 0}}))
    clear = _scene(_sheet(tmp_path, "clear", []))
    assert cache_parts(tex) == {"textured_transmission_code": TEXTURED_CODE_VERSION} and cache_parts(clear) == {}
    def keys():
        return [reference_cache_key(s, spp=4, mode="path", seed=1, max_depth=8) for s in (tex, clear)]

    with_part = keys()
    monkeypatch.setattr(reference_render, "transmission_cache_parts", lambda scene: {})
    without = keys()
    assert with_part[0] != without[0] and with_part[1] == without[1]
