"""Column buffers: rows gathered in Python lists, sent to rerun as columns (``send_columns``).

Timelines: ``sim_time`` (duration, seconds of simulated time) and the sequences ``step``
(interpreter gait steps), ``colony_step`` (colony steps, SPEC §7) and ``cycle`` (gait cycles
of a calibration walk). Every row of one
buffer carries the same timelines; a buffer refuses a row with another set.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import rerun as rr

DURATION_TIMELINES = frozenset({"sim_time"})
"""Timelines in seconds; every other timeline is a sequence."""

Times = Mapping[str, float | int]


def times_of(t_s: float | None = None, **sequences: int | None) -> dict[str, float | int]:
    """The time point of one row: ``sim_time`` (when ``t_s`` is given) and the sequences given."""
    out: dict[str, float | int] = {k: int(v) for k, v in sequences.items() if v is not None}
    if t_s is not None:
        out["sim_time"] = float(t_s)
    return out


class ColumnBuffer:
    """Rows of one entity (or one group of entities sharing times): times plus named payloads."""

    def __init__(self, what: str = "rows") -> None:
        self.what = what
        self.times: dict[str, list[float | int]] = {}
        self.rows: dict[str, list[Any]] = {}
        self.n = 0

    def add(self, times: Times, **payload: Any) -> None:
        """Append one row; raises ``ValueError`` if its timelines differ from the first row's."""
        if not self.n:
            self.times = {k: [] for k in times}
            self.rows = {k: [] for k in payload}
        elif self.times.keys() != times.keys():
            raise ValueError(
                f"{self.what}: every row needs the same timelines; got {sorted(times)} "
                f"after {sorted(self.times)} (give t_s for every row or for none)"
            )
        for k, v in times.items():
            self.times[k].append(v)
        for k, v in payload.items():
            self.rows[k].append(v)
        self.n += 1

    def timelines(self) -> set[str]:
        return set(self.times)

    def time_columns(self, mask: np.ndarray | None = None) -> list[rr.TimeColumn]:
        """The rows' time columns (only the rows where ``mask`` is true, when given)."""
        cols = []
        for name, vals in self.times.items():
            arr = np.asarray(vals, dtype=np.float64 if name in DURATION_TIMELINES else np.int64)
            if mask is not None:
                arr = arr[mask]
            if name in DURATION_TIMELINES:
                cols.append(rr.TimeColumn(name, duration=arr))
            else:
                cols.append(rr.TimeColumn(name, sequence=arr))
        return cols

    def array(self, key: str, dtype: Any = np.float64) -> np.ndarray:
        """One payload as an array, rows stacked along axis 0."""
        return np.asarray(self.rows[key], dtype=dtype)

    def clear(self) -> None:
        """Forget the rows (after they were sent); the timelines may change afterwards."""
        self.times, self.rows, self.n = {}, {}, 0


def scalars(
    rec: rr.RecordingStream, path: str, index: list[rr.TimeColumn], values: np.ndarray
) -> None:
    """Send one scalar (n,) or several (n, k) per row to ``path``."""
    vals = np.asarray(values, dtype=np.float64)
    rec.send_columns(path, indexes=index, columns=rr.Scalars.columns(scalars=vals))


__all__ = ["ColumnBuffer", "DURATION_TIMELINES", "scalars", "times_of"]
