"""``python -m evolve``: the evolve and trace commands without the ``servobot`` script.

::

    python -m evolve evolve navigation|coverage [options]   # = servobot evolve ...
    python -m evolve trace FILE --start X Y H [options]     # = servobot trace ...
    python -m evolve navigation|coverage [options]          # shorthand for "evolve ..."
"""

from __future__ import annotations

import sys

USAGE = (
    "usage: python -m evolve {evolve,trace} ...\n"
    "       python -m evolve {navigation,coverage} ...   (shorthand for 'evolve ...')\n\n"
    "  evolve  run the CGA: navigation or coverage stage (see 'python -m evolve evolve -h')\n"
    "  trace   print (and record) a controller's run step by step"
)


def main(argv: list[str] | None = None) -> int:
    """Dispatch to ``evolve.cli.main`` or ``evolve.trace.main``; returns the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help"):
        print(USAGE)
        return 0 if argv else 2
    name, rest = argv[0], argv[1:]
    if name in ("navigation", "coverage"):
        name, rest = "evolve", argv
    if name == "evolve":
        from evolve import cli

        return cli.main(rest)
    if name == "trace":
        from evolve import trace

        return trace.main(rest)
    print(f"python -m evolve: unknown command {name!r}\n\n{USAGE}", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main())
