"""Issue 34, outputs side (docs/security.md): every hostile case is built here and asserts the refusal
or the escaped output.

* The render cache: ``cache clear`` on a folder that is not pbrcheck's removes nothing (exit 2, one
  line); in a marked cache it removes the cache's entries alone (a photo, a render, a ``.git`` pack
  file, a linked folder's files stay); a folder gets its marker when the cache creates it, a pre-marker
  cache is adopted; a corrupted header (an attribute renamed or changed) is a miss, removed and reported.
* Corpus CSV: cells that begin with ``= + - @``, tab or CR are text (OWASP's rule).
* ``check-scene``: names holding ESC, newlines, quotes, backslashes, ``]`` and non-BMP characters
  neither reach the terminal raw nor break the TOML (it parses, and the names read back).
* A scene's name cannot move a command's default output path out of ``out/`` (``../../x``).
* ``export``: an asset's buffer named ``scenario.json`` and image named ``scene.gltf`` are kept (in
  ``_asset/``), the export's own files are the export's.
* SIGTERM during a long ray-cast frame: exit 143 within :data:`SIGTERM_BOUND_S`, nothing written;
  the banded frame is bit-identical to one dispatch.
"""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import textwrap
import time
import tomllib
from pathlib import Path

import numpy as np
import pytest

from pbrcheck import cache
from pbrcheck.cli import main
from pbrcheck.exr import Image
from pbrcheck.gltf_build import Doc, png_bytes
from pbrcheck.scene import load_scene, toml_string

ROOT = Path(__file__).resolve().parents[1]

#: Names an attacker gives a scene, an object or a material: an ANSI colour sequence, a newline that
#: would start a forged line, TOML's quote, backslash and table bracket, C1's CSI, DEL, and text
#: outside the Basic Multilingual Plane (a surrogate pair in a JSON escape, which TOML refuses).
HOSTILE = "evil\x1b[31mRED\x1b[0m\n[forged]\nname = \"x\\\"] \u00fc \U0001F600 \x7f\x9b2J"


#: The real-time renderer at its smallest (tests/test_faults.py's).
RT_FAST = ["--set", "cube_size=16", "--set", "prefilter_samples=16", "--set", "irradiance=sh9",
           "--set", "prefilter_levels=4", "--set", "lut_size=16", "--set", "lut_samples=16",
           "--set", "irradiance_source_size=8"]


# --- the cache ------------------------------------------------------------------------------------

def _entry(ns: str, k: str, root: Path) -> Path:
    return cache.Cache(ns, root).put(cache.cache_key(k=k), Image({"x": np.full((4, 4), 1.0, np.float32)},
                                                                 {"scene": "abc"}))


