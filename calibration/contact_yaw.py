"""How far a robot turns away from a robot it walks into, measured in MuJoCo
(``ColonySettings.contact_yaw_deg``, the table world's rule for it).

    python -m calibration.contact_yaw [--gaits 0,8,2,10]

Robot 0 stands at the arena's centre with a heading from ``HEADINGS``; robot 1 stands
``DISTANCE_CM`` away at bearing ±``BEARING_DEG`` from robot 0's heading (clockwise, so + is
front-right), its bumper just clear of robot 0's. Robot 0 walks one cycle of a gait into it.
The *extra yaw* is its heading change minus that of the same cycle walked free (robot 1 far
away, the same servo noise): the turn the contact adds. The table world's rule turns a blocked
robot by −Y · sin b (``geometry.contact_yaw``); the measured Y is the mean of −extra / sin b
over every gait, heading and side.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass

import numpy as np

from evolve import geometry
from evolve.settings import ColonySettings

HEADINGS = (0.0, 120.0, 250.0)
"""Robot 0's headings (deg): the gait cycle's servo noise and the contact differ with them."""
BEARING_DEG = 45.0
"""Where robot 1 stands, degrees off robot 0's heading (both sides)."""
DISTANCE_CM = 31.0
"""Centre distance of the two robots at the start, cm: the bumpers (15 cm) 1 cm apart."""
CENTRE = (250.0, 250.0)
"""Robot 0's start centre, arena units (cm): far from the walls and the station."""
FAR = [60.0, 60.0, 0.0]
"""Robot 1's pose when robot 0 walks free: 268 cm away."""


@dataclass(frozen=True)
class ContactTurn:
    """One measured cycle: robot 0 walks ``gait`` from ``heading`` into robot 1 at
    ``bearing`` (deg, clockwise from the heading)."""

    gait: int
    heading: float
    bearing: float
    turn_deg: float
    """Robot 0's heading change over the cycle, degrees (clockwise +)."""
    free_deg: float
    """The same cycle's heading change with robot 1 far away, degrees."""

    @property
    def extra_deg(self) -> float:
        """The turn the contact added, degrees."""
        return self.turn_deg - self.free_deg

    @property
    def abeam_deg(self) -> float:
        """The contact yaw Y this cycle implies: −extra / sin b."""
        return -self.extra_deg / math.sin(math.radians(self.bearing))


def _turn(starts: list[list[float]], gait: int) -> float:
    """Robot 0's heading change, degrees, over one cycle of ``gait`` in a fresh arena of two
    robots at ``starts`` (robots unseen, so no shell; the default servo noise)."""
    from servo_mj.world.physics_colony import PhysicsColony

    world = PhysicsColony(starts, colony_settings=ColonySettings(robots=2, robots_seen=False))
    before = world.pose(0)[2]
    world.step(0, gait)
    return float(geometry.wrap180(world.pose(0)[2] - before))


def measure(
    gaits: tuple[int, ...], headings: tuple[float, ...] = HEADINGS,
    bearing: float = BEARING_DEG, distance: float = DISTANCE_CM,
) -> list[ContactTurn]:  # fmt: skip
    """Every (gait, heading, ±bearing) cycle, and each (gait, heading) walked free."""
    x, y = CENTRE
    out = []
    for gait in gaits:
        for h in headings:
            free = _turn([[x, y, h], FAR], gait)
            for b in (bearing, -bearing):
                ox, oy, _ = geometry.move(x, y, h + b, distance, 0.0, 0.0)
                out.append(ContactTurn(gait, h, b, _turn([[x, y, h], [ox, oy, 0.0]], gait), free))
    return out


def summary_lines(turns: list[ContactTurn]) -> list[str]:
    """Per gait and side the mean extra yaw, then the implied Y (mean and spread)."""
    lines = ["gait | side | free turn | turn into the robot | extra (contact) | implied Y"]
    for gait in sorted({t.gait for t in turns}):
        for b in sorted({t.bearing for t in turns}, reverse=True):
            sel = [t for t in turns if t.gait == gait and t.bearing == b]
            side = "front-right" if b > 0 else "front-left"
            lines.append(
                f"{gait:4d} | {side} | {np.mean([t.free_deg for t in sel]):6.1f} | "
                f"{np.mean([t.turn_deg for t in sel]):6.1f} | "
                f"{np.mean([t.extra_deg for t in sel]):+6.1f} | "
                f"{np.mean([t.abeam_deg for t in sel]):6.1f}"
            )
    y = np.array([t.abeam_deg for t in turns])
    lines.append(f"contact yaw abeam Y = {y.mean():.1f}° (± {y.std(ddof=1) / math.sqrt(len(y)):.1f}"
                 f" s.e., {len(y)} cycles)")  # fmt: skip
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m calibration.contact_yaw",
                                 description=__doc__.splitlines()[0])  # fmt: skip
    ap.add_argument("--gaits", default="0,8,2,10", help="gaits walked (default 0,8,2,10)")
    args = ap.parse_args(argv)
    gaits = tuple(int(g) for g in args.gaits.split(","))
    if not all(0 <= g < 16 for g in gaits):
        print(f"python -m calibration.contact_yaw: --gaits must be in 0..15, got {args.gaits}")
        return 2
    print("\n".join(summary_lines(measure(gaits))))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
