"""Untrusted assets and scenes (issue 34, the assets side): every hostile input is built here and
must be refused in one line (exit 2 through the CLI, or the typed error naming file and JSON pointer),
and every resource budget holds at its boundary (just under passes, just over is refused).

The resolver (:mod:`pbrcheck.untrusted`): traversal ``../``, an absolute path, ``..%2F``, a
``file:`` URI, a symlink out of the asset's folder, a FIFO, ``/dev/zero``; ``export`` never copies a
symlinked file's target; a scene file's paths stay in its folder. The guards
(:mod:`pbrcheck.asset_guard`): malformed fields, GLB version 1, non-finite world geometry, pygltflib's
warnings. The budgets (:mod:`pbrcheck.limits`): node instances, triangles, texture bytes (from a
crafted PNG header: nothing of 30000^2 is decoded), environment pixels (a crafted HDR header),
reference samples and pixels, the raster pipeline's GL target size.
"""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
import threading
import time
import warnings
import zlib
from pathlib import Path

import numpy as np
import pytest

from pbrcheck import limits
from pbrcheck.cli import main
from pbrcheck.gltf import AssetError, load_asset
from pbrcheck.gltf_build import png_bytes
from pbrcheck.scene import load_scene
from tests.gltf_build import QUAD_IDX, QUAD_POS, Doc, quad_asset, quad_scene


# ------------------------------------------------------------------------------------------------
# builders
# ------------------------------------------------------------------------------------------------

def quad_doc(indices: np.ndarray = QUAD_IDX, positions: np.ndarray = QUAD_POS, **node_kw) -> Doc:
    """One quad (2 triangles) on one root node, no material."""
    doc = Doc()
    doc.node(doc.mesh({"POSITION": doc.accessor(positions, "VEC3", minmax=True)},
                      doc.accessor(indices, "SCALAR"), None), **node_kw)
    return doc


def write_external(doc: Doc, folder: Path, *, bin_uri: str = "a.bin", name: str = "a.gltf") -> Path:
    """``folder/name`` with its buffer in ``folder/a.bin`` named by ``bin_uri``."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "a.bin").write_bytes(bytes(doc.bin))
    doc.d["buffers"] = [{"byteLength": len(doc.bin), "uri": bin_uri}]
    p = folder / name
    p.write_text(json.dumps(doc.d))
    return p


def png_header(width: int, height: int, color_type: int = 6) -> bytes:
    """A PNG whose IHDR claims ``width x height`` (8-bit, ``color_type`` 6 RGBA, 0 grey) with one tiny
    IDAT: a bomb by its header, a few dozen bytes on disk."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    ihdr = struct.pack(">IIBBBBB", width, height, 8, color_type, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 64)) + chunk(b"IEND", b"")


def with_images(doc: Doc, folder: Path, images: list[bytes]) -> Path:
    """``doc`` with external images ``img<k>.png`` (each its bytes), each the emissive texture of a
    material of its own that no primitive draws: the loader decodes every image a material's texture
    reads (pbrcheck.gltf_features.used_images), so each is read and counted."""
    folder.mkdir(parents=True, exist_ok=True)
    doc.d["images"], doc.d["textures"], doc.d["materials"] = [], [], []
    for k, raw in enumerate(images):
        (folder / f"img{k}.png").write_bytes(raw)
        doc.d["images"].append({"uri": f"img{k}.png"})
        doc.d["textures"].append({"source": k})
        doc.d["materials"].append({"emissiveTexture": {"index": k}})
    return write_external(doc, folder)


def cli(capsys, *argv: str) -> tuple[int, str]:
    """(exit code, stderr stripped) of ``pbrcheck argv`` in this process."""
    rc = main(list(argv))
    return rc, capsys.readouterr().err.strip()


