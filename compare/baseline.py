"""Accepted baselines of the gate: what changed since the last accepted render, and was it better or worse.

A gate check (:mod:`compare.gate`) measures (a) the accuracy of the renderer under test against the
reference (budgets) and (b) its change against the check's *accepted baseline*: the renderer's own
image when the check was last accepted (``pbrcheck gate BUDGET.toml --accept --reason "..."``).

Storage (``baselines/<check>.exr`` and ``baselines/<check>.json`` beside the budget file)
-----------------------------------------------------------------------------------------------
The baseline is the renderer's image itself (linear ``R G B`` float32, the ``object`` and
``coverage`` AOVs, and ``spread.R/G/B``: the renderer's measured run-to-run standard deviation per
pixel, zero for a bit-exact renderer), not a per-object summary: the CI scenes are small (120 x 100
and 192 x 48 pixels: 30 to 140 KB per ZIP-compressed EXR), and the pixels are what the change's noise
(``sum (t1 - t0)^2 var_ref``) and a shape change that keeps every mean (an environment rotated by
1 degree moves highlights) need, and what the before / after thumbnails show. A summary would be
~5 KB but could answer neither. The JSON sidecar holds what made it (preset, resolved options, the
shader sources' SHA-256, the hook file's SHA-256, the client and its version, the GL renderer), the
figures at acceptance and the LOD probe's response per region (the sensitivity).

Regions and statistics
----------------------
Regions are the objects (valid pixels of one object id) and the screen tiles of :data:`TILE` x
:data:`TILE` pixels holding at least :data:`MIN_TILE_PIXELS` valid pixels (a large object's local
change is not averaged away). With ``r`` the reference, ``t0`` the baseline, ``t1`` the current render,
``v`` the reference's per-pixel variance, ``s`` the renderer's run-to-run standard deviation and
``w = 1 / (r^2 + REL_EPS)`` (the relmse weight, :mod:`compare.metrics`), per region (means over its
pixels and channels, ``Y`` luminance):

- ``bias = sum(Y1 - Y0) / sum(Y0)``: the signed relative change of brightness; its noise
  ``sigma_bias = sqrt(2 sum(s_Y^2)) / sum(Y0)``.
- ``change = mean((t1 - t0)^2 w)``: the relmse between the two renders (a change that keeps the
  mean); its noise ``2 mean(s^2 w)``, with standard deviation ``2 mean(s^2 w) sqrt(2 / n)``.
- ``d_relmse = relmse(t1, r) - relmse(t0, r)``: better (< 0) or worse (> 0) against the reference;
  its noise ``sigma_d = 2 sqrt(sum((t1 - t0)^2 v w^2) + sum(((t1 - r)^2 + (t0 - r)^2) s^2 w^2)) / n``
  (first order in the reference's noise and the renderer's spread).

A region has *changed* when ``|bias| > max(GATE_Z sigma_bias, BIAS_FLOOR)`` or
``change > max(noise + GATE_Z sd, CHANGE_FLOOR)``; a changed region is *worse* when
``d_relmse > GATE_Z sigma_d`` and *better* when ``d_relmse < -GATE_Z sigma_d``. Verdict of a check:
``regressed`` when a region is worse, else ``improved`` when one is better, else ``changed`` when one
changed, else ``pass``.

Sensitivity (printed per check): the smallest uniform brightness change ``k`` detected (``t1 = (1 + k)
t0``: ``bias = k``, ``change = k^2 mean(t0^2 w)``; the smallest over the regions) and the smallest
LOD shift (from the LOD probe: a render with every prefiltered lookup :data:`LOD_PROBE` mip deeper,
made at acceptance where the renderer takes shader hooks; ``bias`` scales with the shift,
``change`` with its square).

API
---
- :func:`baseline_paths` -- the EXR and JSON of a check's baseline.
- :func:`load_baseline` -- a stored baseline (:class:`Baseline`) or None.
- :func:`compare_to_baseline` -- per-region statistics and the verdict (:class:`Change`).
- :func:`sensitivity` -- the smallest detected brightness change and LOD shift.
- :func:`region_masks` -- the objects and tiles of an image pair.
- :func:`begin_accept`, :func:`stage_baseline`, :func:`commit_accept`, :func:`abandon_accept` -- an
  accept: stage every baseline and the budget's new text, then switch them in one rename.
- :func:`finish_accepts` -- complete a committed accept a stop interrupted (run by every read).
- :func:`spread_of` -- the per-pixel run-to-run standard deviation of repeated renders.
- :func:`shader_sources_hash` -- SHA-256 over every file the GL programs read
  (:func:`realtime.gl.shader_sources_hash`: one rule for the baselines and the real-time cache).
- :data:`LOD_PROBE_HOOK` -- the hook file text of the LOD probe.

References: the significance test is a z-test on first-order noise propagation (the delta method);
golden-image CI for comparison: Filament's renderdiff, model-viewer's fidelity test.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pbrcheck.atomic import write_text_atomic
from pbrcheck.errors import PbrcheckError
from pbrcheck.exr import RGB, Image, read_exr, write_exr
from realtime.gl import shader_sources_hash  # noqa: F401 (re-exported: the gate records it per baseline)

from .metrics import LUMA, REL_EPS, pixel_classes

#: Folder of the baselines, beside the budget file.
BASELINE_DIR = "baselines"
#: Significance of a change, in standard deviations of its noise: P(|z| > 5) = 6e-7 per region, so
#: the ~100 regions of a check and the 16 checks of `make gate` give a false alarm < 1e-3 per run.
GATE_Z = 5.0
#: Smallest relative brightness change of a region counted as a change, even for a bit-exact
#: renderer (spread 0): 1e-4 is far above float32 rounding of a mean (~1e-7) and far below what a
#: user sees (1 %), so a GL driver that reorders a sum does not alarm while a 0.1 % change does.
BIAS_FLOOR = 1e-4
#: Smallest ``change`` (relmse between current and baseline) counted as a change for a bit-exact
#: renderer: a 0.1 % per-pixel relative difference (1e-3 squared).
CHANGE_FLOOR = 1e-6
#: Tile size in pixels (screen tiles: a large object's local change).
TILE = 16
#: A tile is a region when it holds at least this many valid pixels.
MIN_TILE_PIXELS = 24
#: Mip shift of the LOD probe rendered at acceptance (the sensitivity's LOD figure).
LOD_PROBE = 0.1
#: Renders at acceptance from which the run-to-run spread is measured.
SPREAD_RUNS = 3
#: The LOD probe as a shader hook: every prefiltered lookup LOD_PROBE mip deeper (docs/hooks.md).
LOD_PROBE_HOOK = ("// pbrcheck gate's LOD probe: the preset's mapping, %g mip deeper.\n"
                  "float hook_lod(float roughness, float max_lod, float cube_log2) {\n"
                  "    return clamp(lod_from_roughness(roughness, max_lod, cube_log2) + %g, 0.0, max_lod);\n"
                  "}\n") % (LOD_PROBE, LOD_PROBE)


class BaselineError(PbrcheckError):
    """A stored baseline that cannot be used (unreadable, another size, missing channels)."""


def baseline_paths(base: Path, safe_name: str) -> tuple[Path, Path]:
    """The baseline EXR and JSON of a check (``safe_name``: the check name made file-safe)."""
    d = Path(base) / BASELINE_DIR
    return d / f"{safe_name}.exr", d / f"{safe_name}.json"


@dataclass
class Baseline:
    """A stored baseline: the image (``rgb``, AOVs), the spread per pixel and the sidecar's record."""
    image: Image
    spread: np.ndarray      # (H, W, 3) run-to-run standard deviation
    record: dict
    path: Path


