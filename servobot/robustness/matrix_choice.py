"""The finalist chosen by physics across the test matrix's worlds (issue 16):
``python -m servobot.robustness.matrix_choice MATRIX [--by worst|mean] [--worlds LIST]
[--sections coverage|navigation] [--confirm N [--confirm-seed S]] [--out OUT] [--workers N]``.

MATRIX is a finished ``servobot robustness`` folder of a run's finalists (one coverage
chromosome per population), or with ``--sections navigation`` of navigation sections (a
navigation stage's candidates, judged by the share of runs that dock: the section a coverage
stage is then evolved on, ``servobot evolve coverage --navigation OUT/NAME.txt``).

The GA's finalists differ in physics by more than their runs' spread, and no table world
ranks them as physics does (docs/envelope.md), so the controller a user should run is chosen
by its own physics runs, as the colony's is (``servobot.validation.colony_choice``).

Rule (``ChoiceRule``): the coverage chromosome whose *worst* physics world (``--by worst``,
default: issue 16 asks for ≥ 50 % of the inner squares in every world) or *mean* over the
worlds (``--by mean``) has the most inner coverage (navigation sections: docking, with no
goal); ties go to the mean. The worlds that choose are the matrix's, or those of
``--worlds``, never the held-out one (``worlds.HELD_OUT``, ``long-legs``: no choice may look
at it, so it still measures what was not tuned for). A choice among K finalists on the runs
that scored them is biased upward, so ``--confirm N`` runs the chosen chromosome again
through the matrix, every world of MATRIX (held-out ones included), from N fresh starts (seed
``--confirm-seed``, default MATRIX's seed + 1000), with MATRIX's table and steps, into
``OUT/confirm`` (a matrix folder: a finished one is read back, an interrupted one resumed):
that measurement is the choice's figure.

Writes ``OUT/choice.json``, ``OUT/choice.md`` and ``OUT/choice.png`` (the finalists × worlds,
the confirmation beneath; OUT defaults to ``MATRIX/choice``) and prints the Markdown. Exit
status: 0, 1 when a confirmation's physics run failed, 2 = bad input (not a finished matrix,
nothing of the kind chosen, an unknown world, a world whose model changed since MATRIX ran),
130 = interrupted (143 on SIGTERM).
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from evolve.codec import format_chromosome, parse_chromosome
from infra.command import EXIT_FAILED
from infra.errors import InputError
from infra.io import atomic_write_json, atomic_write_text
from servobot.progress import RunBar
from servobot.robustness.floor import read_matrix
from servobot.robustness.matrix import RobustnessSettings, run_matrix
from servobot.robustness.report import heatmap
from servobot.robustness.worlds import BUILT_IN, HELD_OUT, SHIPPED, resolve_worlds, world_sha256
from servobot.validation.colony_choice import (
    CONFIRM_SEED_OFFSET,
    add_confirm_options,
    check_confirm_options,
    run_choice_command,
)
from servobot.validation.lone import NAVIGATION_MODE

PROG = "python -m servobot.robustness.matrix_choice"
CRITERIA = ("worst", "mean")
"""What a chromosome is scored by over the choosing worlds (module docstring)."""
SECTIONS = ("coverage", "navigation")
"""What is chosen: coverage chromosomes by inner coverage, navigation sections by docking."""
MEASURE = {"coverage": ("inner coverage", "% of the 64 inner squares"),
           "navigation": ("docking", "% of the runs that docked")}  # fmt: skip
"""The physics figure each kind is chosen by, as the reports name it."""
GOAL_PERCENT = 50.0
"""Issue 16's goal: inner coverage in every physics world, %."""
GOAL_DROP_PP = 5.0
"""Issue 16's goal: no world more than this below ``shipped``, percentage points."""


