"""Snapshot the real-time renderer's images to check a refactor changes no number.

``python tools/realtime_snapshot.py save OUT.npz`` renders every preset on every built-in scene, and
every single-option change of a choice or bool option on every preset on the furnace, at 16 x 16
with small bakes; ``python tools/realtime_snapshot.py diff A.npz B.npz`` prints the largest absolute
difference per render (and the renders only one side has: refused or failed ones).
"""

from __future__ import annotations

import sys
import time

import numpy as np

SMALL = {"cube_size": 32, "irradiance_source_size": 8, "irradiance_size": 8, "prefilter_levels": 4,
         "prefilter_samples": 64, "lut_size": 16, "lut_samples": 64, "supersample": 1, "runtime_samples": 8}
CHANNELS = ("R", "G", "B", "N.X", "N.Y", "N.Z", "NdotV", "object", "coverage")


def _cases():
    from pbrcheck.scene import builtin_scene_names
    from realtime.presets import OPTIONS, PRESETS
    for scene in builtin_scene_names():
        for preset in PRESETS:
            yield f"{scene}|{preset}|", scene, preset, {}
    for preset, values in PRESETS.items():
        for name, opt in OPTIONS.items():
            if opt.kind not in ("choice", "bool"):
                continue
            for v in (opt.choices if opt.kind == "choice" else (False, True)):
                if v != values[name]:
                    yield f"furnace|{preset}|{name}={v}", "furnace", preset, {name: v}


def save(out: str) -> None:
    from pbrcheck.errors import PbrcheckError
    from pbrcheck.scene import load_scene
    from realtime.render import render_realtime
    arrays, t0, n = {}, time.perf_counter(), 0
    for key, scene, preset, opts in _cases():
        s = load_scene(scene).with_camera(width=16, height=16)
        try:
            img = render_realtime(s, preset, {**SMALL, **opts}, progress=False)
        except (PbrcheckError, KeyError) as e:
            print(f"{key}: {type(e).__name__}: {str(e).splitlines()[0][:120]}")
            continue
        arrays[key] = np.stack([img.channels[c] for c in CHANNELS])
        n += 1
    np.savez_compressed(out, **arrays)
    print(f"{n} renders in {time.perf_counter() - t0:.0f} s -> {out}")


def diff(a: str, b: str) -> int:
    A, B = np.load(a), np.load(b)
    worst = 0.0
    for k in sorted(set(A.files) | set(B.files)):
        if k not in A.files or k not in B.files:
            print(f"{k}: only in {a if k in A.files else b}")
            continue
        d = float(np.nanmax(np.abs(A[k].astype(np.float64) - B[k])))
        same_nan = np.array_equal(np.isnan(A[k]), np.isnan(B[k]))
        worst = max(worst, d)
        if d > 0 or not same_nan:
            print(f"{k}: max |diff| {d:.3g}{'' if same_nan else ', NaN pattern differs'}")
    print(f"{len(set(A.files) & set(B.files))} renders compared; largest |diff| {worst:.3g}")
    return 0


if __name__ == "__main__":
    if sys.argv[1:2] == ["save"]:
        save(sys.argv[2])
    elif sys.argv[1:2] == ["diff"]:
        sys.exit(diff(sys.argv[2], sys.argv[3]))
    else:
        sys.exit(__doc__)
