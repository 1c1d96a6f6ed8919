"""The lobes' parameters (pbrcheck/lobe_params.py, issue 36 item 1, data side): the five glTF PBR
extensions parsed from small assets built here (factors, defaults, textures with texCoord and
``KHR_texture_transform``, each malformed field refused naming its pointer), the scene-file fields
(validation, round trip through ``to_dict`` / ``dump_toml``), the export (export then load gives the
same parameters), the honesty contract naming them, ``check-scene`` listing them, the built-in lobe
scenes, and the neutral values giving today's images bit for bit."""

from __future__ import annotations

import json
import math
import tomllib

import numpy as np
import pytest

from pbrcheck import lobe_params as lp
from pbrcheck_cli import main
from pbrcheck.errors import AssetError, SceneError
from pbrcheck.export import export_scene, gltf_document
from pbrcheck.gltf import MODELLED_EXTENSIONS, SRGB_SLOTS, load_asset, texture_transform_matrix
from pbrcheck.gltf_features import used_images
from pbrcheck.scene import Material, dump_toml, load_scene, scene_from_dict
from pbrcheck.unmodelled import Unmodelled
from tests.gltf_build import QUAD_UV, quad_asset, quad_scene

CC, SH, SP, AN, IR = lp.CLEARCOAT, lp.SHEEN, lp.SPECULAR, lp.ANISOTROPY, lp.IRIDESCENCE
LOBES = (CC, SH, SP, AN, IR)
XF = {"KHR_texture_transform": {"offset": [0.25, 0.5], "rotation": 0.5, "scale": [2.0, 3.0], "texCoord": 1}}

#: Every field of the five extensions at a non-default value; textures 0..9, the odd ones on
#: TEXCOORD_1, texture 4 (sheenColor) with a KHR_texture_transform (which moves it to TEXCOORD_1).
FULL = {
    CC: {"clearcoatFactor": 0.5, "clearcoatTexture": {"index": 0}, "clearcoatRoughnessFactor": 0.25,
         "clearcoatRoughnessTexture": {"index": 1, "texCoord": 1},
         "clearcoatNormalTexture": {"index": 2, "scale": 0.75}},
    SH: {"sheenColorFactor": [0.1, 0.2, 0.3], "sheenColorTexture": {"index": 4, "extensions": XF},
         "sheenRoughnessFactor": 0.4, "sheenRoughnessTexture": {"index": 3, "texCoord": 1}},
    SP: {"specularFactor": 0.6, "specularTexture": {"index": 5, "texCoord": 1}, "specularColorFactor": [1.5, 0.5, 0.0],
         "specularColorTexture": {"index": 6}},
    AN: {"anisotropyStrength": 0.7, "anisotropyRotation": -4.0, "anisotropyTexture": {"index": 7, "texCoord": 1}},
    IR: {"iridescenceFactor": 0.8, "iridescenceTexture": {"index": 8}, "iridescenceIor": 1.8,
         "iridescenceThicknessMinimum": 500.0, "iridescenceThicknessMaximum": 200.0,   # min > max: allowed
         "iridescenceThicknessTexture": {"index": 9, "texCoord": 1}},
}


def _px(k: int) -> np.ndarray:
    return np.full((2, 2, 4), 20 * k + 10, np.uint8)


def _asset(tmp_path, ext: dict, n_images: int = 0, name: str = "a.gltf", **kw):
    mat = {"name": "m", "pbrMetallicRoughness": {"metallicFactor": 0.0}}
    if ext is not None:
        mat["extensions"] = ext
    return quad_asset(tmp_path / name, mat, [(_px(k), None) for k in range(n_images)], uv1=QUAD_UV, **kw)


