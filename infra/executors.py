"""One executor interface for batches of independent runs: serial, a process pool, or Ray.

``make_executor(spec, workers)`` builds one; ``spec`` is

- ``"serial"``: one run after another in this process (tests, debugging, callbacks);
- ``"process"``: a pool of ``workers`` processes on this machine (``spawn``);
- ``"ray"``: a local Ray instance of ``workers`` CPUs, started on first use;
- ``"ray:ADDRESS"``: a running Ray cluster (``ray start --head``; ``ADDRESS`` as
  ``ray.init(address=...)`` takes it: ``auto``, ``HOST:6379``, ``ray://HOST:10001``).

``Executor.imap(fn, items)`` yields ``(index, outcome)`` as runs finish, in any order, where
``outcome`` is ``Ok(value)`` or ``Failed(message)``; ``run_in_order`` collects every outcome
in item order. A run that raises becomes ``Failed`` and the others go on. A worker process
that dies (segfault, out of memory) fails no other run: its run is retried once, then
recorded as ``Failed`` — in a pool the runs it left are rerun alone in a fresh process, on Ray
the task is resubmitted once (``max_retries=1``). ``fn`` and the items must be picklable for
every executor but ``serial`` (a module-level function and plain data), and results do not
depend on the executor: each run carries its own seeds.

Ray is an optional dependency (``pip install -e ".[ray]"``), imported only when a Ray
executor runs its first batch.
"""

from __future__ import annotations

import logging
import multiprocessing as mp
import os
import traceback
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from typing import Any, Protocol

EXECUTOR_SPECS = ("serial", "process", "ray", "ray:ADDRESS")
"""The executor specs ``make_executor`` accepts (ADDRESS: a Ray cluster's address)."""
WORKER_DIED = "worker process died (crash or out of memory) on its try and on its retry"
"""``Failed.message`` of a run whose worker died twice."""


@dataclass(frozen=True)
class Ok:
    """A run that returned ``value``."""

    value: Any


@dataclass(frozen=True)
class Failed:
    """A run that raised (``message`` names the exception; ``detail`` is the traceback)."""

    message: str
    detail: str = ""


Outcome = Ok | Failed


class BatchError(RuntimeError):
    """Runs of a batch failed; the message names each (``failures``: index → ``Failed``)."""

    def __init__(self, message: str, failures: dict[int, Failed]) -> None:
        super().__init__(message)
        self.failures = failures


class ExecutorError(RuntimeError):
    """An executor cannot start: Ray missing, or its cluster cannot be joined."""


def _call(fn: Callable[[Any], Any], item: Any) -> Outcome:
    try:
        return Ok(fn(item))
    except Exception as exc:  # noqa: BLE001 - every failure becomes that run's record
        return Failed(f"{type(exc).__name__}: {exc}", traceback.format_exc())


class Executor(Protocol):
    """Runs ``fn`` over ``items``, yielding ``(index, outcome)`` as each finishes."""

    def imap(
        self, fn: Callable[[Any], Any], items: Sequence[Any]
    ) -> Iterator[tuple[int, Outcome]]: ...


