"""The colony's docks over time (issue 17): how often its robots dock, and how many stay live,
colony step by colony step.

A colony chromosome runs with the reference interpreter (``evolve.interpreter.run_colony``,
its ``on_event`` stream) in the table world from N colony starts (``evolve.starts.
colony_starts``), and for every colony step t = 0 … T the mean over the starts of

- the cumulative docks per robot (docks of all robots up to t, / R),
- the robots live (of R): not yet ended by the kill zone, an empty store or the branch limit
  (``LIVE_ENDS``: a robot that reached its own step limit stays live, as in
  ``final_test``'s ``live_at_end_per_run``),
- the robots charging: those whose colony step t was a charging step (a ``"charge"`` event).

A run that ends before T holds its last docks and live robots (nobody charges after it).

**Hand-offs in the colony and alone.** Every switch of a robot from coverage to navigation is a
hand-off (``evolve.handoff``): it docks, or the robot ends first, or the run's step limit cuts
it. For each finalist the same is counted for its robots run *alone* from their colony start
poses and start powers (``collect_handoffs``), so the two docking rates say what the other
robots cost the navigation section. A failed hand-off in the colony also records its
cancelled moves and whether another robot had already ended within ``NEAR_DOCK`` of the dock
point: ended robots stay as obstacles (SPEC §7).

**A dock in the event stream.** The interpreter counts a dock when, after a gait step in the
navigation section, the docking rule holds and no other robot charges. That step is a
``"gait"`` event of mode ``"navigation"`` whose pose meets the rule (``geometry.docked``)
and which did not end the robot (kill zone, store empty: checked before docking); the dock is
refused when that robot's next event is a ``"wait"`` (station busy). The charge itself shows
one colony step later (``"charge"`` events), or never when the dock was the robot's last
allowed gait step or the colony-step limit came first, so the dock is dated by its gait
step. Every run checks the count against ``RunResult.docks`` of each robot.

**What the other robots do to an approach** (``--others``, a diagnostic outside SPEC §7): the
same runs with the other robots ``unseen`` by the object sensors (they still block),
``passable`` (seen, never blocking a move), or both (``unseen-passable``); the station still
refuses a robot while another charges. The colony's hand-off rate in each against ``as-is``
says which of the two costs the navigation section its approaches (``OTHERS``).

Run: ``python -m evolve.colony_timeline RUN_DIR [--starts 20] [--seed 0] [--table paper|PATH]
[--others as-is|unseen|passable|unseen-passable] [--out FILE.png]``: every finalist
``RUN_DIR/colony/best_pop{k}.txt``, under the run's own settings (``colony/settings.json``:
``WorldSettings``, ``ColonySettings`` and the gait table it recorded, unless ``--table`` names
another), into ``RUN_DIR/colony/docks_over_time.png`` (``docks_over_time-OTHERS.png`` but for
``as-is``) and the curves beside it (``.json``); prints each finalist's final means and
hand-offs.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from evolve import geometry as geo
from evolve.codec import read_chromosome
from evolve.handoff import CUT, DOCKED, collect_handoffs, handoff_rate, open_outcome
from evolve.interpreter import (
    BLOCKED_MARK,
    END_NAMES,
    LIVE_ENDS,
    ColonyEvent,
    ColonyResult,
    run_colony,
)
from evolve.settings import ColonySettings, GASettings, WorldSettings, settings_from_record
from evolve.starts import colony_starts
from evolve.table import GaitTable, load_table
from evolve.world import TableColony
from infra.errors import InputError
from infra.io import atomic_write_json, read_json

DOCK_GOAL = 2.0
"""Issue 17's goal: every robot docks at least this many times in a run."""
LIVE_GOAL_SHARE = 2.0 / 3.0
"""Issue 17's goal: at least this share of the colony's robots live at the end (2 of 3)."""
NEAR_DOCK = 80.0
"""A failed hand-off is *beside an ended robot* when another robot ended within this many
units of the dock point before it failed, units."""
FIGURE_NAME = "docks_over_time.png"
"""The figure's default name in ``RUN_DIR/colony``; the curves go beside it as ``.json``."""


class _Passable(TableColony):
    """The other robots never block a move."""

    def _blockers(self, i: int, x: float, y: float) -> list[tuple[float, float]]:
        return []


OTHERS: dict[str, tuple[type[TableColony], bool]] = {
    "as-is": (TableColony, True), "unseen": (TableColony, False),
    "passable": (_Passable, True), "unseen-passable": (_Passable, False),
}  # fmt: skip
"""The colony worlds of ``--others``: SPEC §7's, and the other robots unseen by the object
sensors (``ColonySettings.robots_seen`` False), passable, or both (diagnostics, interpreter
only): (the colony's class, whether the other robots may be seen)."""


