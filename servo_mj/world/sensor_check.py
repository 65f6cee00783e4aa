"""Do the physics object sensors agree with the SPEC's geometric ones? (diagnostic)

``python -m servo_mj.world.sensor_check [N] [SEED]``: place the robot at N sampled poses
(uniform, then near a wall) and compare its rangefinder object sensors with
``evolve.geometry.object_sensors`` at its physical pose after settling.
``python -m servo_mj.world.sensor_check --runs CHROMOSOME N [SEED]``: the same along N
coverage runs (every ``StepEvent``). Prints JSON; asserts nothing. Light sensors use the
SPEC rule on the physical pose in both worlds, so they agree by construction.
"""

from __future__ import annotations

import json
import sys
from typing import Any

import numpy as np

from evolve import geometry
from evolve.codec import OBJECT_LEFT, OBJECT_RIGHT, read_chromosome
from evolve.interpreter import run
from evolve.settings import WorldSettings
from evolve.starts import coverage_starts
from servo_mj.robot.constants import CM_PER_M
from servo_mj.world.arena import ArenaSettings, overlaps_station
from servo_mj.world.physics_world import PhysicsWorld


def sample_poses(
    n: int,
    rng: np.random.Generator,
    world: WorldSettings,
    arena: ArenaSettings | None = None,
    *,
    band: float | None = None,
) -> np.ndarray:
    """(n, 3) poses outside the kill zone and clear of the station block: uniform over the
    arena, or (``band`` cm) with the centre within ``band`` of the kill-zone edge, i.e. near a
    wall, where the sensors change."""
    arena = arena or ArenaSettings()
    lo, hi = world.kill_margin, world.arena_size - world.kill_margin
    out = []
    while len(out) < n:
        x, y, h = rng.uniform(lo, hi), rng.uniform(lo, hi), rng.uniform(0.0, 360.0)
        if overlaps_station(x, y, world, arena):
            continue
        if band is None or min(x - lo, hi - x, y - lo, hi - y) <= band:
            out.append((x, y, h))
    return np.asarray(out)


def near_station(x: float, y: float, world: WorldSettings, arena: ArenaSettings) -> bool:
    """Whether the station block can be within object range while the wall behind it is not."""
    depth = arena.station_depth_m * CM_PER_M
    reach = world.object_range + depth
    return x > world.arena_size - reach and abs(y - world.station_y) < (
        world.station_width / 2 + world.object_range
    )


def sensor_agreement(
    poses: np.ndarray, *, world: WorldSettings | None = None, arena: ArenaSettings | None = None
) -> dict[str, Any]:
    """Place the robot at each pose and compare its physics object sensors with the SPEC's
    geometric sensors at its physical pose (after settling). Light sensors use the SPEC rule
    on the same pose in both worlds, so they agree by construction and are not counted."""
    world = world or WorldSettings()
    arena = arena or ArenaSettings()
    n = agree = 0
    n_far = agree_far = 0
    misses: list[dict[str, Any]] = []
    for x, y, h in np.asarray(poses, dtype=float):
        pw = PhysicsWorld(x, y, h, world=world, arena=arena)
        px, py, ph = pw.pose()
        got, want = pw.object_sensors(), geometry.object_sensors(px, py, ph, world)
        n += 1
        agree += got == want
        if not near_station(px, py, world, arena):
            n_far += 1
            agree_far += got == want
        if got != want:
            left, right = pw.ray_ranges_cm()
            hits = [r[r >= 0].min(initial=np.inf) for r in (left, right)]
            misses.append(
                {"pose": [px, py, ph], "physics": got, "geometry": want, "nearest_cm": hits}
            )
    return {
        "poses": n,
        "agree": agree / n if n else float("nan"),
        "poses_away_from_station": n_far,
        "agree_away_from_station": agree_far / n_far if n_far else float("nan"),
        "disagreements": misses,
    }


def run_agreement(
    bits: np.ndarray, starts: np.ndarray, *, world: WorldSettings | None = None
) -> dict[str, Any]:
    """Run ``bits`` (coverage mode) from each start in physics and compare the object sensors
    of every ``StepEvent`` with the geometric sensors at the event's physical pose."""
    world = world or WorldSettings()
    n = agree = 0
    misses: list[dict[str, Any]] = []
    for x, y, h in np.asarray(starts, dtype=float):
        events: list[Any] = []
        run(bits, PhysicsWorld(x, y, h, world=world), mode="coverage", settings=world,
            on_event=events.append)  # fmt: skip
        for e in events:
            got = (bool(e.sensors & OBJECT_LEFT), bool(e.sensors & OBJECT_RIGHT))
            want = geometry.object_sensors(*e.pose, world)
            n += 1
            agree += got == want
            if got != want:
                misses.append({"pose": list(e.pose), "physics": got, "geometry": want})
    return {"events": n, "agree": agree / n if n else float("nan"), "disagreements": misses}


def main(argv: list[str] | None = None) -> int:
    """``python -m servo_mj.world.physics_world [N] [SEED]``: sensor agreement on N sampled poses;
    ``python -m servo_mj.world.physics_world --runs CHROMOSOME N [SEED]``: along N coverage runs."""
    args = list(sys.argv[1:] if argv is None else argv)
    if args and args[0] == "--runs":
        world = WorldSettings()
        seed = int(args[3]) if len(args) > 3 else 0
        starts = coverage_starts(np.random.default_rng(seed), int(args[2]), world)
        res = run_agreement(read_chromosome(args[1]), starts, world=world)
        res["disagreements"] = res["disagreements"][:10]
        print(json.dumps(res, default=float, indent=1))
        return 0
    n = int(args[0]) if args else 200
    seed = int(args[1]) if len(args) > 1 else 0
    world = WorldSettings()
    rng = np.random.default_rng(seed)
    for name, band in (("uniform", None), ("near a wall (within 75 cm of the kill zone)", 75.0)):
        res = sensor_agreement(sample_poses(n, rng, world, band=band), world=world)
        res["disagreements"] = res["disagreements"][:10]
        print(name, json.dumps(res, default=float, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
