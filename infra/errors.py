"""The one base class of every error a user can cause: ``InputError``.

Anything a user types or points at that cannot be used — a file that cannot be read or
parsed, an option out of range, an output place that cannot be written, a run folder that
belongs to another run or is in use, settings whose memory or time cannot be met — raises a
subclass of ``InputError`` whose message names the file or option and the problem. The
command-line runner (``servobot.cli.runner``) prints that message and exits with status 2,
without a traceback; every other exception is a bug and keeps its traceback.

Each domain keeps its own subclass (``ChromosomeError``, ``GaitTableError``, ``StageError``,
...), usually also deriving from ``ValueError`` or ``RuntimeError`` so that existing
``except`` clauses keep working.
"""

from __future__ import annotations


class InputError(Exception):
    """Something the user typed or pointed at cannot be used; the message says what and why."""


__all__ = ["InputError"]
