"""MASK / BLEND transmissive glTF materials in the reference's ``path`` mode (issue 37): alpha is
coverage ([Trans] "Blend Mode": whether the surface is there; transmission applies to the surface
that is), so a texel whose alpha (``baseColorFactor.a`` x the base colour texture's A) is below
``alphaCutoff`` lets the ray through unchanged (a null interaction: no refraction, no tint) and the
others are the transmissive BSDF; BLEND is there with probability alpha. Known answers: a tinted
IOR-1 sheet whose alpha texture cuts its left half shows the environment behind there (the sheet
moved out of view, to float32 noise) and the OPAQUE sheet's tinted transmission on the right; a
MASK material whose every alpha is above the cutoff is the OPAQUE render bit for bit; a BLEND sheet
of alpha 0.25 mixes the two images by 0.25 (within the noise); a negative cutoff is a typed error.
Slow: TransmissionTest's MASK materials (its only ones among the shared assets) before / after."""

from __future__ import annotations

import numpy as np
import pytest

from tests.gltf_build import quad_asset

# the path render at seed 1, the 12 x 12 camera at the sheet, the RGB stack: the textured tests'
from tests.test_reference_transmission_textured import NEAREST, PASS_ATOL, PATH, SHARED, _rgb, _scene, render  # noqa: F401

TINT = [1.0, 0.5, 0.25]
#: BLEND's estimated coverage (over 12 x 12 pixels x 64 spp = 9216 Bernoulli draws: std
#: sqrt(0.25 x 0.75 / 9216) = 0.0045) within this of the material's alpha 0.25 (4.4 sigma).
BLEND_TOL = 0.02
#: TransmissionTest's MASK pixels must change by more than this (99th percentile of max_rgb |after -
#: before| over the pixels of its MASK primitives) at 48 x 48, 4 spp.
ASSET_MIN_CHANGE = 1e-2


def _sheet(tmp_path, name, *, mode="OPAQUE", alpha=1.0, images=(), pbr=None, ior=1.0, roughness=0.0, cutoff=None):
    mat = {"name": name, "alphaMode": mode,
           "pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": roughness,
                                    "baseColorFactor": TINT + [alpha], **(pbr or {})},
           "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0},
                          "KHR_materials_ior": {"ior": ior}}}
    if cutoff is not None:
        mat["alphaCutoff"] = cutoff
    return quad_asset(tmp_path / f"{name}.gltf", mat, list(images), scale=3.0)


def _alpha_texture(left: int, right: int):
    px = np.full((4, 4, 4), 255, np.uint8)
    px[:, :2, 3], px[:, 2:, 3] = left, right
    return [(px, NEAREST)]


def test_an_alpha_texture_cuts_half_of_a_transmissive_sheet(render, tmp_path):
    """MASK, alpha 0 on the left half, 1 on the right (NEAREST): the left half of the image is the
    environment behind (the sheet moved out of view), the right half the OPAQUE sheet's tinted
    transmission (the environment times the base colour), which differs from the environment."""
    cut = _sheet(tmp_path, "cut", mode="MASK", images=_alpha_texture(0, 255),
                 pbr={"baseColorTexture": {"index": 0}})
    plain = _sheet(tmp_path, "plain", images=_alpha_texture(0, 255), pbr={"baseColorTexture": {"index": 0}})
    seen, away, whole = _rgb(render(_scene(cut))), _rgb(render(_scene(cut, (50.0, 0.0, 0.0)))), _rgb(render(_scene(plain)))
    np.testing.assert_allclose(seen[:, :6], away[:, :6], atol=PASS_ATOL)
    np.testing.assert_allclose(seen[:, 6:], whole[:, 6:], atol=PASS_ATOL)
    np.testing.assert_allclose(whole, away * np.asarray(TINT), atol=PASS_ATOL, rtol=1e-5)
    assert np.abs(whole - away).max(axis=-1).min() > 0.05


@pytest.mark.parametrize("textured", [False, True])
def test_mask_above_the_cutoff_everywhere_is_the_plain_render_bit_for_bit(render, tmp_path, textured):
    """A rough IOR-1.5 sheet (a noisy image) with MASK whose every alpha is above the cutoff (the
    factor 0.9; or a texture of A = 200 / 255) is the OPAQUE sheet's render bit for bit; a cutoff
    above the alpha (0.95) cuts the whole sheet: the environment behind."""
    kw = dict(ior=1.5, roughness=0.4)
    if textured:
        px = np.full((2, 2, 4), 255, np.uint8)
        px[..., 3] = 200
        kw.update(images=[(px, None)], pbr={"baseColorTexture": {"index": 0}})
    else:
        kw.update(alpha=0.9)
    mask = render(_scene(_sheet(tmp_path, "mask", mode="MASK", **kw)))
    plain = render(_scene(_sheet(tmp_path, "plain", **kw)))
    np.testing.assert_array_equal(_rgb(mask), _rgb(plain))
    gone = _rgb(render(_scene(_sheet(tmp_path, "gone", mode="MASK", cutoff=0.95, **kw))))
    away = _rgb(render(_scene(_sheet(tmp_path, "gone", mode="MASK", cutoff=0.95, **kw), (50.0, 0.0, 0.0))))
    np.testing.assert_allclose(gone, away, atol=PASS_ATOL)
    assert np.abs(_rgb(plain) - away).max() > 0.05