def test_each_extension_parsed_with_its_factors_textures_texcoords_and_transform(tmp_path):
    a = load_asset(_asset(tmp_path, FULL, 11))
    m = a.materials[0]
    assert (m.clearcoat.factor, m.clearcoat.roughness) == (0.5, 0.25)
    assert m.sheen.color == (0.1, 0.2, 0.3) and m.sheen.roughness == 0.4
    assert m.khr_specular.factor == 0.6 and m.khr_specular.color == (1.5, 0.5, 0.0)
    assert (m.anisotropy.strength, m.anisotropy.rotation) == (0.7, -4.0)
    assert (m.iridescence.factor, m.iridescence.ior) == (0.8, 1.8)
    assert (m.iridescence.thickness_minimum, m.iridescence.thickness_maximum) == (500.0, 200.0)
    assert all(getattr(m, f).active for f in ("clearcoat", "sheen", "khr_specular", "anisotropy", "iridescence"))
    # every slot: its image, its UV set (odd textures on TEXCOORD_1), its pointer
    slots = {"clearcoat": 0, "clearcoatRoughness": 1, "clearcoatNormal": 2, "sheenRoughness": 3, "sheenColor": 4,
             "specular": 5, "specularColor": 6, "anisotropy": 7, "iridescence": 8, "iridescenceThickness": 9}
    tex = m.textures()
    assert {s: t.image for s, t in tex.items()} == slots
    assert {s: t.texcoord for s, t in tex.items()} == {s: k % 2 for s, k in slots.items()} | {"sheenColor": 1}
    assert tex["clearcoatNormal"].scale == 0.75 and tex["clearcoat"].scale == 1.0
    assert tex["sheenRoughness"].pointer == "/materials/0/extensions/KHR_materials_sheen/sheenRoughnessTexture"
    want = texture_transform_matrix((0.25, 0.5), 0.5, (2.0, 3.0)).reshape(-1)
    assert np.allclose(tex["sheenColor"].transform, want) and tex["clearcoat"].transform is None
    assert {s: lp.TEXTURE_CHANNELS[s] for s in ("clearcoat", "clearcoatRoughness", "sheenRoughness", "specular",
                                                "iridescence", "iridescenceThickness")} == {
        "clearcoat": "R", "clearcoatRoughness": "G", "sheenRoughness": "A", "specular": "A", "iridescence": "R",
        "iridescenceThickness": "G"}
    # only the images a lobe reads are decoded (image 10: no texture reads it)
    assert used_images(a.materials) == set(range(10))
    assert [im.decoded for im in a.images] == [True] * 10 + [False]
    # the colour slots are sRGB (check-scene's colour space), the data slots linear
    assert a.texture_slots()[4] == ["m:sheenColor"] and {"sheenColor", "specularColor"} <= set(SRGB_SLOTS)
    assert not {"sheenRoughness", "specular", "anisotropy", "clearcoat"} & set(SRGB_SLOTS)
    # a frozen part of the material
    with pytest.raises(AttributeError):
        m.clearcoat.factor = 1.0   # type: ignore[misc]


def test_defaults_of_empty_extensions_and_none_when_absent(tmp_path):
    m = load_asset(_asset(tmp_path, {e: {} for e in LOBES})).materials[0]
    assert m.clearcoat == lp.Clearcoat(0.0, None, 0.0, None, None)
    assert m.sheen == lp.Sheen((0.0, 0.0, 0.0), None, 0.0, None)
    assert m.khr_specular == lp.Specular(1.0, None, (1.0, 1.0, 1.0), None)
    assert m.anisotropy == lp.Anisotropy(0.0, 0.0, None)
    assert m.iridescence == lp.Iridescence(0.0, None, 1.3, 100.0, 400.0, None)
    assert not any(getattr(m, f).active for f in ("clearcoat", "sheen", "khr_specular", "anisotropy", "iridescence"))
    m0 = load_asset(_asset(tmp_path, None, name="plain.gltf")).materials[0]
    assert (m0.clearcoat, m0.sheen, m0.khr_specular, m0.anisotropy, m0.iridescence) == (None,) * 5
    assert m0.textures() == {}


BAD = [
    (CC, "clearcoatFactor", 1.5), (CC, "clearcoatFactor", "1"), (CC, "clearcoatRoughnessFactor", -0.1),
    (SH, "sheenColorFactor", [0.1, 0.2]), (SH, "sheenColorFactor", [0.1, 0.2, 1.1]), (SH, "sheenRoughnessFactor", 2),
    (SP, "specularFactor", -1), (SP, "specularColorFactor", [1, 1, -0.5]), (SP, "specularColorFactor", [1, True, 1]),
    (AN, "anisotropyStrength", 1.01), (AN, "anisotropyRotation", "x"), (IR, "iridescenceFactor", 3),
    (IR, "iridescenceIor", 0.9), (IR, "iridescenceThicknessMinimum", -1), (IR, "iridescenceThicknessMaximum", None),
]


@pytest.mark.parametrize("ext,key,value", BAD, ids=[f"{k}={v!r}" for _, k, v in BAD])
def test_each_malformed_field_refused_naming_its_pointer(tmp_path, ext, key, value):
    p = _asset(tmp_path, {ext: {key: value}})
    with pytest.raises(AssetError, match=f"/materials/0/extensions/{ext}/{key}: ") as e:
        load_asset(p)
    assert str(p) in str(e.value)


