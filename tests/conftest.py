"""Shared test fixtures.

* ``envmap``: path of a real HDR environment in ``../shared/envmaps`` (skips cleanly when absent,
  as on a user's fresh clone; they are never copied into the repository).
* ``tmp_cache``: points ``PBRCHECK_CACHE`` at a per-test directory.
* ``lobes_unmodelled``: the honesty contract with the glTF lobes unmodelled (its own tests).
* ``transmission_unmodelled``: the same with the transmission extensions unmodelled.
"""

from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
ENVMAPS = ROOT.parent / "shared" / "envmaps"


@pytest.fixture
def envmap():
    def get(name: str) -> Path:
        p = ENVMAPS / name
        if not p.is_file():
            pytest.skip(f"{p} is absent (real HDR environments live in ../shared/envmaps)")
        return p

    return get


@pytest.fixture
def tmp_cache(tmp_path, monkeypatch):
    d = tmp_path / "cache"
    monkeypatch.setenv("PBRCHECK_CACHE", str(d))
    return d


@pytest.fixture
def lobes_unmodelled(monkeypatch):
    """The honesty contract as it stood before the renderers rendered the glTF lobes
    (``MODELLED_LOBE_EXTENSIONS`` empty): the contract's tests use the lobes as their unmodelled
    material extensions, built with a known answer, so they keep testing the mechanism (naming,
    stripping, the gate's verdict) whatever the renderers model today."""
    import compare.report.lobes_section as lobes_section
    import pbrcheck.export as export
    import pbrcheck.gltf as gltf
    import pbrcheck.lobe_params as lp
    import pbrcheck.unmodelled as unmodelled

    lobes = set(lp.LOBE_EXTENSIONS)
    without = tuple(e for e in gltf.MODELLED_EXTENSIONS if e not in lobes)
    for mod, name, value in ((lp, "MODELLED_LOBE_EXTENSIONS", ()), (unmodelled, "MODELLED_LOBE_EXTENSIONS", ()),
                             (lobes_section, "MODELLED_LOBE_EXTENSIONS", ()), (gltf, "MODELLED_EXTENSIONS", without),
                             (gltf, "SUPPORTED_EXTENSIONS", without), (export, "SUPPORTED_EXTENSIONS", without)):
        monkeypatch.setattr(mod, name, value)


@pytest.fixture
def transmission_unmodelled(monkeypatch):
    """The honesty contract as it stood before both renderers rendered the transmission extensions
    (``MODELLED_TRANSMISSION_EXTENSIONS`` empty): the contract's tests that use transmission as their
    unmodelled extension (naming, the path-mode-only wording, stripping, ``--keep-unmodelled``) keep
    testing the mechanism whatever the renderers model today. The loader's cache is emptied for the
    test (an asset loaded under one contract keeps that contract's records)."""
    import pbrcheck.export as export
    import pbrcheck.gltf as gltf
    import pbrcheck.transmission_params as tp
    import pbrcheck.unmodelled as unmodelled

    trans = set(tp.TRANSMISSION_EXTENSIONS)
    without = tuple(e for e in gltf.MODELLED_EXTENSIONS if e not in trans)
    for mod, name, value in ((tp, "MODELLED_TRANSMISSION_EXTENSIONS", ()),
                             (unmodelled, "MODELLED_TRANSMISSION_EXTENSIONS", ()), (gltf, "MODELLED_EXTENSIONS", without),
                             (gltf, "SUPPORTED_EXTENSIONS", without), (export, "SUPPORTED_EXTENSIONS", without),
                             (gltf, "_CACHE", {})):
        monkeypatch.setattr(mod, name, value)