def load_baseline(base: Path, safe_name: str) -> Baseline | None:
    """The check's baseline, or None when there is none; raises :class:`BaselineError` when one
    exists but cannot be read. A committed accept left unfinished is completed first
    (:func:`finish_accepts`)."""
    finish_accepts(base)
    exr, js = baseline_paths(base, safe_name)
    if not exr.exists() and not js.exists():
        return None
    if not exr.is_file() or not js.is_file():
        raise BaselineError(f"{exr.parent}: baseline of {safe_name} is incomplete (needs {exr.name} and {js.name})")
    try:
        record = json.loads(js.read_text(encoding="utf-8"))
    except (OSError, ValueError) as e:
        raise BaselineError(f"{js}: not a readable baseline record ({e})") from None
    img = read_exr(exr, require=RGB)
    sp = [img.channels.get(f"spread.{c}") for c in RGB]
    spread = np.stack(sp, -1).astype(np.float64) if all(s is not None for s in sp) else np.zeros(img.rgb.shape)
    return Baseline(img, spread, record, exr)


def spread_of(images: list[np.ndarray]) -> np.ndarray:
    """Per-pixel standard deviation (ddof 1) of repeated renders (H, W, 3); zero for one render."""
    if len(images) < 2:
        return np.zeros_like(images[0], dtype=np.float64)
    return np.std(np.stack([i.astype(np.float64) for i in images]), axis=0, ddof=1)


