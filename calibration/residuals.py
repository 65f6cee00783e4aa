"""Per-cycle residuals of a world against a gait table, along controller runs.

``LoggingWorld`` wraps any world (``evolve.world.World``: the table world or the physics
world) and logs every gait cycle the interpreter executes as (gait, pose before, pose after);
``residuals(log, table)`` turns that log into each cycle's move (F, T cm, dH deg, in the frame
the robot had when the cycle began: ``servo_mj.robot.bot.displacement``) minus the table row of
its gait. The diagnostic ``python -m calibration.gap`` prints them per gait; anytime learning
(``servobot.anytime.run``, method ``model``) corrects the gait table with them.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from servo_mj.robot.bot import displacement

Cycle = tuple[int, tuple[float, ...], tuple[float, ...]]
"""One logged cycle: (gait, pose before, pose after), poses (x cm, y cm, heading deg)."""


class LoggingWorld:
    """Wraps a world and records (gait, pose before, pose after) of every cycle."""

    def __init__(self, inner: Any) -> None:
        self.inner = inner
        self.log: list[Cycle] = []

    def pose(self) -> tuple[float, float, float]:
        return self.inner.pose()

    def step(self, gait: int) -> None:
        before = self.inner.pose()
        self.inner.step(gait)
        self.log.append((int(gait), before, self.inner.pose()))

    def object_sensors(self) -> tuple[bool, bool]:
        return self.inner.object_sensors()

    def light_sensors(self) -> tuple[bool, bool]:
        return self.inner.light_sensors()


def residuals(log: list[Cycle], table: np.ndarray) -> list[tuple[int, int, np.ndarray]]:
    """Per cycle (gait, previous gait or −1, move (F, T, dH) − table row)."""
    out, prev = [], -1
    for gait, before, after in log:
        out.append((gait, prev, np.array(displacement(before, after)) - table[gait]))
        prev = gait
    return out


__all__ = ["Cycle", "LoggingWorld", "residuals"]
