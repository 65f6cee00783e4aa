"""``servobot evolve navigation|coverage|colony``: the CGA stages from the command line.

A thin layer over ``evolve.stages`` and ``evolve.colony_stage``::

    servobot evolve navigation [--populations 5 --generations 1024 --population-size 256
                                --starts-per-generation 40 --seed 0
                                --table paper|PATH --power paper|table
                                --envelope none|default|FILE.json --nav-start-power V
                                --nav-dock-tol DEG --nav-starts FILE.csv --first FILE
                                --out runs/evolve --resume
                                --executor serial|process|ray|ray:ADDRESS --workers N]
    servobot evolve coverage   [... --generations 512 ... --navigation FILE --first FILE]
    servobot evolve colony     [... as coverage ... --robots 3 --blocking cancel|slide
                                --colony-fitness squares|alive|per_step|docks|alive_docks
                                --alive-weight 8 --dock-weight 4 --dock-cap 2
                                --start-power-spread 0 --robots-unseen --contact-yaw 0
                                --sections shared|team|navigation|beside --team-from DIR
                                --coverage-from DIR --partners FILE[,FILE...]
                                --beside-robot K --first FILE]

Defaults are the paper's scale (SPEC §5, §6): ``navigation_ga_settings()`` for navigation,
``GASettings()`` for coverage and the colony (SPEC §7: ``ColonySettings``, ``--robots`` its
R, ``--blocking`` its table-world blocking rule, ``--colony-fitness`` what a colony run
scores, ``--alive-weight`` (with ``alive``), ``--dock-weight`` and ``--dock-cap`` (with
``docks``) its terms, ``--start-power-spread`` its robots' staggered start powers,
``--robots-unseen`` object sensors blind to the other robots, ``--contact-yaw`` the table
world's turn away from a robot that blocks a move, ``--sections`` one section
for every robot, a coevolved team of them, or the navigation section learned in the colony
under the coverage sections of ``--coverage-from``'s finalists, or one robot's section
(``--beside-robot``, default the last) beside robots carrying ``--partners``' (a coverer
learned for its team, or a liver learned beside a coverer);
``--nav-start-power``, ``--nav-dock-tol``, ``--nav-starts``: ``NavigationSettings.start_power_v``,
``dock_heading_tol_deg``, ``start_poses``).
``--navigation`` defaults to ``DIR/navigation/best.txt``; a 16-gene file (e.g. a
``coverage/best_pop{k}.txt``) is accepted too and its genes 8–15, the navigation section,
are used. Bad input (missing or malformed files, a bad gait table, impossible sizes, a run
folder holding another run or in use) prints one message and exits with code 2, without a
traceback (``servobot.cli.runner``); ``--force`` deletes the stage's own files in a folder
holding another run and starts afresh. Ctrl-C keeps the checkpoints and says how to resume (exit
130).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from evolve.envelope import NONE
from evolve.settings import (
    ALIVE_FITNESSES,
    BLOCKING_RULES,
    COLONY_FITNESSES,
    COLONY_SECTIONS,
    DOCK_FITNESSES,
    GASettings,
    WorldSettings,
    coverage_ga_settings,
    navigation_ga_settings,
)
from infra.bounds import check_int, check_nonnegative, check_workers
from infra.errors import InputError
from infra.executors import Executor
from infra.io import check_output_dir
from servobot.cli.options import (
    add_envelope_option,
    add_executor_option,
    add_ga_options,
    comma_list,
    envelope_from_args,
    executor_from_args,
)
from servobot.cli.runner import run_main
from servobot.progress import GenerationBars

PROG = "servobot evolve"
DEFAULT_OUT = Path("runs/evolve")
"""Default run folder of ``--out``."""


class CliError(InputError, ValueError):
    """Bad command-line input; the message is printed as is."""


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``servobot evolve``."""
    p = argparse.ArgumentParser(
        prog="servobot evolve",
        description="Run a CGA stage on the table simulation: navigation (the docking "
        "section), then coverage (the area-coverage section with the navigation fixed), or "
        "colony (coverage learned by a colony of robots sharing the station).",
    )
    p.add_argument("stage", choices=("navigation", "coverage", "colony"), help="which stage to run")
    add_ga_options(p, "1024 for navigation, 512 for coverage and colony")
    p.add_argument(
        "--table", default="paper", help="gait table: 'paper' (Figure 4) or a calibration JSON"
    )
    p.add_argument(
        "--out", type=Path, default=DEFAULT_OUT, help=f"run folder (default {DEFAULT_OUT})"
    )
    p.add_argument(
        "--resume", action="store_true", help="continue from the checkpoints in the run folder"
    )
    p.add_argument(
        "--force",
        action="store_true",
        help="the stage's folder holds another run: delete that run's files (only those) and "
        "start afresh",
    )
    p.add_argument(
        "--navigation",
        type=Path,
        default=None,
        help="coverage and colony: navigation section file (default DIR/navigation/best.txt)",
    )
    p.add_argument(
        "--robots", type=int, default=None, help="colony only: robots sharing the station (3)"
    )
    p.add_argument(
        "--blocking",
        choices=BLOCKING_RULES,
        default=None,
        help="colony only: a move another robot blocks is cancelled (the robot keeps its "
        "pose; SPEC §7, default) or slides along the contact tangent (its component into "
        "the other robot removed, as frictionless physics bumpers do); docs/colony.md",
    )
    p.add_argument(
        "--start-power-spread",
        type=float,
        default=None,
        metavar="V",
        help="colony only: robot i starts with 4.0 + i × V volts, capped at the charged 5.0 V "
        "(0, default: every robot on 4.0 V; 0.5: 4.0, 4.5, 5.0 V); "
        "ColonySettings.start_power_spread, docs/colony.md",
    )
    p.add_argument(
        "--contact-yaw",
        type=float,
        default=None,
        metavar="DEG",
        help="colony only, table world: a blocked move also turns the robot away from each "
        "robot that blocks it, DEG degrees for one abeam (ColonySettings.contact_yaw_deg; 0, "
        "default; 9.3 measured in MuJoCo: python -m calibration.contact_yaw)",
    )
    p.add_argument(
        "--robots-unseen",
        action="store_true",
        default=None,
        help="colony only: the object sensors do not see the other robots (they still block "
        "moves; in MuJoCo the rangefinder rays pass above them). Default: seen, SPEC §7; "
        "ColonySettings.robots_seen, docs/colony.md",
    )
    p.add_argument(
        "--sections",
        choices=COLONY_SECTIONS,
        default=None,
        help="colony only: every robot carries one evolved coverage section (shared, default; "
        "SPEC §7) or each its own, evolved by cooperative coevolution: a team of R "
        "populations per population, R × the runs (team); or the colony learns the "
        "navigation section, from --navigation, under --coverage-from's coverage sections "
        "(navigation); or the last robot's coverage section beside robots carrying --partners' "
        "(beside); ColonySettings.sections, docs/colony.md",
    )
    p.add_argument(
        "--partners",
        type=_paths,
        default=None,
        metavar="FILE[,FILE...]",
        help="colony, --sections beside: robots 0 … R−2 carry the coverage section of this "
        "16-gene chromosome (its navigation section must be --navigation's); the stage learns "
        "robot R−1's. Or R−1 files, comma-separated: the other robots' chromosomes in robot "
        "order, the learned robot left out; docs/colony.md",
    )
    p.add_argument(
        "--beside-robot",
        type=int,
        default=None,
        metavar="K",
        help="colony, --sections beside: the robot whose coverage section the stage learns "
        "(0 … R−1; default the last, R−1)",
    )
    p.add_argument(
        "--first",
        type=Path,
        default=None,
        metavar="FILE",
        help="navigation: every individual of generation 0 carries this file's navigation "
        "section (8 genes, or genes 8–15 of 16) instead of a random one; coverage, and colony "
        "with --sections beside: this 16-gene chromosome's coverage section (genes 0–7, e.g. a "
        "finalist evolved in another envelope, or the team's current section of the learned "
        "robot)",
    )
    p.add_argument(
        "--coverage-from",
        type=Path,
        default=None,
        metavar="DIR",
        help="colony, --sections navigation: population k's robots carry the coverage section "
        "of the finished colony run DIR's finalist k (DIR/colony/best_pop{k}.txt); every "
        "individual starts as the --navigation section; docs/colony.md",
    )
    p.add_argument(
        "--team-from",
        type=Path,
        default=None,
        metavar="DIR",
        help="colony, --sections team: start team t's every population from population t of "
        "the finished shared colony run DIR (its final population, best first) instead of "
        "at random; docs/colony.md",
    )
    p.add_argument(
        "--colony-fitness",
        choices=COLONY_FITNESSES,
        default=None,
        help="colony only: what a colony run scores: its squares (default), its squares + "
        "8 × the fraction of robots live at the end ('alive'), or its squares per robot step "
        "scaled by R × 600 ('per_step'), or its squares + 4 × the docks per robot, each "
        "robot's capped at 2 ('docks'), or both terms ('alive_docks'); "
        "ColonySettings.fitness, docs/colony.md",
    )
    p.add_argument(
        "--alive-weight",
        type=float,
        default=None,
        help="colony, --colony-fitness alive or alive_docks: squares that every robot live at "
        "the end adds (8; ColonySettings.alive_weight)",
    )
    p.add_argument(
        "--dock-weight",
        type=float,
        default=None,
        help="colony, --colony-fitness docks or alive_docks: squares per dock per robot (4; "
        "ColonySettings.dock_weight)",
    )
    p.add_argument(
        "--dock-cap",
        type=int,
        default=None,
        help="colony, --colony-fitness docks or alive_docks: docks per robot and run that "
        "count (2; ColonySettings.dock_cap)",
    )
    p.add_argument(
        "--nav-start-power",
        type=float,
        default=None,
        metavar="V",
        help="navigation only: store (V) at the start of every run of the stage (default 4.0, "
        "SPEC §6); below 4.0 (e.g. 3.99) the low-power sensor is on from the start, as at every "
        "hand-off from coverage (NavigationSettings.start_power_v, docs/envelope.md)",
    )
    p.add_argument(
        "--nav-starts",
        type=Path,
        default=None,
        metavar="FILE.csv",
        help="navigation only: every run of the stage (training, selection, test) starts from a "
        "pose of this CSV (columns x, y, h; e.g. a coverage run's handoffs.csv), drawn with "
        "replacement, instead of SPEC §6's region (NavigationSettings.start_poses, "
        "docs/robustness.md)",
    )
    p.add_argument(
        "--nav-dock-tol",
        type=float,
        default=None,
        metavar="DEG",
        help="navigation only: dock within ± DEG of the station's heading in every run of the "
        "stage (default 30, SPEC §3); a stricter band (20) trains sections that arrive squarer "
        "to the station (NavigationSettings.dock_heading_tol_deg, docs/envelope.md)",
    )
    p.add_argument(
        "--power",
        choices=("paper", "table"),
        default="paper",
        help="power model: 'paper' (0.0209 V per cycle, gait 7 free; default) or 'table' "
        "(each gait costs the dV measured in --table)",
    )
    add_envelope_option(p)
    add_executor_option(
        p, "serial", "serial (one population after another: the kernel uses every core)"
    )
    p.add_argument(
        "--workers", type=int, default=None, help="processes or Ray CPUs (default: one per core)"
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    return p


def executor(args: argparse.Namespace) -> Executor | None:
    """Where the populations evolve: None = here (live progress), else an executor."""
    check_workers(args.workers)
    return None if args.executor == "serial" else executor_from_args(args)


def ga_settings(args: argparse.Namespace) -> GASettings:
    """The stage's GA settings with the command-line overrides applied."""
    if args.stage == "navigation":
        base = navigation_ga_settings()
    elif args.stage == "coverage":
        base = coverage_ga_settings(in_envelope=envelope_from_args(args) != NONE)
    else:
        base = GASettings()
    over: dict[str, Any] = {}
    for field, value in (
        ("populations", args.populations),
        ("generations", args.generations),
        ("population_size", args.population_size),
        ("starts_per_generation", args.starts_per_generation),
        ("seed", args.seed),
    ):
        if value is not None:
            over[field] = value
    ga = dataclasses.replace(base, **over)
    if ga.populations < 1:
        raise CliError(f"--populations must be ≥ 1, got {ga.populations}")
    if ga.population_size < 2:
        raise CliError(f"--population-size must be ≥ 2, got {ga.population_size}")
    if ga.generations < 1:
        raise CliError(f"--generations must be ≥ 1, got {ga.generations}")
    if ga.starts_per_generation < 1:
        raise CliError(f"--starts-per-generation must be ≥ 1, got {ga.starts_per_generation}")
    if ga.seed < 0:
        raise CliError(f"--seed must be ≥ 0, got {ga.seed}")
    return ga


def _paths(text: str) -> list[Path]:
    """``FILE[,FILE...]`` as paths (``--partners``)."""
    paths = [Path(f) for f in comma_list(text)]
    if not paths:
        raise argparse.ArgumentTypeError("no file named")
    return paths


def load_navigation(path: Path, *, given: bool = True, option: str = "--navigation") -> np.ndarray:
    """The navigation section of ``path`` (``evolve.stages.navigation_section``): the file
    ``option`` names (``given``) or the default ``DIR/navigation/best.txt``."""
    from evolve.codec import read_chromosome
    from evolve.stages import navigation_section

    if not path.exists() and not path.is_symlink():
        if given:
            raise CliError(f"{option} {path}: no such file")
        raise CliError(
            f"{path}: no navigation section file; run 'servobot evolve navigation' with the "
            "same --out first, or give --navigation FILE"
        )
    return navigation_section(read_chromosome(path))


def _print_navigation(summary: dict[str, Any], out: Path) -> None:
    steps = summary["mean_steps_to_dock"]
    sel = summary["selection"]
    print(
        f"navigation: chosen generation {summary['chosen_generation']} of population "
        f"{summary['chosen_population']} (of {len(summary['candidates'])} candidates, by "
        f"{sel['criterion']}: docked {sel['dock_rate']:.0%} of {sel['selection_starts']} "
        f"selection starts); test fitness {summary['test_fitness']:.3f}, docked "
        f"{summary['dock_success']:.0%} of {summary['test_starts']} fresh starts"
        + (f", mean {steps:.1f} steps to dock" if steps is not None else "")
    )
    if "envelope_dock_success" in summary:
        envelope_dock = summary["envelope_dock_success"]
        print(f"  in its envelope (same test starts): docked {envelope_dock:.0%}")
    if "spec_dock_success" in summary:
        print(f"  docking within SPEC §3's band (same test starts): docked "
              f"{summary['spec_dock_success']:.0%}")  # fmt: skip
    for p in summary["populations"]:
        print(
            f"  population {p['population']} (final best): test fitness "
            f"{p['test_fitness']:.3f}, docked {p['dock_rate']:.0%}"
        )
    print(f"wrote {out / 'navigation' / 'best.txt'} ({summary['wall_s']:.1f} s)")


def _figure9(summary: dict[str, Any]) -> str:
    """Figure 9 at the last generation: the mean and each population's inner coverage (and the
    mean in the stage's envelope, on the same test starts, for a stage evolved in one)."""
    per = ", ".join(f"{v:.1f}" for v in summary["final_inner_percent"])
    text = (
        f"Figure 9 at generation {summary['generations'][-1]}: mean "
        f"{summary['final_mean_inner_percent']:.1f}% of the 64 inner squares (populations: {per})"
    )
    if "envelope_final_mean_inner_percent" in summary:
        text += f"; in its envelope {summary['envelope_final_mean_inner_percent']:.1f}%"
    return text


def _print_coverage(summary: dict[str, Any], out: Path) -> None:
    print(f"coverage: {_figure9(summary)}")
    ho = summary["handoffs"]["all"]
    if ho["dock_rate"] is not None:
        print(
            f"  navigation docked after {ho['dock_rate']:.0%} of the finalists' "
            f"{ho['docked'] + ho['failed']} hand-offs on the test starts ({ho['cut']} cut by the "
            "step limit)"
        )
    for f in summary["figure10"]:
        print(
            f"  Figure 10 population {f['population']}: {f['squares']} squares "
            f"({f['inner_squares']} inner), {f['docks']} docks, end: {f['end']}"
        )
    print(f"wrote {out / 'coverage'} and {out / 'figure8.png'} ({summary['wall_s']:.1f} s)")


def _print_colony(summary: dict[str, Any], out: Path) -> None:
    print(
        f"colony of {summary['robots']}: {_figure9(summary)}; the same bests alone: "
        f"{summary['one_robot_final_mean_inner_percent']:.1f}%"
    )
    for t in summary["final_test"]:
        print(
            f"  population {t['population']}: per robot {t['robot_inner_percent']:.1f}%, "
            f"{t['docks_per_robot']:.1f} docks/robot, {t['station_waits_per_run']:.1f} station "
            f"waits and {t['collisions_per_run']:.1f} blocked moves per run, "
            f"{t['live_at_end_per_run']:.2f} of {summary['robots']} robots live at the end"
        )
    print(f"wrote {out / 'colony'} ({summary['wall_s']:.1f} s)")


def _colony(args: argparse.Namespace) -> Any:
    from evolve.settings import ColonySettings

    kw: dict[str, Any] = {} if args.blocking is None else {"blocking": args.blocking}
    if args.colony_fitness is not None:
        kw["fitness"] = args.colony_fitness
    if args.sections is not None:
        kw["sections"] = args.sections
    for flag, field, fitnesses in FITNESS_TERMS:
        value = getattr(args, field)
        if value is None:
            continue
        if args.colony_fitness not in fitnesses:
            raise CliError(f"{flag} is an option of --colony-fitness {' or '.join(fitnesses)}")
        if field == "dock_cap":
            check_int(value, flag, lo=1)
        else:
            check_nonnegative(value, flag, "squares")
        kw[field] = value
    if args.start_power_spread is not None:
        kw["start_power_spread"] = check_nonnegative(args.start_power_spread,
                                                     "--start-power-spread", "volts")  # fmt: skip
    if args.robots_unseen:
        kw["robots_seen"] = False
    if args.contact_yaw is not None:
        kw["contact_yaw_deg"] = check_nonnegative(args.contact_yaw, "--contact-yaw", "degrees")
    if args.robots is None:
        return ColonySettings(**kw)
    check_int(args.robots, "--robots", lo=1)
    return ColonySettings(robots=args.robots, **kw)


FITNESS_TERMS = (
    ("--alive-weight", "alive_weight", ALIVE_FITNESSES),
    ("--dock-weight", "dock_weight", DOCK_FITNESSES),
    ("--dock-cap", "dock_cap", DOCK_FITNESSES),
)
"""(option, ``ColonySettings`` field, the ``--colony-fitness`` values that read it)."""


STAGE_OPTIONS = (
    ("robots", "colony"), ("blocking", "colony"), ("start_power_spread", "colony"),
    ("colony_fitness", "colony"), ("sections", "colony"), ("robots_unseen", "colony"),
    ("contact_yaw", "colony"),
    ("nav_start_power", "navigation"), ("nav_dock_tol", "navigation"),
    ("nav_starts", "navigation"),
)  # fmt: skip
"""(option's field, the one stage that takes it): refused with any other stage."""


def _run(args: argparse.Namespace, bars: GenerationBars) -> int:
    from evolve import stages
    from evolve.table import load_table, with_power_model

    for field, stage in STAGE_OPTIONS:
        if getattr(args, field) is not None and args.stage != stage:
            flag = "--" + field.replace("_", "-")
            raise CliError(f"{flag} is an option of the {stage} stage")
    if args.team_from is not None and args.sections != "team":
        raise CliError("--team-from is an option of the colony stage with --sections team")
    if (args.coverage_from is not None) != (args.sections == "navigation"):
        raise CliError("--sections navigation needs --coverage-from DIR, and --coverage-from "
                       "is an option of the colony stage with --sections navigation")  # fmt: skip
    if (args.partners is not None) != (args.sections == "beside"):
        raise CliError("--sections beside needs --partners FILE, and --partners is an option of "
                       "the colony stage with --sections beside")  # fmt: skip
    if args.beside_robot is not None and args.sections != "beside":
        raise CliError("--beside-robot is an option of the colony stage with --sections beside")
    if args.first is not None and args.stage == "colony" and args.sections != "beside":
        raise CliError("--first is an option of the navigation and coverage stages and of the "
                       "colony stage with --sections beside")  # fmt: skip
    colony = _colony(args)
    ga = ga_settings(args)
    table = load_table(args.table)
    world = with_power_model(WorldSettings(), args.power, table)
    check_output_dir(args.out, option="--out")
    kw = dict(table=table, ga=ga, world=world, resume=args.resume, force=args.force,
              on_generation=bars, executor=executor(args),
              envelope=envelope_from_args(args))  # fmt: skip
    if args.stage == "navigation":
        if args.navigation is not None:
            raise CliError("--navigation is an option of the coverage and colony stages")
        poses = None
        if args.nav_starts is not None:
            from evolve.handoff import read_poses

            poses = tuple(map(tuple, read_poses(args.nav_starts)[0].tolist()))
        nav = stages.NavigationSettings(start_power_v=args.nav_start_power,
                                        dock_heading_tol_deg=args.nav_dock_tol,
                                        start_poses=poses)  # fmt: skip
        first = None if args.first is None else load_navigation(args.first, option="--first")
        summary = stages.run_navigation(args.out, navigation=nav, first=first, **kw)
        _print_navigation(summary, args.out)
        return 0
    navigation = load_navigation(args.navigation or args.out / "navigation" / "best.txt",
                                 given=args.navigation is not None)  # fmt: skip
    from evolve.colony_stage import coverage_section

    first = None if args.first is None else coverage_section(args.first, option="--first")
    if args.stage == "coverage":
        summary = stages.run_coverage(args.out, navigation=navigation, first=first, **kw)
        _print_coverage(summary, args.out)
    else:
        from evolve.colony_stage import run_colony_stage

        team_from = coverage = None
        if args.team_from is not None:
            from evolve.coevolution import shared_populations

            team_from = shared_populations(args.team_from, ga)
        if args.coverage_from is not None:
            from evolve.colony_stage import finalists_coverage

            coverage = finalists_coverage(args.coverage_from, ga.populations)
        partners = None
        if args.partners is not None:
            sections = [coverage_section(f, navigation) for f in args.partners]
            partners = sections[0] if len(sections) == 1 else np.stack(sections)
        summary = run_colony_stage(args.out, navigation=navigation, colony=colony,
                                   team_from=team_from, coverage=coverage, partners=partners,
                                   first=first, robot=args.beside_robot, **kw)  # fmt: skip
        _print_colony(summary, args.out)
    return 0


def run_evolution(
    prog: str,
    parser: argparse.ArgumentParser,
    argv: list[str] | None,
    run: Callable[[argparse.Namespace, GenerationBars], int],
    kept: Callable[[argparse.Namespace], str],
) -> int:
    """The ``main`` of a command that evolves populations (``servobot.cli.runner.run_main``):
    ``run(args, bars)`` with progress bars unless ``--no-progress``; Ctrl-C resumes with
    ``--resume`` (and without ``--force``)."""

    def body(args: argparse.Namespace, _command: str) -> int:
        with contextlib.closing(GenerationBars(enabled=not args.no_progress)) as bars:
            return run(args, bars)

    return run_main(prog, parser, argv, body, kept, extra=["--resume"], drop=["--force"])


def main(argv: list[str] | None = None) -> int:
    """Run ``servobot evolve``; returns the exit code (0 ok, 2 bad input, 130 interrupted)."""

    def kept(args: argparse.Namespace) -> str:
        ckpt = args.out / args.stage / "checkpoints"
        return f"the checkpoints in {ckpt}" if ckpt.is_dir() else "nothing yet"

    return run_evolution(PROG, build_parser(), argv, _run, kept)


if __name__ == "__main__":
    sys.exit(main())