def cli_process(*argv: str, timeout: float) -> tuple[int, str]:
    """(exit code, stderr stripped) of ``pbrcheck argv`` in a child process, killed after ``timeout``
    seconds (a test of a refusal that, without it, would run for hours fails instead of hanging)."""
    root = Path(__file__).resolve().parents[1]
    env = {**os.environ, "PYTHONPATH": str(root)}
    try:
        r = subprocess.run([sys.executable, "-m", "pbrcheck.cli", *argv], cwd=root, env=env, capture_output=True,
                           text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        pytest.fail(f"pbrcheck {' '.join(argv)} still running after {timeout} s")
    return r.returncode, r.stderr.strip()


def assert_one_line_refusal(rc: int, err: str, *needles: str) -> None:
    assert rc == 2, err
    assert err.startswith("pbrcheck: error: ") and "\n" not in err and "Traceback" not in err, err
    for n in needles:
        assert n in err, (n, err)


# ------------------------------------------------------------------------------------------------
# the URI resolver
# ------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("uri, reason", [
    ("../outside.bin", "leaving the file's folder"),
    ("ABS", "absolute path"),
    ("..%2Foutside.bin", "leaving the file's folder"),
    ("sub/..%2F..%2Foutside.bin", "leaving the file's folder"),
    ("file://ABS", "scheme (file:)"),
])
def test_buffer_uri_outside_the_folder_is_refused(tmp_path, capsys, uri, reason):
    doc = quad_doc()
    (tmp_path / "outside.bin").write_bytes(bytes(doc.bin))  # readable and valid: only containment refuses it
    uri = uri.replace("ABS", str(tmp_path / "outside.bin"))
    p = write_external(doc, tmp_path / "asset", bin_uri=uri)
    with pytest.raises(AssetError) as e:
        load_asset(p)
    assert e.value.pointer == "/buffers/0/uri" and reason in e.value.problem, str(e.value)
    rc, err = cli(capsys, "check-scene", str(p))
    assert_one_line_refusal(rc, err, str(p), "/buffers/0/uri", reason)


def test_symlink_out_of_the_folder_is_refused_and_one_inside_is_read(tmp_path):
    doc = quad_doc()
    (tmp_path / "outside.bin").write_bytes(bytes(doc.bin))
    p = write_external(doc, tmp_path / "asset", bin_uri="link.bin")
    (tmp_path / "asset" / "link.bin").symlink_to(tmp_path / "outside.bin")
    with pytest.raises(AssetError, match="resolves outside the file's folder") as e:
        load_asset(p)
    assert e.value.pointer == "/buffers/0/uri"
    # a symlink to a file inside the folder is fine
    (tmp_path / "asset" / "link.bin").unlink()
    (tmp_path / "asset" / "data").mkdir()
    (tmp_path / "asset" / "data" / "real.bin").write_bytes(bytes(doc.bin))
    (tmp_path / "asset" / "link.bin").symlink_to(Path("data") / "real.bin")
    assert load_asset(p).triangles == 2


def test_image_symlink_out_of_the_folder_is_refused(tmp_path):
    doc = quad_doc()
    (tmp_path / "outside.png").write_bytes(png_bytes(np.full((4, 4, 3), 200, np.uint8)))
    p = write_external(doc, tmp_path / "asset")
    d = json.loads(p.read_text())
    d["images"] = [{"uri": "tex.png"}]
    p.write_text(json.dumps(d))
    (tmp_path / "asset" / "tex.png").symlink_to(tmp_path / "outside.png")
    with pytest.raises(AssetError, match="resolves outside") as e:
        load_asset(p)
    assert e.value.pointer == "/images/0/uri"


def test_export_never_copies_a_symlinked_files_outside_target(tmp_path):
    from pbrcheck.gltf_export import asset_document

    doc = quad_doc()
    p = with_images(doc, tmp_path / "asset", [png_bytes(np.full((4, 4, 3), 90, np.uint8))])
    scene = load_scene(quad_scene(tmp_path / "asset", p, size=(8, 8)))
    secret = tmp_path / "secret.png"
    secret.write_bytes(png_bytes(np.full((4, 4, 3), 7, np.uint8)))
    (tmp_path / "asset" / "img0.png").unlink()  # swapped for a symlink out after the load
    (tmp_path / "asset" / "img0.png").symlink_to(secret)
    with pytest.raises(AssetError, match="resolves outside") as e:
        asset_document(scene, {"name": "camera", "camera": 0}, {"type": "perspective", "perspective": {"yfov": 0.5}})
    assert e.value.pointer == "/images/0/uri"


