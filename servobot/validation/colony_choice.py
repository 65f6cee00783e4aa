"""The colony's finalist chosen by physics: ``python -m servobot.validation.colony_choice DIR
[--min-live L] [--by physics|table] [--confirm N [--confirm-seed S]] [--out OUT] [--workers N]``.

DIR holds one colony validation per population's finalist (``DIR/pop{k}/report.json``: the
reproduction's ``colony_validation``, or ``servobot validate FILE --robots R --out DIR/pop{k}``
for each). The table world predicts a colony's coverage well but its robots' lives poorly
(issue 17, docs/colony.md): populations whose robots stay live in the table die at the station
in physics, while others live in both. Physics separates the populations (their finalists'
lives differ by more than their runs' spread), so the finalist a user should run is chosen by
its own physics runs.

Rule (``ChoiceRule``): a finalist *qualifies* when its robots are live at the end of a physics
run ≥ ``min_live`` on average (default 2.0 of R: issue 17's goal); the choice is the qualifying
finalist with the highest physics colony inner coverage, else, when none qualifies, the one
with the most robots live (ties: coverage). ``--by table`` applies the rule to the table
world's runs from the same starts instead (no physics: could the table have chosen?). A choice
among K finalists on the same runs that scored them is biased upward, so ``--confirm N`` runs
the chosen finalist again from N fresh colony starts (seed ``--confirm-seed``, default the
validation's seed + 1000; drawn as ``servobot validate --robots R --seed S`` draws them), with
every setting of its validation, into ``OUT/confirm`` (kept and not run again once finished):
that measurement is the choice's figure.

Writes ``OUT/choice.json``, ``OUT/choice.md`` and ``OUT/choice.png`` (each finalist's physics
coverage against its robots live, the chosen one joined to its confirmation; OUT defaults to
``DIR/choice``) and prints the Markdown. Exit status: 0, 1 when a confirmation's physics run
failed, 2 = bad input (a folder without reports, a report that is not a colony validation, a
confirmation this module cannot rebuild), 130 = interrupted (143 on SIGTERM).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from evolve.codec import read_chromosome
from evolve.settings import ColonySettings, WorldSettings, settings_from_record
from evolve.starts import colony_starts
from infra.bounds import check_int, check_nonnegative
from infra.command import EXIT_FAILED, Interrupted, command_line, run_command
from infra.errors import InputError
from infra.executors import make_executor
from infra.io import atomic_write_json, atomic_write_text
from infra.rundir import RECORD_FILE, record_of
from servo_mj.world.arena import ArenaSettings
from servobot.progress import RunBar
from servobot.validation.colony import colony_kind
from servobot.validation.colony_pool import pool, read_report, report_files
from servobot.validation.colony_report import WORLDS
from servobot.validation.lone import execute, load_checked_table, plan_validation

PROG = "python -m servobot.validation.colony_choice"
CONFIRM_SEED_OFFSET = 1000
"""``--confirm-seed`` default: the validation's seed + this, fresh colony starts."""


@dataclasses.dataclass(frozen=True)
class ChoiceRule:
    """How one finalist is chosen among the finalists' colony validations."""

    min_live: float = 2.0
    """Robots live at the end of a run, mean over the runs, a finalist needs to qualify (of R;
    issue 17's goal: 2 of 3)."""
    world: str = "physics"
    """Whose runs choose: ``physics``, or ``table`` (the table world's runs from the same
    starts, no physics needed: whether the table world could have made the choice)."""

    def __post_init__(self) -> None:
        if self.world not in WORLDS:
            raise InputError(f"choice world must be one of {list(WORLDS)}, got {self.world!r}")


def finalist_rows(folder: Path) -> tuple[list[Path], list[dict[str, Any]], list[dict[str, Any]]]:
    """``folder``'s validation reports (``colony_pool.report_files``), the reports, and one row
    per finalist: its name (``pop{k}``) and its pooled figures in each world
    (``colony_pool.pool``)."""
    paths = report_files(folder)
    reports = [read_report(p) for p in paths]
    keep = ("runs", "inner_pct", "docks_per_robot", "live_per_run")
    rows = []
    for path, report in zip(paths, reports, strict=True):
        pooled = pool([report])
        name = path.parent.name if path.parent != folder else folder.name
        rows.append({"name": name, **{w: {k: pooled[w][k] for k in keep} for w in WORLDS}})
    return paths, reports, rows


