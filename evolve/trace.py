"""One controller run on the table world, step by step: the library under ``servobot trace``.

``trace(bits, start, ...)`` runs a chromosome with the reference interpreter on the table
world and hands every ``StepEvent`` to ``on_event``; ``event_line``/``event_dict`` format an
event (pose after the event: x, y in arena units = cm, heading in degrees, 0 = north,
clockwise; power in volts; active sensors by name), ``summary_line`` the run's result. A
recorder (``servobot.recording``) is just another ``on_event`` consumer, passed in by the
application layer.
"""

from __future__ import annotations

from typing import Any

from evolve.codec import SENSOR_NAMES
from evolve.interpreter import END_NAMES, RunResult, StepEvent, run
from evolve.settings import WorldSettings
from evolve.world import TableWorld

DEFAULT_WORLD = WorldSettings()
"""The SPEC's world (frozen)."""
TEXT_HEADER = (
    "step  gene  kind    instruction                      gait      x      y      h  power"
    "  mode        sq  sensors"
)
"""Column header of the text form."""


def active_sensor_names(bits: int) -> list[str]:
    """Names of the sensors active in bitmask ``bits`` (``evolve.codec`` sensor bits)."""
    return [name for bit, name in SENSOR_NAMES if bits & bit]


def event_dict(e: StepEvent) -> dict[str, Any]:
    """One event as a JSON-able dict (pose after the event; gene/instruction/gait −1 = none)."""
    x, y, h = (float(v) for v in e.pose)
    return {
        "step": int(e.step),
        "kind": e.kind,
        "gene": int(e.gene),
        "instruction": int(e.instruction),
        "text": e.text,
        "gait": int(e.gait),
        "x": x,
        "y": y,
        "heading": h,
        "power": float(e.power),
        "mode": e.mode,
        "sensors": active_sensor_names(int(e.sensors)),
        "squares": int(e.squares),
        "new_square": int(e.new_square),
    }


def event_line(e: StepEvent) -> str:
    """One event as a fixed-width text line (columns of ``TEXT_HEADER``)."""
    x, y, h = e.pose
    where = f"{e.gene}.{e.instruction}" if e.gene >= 0 and e.instruction >= 0 else "-"
    gait = str(e.gait) if e.gait >= 0 else "-"
    names = ",".join(active_sensor_names(int(e.sensors))) or "-"
    new = f" +{e.new_square}" if e.new_square >= 0 else ""
    return (
        f"{e.step:4d}  {where:<5} {e.kind:<7} {e.text:<32} {gait:>4} {x:6.1f} {y:6.1f} "
        f"{h:6.1f} {e.power:6.3f}  {e.mode:<10} {e.squares:3d}  {names}{new}"
    )


def summary_line(res: RunResult) -> str:
    """The ``#`` summary line that ends the text form."""
    x, y, h = res.final_pose
    return (
        f"# end: {END_NAMES[res.end]}; {res.squares} squares ({res.inner_squares} inner), "
        f"{res.docks} docks, {res.steps} steps; final pose ({x:.1f}, {y:.1f}, {h:.1f})"
    )


def trace(
    bits: Any,
    start: tuple[float, float, float],
    *,
    mode: str,
    table: Any,
    world: WorldSettings = DEFAULT_WORLD,
    power: float | None = None,
    max_steps: int | None = None,
    on_event: Any = None,
) -> RunResult:
    """Run ``bits`` from ``start`` on the table world, calling ``on_event`` per event."""
    x, y, h = start
    tw = TableWorld(getattr(table, "values", table), x, y, h, world)
    return run(
        bits,
        tw,
        mode=mode,
        settings=world,
        start_power=power,
        max_steps=max_steps,
        on_event=on_event,
    )


__all__ = [
    "TEXT_HEADER",
    "active_sensor_names",
    "event_dict",
    "event_line",
    "summary_line",
    "trace",
]
