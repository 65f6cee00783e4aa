"""``python -m servobot.robustness.transfer``: does behaviour in the table world predict the
reality gap? Held-out predictions by hand, and the command on a hand-made matrix."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from servobot.robustness.ranking import groups_of
from servobot.robustness.transfer import held_out_predictions
from servobot.robustness.transfer import main as transfer_main

GENE = "01 0100000 0100000 0100000 0100000\n"  # gait 4 forever


def test_groups_are_populations_when_every_name_says_so():
    assert groups_of(["p0g512r0", "p0g512r3", "p2g64best"]).tolist() == [0, 0, 2]


def test_each_group_is_predicted_from_the_others_only():
    desc = np.array([[0.0], [0.1], [1.0], [1.1], [5.0]])
    d = np.array([2.0, 4.0, 10.0, 20.0, 7.0])
    groups = np.array([0, 0, 1, 1, 2])
    knn, mean = held_out_predictions(desc, d, groups, 1)
    # group 0's nearest outside it is (1.0): 10; group 1's is (0.1): 4; group 2's is (1.1): 20
    assert knn.tolist() == [10.0, 10.0, 4.0, 4.0, 20.0]
    assert mean.tolist() == [37 / 3, 37 / 3, 13 / 3, 13 / 3, 9.0]
    with pytest.raises(ValueError, match="one group only"):
        held_out_predictions(desc, d, np.zeros(5, dtype=int), 1)


def _matrix(folder: Path, inner: dict[str, list[int]]) -> None:
    """A finished matrix in ``shipped``: these physics inner squares per start (what the
    command reads)."""
    poses = [[300.0, 200.0 + 40 * s, 90.0 * s] for s in range(len(next(iter(inner.values()))))]
    doc = {"starts": len(poses), "steps": 60, "seed": 0, "start_poses": {"coverage": poses},
           "worlds": [{"name": "shipped"}]}  # fmt: skip
    folder.mkdir(parents=True)
    (folder / "robustness.json").write_text(json.dumps(doc))
    rng = np.random.default_rng(1)
    controllers = []
    for name in inner:
        genes = "".join("".join(map(str, rng.integers(0, 2, 30))) + "\n" for _ in range(8))
        controllers.append({"name": name, "chromosome": genes + GENE * 8})
    (folder / "settings.json").write_text(json.dumps({"controllers": controllers}))
    for name, row in inner.items():
        cell = folder / "runs" / "shipped" / name
        cell.mkdir(parents=True)
        runs = [{"index": s, "physics": {"inner_squares": v}} for s, v in enumerate(row)]
        (cell / "report.json").write_text(json.dumps({"runs": runs}))


def test_the_check_on_a_hand_made_matrix(tmp_path, capsys):
    inner = {"p0g8r0": [3, 5], "p0g8r1": [0, 1], "p1g8r0": [7, 7], "p1g8r1": [2, 4]}
    _matrix(tmp_path / "m", inner)
    out = tmp_path / "out"
    argv = [str(tmp_path / "m"), "--neighbours", "1", "2", "--descriptor-starts", "2",
            "--out", str(out)]  # fmt: skip
    assert transfer_main(argv) == 0
    doc = json.loads((out / "transfer.json").read_text())
    shipped = doc["worlds"]["shipped"]
    assert (shipped["chromosomes"], shipped["groups"]) == (4, 2)
    assert [r["neighbours"] for r in shipped["by_neighbours"]] == [1, 2]
    two = shipped["by_neighbours"][1]  # k = 2: each population gets the other's mean
    assert two["mean_abs_error"] == pytest.approx(two["mean_abs_error_of_the_mean"])
    assert "| shipped | 4 (2) |" in (out / "transfer.md").read_text()
    assert transfer_main([str(tmp_path / "missing"), "--out", str(tmp_path / "o")]) == 2
    assert "not a finished `servobot robustness` folder" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        transfer_main([str(tmp_path / "m"), "--neighbours", "0"])
