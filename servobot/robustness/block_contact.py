"""Which table rule for the station block predicts a robot walking into it in MuJoCo (issue 16):
``Envelope.station_blocking`` ``cancel`` against ``slide`` at a sweep of ``station_friction``.

    python -m servobot.robustness.block_contact [--table runs/cal/gait_table.json] \\
        [--frictions 0,0.25,0.4,0.5,0.6,0.75,1] [--cycles 3] [--margins 0,1,2,3,4,5] \\
        [--bodies 15/15/12,18/15/12] [--world shipped] [--out runs/block_contact]

From each pose of a set in front of the block, the robot walks ``--cycles`` cycles of one gait
in a physics world of the test matrix (``--world``: ``shipped``, whose low block stops it, or
a robot variant such as ``slippery``, with that robot's calibrated ``--table``) and in the
table world with the block always in the way, under each rule. A case counts when the
table's block stops at least one of its moves (under ``cancel``); its errors are the distance
between the table's and physics' final positions (units) and between their headings
(degrees). Two pose sets:
``tuning`` (on which the friction was chosen) and ``held-out`` (other poses, every gait).
Writes ``OUT/block_contact.json``, ``.md`` and ``.png`` (mean position error against the
friction, both sets, ``cancel`` as a line).

``--margins 0,1,2,3,4,5`` adds a cycle-by-cycle comparison (``cycle_errors``): before each
physics cycle of every case, each rule (``cancel``, and ``slide`` at friction 0.5 with each
``Envelope.station_margin``) walks that one cycle in the table world from physics' pose; its
errors are the distance to physics' end and the difference of the turns. Every cycle counts,
stopped or not, so a block that stops at a larger distance is judged on the near misses too.
``--bodies 15/15/12,...`` adds ``slide`` rules whose robot is an oval (``Envelope.body_front``
/ ``body_back`` / ``body_side``, units) to that comparison, and both run on a third pose set,
``corners``: poses beside the block's two ends, walking past its corners, where the robot's
narrow sides come closer to the block than its disc.
"""

from __future__ import annotations

import argparse
import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from evolve.envelope import STOPS_ALWAYS, Envelope
from evolve.geometry import wrap180
from evolve.table import N_GAITS, PAPER_TABLE, load_table
from evolve.world import TableWorld
from infra.io import atomic_write, write_report
from servo_mj.world.arena import ArenaSettings, default_robot
from servobot.robustness.report import DPI
from servobot.robustness.worlds import WorldError, materialise, resolve_worlds

Pose = tuple[float, float, float]

HEADINGS = (30.0, 60.0, 90.0, 120.0, 150.0)
POSE_SETS: dict[str, tuple[list[Pose], tuple[int, ...]]] = {
    "tuning": (
        list(itertools.product((452.0, 456.0, 460.0), (235.0, 255.0, 275.0), HEADINGS)),
        (0, 1, 5, 9, 12, 13),
    ),
    "held-out": (
        list(itertools.product((454.0, 458.0), (225.0, 245.0, 265.0), (45.0, 75.0, 105.0, 135.0))),
        tuple(range(N_GAITS)),
    ),
}
"""Start poses (x, y units; heading deg) in front of the block (x ≥ 480, |y − 250| ≤ 30) and
the gaits walked from each."""
CORNERS: tuple[list[Pose], tuple[int, ...]] = (
    [*itertools.product((462.0, 468.0), (294.0, 297.0, 300.0), (60.0, 90.0, 120.0)),
     *itertools.product((462.0, 468.0), (206.0, 203.0, 200.0), (60.0, 90.0, 120.0))],
    tuple(range(N_GAITS)),
)  # fmt: skip
"""The ``corners`` pose set of the cycle-by-cycle comparison (``--margins``, ``--bodies``):
start poses beside the block's north (y 280) and south (y 220) ends, heading east-ish, every
gait."""
FRICTIONS = (0.0, 0.25, 0.4, 0.5, 0.6, 0.75, 1.0)
"""``station_friction`` values swept by default."""
MARGIN_FRICTION = 0.5
"""``station_friction`` of the slide rules compared at each ``--margins`` value."""