def others_colony(
    others: str, table: np.ndarray, starts: np.ndarray, world: WorldSettings,
    colony: ColonySettings,
) -> TableColony:  # fmt: skip
    """The table colony of ``--others`` ``others`` (a key of ``OTHERS``); robots the run's own
    settings leave unseen stay unseen."""
    cls, seen = OTHERS[others]
    seen_colony = dataclasses.replace(colony, robots_seen=colony.robots_seen and seen)
    return cls(table, starts, world, seen_colony)


class TimelineError(InputError, ValueError):
    """A run folder the timeline cannot use; the message names the folder and the problem."""


@dataclass(frozen=True)
class RunTimeline:
    """One colony run, colony step by colony step (index t = 0 … colony_steps)."""

    docks: np.ndarray
    """(T + 1,) int: docks of all robots up to and including colony step t."""
    live: np.ndarray
    """(T + 1,) int: robots live after colony step t (``LIVE_ENDS``)."""
    charging: np.ndarray
    """(T + 1,) int: robots that spent colony step t charging."""
    dock_steps: tuple[tuple[int, ...], ...]
    """Per robot: the colony steps at which it docked."""
    result: ColonyResult
    """The interpreter's result of the run."""
    handoffs: tuple[ColonyHandoff, ...]
    """Every hand-off of every robot, in the order they closed."""


@dataclass(frozen=True)
class ColonyHandoff:
    """One robot's switch to navigation in a colony run, and what followed."""

    robot: int
    outcome: str
    """``DOCKED``, ``CUT`` or the name of the robot's end (``END_NAMES``)."""
    blocked: int
    """Its moves cancelled between the switch and the outcome."""
    beside_ended: bool
    """Another robot had ended within ``NEAR_DOCK`` of the dock point when it closed."""


class _DockWatcher:
    """Follows a colony's events: each robot's docks (dated by their gait step), charging
    steps, end step and hand-offs (``ColonyHandoff``)."""

    def __init__(self, robots: int, world: WorldSettings) -> None:
        self.p = geo.packed_tuple(world)
        self.empty = world.empty_power_v
        self.pending: list[int | None] = [None] * robots
        self.docks: list[list[int]] = [[] for _ in range(robots)]
        self.charging: list[int] = []
        self.ended = [0] * robots
        self.dock_point = world.dock_point
        self.mode = ["coverage"] * robots
        self.blocked: list[int | None] = [None] * robots  # open hand-off's cancelled moves
        self.ended_near: set[int] = set()
        self.beside: list[bool | None] = [None] * robots  # at the robot's end, if it ended
        self.handoffs: list[ColonyHandoff] = []

    def _close(self, i: int, outcome: str) -> None:
        beside = self.beside[i] if self.beside[i] is not None else bool(self.ended_near - {i})
        self.handoffs.append(ColonyHandoff(i, outcome, self.blocked[i], beside))
        self.blocked[i] = None

    def close_open(self, result: ColonyResult) -> None:
        """Close the hand-offs still open when the run ended, with each robot's end."""
        for i, r in enumerate(result.robots):
            if self.blocked[i] is not None:
                self._close(i, open_outcome(r.end))

    def __call__(self, ce: ColonyEvent) -> None:
        i, t, e = ce.robot, ce.colony_step, ce.event
        if e.kind == "gait":
            if e.mode == "navigation" and self.mode[i] != "navigation":
                self.blocked[i] = 0
            self.mode[i] = e.mode
            if self.blocked[i] is not None and e.text.endswith(BLOCKED_MARK):
                self.blocked[i] += 1
        elif e.kind == "charge" and self.blocked[i] is not None:
            self._close(i, DOCKED)
        if self.pending[i] is not None:
            if e.kind != "wait":  # the docking rule held and the station was free
                self.docks[i].append(self.pending[i])
            self.pending[i] = None
        if e.kind == "gait" and e.mode == "navigation":
            x, y, h = e.pose
            if (
                not geo.killed(x, y, self.p)
                and e.power >= self.empty
                and geo.docked(x, y, h, self.p)
            ):
                self.pending[i] = t
        elif e.kind == "charge":
            self.charging.append(t)
        elif e.kind == "end":
            self.ended[i] = t
            self.beside[i] = bool(self.ended_near - {i})
            x, y, _ = e.pose
            if np.hypot(x - self.dock_point[0], y - self.dock_point[1]) <= NEAR_DOCK:
                self.ended_near.add(i)


