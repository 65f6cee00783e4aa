"""Options that several subcommands share: ``--executor`` of those that run batches
(``infra.executors``), ``--model`` of those that walk a robot model in physics, ``--envelope``
(``evolve.envelope``) of those that evolve, and their GA budget (``add_ga_options``)."""

from __future__ import annotations

import argparse
import importlib.util
from collections.abc import Callable
from pathlib import Path
from typing import Any

from evolve.envelope import Envelope, load_envelope
from infra.executors import (
    EXECUTOR_SPECS,
    Executor,
    RayExecutor,
    check_spec,
    make_executor,
    parse_spec,
)

METAVAR = "|".join(EXECUTOR_SPECS)
MODEL_HELP = "robot model file, e.g. from 'servobot variant' (default: the shipped ServoBot)"


def comma_list(text: str) -> tuple[str, ...]:
    """argparse type of a comma-separated list (``--worlds``, ``--partners``): its non-empty
    items, stripped; what they name is checked where they are used."""
    return tuple(w.strip() for w in text.split(",") if w.strip())


def executor_spec(text: str) -> str:
    """argparse type of ``--executor``: a valid spec, with Ray installed when it names Ray."""
    try:
        spec = check_spec(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from exc
    if spec.startswith("ray") and importlib.util.find_spec("ray") is None:
        raise argparse.ArgumentTypeError(
            f'{spec}: Ray is not installed; pip install -e ".[ray]" (or pip install ray)'
        )
    return spec


def add_executor_option(p: argparse.ArgumentParser, default: str | None, default_help: str) -> None:
    """Add ``--executor`` (default ``default``, described by ``default_help``)."""
    p.add_argument(
        "--executor",
        type=executor_spec,
        default=default,
        metavar=METAVAR,
        help="where the independent runs go: serial (here), process (a pool of --workers), "
        "ray (a local Ray instance of --workers CPUs) or ray:ADDRESS (a running Ray cluster, "
        f"see docs/executors.md); default: {default_help}",
    )


def add_model_option(
    p: argparse.ArgumentParser, help: str = MODEL_HELP, type: Callable[[str], Any] = Path
) -> None:
    """Add ``--model FILE`` (default None: the shipped ServoBot), read as ``type``."""
    p.add_argument("--model", type=type, default=None, metavar="FILE", help=help)


def check_model_option(model: Any) -> Any:
    """Read, compile and check the model of ``--model`` (``servo_mj.robot.model.check_model``,
    the one gate of every model file): a ``ModelFileError`` naming ``--model`` and the file,
    exit 2, before any work. Returns ``model`` unchanged (None: the shipped ServoBot)."""
    if model is None:
        return None
    from servo_mj.robot.model import check_model  # MuJoCo only for commands that take a model

    check_model(model, option="--model")
    return model


def check_shared_options(args: argparse.Namespace) -> None:
    """Before any work of a command (``servobot.cli.runner.run_main`` calls it): its
    ``--model`` is a usable ServoBot model, and a Ray cluster its ``--executor`` names answers
    (``ExecutorSpec.reach``, a few seconds at most). ``InputError`` naming the option."""
    check_model_option(getattr(args, "model", None))
    spec = getattr(args, "executor", None)
    if isinstance(spec, str):
        parse_spec(spec).reach()


def executor_from_args(args: argparse.Namespace) -> Executor:
    """The executor of ``--executor`` and ``--workers`` (already checked); a Ray one joins
    or starts Ray now, so that a cluster that cannot be reached stops the command before any
    work (an ``ExecutorError``, an ``InputError``: message, exit status 2)."""
    ex = make_executor(args.executor, args.workers)
    if isinstance(ex, RayExecutor):
        ex.connect()
    return ex


def add_envelope_option(p: argparse.ArgumentParser) -> None:
    """Add ``--envelope`` (SPEC §9): the variation the table world trains in."""
    p.add_argument(
        "--envelope",
        default="none",
        metavar="none|default|FILE.json",
        help="envelope of variation the table world trains in (SPEC §9): 'none' (the exact "
        "world of SPEC §3; default), 'default' (evolve.envelope.DEFAULT) or a JSON file of "
        "Envelope fields; tests report in the envelope and in the exact world",
    )


def envelope_from_args(args: argparse.Namespace) -> Envelope:
    """The ``Envelope`` of ``--envelope`` (an ``EnvelopeError``, exit 2, names a bad one)."""
    return load_envelope(args.envelope)


def add_ga_options(p: argparse.ArgumentParser, generations: str) -> None:
    """Add the options ``servobot.cli.evolve.ga_settings`` reads, each None = the stage's default:
    ``--populations``, ``--generations`` (its default described by ``generations``),
    ``--population-size``, ``--starts-per-generation`` and ``--seed``."""
    for flag, what in (
        ("--populations", "independent populations (default 5)"),
        ("--generations", f"generations (default {generations})"),
        ("--population-size", "individuals per population (256)"),
        (
            "--starts-per-generation",
            "training starts drawn anew each generation and shared by the population "
            "(default: 40 for navigation; 10 for coverage, 30 in an envelope other than "
            "none; 10 for the colony; GASettings)",
        ),
        ("--seed", "seed of every random draw (0)"),
    ):
        p.add_argument(flag, type=int, default=None, help=what)
