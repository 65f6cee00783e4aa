"""``python -m servobot.robustness.ends``: a test matrix's physics coverage runs split by how they
end — hand-made matrix folders pooled, worked by hand, navigation sections and failed runs left
out, the name filter, the outputs, and bad inputs."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from servobot.robustness.ends import main, markdown, matrix_ends, split_by_end


def _run(end: str, inner: int, docks: int = 7, steps: int = 600) -> dict:
    physics = {"end": {"name": end}, "inner_squares": inner, "docks": docks, "steps": steps}
    return {"physics": physics, "error": None}


def _write_matrix(folder: Path, cells: dict[str, dict[str, list[dict]]]) -> None:
    """A finished matrix folder: per world, per chromosome its runs; ``nav`` is a section."""
    names = sorted({n for per in cells.values() for n in per})
    per = [{"name": n, "mode": "navigation" if n == "nav" else "coverage"} for n in names]
    doc = {"worlds": [{"name": w, "per_chromosome": per} for w in cells]}
    folder.mkdir(parents=True)
    (folder / "robustness.json").write_text(json.dumps(doc))
    (folder / "settings.json").write_text("{}")
    for world, by_name in cells.items():
        for name, runs in by_name.items():
            cell = folder / "runs" / world / name
            cell.mkdir(parents=True)
            report = {"summary": {"inner_squares_total": 64}, "runs": runs}
            (cell / "report.json").write_text(json.dumps(report))


def test_a_worlds_runs_split_by_hand():
    # 32 and 48 of 64 inner squares to the step limit (62.5 % mean), 16 with the store empty at
    # step 300 and 0 in the kill zone at step 100: 37.5 % over all four, the early ends cost 25 pp
    runs = [{"end": "step limit", "inner": 50.0, "docks": 7, "steps": 600},
            {"end": "step limit", "inner": 75.0, "docks": 8, "steps": 600},
            {"end": "power empty", "inner": 25.0, "docks": 3, "steps": 300},
            {"end": "kill zone", "inner": 0.0, "docks": 1, "steps": 100}]  # fmt: skip
    s = split_by_end(runs)
    assert s["runs"] == 4 and s["inner"] == pytest.approx(37.5)
    assert s["step_limit"] == {"runs": 2, "inner": pytest.approx(62.5), "docks": pytest.approx(7.5)}
    assert s["early"]["runs"] == 2 and s["early"]["inner"] == pytest.approx(12.5)
    assert s["early"]["steps"] == pytest.approx(200.0) and s["early"]["docks"] == pytest.approx(2.0)
    assert s["early"]["by_end"] == {"kill zone": 1, "power empty": 1}
    assert s["early_cost"] == pytest.approx(25.0)
    # no run lasted: no cost to name
    assert split_by_end(runs[2:])["early_cost"] is None


def _ho(outcome: str) -> dict:
    return {"pose": [400.0, 250.0, 90.0], "power": 3.9, "step": 0, "outcome": outcome}


def test_a_worlds_hand_offs_pooled_by_hand():
    # run 1 lasted: 3 docked, its last approach cut; run 2's store emptied on its second
    # approach; run 3 ended in the kill zone while covering, after one docked approach; run 4
    # (an older record) has none: 4 + 0 + 1 docked, 1 failed -> 5 of 6, one early end in approach
    runs = [{"end": "step limit", "inner": 60.0, "docks": 3, "steps": 600,
             "handoffs": [_ho("docked"), _ho("docked"), _ho("docked"), _ho("cut")]},
            {"end": "power empty", "inner": 30.0, "docks": 1, "steps": 300,
             "handoffs": [_ho("docked"), _ho("power empty")]},
            {"end": "kill zone", "inner": 20.0, "docks": 1, "steps": 200,
             "handoffs": [_ho("docked")]},
            {"end": "step limit", "inner": 50.0, "docks": 7, "steps": 600}]  # fmt: skip
    a = split_by_end(runs)["handoffs"]
    assert a == {"runs": 3, "handoffs": 7, "docked": 5, "failed": 1, "cut": 1,
                 "dock_rate": pytest.approx(5 / 6), "early_in_approach": 1}  # fmt: skip
    world = {"world": "w", **split_by_end(runs), "drop": None}
    doc = {"matrices": ["m"], "only": "", "worlds": [world]}
    assert "| 5 of 6, 83.3 % (3 runs recorded them) | 1 |" in markdown(doc)
    assert split_by_end(runs[3:])["handoffs"] is None  # no record: no figure


def test_matrices_pool_per_world(tmp_path):
    a, b = tmp_path / "seed1", tmp_path / "seed2"
    failed = {"physics": None, "error": "unstable"}
    _write_matrix(a, {"shipped": {"x": [_run("step limit", 40)], "nav": [_run("docked", 0)]},
                      "slippery": {"x": [_run("power empty", 8, steps=250), failed]}})  # fmt: skip
    _write_matrix(b, {"shipped": {"x": [_run("step limit", 24)], "y": [_run("step limit", 64)]},
                      "slippery": {"x": [_run("step limit", 32)],
                                   "y": [_run("step limit", 48)]}})  # fmt: skip
    doc = matrix_ends([a, b])
    shipped, slippery = doc["worlds"]
    assert shipped["world"] == "shipped" and shipped["runs"] == 3  # the section left out
    assert shipped["inner"] == pytest.approx(100 * (40 + 24 + 64) / 192)
    assert slippery["runs"] == 3  # the failed run left out
    assert slippery["step_limit"]["inner"] == pytest.approx(62.5)
    assert slippery["early"]["by_end"] == {"power empty": 1}
    only_x = matrix_ends([a, b], only="x")
    assert only_x["worlds"][0]["inner"] == pytest.approx(50.0)  # 40 and 24 of 64
    assert only_x["worlds"][1]["early_cost"] == pytest.approx(50.0 - 100 * 40 / 128)
    text = markdown(only_x)
    assert "named *x*" in text
    row = "| slippery | 2 | 31.2 | 1, 50.0, 7.0 | 1 (power empty 1), 12.5, 7.0, 250 | 18.8 |"
    assert row in text


def test_a_worlds_drop_below_shipped_paired_by_hand(tmp_path):
    # two matrices, chromosome x: shipped 40, 24 | 48 of 64; slippery 32, (failed) | 40, and
    # y, whose shipped run failed. Pairs: (40 - 32), (48 - 40) squares -> 12.5 pp both, s.e. 0;
    # the failed run and y have no partner. s.e. of slippery's inner % over 32, 40, 16
    a, b = tmp_path / "a", tmp_path / "b"
    failed = {"physics": None, "error": "unstable"}
    _write_matrix(a, {"shipped": {"x": [_run("step limit", 40), _run("step limit", 24)],
                                  "y": [failed]},
                      "slippery": {"x": [_run("step limit", 32), failed],
                                   "y": [_run("power empty", 16, steps=300)]}})  # fmt: skip
    _write_matrix(b, {"shipped": {"x": [_run("step limit", 48)]},
                      "slippery": {"x": [_run("step limit", 40)]}})  # fmt: skip
    doc = matrix_ends([a, b])
    shipped, slippery = doc["worlds"]
    assert shipped["drop"] is None
    assert slippery["drop"] == {"pairs": 2, "mean": pytest.approx(12.5), "se": pytest.approx(0.0)}
    pct = [50.0, 62.5, 25.0]  # 32, 40 and 16 of 64
    se = (sum((p - sum(pct) / 3) ** 2 for p in pct) / 2) ** 0.5 / 3**0.5
    assert slippery["inner_se"] == pytest.approx(se)
    assert f"| {se:.1f} | 12.5 ± 0.0 (2) |" in markdown(doc)
    # one pair: no s.e.; without shipped: no drop
    one = matrix_ends([b])
    assert one["worlds"][1]["drop"] == {"pairs": 1, "mean": pytest.approx(12.5), "se": None}
    assert "| 12.5 (1) |" in markdown(one)
    assert matrix_ends([b], only="x")["worlds"][0]["inner_se"] is None
    c = tmp_path / "c"
    _write_matrix(c, {"slippery": {"x": [_run("step limit", 40)]}})
    assert matrix_ends([c])["worlds"][0]["drop"] is None


def test_main_writes_and_refuses(tmp_path, capsys):
    m = tmp_path / "m"
    _write_matrix(m, {"shipped": {"x": [_run("step limit", 32)]}})
    out = tmp_path / "out"
    assert main([str(m), "--out", str(out)]) == 0
    assert {p.name for p in out.iterdir()} == {"ends.json", "ends.md"}
    assert "| shipped | 1 | 50.0 |" in capsys.readouterr().out
    assert main([str(m), "--only", "zz"]) == 2
    assert "no physics coverage run of a chromosome named *zz*" in capsys.readouterr().err
    assert main([str(tmp_path / "nothing")]) == 2
    assert "not a finished `servobot robustness` folder" in capsys.readouterr().err
    cell = m / "runs" / "shipped" / "x" / "report.json"
    cell.write_text("{not json")
    assert main([str(m)]) == 2
    assert "report.json" in capsys.readouterr().err
    cell.write_text(json.dumps({"runs": []}))  # no summary
    assert main([str(m)]) == 2
    assert "x/report.json: not a matrix cell report" in capsys.readouterr().err