def test_a_fifo_is_refused_without_blocking(tmp_path):
    doc = quad_doc()
    p = write_external(doc, tmp_path / "asset", bin_uri="pipe.bin")
    fifo = tmp_path / "asset" / "pipe.bin"
    os.mkfifo(fifo)
    out: dict = {}

    def load():
        try:
            load_asset(p)
        except AssetError as e:
            out["err"] = e
    t = threading.Thread(target=load, daemon=True)
    t.start()
    t.join(10.0)
    if t.is_alive():  # unblock the reader the loader left waiting for a writer, then fail
        fd = os.open(fifo, os.O_WRONLY | os.O_NONBLOCK)
        os.close(fd)
        pytest.fail("opening a FIFO buffer blocked")
    assert "err" in out and out["err"].pointer == "/buffers/0/uri" and "a FIFO" in str(out["err"]), out


def test_devices_are_refused_and_reads_are_bounded(tmp_path):
    from pbrcheck import untrusted

    with pytest.raises(ValueError, match="a character device, not a regular file"):
        untrusted.read_regular("/dev/zero", 1 << 20)
    with pytest.raises(ValueError, match="a character device"):
        untrusted.read_regular("/dev/urandom", 1 << 20)
    f = tmp_path / "ten.bin"
    f.write_bytes(b"0123456789")
    assert untrusted.read_regular(f, 10) == b"0123456789"
    with pytest.raises(ValueError, match="10 bytes, more than the 9 read at most"):
        untrusted.read_regular(f, 9)


def test_a_buffer_longer_than_declared_is_not_read_past_the_cap(tmp_path):
    from pbrcheck.untrusted import READ_SLACK

    doc = quad_doc()
    p = write_external(doc, tmp_path / "asset")
    n = len(doc.bin)
    (tmp_path / "asset" / "a.bin").write_bytes(bytes(doc.bin) + b"\0" * READ_SLACK)  # at the cap: read
    assert load_asset(p).triangles == 2
    (tmp_path / "asset" / "a.bin").write_bytes(bytes(doc.bin) + b"\0" * (READ_SLACK + 1))
    with pytest.raises(AssetError, match=f"{n + READ_SLACK + 1} bytes, more than the {n + READ_SLACK}"):
        load_asset(p)


# ------------------------------------------------------------------------------------------------
# scene files' paths
# ------------------------------------------------------------------------------------------------

SCENE_HEAD = '[camera]\norigin = [0.0, 0.0, 4.0]\nwidth = 8\nheight = 8\n'


def test_scene_paths_stay_in_the_scenes_folder(tmp_path, capsys):
    asset = write_external(quad_doc(), tmp_path / "assets")
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    (scenes / "link.gltf").symlink_to(asset)
    for i, path in enumerate(("../assets/a.gltf", str(asset), "link.gltf")):
        s = scenes / f"s{i}.toml"
        s.write_text(SCENE_HEAD + f'[environment]\ntype = "constant"\n[[objects]]\ntype = "gltf"\npath = "{path}"\n')
        rc, err = cli(capsys, "check-scene", str(s))
        assert_one_line_refusal(rc, err, str(s), "objects[0].path", "outside the scene's folder")
    env = tmp_path / "env.exr"
    from pbrcheck.exr import Image, write_exr
    write_exr(env, Image.from_rgb(np.ones((4, 8, 3), np.float32)))
    s = scenes / "env.toml"
    s.write_text(SCENE_HEAD + '[environment]\ntype = "file"\npath = "../env.exr"\n[[objects]]\ntype = "sphere"\n')
    rc, err = cli(capsys, "check-scene", str(s))
    assert_one_line_refusal(rc, err, "environment.path", "outside the scene's folder")
    # inside: relative or absolute, both read; the asset given on the command line is the user's own
    inside = write_external(quad_doc(), scenes / "sub")
    for path in ("sub/a.gltf", str(inside)):
        s.write_text(SCENE_HEAD + f'[environment]\ntype = "constant"\n[[objects]]\ntype = "gltf"\npath = "{path}"\n')
        assert load_scene(s).assets[0].asset.triangles == 2
    assert cli(capsys, "check-scene", str(asset))[0] == 0


# ------------------------------------------------------------------------------------------------
# malformed fields: typed errors naming the file and the JSON pointer
# ------------------------------------------------------------------------------------------------

def _stride(d):
    d["bufferViews"][0]["byteStride"] = -12


def _sparse(d):
    d["accessors"][0]["sparse"] = {"count": -3, "indices": {"bufferView": 1, "componentType": 5123},
                                   "values": {"bufferView": 0}}


def _matrix(d):
    d["nodes"][0]["matrix"] = [1.0, 2.0, 3.0]