def region_masks(valid: np.ndarray, ids: np.ndarray | None, names: dict[int, str] | None = None) -> list[tuple[str, np.ndarray]]:
    """(name, mask) of every object (``object <name or #id>``) and every screen tile with at least
    :data:`MIN_TILE_PIXELS` valid pixels (``tile x0-x1,y0-y1``)."""
    out = []
    if ids is not None:
        for oid in np.unique(ids[valid]):
            m = valid & (ids == oid)
            nm = (names or {}).get(int(oid))
            out.append((f"object {nm}" if nm else f"object #{int(oid)}", m))
    h, w = valid.shape
    for y in range(0, h, TILE):
        for x in range(0, w, TILE):
            m = np.zeros_like(valid)
            m[y:y + TILE, x:x + TILE] = valid[y:y + TILE, x:x + TILE]
            if int(m.sum()) >= MIN_TILE_PIXELS:
                out.append((f"tile x{x}-{min(x + TILE, w) - 1},y{y}-{min(y + TILE, h) - 1}", m))
    return out


def _thresholds(t0, s, w, mask):
    """(bias threshold, change threshold) of one region (see the module docstring)."""
    y0 = float((t0[mask] @ LUMA).sum())
    sy2 = float(((s[mask] ** 2) @ (LUMA ** 2)).sum())
    sig_b = math.sqrt(2.0 * sy2) / y0 if y0 > 0 else math.inf
    n = int(mask.sum()) * 3
    e = 2.0 * float((s[mask] ** 2 * w[mask]).mean())
    thr_c = max(e + GATE_Z * e * math.sqrt(2.0 / n), CHANGE_FLOOR)
    return max(GATE_Z * sig_b, BIAS_FLOOR), thr_c, y0


@dataclass
class RegionChange:
    """One region's change against the baseline (module docstring)."""
    name: str
    pixels: int
    bias: float
    bias_threshold: float
    change: float
    change_threshold: float
    relmse_before: float
    relmse_after: float
    d_relmse: float
    sigma_d: float
    changed: bool
    state: str  # same | worse | better | changed

    def as_dict(self) -> dict:
        return dict(self.__dict__)

    @property
    def relative_d(self) -> float:
        """Change of relmse relative to its value before."""
        return self.d_relmse / self.relmse_before if self.relmse_before > 0 else math.inf


@dataclass
class Change:
    """The change of a check against its baseline: every region and the verdict."""
    verdict: str  # pass | regressed | improved | changed
    regions: list[RegionChange] = field(default_factory=list)

    def by_state(self, state: str) -> list[RegionChange]:
        rows = [r for r in self.regions if r.state == state]
        key = (lambda r: -abs(r.d_relmse / r.sigma_d) if r.sigma_d > 0 else -math.inf) if state in ("worse", "better") \
            else (lambda r: -abs(r.bias) / r.bias_threshold - r.change / r.change_threshold)
        return sorted(rows, key=key)


def _pair_masks(ref: Image, base: Image, cur: Image) -> tuple[np.ndarray, np.ndarray | None]:
    v1, _, _ = pixel_classes(ref, cur)
    v0, _, _ = pixel_classes(ref, base)
    valid = v1 & v0
    ob = ref.channels.get("object", cur.channels.get("object"))
    ids = np.rint(ob).astype(np.int64) if ob is not None else None
    if ids is not None and "object" in base.channels:
        valid &= np.rint(base.channels["object"]).astype(np.int64) == ids
    return valid, ids


