"""A scene made from a glTF asset alone is set up by an explicit argument of ``load_scene``
(``AssetOptions``: the command line's ``--env`` and ``--size WxH``), with no module state: the same
call gives the same scene whatever ran before; every command that takes a SCENE lists both options
in its ``--help``; a ``WxH`` given to a command's own integer ``--size`` is the asset's."""

from __future__ import annotations

import numpy as np
import pytest

import pbrcheck.gltf_objects as gltf_objects
from pbrcheck_cli import build_parser, main
from pbrcheck.exr import Image, write_exr
from pbrcheck.gltf_build import panel_asset
from pbrcheck.gltf_objects import DEFAULT_ASSET_SIZE, AssetOptions, asset_options_of
from pbrcheck.scene import load_scene


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("asset_options")
    env = write_exr(d / "env.exr", Image.from_rgb(np.full((8, 16, 3), 0.25, np.float32)))
    return panel_asset(d / "panel.glb", segments=4, tex=8), env


def test_load_scene_takes_the_asset_options_explicitly(files):
    asset, env = files
    a = load_scene(asset, AssetOptions(env=str(env), size=(40, 30)))
    assert (a.camera.width, a.camera.height) == (40, 30)
    assert (a.environment.type, a.environment.path) == ("file", str(env.resolve()))
    b = load_scene(asset)  # no options: the neutral environment at the default size, whatever ran before
    assert (b.camera.width, b.camera.height) == DEFAULT_ASSET_SIZE and b.environment.type == "constant"
    assert load_scene(asset, AssetOptions(size=(40, 30))).camera.width == 40
    assert load_scene("spheres", AssetOptions(size=(40, 30))).camera.width == load_scene("spheres").camera.width
    assert not hasattr(gltf_objects, "_OPTIONS") and not hasattr(gltf_objects, "set_asset_options")


def test_the_command_line_passes_them_and_leaves_no_state(files, capsys):
    asset, env = files
    assert main(["check-scene", str(asset), "--env", str(env), "--size", "40x30", "--json"]) == 0
    out = capsys.readouterr().out
    assert '"width": 40' in out and '"height": 30' in out and str(env.resolve()) in out
    assert (load_scene(asset).camera.width, load_scene(asset).environment.type) == (512, "constant")
    with pytest.raises(SystemExit) as e:  # argparse's bad-argument exit, one line naming the option
        main(["check-scene", str(asset), "--size", "0x10"])
    assert e.value.code == 2
    assert "argument --size: expected sides in [1, 16384], found '0x10'" in capsys.readouterr().err


def test_every_scene_command_lists_env_and_size():
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    scene_commands = [name for name, p in sub.choices.items()
                      if any(a.dest == "scene" or (a.dest == "scenes" and not a.option_strings) for a in p._actions)]
    assert {"check-scene", "reference", "realtime", "render", "export", "compare", "diagnose", "fit-lod",
            "fit-roughness", "explain", "report", "sweep", "corpus"} <= set(scene_commands)
    for name in scene_commands:
        text = sub.choices[name].format_help()
        assert "--env FILE" in text and "WxH" in text, name


def test_a_wxh_size_on_a_commands_own_integer_size_is_the_assets():
    parser = build_parser()
    args = parser.parse_args(["fit-roughness", "a.glb", "--size", "64x48", "--env", "e.hdr"])
    own = parser.parse_args(["fit-roughness", "a.glb"]).size
    assert asset_options_of(args) == AssetOptions("e.hdr", (64, 48)) and args.size == own
    assert asset_options_of(args) == AssetOptions("e.hdr", (64, 48))  # idempotent
    args = parser.parse_args(["fit-roughness", "a.glb", "--size", "32"])
    assert asset_options_of(args) == AssetOptions() and args.size == 32
    args = parser.parse_args(["reference", "a.glb", "--size", "64x48"])
    assert asset_options_of(args) == AssetOptions(None, (64, 48))
