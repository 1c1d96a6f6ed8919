"""HDR-FLIP maps on disk (``compare.metrics.flip_map(..., cache=True)``, ``compare_images(...,
flip_cache=True)``): a map whose two images are unchanged is read back, equal to the computed one;
any change of either image is a miss; a corrupt entry is recomputed; without the flag nothing is
read or written. And
``compare_images(flip=False, itp=False)`` skips both maps (their metrics None, the rest unchanged); flip-evaluator's OpenMP threads wait
passively unless the environment says otherwise."""

from __future__ import annotations

import os

import numpy as np
import pytest

from compare import metrics
from pbrcheck.exr import Image


@pytest.fixture
def pair():
    rng = np.random.default_rng(3)
    a = (rng.random((12, 16, 3)) ** 4 * 20).astype(np.float32)
    return a, (a * 1.1 + 0.01).astype(np.float32)


@pytest.fixture
def counted(monkeypatch):
    """Count evaluations by flip-evaluator; empty the per-process memo so only the disk can serve."""
    calls = []
    real = metrics._flip_map
    monkeypatch.setattr(metrics, "_flip_map", lambda r, t: calls.append(1) or real(r, t))
    monkeypatch.setattr(metrics, "_map_memo", {})
    return calls


def _entries(root):
    return sorted(p for p in (root / metrics.FLIP_NAMESPACE).rglob("*.exr")) if (root / metrics.FLIP_NAMESPACE).exists() else []


def test_a_stored_map_is_read_back_equal(tmp_cache, pair, counted, monkeypatch):
    a, b = pair
    m1 = metrics.flip_map(a, b, cache=True)
    assert len(counted) == 1 and len(_entries(tmp_cache)) == 1
    monkeypatch.setattr(metrics, "_map_memo", {})        # a new process: only the disk has it
    m2 = metrics.flip_map(a.copy(), b.copy(), cache=True)
    assert len(counted) == 1                             # read, not computed
    np.testing.assert_array_equal(m1, m2)
    assert m2.dtype == np.float32 and m2.shape == a.shape[:2]


def test_either_image_changed_is_a_miss(tmp_cache, pair, counted, monkeypatch):
    a, b = pair
    metrics.flip_map(a, b, cache=True)
    b2 = b.copy()
    b2[3, 4, 1] += 0.5
    metrics.flip_map(a, b2, cache=True)
    a2 = a.copy()
    a2[0, 0, 0] *= 2.0
    metrics.flip_map(a2, b, cache=True)
    assert len(counted) == 3 and len(_entries(tmp_cache)) == 3


def test_a_corrupt_entry_is_recomputed(tmp_cache, pair, counted, monkeypatch):
    a, b = pair
    m1 = metrics.flip_map(a, b, cache=True)
    (entry,) = _entries(tmp_cache)
    entry.write_bytes(b"not an exr")
    monkeypatch.setattr(metrics, "_map_memo", {})
    m2 = metrics.flip_map(a, b, cache=True)
    assert len(counted) == 2
    np.testing.assert_array_equal(m1, m2)


def test_without_the_flag_nothing_is_stored(tmp_cache, pair, counted):
    a, b = pair
    metrics.flip_map(a, b)
    metrics.flip_map(a, b * 1.5)
    assert _entries(tmp_cache) == [] and len(counted) == 2


def test_the_key_has_the_flip_version_and_code_version(tmp_cache, pair, counted, monkeypatch):
    a, b = pair
    metrics.flip_map(a, b, cache=True)
    monkeypatch.setattr(metrics, "_map_memo", {})
    monkeypatch.setattr(metrics, "FLIP_CODE_VERSION", metrics.FLIP_CODE_VERSION + 1)
    metrics.flip_map(a, b, cache=True)
    monkeypatch.setattr(metrics, "_map_memo", {})
    monkeypatch.setattr(metrics, "_flip_version", lambda: "0.0-other")
    metrics.flip_map(a, b, cache=True)
    assert len(counted) == 3


def test_compare_without_flip_and_itp(pair, counted):
    a, b = pair
    ref, test = Image.from_rgb(a), Image.from_rgb(b)
    full = metrics.compare_images(ref, test)
    lean = metrics.compare_images(ref, test, flip=False, itp=False)
    assert len(counted) == 1                              # the full comparison's map only
    for k, v in lean.metrics.items():
        if k in ("flip_mean", "delta_e_itp_mean", "delta_e_itp_p95"):
            assert v is None
        else:
            assert v == pytest.approx(full.metrics[k], rel=1e-12), k
    assert lean.maps.flip is None and lean.maps.dE is None


def test_compare_images_stores_its_maps_only_when_asked(tmp_cache, pair, counted):
    a, b = pair
    ref, test = Image.from_rgb(a), Image.from_rgb(b)
    metrics.compare_images(ref, test, noise=False)
    assert _entries(tmp_cache) == []
    metrics.compare_images(ref, Image.from_rgb(b * 1.2), noise=False, flip_cache=True)
    assert len(_entries(tmp_cache)) == 1


def test_flip_threads_wait_passively_unless_the_environment_says(monkeypatch):
    monkeypatch.delenv("OMP_WAIT_POLICY", raising=False)
    metrics._import_flip()
    assert os.environ["OMP_WAIT_POLICY"] == metrics.FLIP_OMP_WAIT_POLICY == "PASSIVE"
    monkeypatch.setenv("OMP_WAIT_POLICY", "ACTIVE")
    metrics._import_flip()
    assert os.environ["OMP_WAIT_POLICY"] == "ACTIVE"
