"""The honesty contract's transmission list is what both renderers render (issue 37, the flip).

The core (``pbrcheck.transmission_params.MODELLED_TRANSMISSION_EXTENSIONS``) cannot import the
renderers, so this test holds it to the intersection of the reference's and the real-time renderer's
own sets: an extension one renderer drops must leave the list (and be named as unmodelled again). A
transmissive glTF material the reference's path mode renders opaque stays named, for that material
alone, its notice saying why; the engines' export keeps the modelled extensions."""
from __future__ import annotations

import json

import numpy as np
import pytest

from pbrcheck import transmission_params as tp
from pbrcheck.export import export_scene
from pbrcheck.gltf import MODELLED_EXTENSIONS, load_asset
from pbrcheck.scene import load_scene, scene_from_dict
from pbrcheck.unmodelled import REFERENCE_REFUSED, Unmodelled, notice_lines
from realtime.transmission import REALTIME_TRANSMISSION_EXTENSIONS
from tests.gltf_build import quad_asset

EXTS = tuple(tp.TRANSMISSION_EXTENSIONS)


def test_modelled_transmission_is_what_both_renderers_render():
    from reference.variant import ensure_variant

    ensure_variant()   # reference.transmission defines Mitsuba BSDF classes at import
    from reference.transmission import REFERENCE_TRANSMISSION_EXTENSIONS

    assert set(tp.MODELLED_TRANSMISSION_EXTENSIONS) == set(REFERENCE_TRANSMISSION_EXTENSIONS) & set(
        REALTIME_TRANSMISSION_EXTENSIONS)
    assert set(tp.MODELLED_TRANSMISSION_EXTENSIONS) == set(EXTS)   # all four, today
    assert set(tp.MODELLED_TRANSMISSION_EXTENSIONS) <= set(MODELLED_EXTENSIONS)


def test_the_built_in_glass_scene_is_judged_and_exported_with_its_transmission(tmp_path):
    scene = load_scene("glass")
    assert any(tp.scene_features(o.material) for o in scene.objects if hasattr(o, "material"))
    assert scene.unmodelled == ()
    ex = export_scene(scene.with_camera(width=8, height=6), tmp_path / "e")
    assert ex.unmodelled == [] and ex.kept_unmodelled is False
    doc = json.loads((tmp_path / "e" / "scene.gltf").read_text())
    used = {e for m in doc["materials"] for e in m.get("extensions", {})}
    assert {tp.TRANSMISSION, tp.VOLUME} <= used and {tp.TRANSMISSION, tp.VOLUME} <= set(doc["extensionsUsed"])


def _quad(tmp_path, name, **material):
    mat = {"name": name, "pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 0.0},
           "extensions": {tp.TRANSMISSION: {"transmissionFactor": 1.0}, **material.pop("extensions", {})}, **material}
    return quad_asset(tmp_path / f"{name}.gltf", mat, [(np.full((2, 2, 4), 255, np.uint8), None)])


def test_a_material_the_reference_renders_opaque_stays_named_for_that_material_alone(tmp_path):
    """An OPAQUE glass quad is modelled (no record, no notice); one the reference's path mode renders
    opaque (here: a clearcoat texture it does not read per hit, and unlit) keeps its transmission named,
    the notice giving the reason."""
    clear = load_asset(_quad(tmp_path, "clear"))
    assert tp.reference_renders(clear.materials[0]) and clear.unmodelled == () and notice_lines(clear) == []
    coat = load_asset(_quad(tmp_path, "coat", extensions={
        "KHR_materials_clearcoat": {"clearcoatFactor": 1.0, "clearcoatTexture": {"index": 0}}}))
    why = "textures it does not read per hit: clearcoat"
    assert tp.reference_refusal(coat.materials[0]) == why
    assert coat.unmodelled == (Unmodelled(tp.TRANSMISSION, ("coat",), (0,)),)
    assert notice_lines(coat) == [f"pbrcheck: coat.gltf: not modelled: {tp.TRANSMISSION} (materials: coat): "
                                  f"{REFERENCE_REFUSED.format(why=why)}; a gate check of it is not judged"]
    unlit = load_asset(_quad(tmp_path, "unlit", extensions={"KHR_materials_unlit": {}}))
    assert tp.reference_refusal(unlit.materials[0]) == "KHR_materials_unlit"
    assert [u.feature for u in unlit.unmodelled] == [tp.TRANSMISSION]
    assert tp.reference_refusal(clear.materials[0]) == ""