def run_timeline(
    chromosome: np.ndarray,
    start: np.ndarray,
    *,
    table: GaitTable | np.ndarray,
    world: WorldSettings,
    colony: ColonySettings,
    start_power: float | None = None,
    max_steps: int | None = None,
    others: str = "as-is",
) -> RunTimeline:
    """One colony run of a 16-gene ``chromosome`` from ``start`` (R, 3) with the reference
    interpreter in the table world (coverage mode; ``others``: a key of ``OTHERS``), colony
    step by colony step. Raises ``AssertionError`` if the docks counted from the events
    differ from the interpreter's."""
    values = getattr(table, "values", table)
    start = np.asarray(start, dtype=np.float64)
    watch = _DockWatcher(start.shape[0], world)
    res = run_colony(
        np.asarray(chromosome, np.uint8), others_colony(others, values, start, world, colony),
        settings=world, colony=colony, start_power=start_power, max_steps=max_steps,
        on_event=watch,
    )  # fmt: skip
    watch.close_open(res)
    counted = [len(d) for d in watch.docks]
    want = [r.docks for r in res.robots]
    assert counted == want, f"docks from the events {counted} != the interpreter's {want}"
    steps = res.colony_steps + 1
    t = np.arange(steps)
    docks = np.zeros(steps, dtype=np.int64)
    for d in watch.docks:
        docks += np.searchsorted(np.sort(d), t, side="right")
    live = np.full(steps, len(res.robots), dtype=np.int64)
    for r, end in zip(res.robots, watch.ended, strict=True):
        if r.end not in LIVE_ENDS:
            live[end:] -= 1
    charging = np.bincount(np.asarray(watch.charging, dtype=np.int64), minlength=steps)[:steps]
    return RunTimeline(docks, live, charging, tuple(tuple(d) for d in watch.docks), res,
                       tuple(watch.handoffs))  # fmt: skip


def _hold(a: np.ndarray, n: int, fill: float | None = None) -> np.ndarray:
    """``a`` extended to length ``n`` with its last value (or ``fill``)."""
    pad = a[-1] if fill is None else fill
    return np.concatenate([a, np.full(n - len(a), pad, dtype=a.dtype)])


def colony_timeline(chromosome: np.ndarray, starts: np.ndarray, **run: Any) -> dict[str, Any]:
    """Means over the colony ``starts`` (S, R, 3) of a chromosome's runs (``run``: the keyword
    arguments of ``run_timeline``: table, world, colony, ...), per colony step
    t = 0 … T (T the longest run): ``docks_per_robot`` (cumulative docks / R), ``live`` and
    ``charging`` (robots, of R), as lists; and ``final_docks_per_robot`` (the interpreter's
    ``RunResult.docks``, mean over robots and starts: the last ``docks_per_robot``),
    ``live_at_end`` (``ColonyResult.live``, mean), ``colony_steps`` (mean run length),
    ``robots``, ``starts``."""
    starts = np.asarray(starts, dtype=np.float64)
    runs = [run_timeline(chromosome, s, **run) for s in starts]
    alone = {k: v for k, v in run.items() if k != "others"}  # a robot alone has no others
    in_colony = [h for r in runs for h in r.handoffs]
    n = max(len(r.docks) for r in runs)
    r_count = starts.shape[1]
    docks = np.mean([_hold(r.docks, n) for r in runs], axis=0) / r_count
    live = np.mean([_hold(r.live, n) for r in runs], axis=0)
    charging = np.mean([_hold(r.charging, n, 0) for r in runs], axis=0)
    return {
        "robots": r_count,
        "starts": len(runs),
        "docks_per_robot": docks.tolist(),
        "live": live.tolist(),
        "charging": charging.tolist(),
        "final_docks_per_robot": float(np.mean([[x.docks for x in r.result.robots] for r in runs])),
        "live_at_end": float(np.mean([r.result.live for r in runs])),
        "colony_steps": float(np.mean([r.result.colony_steps for r in runs])),
        "handoffs": _colony_handoff_rate(in_colony),
        "handoffs_alone": handoff_rate(_alone(chromosome, starts, **alone)),
    }


def _colony_handoff_rate(handoffs: list[ColonyHandoff]) -> dict[str, Any]:
    """``handoff_rate`` of a colony's hand-offs, the failed ones by their end, and their mean
    cancelled moves and share beside an ended robot (None without a failed one)."""
    failed = [h for h in handoffs if h.outcome not in (DOCKED, CUT)]
    return {
        **handoff_rate(handoffs),
        "failed_by_end": {n: sum(h.outcome == n for h in failed) for n in END_NAMES[1:4]},
        "blocked_per_failed": float(np.mean([h.blocked for h in failed])) if failed else None,
        "failed_beside_ended": float(np.mean([h.beside_ended for h in failed])) if failed else None,
    }