@dataclass(frozen=True)
class ContactErrors:
    """One rule's errors over a pose set's cases: (n, 2) position error (units), heading error
    (deg)."""

    rule: str
    errors: np.ndarray

    def summary(self) -> dict[str, float]:
        out = {}
        for i, what in enumerate(("position", "heading")):
            out[f"{what}_mean"] = float(self.errors[:, i].mean())
            out[f"{what}_median"] = float(np.median(self.errors[:, i]))
        return out


def rules(frictions: Sequence[float]) -> dict[str, Envelope]:
    """The table worlds compared: ``cancel`` and ``slide`` at each friction, the block always
    in the way (as in physics) and unseen."""
    out = {"cancel": Envelope(station_stops=STOPS_ALWAYS)}
    for mu in frictions:
        out[f"slide {mu:g}"] = Envelope(station_stops=STOPS_ALWAYS, station_blocking="slide",
                                        station_friction=float(mu))  # fmt: skip
    return out


Walks = dict[tuple[Pose, int], list[Pose]]
"""Physics' poses of each case (start pose, gait): before each cycle, then after the last."""


def walk_physics(
    poses: Sequence[Pose], gaits: Sequence[int], cycles: int, *,
    arena: ArenaSettings | None = None, model: Path | None = None,
) -> Walks:  # fmt: skip
    """Every case (pose × gait) walked ``cycles`` cycles in physics: the shipped world, or
    ``arena`` with the robot of the MJCF file ``model`` (a matrix world's,
    ``servobot.robustness.worlds``)."""
    from servo_mj.world.physics_world import PhysicsWorld  # physics only where it is run

    robot = None if model is None else default_robot(model)
    walks: Walks = {}
    for pose, gait in itertools.product(poses, gaits):
        phys = PhysicsWorld(*pose, arena=arena, robot=robot)
        track = [phys.pose()]
        for _ in range(cycles):
            phys.step(gait)
            track.append(phys.pose())
        walks[pose, gait] = track
    return walks


def _errors(tab: TableWorld, phys: Pose) -> tuple[float, float]:
    """Distance (units) and heading difference (deg) between a table pose and physics'."""
    (x, y, h), (px, py, ph) = tab.pose(), phys
    return float(np.hypot(x - px, y - py)), abs(wrap180(h - ph))


def contact_errors(
    table: np.ndarray, poses: Sequence[Pose], gaits: Sequence[int], envelopes: dict[str, Envelope],
    cycles: int = 3, walks: Walks | None = None,
) -> list[ContactErrors]:  # fmt: skip
    """Each rule's errors against physics over the cases (pose × gait) whose block stops a
    move under the first rule of ``envelopes`` (``cancel``); ``walks``: physics' walks of
    these cases (``walk_physics``, walked here when None)."""
    walks = walk_physics(poses, gaits, cycles) if walks is None else walks
    errors: dict[str, list[tuple[float, float]]] = {name: [] for name in envelopes}
    first = next(iter(envelopes))
    for pose, gait in itertools.product(poses, gaits):
        tabs = {name: TableWorld(table, *pose, envelope=env) for name, env in envelopes.items()}
        stopped = False
        for _ in range(cycles):
            for name, tab in tabs.items():
                stopped |= tab.step(gait) and name == first
        if not stopped:
            continue
        for name, tab in tabs.items():
            errors[name].append(_errors(tab, walks[pose, gait][-1]))
    return [ContactErrors(name, np.array(e, dtype=float).reshape(-1, 2))
            for name, e in errors.items()]  # fmt: skip


