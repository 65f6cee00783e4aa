"""A ``servobot`` subcommand's ``main``: ``run_main(prog, parser, argv, body, kept)`` parses the
arguments (argparse exits 2 on a malformed option), checks the options several commands share
and hands the rest to ``infra.command.run_command``, which maps how the command ends to an
exit code and a message (bad input 2, Ctrl-C 130, SIGTERM 143 with what is kept and how to
resume)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence

from infra.command import Interrupted, command_line, run_command


def run_main(
    prog: str,
    parser: argparse.ArgumentParser,
    argv: Sequence[str] | None,
    body: Callable[[argparse.Namespace, str], int | None],
    kept: Callable[[argparse.Namespace], str],
    *,
    extra: Sequence[str] = (),
    drop: Sequence[str] = (),
    again: str | None = None,
) -> int:
    """A subcommand's ``main``: parse ``argv`` (None: ``sys.argv[1:]``) and ``run_command``
    ``body(args, command)``, ``command`` being the command line as typed. Interrupted, it says
    that ``kept(args)`` is kept and resumes with the command line less ``drop`` plus
    ``extra``, and ``again`` in parentheses (e.g. "the calibration starts again"). The options
    several commands share (``--model``, ``--executor``) are checked before ``body`` runs
    (``servobot.cli.options.check_shared_options``)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(argv)
    command = command_line(prog, argv)

    def interrupted() -> Interrupted:
        resume = command_line(prog, argv, *extra, drop=drop)
        return Interrupted(kept(args), resume if again is None else f"{resume} ({again})")

    def checked_body() -> int | None:
        from servobot.cli.options import check_shared_options

        check_shared_options(args)  # --model, --executor: before any work
        return body(args, command)

    return run_command(prog, checked_body, interrupted)


__all__ = ["run_main"]
