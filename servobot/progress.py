"""Progress of long work, fed by the libraries' callbacks (the libraries never print).

One policy, here: on a terminal, tqdm bars (redrawn in place); anywhere else (a log file, a
pipe, CI), plain lines a person can read — one when a stage starts, then at most one every
``LINE_INTERVAL_S`` (a minute) while it runs, and one when it ends; never a carriage return.
``progress_bar`` picks one of the two; ``GenerationBars`` and ``RunBar`` are the callbacks
the commands hand to the libraries.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import Any, TextIO

from tqdm import tqdm

LINE_INTERVAL_S = 60.0
"""Off a terminal: the least time between two progress lines of one stage, s."""

Clock = Callable[[], float]


def on_terminal(file: Any) -> bool:
    """Whether ``file`` is a terminal (where a bar can redraw itself)."""
    try:
        return bool(file.isatty())
    except (AttributeError, ValueError):  # no isatty, or closed
        return False


def _duration(s: float) -> str:
    s = max(0.0, s)
    if s < 60:
        return f"{s:.0f} s"
    m, s = divmod(int(round(s)), 60)
    return f"{m} min {s:02d} s" if m < 60 else f"{m // 60} h {m % 60:02d} min"


class LineProgress:
    """Progress as plain lines (off a terminal), with the parts of tqdm's interface the
    commands use: ``update``, ``set_postfix``, ``write``, ``close``, ``n``, ``total``.

    Prints a line when the stage starts, a line at most every ``interval_s`` of ``clock`` while
    it advances, and a line when it closes; each line ends in a newline.
    """

    def __init__(
        self, *, desc: str, unit: str = "it", total: int | None = None, initial: int = 0,
        file: TextIO | None = None, clock: Clock = time.monotonic,
        interval_s: float = LINE_INTERVAL_S,
    ) -> None:  # fmt: skip
        self.desc, self.unit, self.total = desc, unit, total
        self.n = int(initial)
        self.file = file if file is not None else sys.stderr
        self.clock, self.interval_s = clock, interval_s
        self.postfix = ""
        self.t0 = self.last = clock()
        self.closed = False
        self._line(f"started{self._count()}" if self.n or total else "started")

    def _count(self) -> str:
        if self.total:
            return f", {self.n}/{self.total} {self.unit} ({100.0 * self.n / self.total:.0f} %)"
        return f", {self.n} {self.unit}"

    def _line(self, text: str) -> None:
        post = f" [{self.postfix}]" if self.postfix else ""
        self.file.write(f"{self.desc}: {text}{post}\n")
        self.file.flush()

    def update(self, n: int = 1) -> None:
        """``n`` more done; prints a line if ``interval_s`` passed since the last one."""
        self.n += int(n)
        now = self.clock()
        if now - self.last >= self.interval_s:
            self.last = now
            self._line(f"{_duration(now - self.t0)}{self._count()}")

    def set_postfix(self, **values: Any) -> None:
        """Values shown on the next line (``best=0.41``)."""
        self.postfix = ", ".join(f"{k}={v}" for k, v in values.items())

    def write(self, text: str) -> None:
        """A line of its own (e.g. a failed run)."""
        self.file.write(text.rstrip("\n") + "\n")
        self.file.flush()

    def close(self) -> None:
        """The closing line (once)."""
        if self.closed:
            return
        self.closed = True
        self._line(f"done in {_duration(self.clock() - self.t0)}{self._count()}")


def progress_bar(
    *, desc: str, unit: str = "it", total: int | None = None, initial: int = 0,
    enabled: bool = True, file: TextIO | None = None, clock: Clock = time.monotonic,
) -> Any:  # fmt: skip
    """A progress display on ``file`` (default stderr): a tqdm bar on a terminal, a
    ``LineProgress`` elsewhere, a silent tqdm when not ``enabled``."""
    out = file if file is not None else sys.stderr
    if enabled and not on_terminal(out):
        return LineProgress(desc=desc, unit=unit, total=total, initial=initial, file=out,
                            clock=clock)  # fmt: skip
    return tqdm(total=total, initial=initial, desc=desc, unit=unit, disable=not enabled, file=out)


class GenerationBars:
    """An ``on_generation`` callback: one progress display per (stage, population).

    A display appears at the first generation it is told of (a resumed population starts
    part way), shows the best and mean fitness and the distinct genomes, and closes after
    the final generation.
    """

    def __init__(self, enabled: bool = True, *, file: TextIO | None = None,
                 clock: Clock = time.monotonic) -> None:  # fmt: skip
        self.enabled, self.file, self.clock = enabled, file, clock
        self._bars: dict[tuple[str, int], Any] = {}

    def __call__(self, rec: dict[str, Any]) -> None:
        key = (str(rec["stage"]), int(rec["population"]))
        bar = self._bars.get(key)
        if bar is None:
            bar = progress_bar(
                total=int(rec["generations"]) + 1, initial=int(rec["generation"]),
                desc=f"{key[0]} pop {key[1]}", unit="gen", enabled=self.enabled,
                file=self.file, clock=self.clock,
            )  # fmt: skip
            self._bars[key] = bar
        if self.enabled:
            bar.set_postfix(
                best=f"{rec['best_fitness']:.3f}", mean=f"{rec['mean_fitness']:.3f}",
                uniq=rec["unique"],
            )  # fmt: skip
        bar.update(1)
        if rec["generation"] >= rec["generations"]:
            bar.close()

    def close(self) -> None:
        """Close every display still open (after an error or Ctrl-C)."""
        for bar in self._bars.values():
            bar.close()


class RunBar:
    """An ``on_run()`` callback: one progress display counting finished runs, opened at the
    first run (a command refused before any run shows nothing). ``total``: the runs expected,
    if known."""

    def __init__(self, desc: str, enabled: bool = True, *, total: int | None = None,
                 unit: str = "run", file: TextIO | None = None,
                 clock: Clock = time.monotonic) -> None:  # fmt: skip
        self.desc, self.enabled, self.total, self.unit = desc, enabled, total, unit
        self.file, self.clock = file, clock
        self._bar: Any = None

    def __call__(self, *_: Any) -> None:
        self.advance(1)

    def advance(self, n: int) -> None:
        """Count ``n`` finished runs at once (e.g. runs read back on resume)."""
        self.bar.update(n)

    @property
    def bar(self) -> Any:
        """The display (opened on first use)."""
        if self._bar is None:
            self._bar = progress_bar(
                desc=self.desc, unit=self.unit, total=self.total, enabled=self.enabled,
                file=self.file, clock=self.clock,
            )  # fmt: skip
        return self._bar

    def write(self, text: str) -> None:
        """A line of its own, above a bar (e.g. a failed run)."""
        self.bar.write(text)

    def close(self) -> None:
        """Close the display if it was opened."""
        if self._bar is not None:
            self._bar.close()


__all__ = ["LINE_INTERVAL_S", "GenerationBars", "LineProgress", "RunBar", "on_terminal",
           "progress_bar"]  # fmt: skip
