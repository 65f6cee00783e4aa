"""``python -m servobot.robustness.matrix_choice``: the finalist chosen by physics across the
test matrix's worlds — the rule on hand-made matrices, the held-out world kept out of it, a
choice confirmed end to end on a tiny matrix (2 chromosomes × shipped and weak, 1 start, 20
steps) from fresh starts, a finished confirmation read back, and bad inputs."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from chromosome_text import LIGHT_FOLLOWER

from evolve.settings import WorldSettings
from evolve.starts import coverage_starts
from infra.errors import InputError
from servobot.cli import main as servobot
from servobot.robustness.matrix_choice import (
    ChoiceRule,
    against_goals,
    choose,
    choosing_worlds,
    finalist_rows,
    score,
)
from servobot.robustness.matrix_choice import main as choice_main

GENES = {"a": "01 0100000 0100000 0100000 0100000\n",   # straight ahead
         "b": "01 0000011 0000011 0000011 0000011\n"}  # fmt: skip


def hand_matrix(
    physics: dict[str, list[float | None]], table=(40.0, 45.0), docks: dict | None = None
) -> dict:
    """A ``robustness.json`` document of two coverage chromosomes a, b and a navigation
    section, with the given physics inner % per world (and the section's dock rate per world,
    ``docks``, else 0.5)."""
    names = ["a", "b"]
    docks = docks or dict.fromkeys(physics, 0.5)

    def per(w: str) -> list[dict]:
        return [*({"physics_inner_percent": v, "dock_rate": 1.0, "ends": {}} for v in physics[w]),
                {"physics_inner_percent": None, "dock_rate": docks[w], "ends": {}}]  # fmt: skip

    return {
        "worlds": [{"name": w, "per_chromosome": per(w)} for w in physics],
        "table_per_chromosome": [
            *({"name": n, "file": f"{n}.txt", "mode": "coverage", "table_inner_percent": t}
              for n, t in zip(names, table, strict=True)),
            {"name": "nav", "file": "nav.txt", "mode": "navigation", "table_inner_percent": None,
             "dock_rate": 0.9},
        ],
        "starts": 10, "seed": 0,
    }  # fmt: skip


def test_the_worst_world_and_the_mean_choose_differently():
    # a: steady 52 everywhere; b: 70 in shipped, 45 when heavy — mean 57.5 against 52
    doc = hand_matrix({"shipped": [52.0, 70.0], "heavy": [52.0, 45.0]})
    rows = finalist_rows(doc)
    assert [r["name"] for r in rows] == ["a", "b"] and [r["index"] for r in rows] == [0, 1]
    worlds = choosing_worlds(doc, ChoiceRule())
    assert worlds == ["shipped", "heavy"]
    assert score(rows[1]["physics"], worlds) == {"worst": 45.0, "mean": 57.5}
    assert choose(rows, worlds, ChoiceRule("worst")) == 0
    assert choose(rows, worlds, ChoiceRule("mean")) == 1
    # a tie on the worst world goes to the mean
    tie = finalist_rows(hand_matrix({"shipped": [50.0, 60.0], "heavy": [50.0, 50.0]}))
    assert choose(tie, ["shipped", "heavy"]) == 1
    # a world without a finished run scores 0 there
    gap = finalist_rows(hand_matrix({"shipped": [52.0, 70.0], "heavy": [None, 45.0]}))
    assert choose(gap, ["shipped", "heavy"]) == 1


def test_the_held_out_world_never_chooses():
    # b is best only in the held-out world; the choice must not see it
    doc = hand_matrix({"shipped": [55.0, 54.0], "long-legs": [20.0, 90.0]})
    worlds = choosing_worlds(doc, ChoiceRule())
    assert worlds == ["shipped"]
    assert choose(finalist_rows(doc), worlds) == 0
    with pytest.raises(InputError, match="held out"):
        ChoiceRule(worlds=("shipped", "long-legs"))
    assert choosing_worlds(doc, ChoiceRule(worlds=("shipped",))) == ["shipped"]
    with pytest.raises(InputError, match="'heavy' is not a world of the matrix"):
        choosing_worlds(doc, ChoiceRule(worlds=("heavy",)))
    with pytest.raises(InputError, match="no world left"):
        choosing_worlds(hand_matrix({"long-legs": [1.0, 2.0]}), ChoiceRule())


def test_the_goals_worked_by_hand():
    g = against_goals({"shipped": 60.0, "heavy": 48.0, "weak": 57.0, "slippery": None})
    assert g == {"worst_world": "heavy", "worst_percent": 48.0, "every_world_at_goal": False,
                 "largest_drop_vs_shipped_pp": 12.0}  # fmt: skip
    g = against_goals({"shipped": 50.0, "station-seen": 53.0})
    assert g["every_world_at_goal"] and g["largest_drop_vs_shipped_pp"] == 0.0
    assert against_goals({"heavy": 51.0})["largest_drop_vs_shipped_pp"] is None


def test_navigation_sections_are_chosen_by_their_docking():
    doc = hand_matrix({"shipped": [52.0, 70.0], "heavy": [52.0, 45.0]},
                      docks={"shipped": 0.85, "heavy": None})  # fmt: skip
    rows = finalist_rows(doc, "navigation")
    assert [(r["name"], r["index"], r["table"]) for r in rows] == [("nav", 2, 90.0)]
    assert rows[0]["physics"] == {"shipped": 85.0, "heavy": None}
    # docking has no per-world goal; its worst world and drop below shipped still count
    g = against_goals({"shipped": 85.0, "heavy": 60.0}, goal=None)
    assert g == {"worst_world": "heavy", "worst_percent": 60.0, "every_world_at_goal": None,
                 "largest_drop_vs_shipped_pp": 25.0}  # fmt: skip
    with pytest.raises(InputError, match="--sections must be one of"):
        ChoiceRule(sections="colony")


def test_a_matrix_without_the_kind_chosen_is_refused():
    doc = hand_matrix({"shipped": [1.0, 2.0]})
    covers, nav = doc["table_per_chromosome"][:2], doc["table_per_chromosome"][2:]
    doc["table_per_chromosome"] = nav
    with pytest.raises(InputError, match="no coverage chromosome"):
        finalist_rows(doc)
    doc["table_per_chromosome"] = covers
    with pytest.raises(InputError, match="no navigation section"):
        finalist_rows(doc, "navigation")


@pytest.fixture(scope="module")
def tiny(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A finished tiny matrix: chromosomes a and b (16 genes) and a navigation section."""
    d = tmp_path_factory.mktemp("matrix_choice")
    files = []
    for name, gene in GENES.items():
        (d / f"{name}.txt").write_text(gene * 16)
        files.append(d / f"{name}.txt")
    (d / "nav.txt").write_text(LIGHT_FOLLOWER)
    argv = ["robustness", *map(str, files), str(d / "nav.txt"), "--worlds", "shipped,weak",
            "--starts", "1", "--steps", "20", "--workers", "1", "--no-progress",
            "--out", str(d / "m")]  # fmt: skip
    assert servobot(argv) == 0
    return d / "m"