@dataclasses.dataclass(frozen=True)
class ChoiceRule:
    """How one chromosome is chosen among a matrix's coverage chromosomes."""

    criterion: str = "worst"
    """``worst``: the lowest physics inner % over the choosing worlds; ``mean``: their mean."""
    worlds: tuple[str, ...] | None = None
    """The worlds that choose; None: the matrix's. Never the held-out world."""
    sections: str = "coverage"
    """``coverage``: choose among the coverage chromosomes by physics inner %;
    ``navigation``: among the navigation sections by physics docking %."""

    def __post_init__(self) -> None:
        if self.criterion not in CRITERIA:
            raise InputError(f"--by must be one of {list(CRITERIA)}, got {self.criterion!r}")
        if self.sections not in SECTIONS:
            raise InputError(f"--sections must be one of {list(SECTIONS)}, got {self.sections!r}")
        if self.worlds is not None and HELD_OUT.name in self.worlds:
            raise InputError(f"--worlds: {HELD_OUT.name!r} is held out; no choice may look at it")


def figure_of(entry: dict[str, Any], side: str, sections: str = "coverage") -> float | None:
    """The figure a chromosome is chosen by in one ``robustness.json`` entry (``side``:
    ``table`` or ``physics``): inner % for coverage, docking % for navigation sections; None
    where no run finished."""
    if sections == "coverage":
        return entry[f"{side}_inner_percent"]
    return None if entry["dock_rate"] is None else 100.0 * entry["dock_rate"]


def finalist_rows(doc: dict[str, Any], sections: str = "coverage") -> list[dict[str, Any]]:
    """One row per chromosome of kind ``sections`` (``SECTIONS``) of ``robustness.json``'s
    ``doc``: its name, file, and its figure (``figure_of``) in the table world and per
    physics world (None where no physics run finished)."""
    rows = []
    for k, t in enumerate(doc["table_per_chromosome"]):
        if (t["mode"] == NAVIGATION_MODE) != (sections == "navigation"):
            continue
        physics = {w["name"]: figure_of(w["per_chromosome"][k], "physics", sections)
                   for w in doc["worlds"]}  # fmt: skip
        rows.append({"name": t["name"], "file": t["file"], "index": k,
                     "table": figure_of(t, "table", sections), "physics": physics})  # fmt: skip
    if not rows:
        kind = "coverage chromosome" if sections == "coverage" else "navigation section"
        raise InputError(f"the matrix has no {kind} to choose among")
    return rows


def choosing_worlds(doc: dict[str, Any], rule: ChoiceRule) -> list[str]:
    """The worlds ``rule`` chooses by, in the matrix's order; ``InputError`` for a world the
    matrix did not run, or none left."""
    names = [w["name"] for w in doc["worlds"]]
    if rule.worlds is None:
        chosen = [n for n in names if n != HELD_OUT.name]
    else:
        unknown = [w for w in rule.worlds if w not in names]
        if unknown:
            raise InputError(f"--worlds: {unknown[0]!r} is not a world of the matrix {names}")
        chosen = [n for n in names if n in rule.worlds]
    if not chosen:
        raise InputError(f"no world left to choose by among {names}")
    return chosen


def score(physics: dict[str, float | None], worlds: list[str]) -> dict[str, float]:
    """A chromosome's ``worst`` and ``mean`` physics inner % over ``worlds`` (a world without
    a finished run counts 0: a choice must not favour a chromosome physics could not run)."""
    values = [physics[w] or 0.0 for w in worlds]
    return {"worst": float(min(values)), "mean": float(np.mean(values))}


def choose(rows: list[dict[str, Any]], worlds: list[str], rule: ChoiceRule = ChoiceRule()) -> int:
    """Index in ``rows`` (``finalist_rows``) of the chromosome ``rule`` chooses."""
    scores = [score(r["physics"], worlds) for r in rows]
    return max(range(len(rows)), key=lambda i: (scores[i][rule.criterion], scores[i]["mean"]))


