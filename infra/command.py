"""How a command ends: ``run_command(prog, body, on_interrupt)``, which every ``servobot``
subcommand (through ``servobot.cli.runner.run_main``) and every ``python -m`` measurement
script runs its work in. It

- runs ``body()`` and returns its exit code (0 done, 1 a run failed, e.g. physics);
- turns an ``infra.errors.InputError`` (a file, option, output place, run folder or size that
  cannot be used) into ``prog: error: <message>`` on stderr and exit code 2, removing the
  output folders the command created and left empty (``infra.io.remove_created_folders``);
- turns ``MemoryError`` into a message and exit code 2 (the size checks should come first);
- ends quietly (exit 0) when stdout is a pipe whose reader stopped (``| head``);
- turns Ctrl-C into ``prog: interrupted; kept: ...; resume with: ...`` and exit code 130,
  and SIGTERM into the same message and exit code 143 (SIGTERM is raised in the main thread
  as ``Terminated``, a ``KeyboardInterrupt``, so every ``finally`` and ``with`` block runs:
  atomic writes finish or vanish, recordings are discarded, locks are released).

Any other exception is a bug and keeps its traceback, unless it came after a Ctrl-C or
SIGTERM: a library that turns the ``KeyboardInterrupt`` raised in its code into an error of
its own (numpy's structured ``np.unique`` makes it a ``TypeError``) still ends the command as
interrupted. A ``KeyboardInterrupt`` swallowed where Python cannot raise it (a callback of
numba's compiler: "Exception ignored ...") is delivered again, at the next line of Python.
"""

from __future__ import annotations

import _thread
import contextlib
import os
import shlex
import signal
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

from infra.errors import InputError
from infra.io import forget_created_folders, remove_created_folders

EXIT_FAILED = 1
"""A run finished but failed (e.g. physics blew up in some validation runs)."""
EXIT_USAGE = 2
"""Bad input: the message names the file or option (argparse's convention)."""
EXIT_INTERRUPTED = 130
"""Ctrl-C (128 + SIGINT, the shell's convention)."""
EXIT_TERMINATED = 143
"""SIGTERM (128 + SIGTERM)."""


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread so that cleanup runs as after Ctrl-C."""


@dataclass(frozen=True)
class Interrupted:
    """What an interrupted command tells the user."""

    kept: str
    """What is kept on disk (and what is not)."""
    resume: str
    """The command that resumes (or redoes) the run."""


def command_line(prog: str, argv: Sequence[str], *extra: str, drop: Sequence[str] = ()) -> str:
    """``prog`` and its arguments as one shell-quoted line, without the flags in ``drop`` and
    with ``extra`` appended unless already there (the resume command of an interrupted run:
    ``command_line("servobot evolve", argv, "--resume", drop=["--force"])``)."""
    args = [a for a in argv if a not in drop]
    args += [e for e in extra if e not in args]
    return " ".join([prog, *(shlex.quote(a) for a in args)])


_received: list[int] = []
"""The signals (SIGINT, SIGTERM) received while the command runs, in order."""
_again: list[threading.Timer] = []
"""Swallowed interrupts waiting to be raised again (cancelled when the command ends)."""

_DELIVER_AGAIN_AFTER_S = 0.05
"""How long after a swallowed ``KeyboardInterrupt`` it is raised again (s)."""


def _interrupt(signum: int, _frame: Any) -> None:
    _received.append(signum)
    raise Terminated if signum == signal.SIGTERM else KeyboardInterrupt


def _deliver_again(previous: Callable[[Any], Any]) -> Callable[[Any], Any]:
    """A ``sys.unraisablehook`` that hands a swallowed ``KeyboardInterrupt`` back to the main
    thread, ``previous`` the rest. The signal is raised again from another thread, a moment
    later (``_thread.interrupt_main``), so that it lands after the callback that swallowed it
    returned; should it land in another such callback, this repeats."""

    def hook(unraisable: Any) -> None:
        if issubclass(unraisable.exc_type, KeyboardInterrupt):
            sigterm = issubclass(unraisable.exc_type, Terminated)
            signum = signal.SIGTERM if sigterm else signal.SIGINT
            again = threading.Timer(_DELIVER_AGAIN_AFTER_S, _thread.interrupt_main, (signum,))
            again.daemon = True
            _again.append(again)
            again.start()
        else:
            previous(unraisable)

    return hook


@contextlib.contextmanager
def _interrupts_raised(main: bool) -> Iterator[None]:
    """While the block runs (main thread only): SIGTERM and Ctrl-C raise ``Terminated`` and
    ``KeyboardInterrupt`` and are noted in ``_received``, swallowed ones are delivered again.
    A Ctrl-C that this process ignores from birth (a background job) stays ignored."""
    if not main:
        yield
        return
    old_int = signal.getsignal(signal.SIGINT)
    old_term = signal.signal(signal.SIGTERM, _interrupt)
    if old_int is signal.default_int_handler:
        signal.signal(signal.SIGINT, _interrupt)
    old_hook, sys.unraisablehook = sys.unraisablehook, _deliver_again(sys.unraisablehook)
    _received.clear()
    try:
        yield
    finally:
        sys.unraisablehook = old_hook
        for again in _again:
            again.cancel()
        _again.clear()
        _received.clear()
        signal.signal(signal.SIGTERM, old_term if old_term is not None else signal.SIG_DFL)
        signal.signal(signal.SIGINT, old_int if old_int is not None else signal.SIG_DFL)
        # CPython notes a KeyboardInterrupt that escaped an exec() of source text (numba
        # compiles that way) and, at exit, kills the process with SIGINT although the
        # interrupt was handled here; each exec() of source text clears that note.
        exec("")


def _call(body: Callable[[], int | None]) -> int:
    """``body()``'s exit code; an error it raises after a Ctrl-C or SIGTERM is that interrupt
    (a library turned the ``KeyboardInterrupt`` raised in its code into an error of its own)."""
    try:
        return int(body() or 0)
    except Exception as exc:
        if not _received:
            raise
        raise (Terminated() if _received[0] == signal.SIGTERM else KeyboardInterrupt()) from exc


def run_command(
    prog: str, body: Callable[[], int | None], on_interrupt: Callable[[], Interrupted]
) -> int:
    """Run ``body`` and map how it ends to an exit code and a message (module docstring)."""
    main = threading.current_thread() is threading.main_thread()
    forget_created_folders()
    with _interrupts_raised(main):
        try:
            return _call(body)
        except InputError as exc:
            remove_created_folders()  # refused before any work: no empty --out left behind
            print(f"{prog}: error: {exc}", file=sys.stderr)
            return EXIT_USAGE
        except MemoryError:
            remove_created_folders()
            print(f"{prog}: error: out of memory; choose smaller sizes", file=sys.stderr)
            return EXIT_USAGE
        except BrokenPipeError:  # output piped into e.g. `head`: stop quietly, as Unix tools do
            with contextlib.suppress(OSError, ValueError):
                os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            return 0
        except KeyboardInterrupt as exc:
            if main:  # a second Ctrl-C must not cut the message short
                signal.signal(signal.SIGINT, signal.SIG_IGN)
            note = on_interrupt()
            print(
                f"\n{prog}: interrupted; kept: {note.kept}; resume with: {note.resume}",
                file=sys.stderr,
            )
            return EXIT_TERMINATED if isinstance(exc, Terminated) else EXIT_INTERRUPTED


__all__ = [
    "EXIT_FAILED",
    "EXIT_INTERRUPTED",
    "EXIT_TERMINATED",
    "EXIT_USAGE",
    "Interrupted",
    "Terminated",
    "command_line",
    "run_command",
]