def _translation(d):
    d["nodes"][0]["translation"] = [1.0, 2.0]


def _scale(d):
    d["nodes"][0]["scale"] = [1e300, 1e300, 1e300]


@pytest.mark.parametrize("mutate, pointer, needle", [
    (_stride, "/bufferViews/0/byteStride", "a multiple of 4 in [4, 252], found -12"),
    (_sparse, "/accessors/0/sparse/count", "an integer >= 1, found -3"),
    (_matrix, "/nodes/0/matrix", "16 finite numbers, found 3 values"),
    (_translation, "/nodes/0/translation", "3 finite numbers, found 2 values"),
    (_scale, "/nodes/0", "a world transform with an entry of magnitude 1e+300, beyond 1e+18"),
])
def test_malformed_field_is_a_typed_error_with_its_pointer(tmp_path, capsys, mutate, pointer, needle):
    doc = quad_doc()
    mutate(doc.d)
    p = doc.write(tmp_path / "bad.gltf")
    with pytest.raises(AssetError) as e:
        load_asset(p)
    assert (e.value.file, e.value.pointer) == (str(p), pointer) and needle in e.value.problem, str(e.value)
    rc, err = cli(capsys, "check-scene", str(p))
    assert_one_line_refusal(rc, err, f"{p}: {pointer}: ")


def test_huge_positions_are_refused_not_rendered_blank(tmp_path):
    p = quad_doc(positions=QUAD_POS * np.float32(3e38)).write(tmp_path / "big.gltf")
    with pytest.raises(AssetError, match="4 position.s. non-finite or beyond 1e.18") as e:
        load_asset(p)
    assert e.value.pointer == "/meshes/0/primitives/0/attributes/POSITION"


def test_positions_beyond_the_bound_after_the_node_transform_are_refused(tmp_path):
    # each finite and within the bound alone (positions 1e9, scale 1e10); their product, 1e19, is not
    # (6 positions: the quad without NORMAL is unwelded into its triangles' corners)
    p = quad_doc(positions=QUAD_POS * np.float32(1e9), scale=[1e10, 1e10, 1e10]).write(tmp_path / "w.gltf")
    with pytest.raises(AssetError, match="6 world-space position.s. non-finite or beyond 1e.18") as e:
        load_asset(p)
    assert e.value.pointer == "/nodes/0"
    with_margin = quad_doc(positions=QUAD_POS * np.float32(1e9), scale=[1e8, 1e8, 1e8]).write(tmp_path / "ok.gltf")
    assert float(np.abs(load_asset(with_margin).primitives[0].positions).max()) == pytest.approx(1e17, rel=1e-6)


def test_signed_indices_are_refused_as_such(tmp_path):
    p = quad_doc(indices=np.array([0, -1, 2], np.int16)).write(tmp_path / "i16.gltf")
    with pytest.raises(AssetError) as e:
        load_asset(p)
    assert e.value.pointer == "/accessors/1/componentType", str(e.value)
    assert "5122" in e.value.problem and "unsigned" in e.value.problem and "out of range" not in e.value.problem


def test_glb_version_1_is_refused(tmp_path):
    p = quad_doc().write_glb(tmp_path / "v.glb")
    raw = bytearray(p.read_bytes())
    raw[4:8] = struct.pack("<I", 1)
    p.write_bytes(bytes(raw))
    with pytest.raises(AssetError, match="GLB header version 1"):
        load_asset(p)


def test_pygltflib_warnings_are_captured_never_shown(tmp_path, capfd):
    p = quad_doc().write_glb(tmp_path / "x.glb")
    raw = bytearray(p.read_bytes())
    raw += struct.pack("<I", 4) + b"XTRA" + b"\0" * 4   # a chunk of an unknown type: pygltflib warns
    raw[8:12] = struct.pack("<I", len(raw))
    p.write_bytes(bytes(raw))
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        assert load_asset(p).triangles == 2
    assert [str(x.message) for x in w] == []
    assert "open an issue" not in capfd.readouterr().err


# ------------------------------------------------------------------------------------------------
# budgets, each at its boundary
# ------------------------------------------------------------------------------------------------

