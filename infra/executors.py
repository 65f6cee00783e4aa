"""A small executor interface for independent runs: serial (tests, debugging) or a process pool.

``Executor.imap(fn, items)`` yields ``(index, outcome)`` as runs finish, in any order, where
``outcome`` is ``Ok(value)`` or ``Failed(message)``. A run that raises becomes ``Failed`` and
the others go on; a worker process that dies (segfault, out of memory) fails the runs it had
not returned, never the whole batch.

Interrupts: worker processes ignore Ctrl-C from birth (they are started inside
``spawning()``); the main process gets the ``KeyboardInterrupt``, cancels the runs not
started and terminates the workers before it re-raises (``process_pool``), so Ctrl-C stops a
batch at once, with no traceback from any worker.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import threading
import traceback
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Protocol


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


def _call(fn: Callable[[Any], Any], item: Any) -> Outcome:
    try:
        return Ok(fn(item))
    except Exception as exc:  # noqa: BLE001 - every failure becomes that run's record
        return Failed(f"{type(exc).__name__}: {exc}", traceback.format_exc())


def _ignore_interrupts() -> None:
    """Worker initializer: Ctrl-C is the main process's to handle; SIGTERM (from ``_stop``)
    ends a worker at once, even one forked from a process with its own SIGTERM handler."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


@contextmanager
def spawning() -> Iterator[None]:
    """Start worker processes (submit to a pool) in this block: they inherit an ignored
    SIGINT from birth, before their initializer runs. A Ctrl-C within the block is dropped."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old if old is not None else signal.SIG_DFL)


def _stop(pool: ProcessPoolExecutor, timeout_s: float = 5.0) -> None:
    """Cancel the runs not started and terminate the workers (SIGTERM, then SIGKILL)."""
    procs = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        p.terminate()
    for p in procs:
        p.join(timeout_s)
        if p.is_alive():
            p.kill()
            p.join(timeout_s)


@contextmanager
def process_pool(workers: int, mp_context: Any = None) -> Iterator[ProcessPoolExecutor]:
    """A ``ProcessPoolExecutor`` whose workers ignore Ctrl-C and are terminated when the block
    ends with an exception (Ctrl-C, SIGTERM as ``KeyboardInterrupt``, an error)."""
    pool = ProcessPoolExecutor(
        max_workers=workers, mp_context=mp_context, initializer=_ignore_interrupts
    )
    try:
        yield pool
    except BaseException:
        _stop(pool)
        raise
    pool.shutdown(wait=True)


class Executor(Protocol):
    """Runs ``fn`` over ``items``, yielding ``(index, outcome)`` as each finishes. ``imap``
    returns a generator: closing it (``contextlib.closing``) stops the runs still going, so a
    caller interrupted between two outcomes leaves no worker behind."""

    def imap(
        self, fn: Callable[[Any], Any], items: Sequence[Any]
    ) -> Iterator[tuple[int, Outcome]]: ...


class SerialExecutor:
    """Runs items one after another in this process (deterministic order)."""

    workers = 1

    def imap(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> Iterator[tuple[int, Outcome]]:
        for i, item in enumerate(items):
            yield i, _call(fn, item)


class ProcessExecutor:
    """Runs items in a pool of ``workers`` processes (``spawn`` start method).

    ``fn`` and the items must be picklable (module-level function, plain data). If a worker
    dies, every item it left unfinished is rerun alone in a fresh one-process pool, so only
    the item that kills its process is ``Failed``.
    """

    def __init__(self, workers: int | None = None) -> None:
        self.workers = max(1, workers or os.cpu_count() or 1)

    def imap(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> Iterator[tuple[int, Outcome]]:
        ctx = mp.get_context("spawn")
        broken: list[int] = []
        n = min(self.workers, len(items))
        if n == 0:
            return
        with process_pool(n, ctx) as pool:
            with spawning():
                futures: dict[Future, int] = {
                    pool.submit(_call, fn, item): i for i, item in enumerate(items)
                }
            waiting = set(futures)
            while waiting:
                done, waiting = wait(waiting, return_when=FIRST_COMPLETED)
                for fut in done:
                    try:
                        yield futures[fut], fut.result()
                    except BrokenProcessPool:
                        broken.append(futures[fut])
        for i in sorted(broken):
            try:
                with process_pool(1, ctx) as solo:
                    with spawning():
                        future = solo.submit(_call, fn, items[i])
                    outcome = future.result()
            except BrokenProcessPool:
                outcome = Failed("worker process died (crash or out of memory)")
            yield i, outcome


def make_executor(workers: int | None) -> Executor:
    """``workers`` = 1 → serial; None → one process per core; k > 1 → a pool of k."""
    if workers is not None and workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    if workers == 1:
        return SerialExecutor()
    return ProcessExecutor(workers)


def run_all(executor: Executor, fn: Callable[[Any], Any], items: Iterable[Any]) -> list[Outcome]:
    """All outcomes, in item order."""
    items = list(items)
    out: list[Outcome | None] = [None] * len(items)
    for i, o in executor.imap(fn, items):
        out[i] = o
    return out  # type: ignore[return-value]


__all__ = [
    "Executor",
    "Failed",
    "Ok",
    "Outcome",
    "ProcessExecutor",
    "SerialExecutor",
    "make_executor",
    "process_pool",
    "run_all",
    "spawning",
]