def choose(rows: list[dict[str, Any]], rule: ChoiceRule = ChoiceRule()) -> int:
    """Index in ``rows`` (``finalist_rows``) of the finalist ``rule`` chooses."""
    if not rows:
        raise InputError("no finalist to choose from")

    def key(i: int) -> tuple[bool, float, float]:
        p = rows[i][rule.world]
        qualifies = p["live_per_run"] >= rule.min_live
        first = p["inner_pct"] if qualifies else p["live_per_run"]
        return qualifies, first, p["inner_pct"]

    return max(range(len(rows)), key=key)


@dataclasses.dataclass(frozen=True)
class Confirmation:
    """What a chosen finalist's validation ran with, to run it again from fresh starts."""

    chromosome: Path
    """Its chromosome file."""
    table: str
    """Its gait table: ``paper`` or a calibration file."""
    world: WorldSettings
    colony: ColonySettings
    arena: ArenaSettings
    max_steps: int
    """Each robot's own gait-step limit."""


def confirmation_of(report: dict[str, Any], folder: Path) -> Confirmation:
    """The settings ``report`` (a colony validation in ``folder``) ran with; an ``InputError``
    when it used what this module cannot repeat (another robot model or physics settings) or
    its chromosome or gait table file is gone."""
    settings, meta = report["settings"], report.get("meta") or {}
    name = str(folder)
    model = str(settings.get("model", ""))
    if settings.get("PhysicsSettings") != "default" or not model.startswith("shipped"):
        raise InputError(
            f"{name}: validated with another robot model or physics settings; "
            "confirm it with servobot validate by hand"
        )
    if "chromosome_file" in meta:
        chromosome = Path(meta["chromosome_file"])
    elif "source" in meta:  # the reproduction's colony_validation/pop{k}: RUN/colony/best_pop{k}
        chromosome = folder.parent.parent / meta["source"]
    else:
        raise InputError(f"{name}: its report names no chromosome file")
    if not chromosome.is_file():
        raise InputError(f"{name}: its chromosome file {chromosome} is gone")
    table = report["table"].get("source")
    if table != "paper" and not (table and Path(table).is_file()):
        raise InputError(f"{name}: its gait table file {table} is gone")
    height = settings["ArenaSettings"]["station_height_m"]
    return Confirmation(
        chromosome=chromosome,
        table=table,
        world=settings_from_record(WorldSettings, settings["WorldSettings"], name, InputError),
        colony=settings_from_record(ColonySettings, settings["ColonySettings"], name, InputError),
        arena=dataclasses.replace(ArenaSettings(), station_height_m=height),
        max_steps=int(settings["max_steps"]),
    )


def confirm_finalist(
    c: Confirmation,
    starts: int,
    seed: int,
    out: Path,
    workers: int | None = None,
    team: Sequence[Path] = (),
    label: str = "confirm",
    poses: np.ndarray | None = None,
) -> None:
    """Run ``c``'s finalist as its validation did from ``starts`` fresh colony starts of
    ``seed`` (``colony_starts``, as ``servobot validate --robots R --seed S`` draws them) into
    ``out``, unless ``out`` already holds that validation finished: its report written and its
    run folder's record (``settings.json``) the plan's own, so the same chromosome, table,
    starts and settings. ``team``: R chromosome files, robot r carrying file r, in place of
    ``c``'s (``servobot.validation.colony_team``); ``label``: the progress bar's; ``poses``
    ((N, R, 3)): these colony starts instead of drawn ones (``starts`` is then N)."""
    table, warning = load_checked_table(c.table)
    if warning:
        print(warning, file=sys.stderr)
    if poses is None:
        poses = colony_starts(np.random.default_rng(seed), starts, c.world, c.colony)
    files = list(team) or [c.chromosome]
    bits = np.stack([read_chromosome(f) for f in team]) if team else read_chromosome(c.chromosome)
    plan = plan_validation(
        bits, poses, table=table, kind=colony_kind(c.colony),
        world=c.world, arena=c.arena, out_dir=out, max_steps=c.max_steps, seed=seed,
        meta={"chromosome_file": ", ".join(map(str, files)), "seed": seed, "command": PROG},
    )  # fmt: skip
    record = out / RECORD_FILE
    if (out / "report.json").is_file() and record.is_file():
        if json.loads(record.read_text()) == record_of(plan.record, "validate"):
            return
    bar = RunBar(label, True, total=starts, unit="start")
    try:
        execute([plan], make_executor(None, workers), lambda rec: bar())
    finally:
        bar.close()