def dag_doc(levels: int) -> Doc:
    """Node i lists node i + 1 twice; the last draws the quad: 2^(levels+1) - 1 node instances,
    2^levels x 2 triangles once expanded."""
    doc = quad_doc()
    leaf = doc.d["nodes"][0]
    doc.d["nodes"] = [{"children": [i + 1, i + 1]} for i in range(levels)] + [leaf]
    doc.d["scenes"][0]["nodes"] = [0]
    return doc


def test_node_dag_is_refused_before_expanding(tmp_path):
    p = dag_doc(30).write(tmp_path / "dag.gltf")
    rc, err = cli_process("check-scene", str(p), timeout=30.0)
    assert_one_line_refusal(rc, err, f"{2 ** 31 - 1:,} node instances", "MAX_NODE_INSTANCES", "--max-node-instances N")


def test_node_instance_budget_boundary(tmp_path):
    p = dag_doc(5).write(tmp_path / "dag5.gltf")   # 63 instances, 32 quads
    with limits.overridden(node_instances=63):
        assert load_asset(p).triangles == 64
    with limits.overridden(node_instances=62), pytest.raises(limits.LimitError, match="63 node instances"):
        load_asset(p)


def test_triangle_budget_boundary_counts_instances(tmp_path, capsys):
    doc = quad_doc()
    doc.node(0)                                   # the same mesh on a second node: 4 triangles
    p = doc.write(tmp_path / "two.gltf")
    with limits.overridden(triangles=4):
        assert load_asset(p).triangles == 4
    with limits.overridden(triangles=3), pytest.raises(limits.LimitError, match="4 triangles"):
        load_asset(p)
    rc, err = cli(capsys, "check-scene", str(p), "--max-triangles", "3")
    assert_one_line_refusal(rc, err, "4 triangles, above the limit of 3", "--max-triangles N")
    assert cli(capsys, "check-scene", str(p), "--max-triangles", "4")[0] == 0


def test_texture_bomb_refused_from_its_header(tmp_path, capsys):
    bomb = png_header(30000, 30000)
    assert len(bomb) < 200
    p = with_images(quad_doc(), tmp_path / "bomb", [bomb])
    t0 = time.perf_counter()
    rc, err = cli(capsys, "check-scene", str(p))
    assert_one_line_refusal(rc, err, f"{30000 * 30000 * 4:,} bytes", "30000x30000", "--max-texture-bytes N")
    assert time.perf_counter() - t0 < 10.0


def test_texture_budget_boundary(tmp_path):
    small = png_bytes(np.full((4, 4, 4), 100, np.uint8))   # 64 decoded bytes each
    p = with_images(quad_doc(), tmp_path / "two", [small, small])
    with limits.overridden(texture_bytes=128):
        assert [im.pixels.nbytes for im in load_asset(p).images] == [64, 64]
    with limits.overridden(texture_bytes=127), pytest.raises(limits.LimitError, match="128 bytes"):
        load_asset(p)


def test_pillow_decompression_bomb_warning_never_leaks(tmp_path):
    # 10^8 pixels: above Pillow's MAX_IMAGE_PIXELS (89.5 M: its warning), inside the budget (100 MB of
    # grey); the IDAT is truncated, so the decode fails fast with pbrcheck's own line
    p = with_images(quad_doc(), tmp_path / "warn", [png_header(10000, 10000, color_type=0)])
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        with pytest.raises(AssetError, match="unreadable texture image") as e:
            load_asset(p)
    assert e.value.pointer == "/images/0"
    assert [x.category.__name__ for x in w] == []


def _env_scene(folder: Path, env_name: str) -> Path:
    s = folder / "env.toml"
    s.write_text(SCENE_HEAD + f'[environment]\ntype = "file"\npath = "{env_name}"\n[[objects]]\ntype = "sphere"\n')
    return s


def test_environment_size_refused_from_its_header(tmp_path, capsys):
    (tmp_path / "huge.hdr").write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 8192 +X 16384\n")
    rc, err = cli(capsys, "check-scene", str(_env_scene(tmp_path, "huge.hdr")))
    assert_one_line_refusal(rc, err, "environment map of 16384x8192", f"{16384 * 8192:,} pixels",
                            "--max-env-pixels N")


