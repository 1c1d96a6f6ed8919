"""``pbrcheck energy``: the engines' multiple-scattering energy compensations against the truth.

The truth is the reference's random walk (``[brdf] multiscatter = "random_walk"``, Heitz et al.
2016): its directional albedo (specular lobe, grey Schlick F0) is estimated from the walk's exact
throughput (:func:`compare.renderers.multiscatter_albedo`). Each real-time compensation
(:data:`realtime.registry.ENERGY_COMPENSATIONS`, formulas in :mod:`pbrcheck.energy`) predicts that
albedo from the single-scattering DFG terms ``A, B`` (:func:`pbrcheck.brdf.specular_dfg`, the exact
quadrature the DFG LUT approximates) under a white furnace (irradiance E(n)/pi = 1):
:func:`realtime.dispatch.specular_albedo_compensated`. The grid is roughness x F0 x n.v; the
summary gives each compensation's max and mean absolute error and its worst configuration.

Images (optional): each scene rendered by the real-time preset with each compensation, compared with
the random_walk reference and with the single-scattering reference (so the share of an error that
is the reference's missing physics is visible), and, for the furnace, every sphere's mean radiance.

API
---
:data:`DEFAULT_ROUGHNESS`, :data:`DEFAULT_F0`, :data:`DEFAULT_NOV`, :class:`CompensationSummary`,
:class:`ImageRow`, :class:`EnergyResult`, :func:`run_energy`, :func:`write_energy`,
:func:`table_markdown`, :func:`plot_energy`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from pbrcheck import brdf as _brdf
from pbrcheck.atomic import write_text_atomic
from pbrcheck.fmt import TABLE_DIGITS, format_value
from pbrcheck.jsonio import write_json_atomic
from pbrcheck.progress import Progress
from realtime.dispatch import specular_albedo_compensated
from realtime.registry import ENERGY_COMPENSATIONS
from pbrcheck.scene import load_scene

from .. import renderers
from ..maps import pyplot, save_figure, write_tonemapped
from ..metrics import compare_images

DEFAULT_ROUGHNESS = tuple(round(x, 3) for x in np.linspace(0.0, 1.0, 11))
DEFAULT_F0 = (0.04, 0.25, 0.5, 0.75, 1.0)
DEFAULT_NOV = (0.05, 0.1, 0.2, 0.35, 0.5, 0.7, 0.85, 1.0)
#: Walks per grid point: standard error <= 1e-3 (the throughput lies in [0, 1]).
DEFAULT_SAMPLES = 1 << 16
DEFAULT_SCENES = ("furnace", "spheres")
IMAGE_METRICS = ("relmse", "mean_abs", "flip_mean")


def _fmt(v) -> str:
    return format_value(v, TABLE_DIGITS)


@dataclass
class CompensationSummary:
    """One compensation's directional-albedo error against the walk over the grid (absolute,
    compensated - walk), its worst configuration, and per roughness the max |error|."""

    compensation: str
    max_abs: float
    mean_abs: float
    mean_signed: float
    worst: dict
    max_abs_per_roughness: list


@dataclass
class ImageRow:
    """One real-time render (``compensation``) of ``scene`` against the random_walk reference and
    the single-scattering reference (``compensation`` "reference: single scattering" compares the
    two references). ``sphere_means``: furnace only, mean radiance of each object."""

    scene: str
    compensation: str
    vs_random_walk: dict
    vs_single: dict | None
    sphere_means: list | None = None
    png: str | None = None


@dataclass
class EnergyResult:
    """The whole measurement; ``walk``/``walk_se``/``albedo[c]`` are nested lists indexed
    [roughness][F0][n.v]."""

    roughness: list
    f0: list
    nov: list
    samples: int
    walk: list
    walk_se: list
    single: list
    albedo: dict
    summaries: list
    images: list = field(default_factory=list)
    settings: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        return asdict(self)

    def best(self) -> str:
        """The compensation with the lowest mean absolute albedo error."""
        return min(self.summaries, key=lambda s: s.mean_abs).compensation


def _albedo_grid(roughness, f0, nov, samples, seed):
    R, F, M = np.meshgrid(np.asarray(roughness, float), np.asarray(f0, float), np.asarray(nov, float), indexing="ij")
    A = np.zeros(R.shape)
    B = np.zeros(R.shape)
    for i, r in enumerate(roughness):
        for k, m in enumerate(nov):
            A[i, :, k], B[i, :, k] = _brdf.specular_dfg(m, r)
    walk, se = renderers.multiscatter_albedo(M, R, F, samples=samples, seed=seed)
    return R, F, M, A, B, walk, se


def _summary(name, err, R, F, M, roughness):
    a = np.abs(err)
    w = np.unravel_index(int(np.argmax(a)), a.shape)
    return CompensationSummary(
        compensation=name, max_abs=float(a.max()), mean_abs=float(a.mean()), mean_signed=float(err.mean()),
        worst={"roughness": float(R[w]), "f0": float(F[w]), "nov": float(M[w]), "error": float(err[w])},
        max_abs_per_roughness=[float(a[i].max()) for i in range(len(roughness))])


def _sphere_means(img) -> list:
    obj = img.channels["object"]
    cov = img.channels["coverage"] >= 1.0
    rgb = img.rgb.mean(-1)
    return [float(rgb[(obj == k) & cov].mean()) if np.any((obj == k) & cov) else None
            for k in range(int(obj.max()) + 1)]


def _images(scenes, *, preset, options, spp, size, out_dir, progress, context):
    def _metrics(r, t) -> dict:
        return compare_images(r, t, noise=False, flip_cache=context.flip_cache).metrics

    rows: list[ImageRow] = []
    comps = ENERGY_COMPENSATIONS.names
    with Progress("energy images", total=len(scenes) * (2 + len(comps)), enabled=progress) as prog:
        for name in scenes:
            s = load_scene(name)
            if size:
                s = s.with_camera(width=max(1, round(size * s.camera.width / s.camera.height)), height=size)
            s_rw = replace(s, brdf=replace(s.brdf, multiscatter="random_walk"))
            ref_rw = renderers.render_reference(s_rw, spp=spp, use_cache=True, progress=False)
            prog.update(1, f"{name}: reference random_walk")
            ref_ss = renderers.render_reference(s, spp=spp, use_cache=True, progress=False)
            prog.update(1, f"{name}: reference single scattering")
            furnace = name == "furnace"
            png = None
            if out_dir is not None:
                png = f"energy_{name}_reference_random_walk.png"
                write_tonemapped(out_dir / png, ref_rw.rgb)
                write_tonemapped(out_dir / f"energy_{name}_reference_single.png", ref_ss.rgb)
            rows.append(ImageRow(name, "reference: random_walk", {}, _metrics(ref_ss, ref_rw),
                                 _sphere_means(ref_rw) if furnace else None, png))
            rows.append(ImageRow(name, "reference: single scattering",
                                 _metrics(ref_rw, ref_ss), {},
                                 _sphere_means(ref_ss) if furnace else None,
                                 f"energy_{name}_reference_single.png" if out_dir is not None else None))
            for c in comps:
                img = renderers.render_under_test(s, preset, {**options, "energy_compensation": c},
                                                  context=context)
                png = None
                if out_dir is not None:
                    png = f"energy_{name}_{c}.png"
                    write_tonemapped(out_dir / png, img.rgb)
                rows.append(ImageRow(name, c, _metrics(ref_rw, img),
                                     _metrics(ref_ss, img),
                                     _sphere_means(img) if furnace else None, png))
                prog.update(1, f"{name}: {c}")
    return rows


def run_energy(*, roughness=DEFAULT_ROUGHNESS, f0=DEFAULT_F0, nov=DEFAULT_NOV, samples: int = DEFAULT_SAMPLES,
               seed: int = 0, images: bool = True, scenes=DEFAULT_SCENES, preset: str = "default",
               options: dict | None = None, spp: int = 128, size: int | None = 64, out_dir: Path | None = None,
               progress: bool = False, context: renderers.RenderContext = renderers.DIRECT) -> EnergyResult:
    """Measure every compensation against the random walk (module docstring).

    Parameters
    ----------
    roughness, f0, nov : sequences of float
        The albedo grid.
    samples, seed : int
        Walks per grid point and the walks' hash seed.
    images : bool
        Also render ``scenes`` (the reference with and without the walk, the preset with each
        compensation) at image height ``size`` (None: the scene's own) and ``spp``.
    preset, options
        The real-time preset and option overrides of the image renders.
    out_dir : Path, optional
        Where the images' PNGs go (none written without it).

    Returns
    -------
    EnergyResult

    Raises
    ------
    PbrcheckError
        A bad preset, option or scene name; a renderer's failure.
    """
    roughness, f0, nov = [list(map(float, x)) for x in (roughness, f0, nov)]
    if out_dir is not None:
        Path(out_dir).mkdir(parents=True, exist_ok=True)
    R, F, M, A, B, walk, se = _albedo_grid(roughness, f0, nov, samples, seed)
    albedo, summaries = {}, []
    for c in ENERGY_COMPENSATIONS.names:
        alb = specular_albedo_compensated(F, A, B, R, c)
        albedo[c] = alb.tolist()
        summaries.append(_summary(c, alb - walk, R, F, M, roughness))
    rows = _images(list(scenes), preset=preset, options=dict(options or {}), spp=spp, size=size,
                   out_dir=Path(out_dir) if out_dir is not None else None, progress=progress,
                   context=context) if images else []
    return EnergyResult(roughness, f0, nov, int(samples), walk.tolist(), se.tolist(), (F * A + B).tolist(), albedo,
                        summaries, rows, {"seed": seed, "preset": preset, "options": dict(options or {}), "spp": spp,
                                           "size": size, "scenes": list(scenes) if images else []})


def table_markdown(res: EnergyResult) -> str:
    """The summary table, the per-roughness table and (with images) the image table, as Markdown."""
    lines = [f"Directional albedo against the random walk ({len(res.roughness)} roughness x {len(res.f0)} F0 x "
             f"{len(res.nov)} n.v, {res.samples} walks each, max standard error "
             f"{_fmt(float(np.max(res.walk_se)))})", "",
             "| compensation | max abs error | mean abs error | mean signed error | worst (roughness, F0, n.v: error) |",
             "| --- | --- | --- | --- | --- |"]
    for s in res.summaries:
        w = s.worst
        lines.append(f"| {s.compensation} | {_fmt(s.max_abs)} | {_fmt(s.mean_abs)} | {_fmt(s.mean_signed)} | "
                     f"{w['roughness']:.3g}, {w['f0']:.3g}, {w['nov']:.3g}: {_fmt(w['error'])} |")
    lines += ["", "Max |albedo error| per roughness (over F0 and n.v)", "",
              "| roughness | " + " | ".join(s.compensation for s in res.summaries) + " |",
              "| --- |" + " --- |" * len(res.summaries)]
    for i, r in enumerate(res.roughness):
        lines.append(f"| {r:.3g} | " + " | ".join(_fmt(s.max_abs_per_roughness[i]) for s in res.summaries) + " |")
    if res.images:
        lines += ["", f"Images ({res.settings.get('preset')}, {res.settings.get('spp')}-spp references): "
                  "metrics against the random_walk reference | against the single-scattering reference", "",
                  "| scene | render | " + " | ".join(f"{m} (walk)" for m in IMAGE_METRICS) + " | "
                  + " | ".join(f"{m} (single)" for m in IMAGE_METRICS) + " |",
                  "| --- | --- |" + " --- |" * (2 * len(IMAGE_METRICS))]
        for r in res.images:
            a = [_fmt(r.vs_random_walk.get(m)) if r.vs_random_walk else "-" for m in IMAGE_METRICS]
            b = [_fmt(r.vs_single.get(m)) if r.vs_single else "-" for m in IMAGE_METRICS]
            lines.append(f"| {r.scene} | {r.compensation} | " + " | ".join(a + b) + " |")
        fr = [r for r in res.images if r.sphere_means]
        if fr:
            lines += ["", "Furnace: mean radiance of each sphere (white metal, white environment: 1 is exact)", "",
                      "| render | " + " | ".join(f"sphere {k}" for k in range(len(fr[0].sphere_means))) + " |",
                      "| --- |" + " --- |" * len(fr[0].sphere_means)]
            for r in fr:
                lines.append(f"| {r.compensation} | " + " | ".join(_fmt(v) for v in r.sphere_means) + " |")
    return "\n".join(lines) + "\n"


def plot_energy(res: EnergyResult, path: Path) -> str:
    """Two panels: albedo against roughness at n.v nearest 0.5 (walk with 2-sigma bars, each
    compensation) for F0 = 1 and the F0 nearest 0.5; max |error| per roughness per compensation."""
    plt = pyplot()
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4.2))
    r = np.asarray(res.roughness)
    k = int(np.argmin(np.abs(np.asarray(res.nov) - 0.5)))
    walk = np.asarray(res.walk)
    se = np.asarray(res.walk_se)
    fsel = sorted({int(np.argmin(np.abs(np.asarray(res.f0) - 1.0))), int(np.argmin(np.abs(np.asarray(res.f0) - 0.5)))})
    styles = ("-", "--")
    for j, ls in zip(fsel, styles):
        ax.errorbar(r, walk[:, j, k], yerr=2 * se[:, j, k], fmt="ko", ms=4, capsize=2,
                    label=f"random walk, F0 = {res.f0[j]:.2g}")
        for i, c in enumerate(res.albedo):
            ax.plot(r, np.asarray(res.albedo[c])[:, j, k], ls, color=f"C{i}", lw=1.2,
                    label=f"{c}, F0 = {res.f0[j]:.2g}")
    ax.set_xlabel("roughness")
    ax.set_ylabel(f"directional albedo at n.v = {res.nov[k]:.2g}")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=6.5, ncol=2)
    for i, s in enumerate(res.summaries):
        bx.plot(r, s.max_abs_per_roughness, "o-", color=f"C{i}", ms=3, label=f"{s.compensation} (mean {_fmt(s.mean_abs)})")
    bx.set_xlabel("roughness")
    bx.set_ylabel("max |albedo - walk| over F0 and n.v")
    bx.grid(alpha=0.3)
    bx.legend(fontsize=7)
    return save_figure(fig, path)


def write_energy(res: EnergyResult, out_dir: Path) -> dict[str, Path]:
    """``energy.json``, ``energy.md`` and ``energy.png`` in ``out_dir`` (atomic writes)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = {"json": write_json_atomic(out_dir / "energy.json", res)}
    md = out_dir / "energy.md"
    write_text_atomic(md, table_markdown(res))
    paths["table"] = md
    paths["plot"] = out_dir / plot_energy(res, out_dir / "energy.png")
    return paths
