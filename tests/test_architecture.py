"""Pieces the architecture issue made explicit: strict uniforms, the one JSON writer, the one value
formatter, display transforms applied to what the report shows (never to what it measures)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from compare.maps import display_rgb, tonemap, tonemap_aces
from pbrcheck.fmt import TABLE_DIGITS, format_value
from pbrcheck.jsonio import dump_json, write_json_atomic


def test_setting_a_uniform_the_program_lacks_raises_unless_optional():
    from realtime.gl import compute_program
    from realtime.render import UniformError, _set

    prog = compute_program("kd_lut.comp")
    _set(prog, "lut_size", 8)  # present: fine
    with pytest.raises(UniformError, match="lut_sizee"):
        _set(prog, "lut_sizee", 8)
    _set(prog, "lut_sizee", 8, optional=True)  # declared optional: ignored


def test_json_writer_is_strict_and_atomic(tmp_path):
    from compare.research.results import HardcaseRow

    row = HardcaseRow("c", "realtime", "default", finite=True, nonfinite=0, metrics={"relmse": float("nan")})
    text = dump_json({"rows": [row], "x": float("inf"), "t": (1, 2)})
    d = json.loads(text)
    assert d == {"rows": [{"case": "c", "renderer": "realtime", "preset": "default", "finite": True,
                           "nonfinite": 0, "metrics": {"relmse": None}, "error": None}], "x": None, "t": [1, 2]}
    p = write_json_atomic(tmp_path / "a" / "b.json", {"v": 1.5})
    assert p.read_text() == '{\n  "v": 1.5\n}\n'
    assert [f.name for f in p.parent.iterdir()] == ["b.json"]  # no temporary file left


@pytest.mark.parametrize("v,digits,want", [
    (None, 6, "n/a"), (float("nan"), 6, "n/a"), (float("inf"), 6, "inf"), (-math.inf, 6, "-inf"),
    (0.00146863123, 6, "0.00146863"), (0.00146863123, TABLE_DIGITS, "0.001469"), (12345678, 4, "12345678"),
    ("lut", 4, "lut"),
])
def test_one_formatter(v, digits, want):
    assert format_value(v, digits) == want


def test_display_transform_follows_the_presets_options():
    rng = np.random.default_rng(0)
    rgb = rng.random((4, 5, 3)) * 3.0
    # No options (the reference) and tonemap=none: the report's filmic curve.
    assert np.array_equal(display_rgb(rgb), tonemap(rgb))
    assert np.array_equal(display_rgb(rgb, {"tonemap": "none", "exposure": 1.0}), tonemap(rgb))
    # Exposure scales the radiance before the curve.
    assert np.allclose(display_rgb(rgb, {"tonemap": "none", "exposure": 2.0}), tonemap(2.0 * rgb))
    # aces: article 002's fit, then the sRGB transfer function.
    aces = display_rgb(rgb, {"tonemap": "aces", "exposure": 1.0})
    lin = tonemap_aces(rgb)
    assert np.allclose(aces, np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * lin ** (1 / 2.4) - 0.055))
    assert not np.allclose(aces, tonemap(rgb))
    assert aces.min() >= 0.0 and aces.max() <= 1.0


def test_tonemap_aces_known_values():
    """Article 002's toneMapACES: 0 -> 0 (clamped), large -> ~1 (the fit saturates), monotone."""
    x = np.linspace(0, 50, 200)[:, None] * np.ones((1, 3))
    y = tonemap_aces(x)[:, 0]
    assert y[0] == pytest.approx(0.0, abs=1e-3) and y[-1] == pytest.approx(1.0, abs=0.02)
    assert np.all(np.diff(y) >= -1e-12)


def test_every_python_package_is_in_the_distribution():
    """pyproject lists its packages explicitly: a new sub-package missing there imports fine from an
    editable checkout but is absent from a wheel (compare.research and compare.report once were)."""
    import tomllib
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    listed = set(tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {".".join(p.parent.relative_to(root).parts)
             for top in ("pbrcheck", "reference", "realtime", "compare", "clients")
             for p in (root / top).rglob("__init__.py")
             if "node_modules" not in p.parts and not any(q.startswith(".") for q in p.relative_to(root).parts)}
    assert found - listed == set(), f"packages missing from pyproject.toml: {sorted(found - listed)}"