def test_malformed_extension_object_and_texture_refused(tmp_path):
    with pytest.raises(AssetError, match=f"/materials/0/extensions/{SH}: an object"):
        load_asset(_asset(tmp_path, {SH: [1]}, name="o.gltf"))
    with pytest.raises(AssetError, match=f"/materials/0/extensions/{AN}/anisotropyTexture/index: index 3 out of range"):
        load_asset(_asset(tmp_path, {AN: {"anisotropyTexture": {"index": 3}}}, 1, name="t.gltf"))
    with pytest.raises(AssetError, match=f"/materials/0/extensions/{CC}/clearcoatTexture: a textureInfo with an index"):
        load_asset(_asset(tmp_path, {CC: {"clearcoatTexture": {}}}, 1, name="i.gltf"))
    with pytest.raises(AssetError, match=f"/materials/0/extensions/{IR}/iridescenceTexture/texCoord: TEXCOORD_2"):
        load_asset(_asset(tmp_path, {IR: {"iridescenceTexture": {"index": 0, "texCoord": 2}}}, 1, name="c.gltf"))


BAD_TEXTURE = [({"index": "0"}, ""), ({"index": 0, "texCoord": "x"}, "/texCoord"),
               ({"index": 0, "extensions": {"KHR_texture_transform": {"rotation": "a"}}},
                "/extensions/KHR_texture_transform/rotation"),
               ({"index": 0, "extensions": {"KHR_texture_transform": {"offset": [1]}}},
                "/extensions/KHR_texture_transform/offset"),
               ({"index": 0, "extensions": {"KHR_texture_transform": {"texCoord": 1.5}}},
                "/extensions/KHR_texture_transform/texCoord")]


@pytest.mark.parametrize("info,where", BAD_TEXTURE, ids=[w or "index" for _, w in BAD_TEXTURE])
def test_malformed_texture_info_of_an_extension_refused_naming_its_pointer(tmp_path, info, where):
    with pytest.raises(AssetError, match=f"/materials/0/extensions/{SP}/specularColorTexture{where}: "):
        load_asset(_asset(tmp_path, {SP: {"specularColorTexture": info}}, 1))
    with pytest.raises(AssetError, match=f"/materials/0/extensions/{CC}/clearcoatNormalTexture/scale: a finite number"):
        load_asset(_asset(tmp_path, {CC: {"clearcoatNormalTexture": {"index": 0, "scale": "s"}}}, 1, name="n.gltf"))


def test_check_scene_lists_an_assets_lobes(tmp_path, capsys):
    p = _asset(tmp_path, {CC: {"clearcoatFactor": 0.5, "clearcoatTexture": {"index": 0}}, SP: {}}, 1)
    assert main(["check-scene", str(p)]) == 0
    out = capsys.readouterr().out
    assert "#       lobes: clearcoat (factor 0.5, roughness 0.0, clearcoat=R of image0/uv0); " \
           "specular (factor 1.0, color [1.0, 1.0, 1.0]; neutral)" in out
    assert "m:clearcoat" in out


# ---- scene files ---------------------------------------------------------------------------------

LOBE_FIELDS = {"clearcoat": 0.5, "clearcoat_roughness": 0.25, "sheen_color": (0.1, 0.2, 0.3), "sheen_roughness": 0.4,
               "specular_factor": 0.6, "specular_color": (1.5, 0.5, 0.0), "anisotropy_strength": 0.7,
               "anisotropy_rotation": -1.25, "iridescence": 0.8, "iridescence_ior": 1.8, "iridescence_thickness": 250.0}


def _scene(materials: list[dict]) -> dict:
    return {"environment": {"type": "constant"}, "camera": {"width": 16, "height": 16},
            "objects": [{"type": "sphere", "center": [2.0 * k, 0.0, 0.0], "radius": 0.5, "material": m}
                        for k, m in enumerate(materials)]}


def _tomlable(d):
    return {k: list(v) if isinstance(v, tuple) else v for k, v in d.items()}


