"""The cache's usage and pruning (pbrcheck.cache.usage / prune, ``pbrcheck cache``): least recently
used first (a hit refreshes an entry), by age and by size, per namespace, dry runs, a crashed writer's
stale temporary files; bad input is exit 2 and removes nothing."""

from __future__ import annotations

import os
import time

import numpy as np
import pytest

from pbrcheck import cache
from pbrcheck.cli import main
from pbrcheck.errors import CacheError
from pbrcheck.exr import Image

DAY = 86400.0


def _put(ns: str, key: str, days_ago: float, size: int = 16) -> os.PathLike:
    c = cache.Cache(ns)
    p = c.put(cache.cache_key(k=key), Image({"x": np.arange(size * size, dtype=np.float32).reshape(size, size)}))
    t = time.time() - days_ago * DAY
    os.utime(p, (t, t))
    return p


@pytest.fixture
def filled(tmp_cache):
    paths = {"old_ref": _put("reference", "a", 30), "mid_ref": _put("reference", "b", 10),
             "new_ref": _put("reference", "c", 0.1), "old_flip": _put("flip", "d", 40), "new_rt": _put("realtime", "e", 1)}
    return tmp_cache, paths


def test_usage_per_namespace(filled):
    root, paths = filled
    u = {x.namespace: x for x in cache.usage(root)}
    assert set(u) == {"reference", "flip", "realtime"} and u["reference"].entries == 3
    assert u["reference"].bytes == sum(paths[k].stat().st_size for k in ("old_ref", "mid_ref", "new_ref"))
    assert u["flip"].oldest_use == pytest.approx(time.time() - 40 * DAY, abs=60)


def test_prune_by_age_and_namespace(filled):
    root, paths = filled
    res = cache.prune(root=root, older_than_days=20, dry_run=True)
    assert res.removed == 2 and all(p.exists() for p in paths.values())        # a dry run removes nothing
    res = cache.prune(root=root, older_than_days=20, namespaces=["reference"])
    assert res.removed == 1 and not paths["old_ref"].exists() and paths["old_flip"].exists()
    assert res.kept == 2 and res.kept_bytes == paths["mid_ref"].stat().st_size + paths["new_ref"].stat().st_size


def test_prune_by_size_removes_the_least_recently_used_and_a_hit_refreshes(filled):
    root, paths = filled
    c = cache.Cache("flip")
    assert c.get(cache.cache_key(k="d")) is not None                            # a hit: now the most recent
    one = paths["new_ref"].stat().st_size
    res = cache.prune(root=root, max_bytes=2 * one)
    assert res.removed == 3 and res.kept == 2
    assert paths["old_flip"].exists() and paths["new_ref"].exists()             # the two most recently used
    assert not any(paths[k].exists() for k in ("old_ref", "mid_ref", "new_rt"))


def test_clear_and_stale_temporary_files(filled):
    root, paths = filled
    stale = paths["new_rt"].parent / f".{paths['new_rt'].name}.abc123.tmp.exr"   # pbrcheck.atomic.temp_beside's names
    fresh = paths["new_rt"].parent / f".{paths['new_rt'].stem}.exr.def456.tmp"
    for t, age in ((stale, 2 * cache.STALE_TEMP_S), (fresh, 0)):
        t.write_bytes(b"partial")
        os.utime(t, (time.time() - age, time.time() - age))
    res = cache.prune(root=root)
    assert res.removed == 5 and res.kept == 0 and res.stale_temp_files == 1
    assert not stale.exists() and fresh.exists()                                # a live write is left alone
    assert cache.usage(root) == [] or all(u.entries == 0 for u in cache.usage(root))


def test_parse_size_and_bad_input():
    assert cache.parse_size("500M") == 500 * 2 ** 20 and cache.parse_size("2G") == 2 ** 31
    assert cache.parse_size("1.5GiB") == int(1.5 * 2 ** 30) and cache.parse_size("123") == 123
    for bad in ("lots", "-1G", "2X"):
        with pytest.raises(CacheError, match="size"):
            cache.parse_size(bad)
    with pytest.raises(CacheError, match=">= 0"):
        cache.prune(older_than_days=-1)


def test_cli(filled, capsys):
    root, paths = filled
    assert main(["cache"]) == 0
    out = capsys.readouterr().out
    assert str(root) in out and "reference" in out and "3 entries" in out
    assert main(["cache", "prune"]) == 2                                         # no limit given
    assert main(["cache", "prune", "--max-size", "lots"]) == 2
    assert main(["cache", "prune", "--older-than", "5", "--namespace", "nope"]) == 2
    assert "no cache namespace 'nope'" in capsys.readouterr().err
    assert all(p.exists() for p in paths.values())                               # bad input removed nothing
    assert main(["cache", "prune", "--older-than", "5", "--dry-run"]) == 0
    assert "would remove 3 entries" in capsys.readouterr().out
    assert main(["cache", "clear", "--namespace", "flip"]) == 0
    assert not paths["old_flip"].exists() and paths["old_ref"].exists()