class SerialExecutor:
    """Runs items one after another in this process (deterministic order)."""

    workers = 1

    def imap(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> Iterator[tuple[int, Outcome]]:
        for i, item in enumerate(items):
            yield i, _call(fn, item)


_started: Any = None
"""In a pool worker: the queue on which it announces each item it starts."""


def _init_worker(started: Any) -> None:
    global _started
    _started = started


def _call_announced(fn: Callable[[Any], Any], item: Any, index: int) -> Outcome:
    _started.put(index)
    return _call(fn, item)


class ProcessExecutor:
    """Runs items in a pool of ``workers`` processes (``spawn`` start method; None = one per
    core). A worker that dies breaks the whole pool; every item the pool left unfinished is
    then rerun alone in a fresh one-process pool — once if it had started (its worker may be
    the one that died), up to twice if it had not — so only an item that kills its process
    twice is ``Failed``.
    """

    def __init__(self, workers: int | None = None) -> None:
        self.workers = max(1, workers or os.cpu_count() or 1)

    def imap(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> Iterator[tuple[int, Outcome]]:
        n = min(self.workers, len(items))
        if n == 0:
            return
        ctx = mp.get_context("spawn")
        started = ctx.SimpleQueue()
        broken: list[int] = []
        ran: set[int] = set()  # items a worker has started (drained often: a pipe is finite)
        pool = ProcessPoolExecutor(
            max_workers=n, mp_context=ctx, initializer=_init_worker, initargs=(started,)
        )
        with pool:
            futures: dict[Future, int] = {
                pool.submit(_call_announced, fn, item, i): i for i, item in enumerate(items)
            }
            waiting = set(futures)
            while waiting:
                done, waiting = wait(waiting, return_when=FIRST_COMPLETED)
                while not started.empty():
                    ran.add(started.get())
                for fut in done:
                    try:
                        yield futures[fut], fut.result()
                    except BrokenProcessPool:
                        broken.append(futures[fut])
        while not started.empty():
            ran.add(started.get())
        for i in sorted(broken):
            yield i, _run_alone(fn, items[i], ctx, tries=1 if i in ran else 2)


def _run_alone(fn: Callable[[Any], Any], item: Any, ctx: Any, tries: int) -> Outcome:
    """``item`` in a fresh one-process pool, up to ``tries`` times while its worker dies."""
    for _ in range(tries):
        try:
            with ProcessPoolExecutor(max_workers=1, mp_context=ctx) as solo:
                return solo.submit(_call, fn, item).result()
        except BrokenProcessPool:
            continue
    return Failed(WORKER_DIED)


class RayExecutor:
    """Runs items as Ray tasks (one CPU each), on a local instance or a running cluster.

    ``address`` None starts a local instance of ``workers`` CPUs (None = every core) at the
    first batch; otherwise this process joins the cluster at ``address`` (``workers`` is
    ignored: the cluster's CPUs decide). A Ray connection this process already holds is
    reused. A task whose worker dies is resubmitted once, then recorded as ``Failed``. On a
    cluster every node needs this project installed (same Python and Ray versions) and the
    run folder on a shared file system (runs write their own files, e.g. recordings).
    """

    def __init__(self, workers: int | None = None, address: str | None = None) -> None:
        self.workers = workers
        self.address = address

    def connect(self) -> Any:
        """Start or join Ray (once per process); returns the ``ray`` module. Raises
        ``ExecutorError`` when Ray is not installed or the cluster cannot be joined."""
        try:
            import ray
        except ImportError as exc:
            raise ExecutorError(
                'executor "ray" needs Ray: pip install -e ".[ray]" (or pip install ray)'
            ) from exc
        if ray.is_initialized():
            return ray
        kwargs: dict[str, Any] = {"logging_level": logging.WARNING}
        if self.address is None:  # "local": a new instance, even if a cluster runs here
            kwargs |= {"address": "local", "num_cpus": self.workers, "include_dashboard": False}
        else:
            kwargs["address"] = self.address
        try:
            ray.init(**kwargs)
        except ConnectionError as exc:
            raise ExecutorError(
                f"cannot join the Ray cluster at {self.address}: {exc}. Is 'ray start --head' "
                "running there, and do this process and the cluster agree on RAY_AUTH_MODE "
                "(docs/executors.md)?"
            ) from exc
        return ray

    def imap(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> Iterator[tuple[int, Outcome]]:
        if not items:
            return
        ray = self.connect()
        task = ray.remote(num_cpus=1, max_retries=1)(_call)
        fn_ref = ray.put(fn)
        refs = {task.remote(fn_ref, item): i for i, item in enumerate(items)}
        pending = list(refs)
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                try:
                    outcome = ray.get(ref)
                except ray.exceptions.WorkerCrashedError:
                    outcome = Failed(WORKER_DIED)
                except ray.exceptions.RayError as exc:  # node lost, out of memory, ...
                    outcome = Failed(f"{type(exc).__name__}: {exc}")
                yield refs[ref], outcome


def check_spec(spec: str) -> str:
    """``spec`` if it names an executor (``EXECUTOR_SPECS``), else ``ValueError``."""
    if spec in ("serial", "process", "ray") or (
        isinstance(spec, str) and spec.startswith("ray:") and len(spec) > 4
    ):
        return spec
    raise ValueError(
        f"executor must be serial, process, ray or ray:ADDRESS (a Ray cluster), got {spec!r}"
    )


def make_executor(spec: str | None = "process", workers: int | None = None) -> Executor:
    """The executor ``spec`` names (``EXECUTOR_SPECS``) with ``workers`` processes or CPUs
    (None = one per core; ignored by ``serial`` and ``ray:ADDRESS``). ``spec`` None picks
    ``serial`` when ``workers`` is 1 and ``process`` otherwise. ``ValueError`` on a bad spec
    or ``workers`` < 1."""
    if workers is not None and workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    if spec is None:
        spec = "serial" if workers == 1 else "process"
    spec = check_spec(spec)
    if spec == "serial":
        return SerialExecutor()
    if spec == "process":
        return ProcessExecutor(workers)
    return RayExecutor(workers, address=spec[4:] or None)


def run_in_order(
    executor: Executor, fn: Callable[[Any], Any], items: Iterable[Any]
) -> list[Outcome]:
    """Every item's outcome, in item order (the batch runs as ``executor.imap`` runs it)."""
    items = list(items)
    out: list[Outcome | None] = [None] * len(items)
    for i, o in executor.imap(fn, items):
        out[i] = o
    return out  # type: ignore[return-value]


def values_or_raise(outcomes: Sequence[Outcome], names: Sequence[str] | None = None) -> list[Any]:
    """The values of ``outcomes``, or ``BatchError`` naming every failed run (``names[i]``,
    default ``run i``) and its message."""
    failures = {i: o for i, o in enumerate(outcomes) if isinstance(o, Failed)}
    if failures:
        label = (lambda i: names[i]) if names is not None else (lambda i: f"run {i}")
        listed = "; ".join(f"{label(i)}: {f.message}" for i, f in failures.items())
        raise BatchError(f"{len(failures)} of {len(outcomes)} runs failed: {listed}", failures)
    return [o.value for o in outcomes]  # type: ignore[union-attr]


__all__ = [
    "EXECUTOR_SPECS",
    "WORKER_DIED",
    "BatchError",
    "Executor",
    "ExecutorError",
    "Failed",
    "Ok",
    "Outcome",
    "ProcessExecutor",
    "RayExecutor",
    "SerialExecutor",
    "check_spec",
    "make_executor",
    "run_in_order",
    "values_or_raise",
]
