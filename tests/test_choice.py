"""``python -m servobot.robustness.choice``: a population's finalist chosen by physics on half
the starts, scored on the other half. Hand-worked choices, and the command on a hand-made
matrix."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from servobot.robustness.choice import held_out_choice
from servobot.robustness.choice import main as choice_main


def test_a_choice_made_on_one_half_is_scored_on_the_other():
    # g0 shines on the even starts only, g1 on the odd ones, g2 is steady; the table likes g2
    physics = {"w": np.array([[10, 0, 10, 0], [0, 8, 0, 8], [5, 5, 5, 5]], dtype=float)}
    table = np.array([[1.0] * 4, [2.0] * 4, [3.0] * 4])
    got = held_out_choice(physics, table, [[0, 1, 2]], 3, ["w"])
    # even half: physics picks g0 (10), held out 0; odd half: it picks g1 (8), held out 0
    assert got["physics"]["w"] == 0.0
    assert got["table"]["w"] == 5.0  # g2 both times
    assert got["ga"]["w"] == 5.0  # g0 both times: 0 then 10
    assert got["candidates"]["w"] == pytest.approx((13 / 3 + 5) / 2)
    one = held_out_choice(physics, table, [[0, 1, 2]], 1, ["w"])
    assert {c: v["w"] for c, v in one.items()} == dict.fromkeys(one, 5.0)  # only g0 to choose


def test_populations_choose_apart_and_are_averaged():
    physics = {"a": np.array([[0, 0], [4, 4], [8, 8], [2, 2]], dtype=float)}
    physics["b"] = physics["a"][::-1].copy()
    table = np.zeros((4, 2))
    got = held_out_choice(physics, table, [[0, 1], [2, 3]], 2, ["a"])
    # b's rows are a's reversed: g0 2, g1 8, g2 4, g3 0
    assert got["physics"] == {"a": (4 + 8) / 2, "b": (8 + 4) / 2}  # g1 and g2, chosen on a
    assert got["ga"] == {"a": (0 + 8) / 2, "b": (2 + 4) / 2}  # g0 and g2


def _matrix(folder: Path, cells: dict[str, dict[str, list[tuple[int, str, int]]]]) -> None:
    """A finished matrix: per world, per chromosome, (physics inner squares, physics end,
    docks) per start; the table side 32 squares, step limit and 5 docks everywhere."""
    worlds = list(cells)
    starts = len(next(iter(cells[worlds[0]].values())))
    doc = {"starts": starts, "steps": 60, "seed": 0, "worlds": [{"name": w} for w in worlds]}
    folder.mkdir(parents=True)
    (folder / "robustness.json").write_text(json.dumps(doc))
    (folder / "settings.json").write_text(json.dumps({"controllers": []}))
    table = {"inner_squares": 32, "end": {"name": "step limit"}, "docks": 5}
    for w, by_name in cells.items():
        for name, row in by_name.items():
            runs = [{"index": s, "table": table,
                     "physics": {"inner_squares": v, "end": {"name": e}, "docks": d}}
                    for s, (v, e, d) in enumerate(row)]  # fmt: skip
            cell = folder / "runs" / w / name
            cell.mkdir(parents=True)
            (cell / "report.json").write_text(json.dumps({"runs": runs}))


def test_the_command_on_a_hand_made_matrix(tmp_path, capsys):
    ok, empty = (32, "step limit", 4), (16, "power empty", 1)
    cells = {"shipped": {"p0g8r0": [ok, empty], "p0g8r1": [ok, ok], "p1g8r0": [empty, empty]},
             "station-seen": {"p0g8r0": [ok, ok], "p0g8r1": [empty, ok],
                              "p1g8r0": [ok, ok]}}  # fmt: skip
    _matrix(tmp_path / "m", cells)
    out = tmp_path / "out"
    assert choice_main([str(tmp_path / "m"), "--candidates", "1", "2", "--out", str(out)]) == 0
    doc = json.loads((out / "choice.json").read_text())
    assert (doc["genomes"], doc["populations"], doc["starts"]) == (3, 2, 2)
    ga = doc["by_candidates"]["1"]["ga"]
    # rank 0 of each population, held out: p0 (50, 25 in shipped), p1 25; averaged
    assert ga["shipped"] == pytest.approx(((50 + 25) / 2 + 25) / 2)
    assert doc["ends"]["shipped"]["physics"] == {"step limit": 3, "power empty": 3}
    assert doc["ends"]["shipped"]["table"] == {"step limit": 6}
    assert doc["ends"]["station-seen"]["docks_per_run"] == {"physics": 3.5, "table": 5.0}
    assert "| shipped | 6 | power empty 3, step limit 3 | step limit 6 |" in (
        out / "choice.md"
    ).read_text()
    bad = [str(tmp_path / "m"), "--selection-worlds", "heavy", "--out", str(tmp_path / "o")]
    assert choice_main(bad) == 2
    assert "no world heavy (it has shipped, station-seen)" in capsys.readouterr().err
    assert choice_main([str(tmp_path / "missing"), "--out", str(tmp_path / "o")]) == 2
    with pytest.raises(SystemExit):
        choice_main([str(tmp_path / "m"), "--candidates", "0"])


def test_a_matrix_without_ranked_names_is_refused(tmp_path, capsys):
    row = [(32, "step limit", 4)] * 2
    _matrix(tmp_path / "m", {"shipped": {"best_pop0": row}, "station-seen": {"best_pop0": row}})
    assert choice_main([str(tmp_path / "m"), "--out", str(tmp_path / "o")]) == 2
    assert "no chromosome named p{k}g{generation}r{rank}" in capsys.readouterr().err
