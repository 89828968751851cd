"""Executors of a sweep: run specs in parallel and yield their rows as they finish.

Two executors behind one small interface (``imap_unordered`` in a ``with`` block):

- ``LocalExecutor``: a ``concurrent.futures.ProcessPoolExecutor`` on this machine. Workers are
  fresh processes (``forkserver`` where available, which imports the simulation stack once and
  forks clean workers from it; ``spawn`` elsewhere): PyBullet and numba are not safe to use in
  a child forked from a process that already ran them. Each run opens its own Bullet client.
  A run that raises is recorded by the worker itself; a worker process that dies (a crash in
  Bullet, the OOM killer) costs the runs it held one attempt each, and a run that loses
  ``retries + 1`` attempts is recorded as an error.
- ``RayExecutor``: Ray tasks on an existing cluster (``address``) or on a local Ray started for
  the sweep with ``workers`` CPUs. Tasks are retried by Ray (``max_retries``, ``retry_exceptions``);
  a run that still fails is recorded with its error.
"""

from __future__ import annotations

import collections
import concurrent.futures as cf
import enum
import multiprocessing
import os
import threading
import time
from types import TracebackType
from typing import TYPE_CHECKING, Any, Callable, Iterator, Mapping, Sequence

from pybullet_swarm.errors import ConfigError

if TYPE_CHECKING:  # pragma: no cover
    from pybullet_swarm.experiment.results import Row
    from pybullet_swarm.experiment.jobs import RunSpec

    Worker = Callable[[RunSpec], Row]

#: Modules the forkserver imports once, so that forked workers start warm (``warm`` also loads the
#: compiled kernels).
PRELOAD = ("pybullet_swarm.experiment.sweep", "pybullet_swarm.experiment.runner", "pybullet_swarm.experiment.warm")


class ExecutorKind(str, enum.Enum):
    """Where the runs of a sweep execute."""

    LOCAL = "local"
    RAY = "ray"


class _Executor:
    """Base: a context manager whose ``imap_unordered`` yields one row per spec, in finishing order."""

    def __enter__(self) -> _Executor:
        return self

    def __exit__(self, et: type[BaseException] | None, ev: BaseException | None, tb: TracebackType | None) -> None:
        self.close(cancel=et is not None)

    def imap_unordered(self, specs: Sequence[RunSpec]) -> Iterator[Row]:
        """Run every spec; yield each row as soon as its run finishes."""
        raise NotImplementedError

    def close(self, cancel: bool = False) -> None:
        """Release the workers (``cancel``: drop runs not started)."""


def _default_worker() -> Worker:
    from pybullet_swarm.experiment.jobs import execute_run

    return execute_run


def _lost_message(attempts: int, exc: BaseException) -> str:
    return f"worker lost {attempts} times ({type(exc).__name__}: {exc})"


# --------------------------------------------------------------------- local
def start_method() -> str:
    """``forkserver`` where the platform has it, else ``spawn`` (never ``fork``)."""
    return "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"


def _ping() -> int:
    """A task that does nothing: proves that a new pool's workers can start."""
    return os.getpid()


def _watch_parent(pid: int, period_s: float = 1.0) -> None:
    """Worker initialiser: exit when the sweep process ``pid`` is gone.

    A pool worker blocks on its task queue, whose pipe ends it holds itself, so it would outlive a
    sweep killed with SIGKILL forever (and keep writing into a directory a restarted sweep uses).
    A daemon thread polls the sweep process and ends the worker within ``period_s``.
    """
    if os.name != "posix":  # os.kill(pid, 0) only tests for existence on POSIX
        return

    def watch() -> None:
        while True:
            time.sleep(period_s)
            try:
                os.kill(pid, 0)
            except ProcessLookupError:
                os._exit(1)
            except PermissionError:  # alive, owned by someone else after a pid reuse: keep going
                pass

    threading.Thread(target=watch, name="sweep-parent-watch", daemon=True).start()


