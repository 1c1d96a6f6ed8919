"""``pbrcheck layered-coat``: what the spec's clearcoat layering itself costs (issue 36 item 5a).

The truth is the physically layered coat of :mod:`pbrcheck.layered` (a position-free random walk
through a dielectric slab of IOR 1.5 over the glTF base [Guo18]); against it the spec's albedo
scaling ([Coat] "Layering": ``(1 - c Fc(n.v)) f_base + c Fc(n.v) clearcoat_brdf``, Schlick Fc at
n.v: :func:`pbrcheck.layered.spec_albedo`, :func:`pbrcheck.layered.spec_brdf`). Per coat roughness
(:data:`ROUGHNESS`) and view cosine (:data:`NOV`): the directional albedo of both, the albedo of a
white Lambertian under the same coat (the "furnace" column: 1 for a smooth coat; below 1 the rough
interface's single-scattering loss, which the walk's microfacet interface shares with every
single-scattering microfacet model), the albedo with the rough interface as a random walk on its
microsurface (``Coat(interface="multiple")``: no such loss; its furnace is 1), and the BRDF of both
at the light directions :data:`LIGHTS` (single-scattering interface).

API
---
:data:`ROUGHNESS`, :data:`NOV`, :data:`LIGHTS`, :data:`DEFAULT_BASE`, :data:`DEFAULT_SAMPLES`,
:class:`Row`, :func:`run_layered_coat`, :func:`table_markdown`.

References
----------
[Guo18] Y. Guo, M. Hasan, S. Zhao, "Position-Free Monte Carlo Simulation for Arbitrary Layered
        BSDFs", ACM TOG 37(6), 2018.
[Coat]  KHR_materials_clearcoat README, "Layering".
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from pbrcheck import layered as _lay

#: The coat roughness values of the table (the issue's grid).
ROUGHNESS = (0.0, 0.25, 0.5, 1.0)
#: The view cosines n.v of the table.
NOV = (1.0, 0.5, 0.2)
#: The light directions of the BRDF columns: (n.l, azimuth from the view's plane in degrees).
#: Neither is the mirror direction of any view of :data:`NOV` (a smooth coat's delta is left out).
LIGHTS = ((0.9, 90.0), (0.5, 150.0))
#: The base under the coat: a grey dielectric (base colour 0.5, roughness 0.5, metallic 0, F0 0.04).
DEFAULT_BASE = _lay.Base(0.5, 0.0, 0.5, 0.04)
#: Walks per estimate (standard errors ~3e-3 of the albedo at 16384).
DEFAULT_SAMPLES = 16384


@dataclass
class Row:
    roughness: float
    nov: float
    albedo: float
    albedo_se: float
    albedo_spec: float
    furnace: float
    furnace_se: float
    brdf: list = field(default_factory=list)       # per light: (layered, se, spec)
    albedo_ms: float = 0.0                         # the walk with a multiple-scattering interface
    albedo_ms_se: float = 0.0


def run_layered_coat(samples: int = DEFAULT_SAMPLES, seed: int = 0, base: _lay.Base = DEFAULT_BASE,
                     roughness=ROUGHNESS, nov=NOV) -> list[Row]:
    """The comparison grid (each estimate seeded with ``seed`` plus its index: reproducible)."""
    rows, k = [], seed
    white = _lay.Base(1.0, lambert=True)
    for r in roughness:
        coat = _lay.Coat(float(r))
        for mu in nov:
            v = _lay.direction(mu)
            e, se = _lay.layered_albedo(base, coat, v, n=samples, seed=k)
            fe, fse = _lay.layered_albedo(white, coat, v, n=samples, seed=k + 1)
            row = Row(float(r), float(mu), e, se, _lay.spec_albedo(base, coat, v), fe, fse)
            if coat.smooth:   # no microsurface: both interface models are the same walk
                row.albedo_ms, row.albedo_ms_se = e, se
            else:
                row.albedo_ms, row.albedo_ms_se = _lay.layered_albedo(
                    base, _lay.Coat(float(r), interface="multiple"), v, n=samples, seed=k)
            for j, (cl, az) in enumerate(LIGHTS):
                light = _lay.direction(cl, math.radians(az))
                f, fs = _lay.layered_brdf(base, coat, light, v, n=samples, seed=k + 2 + j)
                row.brdf.append((f, fs, _lay.spec_brdf(base, coat, light, v)))
            rows.append(row)
            k += 2 + len(LIGHTS)
    return rows


def table_markdown(rows: list[Row]) -> str:
    """The table: albedo layered +- se, spec, spec - layered (relative), furnace, and per light the
    BRDF layered +- se, spec and their ratio spec / layered."""
    head = ["coat roughness", "n.v", "E layered", "E spec", "spec/layered", "white furnace",
            "E layered, MS interface", "spec/layered (MS)"]
    for cl, az in LIGHTS:
        head += [f"f layered (n.l {cl:g}, {az:g} deg)", "f spec", "spec/layered"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        cells = [f"{r.roughness:g}", f"{r.nov:g}", f"{r.albedo:.4f} ± {r.albedo_se:.4f}", f"{r.albedo_spec:.4f}",
                 f"{r.albedo_spec / r.albedo:.3f}", f"{r.furnace:.4f} ± {r.furnace_se:.4f}",
                 f"{r.albedo_ms:.4f} ± {r.albedo_ms_se:.4f}", f"{r.albedo_spec / r.albedo_ms:.3f}"]
        for f, fs, sp in r.brdf:
            cells += [f"{f:.4f} ± {fs:.4f}", f"{sp:.4f}", f"{sp / f:.3f}"]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"
