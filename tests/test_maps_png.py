"""compare.maps.png_bytes: images written without a matplotlib figure, the pixels pyplot.imsave wrote."""

from __future__ import annotations

import io

import numpy as np
from PIL import Image

from compare.maps import _save_rgb, false_colour, png_bytes, pyplot


def test_png_bytes_are_pyplot_imsaves_pixels(tmp_path):
    rng = np.random.default_rng(0)
    x = rng.random((9, 7, 3)) * 1.2 - 0.1  # out of range both ways: clipped
    x[0, 0] = [1.0, 0.0, 0.5]
    x[0, 1] = [0.999, 1 / 255, 254.5 / 255]  # truncated, not rounded
    buf = io.BytesIO()
    pyplot().imsave(buf, np.clip(x, 0.0, 1.0), format="png")
    want = np.array(Image.open(io.BytesIO(buf.getvalue())))
    got = np.array(Image.open(io.BytesIO(png_bytes(x))))
    assert got.shape == (9, 7, 4) and got.dtype == np.uint8
    np.testing.assert_array_equal(got, want)
    assert list(got[0, 1, :3]) == [254, 1, 254]
    path = _save_rgb(tmp_path / "m.png", false_colour(x[..., 0], 1.0, "magma", x[..., 1] > 0.5))
    img = np.array(Image.open(path))
    assert img.shape == (9, 7, 4) and (img[x[..., 1] <= 0.5][:, :3] == 89).all()  # MASKED_GREY 0.35 -> 89