def test_blend_mixes_the_surface_and_what_lies_behind_by_alpha(render, tmp_path):
    """BLEND of alpha 0.25 on the tinted IOR-1 sheet: each pixel is the OPAQUE sheet's with
    probability 0.25, the environment behind otherwise (glTF's over operator, in expectation); the
    coverage estimated from the blue channel (tint 0.25) is 0.25 within :data:`BLEND_TOL`."""
    blend = _sheet(tmp_path, "blend", mode="BLEND", alpha=0.25)
    seen = _rgb(render(_scene(blend), 64))
    away = _rgb(render(_scene(blend, (50.0, 0.0, 0.0)), 64))
    whole = _rgb(render(_scene(_sheet(tmp_path, "whole")), 64))
    p = float(((seen - away)[..., 2]).sum() / ((whole - away)[..., 2]).sum())
    assert abs(p - 0.25) < BLEND_TOL, p
    assert np.abs(whole - away)[..., 2].min() > 0.05


def test_the_null_component_only_where_coverage_can_fall_below_one(render, tmp_path):
    """gltf_shape_props: a texture whose least alpha is at the cutoff itself keeps the per-lane cut
    (a Null component: bilinear rounding may fall under it); one above it, OPAQUE and BLEND of alpha
    1 do not (the OPAQUE material)."""
    import mitsuba as mi

    from pbrcheck.gltf import load_asset
    from pbrcheck.scene import BRDFModel
    from reference.textured import texture_dict
    from reference.transmission import gltf_shape_props

    def has_null(path):
        a = load_asset(path)
        bsdf = gltf_shape_props(a.materials[0], BRDFModel(), a, core=lambda: {"type": "pbr_textured"}, cache={},
                                texture=texture_dict)["bsdf"]
        return mi.has_flag(bsdf.flags(), mi.BSDFFlags.Null)

    def tex(a):
        px = np.full((2, 2, 4), 255, np.uint8)
        px[0, 0, 3] = a
        return dict(images=[(px, None)], pbr={"baseColorTexture": {"index": 0}})

    assert has_null(_sheet(tmp_path, "at", mode="MASK", cutoff=128 / 255, **tex(128)))
    assert not has_null(_sheet(tmp_path, "above", mode="MASK", cutoff=127 / 255, **tex(128)))
    assert not has_null(_sheet(tmp_path, "blend1", mode="BLEND"))
    assert has_null(_sheet(tmp_path, "blend", mode="BLEND", alpha=0.999))
    assert not has_null(_sheet(tmp_path, "opaque", alpha=0.0))


def test_a_negative_cutoff_is_a_typed_error_naming_the_field(render, tmp_path):
    from pbrcheck.errors import AssetError
    from reference.render import render_uncached

    with pytest.raises(AssetError, match=r"/materials/0/alphaCutoff.*found -0\.5"):
        render_uncached(_scene(_sheet(tmp_path, "neg", mode="MASK", cutoff=-0.5)), spp=2, **PATH)


def test_a_masked_transmissive_asset_has_its_own_cache_key_part(tmp_path):
    """Scenes holding a MASK / BLEND transmissive material key their cached renders with
    ALPHA_TRANSMISSION_CODE_VERSION (they rendered opaque before); an OPAQUE one keeps its key."""
    from reference.render import ALPHA_TRANSMISSION_CODE_VERSION, transmission_cache_parts

    assert transmission_cache_parts(_scene(_sheet(tmp_path, "m", mode="MASK", alpha=0.2))) == {
        "alpha_transmission_code": ALPHA_TRANSMISSION_CODE_VERSION}
    assert transmission_cache_parts(_scene(_sheet(tmp_path, "o"))) == {}


@pytest.mark.slow
def test_transmission_test_mask_materials_render_cut_and_transmissive(render, monkeypatch):
    """TransmissionTest (the only shared asset with MASK transmissive materials: BlueTransWithMask x3,
    GreenMask x3) at 48 x 48, 4 spp under a real environment: every transmissive material is rendered
    now, and the image differs from the former one (MASK transmissive materials left to
    ``pbr_textured``: opaque, cut) on the MASK primitives' pixels by more than :data:`ASSET_MIN_CHANGE`."""
    from clients.run import object_ids
    from pbrcheck.gltf import load_asset
    from pbrcheck.scene import asset_scene
    from pbrcheck.transmission_params import is_transmissive, reference_renders
    from reference import transmission

    path = SHARED / "TransmissionTest" / "TransmissionTest.gltf"
    envs = sorted((SHARED.parents[1] / "envmaps").glob("*.hdr")) if (SHARED.parents[1] / "envmaps").is_dir() else []
    if not path.exists() or not envs:
        pytest.skip(f"{path} or ../shared/envmaps is absent (the real assets live in ../shared)")
    asset = load_asset(path)
    masked = [m for m in asset.materials if is_transmissive(m) and m.alpha_mode != "OPAQUE"]
    assert len(masked) == 6 and all(reference_renders(m) for m in masked)
    sc = asset_scene(path, env=str(envs[0]), size=(48, 48))
    after = _rgb(render(sc, 4))
    props = transmission.gltf_shape_props
    monkeypatch.setattr(transmission, "gltf_shape_props",
                        lambda m, *a, **kw: {} if m.alpha_mode != "OPAQUE" else props(m, *a, **kw))
    before = _rgb(render(sc, 4))
    ids = object_ids(sc)
    on_mask = np.isin(ids, [o.id for o in sc.objects if getattr(o, "gltf_material", -1) >= 0
                            and asset.material(o.gltf_material).alpha_mode != "OPAQUE"])
    assert np.isfinite(after).all() and on_mask.sum() > 20
    change = float(np.percentile(np.abs(after - before).max(axis=-1)[on_mask], 99))
    assert change > ASSET_MIN_CHANGE, change
