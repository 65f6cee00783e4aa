"""A small executor interface for independent runs: serial (tests, debugging) or a process pool.

``Executor.imap(fn, items)`` yields ``(index, outcome)`` as runs finish, in any order, where
``outcome`` is ``Ok(value)`` or ``Failed(message)``. A run that raises becomes ``Failed`` and
the others go on; a worker process that dies (segfault, out of memory) fails the runs it had
not returned, never the whole batch.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import traceback
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
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
        with ProcessPoolExecutor(max_workers=n, mp_context=ctx) as pool:
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
                with ProcessPoolExecutor(max_workers=1, mp_context=ctx) as solo:
                    outcome = solo.submit(_call, fn, items[i]).result()
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
    "run_all",
]
