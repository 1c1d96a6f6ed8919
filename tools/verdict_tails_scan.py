"""Print the heavy-tail bound of the verdict rule (compare.verdict_spp.floor_tail_rse) for every
reference EXR under the given render caches: which cached pilots and finals the rule would trust.

    .venv/bin/python tools/verdict_tails_scan.py CACHE_DIR [CACHE_DIR ...] [--scenes spheres,grazing]

One line per render (scene, size, spp, seed, replicates, the first 8 digits of its cache key: scenes
of one name may differ, e.g. a test's variant): the floor's relative standard
error bound ``sqrt(2 / (dof n_eff))`` over the image's valid pixels (the reference compared with
itself, so every pixel the comparator keeps counts), for the ``mse`` and ``relmse`` metrics, and
whether it exceeds ``FLOOR_RSE_MAX``. Reads only; renders nothing.
"""

from __future__ import annotations

import argparse
import glob
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from compare.verdict_spp import FLOOR_RSE_MAX, floor_tail_rse  # noqa: E402
from pbrcheck.exr import read_exr  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("caches", nargs="+")
    ap.add_argument("--scenes", default="", help="comma-separated scene names (default: all)")
    a = ap.parse_args(argv)
    want = {s for s in a.scenes.split(",") if s}
    seen = {}
    for c in a.caches:
        for f in sorted(glob.glob(os.path.join(c, "reference", "*", "*.exr"))):
            try:
                im = read_exr(f)
            except Exception:  # a file being written by another process, or not an EXR: skip it
                continue
            m = im.meta
            if im.variance is None or (want and m.get("scene") not in want):
                continue
            key = (m.get("scene"), im.rgb.shape[1], im.rgb.shape[0], m.get("spp"), m.get("seed"),
                   m.get("replicates", "-"), m.get("mode"), os.path.basename(f)[:8])  # the cache key: one render
            if key in seen:
                continue
            seen[key] = (floor_tail_rse(im, [im]), floor_tail_rse(im, [im], metric="relmse"))
    print(f"# FLOOR_RSE_MAX = {FLOOR_RSE_MAX}")
    print("scene\tWxH\tspp\tseed\treplicates\tmode\tkey\trse_mse\trse_relmse\tflagged(mse)")
    for k, (r, rr) in sorted(seen.items(), key=lambda kv: tuple(str(x) for x in kv[0])):
        print(f"{k[0]}\t{k[1]}x{k[2]}\t{k[3]}\t{k[4]}\t{k[5]}\t{k[6]}\t{k[7]}\t{r:.3f}\t{rr:.3f}\t{'yes' if r > FLOOR_RSE_MAX else 'no'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