def assert_scene_fields_round_trip(fields: dict) -> None:
    """Scene-file material ``fields`` (set on one sphere, the other plain) load as given, write to TOML
    and load back the same; neutral values are left out of the dict (hashes unchanged); set, they
    enter the content (not the plain scene's cache entry). Shared with the transmission fields."""
    s = scene_from_dict(_scene([_tomlable(fields), {}]))
    m = s.objects[0].material
    assert {k: getattr(m, k) for k in fields} == fields
    assert s.objects[1].material == Material()
    d = s.to_dict()
    assert {k: d["objects"][0]["material"][k] for k in fields} == _tomlable(fields)
    assert not set(fields) & set(d["objects"][1]["material"])   # neutral: left out (hashes unchanged)
    again = scene_from_dict(tomllib.loads(dump_toml(d)))
    assert again.objects == s.objects and again.content_dict() == s.content_dict()
    assert scene_from_dict(_scene([{}, {}])).content_dict() != s.content_dict()


def test_scene_fields_loaded_and_round_trip_through_dump_toml():
    assert_scene_fields_round_trip(LOBE_FIELDS)


def test_scene_spheres_text_unchanged_by_the_new_fields():
    d = load_scene("spheres").to_dict()
    assert set(d["objects"][0]["material"]) == {"base_color", "metallic", "roughness", "specular"}


BAD_SCENE = [("clearcoat", 1.5), ("clearcoat_roughness", -0.5), ("sheen_color", [0.5, 1.5, 0.0]),
             ("sheen_roughness", "a"), ("specular_factor", 2.0), ("specular_color", [1.0, -1.0, 1.0]),
             ("anisotropy_strength", -0.1), ("anisotropy_rotation", math.inf), ("iridescence", 1.1),
             ("iridescence_ior", 0.5), ("iridescence_thickness", -10.0)]


@pytest.mark.parametrize("key,value", BAD_SCENE, ids=[k for k, _ in BAD_SCENE])
def test_scene_field_out_of_range_refused_naming_it(key, value):
    with pytest.raises(SceneError, match=rf"objects\[0\]\.material\.{key}"):
        scene_from_dict(_scene([{key: value}]))


def test_a_grid_material_takes_the_lobe_fields_for_every_sphere():
    s = scene_from_dict({"environment": {"type": "constant"}, "objects": [
        {"type": "sphere_grid", "rows": 2, "columns": 2, "material": {"clearcoat": 1.0}}]})
    assert [o.material.clearcoat for o in s.objects] == [1.0] * 4


# ---- export and the honesty contract -----------------------------------------------------------------

def _one_lobe_each() -> list[dict]:
    return [{"clearcoat": 0.5, "clearcoat_roughness": 0.25}, {"sheen_color": [0.1, 0.2, 0.3], "sheen_roughness": 0.4},
            {"specular_factor": 0.6, "specular_color": [1.5, 0.5, 0.0]},
            {"anisotropy_strength": 0.7, "anisotropy_rotation": -1.25},
            {"iridescence": 0.8, "iridescence_ior": 1.8, "iridescence_thickness": 250.0}, {}]


@pytest.mark.usefixtures("lobes_unmodelled")  # the contract's mechanism on unmodelled lobes
def test_export_then_load_gives_the_same_parameters(tmp_path):
    s = scene_from_dict(_scene(_one_lobe_each()))
    ex = export_scene(s, tmp_path / "kept", keep_unmodelled=True)
    doc = json.loads((tmp_path / "kept" / "scene.gltf").read_text())
    assert set(LOBES) | {"KHR_materials_ior"} >= set(doc["extensionsUsed"]) >= set(LOBES)
    a = load_asset(tmp_path / "kept" / "scene.gltf")
    by_name = {m.name: m for m in a.materials}
    for o in s.objects:
        m = by_name[f"material_{o.id}"]
        back = lp.scene_fields_of({f: getattr(m, f) for f, _ in lp.LOBE_EXTENSIONS.values()})
        assert back == {k: getattr(o.material, k) for k in lp.SCENE_DEFAULTS}, o.id
    assert by_name["material_5"].clearcoat is None and by_name["material_5"].iridescence is None
    assert ex.kept_unmodelled and [f for f, _ in ex.unmodelled] == list(LOBES)
    # not kept: removed from what the engines get, and named
    ex2 = export_scene(s, tmp_path / "stripped")
    doc2 = json.loads((tmp_path / "stripped" / "scene.gltf").read_text())
    assert not set(LOBES) & set(doc2.get("extensionsUsed", [])) and not any("extensions" in m for m in doc2["materials"])
    assert ex2.unmodelled == [(e, (f"material_{k}",)) for k, e in enumerate(LOBES)]


