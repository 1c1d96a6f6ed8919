"""The glTF PBR extensions' lobes in the comparison: which objects of a scene carry each lobe, the
real-time renderer's lobe options (read generically from :data:`realtime.registry.LOBE_REGISTRIES`)
and the error of a renderer over the objects of one lobe.

Nothing here names an option: a lobe family of the real-time registry (``COAT_ATTENUATION``,
``SHEEN_DFG``, ...) belongs to the lobe its switch name starts with (:data:`SWITCH_PREFIXES`), and
its option is the real-time option whose registry it is (:data:`realtime.presets.OPTION_REGISTRIES`)
or, failing that, the switch name in lower case where :class:`realtime.presets.RealtimeOptions` has
such a field. A family the real-time renderer does not take as an option yet (issue 36 item 3 wires
them) is listed by :func:`lobe_families` with ``option`` None and swept or explained by no one; once
it is an option every caller (``report``'s lobe sections and sweep, ``explain``, ``sweep --lobes``,
``diagnose``'s lobe departures) takes it up with no change here.

API
---
- :data:`LOBE_NAMES` -- ``{extension: short name}`` (``clearcoat``, ``sheen``, ...), in
  :data:`pbrcheck.lobe_params.LOBE_EXTENSIONS`' order; :data:`SWITCH_PREFIXES`.
- :func:`object_lobes` -- ``{extension: object ids}`` of a scene: analytic objects by their
  material's lobe fields, glTF mesh objects by their material's active extensions.
- :func:`scene_lobes` -- the extensions a scene uses, in order; :func:`no_random_walk` -- why a
  scene's lobes leave it without a random-walk reference (anisotropy, iridescence; None otherwise).
- :class:`LobeFamily`, :func:`lobe_families` -- the real-time registry's lobe families with the
  option that chooses among their members (None: not an option yet).
- :func:`lobe_variants` -- for a renderer and a scene: one ``{option: member}`` per member of each
  family of the scene's lobes other than the renderer's own choice (what ``sweep`` and ``explain``
  render).
- :func:`parameter_groups` -- a lobe's objects grouped by the value of each of its parameters (the
  built-in scenes' grid rows and columns).
- :func:`pooled_metrics` -- a comparison's metrics pooled over a set of objects (pixel-weighted:
  exact for the means ``relmse``, ``flip_mean``, ``mean_abs``; ``rmse`` from the pooled MSE).
- :data:`POOLED_METRICS`.

References: KhronosGroup/glTF ``extensions/2.0/Khronos/KHR_materials_*/README.md``; the families'
members and sources: ``realtime/registry.py`` and docs/realtime.md.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from pbrcheck.errors import PbrcheckError
from pbrcheck.lobe_params import (ANISOTROPY, CLEARCOAT, IRIDESCENCE, LOBE_EXTENSIONS, SCENE_FIELD_EXTENSION, SHEEN,
                                  SPECULAR, WALK_LOBE_EXTENSIONS, scene_features)

#: extension -> the short name the report, the tables and the CLI use.
LOBE_NAMES = {e: e.removeprefix("KHR_materials_") for e in LOBE_EXTENSIONS}
#: A real-time lobe family belongs to the lobe its switch name starts with (``COAT_IBL``: clearcoat).
SWITCH_PREFIXES = {"COAT": CLEARCOAT, "CLEARCOAT": CLEARCOAT, "SHEEN": SHEEN, "SPECULAR": SPECULAR,
                   "ANISOTROPY": ANISOTROPY, "IRIDESCENCE": IRIDESCENCE}
#: The metrics :func:`pooled_metrics` pools (the means, and rmse through the pooled MSE); percentiles
#: and maxima cannot be pooled from per-object figures.
POOLED_METRICS = ("relmse", "flip_mean", "mean_abs", "rmse")


def _asset_material_lobes(scene, o) -> tuple[str, ...]:
    """The active lobe extensions of a glTF mesh object's material (an inactive one, at its
    neutral values, changes no pixel)."""
    mat = scene.assets[o.instance].asset.material(o.gltf_material)
    out = []
    for ext, (attr, _) in LOBE_EXTENSIONS.items():
        lobe = getattr(mat, attr, None)
        if lobe is not None and lobe.active:
            out.append(ext)
    return tuple(out)


def object_lobes(scene) -> dict[str, tuple[int, ...]]:
    """``{extension: ids of the objects that carry it}`` for every lobe extension some object of
    ``scene`` uses, in :data:`LOBE_NAMES`' order (empty: no lobe)."""
    by: dict[str, list[int]] = {}
    for o in scene.objects:
        if getattr(o, "type", "") == "mesh":
            feats = _asset_material_lobes(scene, o)
        else:
            feats = scene_features(o.material)
        for f in feats:
            by.setdefault(f, []).append(o.id)
    return {e: tuple(by[e]) for e in LOBE_NAMES if e in by}


def scene_lobes(scene) -> tuple[str, ...]:
    """The lobe extensions ``scene`` uses (:func:`object_lobes`' keys)."""
    return tuple(object_lobes(scene))


