"""What the report measured, as the page template reads it (``templates/report.html``).

API
---
- :class:`PresetResult` -- one renderer under test on one scene.
- :class:`SceneSection` -- one scene: its reference, every renderer's result, plots, provenance.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..verdict_spp import VerdictSpp
from .references import REFERENCE_MODES


@dataclass
class PresetResult:
    """One renderer under test on one scene: its metrics, noise flags, timings and image files."""

    preset: str
    metrics: dict
    pixels: dict
    within: dict
    precompute: float | None
    frame: float | None
    rt_png: str
    flip_png: str
    rel_png: str
    mse: float
    timed_on: str = ""
    space: str = "linear"
    diagnosis: str = ""       # external renderers: pbrcheck diagnose's verdict line
    diagnosis_json: str = ""  # ... and its table (JSON, relative to the report)


@dataclass
class SceneSection:
    """One scene of the report (the template's ``scenes``)."""

    id: str
    name: str
    description: str
    spp: object
    ref_png: str
    presets: list[PresetResult]
    plots: list[dict]
    provenance: list[tuple[str, str]]
    noise_floor: float | None
    sweep_rows: list[dict]
    verdict: VerdictSpp | None = None
    material_rows: list[dict] = field(default_factory=list)   # glTF assets: renderer x material
    approx_preset: str | None = None   # glTF assets: the preset of the approximation rows
    approx_rows: list[dict] = field(default_factory=list)     # compare.approximations.approximation_rows
    unmodelled: list[dict] = field(default_factory=list)      # features not modelled (scene.unmodelled_banner)
    reference_mode: str = "local"   # the reference every renderer of the scene is set against

    @property
    def reference_text(self) -> str:
        """The page's sentence on the reference of this scene's comparisons."""
        return REFERENCE_MODES.get(self.reference_mode, self.reference_mode)


__all__ = ["PresetResult", "SceneSection"]