def choice_markdown(doc: dict[str, Any]) -> str:
    """``choice.json`` as Markdown: each finalist's physics and table figures, the choice, and
    its confirmation when run."""
    rule = doc["rule"]
    lines = [
        "# The colony's finalist chosen by "
        + ("physics" if rule["world"] == "physics" else "the table world"),
        "",
        f"Rule, on the {rule['world']} world's runs: qualifies with ≥ {rule['min_live']:g} robots "
        "live at the end of a run (mean); the qualifying finalist with the most colony inner "
        "coverage, else the one with the most robots live.",
        "",
        *finalist_table(doc["finalists"], {doc["chosen"]: "chosen"}),
    ]
    c = doc.get("confirmation")
    if c:
        p, t = c["physics"], c["table"]
        lines += [
            "",
            f"Confirmation on {p['runs']} fresh colony starts (seed {c['seed']}, "
            f"`{c['folder']}`): physics **{p['inner_pct']:.1f} %** colony inner coverage, "
            f"**{p['live_per_run']:.2f}** robots live per run, {p['docks_per_robot']:.2f} docks "
            f"per robot; table world {t['inner_pct']:.1f} %, {t['live_per_run']:.2f} live "
            f"(gap table − physics {t['inner_pct'] - p['inner_pct']:+.1f} pp).",
        ]
    return "\n".join(lines) + "\n"