def against_goals(physics: dict[str, float | None], goal: float | None = GOAL_PERCENT
                  ) -> dict[str, Any]:  # fmt: skip
    """Issue 16's two per-world goals for one controller over every world it ran: its worst
    world, whether each world reaches ``goal`` (None: no goal, as for docking), and the
    largest drop below ``shipped`` (None without a shipped world)."""
    kept = {w: v for w, v in physics.items() if v is not None}
    worst = min(kept, key=kept.__getitem__)
    drop = None
    if kept.get(SHIPPED) is not None:
        drop = max(kept[SHIPPED] - v for v in kept.values())
    return {"worst_world": worst, "worst_percent": kept[worst],
            "every_world_at_goal": None if goal is None else all(v >= goal for v in kept.values()),
            "largest_drop_vs_shipped_pp": drop}  # fmt: skip


def choice_line(doc: dict[str, Any], folder: str = "robustness") -> str:
    """One Markdown paragraph for the reproduction's report: the chromosome of matrix ``doc``
    (``robustness.json``, in ``folder``) that the default rule chooses."""
    try:
        rows, worlds = finalist_rows(doc), choosing_worlds(doc, ChoiceRule())
    except InputError as exc:
        return f"*(no finalist chosen by physics: {exc})*"
    r = rows[choose(rows, worlds)]
    return (
        f"Chosen by physics (`{PROG} {folder}`: the most inner coverage in its worst world of "
        f"{', '.join(worlds)}): **{r['name']}**, {_goal_text(against_goals(r['physics']))} on "
        f"these {doc['starts']} starts per world. A choice on the runs that scored it is "
        f"optimistic: `--confirm 10` measures the chosen finalist again from fresh starts."
    )


def confirmation_settings(
    doc: dict[str, Any], record: dict[str, Any], starts: int, seed: int
) -> RobustnessSettings:
    """MATRIX's settings with ``starts`` fresh starts of ``seed`` in every world it ran (a
    variant file world by its file, which must still exist); ``InputError`` when a world's
    robot model is no longer the one MATRIX ran."""
    rs = record["RobustnessSettings"]
    worlds = []
    for w in doc["worlds"]:
        if w["name"] in BUILT_IN:
            worlds.append(w["name"])
        elif w.get("model") and Path(w["model"]).is_file():
            worlds.append(str(w["model"]))
        else:
            raise InputError(f"world {w['name']!r}: its variant file {w.get('model')} is gone")
    for w, spec in zip(doc["worlds"], resolve_worlds(worlds), strict=True):
        if world_sha256(spec) != w["model_sha256"]:
            raise InputError(f"world {w['name']!r}: its robot model changed since the matrix ran")
    return RobustnessSettings(worlds=tuple(worlds), starts=starts, steps=int(rs["steps"]),
                              seed=seed, table=str(rs["table"]))  # fmt: skip


def chosen_file(record: dict[str, Any], name: str, out: Path) -> Path:
    """The chosen chromosome written from MATRIX's own record (``OUT/{name}.txt``), so the
    confirmation runs what the matrix ran even if the original file changed or is gone."""
    text = next(c["chromosome"] for c in record["controllers"] if c["name"] == name)
    path = out / f"{name}.txt"
    formatted = format_chromosome(parse_chromosome(text, name=name)) + "\n"
    if not path.is_file() or path.read_text() != formatted:
        atomic_write_text(path, formatted)
    return path


def confirm(
    doc: dict[str, Any], record: dict[str, Any], name: str, starts: int, seed: int, out: Path,
    workers: int | None = None,
) -> dict[str, Any]:  # fmt: skip
    """Run chromosome ``name`` of the matrix through every world of it from ``starts`` fresh
    starts of ``seed`` into ``out/confirm``; its ``robustness.json`` document."""
    settings = confirmation_settings(doc, record, starts, seed)
    file = chosen_file(record, name, out)
    bar = RunBar("confirm", True, total=starts * len(settings.worlds), unit="run")
    try:
        again = run_matrix([file], out / "confirm", settings, workers=workers, resume=True,
                           on_run=bar, on_skip=bar.advance)  # fmt: skip
    finally:
        bar.close()
    return again


