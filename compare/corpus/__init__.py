"""Corpus studies: every renderer under test against the reference under many environments, in
this process or on Dask (``pbrcheck corpus``; docs/corpus.md).

Modules: :mod:`.study` (discovery, task plan, rows, resume), :mod:`.scheduler` (task graph, serial
and Dask executors, ``--scheduler``), :mod:`.tasks` (what runs on a worker), :mod:`.envstats`
(environment statistics), :mod:`.outputs` (tables, summary, plots), :mod:`.renderlist` (the render
lists of ``sweep`` and ``report`` on a scheduler), :mod:`.bench` (``pbrcheck bench corpus``).
"""