def test_a_choice_confirmed_from_fresh_starts_end_to_end(tiny, tmp_path, capsys):
    out = tmp_path / "choice"
    assert choice_main([str(tiny), "--confirm", "1", "--workers", "1", "--out", str(out)]) == 0
    doc = json.loads((out / "choice.json").read_text())
    matrix = json.loads((tiny / "robustness.json").read_text())
    rows = finalist_rows(matrix)
    assert [r["name"] for r in doc["finalists"]] == ["a", "b"]
    assert doc["chosen"] == rows[choose(rows, ["shipped", "weak"])]["name"]
    c = doc["confirmation"]
    assert c["seed"] == 1000 and c["starts"] == 1 and set(c["physics"]) == {"shipped", "weak"}
    again = json.loads((out / "confirm" / "robustness.json").read_text())
    fresh = coverage_starts(np.random.default_rng(1000), 1, WorldSettings())
    np.testing.assert_allclose(again["start_poses"]["coverage"], fresh)
    assert again["steps"] == 20 and [w["name"] for w in again["worlds"]] == ["shipped", "weak"]
    assert again["worlds"][1]["model_sha256"] == matrix["worlds"][1]["model_sha256"]
    # the confirmation ran the matrix's own chromosome, written from its record
    record = json.loads((tiny / "settings.json").read_text())
    text = next(k["chromosome"] for k in record["controllers"] if k["name"] == doc["chosen"])
    assert (out / f"{doc['chosen']}.txt").read_text().split() == text.split()
    md = capsys.readouterr().out
    assert md == (out / "choice.md").read_text() and "1 fresh starts" in md
    assert (out / "choice.png").read_bytes()[:4] == b"\x89PNG"
    # a finished confirmation is read back, not run again
    report = out / "confirm" / "runs" / "shipped" / doc["chosen"] / "report.json"
    before = report.stat().st_mtime_ns
    assert choice_main([str(tiny), "--confirm", "1", "--workers", "1", "--out", str(out)]) == 0
    assert report.stat().st_mtime_ns == before
    assert json.loads((out / "choice.json").read_text()) == doc