def margin_rules(margins: Sequence[float]) -> dict[str, Envelope]:
    """``cancel`` and ``slide`` at ``MARGIN_FRICTION`` with each ``station_margin``, the block
    always in the way and unseen."""
    out = {"cancel": Envelope(station_stops=STOPS_ALWAYS)}
    for m in margins:
        out[f"slide {MARGIN_FRICTION:g}, margin {m:g}"] = Envelope(
            station_stops=STOPS_ALWAYS, station_blocking="slide",
            station_friction=MARGIN_FRICTION, station_margin=float(m),
        )  # fmt: skip
    return out


def body_rules(bodies: Sequence[tuple[float, float, float]]) -> dict[str, Envelope]:
    """``slide`` at ``MARGIN_FRICTION`` with each oval body (front, back, side; units), the
    block always in the way and unseen."""
    out = {}
    for front, back, side in bodies:
        out[f"slide {MARGIN_FRICTION:g}, body {front:g}/{back:g}/{side:g}"] = Envelope(
            station_stops=STOPS_ALWAYS, station_blocking="slide", station_friction=MARGIN_FRICTION,
            body_front=front, body_back=back, body_side=side,
        )  # fmt: skip
    return out


def parse_bodies(text: str) -> list[tuple[float, float, float]]:
    """``"15/15/12,18/15/12"`` → [(15, 15, 12), (18, 15, 12)]; ``ValueError`` naming a bad one."""
    out = []
    for item in text.split(","):
        parts = item.split("/")
        if len(parts) != 3:
            raise ValueError(f"a body is FRONT/BACK/SIDE (units), got {item!r}")
        front, back, side = (float(v) for v in parts)
        out.append((front, back, side))
    return out


def cycle_errors(
    table: np.ndarray, poses: Sequence[Pose], gaits: Sequence[int], envelopes: dict[str, Envelope],
    cycles: int = 3, walks: Walks | None = None,
) -> list[ContactErrors]:  # fmt: skip
    """Each rule's errors against physics cycle by cycle: before each of a case's ``cycles``
    physics cycles, the rule walks the same cycle in the table world from physics' pose; the
    errors are the distance between the two ends (units) and between the two turns (deg).
    ``walks`` as for ``contact_errors``."""
    walks = walk_physics(poses, gaits, cycles) if walks is None else walks
    errors: dict[str, list[tuple[float, float]]] = {name: [] for name in envelopes}
    for pose, gait in itertools.product(poses, gaits):
        track = walks[pose, gait]
        for start, end in itertools.pairwise(track):
            for name, env in envelopes.items():
                tab = TableWorld(table, *start, envelope=env)
                tab.step(gait)
                errors[name].append(_errors(tab, end))
    return [ContactErrors(name, np.array(e, dtype=float).reshape(-1, 2))
            for name, e in errors.items()]  # fmt: skip


def report(
    results: dict[str, list[ContactErrors]], cycles: int, *,
    title: str = "The station block's rule against physics", counted: str = "cases the block stops",
    world: str = "shipped",
) -> tuple[dict, str]:  # fmt: skip
    """(JSON document, markdown) of each pose set's per-rule summaries, physics walked in
    the matrix world ``world``."""
    doc = {"cycles": cycles, "world": world, "sets": {}}
    lines = [f"# {title} ({cycles} cycles per case, physics world `{world}`)", ""]
    for name, rows in results.items():
        n = len(rows[0].errors)
        doc["sets"][name] = {"cases": n, "rules": {r.rule: r.summary() for r in rows}}
        lines += [f"## {name}: {n} {counted}", "",
                  "| rule | position error, mean / median (units) | heading error (°) |",
                  "|---|---|---|"]  # fmt: skip
        for r in rows:
            s = r.summary()
            lines.append(f"| {r.rule} | {s['position_mean']:.2f} / {s['position_median']:.2f} | "
                         f"{s['heading_mean']:.2f} / {s['heading_median']:.2f} |")  # fmt: skip
        lines.append("")
    return doc, "\n".join(lines)


