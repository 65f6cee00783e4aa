"""``python -m servobot.robustness.reach``: how far a test matrix's robots get from the station
— a run's distances worked by hand, a hand-made matrix folder read per world with the table
world once, navigation sections left out, the outputs, and bad inputs."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from servobot.robustness.reach import main, markdown, matrix_reach, track_reach

DOCK = (465.0, 250.0)


def test_a_runs_reach_by_hand():
    # distances 0, 100, 300 from the dock point; the 90th percentile interpolates
    # between 100 and 300 at 0.8: 260; the westmost x is 165
    track = np.array([[465.0, 250.0, 90.0], [465.0, 350.0, 0.0], [165.0, 250.0, 270.0]])
    mean, reach, west = track_reach(track, DOCK)
    assert mean == pytest.approx(400.0 / 3.0)
    assert reach == pytest.approx(260.0)
    assert west == 165.0


def _write_matrix(folder: Path) -> None:
    """Two worlds, coverage chromosome ``a`` and navigation section ``nav``; ``a``'s table
    runs the same in both worlds, its physics walks 100 units west of the dock point in
    ``shipped`` and 50 in ``slippery``."""
    per = [{"name": "a", "mode": "coverage"}, {"name": "nav", "mode": "navigation"}]
    doc = {"worlds": [{"name": w, "per_chromosome": per} for w in ("shipped", "slippery")]}
    (folder / "robustness.json").write_text(json.dumps(doc))
    (folder / "settings.json").write_text("{}")
    table = np.array([[465.0, 250.0, 270.0], [385.0, 250.0, 270.0]])
    for world, step in (("shipped", 100.0), ("slippery", 50.0)):
        cell = folder / "runs" / world / "a"
        cell.mkdir(parents=True)
        physics = np.array([[465.0, 250.0, 270.0], [465.0 - step, 250.0, 270.0]])
        # two runs; the second ends after its start pose (a run killed at once)
        np.savez(cell / "tracks.npz", table_0=table, physics_0=physics, table_1=table[:1],
                 physics_1=physics[:1])  # fmt: skip


def test_a_matrix_read_per_world(tmp_path):
    _write_matrix(tmp_path)
    doc = matrix_reach(tmp_path)
    assert [w["world"] for w in doc["worlds"]] == ["table", "shipped", "slippery"]
    table, shipped, slippery = doc["worlds"]
    assert [r["name"] for r in shipped["per_chromosome"]] == ["a"]  # the section left out
    # run 0: distances 0 and 100 (mean 50, 90th percentile 90, west 365); run 1: 0, 0, 465
    assert shipped["mean_distance"] == pytest.approx(25.0)
    assert shipped["reach"] == pytest.approx(45.0)
    assert shipped["west_x"] == pytest.approx(415.0)
    assert slippery["mean_distance"] == pytest.approx(12.5) and slippery["west_x"] == 440.0
    assert table["mean_distance"] == pytest.approx(20.0)  # 80 units west in run 0
    assert shipped["distances"] == [0.0, 0.0, 100.0]  # every pose, pooled and sorted
    text = markdown(doc)
    assert "| a | 20 / 36 / 425 | 25 / 45 / 415 | 12 / 22 / 440 |" in text


def test_main_writes_and_refuses(tmp_path, capsys):
    _write_matrix(tmp_path)
    out = tmp_path / "out"
    assert main([str(tmp_path), "--out", str(out)]) == 0
    assert {p.name for p in out.iterdir()} == {"reach.json", "reach.md", "reach.png"}
    assert "| **mean** |" in capsys.readouterr().out
    # a cell without tracks, a folder that is no matrix, a matrix of sections only
    (tmp_path / "runs" / "slippery" / "a" / "tracks.npz").unlink()
    assert main([str(tmp_path)]) == 2
    assert "slippery/a: no readable tracks.npz" in capsys.readouterr().err
    assert main([str(tmp_path / "nothing")]) == 2
    assert "not a finished `servobot robustness` folder" in capsys.readouterr().err
    doc = json.loads((tmp_path / "robustness.json").read_text())
    for w in doc["worlds"]:
        w["per_chromosome"] = w["per_chromosome"][1:]
    (tmp_path / "robustness.json").write_text(json.dumps(doc))
    assert main([str(tmp_path)]) == 2
    assert "no coverage chromosome" in capsys.readouterr().err