def _start_worker(pid: int, designs: Mapping[tuple[Any, ...], Any]) -> None:
    """Worker initialiser: watch the sweep process ``pid`` (``_watch_parent``) and take the controller
    designs it made while planning, so that the worker's runs do not design them again."""
    _watch_parent(pid)
    from pybullet_swarm.control.design import add_designs

    add_designs(designs)


def _known_designs() -> dict[tuple[Any, ...], Any]:
    """The controller designs this process made (planning a sweep validates every configuration), or
    none when they cannot be sent to another process (workers then design their own)."""
    import pickle

    from pybullet_swarm.control.design import known_designs

    designs = known_designs()
    try:
        pickle.dumps(designs)
    except Exception:  # noqa: BLE001 - an optimisation only
        return {}
    return designs


def prestart(method: str | None = None) -> None:
    """Start the forkserver now, so that it imports the simulation stack while this process
    is still busy (planning the sweep); a later pool then starts at once. No-op for ``spawn``."""
    method = method or start_method()
    if method != "forkserver":
        return
    multiprocessing.get_context(method).set_forkserver_preload(list(PRELOAD))
    from multiprocessing import forkserver

    forkserver.ensure_running()


class LocalExecutor(_Executor):
    """A process pool of ``workers`` processes on this machine.

    Args:
        workers: parallel runs (>= 1).
        worker: the function that runs one spec and returns its row (importable by name).
        retries: extra attempts of a run whose worker process died.
        method: ``forkserver`` or ``spawn`` (default: ``start_method()``).
        max_tasks_per_child: replace a worker after this many runs (None: never), to bound memory.
    """

    def __init__(
        self,
        workers: int,
        *,
        worker: Worker | None = None,
        retries: int = 2,
        method: str | None = None,
        max_tasks_per_child: int | None = None,
    ) -> None:
        if workers < 1:
            raise ConfigError(f"must be >= 1, got {workers}", source="--workers")
        self.workers = int(workers)
        self.worker = worker or _default_worker()
        self.retries = int(retries)
        self.method = method or start_method()
        if self.method not in ("forkserver", "spawn"):
            raise ConfigError(f"must be forkserver or spawn, got {self.method!r}", source="start method")
        self.max_tasks_per_child = max_tasks_per_child
        self._pool: cf.ProcessPoolExecutor | None = None

    def _new_pool(self) -> cf.ProcessPoolExecutor:
        """A new pool, checked: a worker that cannot start (e.g. a script without a ``__main__``
        guard) stops the sweep here instead of failing every run one by one."""
        ctx = multiprocessing.get_context(self.method)
        if self.method == "forkserver":
            ctx.set_forkserver_preload(list(PRELOAD))
        kwargs: dict[str, Any] = {}
        if self.max_tasks_per_child is not None:
            kwargs["max_tasks_per_child"] = self.max_tasks_per_child
        pool = cf.ProcessPoolExecutor(
            max_workers=self.workers,
            mp_context=ctx,
            initializer=_start_worker,
            initargs=(os.getpid(), _known_designs()),
            **kwargs,
        )
        try:
            pool.submit(_ping).result()
        except Exception as exc:  # noqa: BLE001 - BrokenProcessPool, or the ping could not be unpickled
            pool.shutdown(wait=False, cancel_futures=True)
            raise RuntimeError(
                f"worker processes cannot start ({type(exc).__name__}: {exc}); a script that "
                "runs a sweep needs an `if __name__ == '__main__':` guard"
            ) from None
        return pool

    def _submit(self, spec: RunSpec) -> tuple[cf.Future[Row], cf.ProcessPoolExecutor]:
        for _ in range(2):
            if self._pool is None:
                self._pool = self._new_pool()
            try:
                return self._pool.submit(self.worker, spec), self._pool
            except cf.process.BrokenProcessPool:
                self._drop_pool(self._pool)
        raise RuntimeError("cannot start worker processes")

    def _drop_pool(self, pool: cf.ProcessPoolExecutor) -> None:
        """Forget ``pool`` (broken) if it is still the current one; the next submit starts a new one."""
        if self._pool is pool:
            pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None

    def imap_unordered(self, specs: Sequence[RunSpec]) -> Iterator[Row]:
        """Run every spec on the pool, one run per worker at a time.

        Submitting no more runs than there are workers means the runs in flight are the runs
        executing: when a worker dies, only the runs that were executing at that moment (one per
        worker) are charged an attempt.
        """
        from pybullet_swarm.experiment.jobs import failure_row

        queue = collections.deque(specs)
        attempts: collections.Counter[str] = collections.Counter()
        inflight: dict[cf.Future[Row], tuple[RunSpec, cf.ProcessPoolExecutor]] = {}
        while queue or inflight:
            while queue and len(inflight) < self.workers:
                spec = queue.popleft()
                fut, pool = self._submit(spec)
                inflight[fut] = (spec, pool)
            done, _ = cf.wait(inflight, return_when=cf.FIRST_COMPLETED)
            for fut in done:
                spec, pool = inflight.pop(fut)
                try:
                    row = fut.result()
                except Exception as exc:  # noqa: BLE001 - the worker process died (BrokenProcessPool, ...)
                    if isinstance(exc, cf.process.BrokenProcessPool):
                        self._drop_pool(pool)
                    attempts[spec.run_id] += 1
                    if attempts[spec.run_id] <= self.retries:
                        queue.appendleft(spec)
                    else:
                        yield failure_row(spec, _lost_message(attempts[spec.run_id], exc))
                    continue
                yield row

    def close(self, cancel: bool = False) -> None:
        """Shut the pool down (waiting for running runs unless ``cancel``)."""
        if self._pool is not None:
            self._pool.shutdown(wait=not cancel, cancel_futures=True)
            self._pool = None


