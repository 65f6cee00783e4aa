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

Interrupts: worker processes ignore Ctrl-C from birth (they are started inside
``spawning()``); the main process gets the ``KeyboardInterrupt``, cancels the runs not
started and terminates the workers before it re-raises (``process_pool``), so Ctrl-C stops a
batch at once, with no traceback from any worker.
"""

from __future__ import annotations

import ipaddress
import logging
import multiprocessing as mp
import os
import re
import signal
import socket
import threading
import time
import traceback
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Protocol

from infra.errors import InputError

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


class ExecutorError(InputError, RuntimeError):
    """An executor cannot start: Ray missing, or its cluster cannot be joined."""


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
def process_pool(
    workers: int,
    mp_context: Any = None,
    *,
    initializer: Callable[..., None] = _ignore_interrupts,
    initargs: tuple = (),
) -> Iterator[ProcessPoolExecutor]:
    """A ``ProcessPoolExecutor`` whose workers ignore Ctrl-C (``initializer`` must call
    ``_ignore_interrupts``) and are terminated when the block ends with an exception (Ctrl-C,
    SIGTERM as ``KeyboardInterrupt``, an error)."""
    pool = ProcessPoolExecutor(
        max_workers=workers, mp_context=mp_context, initializer=initializer, initargs=initargs
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


_started: Any = None
"""In a pool worker: the queue on which it announces each item it starts."""


def _init_worker(started: Any) -> None:
    """Pool initializer: ignore Ctrl-C (``_ignore_interrupts``), then keep the queue on which
    the worker announces each item it starts."""
    global _started
    _ignore_interrupts()
    _started = started


def _call_announced(fn: Callable[[Any], Any], item: Any, index: int) -> Outcome:
    _started.put(index)
    return _call(fn, item)


class ProcessExecutor:
    """Runs items in a pool of ``workers`` processes (``spawn`` start method; None = one per
    core). A worker that dies breaks the whole pool; every item the pool left unfinished is
    then rerun alone in a fresh one-process pool — once if it was the only unfinished item
    that had started (its worker is the one that died), up to twice otherwise (the pool's
    break may have killed a started item before it got far) — so only an item that kills its
    process twice is ``Failed``.
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
        with process_pool(n, ctx, initializer=_init_worker, initargs=(started,)) as pool:
            with spawning():
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
        started_unfinished = [i for i in broken if i in ran]
        for i in sorted(broken):
            tries = 1 if started_unfinished == [i] else 2
            yield i, _run_alone(fn, items[i], ctx, tries=tries)


