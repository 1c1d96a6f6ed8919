"""Shared test fixtures.

* ``envmap``: path of a real HDR environment in ``../shared/envmaps`` (skips cleanly when absent,
  as on a user's fresh clone; they are never copied into the repository).
* ``tmp_cache``: points ``PBRCHECK_CACHE`` at a per-test directory.
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