# ----------------------------------------------------------------------- ray
class RunFailed(RuntimeError):
    """Raised inside a Ray task for a run that ended with ``exit_status = error``, so that Ray retries it."""


def _ray_task(worker: Worker, spec: RunSpec, designs: Mapping[tuple[Any, ...], Any] | None = None) -> Row:
    if designs:
        from pybullet_swarm.control.design import add_designs

        add_designs(designs)  # the sweep process's controller designs: not designed again
    row = worker(spec)
    if row.get("exit_status") == "error":
        raise RunFailed(str(row.get("error")))
    return row


class RayExecutor(_Executor):
    """Ray tasks, one per run, on a cluster or on a local Ray started here.

    Args:
        workers: with ``address``: most runs in flight (None: as many as the cluster has CPUs);
            without: the CPUs of the local Ray (None: every core).
        address: ``auto``, ``host:port`` or ``ray://host:port`` of a running cluster; None starts a local Ray.
        worker: the function that runs one spec and returns its row.
        retries: Ray's ``max_retries`` (lost workers) and retries of runs that raised.
        quiet: keep Ray's own start-up messages and worker logs off the terminal.
    """

    def __init__(
        self,
        workers: int | None = None,
        *,
        address: str | None = None,
        worker: Worker | None = None,
        retries: int = 2,
        quiet: bool = True,
    ) -> None:
        try:
            import ray
        except ImportError:
            raise ConfigError("needs Ray: pip install 'pybullet_swarm[ray]'", source="--executor ray") from None
        if workers is not None and workers < 1:
            raise ConfigError(f"must be >= 1, got {workers}", source="--workers")
        self._ray = ray
        self._started = False
        if not ray.is_initialized():
            import logging

            level = logging.ERROR if quiet else logging.WARNING
            kwargs: dict[str, Any] = {"log_to_driver": False, "logging_level": level}
            try:
                if address is not None:
                    ray.init(address=address, **kwargs)
                else:
                    from pybullet_swarm.experiment.jobs import cpu_count

                    # address="local": always a new Ray of our own, never a cluster found on this machine
                    ray.init(address="local", num_cpus=workers or cpu_count(), include_dashboard=False, **kwargs)
            except (ConnectionError, RuntimeError, ValueError) as exc:
                raise ConfigError(
                    f"cannot start or reach Ray ({' '.join(str(exc).split())[:300]})",
                    source="--address" if address else "--executor ray",
                ) from None
            self._started = True
        cpus = int(ray.cluster_resources().get("CPU", 1))
        # tasks submitted at once: on a cluster with --workers, exactly that many run at a time;
        # otherwise Ray's CPU count limits concurrency and a second batch waits queued
        self.limit = workers if (address is not None and workers is not None) else 2 * (workers or cpus)
        self.worker = worker or _default_worker()
        self._task = ray.remote(num_cpus=1, max_retries=retries, retry_exceptions=True)(_ray_task)

    def imap_unordered(self, specs: Sequence[RunSpec]) -> Iterator[Row]:
        """Submit the specs as Ray tasks (a bounded number in flight) and yield rows as they finish."""
        from pybullet_swarm.experiment.jobs import failure_row

        ray = self._ray
        worker_ref = ray.put(self.worker)
        designs_ref = ray.put(_known_designs())
        queue = collections.deque(specs)
        inflight: dict[Any, RunSpec] = {}
        while queue or inflight:
            while queue and len(inflight) < self.limit:
                spec = queue.popleft()
                inflight[self._task.remote(worker_ref, spec, designs_ref)] = spec
            done, _ = ray.wait(list(inflight), num_returns=1)
            for ref in done:
                spec = inflight.pop(ref)
                try:
                    yield ray.get(ref)
                except Exception as exc:  # noqa: BLE001 - every retry failed: record the run's error
                    cause = getattr(exc, "cause", None) or exc
                    msg = str(cause) if isinstance(cause, RunFailed) else f"{type(cause).__name__}: {cause}"
                    yield failure_row(spec, f"{msg} (after Ray retries)")

    def close(self, cancel: bool = False) -> None:
        """Stop the local Ray this executor started (a cluster is left running)."""
        if self._started:
            self._ray.shutdown()
            self._started = False