def compare_to_baseline(ref: Image, base: Baseline, cur: Image, names: dict[int, str] | None = None,
                        cur_spread: np.ndarray | None = None) -> Change:
    """Per-region change of ``cur`` against the baseline and its verdict.

    Parameters
    ----------
    ref : Image
        The reference (its ``variance.*`` channels are the noise of ``d_relmse``; zero without).
    base : Baseline
        The accepted baseline.
    cur : Image
        The current render (same size; display-referred images are compared as they are).
    names : dict, optional
        Object id -> name.
    cur_spread : ndarray, optional
        Run-to-run spread of the current render (default: the baseline's).

    Raises
    ------
    BaselineError
        Sizes differ.
    """
    if base.image.shape != cur.shape or ref.shape != cur.shape:
        (h0, w0), (h1, w1) = base.image.shape, cur.shape
        raise BaselineError(f"{base.path}: baseline is {w0}x{h0}, the current render {w1}x{h1}; accept a new one")
    r = ref.rgb.astype(np.float64)
    t0 = base.image.rgb.astype(np.float64)
    t1 = cur.rgb.astype(np.float64)
    v = np.clip(ref.variance.astype(np.float64), 0, None) if ref.variance is not None else np.zeros_like(r)
    s = base.spread if cur_spread is None else np.sqrt((base.spread ** 2 + cur_spread ** 2) / 2.0)
    w = 1.0 / (r * r + REL_EPS)
    valid, ids = _pair_masks(ref, base.image, cur)
    out = []
    for name, m in region_masks(valid, ids, names):
        thr_b, thr_c, y0 = _thresholds(t0, s, w, m)
        a0, a1, ar, aw, av, as_ = t0[m], t1[m], r[m], w[m], v[m], s[m]
        n = a0.size
        y1 = float((a1 @ LUMA).sum())
        bias = (y1 - y0) / y0 if y0 > 0 else (0.0 if y1 == y0 else math.inf)
        d = a1 - a0
        change = float((d * d * aw).mean())
        rel0 = float(((a0 - ar) ** 2 * aw).mean())
        rel1 = float(((a1 - ar) ** 2 * aw).mean())
        var_d = float((d * d * av * aw * aw).sum() + (((a1 - ar) ** 2 + (a0 - ar) ** 2) * as_ ** 2 * aw * aw).sum())
        sigma_d = 2.0 * math.sqrt(var_d) / n
        changed = abs(bias) > thr_b or change > thr_c
        state = "same"
        if changed:
            state = "worse" if rel1 - rel0 > GATE_Z * sigma_d else "better" if rel0 - rel1 > GATE_Z * sigma_d else "changed"
        out.append(RegionChange(name, int(m.sum()), bias, thr_b, change, thr_c, rel0, rel1, rel1 - rel0, sigma_d,
                                changed, state))
    states = {x.state for x in out}
    verdict = ("regressed" if "worse" in states else "improved" if "better" in states
               else "changed" if "changed" in states else "pass")
    return Change(verdict, out)


def probe_response(ref: Image, base_rgb: np.ndarray, probe_rgb: np.ndarray, valid_img: Image,
                   names: dict[int, str] | None = None) -> dict[str, dict]:
    """Per region: the LOD probe's ``bias`` and ``change`` against the baseline render."""
    r = ref.rgb.astype(np.float64)
    w = 1.0 / (r * r + REL_EPS)
    t0, t1 = base_rgb.astype(np.float64), probe_rgb.astype(np.float64)
    valid, _, _ = pixel_classes(ref, valid_img)
    ob = ref.channels.get("object", valid_img.channels.get("object"))
    ids = np.rint(ob).astype(np.int64) if ob is not None else None
    out = {}
    for name, m in region_masks(valid, ids, names):
        y0 = float((t0[m] @ LUMA).sum())
        y1 = float((t1[m] @ LUMA).sum())
        d = t1[m] - t0[m]
        out[name] = {"bias": (y1 - y0) / y0 if y0 > 0 else 0.0, "change": float((d * d * w[m]).mean())}
    return out


