"""A colony team of liver and coverer, chosen by physics from validated finalists.

``python -m servobot.validation.colony_team DIR... [--coverers K] [--min-live L] [--confirm N
[--confirm-seed S]] [--out OUT] [--workers N]``.

Each DIR holds colony validations of finalists (``DIR/pop{k}/report.json``, as for
``servobot.validation.colony_choice``), all from the same colony starts with the same physics
settings; the finalists of several GA runs may be pooled. Physics separates two kinds of
finalist (issue 17, docs/colony.md): *livers*, whose robots dock 5–6 times each and stay live
but cover less, and *coverers*, which roam, cover most and die at the station. A colony's
robots may carry different chromosomes (SPEC §7, a team), so the team puts both to work: the
liver (``colony_choice.ChoiceRule(min_live)``'s choice: the most coverage among the finalists
with ≥ ``min_live`` robots live, else the most live) on the first R − K robots and the
coverer (the most physics coverage: ``ChoiceRule(min_live=0)``) on the last K (``--coverers``;
with a staggered start power, ``ColonySettings.start_power_spread``, the robots that start
with the most power).

No choice is made on the team's own runs: it runs from the finalists' validation starts
(``OUT/team``, figure by figure comparable with them) and, with ``--confirm N``, from N fresh
colony starts (seed ``--confirm-seed``, default the validations' + 1000; ``OUT/confirm``), each
with every setting of the liver's validation (its table world included) and kept once
finished. When the liver is a colony stage's finalist (``RUN/colony/best_pop{k}.txt`` beside
that stage's ``settings.json``), the team also runs that stage's final table test (its 100
colony test starts, its table world: the measure of its Figure 9's last point).

Writes ``OUT/team.json``, ``OUT/team.md`` and ``OUT/team.png`` (every finalist's physics
coverage against its robots live, the liver and the coverer marked, the team on the same
starts joined to its confirmation; OUT defaults to ``DIR/team`` of the first DIR) and prints
the Markdown. Exit status: 0, 1 when a physics run failed, 2 = bad input, 130 = interrupted
(143 on SIGTERM).
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from evolve.codec import read_chromosome
from evolve.colony_stage import final_test
from evolve.colony_timeline import run_settings
from evolve.population import stage_seeds
from evolve.starts import colony_starts
from evolve.table import GaitTable, validate_table
from infra.bounds import check_int, check_nonnegative
from infra.command import EXIT_FAILED
from infra.errors import InputError
from infra.io import atomic_write_json, atomic_write_text
from servobot.validation.colony_choice import (
    CONFIRM_SEED_OFFSET,
    ChoiceRule,
    add_confirm_options,
    check_confirm_options,
    choose,
    confirm_finalist,
    confirmation_of,
    finalist_rows,
    finalist_table,
    run_choice_command,
)
from servobot.validation.colony_pool import pool, read_report

PROG = "python -m servobot.validation.colony_team"
TABLE_ONLY = ("blocking", "contact_yaw_deg", "fitness", "alive_weight", "dock_weight", "dock_cap")
"""``ColonySettings`` fields only the table world reads: validations that differ in them still
ran the same physics."""


@dataclasses.dataclass(frozen=True)
class TeamRule:
    """How a team of R robots is made of the finalists' colony validations."""

    min_live: float = ChoiceRule.min_live
    """The liver's rule: robots live at the end of a physics run, mean, to qualify (of R)."""
    coverers: int = 1
    """Robots carrying the coverer (the last ones); the other R − ``coverers`` carry the liver."""

    def __post_init__(self) -> None:
        check_nonnegative(self.min_live, "min_live", " robots")
        check_int(self.coverers, "coverers", lo=0)


def pick(rows: list[dict[str, Any]], rule: TeamRule = TeamRule()) -> tuple[int, int]:
    """Indices in ``rows`` (``colony_choice.finalist_rows``) of the liver and the coverer."""
    return choose(rows, ChoiceRule(rule.min_live)), choose(rows, ChoiceRule(min_live=0.0))


def physics_settings(report: dict[str, Any]) -> dict[str, Any]:
    """What a colony validation's physics runs depend on: its start poses and settings (seed,
    world, arena, physics, model, steps) less the ``TABLE_ONLY`` colony fields."""
    settings = {**report["settings"], "starts": [run["start"] for run in report["runs"]]}
    settings["ColonySettings"] = {
        k: v for k, v in settings["ColonySettings"].items() if k not in TABLE_ONLY
    }
    return settings


def finalists(folders: list[Path]) -> tuple[list[Path], list[dict], list[dict[str, Any]]]:
    """The finalists' report paths, reports and rows (``finalist_rows``) of every folder, each
    row named ``DIR/pop{k}`` when there are several folders; an ``InputError`` naming the first
    finalist whose physics ran otherwise than the first one's."""
    paths, reports, rows = [], [], []
    for folder in folders:
        p, rep, r = finalist_rows(folder)
        if len(folders) > 1:
            r = [{**row, "name": f"{folder.name}/{row['name']}"} for row in r]
        paths += p
        reports += rep
        rows += r
    first = physics_settings(reports[0])
    for path, rep in zip(paths, reports, strict=True):
        mine = physics_settings(rep)
        if mine != first:
            diff = sorted(k for k in first.keys() | mine.keys() if first.get(k) != mine.get(k))
            raise InputError(
                f"{path}: its physics ran otherwise than {paths[0]}'s ({', '.join(diff)} "
                "differ): their figures do not compare"
            )
    return paths, reports, rows


