"""Typed results of the research commands, exchanged with the report (:mod:`compare.report`).

Each result is a dataclass with one ``to_json()`` giving the command's JSON layout (written by
:func:`pbrcheck.jsonio.write_json_atomic`); the report and the tables read attributes, never keys.

API
---
:class:`HardcaseRow`; :class:`ExplainRow`, :class:`ExplainPathTruth`, :class:`ExplainResult`; :class:`LodSample`,
:class:`ChainFit`, :class:`MappingEval`, :class:`FitLodResult`; :class:`ApparentRoughness`,
:class:`FitRoughnessResult`; :class:`LevelFit`,
:class:`FitNormalRoughnessResult`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field


class _JSON:
    """``to_json()``: the dataclass as a dict (nested dataclasses too); ``None`` fields listed in
    ``_omit_none`` are left out."""

    _omit_none: tuple[str, ...] = ()

    def to_json(self) -> dict:
        d = asdict(self)
        for k in self._omit_none:
            if d.get(k) is None:
                d.pop(k, None)
        return d


# --- hardcases -----------------------------------------------------------------------------------

@dataclass
class HardcaseRow(_JSON):
    """One render of one hard case: the reference (``preset`` None) or a real-time preset.

    ``finite``: no NaN or Inf in the image; ``nonfinite``: how many values were not (None when the
    render failed); ``metrics``: :data:`compare.research.hardcases.TABLE_METRICS` against the
    reference (None when either image is non-finite or the render failed); ``error``: the failure.
    """

    case: str
    renderer: str
    preset: str | None
    finite: bool
    nonfinite: int | None
    metrics: dict | None = None
    error: str | None = None
    #: the reference row: how its spp was chosen (compare.verdict_spp.VerdictSpp.to_dict())
    reference_spp: dict | None = None
    _omit_none = ("reference_spp",)


# --- explain -------------------------------------------------------------------------------------

@dataclass
class ExplainRow(_JSON):
    """One approximation made exact: its option overrides, the metrics after, and its contribution
    ``error(preset) - error(preset with it exact)`` on the primary metric (None when it failed)."""

    source: str
    options: dict
    metrics: dict | None
    contribution: float | None
    error: str | None = None


@dataclass
class ExplainCombined(_JSON):
    """Several fixes at once (``all_exact``, ``all_but_vnr``)."""

    options: dict
    metrics: dict
    contribution: float


@dataclass
class ExplainPathTruth(_JSON):
    """An approximation whose truth is the ``path`` reference (occlusion: visibility), measured
    against it: the preset's metrics, the metrics with the approximation off (``options``), and
    ``contribution = error(preset) - error(off)`` (negative: the approximation brings the image
    nearer the path truth)."""

    source: str
    options: dict
    spp: int
    baseline: dict
    metrics: dict
    contribution: float


@dataclass
class ExplainResult(_JSON):
    """``pbrcheck explain``'s result (:func:`compare.research.explain.run_explain`)."""

    scene: str
    preset: str
    options: dict
    spp: int
    size: list[int]
    metric: str
    baseline: dict
    noise_relmse: float | None
    sources: list[ExplainRow]
    all_but_vnr: ExplainCombined | None = None
    all_exact: ExplainCombined | None = None
    #: how the reference spp was chosen (compare.verdict_spp.VerdictSpp.to_dict())
    reference_spp: dict | None = None
    #: glTF asset scenes: the approximations whose truth is the path reference (occlusion)
    path_truth: list[ExplainPathTruth] | None = None
    _omit_none = ("all_but_vnr", "all_exact", "reference_spp", "path_truth")


# --- fit-lod -------------------------------------------------------------------------------------

@dataclass
class LodSample(_JSON):
    """One roughness group of the LOD scan: its refined optimal level, the error there, the scan's
    spread, its valid pixel count and the whole scan (one error per scanned level)."""

    roughness: float
    lod: float
    relmse: float
    relmse_spread: float
    pixels: int
    scan: list[float]


@dataclass
class ChainFit(_JSON):
    """The fit on one prefiltered chain: the scan's predicted scene error of the fitted mapping and of
    the chain's own built-in mapping, the coefficients and the per-roughness optima."""

    predicted_relmse: float
    builtin_predicted_relmse: float
    coefficients: list[float]
    optimal_lod: list[float]


@dataclass
class MappingEval(_JSON):
    """A mapping evaluated by a render: its scene relmse and its LOD at each sample's roughness; for
    the fitted one, its file fields (``basis``, ``coefficients``, ``cube_size``, ``mip_count``,
    ``chain``) too."""

    relmse: float | None
    lod: list[float] = field(default_factory=list)
    mapping: dict | None = None

    def to_json(self) -> dict:
        return {**(self.mapping or {}), "relmse": self.relmse, "lod": self.lod}