def sensitivity(ref: Image, base: Baseline, names: dict[int, str] | None = None) -> dict:
    """The smallest uniform brightness change (relative) and LOD shift (mip) this check detects.

    Returns ``{"brightness": k, "brightness_region": name, "lod_probed": bool, "lod": mip or None,
    "lod_region": name}``; ``lod`` is None without a LOD probe in the baseline (renderers that take no
    shader hooks: ``lod_probed`` False) or when no region responds to the probe (a constant
    environment looks the same at every mip level)."""
    r = ref.rgb.astype(np.float64)
    t0 = base.image.rgb.astype(np.float64)
    w = 1.0 / (r * r + REL_EPS)
    valid, ids = _pair_masks(ref, base.image, base.image)
    probe = base.record.get("lod_probe") or {}
    best_k, best_kn, best_l, best_ln = math.inf, None, math.inf, None
    for name, m in region_masks(valid, ids, names):
        thr_b, thr_c, _ = _thresholds(t0, base.spread, w, m)
        q = float((t0[m] ** 2 * w[m]).mean())
        k = min(thr_b, math.sqrt(thr_c / q) if q > 0 else math.inf)
        if k < best_k:
            best_k, best_kn = k, name
        p = probe.get(name)
        if p:
            cand = [LOD_PROBE * thr_b / abs(p["bias"]) if p["bias"] else math.inf,
                    LOD_PROBE * math.sqrt(thr_c / p["change"]) if p["change"] > 0 else math.inf]
            if min(cand) < best_l:
                best_l, best_ln = min(cand), name
    return {"brightness": best_k, "brightness_region": best_kn, "lod_probed": bool(probe),
            "lod": best_l if math.isfinite(best_l) else None, "lod_region": best_ln}


#: Prefix of an ``--accept`` being staged in the baselines folder: incomplete, ignored by readers,
#: removed by the accept that made it (a staging folder left by ``kill -9`` is inert).
STAGING_PREFIX = ".staging-"
#: Prefix of a committed ``--accept``: complete, rolled forward by :func:`finish_accepts`.
COMMIT_PREFIX = ".commit-"
#: In a staged accept: the budget file's new text and the budget file's name.
_JOURNAL_BUDGET, _JOURNAL_TARGET = "budget.toml", "budget-name"


def begin_accept(base: Path) -> Path:
    """A new staging folder in ``base/baselines``; :func:`stage_baseline` writes into the returned
    folder, :func:`commit_accept` commits it."""
    target = Path(base) / BASELINE_DIR
    target.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=STAGING_PREFIX, dir=target))
    (staging / BASELINE_DIR).mkdir()
    return staging / BASELINE_DIR


def commit_accept(staged: Path, budget: Path, budget_text: str) -> None:
    """Commit a staged accept: write the budget's new text (its ``[[history]]`` line) beside the
    staged baselines, then rename the staging folder to ``.commit-*`` -- the one rename that
    switches the set -- and put its files in place (:func:`finish_accepts`).

    A stop (SIGTERM, an error) before the rename leaves the old baselines and budget untouched; after
    it, the new set is complete on disk and the next :func:`finish_accepts` (every budget load and
    baseline read runs it) completes what the stop interrupted. Either way a reader sees the old set
    or the new one, never a mix."""
    staging = Path(staged).parent
    write_text_atomic(staging / _JOURNAL_BUDGET, budget_text)
    write_text_atomic(staging / _JOURNAL_TARGET, Path(budget).name)
    committed = staging.with_name(COMMIT_PREFIX + staging.name[len(STAGING_PREFIX):])
    os.replace(staging, committed)  # the commit point
    finish_accepts(Path(budget).parent)