def team_files(liver: Path, coverer: Path, robots: int, coverers: int) -> list[Path]:
    """Robot r's chromosome file: the liver's for r < R − ``coverers``, else the coverer's."""
    if coverers > robots:
        raise InputError(f"--coverers {coverers}: a colony of {robots} robots has fewer")
    return [liver] * (robots - coverers) + [coverer] * coverers


def stage_table_test(liver: Path, files: list[Path]) -> dict[str, Any] | None:
    """The team's final table test (``evolve.colony_stage.final_test``) on the colony stage's
    own test starts and table world, when ``liver`` is a stage's finalist
    (``RUN/colony/best_pop{k}.txt`` beside the stage's ``settings.json``, read by
    ``evolve.colony_timeline.run_settings``); None otherwise."""
    stage = liver.parent
    if stage.name != "colony" or not (stage / "settings.json").is_file():
        return None
    world, colony, ga, values, _ = run_settings(stage.parent)
    if ga is None or values is None:
        raise InputError(f"{stage / 'settings.json'}: no GA settings or gait table recorded")
    table = GaitTable(validate_table(values, name=f"{stage / 'settings.json'}: table"))
    test_seq, _ = stage_seeds(ga.seed, "colony", ga.populations)
    starts = colony_starts(
        np.random.Generator(np.random.PCG64(test_seq)), ga.test_starts, world, colony
    )
    team = np.stack([read_chromosome(f) for f in files])[None]
    test = final_test(team, starts, table, world, colony)[0]
    keep = ("colony_inner_percent", "live_at_end_per_run", "docks_per_robot", "ends")
    return {"stage": str(stage), "starts": len(starts), **{k: test[k] for k in keep}}


def run_team(
    folders: list[Path],
    rule: TeamRule,
    out: Path,
    confirm: int = 0,
    confirm_seed: int | None = None,
    workers: int | None = None,
) -> tuple[dict[str, Any], int]:
    """Make the team of ``folders``' finalists, run it from their starts and ``confirm`` fresh
    ones (0: none), write ``out/team.{json,md,png}``; the document and the exit code."""
    paths, reports, rows = finalists(folders)
    liver, coverer = pick(rows, rule)
    plan = confirmation_of(reports[liver], paths[liver].parent)
    cover_plan = confirmation_of(reports[coverer], paths[coverer].parent)
    files = team_files(plan.chromosome, cover_plan.chromosome, plan.colony.robots, rule.coverers)
    seed = int(reports[liver]["settings"].get("seed") or 0)
    doc: dict[str, Any] = {
        "folders": [str(f) for f in folders],
        "rule": dataclasses.asdict(rule),
        "finalists": rows,
        "liver": rows[liver]["name"],
        "coverer": rows[coverer]["name"],
        "team": [str(f) for f in files],
        "table_test": stage_table_test(plan.chromosome, files),
    }
    code = 0
    given = np.array(
        [[[p[k] for k in "xyh"] for p in run["start"]] for run in reports[liver]["runs"]]
    )
    runs = [("same_starts", "team", seed, len(given), given)]
    if confirm:
        fresh = seed + CONFIRM_SEED_OFFSET if confirm_seed is None else confirm_seed
        runs.append(("confirmation", "confirm", fresh, confirm, None))
    for key, sub, s, n, poses in runs:
        confirm_finalist(plan, n, s, out / sub, workers, team=files, label=sub, poses=poses)
        done = read_report(out / sub / "report.json")
        code = code or (EXIT_FAILED if done["summary"]["physics_errors"] else 0)
        doc[key] = {"seed": s, "folder": str(out / sub), **pool([done])}
    atomic_write_json(out / "team.json", doc)
    atomic_write_text(out / "team.md", team_markdown(doc))
    team_figure(doc, out / "team.png", plan.colony.robots)
    return doc, code


def roles(doc: dict[str, Any]) -> dict[str, str]:
    """``team.json``'s finalists by name: ``liver``, ``coverer`` or ``liver, coverer``."""
    if doc["liver"] == doc["coverer"]:
        return {doc["liver"]: "liver, coverer"}
    return {doc["liver"]: "liver", doc["coverer"]: "coverer"}