def run_choice(
    matrix: Path, rule: ChoiceRule, out: Path, starts: int = 0, seed: int | None = None,
    workers: int | None = None,
) -> tuple[dict[str, Any], int]:  # fmt: skip
    """Choose among ``matrix``'s chromosomes of kind ``rule.sections``, confirm from
    ``starts`` fresh starts (0: none), write ``out/choice.{json,md,png}``; the document and
    the exit code."""
    doc, record = read_matrix(matrix)
    rows = finalist_rows(doc, rule.sections)
    worlds = choosing_worlds(doc, rule)
    goal = GOAL_PERCENT if rule.sections == "coverage" else None
    for r in rows:
        r.update(score(r["physics"], worlds), goals=against_goals(r["physics"], goal))
    i = choose(rows, worlds, rule)
    out_doc: dict[str, Any] = {
        "matrix": str(matrix), "rule": dataclasses.asdict(rule), "choosing_worlds": worlds,
        "worlds": [w["name"] for w in doc["worlds"]], "starts": doc["starts"],
        "seed": doc["seed"], "finalists": rows, "chosen_index": i, "chosen": rows[i]["name"],
    }  # fmt: skip
    code = 0
    if starts:
        seed = doc["seed"] + CONFIRM_SEED_OFFSET if seed is None else seed
        again = confirm(doc, record, rows[i]["name"], starts, seed, out, workers)
        physics = {w["name"]: figure_of(w["per_chromosome"][0], "physics", rule.sections)
                   for w in again["worlds"]}  # fmt: skip
        out_doc["confirmation"] = {
            "starts": starts, "seed": seed, "folder": str(out / "confirm"),
            "table": figure_of(again["table_per_chromosome"][0], "table", rule.sections),
            "physics": physics, **score(physics, worlds), "goals": against_goals(physics, goal),
            "ends": {w["name"]: w["per_chromosome"][0]["ends"] for w in again["worlds"]},
        }  # fmt: skip
        code = EXIT_FAILED if any(w["physics_errors"] for w in again["worlds"]) else 0
    atomic_write_json(out / "choice.json", out_doc)
    atomic_write_text(out / "choice.md", choice_markdown(out_doc))
    choice_figure(out_doc, out / "choice.png")
    return out_doc, code


def _pct(v: float | None) -> str:
    return "—" if v is None else f"{v:.1f}"


def _goal_text(g: dict[str, Any]) -> str:
    drop, at_goal = g["largest_drop_vs_shipped_pp"], g["every_world_at_goal"]
    return (
        f"worst world {g['worst_world']} {g['worst_percent']:.1f} %"
        + ("" if at_goal is None else
           f" (≥ {GOAL_PERCENT:g} % in every world: {'yes' if at_goal else 'no'})")
        + "; " + ("no shipped world" if drop is None else
                  f"largest drop below shipped {drop:.1f} pp"
                  + ("" if at_goal is None else f" (goal ≤ {GOAL_DROP_PP:g})"))
    )  # fmt: skip


