"""The comparator: image metrics (:mod:`compare.metrics`), error maps and display images
(:mod:`compare.maps`), the CI error-budget gate (:mod:`compare.gate`, budgets in
``compare/budgets``) and the renderer seam (:mod:`compare.renderers`).

Above it, in this order: :mod:`compare.research` (approximation research) and
:mod:`compare.report` (report, sweep, demo). Layers import one way: core ``pbrcheck`` <-
``reference``, ``realtime`` <- ``compare`` <- ``compare.research`` <- ``compare.report`` <- the CLI.
"""