def finalist_table(rows: list[dict[str, Any]], marks: dict[str, str]) -> list[str]:
    """The finalists' rows (``finalist_rows``) as Markdown table lines, both worlds; a row named
    in ``marks`` is marked with its text (``**(chosen)**``)."""
    lines = [
        "| finalist | runs | physics inner % | physics live / run | physics docks / robot | "
        "table inner % | table live / run |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        p, t = r["physics"], r["table"]
        mark = f" **({marks[r['name']]})**" if r["name"] in marks else ""
        lines.append(
            f"| {r['name']}{mark} | {p['runs']} | {p['inner_pct']:.1f} | "
            f"{p['live_per_run']:.2f} | {p['docks_per_robot']:.2f} | "
            f"{t['inner_pct']:.1f} | {t['live_per_run']:.2f} |"
        )
    return lines


def choice_line(folder: Path, robots: int) -> str:
    """One Markdown paragraph: the finalist of ``folder``'s validations (``DIR/pop{k}``) that
    the default rule chooses by physics, for the reproduction's report (a note when some
    finalist has no finished physics run to choose by)."""
    try:
        rows = finalist_rows(folder)[2]
    except InputError as exc:
        return f"*(no finalist chosen by physics: {exc})*"
    chosen = rows[choose(rows)]
    p = chosen["physics"]
    return (
        f"Chosen by physics (`{PROG} {folder.parent.name}/{folder.name}`: the most "
        f"coverage among the finalists with ≥ {ChoiceRule.min_live:g} of {robots} robots "
        f"live at the end of a run, else the most live): **{chosen['name']}**, physics "
        f"{p['inner_pct']:.1f} % colony inner coverage, {p['live_per_run']:.2f} of {robots} "
        f"live, {p['docks_per_robot']:.2f} docks per robot on these {p['runs']} runs. A "
        "choice on the runs that scored it is optimistic: `--confirm 12` measures the "
        "chosen finalist again from fresh colony starts."
    )


def run_choice(
    folder: Path,
    rule: ChoiceRule,
    out: Path,
    confirm: int = 0,
    confirm_seed: int | None = None,
    workers: int | None = None,
) -> tuple[dict, int]:
    """Choose among ``folder``'s finalists, confirm the choice from ``confirm`` fresh starts
    (0: none), write ``out/choice.{json,md,png}``; the document and the confirmation's exit
    code."""
    paths, reports, rows = finalist_rows(folder)
    i = choose(rows, rule)
    doc: dict[str, Any] = {
        "folder": str(folder),
        "rule": dataclasses.asdict(rule),
        "finalists": rows,
        "chosen_index": i,
        "chosen": rows[i]["name"],
    }
    code = 0
    if confirm:
        seed = (
            int(reports[i]["settings"].get("seed") or 0) + CONFIRM_SEED_OFFSET
            if confirm_seed is None
            else confirm_seed
        )
        sub = out / "confirm"
        plan = confirmation_of(reports[i], paths[i].parent)
        confirm_finalist(plan, confirm, seed, sub, workers)
        done = read_report(sub / "report.json")
        code = EXIT_FAILED if done["summary"]["physics_errors"] else 0
        again = pool([done])
        doc["confirmation"] = {
            "seed": seed,
            "folder": str(sub),
            "chromosome_file": str(plan.chromosome),
            **{w: again[w] for w in WORLDS},
        }
    atomic_write_json(out / "choice.json", doc)
    atomic_write_text(out / "choice.md", choice_markdown(doc))
    choice_figure(doc, out / "choice.png", reports[i]["settings"]["ColonySettings"]["robots"])
    return doc, code


def choice_figure(doc: dict[str, Any], path: Path, robots: int) -> Path:
    """``choice.png``: every finalist's physics coverage against its robots live, the chosen
    one and, when run, its confirmation (``evolve.figures.figure_colony_choice``)."""
    from evolve.figures import figure_colony_choice  # matplotlib only where a figure is drawn

    points = [
        {
            "label": r["name"],
            **r["physics"],
            "kind": "chosen" if i == doc["chosen_index"] else "finalist",
        }
        for i, r in enumerate(doc["finalists"])
    ]
    c = doc.get("confirmation")
    if c:
        points.append(
            {
                "label": f"{doc['chosen']}, {c['physics']['runs']} fresh starts",
                "kind": "confirmation",
                **c["physics"],
            }
        )
    title = f"{doc['folder']}: the finalist chosen by {doc['rule']['world']}"
    return figure_colony_choice(
        path, points, title, robots=robots, min_live=doc["rule"]["min_live"]
    )


def add_confirm_options(
    ap: argparse.ArgumentParser,
    starts: str,
    seed_of: str,
    folder: str,
    runs_as: str,
    name: str = "choice",
) -> None:
    """A choice command's ``--confirm N``, ``--confirm-seed S``, ``--out OUT`` and ``--workers
    N`` (also ``servobot.robustness.matrix_choice``, ``servobot.validation.colony_team``): the
    chosen one runs again from N ``starts`` (seed: ``seed_of`` seed + ``CONFIRM_SEED_OFFSET``),
    outputs ``name``.{json,md,png} in OUT (default ``folder``/``name``), the confirmation on
    ``runs_as``'s workers."""
    ap.add_argument(
        "--confirm",
        type=int,
        default=0,
        metavar="N",
        help=f"run the chosen one again from N {starts} (default 0)",
    )
    ap.add_argument(
        "--confirm-seed",
        type=int,
        default=None,
        metavar="S",
        help=f"their seed (default: {seed_of} + {CONFIRM_SEED_OFFSET})",
    )
    ap.add_argument(
        "--out",
        type=Path,
        default=None,
        metavar="OUT",
        help=f"where {name}.{{json,md,png}} and confirm/ go (default {folder}/{name})",
    )
    ap.add_argument("--workers", type=int, default=None, metavar="N",
                    help=f"the confirmation's worker processes ({runs_as}'s default)")  # fmt: skip


def check_confirm_options(args: argparse.Namespace) -> None:
    """``BoundsError`` (an ``InputError``) naming a negative ``--confirm`` or ``--confirm-seed``."""
    check_int(args.confirm, "--confirm", lo=0)
    if args.confirm_seed is not None:
        check_int(args.confirm_seed, "--confirm-seed", lo=0)


def run_choice_command(
    prog: str, argv: list[str] | None, out: Path, body: Callable[[], int], name: str = "choice"
) -> int:
    """A choice command's ``body`` under ``infra.command.run_command`` (also
    ``servobot.robustness.matrix_choice``, ``servobot.validation.colony_team``): bad input
    exits 2 naming it, Ctrl-C 130 and SIGTERM 143 saying what is kept and how to go on."""
    kept = f"what the runs finished in {out}; {name}.json is written at the end"
    resume = command_line(prog, sys.argv[1:] if argv is None else argv)
    return run_command(prog, body, lambda: Interrupted(kept, resume))


def main(argv: list[str] | None = None) -> int:
    """Choose, optionally confirm, print ``choice.md``; exit 0, 1 or 2 (module docstring)."""
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    ap.add_argument(
        "folder",
        type=Path,
        metavar="DIR",
        help="colony validations of the finalists (DIR/pop*/report.json)",
    )
    ap.add_argument(
        "--min-live",
        type=float,
        default=ChoiceRule.min_live,
        metavar="L",
        help="robots live at the end of a physics run (mean) a finalist needs to "
        "qualify (default %(default)s)",
    )
    ap.add_argument(
        "--by",
        choices=WORLDS,
        default=ChoiceRule.world,
        help="whose runs choose: physics (default) or the table world's from the same starts",
    )
    add_confirm_options(ap, "fresh colony starts", "the validation's", "DIR", "servobot validate")
    args = ap.parse_args(argv)
    out = args.out or args.folder / "choice"

    def body() -> int:
        check_nonnegative(args.min_live, "--min-live", " robots")
        check_confirm_options(args)
        rule = ChoiceRule(args.min_live, args.by)
        doc, code = run_choice(
            args.folder, rule, out, args.confirm, args.confirm_seed, args.workers
        )
        print(choice_markdown(doc), end="")
        return code

    return run_choice_command(PROG, argv, out, body)


if __name__ == "__main__":
    raise SystemExit(main())
