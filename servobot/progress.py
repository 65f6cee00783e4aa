"""Progress bars for long work, fed by the libraries' callbacks (the libraries never print)."""

from __future__ import annotations

import sys
from typing import Any

from tqdm import tqdm


class GenerationBars:
    """An ``on_generation`` callback: one tqdm bar per (stage, population), on stderr.

    A bar appears at the first generation it is told of (a resumed population starts part
    way), shows the best and mean fitness and the distinct genomes, and closes after the
    final generation.
    """

    def __init__(self, enabled: bool = True) -> None:
        self.enabled = enabled
        self._bars: dict[tuple[str, int], Any] = {}

    def __call__(self, rec: dict[str, Any]) -> None:
        key = (str(rec["stage"]), int(rec["population"]))
        bar = self._bars.get(key)
        if bar is None:
            bar = tqdm(
                total=int(rec["generations"]) + 1,
                initial=int(rec["generation"]),
                desc=f"{key[0]} pop {key[1]}",
                unit="gen",
                disable=not self.enabled,
                file=sys.stderr,
            )
            self._bars[key] = bar
        bar.update(1)
        if self.enabled:
            bar.set_postfix(
                best=f"{rec['best_fitness']:.3f}", mean=f"{rec['mean_fitness']:.3f}",
                uniq=rec["unique"],
            )  # fmt: skip
        if rec["generation"] >= rec["generations"]:
            bar.close()

    def close(self) -> None:
        """Close every bar still open (after an error or Ctrl-C)."""
        for bar in self._bars.values():
            bar.close()


class RunBar:
    """An ``on_run()`` callback: one tqdm bar counting finished runs, on stderr, opened at the
    first run (a command refused before any run prints no bar). ``total``: the runs expected,
    if known; ``advance(n)`` counts ``n`` runs at once (runs read back on resume)."""

    def __init__(self, desc: str, enabled: bool = True, total: int | None = None) -> None:
        self.desc, self.enabled, self.total = desc, enabled, total
        self._bar: Any = None

    def __call__(self, *_: Any) -> None:
        self.advance(1)

    def advance(self, n: int) -> None:
        """Count ``n`` finished runs."""
        if self._bar is None:
            self._bar = tqdm(desc=self.desc, unit="run", total=self.total,
                             disable=not self.enabled, file=sys.stderr)  # fmt: skip
        self._bar.update(n)

    def close(self) -> None:
        """Close the bar if it was opened."""
        if self._bar is not None:
            self._bar.close()


__all__ = ["GenerationBars", "RunBar"]
