"""The report layer: the static HTML accuracy report (:mod:`compare.report.build`: configuration, stage
list, page; :mod:`compare.report.scene` one scene's measurement, :mod:`compare.report.plots`,
:mod:`compare.report.results`, :mod:`compare.report.stages`, ``templates/report.html``), the
speed-against-error sweep (:mod:`compare.report.sweep`), the research sections of the report
(:mod:`compare.report.research_sections`) and the main job (:mod:`compare.report.demo`).

Imports the comparator (:mod:`compare`), the renderers through :mod:`compare.renderers`, and the
research layer (:mod:`compare.research`), never the CLI.
"""
