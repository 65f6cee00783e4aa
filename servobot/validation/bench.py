"""Cost of a validation run per gait step against the bare gait cycle it walks.

For each start, interleaved ``--repeats`` times, in this process:

- **validation**: ``servobot.validation.lone.run_start`` without recording (table run, then the
  physics run through the interpreter, its sensors and the per-event record keeping), time
  per physics step;
- **validation, sensors every step**: the same with MuJoCo's sensor stage on at every physics
  step, as before the rangefinders were read on demand (the comparison that shows the gain);
- **bare**: the same gait sequence (taken from that run) walked by ``ServoBot.run_gait`` in
  the calibration scene, with the same servo noise: the physics alone.

Times are CPU seconds of this process (``time.process_time``), which other jobs on the machine
disturb far less than wall time; validation is single-threaded, so on a quiet machine they
equal wall time. Prints per-step costs and the ratio validation / bare; asserts nothing.

The default controller (``evolve.bench.circling_population``) circles from the arena centre
testing object and light sensors, with enough power that every run lasts ``--steps``;
``--chromosome FILE`` runs a 16-gene chromosome from seeded coverage starts instead (runs
end as the controller makes them).

Run: ``python -m servobot.validation.bench [--starts 2] [--steps 150] [--repeats 2]
[--chromosome FILE] [--seed 0]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time
from pathlib import Path

import mujoco
import numpy as np

from calibration.bench import bench_gait
from evolve.bench import LONG_START_POWER_V, circling_population
from evolve.codec import read_chromosome
from evolve.interpreter import run
from evolve.settings import WorldSettings
from evolve.starts import coverage_starts
from evolve.table import PAPER_TABLE
from servo_mj.robot.bot import ServoBot
from servo_mj.robot.model import load_robot
from servo_mj.robot.settings import PhysicsSettings
from servo_mj.world.arena import ArenaSettings
from servo_mj.world.physics_world import PhysicsWorld, colony
from servobot.validation.lone import StartJob, run_start

ARENA_CENTRE_START = (250.0, 250.0)
"""Where the default circling controller starts (x, y cm), clear of walls and station."""


def _jobs(args: argparse.Namespace) -> list[StartJob]:
    rng = np.random.default_rng(args.seed)
    world = WorldSettings()
    if args.chromosome is None:
        bits_list = list(circling_population(rng, args.starts))
        starts = [(*ARENA_CENTRE_START, float(h)) for h in rng.uniform(0, 360, args.starts)]
        world = dataclasses.replace(world, start_power_v=LONG_START_POWER_V)
    else:
        bits = read_chromosome(args.chromosome)
        bits_list = [bits] * args.starts
        starts = [tuple(s) for s in coverage_starts(rng, args.starts, world)]
    return [
        StartJob(
            index=k,
            bits=b,
            start=s,
            table=PAPER_TABLE,
            world=world,
            arena=ArenaSettings(),
            physics=None,
            max_steps=args.steps,
            rrd_path=None,
            seed=args.seed,
        )  # fmt: skip
        for k, (b, s) in enumerate(zip(bits_list, starts, strict=True))
    ]


def gait_sequence(job: StartJob) -> tuple[list[int], np.ndarray]:
    """The gaits the physics run of ``job`` walks, and its track (untimed replay)."""
    pw = PhysicsWorld(*job.start, world=job.world, arena=job.arena,
                      rng=np.random.default_rng((job.seed, job.index)))  # fmt: skip
    gaits: list[int] = []

    def on_event(e) -> None:
        if e.kind == "gait":
            gaits.append(e.gait)

    res = run(job.bits, pw, mode="coverage", settings=job.world, max_steps=job.max_steps,
              on_event=on_event)  # fmt: skip
    return gaits, res.track


def time_validation(job: StartJob, *, every_step_sensors: bool = False) -> tuple[float, dict]:
    """(CPU s, record) of ``run_start(job)``; optionally with the sensor stage on."""
    model = colony(job.world, job.arena).model
    flag = int(mujoco.mjtDisableBit.mjDSBL_SENSOR)
    before = model.opt.disableflags
    if every_step_sensors:
        model.opt.disableflags = before & ~flag
    try:
        t0 = time.process_time()
        rec = run_start(job)
        return time.process_time() - t0, rec
    finally:
        model.opt.disableflags = before


def time_bare(gaits: list[int], seed: tuple[int, int]) -> float:
    """CPU s of ``gaits`` walked in the calibration scene (servo noise as in validation)."""
    m, d = load_robot(scene=True)
    bot = ServoBot(m, d, physics=PhysicsSettings(), rng=np.random.default_rng(seed))
    bot.place(0.0, 0.0, 0.0)
    t0 = time.process_time()
    for g in gaits:
        bot.run_gait(g)
    return time.process_time() - t0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m servobot.validation.bench")
    p.add_argument("--starts", type=int, default=2, help="start poses (2)")
    p.add_argument("--steps", type=int, default=150, help="step limit per run (150)")
    p.add_argument("--repeats", type=int, default=2, help="interleaved repeats (2)")
    p.add_argument("--chromosome", type=Path, default=None, help="a 16-gene chromosome file")
    p.add_argument("--seed", type=int, default=0, help="seed of starts, controllers, noise (0)")
    args = p.parse_args(argv)
    if min(args.starts, args.steps, args.repeats) < 1:
        p.error("--starts, --steps and --repeats must be at least 1")
    print(f"mujoco {mujoco.__version__}, {os.cpu_count()} cpus, load {os.getloadavg()[0]:.2f}")
    jobs = _jobs(args)
    totals = np.zeros(3)  # validation, validation with sensors every step, bare
    steps = 0
    for job in jobs:
        gaits, track = gait_sequence(job)
        walls = np.zeros(3)
        for _ in range(args.repeats):
            t_val, rec = time_validation(job)
            t_old, _ = time_validation(job, every_step_sensors=True)
            walls += (t_val, t_old, time_bare(gaits, (job.seed, job.index)))
        assert rec["physics"]["steps"] == len(gaits) and np.array_equal(
            rec["tracks"]["physics"], track
        ), "the replay differs from the validation run"
        n = len(gaits) * args.repeats
        ms = 1000.0 * walls / max(n, 1)
        print(
            f"start {job.index} ({', '.join(f'{v:.1f}' for v in job.start)}): {len(gaits)} steps; "
            f"validation {ms[0]:.2f} ms/step (sensors every step {ms[1]:.2f}), "
            f"bare {ms[2]:.2f} ms/cycle; ratio {ms[0] / ms[2]:.3f} ({ms[1] / ms[2]:.3f})"
        )
        totals += walls
        steps += n
    ms = 1000.0 * totals / max(steps, 1)
    print(
        f"all (CPU time): validation {ms[0]:.2f} ms/step, sensors every step {ms[1]:.2f}, "
        f"bare same gaits {ms[2]:.2f} ms/cycle; ratio validation/bare {ms[0] / ms[2]:.3f} "
        f"(sensors every step {ms[1] / ms[2]:.3f})"
    )
    print(f"calibration walk, gait 0 in the bare scene: {bench_gait(60)[2]:.2f} ms/cycle (wall)")
    print(f"load {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