def team_line(folder: Path, robots: int) -> str:
    """One Markdown paragraph for the reproduction's report: the team of ``folder``'s finalists
    (``DIR/pop{k}``) the default rule makes, with its two finalists' figures on these runs
    (no team run: ``--confirm 12`` measures it)."""
    try:
        rows = finalist_rows(folder)[2]
    except InputError as exc:
        return f"*(no team made by physics: {exc})*"
    liver, coverer = (rows[i] for i in pick(rows))
    head = f"A team (`{PROG} {folder.parent.name}/{folder.name} --confirm 12`)"
    if liver is coverer:
        return f"{head}: **{liver['name']}** both lives and covers most: the team is it alone."
    first = "robot 0 carries" if robots == 2 else f"robots 0–{robots - 2} carry"
    return (
        f"{head}: {first} the liver **{liver['name']}** (as chosen above), robot "
        f"{robots - 1} the coverer **{coverer['name']}**, the finalist that covers most in "
        f"physics ({_figures(coverer['physics'])} on these runs); what such teams measured: "
        'docs/colony.md, "A team of liver and coverer".'
    )


def _figures(p: dict[str, Any]) -> str:
    return (
        f"{p['inner_pct']:.1f} % colony inner coverage, {p['live_per_run']:.2f} live per "
        f"run, {p['docks_per_robot']:.2f} docks per robot"
    )


def team_markdown(doc: dict[str, Any]) -> str:
    """``team.json`` as Markdown: the finalists, the team, and its runs in both worlds."""
    rule = doc["rule"]
    lines = [
        "# A colony team chosen by physics",
        "",
        f"Liver: the most physics coverage among the finalists with ≥ {rule['min_live']:g} "
        "robots live at the end of a run (mean), else the most live; coverer: the most physics "
        f"coverage. The last {rule['coverers']} robot(s) carry the coverer, the others the "
        "liver.",
        "",
        *finalist_table(doc["finalists"], roles(doc)),
    ]
    lines += ["", "Team, robot by robot: " + ", ".join(f"`{f}`" for f in doc["team"]) + "."]
    for key, what in (("same_starts", "the finalists' starts"), ("confirmation", "fresh starts")):
        run = doc.get(key)
        if run:
            p, t = run["physics"], run["table"]
            lines.append(
                f"\nOn {what} ({p['runs']} colony starts, seed {run['seed']}, "
                f"`{run['folder']}`): physics **{_figures(p)}**; table world "
                f"{t['inner_pct']:.1f} %, {t['live_per_run']:.2f} live (gap table − physics "
                f"{run['gap_inner_pp']:+.1f} pp)."
            )
    test = doc.get("table_test")
    if test:
        lines.append(
            f"\nThe liver's colony stage's final table test (`{test['stage']}`, "
            f"{test['starts']} colony starts, its table world): "
            f"{test['colony_inner_percent']:.1f} % colony inner coverage, "
            f"{test['live_at_end_per_run']:.2f} live per run, {test['docks_per_robot']:.2f} "
            "docks per robot."
        )
    return "\n".join(lines) + "\n"


def team_figure(doc: dict[str, Any], path: Path, robots: int) -> Path:
    """``team.png``: the finalists in the plane of ``colony_choice``'s figure, the liver and
    the coverer marked, the team's runs joined."""
    from evolve.figures import figure_colony_choice  # matplotlib only where a figure is drawn

    role = roles(doc)
    points = [
        {
            "label": f"{r['name']} ({role[r['name']]})" if r["name"] in role else r["name"],
            "kind": "chosen" if r["name"] in role else "finalist",
            **r["physics"],
        }
        for r in doc["finalists"]
    ]
    for key, kind, what in (
        ("same_starts", "team", "team"),
        ("confirmation", "confirmation", "team, fresh starts"),
    ):
        if doc.get(key):
            p = doc[key]["physics"]
            points.append({"label": f"{what} ({p['runs']} runs)", "kind": kind, **p})
    title = f"{', '.join(doc['folders'])}: a team of liver and coverer"
    return figure_colony_choice(
        path,
        points,
        title,
        robots=robots,
        min_live=doc["rule"]["min_live"],
        joined=("team", "confirmation"),
    )


def main(argv: list[str] | None = None) -> int:
    """Make the team, run it, print ``team.md``; exit 0, 1 or 2 (module docstring)."""
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    ap.add_argument(
        "folders",
        type=Path,
        nargs="+",
        metavar="DIR",
        help="colony validations of finalists (DIR/pop*/report.json), same starts",
    )
    ap.add_argument(
        "--coverers",
        type=int,
        default=TeamRule.coverers,
        metavar="K",
        help="robots carrying the coverer, the last K (default %(default)s)",
    )
    ap.add_argument(
        "--min-live",
        type=float,
        default=TeamRule.min_live,
        metavar="L",
        help="the liver's rule: robots live at the end of a physics run (mean) to "
        "qualify (default %(default)s)",
    )
    add_confirm_options(
        ap, "fresh colony starts", "the validations'", "DIR", "servobot validate", name="team"
    )
    args = ap.parse_args(argv)
    out = args.out or args.folders[0] / "team"

    def body() -> int:
        check_confirm_options(args)
        rule = TeamRule(args.min_live, args.coverers)
        doc, code = run_team(args.folders, rule, out, args.confirm, args.confirm_seed, args.workers)
        print(team_markdown(doc), end="")
        return code

    return run_choice_command(PROG, argv, out, body, name="team")


if __name__ == "__main__":
    raise SystemExit(main())
