"""The research layer: approximation studies built on the comparator.

:mod:`~compare.research.hardcases` (edge-of-model scenes), :mod:`~compare.research.fit_lod` (the
LOD scan and fit pipeline) with its maths in :mod:`~compare.research.monotone_fit`,
:mod:`~compare.research.fit_normal_roughness` (the roughness added per normal-map mip level),
:mod:`~compare.research.explain` (error decomposition) and :mod:`~compare.research.fit_roughness`
(apparent roughness through the differentiable reference). Results are typed
(:mod:`~compare.research.results`) with one ``to_json``.

Imports core, the renderers and the comparator (:mod:`compare`), never :mod:`compare.report` or the CLI.
"""