@pytest.mark.usefixtures("lobes_unmodelled")  # the contract's mechanism on unmodelled lobes
def test_honesty_names_an_analytic_objects_lobes():
    s = scene_from_dict(_scene(_one_lobe_each() + [{"clearcoat": 1.0, "sheen_color": [1.0, 1.0, 1.0]}]), file="lobes.toml")
    assert s.unmodelled == (
        Unmodelled(CC, ("sphere0", "sphere6"), (0, 6), "lobes.toml"), Unmodelled(SH, ("sphere1", "sphere6"), (1, 6), "lobes.toml"),
        Unmodelled(SP, ("sphere2",), (2,), "lobes.toml"), Unmodelled(AN, ("sphere3",), (3,), "lobes.toml"),
        Unmodelled(IR, ("sphere4",), (4,), "lobes.toml"))
    assert scene_from_dict(_scene([{}])).unmodelled == ()


@pytest.mark.parametrize("name", ["clearcoat", "sheen", "specular", "anisotropy", "iridescence"])
def test_builtin_lobe_scenes_load_export_and_are_modelled(name):
    s = load_scene(name)
    ext = f"KHR_materials_{name}"
    assert len(s.objects) == 25 and all(o.type == "sphere" for o in s.objects)
    assert s.environment.type == "sky"
    assert s.unmodelled == ()                           # both renderers render the lobe (issue 36)
    doc = gltf_document(s)[0]                           # and the engines get it
    assert ext in doc["extensionsUsed"] and sum(ext in m.get("extensions", {}) for m in doc["materials"]) >= 24


def test_scenes_lists_and_check_scene_shows_the_lobe_scenes(capsys):
    assert main(["scenes"]) == 0
    out = capsys.readouterr().out
    assert all(f"\n{n} " in "\n" + out for n in ("clearcoat", "sheen", "specular", "anisotropy", "iridescence"))
    assert main(["check-scene", "clearcoat"]) == 0
    out = capsys.readouterr().out
    assert "# object 24 clearcoat[r4,c4]: lobes clearcoat 1.0, clearcoat_roughness 1.0 (KHR_materials_clearcoat" in out
    assert "clearcoat_roughness = 0.25" in out


# ---- neutral values: today's images, bit for bit ----------------------------------------------------

NEUTRAL = {CC: {"clearcoatFactor": 0.0, "clearcoatRoughnessFactor": 0.0, "clearcoatTexture": {"index": 0}},
           SH: {"sheenColorFactor": [0, 0, 0], "sheenRoughnessTexture": {"index": 0, "texCoord": 1}},
           SP: {"specularFactor": 1.0, "specularColorFactor": [1, 1, 1]}, AN: {"anisotropyStrength": 0.0},
           IR: {"iridescenceFactor": 0.0}}


def _rgb(img):
    return np.stack([img.channels[c] for c in "RGB"], -1)


@pytest.mark.slow
def test_neutral_extensions_render_bit_identical_in_both_renderers(tmp_path):
    from realtime.render import render_realtime
    from reference.render import render_reference

    images = {}
    for label, ext in [("without", None)] + [(e, {e: NEUTRAL[e]}) for e in LOBES]:
        d = tmp_path / label
        d.mkdir()
        a = _asset(d, ext, 1)   # one image: read by the neutral clearcoat / sheen textures, else unused
        sc = load_scene(quad_scene(d, a, size=(8, 8), env="[0.3, 0.5, 0.7]"))
        images[label] = (_rgb(render_realtime(sc, "default", progress=False)),
                         _rgb(render_reference(sc, spp=4, use_cache=False, progress=False)))
    assert not load_asset(tmp_path / "without" / "a.gltf").images[0].decoded
    assert load_asset(tmp_path / CC / "a.gltf").images[0].decoded
    base = images.pop("without")
    assert base[0].max() > 0 and base[1].max() > 0
    for label, (rt, ref) in images.items():
        assert np.array_equal(rt, base[0]) and np.array_equal(ref, base[1]), label


@pytest.mark.usefixtures("lobes_unmodelled")  # the contract's mechanism on unmodelled lobes
def test_stderr_names_a_scene_files_lobes_once(tmp_path, capsys):
    toml = tmp_path / "coat.toml"
    toml.write_text(dump_toml(scene_from_dict(_scene([{"clearcoat": 1.0}, {}])).to_dict()))
    assert main(["check-scene", str(toml)]) == 0
    err = capsys.readouterr().err
    assert err.count("coat.toml: not modelled: KHR_materials_clearcoat (objects: sphere0)") == 1
    assert main(["check-scene", "spheres"]) == 0 and "not modelled" not in capsys.readouterr().err
