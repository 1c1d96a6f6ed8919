"""A renderer's timings split into precompute and per-frame cost.

API
---
- :func:`split_timings` -- (precompute seconds, frame seconds) of a pass -> seconds dict.
- :func:`image_timings` -- the same from a rendered image's ``timings`` metadata.
- :data:`FRAME_KEYS`, :data:`TOTAL_KEYS` -- the key substrings that decide the split.

Used by the sweep, the report and the corpus runner (moved here from ``compare.report.sweep``,
which re-exports the names).
"""

from __future__ import annotations

#: Timing keys (substrings) that belong to the per-frame cost; every other pass is precompute
#: (prefiltering, irradiance, LUT, shader compile...). An explicit ``frame``/``frame_s`` key wins.
FRAME_KEYS = ("frame", "draw", "shade", "render")
#: Timing keys that are totals of other keys and must not be summed again.
TOTAL_KEYS = ("total",)


def split_timings(timings: dict | None) -> tuple[float | None, float | None]:
    """(precompute seconds, frame seconds) from a pass -> seconds dict (see :data:`FRAME_KEYS`)."""
    if not timings:
        return None, None
    t = {k: float(v) for k, v in timings.items() if isinstance(v, (int, float)) and not isinstance(v, bool)}
    for k in ("frame", "frame_s", "frame_seconds"):
        if k in t:
            frame = t[k]
            pre = sum(v for kk, v in t.items() if kk != k and not any(x in kk.lower() for x in FRAME_KEYS + TOTAL_KEYS))
            return pre, frame
    frame = sum(v for k, v in t.items() if any(x in k.lower() for x in FRAME_KEYS)
                and not any(x in k.lower() for x in TOTAL_KEYS))
    pre = sum(v for k, v in t.items() if not any(x in k.lower() for x in FRAME_KEYS + TOTAL_KEYS))
    return pre, frame


def image_timings(img) -> tuple[float | None, float | None]:
    """(precompute seconds, frame seconds) of a rendered image's ``timings`` metadata (None where absent)."""
    try:
        timings = img.meta_json("timings", {})
    except (ValueError, TypeError):
        timings = {}
    return split_timings(timings if isinstance(timings, dict) else {})


def timed_on(img) -> dict:
    """``{"gl_renderer", "timing_clock"}`` of a real-time image's metadata (what its times mean)."""
    return {"gl_renderer": img.meta.get("gl_renderer", "?"), "timing_clock": img.meta.get("timing_clock", "wall")}


def timed_on_label(rows: list[dict]) -> str:
    """``"on <GL renderer> (<clock>)"`` for the rows' timings ("" when no row says)."""
    seen = sorted({(r["gl_renderer"], r.get("timing_clock", "wall")) for r in rows if r.get("gl_renderer")})
    return "; ".join(f"on {g} ({c.replace('_', ' ')})" for g, c in seen)
