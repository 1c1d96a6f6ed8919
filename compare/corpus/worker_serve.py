"""One browser per client per Dask worker (issue 39): a worker plugin that opens a
:func:`clients.run.serve_clients` block in each worker process when the worker starts and closes it
(its serve processes with it) when the worker closes.

API: :class:`ServeClients` -- registered by :func:`compare.corpus.scheduler.open_executor` on every
``local:N`` and ``tcp://`` executor.

Why a plugin: the CLI wraps every command in ``serve_clients()`` (one Chromium per web client for a
whole command), but that block lives in the command's process; a Dask worker is another process,
where every render started its own browser (~6 CPU-s of Chromium start each). The block's state is
a module global of :mod:`clients.run`, shared by the worker's task threads, so the first render of a
client in a worker starts its serve process and the worker's later renders of that client reuse it.
Its processes are killed when the worker closes (the plugin's ``teardown``), and at the worker's
interpreter exit as a fallback (:mod:`clients.run`'s ``atexit`` hook).

Imported only where Dask runs (it imports ``distributed``).

References: Dask distributed documentation, "Plugins" (``WorkerPlugin.setup`` / ``teardown``,
``Client.register_plugin``).
"""

from __future__ import annotations

from distributed.diagnostics.plugin import WorkerPlugin


class ServeClients(WorkerPlugin):
    """Open :func:`clients.run.serve_clients` in a worker for its life."""

    #: One registration per cluster: a second ``register_plugin`` with this name replaces the first.
    name = "pbrcheck-serve-clients"

    def setup(self, worker) -> None:
        from clients.run import serve_clients

        self._block = serve_clients()
        self._block.__enter__()

    def teardown(self, worker) -> None:
        block = getattr(self, "_block", None)
        if block is not None:
            self._block = None
            block.__exit__(None, None, None)
