"""EXR IO, the render cache, the shared camera, set-up helpers."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import pbrcheck
from pbrcheck.cache import Cache, cache_key, cache_root
from pbrcheck.camera import camera_frame, primary_rays, projection_matrix, view_matrix
from pbrcheck.errors import ImageIOError
from pbrcheck.exr import AOVS, Image, read_exr, write_exr
from pbrcheck.scene import Camera

ROOT = Path(__file__).resolve().parents[1]


def _image(h=6, w=7, seed=0):
    rng = np.random.default_rng(seed)
    extra = {c: rng.random((h, w)) for c in AOVS}
    extra["object"] = np.where(rng.random((h, w)) > 0.5, 3.0, -1.0)
    return Image.from_rgb(rng.random((h, w, 3)) * 1e5, {"scene_hash": "f" * 64, "spp": 16,
                                                        "big": str(2 ** 70)}, **extra)


def test_exr_round_trip_channels_and_metadata(tmp_path):
    img = _image()
    p = write_exr(tmp_path / "a.exr", img)
    back = read_exr(p, require=("R", "G", "B") + AOVS)
    for k, v in img.channels.items():
        np.testing.assert_array_equal(back.channels[k], v)
    assert back.meta["scene_hash"] == "f" * 64
    assert back.meta["spp"] == "16"
    assert int(back.meta["big"]) == 2 ** 70  # large ints survive as strings
    assert back.meta_json("spp") == 16


def test_exr_is_zip_compressed_and_readable_by_mitsuba(tmp_path):
    import OpenEXR

    p = write_exr(tmp_path / "a.exr", _image())
    with OpenEXR.File(str(p)) as f:
        assert f.header()["compression"] == OpenEXR.ZIP_COMPRESSION
    import mitsuba as mi

    assert (mi.Bitmap(str(p)).width(), mi.Bitmap(str(p)).height()) == (7, 6)


def test_exr_missing_channel_and_file(tmp_path):
    p = write_exr(tmp_path / "a.exr", Image.from_rgb(np.zeros((2, 2, 3))))
    with pytest.raises(ImageIOError, match=r"a\.exr: missing channel\(s\) NdotV"):
        read_exr(p, require=("R", "NdotV"))
    with pytest.raises(ImageIOError, match="no such file"):
        read_exr(tmp_path / "nope.exr")
    bad = tmp_path / "bad.exr"
    bad.write_bytes(b"garbage")
    with pytest.raises(ImageIOError, match="bad.exr: not a readable EXR"):
        read_exr(bad)


def test_exr_write_is_atomic(tmp_path, monkeypatch):
    """A failed write leaves the previous file intact and no temporary behind."""
    p = write_exr(tmp_path / "a.exr", Image.from_rgb(np.ones((2, 2, 3))))
    import OpenEXR

    class Boom:
        def __init__(self, *a, **k):
            pass

        def __enter__(self):
            return self

        def __exit__(self, *a):
            return False

        def write(self, path):
            Path(path).write_bytes(b"partial")
            raise RuntimeError("disk full")

    monkeypatch.setattr(OpenEXR, "File", Boom)
    with pytest.raises(ImageIOError, match="cannot write"):
        write_exr(p, Image.from_rgb(np.zeros((2, 2, 3))))
    monkeypatch.undo()
    assert read_exr(p).rgb.max() == 1.0
    assert sorted(x.name for x in tmp_path.iterdir()) == ["a.exr"]


def test_cache_hit_miss_and_corruption(tmp_cache):
    assert cache_root() == tmp_cache
    c = Cache("reference")
    key = cache_key(scene="abc", spp=4)
    assert key != cache_key(scene="abc", spp=8)
    assert c.get(key) is None
    c.put(key, _image())
    got = c.get(key)
    assert got is not None and got.meta["cache_key"] == key
    # corrupt entry: a miss, and removed
    c.path(key).write_bytes(b"truncated")
    assert c.get(key) is None and not c.path(key).exists()
    # an entry stored under another key is never served
    c.put(key, _image())
    shutil.copy(c.path(key), c.path("0" * 64).parent.mkdir(parents=True, exist_ok=True) or c.path("0" * 64))
    assert c.get("0" * 64) is None


def test_camera_pixel_centres_and_fov():
    cam = Camera(origin=(0, 0, 5), target=(0, 0, 0), up=(0, 1, 0), fov=90.0, width=4, height=2)
    o, d = primary_rays(cam)
    assert d.shape == (2, 4, 3)
    # horizontal fov 90: the left edge of pixel 0 is at x_ndc = -1 -> tan = 1
    _, d_edge = primary_rays(cam, offsets=(0.0, 0.5))
    assert d_edge[0, 0, 0] / -d_edge[0, 0, 2] == pytest.approx(-1.0)
    # row 0 is the top: looking down -Z with +Y up, row 0 has positive y
    assert d[0, 0, 1] > 0 > d[1, 0, 1]
    # vertical extent follows the aspect: tan_y = tan_x * H / W = 0.5
    _, d_top = primary_rays(cam, offsets=(0.5, 0.0))
    assert d_top[0, 0, 1] / -d_top[0, 0, 2] == pytest.approx(0.5)
    r, u, f = camera_frame(cam)
    assert np.allclose(r, [1, 0, 0]) and np.allclose(u, [0, 1, 0]) and np.allclose(f, [0, 0, -1])


def test_gl_matrices_project_pixel_centres_back():
    cam = Camera(origin=(1.0, 2.0, 6.0), target=(0.2, -0.1, 0.0), up=(0, 1, 0), fov=40.0, width=64, height=48)
    o, d = primary_rays(cam)
    P = projection_matrix(cam, 0.1, 100.0) @ view_matrix(cam)
    pts = o + 3.0 * d.reshape(-1, 3)
    clip = np.c_[pts, np.ones(len(pts))] @ P.T
    ndc = clip[:, :2] / clip[:, 3:]
    # GL window coordinates: x = (ndc + 1) W / 2, y measured from the bottom
    x = (ndc[:, 0] + 1) * cam.width / 2
    y_top = cam.height - (ndc[:, 1] + 1) * cam.height / 2
    jj, ii = np.meshgrid(np.arange(cam.width) + 0.5, np.arange(cam.height) + 0.5)
    np.testing.assert_allclose(x, jj.ravel(), atol=1e-9)
    np.testing.assert_allclose(y_top, ii.ravel(), atol=1e-9)


def _dpkg_installed(*packages: str) -> bool:
    """Whether Debian's package database lists every one as installed (the target machine's set-up;
    the GPU machine unpacks its GL loaders without dpkg and has no libllvm19)."""
    if shutil.which("dpkg-query") is None:
        return False
    for p in packages:
        r = subprocess.run(["dpkg-query", "-W", "-f=${Status}", p], capture_output=True, text=True)
        if r.returncode != 0 or "install ok installed" not in r.stdout:
            return False
    return True


def test_llvm19_found_and_exported():
    if not _dpkg_installed("libllvm19"):
        pytest.skip("Debian's libllvm19 is not installed here (make setup installs it)")
    path = pbrcheck.find_llvm19()
    assert path is not None and "19" in path
    r = subprocess.run([sys.executable, "-c", "import pbrcheck, os; print(os.environ['DRJIT_LIBLLVM_PATH'])"],
                       capture_output=True, text=True, env={k: v for k, v in os.environ.items() if k != "DRJIT_LIBLLVM_PATH"})
    assert r.returncode == 0 and "19" in r.stdout


def test_setup_without_root_prints_the_apt_line(tmp_path):
    if os.geteuid() != 0 or shutil.which("setpriv") is None:
        pytest.skip("needs root to drop privileges with setpriv")
    if not _dpkg_installed("libegl1"):
        pytest.skip("Debian's libegl1 is not installed here (make setup installs it)")
    # a copy the unprivileged user can read (the checkout may sit in a private directory)
    script = Path("/tmp") / f"pbrcheck-ensure-{os.getpid()}.sh"
    shutil.copy(ROOT / "tools" / "ensure-system-packages.sh", script)
    script.chmod(0o755)
    r = subprocess.run(["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups", "bash",
                        str(script), "libegl1", "pbrcheck-no-such-package"],
                       capture_output=True, text=True)
    script.unlink()
    assert r.returncode == 1, r.stderr
    assert "apt-get install -y pbrcheck-no-such-package" in r.stderr
    assert "libegl1" not in r.stderr.split("apt-get install -y")[1]  # installed ones are not listed


def test_setup_is_a_no_op_when_installed():
    if not _dpkg_installed("libegl1", "libllvm19"):
        pytest.skip("Debian's libegl1 and libllvm19 are not installed here (make setup installs them)")
    r = subprocess.run(["bash", str(ROOT / "tools" / "ensure-system-packages.sh"), "libegl1", "libllvm19"],
                       capture_output=True, text=True)
    assert r.returncode == 0 and r.stdout == "" and r.stderr == ""