def test_environment_budget_boundary(tmp_path):
    from pbrcheck.environment import load_environment
    from pbrcheck.exr import Image, write_exr
    from pbrcheck.hdrimage import hdr_size, write_hdr

    write_exr(tmp_path / "e.exr", Image.from_rgb(np.ones((4, 8, 3), np.float32)))
    scene = load_scene(_env_scene(tmp_path, "e.exr"))
    with limits.overridden(env_pixels=32):
        assert load_environment(scene).width == 8
    with limits.overridden(env_pixels=31), pytest.raises(limits.LimitError, match="environment map of 8x4"):
        load_environment(scene)
    write_hdr(tmp_path / "e.hdr", np.ones((5, 9, 3), np.float32))
    assert hdr_size(tmp_path / "e.hdr") == (9, 5)


def _sized_scene(folder: Path, w: int, h: int) -> Path:
    s = folder / f"s{w}x{h}.toml"
    s.write_text(f'[camera]\norigin = [0.0, 0.0, 4.0]\nwidth = {w}\nheight = {h}\n'
                 '[environment]\ntype = "constant"\n[[objects]]\ntype = "sphere"\n')
    return s


def test_reference_samples_refused_before_the_render(tmp_path):
    s = _sized_scene(tmp_path, 32, 32)
    rc, err = cli_process("reference", str(s), "--spp", "1000000000", "--no-adaptive", "--no-cache",
                          "--out", str(tmp_path / "r.exr"), timeout=60.0)
    assert_one_line_refusal(rc, err, f"{10 ** 9 * 1024:,} samples", "--max-samples N")
    assert not (tmp_path / "r.exr").exists()


def test_reference_budget_boundaries(tmp_path):
    from reference.render import check_budget

    scene = load_scene(_sized_scene(tmp_path, 32, 32))
    with limits.overridden(samples=64 * 1024):
        check_budget(scene, 64)
        with pytest.raises(limits.LimitError, match=f"{65 * 1024:,} samples"):
            check_budget(scene, 65)
    with limits.overridden(reference_pixels=1024):
        check_budget(scene, 2)
    with limits.overridden(reference_pixels=1023), pytest.raises(limits.LimitError, match="reference image of 32x32"):
        check_budget(scene, 2)
    with pytest.raises(limits.LimitError, match="reference image of 16384x16384"):   # the default
        check_budget(load_scene(_sized_scene(tmp_path, 16384, 16384)), 2)


def _gl_or_skip():
    from pbrcheck.errors import BackendError
    from realtime.gl import get_context
    try:
        return get_context()
    except BackendError as e:
        pytest.skip(f"no GL context: {e}")


def test_raster_target_size_asked_from_gl(tmp_path, capsys):
    _gl_or_skip()
    from realtime.raster import check_target_size, max_target_side

    most, name = max_target_side()
    assert name.startswith("GL_MAX_") and most >= 1024
    check_target_size(most // 4, 8, 4)
    with pytest.raises(limits.OutputSizeError, match=f"exceeds this GL's {most} \\({name}\\)"):
        check_target_size(most // 4 + 1, 8, 4)
    p = quad_doc().write(tmp_path / "q.gltf")
    rc, err = cli(capsys, "realtime", str(p), "--size", f"{most // 4 + 1}x8", "--out", str(tmp_path / "rt.exr"))
    assert_one_line_refusal(rc, err, f"{(most // 4 + 1) * 4}x32", name)
    assert not (tmp_path / "rt.exr").exists()


def test_raster_texture_side_asked_from_gl(tmp_path, capsys):
    ctx = _gl_or_skip()
    most = int(ctx.info["GL_MAX_TEXTURE_SIZE"])
    wide = np.full((1, most + 1, 3), 128, np.uint8)   # one grey row: a few hundred bytes as PNG
    p = quad_asset(tmp_path / "wide.gltf", {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}},
                   [(wide, None)])
    rc, err = cli(capsys, "realtime", str(p), "--size", "8x8", "--out", str(tmp_path / "rt.exr"))
    assert_one_line_refusal(rc, err, f"/images/0: a {most + 1}x1 texture", f"GL_MAX_TEXTURE_SIZE of {most}")
    assert not (tmp_path / "rt.exr").exists()


def test_limit_flags_on_every_command_that_reads_a_scene():
    import argparse

    from pbrcheck.cli import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    for name in ("check-scene", "reference", "realtime", "export", "render", "report", "corpus"):
        flags = {o for a in sub.choices[name]._actions for o in a.option_strings}
        assert {lim.flag for lim in limits.LIMITS.values()} <= flags, name