def test_a_navigation_section_chosen_and_confirmed_end_to_end(tiny, tmp_path, capsys):
    out = tmp_path / "navchoice"
    argv = [str(tiny), "--sections", "navigation", "--confirm", "1", "--workers", "1",
            "--out", str(out)]  # fmt: skip
    assert choice_main(argv) == 0
    doc = json.loads((out / "choice.json").read_text())
    matrix = json.loads((tiny / "robustness.json").read_text())
    assert [r["name"] for r in doc["finalists"]] == ["nav"] and doc["chosen"] == "nav"
    assert doc["finalists"][0]["physics"] == {
        w["name"]: 100.0 * w["per_chromosome"][2]["dock_rate"] for w in matrix["worlds"]
    }  # fmt: skip
    again = json.loads((out / "confirm" / "robustness.json").read_text())
    assert set(again["start_poses"]) == {"navigation"}
    assert doc["confirmation"]["physics"] == {
        w["name"]: 100.0 * w["per_chromosome"][0]["dock_rate"] for w in again["worlds"]
    }  # fmt: skip
    assert doc["confirmation"]["goals"]["every_world_at_goal"] is None
    md = capsys.readouterr().out
    assert "navigation section whose worst physics docking" in md and "goal" not in md
    assert (out / "nav.txt").read_text().split() == (tiny.parent / "nav.txt").read_text().split()


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--confirm", "-1"], "--confirm"),
        (["--worlds", "long-legs"], "held out"),
        (["--worlds", "slippery"], "'slippery' is not a world of the matrix"),
    ],
)
def test_bad_input_exits_2_naming_it(tiny, tmp_path, capsys, extra, message):
    assert choice_main([str(tiny), *extra, "--out", str(tmp_path / "c")]) == 2
    assert message in capsys.readouterr().err


def test_a_folder_that_is_not_a_matrix_exits_2(tmp_path, capsys):
    assert choice_main([str(tmp_path), "--out", str(tmp_path / "c")]) == 2
    assert "not a finished `servobot robustness` folder" in capsys.readouterr().err


def test_a_world_whose_model_changed_is_refused_before_any_run(tiny, tmp_path, capsys):
    copy = tmp_path / "m"
    copy.mkdir()
    doc = json.loads((tiny / "robustness.json").read_text())
    doc["worlds"][1]["model_sha256"] = "0" * 64
    (copy / "robustness.json").write_text(json.dumps(doc))
    (copy / "settings.json").write_text((tiny / "settings.json").read_text())
    assert choice_main([str(copy), "--confirm", "1", "--out", str(tmp_path / "c")]) == 2
    assert "world 'weak': its robot model changed" in capsys.readouterr().err
    assert not (tmp_path / "c" / "confirm").exists()