def _files(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*") if p.is_file() or p.is_symlink()}


def test_clear_refuses_a_folder_that_is_not_a_cache(tmp_path, monkeypatch, capsys):
    user = tmp_path / "pictures"
    for rel, data in {"holiday.jpg": b"\xff\xd8 a photo", "photos/2024/holiday.exr": b"an EXR of the user's",
                      f"renders/ab/{'ab' + '0' * 62}.exr": b"a render named like an entry",
                      ".git/objects/pack/pack-1.pack": b"PACK", "\x1b[2Jnamed.txt": b"the first file found"}.items():
        (user / rel).parent.mkdir(parents=True, exist_ok=True)
        (user / rel).write_bytes(data)
    before = _files(user)
    monkeypatch.setenv(cache.CACHE_ENV, str(user))
    for action in ("clear", "prune --older-than 0", "info"):
        assert main(["cache", *action.split()]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "not a pbrcheck cache" in err[0] and str(user) in err[0], err
        assert "\\x1b[2Jnamed.txt" in err[0] and "\x1b" not in err[0]     # the file it names, escaped
    assert _files(user) == before and not (user / cache.MARKER).exists()
    # a render into it is refused the same way, before anything is written
    with pytest.raises(cache.CacheError, match="not a pbrcheck cache"):
        _entry("reference", "a", user)
    assert _files(user) == before


def test_clear_in_a_cache_removes_only_its_entries(tmp_path, monkeypatch, capsys):
    root = tmp_path / "cache"
    entries = [_entry("reference", "a", root), _entry("flip", "b", root)]
    assert cache.is_marked(root)                                          # the cache made and marked it
    outside = tmp_path / "elsewhere" / "cd"
    outside.mkdir(parents=True)
    linked = outside / ("cd" + "1" * 62 + ".exr")                         # an entry's name, through a link
    linked.write_bytes(b"not the cache's")
    (root / "reference" / "cd").symlink_to(outside)
    theirs = {"reference/ab/holiday.exr": b"a photo", "reference/notes.txt": b"notes",
              "photos/2024/holiday.exr": b"an EXR", ".git/objects/pack/pack-1.pack": b"PACK",
              f"Reference/ab/{'ab' + '2' * 62}.exr": b"not a namespace of the cache's",
              f"reference/ab/{'cd' + '3' * 62}.exr": b"an entry's name in the wrong folder"}
    for rel, data in theirs.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_bytes(data)
    monkeypatch.setenv(cache.CACHE_ENV, str(root))
    assert main(["cache", "clear"]) == 0
    assert "removed 2 entries" in capsys.readouterr().out
    assert not any(p.exists() for p in entries)
    assert all((root / rel).read_bytes() == data for rel, data in theirs.items())
    assert linked.read_bytes() == b"not the cache's" and cache.is_marked(root)


def test_marker_on_an_empty_folder_and_a_cache_from_before_markers(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    _entry("reference", "a", empty)
    assert cache.is_marked(empty)
    old = tmp_path / "old"
    p = _entry("reference", "b", old)
    (old / cache.MARKER).unlink()                                          # as written before markers
    cache._claimed.clear()
    res = cache.prune(root=old)                                            # every file is the cache's: adopted
    assert res.removed == 1 and not p.exists() and cache.is_marked(old)
    # another tool's CACHEDIR.TAG is not pbrcheck's
    other = tmp_path / "other"
    other.mkdir()
    (other / cache.MARKER).write_text(cache.CACHEDIR_SIGNATURE + "\n# created by another tool\n")
    (other / "blob.bin").write_bytes(b"x")
    with pytest.raises(cache.CacheError, match="not a pbrcheck cache"):
        cache.prune(root=other)


@pytest.mark.parametrize("old,new", [(b"pbrcheck.scene\0", b"pbrcheck.scenf\0"),   # the attribute renamed
                                     (b"abc", b"abd")],                              # its value changed
                         ids=["name", "value"])
def test_a_corrupted_header_is_a_miss_removed_and_reported(tmp_path, capfd, old, new):
    c = cache.Cache("reference", tmp_path / "cache")
    key = cache.cache_key(k="header")
    p = c.put(key, Image({"x": np.full((4, 4), 1.0, np.float32)}, {"scene": "abc"}))
    hit = c.get(key)
    assert hit.meta["scene"] == "abc" and cache.CHECKSUM_META not in hit.meta
    raw = p.read_bytes()
    assert raw.count(old) == 1
    p.write_bytes(raw.replace(old, new))                                   # the EXR still reads
    assert c.get(key) is None and not p.exists()
    err = capfd.readouterr().err
    assert "corrupt entry removed" in err and "checksum" in err and str(p) in err


# --- corpus CSV -----------------------------------------------------------------------------------

def test_corpus_csv_cells_that_begin_a_formula_are_text(tmp_path):
    from compare.corpus.outputs import write_csv

    names = ["=HYPERLINK(\"http://x\",\"y\")", "+1+2", "-2+3", "@SUM(A1)", "\tx", "\rx", "plain"]
    rows = [{"environment": n, "relmse": -0.5} for n in names]
    path = write_csv(tmp_path / "corpus.csv", rows, ["environment", "relmse"])
    with open(path, newline="", encoding="utf-8") as f:
        got = list(csv.reader(f))[1:]
    assert [r[0] for r in got] == ["'" + n for n in names[:-1]] + ["plain"]
    assert [r[1] for r in got] == ["-0.5"] * len(names)                   # a negative number stays a number


# --- check-scene: the terminal and the TOML -------------------------------------------------------

def _asset(folder: Path, names: str) -> Path:
    doc = Doc()
    pos = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32)
    attrs = {"POSITION": doc.accessor(pos, "VEC3", minmax=True),
             "NORMAL": doc.accessor(np.array([[0, 0, 1]] * 4, np.float32), "VEC3")}
    doc.d["materials"] = [{"name": names, "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0]}}]
    doc.node(doc.mesh(attrs, doc.accessor(np.array([0, 1, 2, 0, 2, 3], np.uint16), "SCALAR"), 0), name=names)
    doc.d["meshes"][0]["name"] = names
    return doc.write(folder / "asset.gltf")


def _hostile_scene(folder: Path, asset: Path | None = None) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    objects = (f"[[objects]]\ntype = \"gltf\"\npath = {toml_string(str(asset))}\n" if asset else
               f"[[objects]]\ntype = \"sphere\"\nname = {toml_string(HOSTILE)}\nradius = 1.0\n")
    p = folder / "scene\x1b[2J\nforged = 1.toml"                            # the file's name is hostile too
    p.write_text(f"name = {toml_string(HOSTILE)}\ndescription = {toml_string(HOSTILE)}\n"
                 "[camera]\norigin = [0, 0, 4]\nfov = 40.0\nwidth = 16\nheight = 8\n"
                 "[environment]\ntype = \"constant\"\nradiance = [1, 1, 1]\n" + objects)
    return p


@pytest.mark.parametrize("with_asset", [False, True], ids=["analytic", "asset"])
def test_check_scene_escapes_names_and_its_toml_parses(tmp_path, capsys, with_asset):
    asset = _asset(tmp_path / "s", HOSTILE) if with_asset else None  # in the scene's folder (docs/assets.md)
    scene = _hostile_scene(tmp_path / "s", asset)
    assert main(["check-scene", str(scene)]) == 0
    out = capsys.readouterr().out
    assert not any(c in out for c in "\x1b\x7f\x9b\r\b")                  # no control character but newlines
    for line in out.splitlines():
        assert not line.startswith(("forged", "[forged]")), line           # no line forged by a name
    doc = tomllib.loads(out)
    assert doc["name"] == HOSTILE and doc["description"] == HOSTILE
    if with_asset:
        assert any(HOSTILE.splitlines()[0][:4] in l and "\\x1b[31m" in l for l in out.splitlines() if l.startswith("#"))
    else:
        assert doc["objects"][0]["name"] == HOSTILE
    assert json.loads(_json_of(scene, capsys))["name"] == HOSTILE           # --format json: the same names


def _json_of(scene: Path, capsys) -> str:
    assert main(["check-scene", str(scene), "--format", "json"]) == 0
    out = capsys.readouterr().out
    assert "\x1b" not in out
    return out


def test_a_scene_name_cannot_move_a_default_output_path(tmp_path, monkeypatch, capsys):
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    scene = tmp_path / "s.toml"
    scene.write_text(f"name = {toml_string('../../escaped' + chr(27) + '[2J')}\n[camera]\norigin = [0, 0, 4]\n"
                     "fov = 40.0\nwidth = 8\nheight = 8\n[environment]\ntype = \"constant\"\nradiance = [1, 1, 1]\n"
                     "[[objects]]\ntype = \"sphere\"\nradius = 1.0\n")
    assert main(["realtime", str(scene), *RT_FAST]) == 0
    out = capsys.readouterr().out
    assert "\x1b" not in out
    written = [p.relative_to(tmp_path) for p in tmp_path.rglob("*.exr")]
    assert written == [Path("work/out/realtime/_.._escaped__2J_default.exr")], written


# --- export never overwrites an asset's file ------------------------------------------------------

def test_export_keeps_an_asset_file_named_like_its_own(tmp_path, capsys):
    folder = tmp_path / "asset"
    folder.mkdir()
    doc = Doc()
    pos = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32)
    attrs = {"POSITION": doc.accessor(pos, "VEC3", minmax=True),
             "NORMAL": doc.accessor(np.array([[0, 0, 1]] * 4, np.float32), "VEC3"),
             "TEXCOORD_0": doc.accessor(np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32), "VEC2")}
    doc.d["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]
    doc.node(doc.mesh(attrs, doc.accessor(np.array([0, 1, 2, 0, 2, 3], np.uint16), "SCALAR"), 0))
    png = png_bytes(np.full((4, 4, 3), 200, np.uint8))
    doc.d["images"] = [{"uri": "scene.gltf", "mimeType": "image/png"}]   # an image named like the export's JSON
    doc.d["textures"] = [{"source": 0}]
    doc.d["buffers"] = [{"uri": "scenario.json", "byteLength": len(doc.bin)}]  # a buffer named like its scenario
    (folder / "scenario.json").write_bytes(bytes(doc.bin))
    (folder / "scene.gltf").write_bytes(png)
    asset = folder / "model.gltf"
    asset.write_text(json.dumps(doc.d))
    out = tmp_path / "out"
    assert main(["export", str(asset), "--out", str(out)]) == 0
    capsys.readouterr()
    assert (out / "_asset" / "scenario.json").read_bytes() == bytes(doc.bin)
    assert (out / "_asset" / "scene.gltf").read_bytes() == png
    exported = json.loads((out / "scene.gltf").read_text())                # the export's own JSON ...
    assert [b["uri"] for b in exported["buffers"]] == ["_asset/scenario.json"]
    assert [i["uri"] for i in exported["images"]] == ["_asset/scene.gltf"]
    assert "output" in json.loads((out / "scenario.json").read_text())   # ... and its own scenario
    again = load_scene(out / "scene.gltf")                                  # the exported asset loads whole
    prim = again.assets[0].asset.primitives[0]
    assert np.array_equal(prim.positions, pos) and again.assets[0].asset.images[0].size == (4, 4)


# --- SIGTERM during a long GL frame ---------------------------------------------------------------

#: Seconds from SIGTERM to the process's exit during a large ray-cast frame. Its bands aim at
#: realtime.render.FRAME_BAND_SECONDS (0.5 s) of GL work; this machine shares two cores among many
#: processes (a band measured fast may then run 4x slower), and the exit itself (the error line,
#: interpreter and GL teardown) took ~0.5 s: 0.5 x 4 + 0.5, doubled. One dispatch of the same frame
#: held the signal 10-20 s (the frame's length, issue 34: 44 s at 8192^2).
SIGTERM_BOUND_S = 5.0
#: The frame: 2048 x 2048 pixels at supersample 4 (67 M samples; 15 s in one dispatch on llvmpipe here).
BIG_FRAME = (2048, 2048)
#: Seconds into the frame before the signal.
SIGNAL_AFTER_S = 1.0

_DRIVER = textwrap.dedent("""
    import sys
    from pathlib import Path
    import realtime.render as R
    flag = Path(sys.argv[1])
    compile_program = R.compute_program
    def marked(name, *a, **k):  # the frame pass is compiled: its dispatch follows at once
        p = compile_program(name, *a, **k)
        if name == "render.comp":
            flag.write_text("frame")
        return p
    R.compute_program = marked
    from pbrcheck.cli import main
    sys.exit(main(sys.argv[2:]))
""")



@pytest.mark.slow
def test_sigterm_during_a_large_frame_is_honoured_within_the_bound(tmp_path):
    w, h = BIG_FRAME
    scene = tmp_path / "big.toml"
    scene.write_text("name = \"big\"\n[camera]\norigin = [0, 0, 3]\nfov = 60.0\n"
                     f"width = {w}\nheight = {h}\n[environment]\ntype = \"constant\"\nradiance = [1, 1, 1]\n"
                     "[[lights]]\ntype = \"point\"\nposition = [2, 2, 3]\nintensity = [5, 5, 5]\n"
                     "[[objects]]\ntype = \"sphere\"\nradius = 1.0\n")
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    flag, out = tmp_path / "flag", tmp_path / "out" / "big.exr"
    env = {**os.environ, "PYTHONPATH": str(ROOT), "TMPDIR": str(tmp), "PBRCHECK_CACHE": str(tmp_path / "cache")}
    p = subprocess.Popen([sys.executable, "-c", _DRIVER, str(flag), "realtime", str(scene), *RT_FAST,
                          "--out", str(out)], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.time() + 120
        while not flag.exists() and p.poll() is None and time.time() < deadline:
            time.sleep(0.05)
        assert p.poll() is None and flag.exists(), p.communicate()
        time.sleep(SIGNAL_AFTER_S)
        assert p.poll() is None, "the frame finished before the signal"
        sent = time.time()
        p.send_signal(signal.SIGTERM)
        _, err = p.communicate(timeout=120)
        took = time.time() - sent
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    assert p.returncode == 143 and err.strip().splitlines()[-1] == "pbrcheck: terminated", (p.returncode, err)
    assert "Traceback" not in err
    assert took < SIGTERM_BOUND_S, f"SIGTERM honoured after {took:.1f} s"
    assert not out.exists() and not (out.parent.exists() and list(out.parent.iterdir()))
    assert not list(tmp.iterdir())


def _banded(monkeypatch, first_rows: int, row_samples: int) -> list[int]:
    """Every frame from now on in bands of ``first_rows`` rows (rows of ``row_samples`` samples); the
    returned list gets each frame's band count."""
    import realtime.gl as G

    counts = []
    bands = G.in_bands
    monkeypatch.setattr(G, "SINGLE_DISPATCH_SAMPLES", 0)
    monkeypatch.setattr(G, "FIRST_BAND_SAMPLES", first_rows * row_samples)
    monkeypatch.setattr(G, "BAND_GROWTH", 1)                              # the bands never grow
    for mod in ("realtime.render", "realtime.raster"):
        monkeypatch.setattr(f"{mod}.in_bands", lambda *a: counts.append(bands(*a)) or counts[-1])
    return counts


def _same_pixels(a: Image, b: Image) -> None:
    assert set(a.channels) == set(b.channels)
    for k in a.channels:
        assert a.channels[k].tobytes() == b.channels[k].tobytes(), k


FAST = {"cube_size": 16, "prefilter_levels": 4, "prefilter_samples": 16, "lut_size": 16, "lut_samples": 16,
        "irradiance_source_size": 8}


def test_a_banded_ray_cast_frame_is_bit_identical_to_one_dispatch(monkeypatch):
    import realtime.render as R
    from pbrcheck.scene import scene_from_dict

    d = load_scene("spheres").to_dict()
    d["camera"]["width"], d["camera"]["height"] = 72, 60
    scene = scene_from_dict(d)
    one = R.render_realtime(scene, "default", FAST, progress=False)
    counts = _banded(monkeypatch, 8, 72 * 16)
    banded = R.render_realtime(scene, "default", FAST, progress=False)
    assert counts == [60 // 8 + 1]                                         # 7 bands of 8 rows and one of 4
    _same_pixels(one, banded)


def test_a_banded_raster_frame_is_bit_identical_to_one_pass(monkeypatch, tmp_path):
    import realtime.render as R

    from gltf_build import quad_asset, quad_scene

    asset = quad_asset(tmp_path / "quad.gltf", {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0},
                                                                         "roughnessFactor": 0.4}},
                       [(np.arange(8 * 8 * 3, dtype=np.uint8).reshape(8, 8, 3) * 3, None)])
    scene = load_scene(quad_scene(tmp_path, asset, size=(40, 36)))
    opts = {**FAST, "supersample": 2}
    one = R.render_realtime(scene, "default", opts, progress=False)
    counts = _banded(monkeypatch, 8, 80)
    banded = R.render_realtime(scene, "default", opts, progress=False)
    assert counts == [72 // 8]                                             # 72 supersampled rows
    _same_pixels(one, banded)


def test_error_lines_escape_control_characters(tmp_path, capsys):
    """The CLI's one error line shows a hostile path's control characters escaped (no ESC reaches
    the terminal, no second line is forged)."""
    missing = tmp_path / "x\x1b[2J\nforged.toml"
    assert main(["check-scene", str(missing)]) == 2
    err = capsys.readouterr().err
    assert "\x1b" not in err and "\\x1b[2J\\nforged.toml" in err and len(err.strip().splitlines()) == 1
