"""The ``servobot`` command: a dispatcher over one module per subcommand.

Each subcommand module only parses arguments, calls its library function and prints; the
modules are imported lazily so that ``servobot evolve`` never imports MuJoCo.
"""

from __future__ import annotations

import importlib
import sys

COMMANDS: dict[str, tuple[str, str]] = {
    "calibrate": ("servobot.cli.calibrate", "regenerate the gait table (Figure 4) from MuJoCo"),
    "evolve": ("servobot.cli.evolve", "run the CGA: navigation or coverage stage"),
    "anytime": ("servobot.cli.anytime", "coverage learning corrected by physics punctuations"),
    "trace": ("servobot.cli.trace", "print (and record) a controller's run step by step"),
    "validate": ("servobot.cli.validate", "run a chromosome in the table simulation and physics"),
    "robustness": ("servobot.cli.robustness", "run chromosomes in named physics worlds (a matrix)"),
    "reproduce": ("servobot.cli.reproduce", "the end-to-end reproduction into one run folder"),
    "variant": ("servobot.cli.variant", "write a ServoBot variant (mass, legs, servos, friction)"),
    "compare": ("servobot.cli.compare", "compare gait tables side by side (PNG + CSV)"),
}


def _usage() -> str:
    lines = ["usage: servobot COMMAND [options]", "", "commands:"]
    lines += [f"  {name:<10} {help_}" for name, (_, help_) in COMMANDS.items()]
    lines += ["", "Run 'servobot COMMAND --help' for a command's options."]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help"):
        print(_usage())
        return 0 if argv else 2
    name, rest = argv[0], argv[1:]
    if name not in COMMANDS:
        print(f"servobot: unknown command {name!r}\n\n{_usage()}", file=sys.stderr)
        return 2
    try:
        module = importlib.import_module(COMMANDS[name][0])
        return int(module.main(rest) or 0)
    except KeyboardInterrupt:  # before the command's own handler (servobot.cli.runner) took over
        print(f"\nservobot {name}: interrupted before it started; nothing written", file=sys.stderr)
        return 130