@pytest.mark.usefixtures("transmission_unmodelled")
def test_the_fixture_restores_the_contract_with_transmission_unmodelled(tmp_path):
    """The mechanism's tests run on the fixture: every transmission extension named again, the glass
    scene's included, and the export strips them."""
    import pbrcheck.gltf as gltf

    assert tp.TRANSMISSION not in gltf.MODELLED_EXTENSIONS
    assert [u.feature for u in load_scene("glass").unmodelled] == [tp.TRANSMISSION, tp.VOLUME]
    assert [u.feature for u in load_asset(_quad(tmp_path, "clear")).unmodelled] == [tp.TRANSMISSION]
    s = scene_from_dict({"camera": {"origin": [0, 0, 4], "target": [0, 0, 0], "width": 8, "height": 6},
                         "environment": {"type": "constant"},
                         "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1,
                                      "material": {"transmission": 1.0}}]})
    ex = export_scene(s, tmp_path / "e")
    assert [f for f, _ in ex.unmodelled] == [tp.TRANSMISSION]


def test_lobes_the_transmissive_bsdf_leaves_out_are_named_for_those_materials(tmp_path):
    """A constant clearcoat / sheen / KHR_materials_specular / anisotropy factor on a material the
    reference renders transmissive is not in its transmissive BSDF: recorded (for that material alone,
    the notice saying so), never dropped silently; the iridescent film, which it renders, is not; a
    transmissive material the reference renders opaque keeps the lobes (its transmission is named)."""
    import io

    from pbrcheck import unmodelled as um
    from pbrcheck.lobe_params import ANISOTROPY, CLEARCOAT, IRIDESCENCE, SHEEN, SPECULAR

    lobes = {CLEARCOAT: {"clearcoatFactor": 0.8}, SHEEN: {"sheenColorFactor": [0.5, 0.5, 0.5]},
             SPECULAR: {"specularFactor": 0.5}, ANISOTROPY: {"anisotropyStrength": 0.6},
             IRIDESCENCE: {"iridescenceFactor": 1.0}}
    a = load_asset(_quad(tmp_path, "coated", extensions=dict(lobes)))
    assert tp.lobes_left_out(a.materials[0]) == (CLEARCOAT, SHEEN, SPECULAR, ANISOTROPY)
    assert a.unmodelled == tuple(Unmodelled(e, ("coated",), (0,)) for e in (CLEARCOAT, SHEEN, SPECULAR, ANISOTROPY))
    assert notice_lines(a)[0] == (f"pbrcheck: coated.gltf: not modelled: {CLEARCOAT} (materials: coated): "
                                  f"{um.TRANSMISSIVE_LOBE}; a gate check of it is not judged")
    film = load_asset(_quad(tmp_path, "film", extensions={IRIDESCENCE: {"iridescenceFactor": 1.0}}))
    assert film.unmodelled == () and tp.lobes_left_out(film.materials[0]) == ()
    neutral = load_asset(_quad(tmp_path, "neutral", extensions={CLEARCOAT: {"clearcoatFactor": 0.0}}))
    assert neutral.unmodelled == ()   # a disabled layer is not a lobe
    opaque = load_asset(_quad(tmp_path, "unlitcoat", extensions={"KHR_materials_unlit": {}, CLEARCOAT: {"clearcoatFactor": 1.0}}))
    assert [u.feature for u in opaque.unmodelled] == [tp.TRANSMISSION]

    s = scene_from_dict({"camera": {"origin": [0, 0, 4], "target": [0, 0, 0], "width": 8, "height": 6},
                         "environment": {"type": "constant"},
                         "objects": [{"type": "sphere", "center": [-1, 0, 0], "radius": 0.5, "name": "glass",
                                      "material": {"transmission": 1.0, "clearcoat": 0.5, "iridescence": 1.0}},
                                     {"type": "sphere", "center": [1, 0, 0], "radius": 0.5, "name": "paint",
                                      "material": {"clearcoat": 0.5}}]}, file="coated.toml")
    assert [(u.feature, u.materials) for u in s.unmodelled] == [(CLEARCOAT, ("glass",))]
    out = io.StringIO()
    um.start_notices(out)
    try:
        um.announce_scene(s)
    finally:
        um.stop_notices()
    assert out.getvalue() == (f"pbrcheck: coated.toml: not modelled: {CLEARCOAT} (objects: glass): "
                              f"{um.TRANSMISSIVE_LOBE}; a gate check of it is not judged\n")