def check_executor(kind: ExecutorKind | str, *, workers: int | None = None, address: str | None = None) -> ExecutorKind:
    """Refuse an executor that cannot work, before anything is written or started.

    Raises:
        ConfigError: an unknown kind, ``workers < 1``, an ``address`` without Ray, Ray not installed.
    """
    try:
        kind = ExecutorKind(kind)
    except ValueError:
        raise ConfigError(
            f"must be one of {', '.join(k.value for k in ExecutorKind)}, got {kind!r}", source="--executor"
        ) from None
    if workers is not None and workers < 1:
        raise ConfigError(f"must be >= 1, got {workers}", source="--workers")
    if kind is ExecutorKind.LOCAL and address is not None:
        raise ConfigError("needs --executor ray", source="--address")
    if kind is ExecutorKind.RAY:
        import importlib.util

        if importlib.util.find_spec("ray") is None:
            raise ConfigError("needs Ray: pip install 'pybullet_swarm[ray]'", source="--executor ray")
    return kind


def make_executor(
    kind: ExecutorKind | str = ExecutorKind.LOCAL,
    *,
    workers: int | None = None,
    address: str | None = None,
    worker: Worker | None = None,
    retries: int = 2,
    quiet: bool = True,
) -> _Executor:
    """The executor named ``kind``.

    Raises:
        ConfigError: an unknown kind, ``workers < 1``, an ``address`` without Ray, Ray not installed.
    """
    kind = check_executor(kind, workers=workers, address=address)
    if kind is ExecutorKind.LOCAL:
        from pybullet_swarm.experiment.jobs import cpu_count

        return LocalExecutor(workers if workers is not None else cpu_count(), worker=worker, retries=retries)
    return RayExecutor(workers, address=address, worker=worker, retries=retries, quiet=quiet)


__all__ = [
    "ExecutorKind",
    "LocalExecutor",
    "RayExecutor",
    "RunFailed",
    "check_executor",
    "make_executor",
    "prestart",
    "start_method",
]
