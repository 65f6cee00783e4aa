"""Size and time bounds: refuse settings whose memory or run time cannot be met, before
anything is allocated.

Each command estimates what its settings need (``Need``: bytes of memory at the peak, and
units of work such as robot steps) and calls ``check_need``; more than ``Limits`` allows raises
``BoundsError`` naming the options to lower. The speeds in ``Limits`` are deliberately
optimistic (several times what this project measures on 2 cores), so only runs that no
ordinary machine would finish are refused; a real run can be slower than its estimate.
``check_int`` / ``check_number`` are the range checks of single options.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from infra.errors import InputError


@dataclass(frozen=True)
class Limits:
    """What one run may plan to use [chosen: generous]."""

    memory_fraction: float = 0.5
    """Share of this machine's memory (physical, or the cgroup limit if lower) a run may use."""
    max_wall_s: float = 30 * 86400.0
    """Longest estimated run accepted, seconds (30 days at the optimistic speeds below)."""
    table_steps_per_s: float = 5e8
    """Optimistic table-simulation speed, robot steps/s (this project: 1.8–3.8e7 on 2 cores)."""
    physics_cycles_per_s: float = 1000.0
    """Optimistic physics speed per process, gait cycles/s (this project: ~67 per core)."""
    interpreter_steps_per_s: float = 1e6
    """Optimistic speed of the Python reference interpreter, steps/s."""
    physics_process_bytes: float = 3e8
    """Memory of one process running physics, bytes [estimate: a MuJoCo arena process peaks
    at ~140 MB here, plus recording buffers]."""


LIMITS = Limits()
"""The default limits (override with ``dataclasses.replace``)."""


class BoundsError(InputError, ValueError):
    """Settings out of range, or needing more memory or time than the machine can give."""


@dataclass(frozen=True)
class Need:
    """What a run needs: peak memory (bytes) and wall time (seconds, at optimistic speed)."""

    memory_bytes: float = 0.0
    wall_s: float = 0.0

    def __add__(self, other: Need) -> Need:
        return Need(
            max(self.memory_bytes, other.memory_bytes), self.wall_s + other.wall_s
        )  # stages run one after another: memory peaks, time adds


def machine_memory_bytes() -> int:
    """Physical memory, or the cgroup (container) memory limit if that is lower."""
    try:
        total = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        total = 16 * 2**30
    try:
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
        if limit.isdigit():
            total = min(total, int(limit))
    except OSError:
        pass
    return int(total)


def format_bytes(n: float) -> str:
    """``n`` bytes as a short human figure (``"3.2 GB"``)."""
    for unit in ("bytes", "kB", "MB", "GB", "TB", "PB"):
        if abs(n) < 1000 or unit == "PB":
            return f"{n:.0f} {unit}" if unit == "bytes" else f"{n:.1f} {unit}"
        n /= 1000
    raise AssertionError  # pragma: no cover


def format_duration(s: float) -> str:
    """``s`` seconds as a short human figure (``"4.2 days"``)."""
    if not math.isfinite(s):
        return "forever"
    for unit, size in (("years", 365 * 86400), ("days", 86400), ("hours", 3600), ("min", 60)):
        if s >= size:
            return f"{s / size:.3g} {unit}"
    return f"{s:.3g} s"


def check_need(need: Need, what: str, *, limits: Limits = LIMITS) -> None:
    """Refuse ``need`` if it exceeds the memory or time ``limits``; ``what`` names the run and
    the options that set its size (``"--populations × --population-size"``)."""
    budget = limits.memory_fraction * machine_memory_bytes()
    if not need.memory_bytes <= budget:
        raise BoundsError(
            f"{what} need about {format_bytes(need.memory_bytes)} of memory; this machine "
            f"allows {format_bytes(budget)} ({limits.memory_fraction:.0%} of its memory): "
            "choose smaller values"
        )
    if not need.wall_s <= limits.max_wall_s:
        raise BoundsError(
            f"{what} would run for at least {format_duration(need.wall_s)} even on a fast "
            f"machine (the limit is {format_duration(limits.max_wall_s)}): choose smaller values"
        )


def is_finite_number(value: Any) -> bool:
    """Whether a value read from JSON is a finite number: an int or float (not a bool) that a
    float holds (an int beyond a float's range, ±1e308, is not)."""
    if not isinstance(value, int | float) or isinstance(value, bool):
        return False
    try:
        return math.isfinite(float(value))
    except OverflowError:
        return False


def check_int(value: Any, option: str, *, lo: int, hi: int | None = None) -> int:
    """``value`` as an int in [lo, hi], else ``BoundsError`` naming ``option``."""
    ok = isinstance(value, int) and not isinstance(value, bool)
    if not ok or value < lo or (hi is not None and value > hi):
        span = f"≥ {lo}" if hi is None else f"between {lo} and {hi}"
        raise BoundsError(f"{option} must be an integer {span}, got {value!r}")
    return value


WORKERS_PER_CORE = 4
"""The most processes (or Ray CPUs) a command may ask for, per core of this machine."""


def check_workers(workers: int | None, option: str = "--workers") -> int | None:
    """``workers`` (None: one per core, passed through) as an int in [1, ``WORKERS_PER_CORE``
    × cores], else ``BoundsError`` naming ``option``."""
    if workers is not None:
        check_int(workers, option, lo=1, hi=WORKERS_PER_CORE * (os.cpu_count() or 1))
    return workers


def check_nonnegative(value: Any, option: str, unit: str) -> float:
    """``value`` as a finite float ≥ 0 (``is_finite_number``), else ``BoundsError`` naming
    ``option`` and its ``unit``."""
    if not (is_finite_number(value) and value >= 0):
        raise BoundsError(f"{option} must be a finite number ≥ 0 ({unit}), got {value!r}")
    return float(value)


def check_number(value: Any, option: str, *, lo: float, hi: float, unit: str = "") -> float:
    """``value`` as a finite float in [lo, hi], else ``BoundsError`` naming ``option``."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    if isinstance(value, bool) or not lo <= v <= hi:
        raise BoundsError(
            f"{option} must be a number between {lo:g} and {hi:g}{unit}, got {value!r}"
        )
    return v


__all__ = [
    "LIMITS",
    "BoundsError",
    "Limits",
    "check_nonnegative",
    "Need",
    "check_int",
    "check_need",
    "check_number",
    "format_bytes",
    "format_duration",
    "machine_memory_bytes",
]
