"""Speed of the ServoBot physics: steps per second, real-time factor, calibration wall time.

Prints rates, asserts nothing. Run: ``python -m calibration.bench [--cycles N]``.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import mujoco
import numpy as np

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


def bench_cli(workers: int) -> float:
    """Wall time of a full default ``python -m calibration`` (process start included), s."""
    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        subprocess.run(
            [sys.executable, "-m", "calibration", "--out", out, "--workers", str(workers)],
            check=True,
            stdout=subprocess.DEVNULL,
        )
        return time.perf_counter() - t0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m calibration.bench")
    p.add_argument("--cycles", type=int, default=200, help="gait cycles to time (200)")
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
    for w in (1, 2):
        print(
            f"full calibration (16 gaits x (1 + 20) cycles), --workers {w}: "
            f"{bench_cli(w):.1f} s wall"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
