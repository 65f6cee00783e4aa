"""Progress a person can read: off a terminal plain lines — one when a stage starts, at most
one a minute while it runs, one when it ends, never a carriage return; on a terminal, tqdm."""

from __future__ import annotations

import io

from tqdm import tqdm

from servobot.progress import (
    LINE_INTERVAL_S,
    GenerationBars,
    LineProgress,
    RunBar,
    on_terminal,
    progress_bar,
)


class FakeClock:
    """A clock that moves only when told (seconds)."""

    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def _generations(bars: GenerationBars, clock: FakeClock, stage: str, pop: int, n: int,
                 step_s: float) -> None:  # fmt: skip
    for g in range(n + 1):
        bars({"stage": stage, "population": pop, "generation": g, "generations": n,
              "best_fitness": 0.5 + g / 1000, "mean_fitness": 0.25, "unique": 30})  # fmt: skip
        clock.t += step_s


def test_off_a_terminal_lines_per_stage_and_at_most_one_a_minute() -> None:
    out, clock = io.StringIO(), FakeClock()
    bars = GenerationBars(file=out, clock=clock)
    # 300 generations, 1.5 s each: a stage of 7.5 minutes; then a 20 s stage.
    _generations(bars, clock, "navigation", 0, 300, 1.5)
    _generations(bars, clock, "coverage", 0, 10, 2.0)
    text = out.getvalue()
    assert "\r" not in text and text.endswith("\n")
    lines = text.splitlines()
    nav = [line for line in lines if line.startswith("navigation pop 0:")]
    cov = [line for line in lines if line.startswith("coverage pop 0:")]
    assert nav[0].startswith("navigation pop 0: started") and "done in" in nav[-1]
    minutes = 301 * 1.5 / 60
    assert len(nav) - 2 <= minutes  # between start and end: at most one line a minute
    assert len(nav) - 2 >= int(minutes) - 1  # and some while it runs
    assert len(cov) == 2  # a 22 s stage: its start and its end
    assert "301/301 gen (100 %)" in nav[-1] and "best=0.800" in nav[-1]


def test_off_a_terminal_each_line_a_minute_apart() -> None:
    out, clock = io.StringIO(), FakeClock()
    runs = RunBar("validate", total=1000, unit="start", file=out, clock=clock)
    stamps = []
    for _ in range(1000):
        clock.t += 0.7
        before = out.getvalue().count("\n")
        runs()
        if out.getvalue().count("\n") > before:
            stamps.append(clock.t)
    runs.write("run 5: PhysicsError: boom")
    runs.close()
    text = out.getvalue()
    assert "\r" not in text
    assert all(b - a >= LINE_INTERVAL_S for a, b in zip(stamps[1:], stamps[2:], strict=False))
    assert text.splitlines()[-2] == "run 5: PhysicsError: boom"
    last = text.splitlines()[-1]  # the bar opened at the first run, 0.7 s in
    assert last.startswith("validate: done in 11 min 39 s, 1000/1000 start")


def test_nothing_before_the_first_run_and_nothing_when_disabled() -> None:
    out = io.StringIO()
    RunBar("validate", file=out).close()  # refused before any run: no line at all
    quiet = RunBar("validate", enabled=False, file=out)
    quiet()
    quiet.close()
    GenerationBars(enabled=False, file=out)(
        {"stage": "s", "population": 0, "generation": 0, "generations": 1,
         "best_fitness": 0.0, "mean_fitness": 0.0, "unique": 1}
    )  # fmt: skip
    assert out.getvalue() == ""


def test_on_a_terminal_tqdm_bars() -> None:
    term = Terminal()
    assert on_terminal(term) and not on_terminal(io.StringIO())
    bar = progress_bar(desc="validate", unit="start", total=3, file=term)
    assert isinstance(bar, tqdm)
    bar.update(3)
    bar.close()
    assert "\r" in term.getvalue()  # redrawn in place, as before
    assert isinstance(progress_bar(desc="x", file=io.StringIO()), LineProgress)