def no_random_walk(scene) -> str | None:
    """Why ``scene`` has no random-walk reference because of its lobes (None: every lobe it uses is one
    the walk carries): the reference's walk gives the base's specular and layers the coat, sheen and
    specular lobes on it as the spec does (:data:`pbrcheck.lobe_params.WALK_LOBE_EXTENSIONS`); it is
    isotropic with Schlick's Fresnel, so reference/lobe_bsdf.py refuses ``multiscatter = "random_walk"``
    beside anisotropy or iridescence, and the report's second truth and diagnose's
    ``multiple_scattering`` are not rendered for a scene whose objects carry one."""
    refused = [e for e in scene_lobes(scene) if e not in WALK_LOBE_EXTENSIONS]
    if not refused:
        return None
    return (f"the glTF lobes ({', '.join(LOBE_NAMES[e] for e in refused)}) have no random walk in the "
            "reference (the walk is isotropic with Schlick's Fresnel)")


@dataclass(frozen=True)
class LobeFamily:
    """One real-time lobe family: its switch, lobe extension, member names, default member and the
    real-time option that chooses the member (None: the renderer does not take it as an option yet)."""

    switch: str
    extension: str
    members: tuple[str, ...]
    default: str
    option: str | None
    registry: object = None


def _option_name(switch: str, registry) -> str | None:
    from realtime.presets import OPTION_REGISTRIES, RealtimeOptions
    named = [name for name, reg in OPTION_REGISTRIES.items() if reg is registry]
    if named:
        return named[0]
    guess = switch.lower()
    return guess if guess in {f.name for f in dataclasses.fields(RealtimeOptions)} else None


def lobe_families() -> list[LobeFamily]:
    """Every family of :data:`realtime.registry.LOBE_REGISTRIES` whose switch names a lobe
    (:data:`SWITCH_PREFIXES`), in the registry's order."""
    from realtime.registry import LOBE_REGISTRIES
    out = []
    for switch, (reg, _shader, default, _roles) in LOBE_REGISTRIES.items():
        ext = next((e for p, e in SWITCH_PREFIXES.items() if switch == p or switch.startswith(p + "_")), None)
        if ext is None:
            continue
        out.append(LobeFamily(switch, ext, tuple(reg.names), default, _option_name(switch, reg), reg))
    return out


def lobe_variants(spec, scene, families: list[LobeFamily] | None = None) -> list[dict]:
    """One ``{option: member}`` per member of each option family of ``scene``'s lobes other than the
    member renderer ``spec`` already uses, where ``spec`` accepts it (a member whose requirements
    this renderer does not meet is left out). None for an external renderer (it takes no option)."""
    if spec.external:
        return []
    used = set(scene_lobes(scene))
    out = []
    for fam in families if families is not None else lobe_families():
        if fam.option is None or fam.extension not in used:
            continue
        current = getattr(spec.options, fam.option, fam.default)
        for m in fam.members:
            if m == current:
                continue
            try:
                spec.with_options(**{fam.option: m})
            except PbrcheckError:
                continue
            out.append({fam.option: m})
    return out


def parameter_groups(scene, extension: str) -> dict[str, tuple[int, ...]]:
    """``{"FIELD=VALUE": object ids}``: the analytic objects carrying ``extension`` grouped by the
    value of each of its scene-file fields (:data:`pbrcheck.lobe_params.SCENE_FIELD_EXTENSION`;
    the built-in lobe scenes' grid rows and columns), by field then value; glTF mesh objects (their
    textures vary the parameters per pixel) are not grouped."""
    ids = set(object_lobes(scene).get(extension, ()))
    out: dict[str, list[int]] = {}
    for fld in (f for f, e in SCENE_FIELD_EXTENSION.items() if e == extension):
        vals: dict = {}
        for o in scene.objects:
            if o.id in ids and getattr(o, "type", "") != "mesh":
                v = getattr(o.material, fld)
                vals.setdefault(tuple(v) if isinstance(v, (list, tuple)) else v, []).append(o.id)
        if len(vals) > 1:   # a field the scene does not vary says nothing per value
            for v in sorted(vals):
                out[f"{fld}={list(v) if isinstance(v, tuple) else v}"] = vals[v]
    return {k: tuple(v) for k, v in out.items()}


def pooled_metrics(objects: list[dict], ids) -> dict:
    """:data:`POOLED_METRICS` over the objects ``ids`` of a comparison summary's ``objects`` list
    (each ``{"id", "pixels", "metrics"}``), weighted by their valid pixels; ``pixels`` and
    ``objects`` (how many had valid pixels) alongside, and ``worst`` (the object with the largest
    relmse: ``{"id", "name", "relmse"}``). Metrics None where no object has valid pixels."""
    want = set(int(i) for i in ids)
    rows = [o for o in objects if o["id"] in want and o.get("pixels", 0) > 0]
    n = sum(o["pixels"] for o in rows)
    out: dict = {"pixels": n, "objects": len(rows)}
    for k in POOLED_METRICS:
        vals = [(o["pixels"], o["metrics"].get(k)) for o in rows if o["metrics"].get(k) is not None]
        if not vals or n == 0:
            out[k] = None
            continue
        w = sum(p for p, _ in vals)
        out[k] = (math.sqrt(sum(p * v * v for p, v in vals) / w) if k == "rmse"
                  else sum(p * v for p, v in vals) / w)
    worst = max((o for o in rows if o["metrics"].get("relmse") is not None), key=lambda o: o["metrics"]["relmse"],
                default=None)
    out["worst"] = None if worst is None else {"id": worst["id"], "name": worst.get("name"),
                                               "relmse": worst["metrics"]["relmse"]}
    return out


__all__ = ["LOBE_NAMES", "LobeFamily", "POOLED_METRICS", "SWITCH_PREFIXES", "lobe_families", "lobe_variants",
           "no_random_walk", "object_lobes", "parameter_groups", "pooled_metrics", "scene_lobes"]
