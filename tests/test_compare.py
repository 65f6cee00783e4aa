"""``servobot compare``: gait tables side by side, the CSV of differences, bad input."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from calibration.compare import compare, compare_tables, default_labels
from evolve.table import PAPER_TABLE, table_to_json
from servobot.cli import main as servobot


def _write(path: Path, values: np.ndarray, dv: float | None = None) -> Path:
    energy = None
    if dv is not None:
        energy = np.column_stack([np.full(16, 9.0), np.full(16, 0.2), np.full(16, dv),
                                  np.full(16, 0.001)])  # fmt: skip
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(table_to_json(values, np.full((16, 3), 0.3), energy=energy)))
    return path


def test_differences_from_the_first_table(tmp_path: Path) -> None:
    turned = PAPER_TABLE.copy()
    turned[11, 2] -= 8.0  # a heavier robot: gait 11 turns 8° less
    a = _write(tmp_path / "shipped" / "gait_table.json", PAPER_TABLE, dv=0.027)
    b = _write(tmp_path / "heavy" / "gait_table.json", turned, dv=0.030)
    cmp = compare_tables([str(a), str(b), "paper"], tmp_path / "out")
    assert cmp.labels == ["shipped", "heavy", "paper"]
    assert cmp.diff[1, 11, 2] == pytest.approx(-8.0)
    assert np.count_nonzero(cmp.diff[1, :, :3]) == 1
    assert cmp.diff[1, 0, 3] == pytest.approx(0.003)
    assert np.isnan(cmp.values[2, :, 3]).all()  # the paper has no measured dV
    assert "dH -8.00 deg (gait 11)" in cmp.summary()
    rows = list(csv.reader((tmp_path / "out" / "compare.csv").open()))
    assert rows[0] == ["gait", "quantity", "unit", "shipped", "heavy", "paper",
                       "heavy - shipped", "paper - shipped"]  # fmt: skip
    row = next(r for r in rows if r[:2] == ["11", "dH"])
    assert float(row[6]) == pytest.approx(-8.0) and float(row[7]) == pytest.approx(0.0)
    assert next(r for r in rows if r[:2] == ["3", "dV"])[5] == ""  # blank, not 0
    assert len(rows) == 1 + 16 * 4
    assert (tmp_path / "out" / "compare.png").stat().st_size > 20_000


def test_labels_and_bad_input(tmp_path: Path, capsys) -> None:
    assert default_labels(["paper", "a/x/gait_table.json", "b/x/gait_table.json", "t.json"]) == [
        "paper", "x#1", "x#2", "t",
    ]  # fmt: skip
    with pytest.raises(ValueError, match="two or more"):
        compare(["paper"])
    assert servobot(["compare", "paper", str(tmp_path / "missing.json")]) == 2
    assert "missing.json" in capsys.readouterr().err


def test_cli_writes_png_and_csv(tmp_path: Path, capsys) -> None:
    a = _write(tmp_path / "a.json", PAPER_TABLE + 0.5)
    out = tmp_path / "cmp"
    assert servobot(["compare", "paper", str(a), "--out", str(out), "--labels", "P", "A"]) == 0
    printed = capsys.readouterr().out
    assert "A: " in printed and "F +0.50 cm" in printed
    assert (out / "compare.png").exists() and (out / "compare.csv").exists()