def choice_markdown(doc: dict[str, Any]) -> str:
    """``choice.json`` as Markdown: the finalists × worlds, the choice and its confirmation."""
    worlds, rule = doc["worlds"], doc["rule"]
    sections = rule.get("sections", "coverage")
    held = [w for w in worlds if w not in doc["choosing_worlds"]]
    lines = [
        "# The finalist chosen by physics across the matrix's worlds", "",
        f"`{doc['matrix']}`, {doc['starts']} starts per world (seed {doc['seed']}). Rule: the "
        f"{sections} {'chromosome' if sections == 'coverage' else 'section'} whose "
        f"{rule['criterion']} physics {MEASURE[sections][0]} over "
        f"{', '.join(doc['choosing_worlds'])} is highest (ties: the mean)"
        + (f"; not choosing: {', '.join(held)}." if held else "."), "",
        "| chromosome | table | " + " | ".join(worlds) + " | worst (choosing) | mean (choosing) |",
        "|---" * (len(worlds) + 4) + "|",
    ]  # fmt: skip
    for i, r in enumerate(doc["finalists"]):
        label = f"**{r['name']} (chosen)**" if i == doc["chosen_index"] else r["name"]
        lines.append(f"| {label} | {_pct(r['table'])} | "
                     + " | ".join(_pct(r["physics"][w]) for w in worlds)
                     + f" | {r['worst']:.1f} | {r['mean']:.1f} |")  # fmt: skip
    c = doc.get("confirmation")
    if c:
        lines.append(f"| **{doc['chosen']}, {c['starts']} fresh starts** | {_pct(c['table'])} | "
                     + " | ".join(f"**{_pct(c['physics'][w])}**" for w in worlds)
                     + f" | {c['worst']:.1f} | {c['mean']:.1f} |")  # fmt: skip
    chosen = doc["finalists"][doc["chosen_index"]]
    lines += ["", f"Physics {', '.join(MEASURE[sections])}; table: the exact table "
              "world (SPEC §3) on the same starts.", "",
              f"- {chosen['name']} on the matrix's starts: {_goal_text(chosen['goals'])}."
              ]  # fmt: skip
    if c:
        lines.append(f"- On {c['starts']} fresh starts (seed {c['seed']}, `{c['folder']}`): "
                     f"{_goal_text(c['goals'])}.")  # fmt: skip
    return "\n".join(lines) + "\n"


def choice_figure(doc: dict[str, Any], path: Path) -> Path:
    """``choice.png``: the finalists × (table, worlds) heatmap, the chosen one marked and its
    confirmation beneath (``report.heatmap``)."""
    worlds = doc["worlds"]
    rows, vals = [], []
    for i, r in enumerate(doc["finalists"]):
        rows.append(f"{r['name']} ◀ chosen" if i == doc["chosen_index"] else r["name"])
        vals.append([r["table"], *(r["physics"][w] for w in worlds)])
    c = doc.get("confirmation")
    if c:
        rows.append(f"{doc['chosen']}, {c['starts']} fresh starts")
        vals.append([c["table"], *(c["physics"][w] for w in worlds)])
    grid = np.array([[np.nan if v is None else v for v in row] for row in vals], dtype=float)
    unit = "inner squares" if doc["rule"].get("sections", "coverage") == "coverage" else "docked"
    title = f"{doc['matrix']}: chosen by the {doc['rule']['criterion']} world — {unit}, %"
    return heatmap(path, rows, ["table", *worlds], grid, title, last_row_apart=bool(c))


def main(argv: list[str] | None = None) -> int:
    """Choose, optionally confirm, print ``choice.md``; exit 0, 1 or 2 (module docstring)."""
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    ap.add_argument(
        "matrix", type=Path, metavar="MATRIX", help="a finished servobot robustness folder"
    )
    ap.add_argument(
        "--by",
        choices=CRITERIA,
        default=ChoiceRule.criterion,
        help="score over the choosing worlds: the worst (default) or the mean",
    )
    ap.add_argument(
        "--worlds",
        default=None,
        metavar="LIST",
        help="comma-separated worlds that choose (default: the matrix's, less the "
        f"held-out {HELD_OUT.name})",
    )
    ap.add_argument(
        "--sections",
        choices=SECTIONS,
        default=ChoiceRule.sections,
        help="choose among the coverage chromosomes by inner coverage (default) or among the "
        "navigation sections by docking",
    )
    add_confirm_options(ap, "fresh starts in every world", "the matrix's", "MATRIX",
                        "servobot robustness")  # fmt: skip
    args = ap.parse_args(argv)  # fmt: skip
    out = args.out or args.matrix / "choice"

    def body() -> int:
        check_confirm_options(args)
        worlds = None if args.worlds is None else tuple(args.worlds.split(","))
        rule = ChoiceRule(args.by, worlds, args.sections)
        doc, code = run_choice(args.matrix, rule, out, args.confirm, args.confirm_seed,
                               args.workers)  # fmt: skip
        print(choice_markdown(doc), end="")
        return code

    return run_choice_command(PROG, argv, out, body)


if __name__ == "__main__":
    raise SystemExit(main())