def plot(results: dict[str, list[ContactErrors]], frictions: Sequence[float], path: Path) -> None:
    """Mean position error against ``station_friction`` per pose set, ``cancel`` dashed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    for (name, rows), colour in zip(results.items(), ("C0", "C1"), strict=False):
        by_rule = {r.rule: r.summary()["position_mean"] for r in rows}
        ax.plot(frictions, [by_rule[f"slide {mu:g}"] for mu in frictions], "o-", color=colour,
                label=f"slide, {name}")  # fmt: skip
        ax.axhline(by_rule["cancel"], color=colour, ls="--", label=f"cancel, {name}")
    ax.set_xlabel("station_friction")
    ax.set_ylabel("mean position error vs physics (units)")
    ax.set_title("A robot walking into the station block: table vs MuJoCo")
    ax.legend(fontsize=8)
    try:
        atomic_write(path, lambda p: fig.savefig(p, dpi=DPI, bbox_inches="tight"))
    finally:
        plt.close(fig)


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m servobot.robustness.block_contact",
                                 description=__doc__.split("\n")[0])  # fmt: skip
    ap.add_argument("--table", help="calibrated gait table (default: the paper's)")
    ap.add_argument("--frictions", default=",".join(f"{f:g}" for f in FRICTIONS))
    ap.add_argument("--cycles", type=int, default=3)
    ap.add_argument("--margins", help="station_margin values (units) compared cycle by cycle, "
                    "e.g. 0,1,2,3,4,5 (default: none)")  # fmt: skip
    ap.add_argument("--bodies", help="oval bodies FRONT/BACK/SIDE (units) compared cycle by "
                    "cycle, e.g. 15/15/12,18/15/12 (default: none)")  # fmt: skip
    ap.add_argument("--world", default="shipped", help="the physics world walked: a test "
                    "matrix world (shipped, slippery, heavy, ...; `servobot robustness`) or a "
                    "`servobot variant` file (default shipped)")  # fmt: skip
    ap.add_argument("--out", type=Path, default=Path("runs/block_contact"))
    args = ap.parse_args(argv)
    try:
        (world,) = resolve_worlds([args.world])
    except WorldError as exc:
        ap.error(f"--world: {exc}")
    try:
        frictions = [float(f) for f in args.frictions.split(",")]
        envelopes = rules(frictions)
    except ValueError as exc:
        ap.error(f"--frictions: {exc}")
    by_cycle_rules: dict[str, Envelope] = {}
    if args.margins is not None or args.bodies is not None:
        try:
            by_cycle_rules = margin_rules([float(m) for m in (args.margins or "0").split(",")])
        except ValueError as exc:
            ap.error(f"--margins: {exc}")
    if args.bodies is not None:
        try:
            by_cycle_rules |= body_rules(parse_bodies(args.bodies))
        except ValueError as exc:
            ap.error(f"--bodies: {exc}")
    if args.cycles < 1:
        ap.error(f"--cycles must be ≥ 1, got {args.cycles}")
    table = PAPER_TABLE if args.table is None else load_table(args.table).values
    sets = {**POSE_SETS, "corners": CORNERS} if by_cycle_rules else POSE_SETS
    model = materialise(world, args.out / "models")
    walks = {name: walk_physics(poses, gaits, args.cycles, arena=world.arena, model=model)
             for name, (poses, gaits) in sets.items()}  # fmt: skip
    results = {name: contact_errors(table, poses, gaits, envelopes, args.cycles, walks[name])
               for name, (poses, gaits) in POSE_SETS.items()}  # fmt: skip
    doc, md = report(results, args.cycles, world=world.name)
    if by_cycle_rules:
        by_cycle = {name: cycle_errors(table, poses, gaits, by_cycle_rules, args.cycles,
                                       walks[name])
                    for name, (poses, gaits) in sets.items()}  # fmt: skip
        doc_c, md_c = report(by_cycle, args.cycles, counted="cycles", world=world.name,
                             title="Cycle by cycle, every cycle: the block's reach")  # fmt: skip
        doc["cycle_by_cycle"] = doc_c["sets"]
        md += "\n" + md_c
    write_report(args.out, "block_contact", doc, md)
    plot(results, frictions, args.out / "block_contact.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
