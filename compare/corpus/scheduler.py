"""Running a task graph in this process or on Dask (``--scheduler serial | local:N | tcp://HOST:PORT``).

A corpus (and a sweep's or a report's render list) is a list of :class:`Task` s: one render, one
comparison or one environment's statistics each, named by a content hash (:attr:`Task.key`), with
:class:`Dep` placeholders for the results of earlier tasks. Two tasks with the same key are the same
computation and run once. The executors run the same functions on the same arguments, so a serial
run and a Dask run give the same results.

API
---
- :class:`Dep`, :class:`Task`, :class:`Failed` -- the graph and the value of a failed task.
- :class:`SchedulerError` (bad spec, exit 2), :class:`SchedulerUnavailable` (no scheduler or no
  worker, exit 3).
- :func:`parse_scheduler` -- ``"serial"``, ``"local"``, ``"local:N"`` or ``"tcp://HOST:PORT"`` to a
  :class:`SchedulerSpec` (raises :class:`SchedulerError`).
- :func:`open_executor` -- a context manager yielding the executor of a spec (starts and stops a
  LocalCluster for ``local:N``; connects to a running scheduler for ``tcp://``); on both, each
  worker keeps one serve process (browser) per web client for its life (:mod:`compare.corpus.worker_serve`).
- :class:`SerialExecutor`, :class:`DaskExecutor` -- ``run(tasks, on_result, progress)``.

Failures. A task function returns :class:`Failed` for a typed error (bad environment file, bad
option, renderer error): deterministic, so never retried, and every dependent passes it on, which
makes one error row per affected result. Any other exception is retried ``retries`` times by Dask
(``client.submit(..., retries=)``) and a task whose worker process dies is rescheduled on another
worker by the Dask scheduler (up to ``distributed.scheduler.allowed-failures`` times); only then does
the client turn it into a :class:`Failed` with the exception's message. The serial executor turns an
exception into a :class:`Failed` at once. Nothing stops the run.

Dask placement. For ``local:N`` each worker is a process with one thread (``threads_per_worker=1``),
and each process owns its own OpenGL context and Mitsuba variant, set up lazily by the renderers on
the first render in that process. On ``tcp://`` clusters the workers may run several threads; the
task functions (:mod:`compare.corpus.tasks`) then run every render on one dedicated thread per
process, so the GL context is never used from two threads.

References: Dask distributed documentation, "Futures" (``submit``, ``as_completed``, ``retries``)
and "Worker resilience" (rescheduling tasks of a lost worker).
"""

from __future__ import annotations

import contextlib
import logging
import os
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass
from typing import Any, Callable

from pbrcheck.errors import PbrcheckError

#: Retries of a task that raised an unexpected exception (Dask's ``retries``; a lost worker is
#: handled by the scheduler's own ``allowed-failures``).
DEFAULT_RETRIES = 2
#: The ``--scheduler`` help text every command shares.
SCHEDULER_HELP = ("where tasks run: serial (this process), local:N (a Dask LocalCluster of N worker "
                  "processes; local alone: one per CPU core) or tcp://HOST:PORT (a running dask scheduler)")
#: Seconds to wait for a remote scheduler to answer and for its first worker to join.
CONNECT_TIMEOUT_S = 120


class SchedulerError(PbrcheckError):
    """A malformed ``--scheduler`` value (exit code 2)."""


class SchedulerUnavailable(SchedulerError):
    """A scheduler that cannot be reached or has no worker: the backend is unavailable (exit code 3)."""

    exit_code = 3


@dataclass(frozen=True)
class Dep:
    """A placeholder in :attr:`Task.args` for the result of the task ``key``."""

    key: str


@dataclass(frozen=True)
class Task:
    """One unit of work: ``fn(*args)`` with each :class:`Dep` replaced by that task's result.

    ``stage`` names the work in error rows (``environment``, ``reference``, ``render``, ``compare``);
    ``deliver``: its result is handed to the client's ``on_result`` (renders stay on the workers)."""

    key: str
    fn: Callable
    args: tuple = ()
    stage: str = "task"
    deliver: bool = False


@dataclass(frozen=True)
class Failed:
    """The value of a task that failed: its stage and the one-line message (naming the file)."""

    stage: str
    message: str


def failure_of(stage: str, exc: BaseException) -> Failed:
    """The :class:`Failed` of an exception (typed errors keep their message, others get the type)."""
    if isinstance(exc, PbrcheckError):
        return Failed(stage, str(exc))
    first = (str(exc).strip().splitlines() or [""])[0]
    return Failed(stage, f"{type(exc).__name__}: {first}" if first else type(exc).__name__)


