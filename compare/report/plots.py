"""The report's matplotlib plots of one scene (PNG files beside the page).

API
---
- :func:`plot_materials` -- error against roughness and metallic (a sphere grid), one line per renderer.
- :func:`plot_ndotv` -- error against NdotV (binned), one line per renderer.
- :func:`plot_convergence` -- the reference's convergence study (log-log) with each renderer's MSE.

Each returns the PNG's file name (:func:`compare.maps.save_figure`), or None when there is nothing to
plot. The speed-against-error plot is :func:`compare.report.sweep.plot_speed_error`.
"""

from __future__ import annotations

import math
from pathlib import Path

from ..maps import pyplot, save_figure


def plot_materials(path: Path, scene, per_preset: dict[str, dict]) -> str | None:
    """Error against roughness (mean over the grid's metallic rows) and against metallic (mean over
    roughness columns), for relmse and flip_mean, one line per preset."""
    if not scene.grids:
        return None
    plt = pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(10, 7))
    for gi, g in enumerate(scene.grids):
        rows, cols, first = g["rows"], g["columns"], g["first_id"]
        for preset, objs in per_preset.items():
            for mi, metric in enumerate(("relmse", "flip_mean")):
                val = lambda r, c: (objs.get(first + r * cols + c) or {}).get(metric)  # noqa: E731
                rough = [scene.objects[first + c].material.roughness for c in range(cols)]
                met = [scene.objects[first + r * cols].material.metallic for r in range(rows)]
                by_r = [_mean([val(r, c) for r in range(rows)]) for c in range(cols)]
                by_m = [_mean([val(r, c) for c in range(cols)]) for r in range(rows)]
                lab = preset if len(scene.grids) == 1 else f"{preset} (grid {gi})"
                axes[mi][0].plot(rough, by_r, "-o", ms=3, label=lab)
                axes[mi][1].plot(met, by_m, "-o", ms=3, label=lab)
    for mi, metric in enumerate(("relmse", "flip_mean")):
        for j, xl in enumerate(("roughness", "metallic")):
            ax = axes[mi][j]
            ys = [y for line in ax.get_lines() for y in line.get_ydata() if math.isfinite(y)]
            if ys and min(ys) > 0:
                ax.set_yscale("log")
            ax.set_xlabel(xl)
            ax.set_ylabel(f"{metric} (mean over the other axis)")
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7)
    return save_figure(fig, path)


def _mean(xs):
    xs = [x for x in xs if x is not None and math.isfinite(x)]
    return sum(xs) / len(xs) if xs else float("nan")


def plot_ndotv(path: Path, per_preset: dict[str, list]) -> str | None:
    """Error against NdotV (binned), one line per preset; the PNG's name, or None without bins."""
    if not any(per_preset.values()):
        return None
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8))
    for preset, bins in per_preset.items():
        xs = [(b["lo"] + b["hi"]) / 2 for b in bins if b["pixels"]]
        for ax, metric in zip(axes, ("relmse", "flip_mean")):
            ax.plot(xs, [b["metrics"][metric] for b in bins if b["pixels"]], "-o", ms=3, label=preset)
    for ax, metric in zip(axes, ("relmse", "flip_mean")):
        ax.set_xlabel("NdotV")
        ax.set_ylabel(metric)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    return save_figure(fig, path)


def plot_convergence(path: Path, conv: list[dict], top_spp: int, floor: float | None,
                     preset_mse: dict[str, float]) -> str | None:
    """MSE of lower-spp references against the report's reference (log-log) with the variance
    prediction, the noise floor and each preset's MSE; the PNG's name, or None without data."""
    if not conv:
        return None
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    spps = [c["spp"] for c in conv]
    ax.loglog(spps, [max(c["mse"], 1e-30) for c in conv], "-o", label=f"MSE of n spp vs {top_spp} spp")
    if all(c["expected"] is not None for c in conv):
        ax.loglog(spps, [c["expected"] for c in conv], "--", color="gray",
                  label="expected from variances (unbiased)")
    if floor is not None:
        ax.axhline(floor, color="tab:green", lw=1, label=f"noise floor of the {top_spp}-spp reference")
    for i, (p, mse) in enumerate(preset_mse.items()):
        if mse is not None and mse > 0:
            ax.axhline(mse, color=f"C{(i + 3) % 10}", ls=":", lw=1, label=p)
    ax.set_xlabel("reference samples per pixel")
    ax.set_ylabel("MSE over valid pixels")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    return save_figure(fig, path)


__all__ = ["plot_convergence", "plot_materials", "plot_ndotv"]