def finish_accepts(base: Path) -> int:
    """Roll every committed accept in ``base/baselines`` forward: move its baselines into place,
    then its budget text over the budget file, then remove it. Idempotent (a file already moved is
    no longer in the commit folder), so a stop during it is completed by the next call. Returns the
    number of accepts finished."""
    folder = Path(base) / BASELINE_DIR
    if not folder.is_dir():
        return 0
    done = 0
    for commit in sorted(folder.glob(COMMIT_PREFIX + "*")):
        # Another process finishing the same commit may move a file first: a missing one is done.
        staged = commit / BASELINE_DIR
        for p in sorted(staged.iterdir()) if staged.is_dir() else []:
            with contextlib.suppress(FileNotFoundError):
                os.replace(p, folder / p.name)
        with contextlib.suppress(FileNotFoundError):
            name = (commit / _JOURNAL_TARGET).read_text(encoding="utf-8").strip()
            os.replace(commit / _JOURNAL_BUDGET, Path(base) / Path(name).name)
        shutil.rmtree(commit, ignore_errors=True)
        done += 1
    return done


def abandon_accept(staged: Path) -> None:
    """Remove a staging folder that was not committed (nothing of it reached the baselines)."""
    staging = Path(staged).parent
    if staging.name.startswith(STAGING_PREFIX):
        shutil.rmtree(staging, ignore_errors=True)


def stage_baseline(folder: Path, safe_name: str, image: Image, spread: np.ndarray, record: dict) -> tuple[Path, Path]:
    """Write a baseline (EXR with ``R G B``, ``object``, ``coverage``, ``spread.*``; JSON record) into
    ``folder`` (a staging folder the caller renames into place); returns the two paths."""
    ch = {c: image.channels[c] for c in RGB}
    for k in ("object", "coverage"):
        if k in image.channels:
            ch[k] = image.channels[k]
    for i, c in enumerate(RGB):
        ch[f"spread.{c}"] = spread[..., i].astype(np.float32)
    meta = {"baseline_of": safe_name, "conventions": "R G B: the renderer's linear output (or display values "
            "when display_referred = 1); spread.*: run-to-run standard deviation per pixel"}
    for k in ("renderer", "preset", "options", "gl_renderer", "version", "display_referred", "scene_hash", "shader"):
        if k in image.meta:
            meta[k] = image.meta[k]
    exr = write_exr(Path(folder) / f"{safe_name}.exr", Image(ch, meta))
    js = write_text_atomic(Path(folder) / f"{safe_name}.json", json.dumps(record, indent=1, sort_keys=True) + "\n")
    return exr, js


#: Relative spread of the objects' biases below which a change reads as one uniform factor.
UNIFORM_SPREAD = 0.1
#: A group of objects (metals or dielectrics) counts as unchanged when its mean |bias| is below
#: this fraction of the other group's.
GROUP_RATIO = 0.2


def likely_term(change: Change, materials: dict[str, dict]) -> str | None:
    """The shading term a change most likely comes from, read off which objects changed: every
    object by the same factor (a uniform factor: exposure, an environment scale), only the
    dielectrics (the diffuse term), mostly the metals (the specular term); None when the pattern
    says nothing. ``materials``: region name -> material (``metallic``, ``roughness``)."""
    objs = [(r, materials[r.name]) for r in change.regions if r.name in materials and r.changed]
    if len(objs) < 2:
        return None
    b = np.array([r.bias for r, _ in objs])
    every = len(objs) == sum(r.name in materials for r in change.regions)
    if every and np.all(b != 0) and (np.all(b > 0) or np.all(b < 0)) and float(np.std(b)) <= UNIFORM_SPREAD * abs(float(np.mean(b))):
        return f"a uniform factor x{1 + float(np.mean(b)):.4g} on every object (exposure, an environment scale)"
    allobj = [(r, materials[r.name]) for r in change.regions if r.name in materials]
    diel = [abs(r.bias) for r, m in allobj if (m.get("metallic") or 0.0) <= 0.0]
    metal = [abs(r.bias) for r, m in allobj if (m.get("metallic") or 0.0) >= 1.0]
    if diel and metal:
        d, s = float(np.mean(diel)), float(np.mean(metal))
        if s < GROUP_RATIO * d:
            return f"the diffuse term (dielectrics' mean abs bias {d:.2%}, metals' {s:.2%})"
        if d < GROUP_RATIO * s:
            return f"the specular term (metals' mean abs bias {s:.2%}, dielectrics' {d:.2%})"
    return None