def _alone(
    chromosome: np.ndarray, starts: np.ndarray, *, table: GaitTable | np.ndarray,
    world: WorldSettings, colony: ColonySettings, start_power: float | None = None,
    max_steps: int | None = None,
) -> list[Any]:  # fmt: skip
    """The hand-offs of each robot of the colony ``starts`` (S, R, 3) run alone from its start
    pose and start power (``ColonySettings.start_powers``)."""
    p0 = world.start_power_v if start_power is None else start_power
    out = []
    for r, power in enumerate(colony.start_powers(p0, world.charged_power_v)):
        own = dataclasses.replace(world, start_power_v=power)
        for found in collect_handoffs(chromosome, starts[:, r], table=table, world=own,
                                      max_steps=max_steps):  # fmt: skip
            out += found
    return out


# --------------------------------------------------------------------------- a run folder


def finalists(run_dir: str | Path) -> list[Path]:
    """The colony finalists ``RUN_DIR/colony/best_pop{k}.txt`` in population order;
    ``TimelineError`` naming the folder if there are none."""
    folder = Path(run_dir, "colony")
    paths = [p for p in folder.glob("best_pop*.txt") if p.stem[8:].isdigit()]
    if not paths:
        raise TimelineError(
            f"{run_dir}: no colony finalists (colony/best_pop<k>.txt): not a finished colony "
            "stage's run folder"
        )
    return sorted(paths, key=lambda p: int(p.stem[8:]))


def run_settings(
    run_dir: str | Path,
) -> tuple[WorldSettings, ColonySettings, GASettings | None, np.ndarray | None, str | None]:
    """The colony stage's ``WorldSettings``, ``ColonySettings``, ``GASettings`` and gait table
    (values and source); the GA settings and the table None where not recorded. Fields the
    record leaves out take their defaults (``ColonySettings.to_dict`` omits defaults)."""
    path = Path(run_dir, "colony", "settings.json")
    if not path.is_file():
        raise TimelineError(
            f"{run_dir}: no colony/settings.json: the colony's settings are unknown"
        )
    doc = read_json(path, what="colony settings", error=TimelineError)
    if not isinstance(doc, dict):
        raise TimelineError(f"{path}: not a JSON object")
    world = settings_from_record(WorldSettings, doc.get("WorldSettings"), str(path), TimelineError)
    colony = settings_from_record(ColonySettings, doc.get("ColonySettings"), str(path),
                                  TimelineError)  # fmt: skip
    ga = (
        settings_from_record(GASettings, doc["GASettings"], str(path), TimelineError)
        if "GASettings" in doc
        else None
    )
    table = doc.get("table") if isinstance(doc.get("table"), dict) else {}
    values = table.get("values")
    arr = None if values is None else np.asarray(values, dtype=np.float64)
    return world, colony, ga, arr, table.get("source")


def docks_over_time(
    run_dir: str | Path,
    *,
    starts: int = 20,
    seed: int = 0,
    table: str | None = None,
    others: str = "as-is",
) -> dict[str, Any]:
    """``colony_timeline`` of every colony finalist of ``run_dir`` under the run's settings,
    from ``starts`` colony starts drawn from ``default_rng(seed)``, all curves held to the
    longest run. ``table``: "paper" or a calibration JSON instead of the run's recorded
    table; ``others``: a key of ``OTHERS``."""
    if starts < 1:
        raise TimelineError(f"--starts must be >= 1, got {starts}")
    if others not in OTHERS:
        raise TimelineError(f"--others must be one of {', '.join(OTHERS)}, got {others!r}")
    paths = finalists(run_dir)
    world, colony, _, recorded, source = run_settings(run_dir)
    if table is not None:
        gt = load_table(table)
        values, source = gt.values, str(table)
    elif recorded is not None:
        values = recorded
    else:
        values, source = load_table("paper").values, "paper"
    poses = colony_starts(np.random.default_rng(seed), starts, world, colony)
    curves = []
    for p in paths:
        c = colony_timeline(read_chromosome(p), poses, table=values, world=world, colony=colony,
                            others=others)  # fmt: skip
        curves.append({"finalist": p.stem, "label": p.stem.replace("best_pop", "population "), **c})
    n = max(len(c["docks_per_robot"]) for c in curves)
    for c in curves:
        for key, fill in (("docks_per_robot", None), ("live", None), ("charging", 0.0)):
            c[key] = _hold(np.asarray(c[key]), n, fill).tolist()
    return {
        "run_dir": str(run_dir),
        "table": source,
        "table_matches_run": recorded is None or bool(np.array_equal(values, recorded)),
        "starts": starts,
        "seed": seed,
        "others": others,
        "ColonySettings": colony.to_dict(),
        "dock_goal": DOCK_GOAL,
        "live_goal": LIVE_GOAL_SHARE * colony.robots,
        "curves": curves,
    }