@dataclass(frozen=True)
class SchedulerSpec:
    """``kind`` is ``serial``, ``local`` (``workers`` processes) or ``tcp`` (``address``)."""

    kind: str
    workers: int = 1
    address: str | None = None

    def __str__(self) -> str:
        return {"serial": "serial", "local": f"local:{self.workers}"}.get(self.kind, self.address or "")


def parse_scheduler(text: str | None, default: str = "serial") -> SchedulerSpec:
    """``serial``, ``local`` (one worker per CPU core), ``local:N`` or ``tcp://HOST:PORT``.

    Raises
    ------
    SchedulerError
        Anything else, or ``N`` < 1.
    """
    s = (text or default).strip()
    if s == "serial":
        return SchedulerSpec("serial")
    if s == "local" or s.startswith("local:"):
        n = os.cpu_count() or 1
        if s != "local":
            try:
                n = int(s.split(":", 1)[1])
            except ValueError:
                n = 0
            if n < 1:
                raise SchedulerError(f"--scheduler {s!r}: expected local:N with an integer N >= 1")
        return SchedulerSpec("local", workers=n)
    if s.startswith("tcp://") and len(s) > len("tcp://"):
        return SchedulerSpec("tcp", address=s)
    raise SchedulerError(f"--scheduler {s!r}: expected serial, local, local:N or tcp://HOST:PORT")


def _consumers(tasks: list[Task]) -> dict[str, int]:
    n: dict[str, int] = {}
    for t in tasks:
        for a in t.args:
            if isinstance(a, Dep):
                n[a.key] = n.get(a.key, 0) + 1
    return n


def unique_tasks(tasks: list[Task]) -> list[Task]:
    """``tasks`` without repeated keys (the first of each key kept, order preserved)."""
    seen, out = set(), []
    for t in tasks:
        if t.key not in seen:
            seen.add(t.key)
            out.append(t)
    return out


class SerialExecutor:
    """Runs the tasks one after another in this process, in list order (dependencies first), and
    frees each result once its last consumer has run."""

    name = "serial"
    workers = 1

    def run(self, tasks: list[Task], on_result: Callable[[Task, Any], None], progress=None) -> None:
        """Run ``tasks`` (dependencies before dependents); ``on_result(task, value)`` for every task
        with ``deliver``; ``progress.update(1)`` per task."""
        tasks = unique_tasks(tasks)
        left = _consumers(tasks)
        results: dict[str, Any] = {}
        for t in tasks:
            args = [results[a.key] if isinstance(a, Dep) else a for a in t.args]
            try:
                value = t.fn(*args)
            except Exception as e:  # noqa: BLE001 - a failed task is an error row, never a stop
                value = failure_of(t.stage, e)
            for a in t.args:
                if isinstance(a, Dep):
                    left[a.key] -= 1
                    if left[a.key] == 0:
                        results.pop(a.key, None)
            if left.get(t.key, 0) > 0:
                results[t.key] = value
            if t.deliver:
                on_result(t, value)
            if progress is not None:
                progress.update(1, t.stage)


class DaskExecutor:
    """Submits the tasks to a ``distributed.Client`` (futures with explicit keys, ``retries``) and
    hands each delivered result to ``on_result`` as it completes (in completion order)."""

    name = "dask"

    def __init__(self, client, retries: int = DEFAULT_RETRIES):
        self.client = client
        self.retries = retries

    @property
    def workers(self) -> int:
        return max(1, len(self.client.scheduler_info().get("workers", {})))

    def run(self, tasks: list[Task], on_result: Callable[[Task, Any], None], progress=None) -> None:
        """As :meth:`SerialExecutor.run`, on the cluster."""
        from distributed import as_completed  # local: Dask is imported only where it is used

        tasks = unique_tasks(tasks)
        futures: dict[str, Any] = {}
        by_key = {t.key: t for t in tasks}
        for t in tasks:
            args = [futures[a.key] if isinstance(a, Dep) else a for a in t.args]
            futures[t.key] = self.client.submit(t.fn, *args, key=t.key, retries=self.retries, pure=False)
        pending = as_completed(list(futures.values()))
        futures.clear()  # the scheduler keeps what dependents still need; finished renders are freed
        for fut in pending:
            t = by_key[fut.key]
            if t.deliver:
                if fut.status == "error":
                    value = failure_of(t.stage, fut.exception())
                else:
                    try:
                        value = fut.result()
                    except Exception as e:  # noqa: BLE001 - e.g. a lost result: an error row
                        value = failure_of(t.stage, e)
                on_result(t, value)
            if progress is not None:
                progress.update(1, t.stage)
            fut.release()


#: Seconds during which a ``tcp://`` scheduler's port is tried (every 0.25 s: a scheduler that is
#: still starting) before Dask's own connect: a refused or unreachable port fails after this, not
#: after :data:`CONNECT_TIMEOUT_S`.
PROBE_TIMEOUT_S = 15.0


