"""Where the tasks run: in this process, in local worker processes, or on a Dask cluster.

Each engine takes tasks (a module-level function and small, picklable arguments) and hands back
futures. A worker that dies takes its tasks with it: :meth:`result` then raises
:class:`WorkerLost`, and the caller sends the task again (the tasks only read).

- :class:`InProcess` runs each task at once, in this process (one job, or one task);
- :class:`Processes` runs them in ``jobs`` worker processes (started with ``spawn``); a worker
  killed breaks the pool, which is started anew for the next task;
- :class:`DaskCluster` sends them to the scheduler of an existing Dask distributed cluster
  (``dask scheduler`` and ``dask worker``); the scheduler itself gives a task whose worker died
  to another one (its ``allowed-failures``, 3 by default), then reports it lost.
"""

from __future__ import annotations

import concurrent.futures
from collections.abc import Callable, Collection
from typing import Any, Protocol

from rasm.errors import RasmError
from rasm.extras import missing_extra

__all__ = ["ClusterError", "DaskCluster", "Engine", "InProcess", "Processes", "WorkerLost"]


class WorkerLost(RasmError):
    """The worker running a task died before it finished (killed, out of memory)."""


class ClusterError(RasmError):
    """The cluster cannot be reached."""


class Engine(Protocol):
    def submit(self, fn: Callable[..., Any], *args: Any) -> Any:
        """Start ``fn(*args)`` somewhere; a future of its result."""

    def wait(self, futures: Collection[Any]) -> set[Any]:
        """Block until one of ``futures`` at least is done; those that are."""

    def result(self, future: Any) -> Any:
        """A done future's result (raises :class:`WorkerLost` for a lost worker)."""

    def close(self) -> None: ...


class InProcess:
    """Each task run at once, here."""

    def submit(self, fn: Callable[..., Any], *args: Any) -> concurrent.futures.Future:
        future: concurrent.futures.Future = concurrent.futures.Future()
        future.set_result(fn(*args))  # what it raises is raised here, as a check in one pass
        return future

    def wait(self, futures: Collection[Any]) -> set[Any]:
        return set(futures)

    def result(self, future: Any) -> Any:
        return future.result()

    def close(self) -> None:
        pass


class Processes:
    """``jobs`` local worker processes."""

    def __init__(self, jobs: int) -> None:
        self.jobs = jobs
        self._pool: concurrent.futures.ProcessPoolExecutor | None = None

    def _fresh(self) -> concurrent.futures.ProcessPoolExecutor:
        import multiprocessing  # here: a check in this process needs none of it

        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
        # spawn: a worker starts clean, whatever threads this process runs (a progress bar)
        self._pool = concurrent.futures.ProcessPoolExecutor(
            self.jobs, mp_context=multiprocessing.get_context("spawn"))
        return self._pool

    def submit(self, fn: Callable[..., Any], *args: Any) -> concurrent.futures.Future:
        pool = self._pool or self._fresh()
        try:
            return pool.submit(fn, *args)
        except concurrent.futures.BrokenExecutor:  # a worker died: the pool takes no more tasks
            return self._fresh().submit(fn, *args)

    def wait(self, futures: Collection[Any]) -> set[Any]:
        done, _ = concurrent.futures.wait(futures, return_when=concurrent.futures.FIRST_COMPLETED)
        return done

    def result(self, future: Any) -> Any:
        try:
            return future.result()
        except concurrent.futures.BrokenExecutor as exc:
            raise WorkerLost(f"a worker process died ({exc})") from None

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None


class DaskCluster:
    """An existing Dask distributed cluster, through its scheduler at ``address``
    (``tcp://host:8786``)."""

    def __init__(self, address: str, *, timeout: float = 10) -> None:
        try:
            from distributed import Client
        except ImportError as exc:
            raise (missing_extra(exc, "--cluster") or exc) from None
        from distributed import as_completed

        try:
            self.client = Client(address, timeout=timeout, set_as_default=False)
        except (OSError, TimeoutError, ValueError) as exc:
            raise ClusterError(f"cannot reach the Dask scheduler at {address}: {exc}") from None
        self._finished = as_completed(loop=self.client.loop)  # every future sent, as done

    def submit(self, fn: Callable[..., Any], *args: Any) -> Any:
        # pure=False: a task sent again is a new task, not the failed one looked up by its key
        future = self.client.submit(fn, *args, pure=False)
        self._finished.add(future)
        return future

    def wait(self, futures: Collection[Any]) -> set[Any]:
        # the next to finish of all those sent (one no longer waited for is passed over)
        return {next(self._finished), *self._finished.next_batch(block=False)}

    def result(self, future: Any) -> Any:
        from distributed import KilledWorker

        try:
            return future.result()
        except KilledWorker as exc:
            raise WorkerLost(f"the cluster lost the workers running it ({exc})") from None

    def close(self) -> None:
        self.client.close()