def _rounded(doc: dict[str, Any]) -> dict[str, Any]:
    out = dict(doc)
    out["curves"] = [
        {k: [round(x, 5) for x in v] if isinstance(v, list) else v for k, v in c.items()}
        for c in doc["curves"]
    ]
    return out


def _share(rate: float | None) -> str:
    return "-" if rate is None else f"{100.0 * rate:.1f} %"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m evolve.colony_timeline",
                                 description=__doc__.splitlines()[0])  # fmt: skip
    ap.add_argument("run_dir", type=Path, help="a run folder with a colony stage")
    ap.add_argument("--starts", type=int, default=20, help="colony starts (20)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the colony starts (0)")
    ap.add_argument(
        "--table",
        default=None,
        help="'paper' or a calibration JSON (default: the run's recorded table)",
    )
    ap.add_argument("--others", choices=tuple(OTHERS), default="as-is",
                    help="the other robots as SPEC §7 has them (as-is), unseen by the object "
                         "sensors, passable, or both: a diagnostic")  # fmt: skip
    ap.add_argument(
        "--out",
        type=Path,
        default=None,
        help=f"figure path (default RUN_DIR/colony/{FIGURE_NAME}, with -OTHERS but for as-is); "
        "curves beside it",
    )
    args = ap.parse_args(argv)
    from evolve import figures

    t0 = time.perf_counter()
    try:
        doc = docks_over_time(args.run_dir, starts=args.starts, seed=args.seed, table=args.table,
                              others=args.others)  # fmt: skip
    except InputError as exc:
        print(f"evolve.colony_timeline: {exc}", file=sys.stderr)
        return 2
    name = FIGURE_NAME if args.others == "as-is" else FIGURE_NAME.replace(".", f"-{args.others}.")
    out = args.out if args.out is not None else args.run_dir / "colony" / name
    c = settings_from_record(ColonySettings, doc["ColonySettings"], str(out), TimelineError)
    title = (
        f"{args.run_dir}: a colony of {c.robots} ({c.blocking}, fitness {c.fitness}"
        f"{'' if c.robots_seen else ', robots unseen'}), "
        f"{args.starts} colony starts (seed {args.seed}), table {doc['table']}"
        + ("" if args.others == "as-is" else f", other robots {args.others}")
    )
    figures.figure_colony_docks(out, doc["curves"], title)
    atomic_write_json(out.with_suffix(".json"), _rounded(doc))
    if not doc["table_matches_run"]:
        print(f"note: table {doc['table']} is not the table the run recorded", file=sys.stderr)
    print(f"{args.run_dir}: {args.starts} colony starts of {c.robots} (seed {args.seed}), "
          f"table {doc['table']}")  # fmt: skip
    for cv in doc["curves"]:
        print(f"  {cv['finalist']}: docks per robot {cv['final_docks_per_robot']:.2f}, "
              f"live at the end {cv['live_at_end']:.2f} of {cv['robots']}, "
              f"colony steps {cv['colony_steps']:.0f}")  # fmt: skip
        h, alone = cv["handoffs"], cv["handoffs_alone"]
        failed = ", ".join(f"{k} {v}" for k, v in h["failed_by_end"].items())
        context = ""
        if h["blocked_per_failed"] is not None:
            context = (f"; per failed: {h['blocked_per_failed']:.1f} moves cancelled, beside "
                       f"an ended robot {_share(h['failed_beside_ended'])}")  # fmt: skip
        print(f"    hand-offs docked {_share(h['dock_rate'])} in the colony ({h['handoffs']}; "
              f"failed: {failed}{context}), {_share(alone['dock_rate'])} alone "
              f"({alone['handoffs']})")  # fmt: skip
    print(f"wrote {out} and {out.with_suffix('.json')} in {time.perf_counter() - t0:.1f} s")
    return 0


__all__ = [
    "DOCK_GOAL",
    "FIGURE_NAME",
    "LIVE_GOAL_SHARE",
    "NEAR_DOCK",
    "OTHERS",
    "ColonyHandoff",
    "RunTimeline",
    "TimelineError",
    "colony_timeline",
    "docks_over_time",
    "finalists",
    "others_colony",
    "run_settings",
    "run_timeline",
]


if __name__ == "__main__":
    sys.exit(main())