def _probe(address: str, timeout: float = PROBE_TIMEOUT_S) -> None:
    """Raise :class:`SchedulerUnavailable` when nothing listens at ``tcp://HOST:PORT`` within
    ``timeout`` seconds."""
    import socket
    from urllib.parse import urlsplit

    try:
        u = urlsplit(address)
        host, port = u.hostname, u.port
    except ValueError as e:
        raise SchedulerError(f"--scheduler {address!r}: {e}") from None
    if not host or port is None:
        raise SchedulerError(f"--scheduler {address!r}: expected tcp://HOST:PORT")
    deadline = time.monotonic() + timeout
    while True:
        try:
            with socket.create_connection((host, port), timeout=max(0.5, deadline - time.monotonic())):
                return
        except OSError as e:
            if time.monotonic() + 0.25 < deadline and not isinstance(e, (TimeoutError, socket.gaierror)):
                time.sleep(0.25)
                continue
            reason = "timed out" if isinstance(e, TimeoutError) else (e.strerror or str(e))
            raise SchedulerUnavailable(f"--scheduler {address}: cannot connect within {timeout:g} s "
                                       f"({reason})") from None


def _silence_dask() -> None:
    """Interrupted: the closing cluster's and client's logging says nothing more, nor does Dask's
    clean-up at exit (``close_clusters`` of a cluster interrupted while it started)."""
    for name in ("distributed", "tornado", "asyncio"):
        logging.getLogger(name).setLevel(logging.CRITICAL + 1)
    sys.unraisablehook = lambda unraisable: None


def _serve_clients_on_workers(client) -> None:
    """Each worker of ``client``'s cluster (those there now and those that join) renders its web
    clients through one browser per client for its life (:class:`compare.corpus.worker_serve.ServeClients`)."""
    from .worker_serve import ServeClients

    client.register_plugin(ServeClients())


@contextlib.contextmanager
def open_executor(spec: SchedulerSpec | str | None, *, retries: int = DEFAULT_RETRIES,
                  timeout: float = CONNECT_TIMEOUT_S):
    """The executor of ``spec``: serial in this process, a LocalCluster of ``spec.workers`` processes
    (one thread each) started for the duration, or a client of the scheduler at ``spec.address``.

    Raises
    ------
    SchedulerError
        A malformed spec.
    SchedulerUnavailable
        A scheduler that cannot be reached, or gets no worker, within ``timeout`` seconds (default
        :data:`CONNECT_TIMEOUT_S`).
    """
    if not isinstance(spec, SchedulerSpec):
        spec = parse_scheduler(spec)
    if spec.kind == "serial":
        yield SerialExecutor()
        return
    import dask
    from distributed import Client, LocalCluster  # local: a heavy import only Dask runs need

    if spec.kind == "local":
        # the workers' own logging is silenced (CRITICAL): a Ctrl-C reaches them too, and their
        # CommClosedError tracebacks would bury pbrcheck's one line; a task's failure still comes
        # back as its error row
        # the workers' scratch folder is this run's own, removed at the end (Dask's default,
        # $TMPDIR/dask-scratch-space, stays behind)
        scratch = tempfile.mkdtemp(prefix="pbrcheck-dask-")
        try:
            with dask.config.set({"temporary-directory": scratch}), \
                    LocalCluster(n_workers=spec.workers, threads_per_worker=1, processes=True,
                                 dashboard_address=None, silence_logs=logging.CRITICAL,
                                 local_directory=scratch) as cluster, \
                    Client(cluster, timeout=timeout) as client:
                _serve_clients_on_workers(client)
                yield DaskExecutor(client, retries)
        except BaseException:  # also an interrupt while the cluster starts
            _silence_dask()
            raise
        finally:
            shutil.rmtree(scratch, ignore_errors=True)
        return
    _probe(spec.address, min(timeout, PROBE_TIMEOUT_S))
    try:
        client = Client(spec.address, timeout=timeout)
    except (OSError, TimeoutError) as e:
        raise SchedulerUnavailable(f"--scheduler {spec.address}: cannot connect ({e})") from None
    with client:
        try:  # tasks would wait forever on a scheduler without workers
            client.wait_for_workers(1, timeout=timeout)
        except (OSError, TimeoutError):
            raise SchedulerUnavailable(f"--scheduler {spec.address}: no worker joined within {timeout:g} s "
                                 f"(start some with `dask worker {spec.address} --nthreads 1`)") from None
        _serve_clients_on_workers(client)
        try:
            yield DaskExecutor(client, retries)
        except BaseException:
            _silence_dask()
            raise
