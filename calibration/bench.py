"""Speed of the ServoBot physics: steps per second, real-time factor, calibration wall time
on each executor.

Prints rates, asserts nothing. Run: ``python -m calibration.bench [--cycles N]
[--executors serial process ray] [--workers 2]``. The cost of a validation run against this
bare cycle is ``python -m servobot.validation.bench``.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import sys
import time

import mujoco
import numpy as np

from calibration.measure import DEFAULTS, measure_all
from infra.executors import RayExecutor, make_executor
from servo_mj.robot.bot import ServoBot
from servo_mj.robot.model import load_robot
from servo_mj.robot.settings import PhysicsSettings


def bench_gait(cycles: int, gait: int = 0, cone: int | None = None) -> tuple[float, float, float]:
    """Walk ``cycles`` cycles of ``gait``: (steps/s, real-time factor, ms wall per cycle).
    ``cone``: a ``mujoco.mjtCone`` value instead of the scene's (comparison only)."""
    m, d = load_robot()
    if cone is not None:
        m.opt.cone = cone
    bot = ServoBot(m, d)
    bot.place(0.0, 0.0, 0.0)
    t_sim0 = d.time
    t0 = time.perf_counter()
    for _ in range(cycles):
        bot.run_gait(gait)
    wall = time.perf_counter() - t0
    sim = d.time - t_sim0
    steps = sim / m.opt.timestep
    return steps / wall, sim / wall, 1000.0 * wall / cycles


def bench_raw_steps(steps: int) -> float:
    """Bare ``mj_step(m, d, nstep)`` while standing (contacts active), steps/s."""
    m, d = load_robot()
    ServoBot(m, d).place(0.0, 0.0, 0.0)
    d.ctrl[:] = np.zeros(m.nu)
    t0 = time.perf_counter()
    mujoco.mj_step(m, d, steps)
    return steps / (time.perf_counter() - t0)


def bench_calibration(spec: str, workers: int) -> tuple[float, float]:
    """(start-up s, wall s) of the 16 default calibration walks on executor ``spec``; the
    start-up is Ray's (started once per process, apart), a pool's spawn is in the wall."""
    ex = make_executor(spec, workers)
    t0 = time.perf_counter()
    if isinstance(ex, RayExecutor):
        ex.connect()
    t1 = time.perf_counter()
    measure_all(executor=ex, **DEFAULTS.measure_kwargs())
    return t1 - t0, time.perf_counter() - t1


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m calibration.bench")
    p.add_argument("--cycles", type=int, default=200, help="gait cycles to time (200)")
    p.add_argument(
        "--executors", nargs="+", default=["serial", "process", "ray"],
        help="executors of the full-calibration timing (serial process ray)",
    )  # fmt: skip
    p.add_argument("--workers", type=int, default=2, help="processes / Ray CPUs (2)")
    args = p.parse_args(argv)
    ps = PhysicsSettings()
    print(f"mujoco {mujoco.__version__}, {os.cpu_count()} cpus, load {os.getloadavg()[0]:.2f}")
    print(f"timestep {ps.timestep_s * 1000:.1f} ms, {ps.substeps} steps per 100 ms frame")
    sps, rtf, ms = bench_gait(args.cycles)
    print(
        f"gait 0, {args.cycles} cycles: {sps:,.0f} steps/s, {rtf:.0f}x real time, "
        f"{ms:.2f} ms wall per 1.6 s cycle"
    )
    for name, cone in (("pyramidal", mujoco.mjtCone.mjCONE_PYRAMIDAL),
                       ("elliptic (the scene's)", mujoco.mjtCone.mjCONE_ELLIPTIC)):  # fmt: skip
        ms_c = bench_gait(args.cycles, cone=int(cone))[2]
        print(f"gait 0, friction cone {name}: {ms_c:.2f} ms wall per cycle")
    print(f"bare mj_step while standing: {bench_raw_steps(50_000):,.0f} steps/s")
    for spec in args.executors:
        if spec.startswith("ray") and importlib.util.find_spec("ray") is None:
            print(f"full calibration, executor {spec}: skipped (Ray is not installed)")
            continue
        start, wall = bench_calibration(spec, args.workers)
        workers = "" if spec == "serial" else f", {args.workers} workers"
        extra = f" (+ {start:.1f} s to start Ray)" if spec.startswith("ray") else ""
        print(
            f"full calibration (16 gaits x (1 + 20) cycles), executor {spec}{workers}: "
            f"{wall:.1f} s wall{extra}"
        )
    print(f"load {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
