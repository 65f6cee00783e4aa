"""Where does physics depart from the gait table along real controller runs? (diagnostic)

``python -m calibration.gap CHROMOSOME --table TABLE.json [--starts 10] [--seed 0]
[--steps 600] [--noise RAD] [--station-depth M] [--robot-xml FILE] [--navigation]
[--dump FILE.npz]``

``--navigation``: CHROMOSOME is an 8-gene navigation section, run in navigation mode from
SPEC §6 navigation starts (those overlapping the station block are skipped) — isolates
docking. ``--robot-xml``: a variant of ``models/servobot/servobot.xml`` (e.g. other probes).

Runs the chromosome (coverage mode) in the physics world from the same seeded start poses as
``servobot validate`` (``evolve.starts.coverage_starts``) and logs every gait cycle the
interpreter executes (``calibration.residuals``).
Each cycle's physical move (F, T cm, dH deg, in the frame the robot had when it began) is
compared with the table row of its gait. It prints the residual (physics − table) per gait,
for cycles that repeat the previous gait vs cycles after a gait change, and the first cycle
after placement; the end reasons and docks; and the table-world run's squares for comparison.
Prints only; asserts nothing.
"""

from __future__ import annotations

import argparse
import dataclasses
from collections import Counter, defaultdict

import numpy as np

from calibration.residuals import LoggingWorld, residuals
from evolve.codec import read_chromosome
from evolve.interpreter import END_NAMES, run
from evolve.settings import WorldSettings
from evolve.starts import coverage_starts, navigation_starts
from evolve.table import load_table
from evolve.world import TableWorld
from servo_mj.robot.settings import PhysicsSettings
from servo_mj.world.arena import ArenaSettings, default_robot, overlaps_station
from servo_mj.world.physics_world import PhysicsWorld


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m calibration.gap", description=__doc__)
    p.add_argument("chromosome")
    p.add_argument("--table", required=True)
    p.add_argument("--starts", type=int, default=10)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--steps", type=int, default=600)
    p.add_argument("--noise", type=float, default=0.0)
    p.add_argument("--station-depth", type=float, default=None)
    p.add_argument("--dump", default=None, help="write per-cycle records to this .npz")
    p.add_argument("--robot-xml", default=None, help="robot MJCF variant to use in physics")
    p.add_argument("--navigation", action="store_true", help="8-gene section, docking runs")
    a = p.parse_args(argv)
    world = WorldSettings()
    table = np.asarray(load_table(a.table).values, dtype=float)
    bits = read_chromosome(a.chromosome)
    arena = ArenaSettings()
    if a.station_depth is not None:
        arena = dataclasses.replace(arena, station_depth_m=a.station_depth)
    physics = PhysicsSettings(servo_noise_rad=a.noise)
    robot = None
    if a.robot_xml:
        from pathlib import Path

        robot = dataclasses.replace(default_robot(), xml=Path(a.robot_xml).resolve())
    mode = "navigation" if a.navigation else "coverage"
    if a.navigation:
        starts = navigation_starts(np.random.default_rng(a.seed), 2 * a.starts, world)
        starts = [s for s in starts if not overlaps_station(s[0], s[1], world, arena)]
        starts = np.asarray(starts[: a.starts])
        if a.steps == 600:
            a.steps = world.navigation_steps
    else:
        starts = coverage_starts(np.random.default_rng(a.seed), a.starts, world)
    all_res: list[tuple[int, int, np.ndarray]] = []
    dump: list[list[float]] = []
    ends: Counter[str] = Counter()
    t_ends: Counter[str] = Counter()
    rows = []
    for k, (x, y, h) in enumerate(starts):
        tres = run(bits, TableWorld(table, x, y, h, world), mode=mode, max_steps=a.steps)
        lw = LoggingWorld(
            PhysicsWorld(x, y, h, world=world, arena=arena, physics=physics, robot=robot,
                         rng=np.random.default_rng((a.seed, k)))
        )  # fmt: skip
        pres = run(bits, lw, mode=mode, max_steps=a.steps)
        res_k = residuals(lw.log, table)
        all_res.extend(res_k)
        for (g, prev, r), (_, before, after) in zip(res_k, lw.log, strict=True):
            dump.append([k, g, prev, *before, *after, *r])
        ends[END_NAMES[pres.end]] += 1
        t_ends[END_NAMES[tres.end]] += 1
        rows.append((k, tres.inner_squares, pres.inner_squares, tres.docks, pres.docks,
                     tres.steps, pres.steps, END_NAMES[tres.end], END_NAMES[pres.end]))  # fmt: skip
    print("run  inner(table phys)  docks(table phys)  steps(table phys)  end(table | phys)")
    for r in rows:
        print(f"{r[0]:3d}  {r[1]:5d} {r[2]:5d}      {r[3]:5d} {r[4]:5d}     {r[5]:5d} {r[6]:5d}"
              f"     {r[7]} | {r[8]}")  # fmt: skip
    ti, pi = np.mean([r[1] for r in rows]), np.mean([r[2] for r in rows])
    n = world.inner_square_count
    print(f"mean inner % of {n}: table {100 * ti / n:.1f}, physics {100 * pi / n:.1f}, "
          f"gap {100 * (ti - pi) / n:+.1f} pp")  # fmt: skip
    print("ends table:", dict(t_ends), " physics:", dict(ends))
    if a.navigation:
        docked = [(r[5], r[6]) for r in rows]
        td = [t for t, _ in docked if t]
        print(f"docked: table {sum(r[3] > 0 for r in rows)}/{len(rows)}, physics "
              f"{sum(r[4] > 0 for r in rows)}/{len(rows)}; mean steps table "
              f"{np.mean([r[5] for r in rows]):.1f}, physics {np.mean([r[6] for r in rows]):.1f}"
              f" ({len(td)} runs)")  # fmt: skip
    by_gait: dict[int, list[np.ndarray]] = defaultdict(list)
    rep, chg, first = [], [], []
    for g, prev, r in all_res:
        by_gait[g].append(r)
        (first if prev < 0 else rep if prev == g else chg).append(r)
    print("\nresidual physics - table per cycle: mean (F, T, dH) / mean |.|, n")
    for g in sorted(by_gait):
        v = np.array(by_gait[g])
        print(f"gait {g:2d}: mean {np.round(v.mean(0), 2)}  |.| {np.round(np.abs(v).mean(0), 2)}"
              f"  n={len(v)}")  # fmt: skip
    for name, v in (("repeat", rep), ("after change", chg), ("first cycle", first)):
        if v:
            v = np.array(v)
            print(f"{name:13s}: mean {np.round(v.mean(0), 2)}  |.| "
                  f"{np.round(np.abs(v).mean(0), 2)}  n={len(v)}")  # fmt: skip
    if a.dump:
        np.savez(a.dump, cycles=np.array(dump))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