def _run_alone(fn: Callable[[Any], Any], item: Any, ctx: Any, tries: int) -> Outcome:
    """``item`` in a fresh one-process pool, up to ``tries`` times while its worker dies."""
    for _ in range(tries):
        try:
            with process_pool(1, ctx) as solo:
                with spawning():
                    future = solo.submit(_call, fn, item)
                return future.result()
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
        if self.address is not None:  # a cluster that does not answer: stop now, not retry
            parse_spec(f"ray:{self.address}").reach()
        kwargs: dict[str, Any] = {"logging_level": logging.WARNING}
        if self.address is None:  # "local": a new instance, even if a cluster runs here
            kwargs |= {"address": "local", "num_cpus": self.workers, "include_dashboard": False}
        else:
            kwargs["address"] = self.address
        try:
            ray.init(**kwargs)
        except ConnectionError as exc:
            raise ExecutorError(
                f"--executor ray:{self.address}: cannot join the Ray cluster at {self.address}: "
                f"{exc}. Is 'ray start --head' "
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
        try:
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
        finally:  # closed early (Ctrl-C, an error): stop the tasks still queued or running
            for ref in pending:
                ray.cancel(ref, force=True)


RAY_PROBE_TIMEOUT_S = 5.0
"""How long ``ExecutorSpec.reach`` waits for a Ray cluster's port to answer, s."""
_HOSTNAME = re.compile(r"[A-Za-z0-9_]([A-Za-z0-9_-]{0,61}[A-Za-z0-9_])?")
_FORMS = "serial, process, ray or ray:ADDRESS (a Ray cluster)"
_ADDRESS_FORMS = "ADDRESS must be auto, HOST:PORT or ray://HOST:PORT (PORT 1-65535)"


class ExecutorSpecError(ExecutorError, ValueError):
    """An ``--executor`` value that names no executor, or a Ray address of the wrong form."""


@dataclass(frozen=True)
class ExecutorSpec:
    """A checked executor spec (``parse_spec``): ``kind`` serial, process or ray; for a Ray
    cluster, ``address`` as ``ray.init(address=...)`` takes it and, unless it is ``auto``,
    its ``host`` and ``port`` (probed by ``reach`` before Ray is asked to join)."""

    kind: str
    address: str | None = None
    host: str | None = None
    port: int | None = None

    def __str__(self) -> str:
        return self.kind if self.address is None else f"ray:{self.address}"

    def reach(self, timeout_s: float = RAY_PROBE_TIMEOUT_S) -> None:
        """For a Ray cluster at HOST:PORT, check within ``timeout_s`` seconds that a Ray server
        answers there, so that an unreachable cluster stops a command at once instead of Ray
        retrying for long: connect to the port and say hello as a gRPC client (Ray's GCS and
        its client server speak gRPC: an HTTP/2 server answers the client preface with its
        SETTINGS frame). ``ExecutorError`` naming ``--executor`` otherwise. Nothing to do for
        the other specs (``ray:auto`` fails fast in Ray itself); with ``RAY_USE_TLS`` set only
        the connection is checked."""
        if self.host is None or self.port is None:
            return
        where = f"{self.host}:{self.port}"
        deadline = time.monotonic() + timeout_s
        try:
            with socket.create_connection((self.host, self.port), timeout=timeout_s) as sock:
                if os.environ.get("RAY_USE_TLS", "0").lower() not in ("", "0", "false"):
                    return
                sock.settimeout(max(deadline - time.monotonic(), 0.001))
                sock.sendall(_H2_HELLO)
                head = b""
                while len(head) < 9:
                    sock.settimeout(max(deadline - time.monotonic(), 0.001))
                    chunk = sock.recv(9 - len(head))
                    if not chunk:
                        break
                    head += chunk
            if len(head) == 9 and head[3] == _H2_SETTINGS:
                return
            why = "the port answers, but not as a Ray (gRPC) server"
        except TimeoutError:
            why = f"timed out after {timeout_s:g} s"
        except socket.gaierror as exc:
            why = f"cannot resolve host {self.host!r}: {exc.strerror or exc}"
        except OSError as exc:
            why = exc.strerror or str(exc) or "unreachable"
            why = why[0].lower() + why[1:]
        raise ExecutorError(
            f"--executor {self}: no Ray cluster answers at {where} ({why}); start one with "
            "'ray start --head' there, or pick serial, process or ray (docs/executors.md)"
        )


_H2_HELLO = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + bytes([0, 0, 0, 4, 0, 0, 0, 0, 0])
"""An HTTP/2 client's connection preface followed by an empty SETTINGS frame."""
_H2_SETTINGS = 4
"""HTTP/2 frame type of SETTINGS: a server's first frame (RFC 9113 §3.4)."""


def _host_port(text: str, spec: str) -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    if not sep or not host:
        raise ExecutorSpecError(f"{spec}: {_ADDRESS_FORMS}")
    if host.startswith("[") and host.endswith("]"):
        try:
            ipaddress.IPv6Address(host[1:-1])
        except ValueError:
            raise ExecutorSpecError(f"{spec}: {host} is not an IPv6 address; "
                                    f"{_ADDRESS_FORMS}") from None  # fmt: skip
        host = host[1:-1]
    elif len(host) > 253 or not all(_HOSTNAME.fullmatch(label) for label in host.split(".")):
        raise ExecutorSpecError(f"{spec}: {host!r} is not a host name or IP "
                                f"address; {_ADDRESS_FORMS}")  # fmt: skip
    if not (port.isascii() and port.isdigit()) or not 1 <= int(port) <= 65535:
        raise ExecutorSpecError(f"{spec}: port {port!r} is not a number 1-65535; "
                                f"{_ADDRESS_FORMS}")  # fmt: skip
    return host, int(port)


def parse_spec(spec: Any) -> ExecutorSpec:
    """The ``ExecutorSpec`` of ``spec`` (``EXECUTOR_SPECS``): ``serial``, ``process``, ``ray``,
    or ``ray:ADDRESS`` where ADDRESS is ``auto``, ``HOST:PORT`` or ``ray://HOST:PORT`` (HOST a
    host name, an IPv4 address or a bracketed IPv6 one; PORT 1-65535). ``ExecutorSpecError``
    (a ``ValueError`` and an ``InputError``) naming ``--executor`` otherwise."""
    if isinstance(spec, ExecutorSpec):
        return spec
    if spec in ("serial", "process", "ray"):
        return ExecutorSpec(spec)
    if not isinstance(spec, str) or not spec.startswith("ray:") or len(spec) == 4:
        raise ExecutorSpecError(f"executor must be {_FORMS}, got {spec!r}")
    address = spec[4:]
    if address == "auto":
        return ExecutorSpec("ray", address)
    rest = address.removeprefix("ray://")
    host, port = _host_port(rest, spec)
    return ExecutorSpec("ray", address, host, port)


def check_spec(spec: str) -> str:
    """``spec`` if it names an executor (``parse_spec``), else ``ExecutorSpecError``."""
    return str(parse_spec(spec))


def make_executor(spec: str | None = "process", workers: int | None = None) -> Executor:
    """The executor ``spec`` names (``EXECUTOR_SPECS``) with ``workers`` processes or CPUs
    (None = one per core; ignored by ``serial`` and ``ray:ADDRESS``). ``spec`` None picks
    ``serial`` when ``workers`` is 1 and ``process`` otherwise. ``ValueError`` on a bad spec
    or ``workers`` < 1."""
    if workers is not None and workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    if spec is None:
        spec = "serial" if workers == 1 else "process"
    parsed = parse_spec(spec)
    if parsed.kind == "serial":
        return SerialExecutor()
    if parsed.kind == "process":
        return ProcessExecutor(workers)
    return RayExecutor(workers, address=parsed.address)


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
    "ExecutorSpec",
    "ExecutorSpecError",
    "Failed",
    "Ok",
    "Outcome",
    "ProcessExecutor",
    "RayExecutor",
    "SerialExecutor",
    "check_spec",
    "make_executor",
    "parse_spec",
    "process_pool",
    "run_in_order",
    "spawning",
    "values_or_raise",
]