@dataclass
class FitLodResult(_JSON):
    """``pbrcheck fit-lod``'s result (:func:`compare.research.fit_lod.run_fit_lod`)."""

    scene: str
    fit_scene: str
    preset: str
    options: dict
    spp: int
    size: list[int]
    lod_step: float
    metric: str
    chain: str
    samples: list[LodSample]
    chains: dict[str, ChainFit]
    mappings: dict[str, MappingEval]
    per_roughness_optimum_mean_relmse: float | None = None
    glsl: str | None = None
    #: how the reference spp was chosen (compare.verdict_spp.VerdictSpp.to_dict())
    reference_spp: dict | None = None

    def to_json(self) -> dict:
        d = {k: getattr(self, k) for k in ("scene", "fit_scene", "preset", "options", "spp", "size", "lod_step",
                                            "metric", "chain")}
        d["samples"] = [s.to_json() for s in self.samples]
        d["chains"] = {k: v.to_json() for k, v in self.chains.items()}
        d["mappings"] = {k: v.to_json() for k, v in self.mappings.items()}
        if self.per_roughness_optimum_mean_relmse is not None:
            d["per_roughness_optimum_mean_relmse"] = self.per_roughness_optimum_mean_relmse
        if self.glsl is not None:
            d["glsl"] = self.glsl
        if self.reference_spp is not None:
            d["reference_spp"] = self.reference_spp
        return d


# --- fit-roughness -------------------------------------------------------------------------------

@dataclass
class ApparentRoughness(_JSON):
    """One object's apparent roughness r*: its own roughness, Adam's start, r*, the final loss over
    its pixels and its pixel count; with the scan, the range of indistinguishable roughness values
    and the scan (``[[r, loss, se], ...]``)."""

    object: int
    name: str | None
    roughness: float
    start: float
    apparent_roughness: float
    loss: float | None
    pixels: int
    range: list[float] | None = None
    scan: list | None = None
    _omit_none = ("range", "scan")


@dataclass
class FitRoughnessResult(_JSON):
    """``pbrcheck fit-roughness``'s result (:func:`compare.research.fit_roughness.run_fit_roughness`)."""

    scene: str
    preset: str
    options: dict
    iterations: int
    lr: float
    lr_final: float
    average_last: int
    spp: int
    scan: bool
    loss: str
    size: list[int]
    objects: list[ApparentRoughness]
    image_loss_trace: list[float]

    def to_json(self) -> dict:
        d = asdict(self)
        d["objects"] = [o.to_json() for o in self.objects]
        return d


# --- fit-normal-roughness ------------------------------------------------------------------------

@dataclass
class LevelFit(_JSON):
    """One normal-map level of fit-normal-roughness: its pixels (0: the entry is its nearest fitted
    neighbour's), the fitted alpha^2 increment, the closed forms' per-level means (``toksvig``, ``lean``),
    the relmse at the optimum and the scan's curve (one relmse per ``u``, increment ``u^2``); ``optimum``:
    stage 1's per-level optimum (None without pixels), ``fitted`` the table's entry after stage 2."""
    level: int
    pixels: int
    fitted: float
    toksvig: float
    lean: float
    relmse_at_optimum: float | None = None
    scan: list = field(default_factory=list)
    optimum: float | None = None


@dataclass
class FitNormalRoughnessResult(_JSON):
    """fit-normal-roughness: per level a :class:`LevelFit`; ``fitted`` the table's JSON
    (:class:`pbrcheck.normal_roughness.NormalRoughnessTable`); ``relmse`` per row of the evaluation
    (none, toksvig, toksvig_table, lean_table, prefiltered, fitted); ``start``: stage 2's start (the lowest of
    ``start_relmse``: per_level_optima, toksvig_table, lean_table; method ad: its starting table, no
    relmse); ``glsl`` the hook file; ``method`` ad or scan; ad only: ``model_relmse`` (the filtered
    reference model's relmse against the truth per table: filtered (none), toksvig_table, lean_table,
    fitted), ``losses`` (Adam's per step), ``lod`` (its convention and range over the pixels)."""
    scene: str
    preset: str
    options: dict
    size: list
    target: str
    metric: str
    levels: list
    fitted: dict
    start: str
    start_relmse: dict
    relmse: dict
    reference_spp: dict | None = None
    glsl: str = ""
    method: str = "scan"
    model_relmse: dict | None = None
    losses: list | None = None
    lod: dict | None = None
