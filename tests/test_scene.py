"""Scene model: built-ins load, validation names file + field + expected + found, CLI exit codes."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from pbrcheck_cli import main
from pbrcheck.errors import SceneError
from pbrcheck.environment import scene_hash
from pbrcheck.scene import builtin_scene_names, dump_toml, load_scene, plane_frame, scene_from_dict
import tomllib

BUILTINS = ("spheres", "furnace", "grazing", "mirror", "sun", "hotspot")

MINIMAL = {
    "environment": {"type": "constant", "radiance": [1.0, 1.0, 1.0]},
    "objects": [{"type": "sphere", "center": [0.0, 0.0, 0.0], "radius": 1.0}],
}


def with_(base: dict, path: str, value):
    """Copy of ``base`` with the dotted ``path`` set (``objects.0.radius``)."""
    import copy

    d = copy.deepcopy(base)
    keys = path.split(".")
    cur = d
    for k in keys[:-1]:
        cur = cur[int(k)] if k.isdigit() else cur.setdefault(k, {})
    last = keys[-1]
    if value is _DELETE:
        del cur[last]
    else:
        cur[last] = value
    return d


_DELETE = object()


def test_builtins_exist_and_load():
    assert set(BUILTINS) <= set(builtin_scene_names())
    for name in BUILTINS:
        s = load_scene(name)
        assert s.description and "\n" not in s.description
        assert s.objects


def test_sphere_grid_layout_metallic_rows_roughness_columns():
    s = load_scene("spheres")
    g = s.grids[0]
    rows, cols = g["rows"], g["columns"]
    assert len(s.objects) == rows * cols
    # ids in scene order; bottom row first, left to right
    assert [o.id for o in s.objects] == list(range(rows * cols))
    first, last = s.objects[0], s.objects[-1]
    assert first.material.metallic == 0.0 and first.material.roughness == 0.0
    assert last.material.metallic == 1.0 and last.material.roughness == 1.0
    assert first.center[0] < last.center[0] and first.center[1] < last.center[1]
    # roughness increases left to right within a row; metallic bottom to top
    row0 = s.objects[:cols]
    assert all(a.material.roughness < b.material.roughness for a, b in zip(row0, row0[1:]))
    assert all(a.center[0] < b.center[0] for a, b in zip(row0, row0[1:]))


def test_defaults_filled():
    s = scene_from_dict(MINIMAL)
    assert s.camera.fov == 40.0 and (s.camera.width, s.camera.height) == (256, 256)
    assert (s.brdf.ndf, s.brdf.geometry, s.brdf.fresnel) == ("ggx", "smith_ggx_correlated", "schlick")
    m = s.objects[0].material
    assert (m.metallic, m.roughness, m.specular) == (0.0, 0.5, 0.04)
    assert m.alpha == 0.25


@pytest.mark.parametrize("path,value,field,fragment", [
    ("objects.0.material.roughness", 1.5, "objects[0].material.roughness", "<= 1"),
    ("objects.0.material.metallic", -0.1, "objects[0].material.metallic", ">= 0"),
    ("objects.0.radius", "big", "objects[0].radius", "a number"),
    ("objects.0.colour", 1, "objects[0].colour", "unknown key"),
    ("environment.radiance", [1.0, -1.0, 1.0], "environment.radiance", "non-negative"),
    ("environment.type", "hdri", "environment.type", "constant | file | sky | none"),
    ("brdf.ndf", "phong", "brdf.ndf", "ggx | beckmann | blinn_phong"),
    ("brdf.geometry", "smith", "brdf.geometry", "smith_ggx_correlated"),
    ("camera.up", [0.0, 0.0, -1.0], "camera.up", "not parallel"),
    ("camera.up", [0.0, 0.0, 0.0], "camera.up", "non-zero"),
    ("camera.width", 0, "camera.width", ">= 1"),
    ("camera.fov", True, "camera.fov", "a number"),
    ("objects.0.type", "cube", "objects[0].type", "sphere | plane | sphere_grid"),
    ("lights", [{"type": "point", "position": [0, 0, 0], "intensity": [1, 1]}], "lights[0].intensity", "3 numbers"),
    ("environment.sun_direction", [0.0, 0.0, 0.0], "environment", "unknown key"),  # not a constant env key
])
def test_validation_names_field_expected_found(path, value, field, fragment):
    with pytest.raises(SceneError) as ei:
        scene_from_dict(with_(MINIMAL, path, value), file="x.toml")
    msg = str(ei.value)
    assert msg.startswith("x.toml: ") and field in msg and fragment in msg, msg
    assert "\n" not in msg


def test_missing_environment_and_objects():
    with pytest.raises(SceneError, match="environment"):
        scene_from_dict(with_(MINIMAL, "environment", _DELETE))
    with pytest.raises(SceneError, match="objects"):
        scene_from_dict(with_(MINIMAL, "objects", []))


def test_missing_environment_file(tmp_path):
    p = tmp_path / "s.toml"
    p.write_text('[environment]\ntype = "file"\npath = "nope.hdr"\n[[objects]]\ntype = "sphere"\n')
    with pytest.raises(SceneError) as ei:
        load_scene(p)
    assert str(p) in str(ei.value) and "environment.path" in str(ei.value) and "nope.hdr" in str(ei.value)


def test_invalid_toml_and_unknown_scene(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text("name = [\n")
    with pytest.raises(SceneError, match="invalid TOML"):
        load_scene(p)
    with pytest.raises(SceneError, match="not a built-in scene"):
        load_scene("no_such_scene")


def test_resolved_toml_round_trips():
    s = load_scene("grazing")
    text = dump_toml(s.to_dict())
    data = tomllib.loads(text)
    # the resolved form is itself a valid scene (sphere grids already expanded as spheres)
    s2 = scene_from_dict(data)
    assert s2.to_dict() == s.to_dict() | {"objects": s2.to_dict()["objects"]}
    assert len(s2.objects) == len(s.objects)


def test_scene_hash_ignores_names_but_not_content():
    a = scene_from_dict(MINIMAL | {"name": "a", "description": "x"})
    b = scene_from_dict(MINIMAL | {"name": "b", "description": "y"})
    c = scene_from_dict(with_(MINIMAL, "objects.0.material.roughness", 0.51))
    d = scene_from_dict(with_(MINIMAL, "environment.radiance", [1.0, 1.0, 1.01]))
    assert scene_hash(a) == scene_hash(b)
    assert scene_hash(a) != scene_hash(c)
    assert scene_hash(a) != scene_hash(d)


def test_plane_frame_orthonormal_right_handed():
    import numpy as np

    for n in [(0, 1, 0), (1, 0, 0), (0, 0, -1), (0.3, -0.2, 0.9)]:
        t, b, nn = (np.array(v) for v in plane_frame(n))
        m = np.stack([t, b, nn])
        assert np.allclose(m @ m.T, np.eye(3), atol=1e-12)
        assert np.allclose(np.cross(t, b), nn, atol=1e-12)


def test_cli_check_scene_ok_and_error(tmp_path, capsys):
    assert main(["check-scene", "spheres"]) == 0
    out = capsys.readouterr().out
    assert "valid" in out and "scene hash" in out and "[camera]" in out
    bad = tmp_path / "bad.toml"
    bad.write_text('[environment]\ntype = "constant"\n[[objects]]\ntype = "sphere"\nradius = -1\n')
    before = sorted(tmp_path.iterdir())
    assert main(["check-scene", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "objects[0].radius" in err and "Traceback" not in err
    assert sorted(tmp_path.iterdir()) == before  # nothing written


def test_cli_scenes_lists_descriptions(capsys):
    assert main(["scenes"]) == 0
    out = capsys.readouterr().out
    for name in BUILTINS:
        assert name in out
    assert "(default)" in out


def test_console_script_help_and_exit_code(tmp_path):
    exe = Path(sys.executable).with_name("pbrcheck")
    r = subprocess.run([str(exe), "--help"], capture_output=True, text=True)
    assert r.returncode == 0 and "check-scene" in r.stdout
    r = subprocess.run([str(exe), "check-scene", str(tmp_path / "missing.toml")], capture_output=True, text=True)
    assert r.returncode == 2 and "missing.toml" in r.stderr and "Traceback" not in r.stderr
